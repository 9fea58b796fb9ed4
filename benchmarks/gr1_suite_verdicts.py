"""Verdict agreement on the field's GR(1) suites, in both readings, and the peer timing table.

Usage::

    python -m benchmarks.gr1_suite_verdicts DIR... [--timeout S] [--slugs PATH]
                                            [--out DIR] [--resume] [--from-log]

Every ``*.spectra``, ``*.structuredslugs`` and ``*.slugsin`` file under the folders (checkouts
of ``SpectraSynthesizer/spectra-specs`` and of slugs' ``examples/``) is imported with ``tli
spec import``'s translation; refused files are counted by reason. Files whose translation is
the same spec (same variables and formulas; the suites hold copies, e.g. SYNTECH17's
``all_realizable/`` and ``groupN/realizable/``) are decided once. Each distinct spec is decided,
each tool in its own process with the time limit (a time-out is never a verdict):

* in the textbook reading (Spectra's and slugs'): ours, omega (``tests/support/omega_oracle``,
  the same formulas) and slugs (its own binary on the same formulas as ``.slugsin``); these
  runs are also the timing measurements of :mod:`benchmarks.bench_gr1_peers`;
* in our reading (``semantics = "tli"``): ours and omega (slugs has no such reading). A tool
  that timed out in the textbook reading is not run again in ours (counted as not decided).

Spectra's label of a file is its folder (``realizable``/``all_realizable`` or
``unrealizable``/``all_unrealizable``), else the word ``realizable``/``unrealizable`` in its
name (:func:`label_of`); other files have no label. Writes
``gr1_suite_verdicts.md``, ``gr1_peers.md`` and the per-spec log ``gr1_suite_runs.jsonl``
under ``--out`` (default ``benchmarks/results``). ``--resume`` skips specs already in the log;
``--from-log`` only rebuilds the tables.
"""

from __future__ import annotations

import argparse
import collections
import hashlib
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from benchmarks.bench_gr1_peers import REPO, Row, _in_process, _slugs, find_slugs, report
from benchmarks.foreign_suites import _reason
from tli_verify.io import atomic_write_text
from tli_verify.logic.escape import markdown_text

READINGS = ("textbook", "tli")
LOG = "gr1_suite_runs.jsonl"


def label_of(path: Path, root: Path) -> tuple[str | None, str]:
    """Spectra's realizability label of the suite file ``root / path``: "R", "U" or None, and
    where it comes from ("folder" or "name").

    A folder ``realizable``/``all_realizable`` or ``unrealizable``/``all_unrealizable`` on the
    path is the label. Else the words ``realizable``/``unrealizable`` in the file name are,
    except next to an ``unrealizable/`` folder: there the suite sorts by folder, and a file
    left outside it (SYNTECH15's ``PCarLTL_Unrealizable_..._fixed``) has no label."""
    for part in reversed(path.parts[:-1]):
        low = part.lower()
        if low in ("unrealizable", "all_unrealizable"):
            return "U", "folder"
        if low in ("realizable", "all_realizable"):
            return "R", "folder"
    if (root / path).parent.joinpath("unrealizable").is_dir():
        return None, ""
    stem = path.stem.lower()
    if "unrealizab" in stem:
        return "U", "name"
    if "realizab" in stem:
        return "R", "name"
    return None, ""


def spec_key(text: str) -> str:
    """The identity of an imported spec: its TOML without comments, name and description."""
    body = [ln for ln in text.splitlines()
            if ln.strip() and not ln.lstrip().startswith("#")
            and not ln.startswith(("name =", "description ="))]
    return hashlib.sha256("\n".join(body).encode("utf-8")).hexdigest()[:16]


@dataclass
class Distinct:
    """One distinct imported spec and the suite files that translate to it."""

    text: str
    files: list[str] = field(default_factory=list)
    labels: dict[str, tuple[str, str]] = field(default_factory=dict)


def collect(dirs: list[Path]) -> tuple[dict[str, Distinct], dict[str, Any], list[str]]:
    """Import every suite file: the distinct specs (by :func:`spec_key`) and the counts."""
    from tli_verify.errors import SpecError
    from tli_verify.logic.foreign import FORMATS, import_spec_file
    from tli_verify.logic.spec import parse_spec

    notes: list[str] = []
    counts: dict[str, Any] = {"files": 0, "imported": 0, "by_format": collections.Counter(),
                              "refused": collections.Counter(),
                              "not_loadable": collections.Counter()}
    specs: dict[str, Distinct] = {}
    for d in dirs:
        if not d.is_dir():
            notes.append(f"suite folder {d} not found, skipped")
            continue
        for p in sorted(q for q in d.rglob("*") if q.suffix in FORMATS and q.is_file()):
            counts["files"] += 1
            counts["by_format"][FORMATS[p.suffix]] += 1
            name = f"{d.name}/{p.relative_to(d)}"
            try:
                text = import_spec_file(p)
            except SpecError as exc:
                counts["refused"][_reason(str(exc))] += 1
                continue
            counts["imported"] += 1
            try:
                parse_spec(text, path=name)
            except SpecError as exc:
                counts["not_loadable"][_reason(str(exc))] += 1
                continue
            entry = specs.setdefault(spec_key(text), Distinct(text=text))
            entry.files.append(name)
            lab, src = label_of(p.relative_to(d), d)
            if lab is not None:
                entry.labels[name] = (lab, src)
    return specs, counts, notes


def _verdict(r: dict[str, Any] | None) -> str:
    """"R", "U", "T" (time-out), "E" (error) or "-" (not run)."""
    if not r:
        return "-"
    if r.get("skipped"):
        return "-"
    if r.get("timeout"):
        return "T"
    if "verdict" not in r or r["verdict"] is None:
        return "E"
    return "R" if r["verdict"] else "U"


def decide(text: str, *, timeout: float, slugs: str | None) -> dict[str, Any]:
    """One spec, every tool, both readings (the textbook runs timed, ours verdict-only)."""
    rec: dict[str, Any] = {"limit": timeout}
    for sem in READINGS:
        res: dict[str, Any] = {}
        for tool in ("ours", "omega"):
            if sem != "textbook" and rec["textbook"][tool].get("timeout"):
                res[tool] = {"timeout": True, "skipped": True, "limit": timeout}
            else:
                res[tool] = _in_process(tool, text, timeout, semantics=sem,
                                        repeats=3 if sem == "textbook" else 1)
        if sem == "textbook" and slugs is not None:
            res["slugs"] = _slugs(slugs, text, timeout)
        rec[sem] = res
    return rec


def _line(k: int, n: int, rec: dict[str, Any]) -> str:
    got = " ".join(f"{sem}:" + "/".join(_verdict(rec[sem].get(t))
                                         for t in ("ours", "omega", "slugs"))
                   for sem in READINGS)
    return f"[{k}/{n}] {rec['name']} ({rec['n_vars']} vars, {rec['limit']:g} s): {got}"


def measure(specs: dict[str, Distinct], *, timeout: float, slugs: str | None,
            log_path: Path, resume: bool) -> None:
    """Decide every distinct spec (smallest first), one JSON line per spec in ``log_path``."""
    from tli_verify.logic.spec import parse_spec

    done = set()
    if resume and log_path.is_file():
        done = {json.loads(ln)["key"] for ln in log_path.read_text("utf-8").splitlines() if ln}
    todo = []
    for key, entry in specs.items():
        spec = parse_spec(entry.text, path=entry.files[0])
        todo.append((len(spec.inputs) + len(spec.outputs), entry.files[0], key, entry))
    todo.sort()
    with log_path.open("a" if resume else "w", encoding="utf-8") as log:
        for k, (n_vars, name, key, entry) in enumerate(todo, start=1):
            if key in done:
                continue
            rec = {"key": key, "name": name, "n_vars": n_vars, "files": entry.files,
                   "labels": entry.labels, **decide(entry.text, timeout=timeout, slugs=slugs)}
            log.write(json.dumps(rec) + "\n")
            log.flush()
            print(_line(k, len(todo), rec), flush=True)


def retry_timeouts(specs: dict[str, Distinct], *, timeout: float, slugs: str | None,
                   log_path: Path) -> None:
    """Decide again, with the (longer) ``timeout``, every spec of the log that a tool did not
    decide within its limit or failed on (smallest first); the log is rewritten after each."""
    recs = [json.loads(ln) for ln in log_path.read_text("utf-8").splitlines() if ln]
    again = sorted((r["n_vars"], i) for i, r in enumerate(recs)
                   if r.get("limit", 0) < timeout and r["key"] in specs
                   and any(_verdict(x) in ("T", "E") for sem in READINGS
                           for x in r[sem].values()))
    for k, (_, i) in enumerate(again, start=1):
        r = recs[i]
        r.update(decide(specs[r["key"]].text, timeout=timeout, slugs=slugs))
        atomic_write_text(log_path, "".join(json.dumps(x) + "\n" for x in recs))
        print(_line(k, len(again), r), flush=True)


# -- the tables --------------------------------------------------------------------------------

def _pair(recs: list[dict[str, Any]], sem: str, a: str, b: str) -> tuple[int, int, int, list[str]]:
    """Agree, disagree, undecided (one or both not decided) and the disagreeing names."""
    agree = disagree = undecided = 0
    names = []
    for r in recs:
        va, vb = _verdict(r[sem].get(a)), _verdict(r[sem].get(b))
        if va in ("R", "U") and vb in ("R", "U"):
            if va == vb:
                agree += 1
            else:
                disagree += 1
                names.append(r["name"])
        else:
            undecided += 1
    return agree, disagree, undecided, names


def _label(r: dict[str, Any]) -> str:
    labels = {lab for lab, _ in r["labels"].values()}
    return labels.pop() if len(labels) == 1 else ("conflict" if labels else "-")


def limits(recs: list[dict[str, Any]], default: float) -> tuple[float, float, int]:
    """The first limit, the longest, and how many specs were decided again with the longest."""
    got = [float(r.get("limit", default)) for r in recs] or [default]
    first, longest = min(got), max(got)
    return first, longest, sum(x == longest for x in got) if longest > first else 0


def command_text(recs: list[dict[str, Any]], default: float, slugs: bool) -> str:
    first, longest, again = limits(recs, default)
    base = ("python -m benchmarks.gr1_suite_verdicts SPECTRA_SPECS SLUGS/examples "
            + ("--slugs SLUGS_BINARY " if slugs else ""))
    out = f"{base}--timeout {first:g}"
    if again:
        out += f"`, then `{base}--timeout {longest:g} --retry-timeouts"
    return out


def limit_text(recs: list[dict[str, Any]], default: float) -> str:
    first, longest, again = limits(recs, default)
    return (f"a {first:g} s limit" + (f" ({longest:g} s for the {again} specs decided again "
                                      "after a time-out)" if again else ""))


def verdict_report(recs: list[dict[str, Any]], counts: dict[str, Any] | None, *,
                   timeout: float, notes: list[str], command: str) -> str:
    tools = {"textbook": ("ours", "omega", "slugs"), "tli": ("ours", "omega")}
    has_slugs = any("slugs" in r["textbook"] for r in recs)
    lines = ["## GR(1) verdicts on the field's suites: both readings, against omega, slugs "
             "and Spectra's labels", "", f"Reproduce: `{command}`.", ""]
    if counts:
        fmts = ", ".join(f"{k} {v}" for k, v in sorted(counts["by_format"].items()))
        lines += [
            f"Suite files: {counts['files']} ({fmts}); "
            f"imported {counts['imported']}, refused {counts['files'] - counts['imported']}; "
            f"imported but not loadable {sum(counts['not_loadable'].values())}; "
            f"{len(recs)} distinct specs decided (copies of one spec are decided once).", ""]
        if counts["refused"]:
            lines += ["| refused by `tli spec import` (first words of the reason) | files |",
                      "|---|---:|"]
            lines += [f"| {markdown_text(k)} | {v} |" for k, v in counts["refused"].most_common()]
            lines.append("")
        if counts["not_loadable"]:
            lines += ["| imported, then refused by the spec loader | files |", "|---|---:|"]
            lines += [f"| {markdown_text(k)} | {v} |"
                      for k, v in counts["not_loadable"].most_common()]
            lines.append("")
    lines += [
        f"Each tool decides each spec in its own process with {limit_text(recs, timeout)}; a "
        "time-out (T) or a failure (E) is never a verdict. *textbook* is Spectra's and "
        "slugs' reading of `G(phi)` at time 0 (the imported specs' own setting), *tli* ours "
        "(docs/explanation/logic.md, \"Two readings of safety at time 0\"); slugs has only "
        "the textbook reading. A tool that timed out in the textbook reading was not run "
        "again in ours.", "",
        "| reading | tool | realizable | unrealizable | time-out | error | not run |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for sem in READINGS:
        for t in tools[sem]:
            if t == "slugs" and not has_slugs:
                continue
            c = collections.Counter(_verdict(r[sem].get(t)) for r in recs)
            lines.append(f"| {sem} | {t} | {c['R']} | {c['U']} | {c['T']} | {c['E']} | {c['-']} |")
    lines += ["", "| reading | comparison | agree | disagree | not both decided |",
              "|---|---|---:|---:|---:|"]
    disagreements: list[str] = []
    for sem in READINGS:
        for t in tools[sem][1:]:
            if t == "slugs" and not has_slugs:
                continue
            a, d, u, names = _pair(recs, sem, "ours", t)
            lines.append(f"| {sem} | ours vs {t} | {a} | {d} | {u} |")
            disagreements += [f"{sem}, ours vs {t}: {markdown_text(n)}" for n in names]
    # Spectra's labels (textbook reading is Spectra's)
    labelled = [r for r in recs if _label(r) in ("R", "U")]
    for sem in READINGS:
        for t in tools[sem]:
            if t == "slugs" and not has_slugs:
                continue
            agree = disagree = und = 0
            for r in labelled:
                v = _verdict(r[sem].get(t))
                if v not in ("R", "U"):
                    und += 1
                elif v == _label(r):
                    agree += 1
                else:
                    disagree += 1
                    if sem == "textbook":
                        disagreements.append(
                            f"textbook, {t} vs Spectra's label {_label(r)} "
                            f"({', '.join(sorted({s for _, s in r['labels'].values()}))}): "
                            f"{markdown_text(r['name'])}")
            lines.append(f"| {sem} | {t} vs Spectra's label ({len(labelled)} labelled) | "
                         f"{agree} | {disagree} | {und} |")
    conflicts = [r["name"] for r in recs if _label(r) == "conflict"]
    differ = [r for r in recs if _verdict(r["textbook"]["ours"]) in ("R", "U")
              and _verdict(r["tli"]["ours"]) in ("R", "U")
              and _verdict(r["textbook"]["ours"]) != _verdict(r["tli"]["ours"])]
    both = sum(_verdict(r["textbook"]["ours"]) in ("R", "U")
               and _verdict(r["tli"]["ours"]) in ("R", "U") for r in recs)
    lines += ["", f"The two readings give different verdicts (ours) on {len(differ)} of the "
              f"{both} specs decided in both" + (": " + "; ".join(
                  f"{markdown_text(r['name'])} (textbook {_verdict(r['textbook']['ours'])}, "
                  f"tli {_verdict(r['tli']['ours'])})" for r in differ) if differ else "") + ".",
              ""]
    lines.append("Disagreements: " + ("; ".join(disagreements) if disagreements else "none")
                 + ".")
    if conflicts:
        lines += ["", "Copies with conflicting labels (not counted): "
                  + ", ".join(markdown_text(n) for n in conflicts) + "."]
    lines.append("")
    lines += [f"Note: {n}." for n in notes]
    return "\n".join(lines).rstrip() + "\n"


def peer_rows(recs: list[dict[str, Any]]) -> list[Row]:
    return [Row(name=r["name"], n_vars=r["n_vars"], results=dict(r["textbook"])) for r in recs]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.gr1_suite_verdicts",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="*", type=Path)
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per tool and spec")
    ap.add_argument("--slugs", default=None, help="the slugs binary (else as bench_gr1_peers)")
    ap.add_argument("--slugs-src", default=None, help="a slugs source tree to build")
    ap.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results")
    ap.add_argument("--resume", action="store_true", help="keep the log, decide the rest")
    ap.add_argument("--from-log", action="store_true", help="only rebuild the tables")
    ap.add_argument("--retry-timeouts", action="store_true",
                    help="decide again, with --timeout, the specs of the log with a time-out "
                         "or a failure under a shorter limit")
    ap.add_argument("--note", action="append", default=[], help="a note for the tables")
    args = ap.parse_args(argv)
    log_path = args.out / LOG
    notes = list(args.note)
    counts = None
    if not args.from_log:
        specs, counts, suite_notes = collect(args.dirs)
        notes += suite_notes
        if not specs:
            print("note: no suite files imported; nothing measured")
            return 0
        slugs, slugs_note = find_slugs(args.slugs, args.slugs_src)
        notes.append(slugs_note)
        if args.retry_timeouts:
            retry_timeouts(specs, timeout=args.timeout, slugs=slugs, log_path=log_path)
        else:
            measure(specs, timeout=args.timeout, slugs=slugs, log_path=log_path,
                    resume=args.resume)
        (args.out / "gr1_suite_counts.json").write_text(json.dumps(
            {k: (dict(v) if isinstance(v, collections.Counter) else v)
             for k, v in counts.items()}, indent=1), encoding="utf-8")
    else:
        path = args.out / "gr1_suite_counts.json"
        if path.is_file():
            raw = json.loads(path.read_text("utf-8"))
            counts = {k: (collections.Counter(v) if isinstance(v, dict) else v)
                      for k, v in raw.items()}
    recs = [json.loads(ln) for ln in log_path.read_text("utf-8").splitlines() if ln]
    if not args.from_log:  # the specs as imported now (a changed translation is a new key)
        recs = [r for r in recs if r["key"] in specs]
        for r in recs:
            r["labels"] = specs[r["key"]].labels
        atomic_write_text(log_path, "".join(json.dumps(x) + "\n" for x in recs))
    has_slugs = any("slugs" in r["textbook"] for r in recs)
    command = command_text(recs, args.timeout, has_slugs)
    first, longest, again = limits(recs, args.timeout)
    if again:
        notes.append(f"the peer table counts a time-out as its limit ({first:g} s, or "
                     f"{longest:g} s for the {again} specs decided again)")
    atomic_write_text(args.out / "gr1_suite_verdicts.md", verdict_report(
        recs, counts, timeout=args.timeout, notes=notes, command=command))
    peers = ["omega"] + (["slugs"] if has_slugs else [])
    section = report(peer_rows(recs), timeout=first, peers=peers, notes=notes,
                     source=f"Suites: the {len(recs)} distinct specs that `tli spec import` "
                     f"imports and loads (`{command}`; the textbook-reading runs).")
    atomic_write_text(args.out / "gr1_peers.md", section)
    sys.stdout.write((args.out / "gr1_suite_verdicts.md").read_text("utf-8") + "\n" + section)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
