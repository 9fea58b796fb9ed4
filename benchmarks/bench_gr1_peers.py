"""GR(1) realizability on the field's suites: tli-verify vs omega vs slugs, by spec size.

Usage::

    python -m benchmarks.bench_gr1_peers [--suites DIR ...] [--timeout S] [--slugs PATH]
                                         [--slugs-src DIR] [--random]

or as part of ``python -m benchmarks`` (``--only gr1_peers``), configured by environment:

* ``TLI_GR1_SUITES``: folders (``os.pathsep``-separated) holding ``*.spectra``,
  ``*.structuredslugs`` and ``*.slugsin`` files, e.g. checkouts of
  ``SpectraSynthesizer/spectra-specs`` and ``VerifiableRobotics/slugs``'s ``examples/``.
  Imported with ``tli spec import``'s translation (textbook reading); refused files are not
  measured. Without suites only the seeded random specs run, and the table says so.
* ``TLI_SLUGS``: the slugs binary (else ``slugs`` on ``PATH``, else a previous build under
  ``benchmarks/.peers/``); ``TLI_SLUGS_SRC``: a slugs source tree to build into
  ``benchmarks/.peers/slugs`` (``make`` in its ``src/``; needs g++ and Boost headers).
  Without either the slugs columns are skipped with a note. Nothing is ever downloaded.
* ``TLI_GR1_TIMEOUT``: seconds per tool and spec (default 60).

Each spec is decided by each tool in its own process with the time limit: ours from the
imported TOML text (parse, game construction, fixpoint), omega from our parsed spec (its
automaton construction and fixpoint), slugs on the same formulas written as ``.slugsin`` (the
whole process). Times are medians of 3 runs below 1 s, else 1 run. Verdicts are compared.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from benchmarks.foreign_suites import last_message
from tli_verify.io import atomic_write_text
from tli_verify.logic.escape import markdown_text

REPO = Path(__file__).resolve().parents[1]
PEERS = Path(__file__).resolve().parent / ".peers"
SIZES = ((0, 20), (21, 50), (51, 100), (101, 10**9))
MIN_PEER = 0.1
"""Ratios are taken on specs where the peer needs more than this many seconds."""


# -- slugs -----------------------------------------------------------------------------------

def _slugs_expr(f: Any) -> str:
    """A propositional formula (``X`` at depth <= 1) in slugs' prefix notation."""
    import spot

    def walk(g: Any, primed: bool) -> str:
        k = g.kind()
        if k == spot.op_tt:
            return "1"
        if k == spot.op_ff:
            return "0"
        if k == spot.op_ap:
            return str(g.ap_name()) + ("'" if primed else "")
        if k == spot.op_X:
            return walk(g[0], True)
        args = [walk(c, primed) for c in g]
        if k == spot.op_Not:
            return f"! {args[0]}"
        if k in (spot.op_And, spot.op_Or):
            op = "&" if k == spot.op_And else "|"
            out = args[-1]
            for a in reversed(args[:-1]):
                out = f"{op} {a} {out}"
            return out
        if k == spot.op_Implies:
            return f"| ! {args[0]} {args[1]}"
        if k == spot.op_Equiv:
            return f"! ^ {args[0]} {args[1]}"
        if k == spot.op_Xor:
            return f"^ {args[0]} {args[1]}"
        raise ValueError(f"not propositional: {g}")

    return walk(f, False)


def slugsin_text(spec: Any) -> str:
    """``spec`` (a :class:`~tli_verify.logic.spec.GR1Spec`) in slugs' ``.slugsin`` format:
    the textbook reading, the same formulas our game is built from."""
    from tli_verify.logic.gr1 import _conjuncts
    from tli_verify.logic.ltl import Slot, gr1_body

    def lines(formulas: Any, slot: Slot | None) -> list[str]:
        out = []
        for f in formulas:
            for g in _conjuncts(f.ltl):
                out.append(_slugs_expr(g if slot is None else gr1_body(g, slot)))
        return out

    sections = [
        ("INPUT", list(spec.inputs)), ("OUTPUT", list(spec.outputs)),
        ("ENV_INIT", lines(spec.assume.init, None)),
        ("SYS_INIT", lines(spec.guarantee.init, None)),
        ("ENV_TRANS", lines(spec.assume.safety, Slot.SAFETY)),
        ("SYS_TRANS", lines(spec.guarantee.safety, Slot.SAFETY)),
        ("ENV_LIVENESS", lines(spec.assume.liveness, Slot.LIVENESS)),
        ("SYS_LIVENESS", lines(spec.guarantee.liveness, Slot.LIVENESS)),
    ]
    return "".join(f"[{name}]\n" + "".join(x + "\n" for x in body) + "\n"
                   for name, body in sections)


def find_slugs(binary: str | None = None, source: str | None = None) -> tuple[str | None, str]:
    """The slugs binary to compare with, and a note on where it came from (or why not)."""
    binary = binary or os.environ.get("TLI_SLUGS")
    if binary:
        return (binary, f"slugs: {binary}") if Path(binary).is_file() else \
            (None, f"slugs skipped: {binary} not found")
    on_path = shutil.which("slugs")
    if on_path:
        return on_path, f"slugs: {on_path} (on PATH)"
    built = PEERS / "slugs" / "src" / "slugs"
    source = source or os.environ.get("TLI_SLUGS_SRC")
    if source and not built.is_file():
        if not (Path(source) / "src" / "Makefile").is_file():
            return None, f"slugs skipped: no src/Makefile under {source}"
        shutil.rmtree(PEERS / "slugs", ignore_errors=True)
        shutil.copytree(source, PEERS / "slugs")
        done = subprocess.run(["make", "-j2"], cwd=PEERS / "slugs" / "src",
                              capture_output=True, text=True, check=False)
        if done.returncode != 0:
            tail = " ".join(done.stderr.split()[-12:])
            return None, f"slugs skipped: building {source} failed ({tail})"
    if built.is_file():
        return str(built), f"slugs: built from source into {built.relative_to(REPO)}"
    return None, ("slugs skipped: not on PATH; set TLI_SLUGS to a binary or TLI_SLUGS_SRC to "
                  "a source tree (github.com/VerifiableRobotics/slugs) to build it")


# -- one spec, one tool, one process -----------------------------------------------------------

def _ours(text: str, semantics: str | None = None) -> tuple[bool, dict[str, float]]:
    from tli_verify.logic.gr1 import build_game, solve
    from tli_verify.logic.spec import parse_spec

    t0 = time.perf_counter()
    spec = parse_spec(text, path="imported.toml")
    t1 = time.perf_counter()
    game = build_game(spec, semantics=semantics)
    t2 = time.perf_counter()
    verdict = solve(game, keep_iterates=False, exact=False).realizable
    t3 = time.perf_counter()
    return verdict, {"parse": t1 - t0, "build": t2 - t1, "solve": t3 - t2, "total": t3 - t0}


def _omega(text: str, semantics: str | None = None) -> tuple[bool, dict[str, float]]:
    sys.path.insert(0, str(REPO))
    from tests.support.omega_oracle import omega_realizable
    from tli_verify.logic.spec import parse_spec

    spec = parse_spec(text, path="imported.toml")
    # omega's parser recurses once per operand of a formula (and logs its repr): the imported
    # specs' long conjunctions need more than Python's default depth (this process only)
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 100_000))
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        verdict = omega_realizable(spec, semantics=semantics)
    return verdict, {"total": time.perf_counter() - t0}


def _repeat(tool: str, text: str, semantics: str | None, repeats: int, out: Any) -> None:
    fn = _ours if tool == "ours" else _omega
    runs = []
    verdict = None
    for _ in range(repeats):
        verdict, times = fn(text, semantics)
        runs.append(times)
        out.put(("partial", verdict, runs))
        if times["total"] > 1.0:
            break
    out.put(("done", verdict, runs))


def _in_process(tool: str, text: str, timeout: float, semantics: str | None = None,
                repeats: int = 3) -> dict[str, Any]:
    """``tool`` ("ours" or "omega") on the spec ``text`` in a forked process, in ``semantics``
    (default: the spec's own), up to ``repeats`` runs while each takes at most 1 s."""
    t0 = time.perf_counter()
    last = last_message(_repeat, (tool, text, semantics, repeats), timeout)
    if last is None:
        if time.perf_counter() - t0 < 0.95 * timeout:  # ended early without a verdict
            return {"timeout": False, "error": "the process ended without a verdict"}
        return {"timeout": True, "limit": timeout}
    _, verdict, runs = last
    med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    return {"timeout": False, "verdict": verdict, **med}


def _slugs(binary: str, text: str, timeout: float) -> dict[str, Any]:
    from tli_verify.logic.spec import parse_spec

    slugsin = slugsin_text(parse_spec(text, path="imported.toml"))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "spec.slugsin"
        path.write_text(slugsin, encoding="utf-8")
        runs, verdict = [], None
        for _ in range(3):
            t0 = time.perf_counter()
            try:
                done = subprocess.run([binary, str(path)],
                                      capture_output=True, text=True, timeout=timeout,
                                      check=False)
            except subprocess.TimeoutExpired:
                return {"timeout": True, "limit": timeout}
            runs.append(time.perf_counter() - t0)
            said = done.stdout + done.stderr
            if "is realizable" in said:
                verdict = True
            elif "is unrealizable" in said:
                verdict = False
            else:
                return {"timeout": False, "error": " ".join(said.split()[:12])}
            if runs[-1] > 1.0:
                break
    return {"timeout": False, "verdict": verdict, "total": statistics.median(runs)}


# -- the benchmark ---------------------------------------------------------------------------

@dataclass
class Row:
    name: str
    n_vars: int
    results: dict[str, dict[str, Any]] = field(default_factory=dict)


def _suite_texts(dirs: list[Path]) -> tuple[list[tuple[str, str]], int, list[str]]:
    from tli_verify.errors import SpecError
    from tli_verify.logic.foreign import FORMATS, import_spec_file

    notes, texts, refused = [], [], 0
    for d in dirs:
        if not d.is_dir():
            notes.append(f"suite folder {d} not found, skipped")
            continue
        for p in sorted(q for q in d.rglob("*") if q.suffix in FORMATS and q.is_file()):
            try:
                texts.append((f"{d.name}/{p.relative_to(d)}", import_spec_file(p)))
            except SpecError:
                refused += 1
    return texts, refused, notes


def _random_texts() -> list[tuple[str, str]]:
    from tli_verify.logic.generate import RandomSpecConfig, random_spec_text

    out = []
    for n_vars in (10, 20, 30, 40):
        half = n_vars // 2
        config = RandomSpecConfig(n_inputs=half, n_outputs=n_vars - half,
                                  n_env_safety=half // 2 + 1, n_sys_safety=half,
                                  n_env_live=2, n_sys_live=3, depth=3)
        for seed in range(4):
            text = random_spec_text(config, 7919 * n_vars + seed)
            out.append((f"random-{n_vars}-{seed}", text.replace(
                "\n[assume]", '\nsemantics = "textbook"\n[assume]', 1)))
    return out


def measure(texts: list[tuple[str, str]], *, timeout: float, slugs: str | None,
            log: Any = None) -> list[Row]:
    """Decide every spec with every tool (each in its own process, with ``timeout``)."""
    from tli_verify.logic.spec import parse_spec

    rows = []
    for name, text in texts:
        spec = parse_spec(text, path=name)
        row = Row(name=name, n_vars=len(spec.inputs) + len(spec.outputs))
        row.results["ours"] = _in_process("ours", text, timeout)
        row.results["omega"] = _in_process("omega", text, timeout)
        if slugs is not None:
            row.results["slugs"] = _slugs(slugs, text, timeout)
        rows.append(row)
        if log is not None:
            log.write(json.dumps({"name": name, "n_vars": row.n_vars, **row.results}) + "\n")
            log.flush()
    return rows


def _t(r: dict[str, Any], timeout: float) -> float:
    """The time of one result; a time-out counts as its limit."""
    if r.get("timeout"):
        return float(r.get("limit", timeout))
    return float(r.get("total", float("nan")))


def table(rows: list[Row], *, timeout: float, peers: list[str]) -> list[str]:
    """The Markdown ratio table (by size) and the summary lines."""
    lines = [
        "| vars | specs | time-outs (ours / " + " / ".join(peers) + ") | "
        + " | ".join(f"vs {p}: n, median, worst" for p in peers)
        + " | vs faster peer: worst |",
        "|---|---:|---|" + "---|" * len(peers) + "---|",
    ]
    buckets = [(lo, hi, [r for r in rows if lo <= r.n_vars <= hi]) for lo, hi in SIZES]
    buckets.append((0, 0, rows))
    for lo, hi, rs in buckets:
        if not rs:
            continue
        label = "all" if (lo, hi) == (0, 0) else (f"{lo}-{hi}" if hi < 10**9 else f"> {lo - 1}")
        outs = [sum(bool(r.results[t].get("timeout")) for r in rs) for t in ["ours", *peers]]
        cells = []
        n_specs = len(rs)
        rs = [r for r in rs if "error" not in r.results["ours"]]  # ours failed: no ratio
        for p in peers:
            ratios = [_t(r.results["ours"], timeout) / _t(r.results[p], timeout) for r in rs
                      if "total" in r.results[p] or r.results[p].get("timeout")
                      if _t(r.results[p], timeout) > MIN_PEER
                      and not (r.results[p].get("timeout") and r.results["ours"].get("timeout"))]
            cells.append(f"{len(ratios)}, {statistics.median(ratios):.2f}x, {max(ratios):.2f}x"
                         if ratios else "0, -, -")
        faster = []
        for r in rs:
            decided = [_t(r.results[p], timeout) for p in peers if "error" not in r.results[p]]
            best = min(decided, default=0.0)
            if best > MIN_PEER and not all(r.results[t].get("timeout")
                                           for t in ["ours", *peers]):
                faster.append(_t(r.results["ours"], timeout) / best)
        lines.append(f"| {label} | {n_specs} | {' / '.join(map(str, outs))} | "
                     + " | ".join(cells)
                     + f" | {max(faster):.2f}x |" if faster else
                     f"| {label} | {n_specs} | {' / '.join(map(str, outs))} | "
                     + " | ".join(cells) + " | - |")
    return lines


def report(rows: list[Row], *, timeout: float, peers: list[str], notes: list[str],
           source: str) -> str:
    fixed_small = [r.results["ours"]["parse"] + r.results["ours"]["build"] for r in rows
                   if "parse" in r.results["ours"] and r.n_vars <= 20]
    fixed_all = [r.results["ours"]["parse"] + r.results["ours"]["build"] for r in rows
                 if "parse" in r.results["ours"]]
    disagree = [r.name for r in rows
                if len({r.results[t]["verdict"] for t in r.results
                        if r.results[t].get("verdict") is not None}) > 1]
    slowest = sorted((r for r in rows if not r.results["ours"].get("timeout")),
                     key=lambda r: -_t(r.results["ours"], timeout))[:5]
    lines = [
        "## GR(1) realizability on the field's suites: tli-verify vs omega and slugs",
        "",
        source,
        "",
        f"Each tool decides each spec in its own process with a {timeout:g} s limit (a "
        f"time-out counts as {timeout:g} s in a ratio); times are medians of 3 runs below "
        "1 s, else 1 run: ours from the spec text (parse, game, fixpoint), omega from our "
        "parsed spec (automaton and fixpoint), slugs the whole process on the same formulas "
        "(`.slugsin`, its default realizability check). Ratio = our time / the peer's, over "
        f"the specs where the peer needs more than {MIN_PEER:g} s; *vs faster peer* divides "
        "by the faster of the peers.",
        "",
        *table(rows, timeout=timeout, peers=peers),
        "",
        f"Fixed cost per spec (ours, parse + game construction, median): "
        f"**{statistics.median(fixed_small) * 1000:.1f} ms** on the {len(fixed_small)} specs "
        f"of at most 20 variables, {statistics.median(fixed_all) * 1000:.1f} ms on all "
        f"{len(fixed_all)} decided." if fixed_small and fixed_all else "",
        "",
        f"Verdicts: the tools disagree on {len(disagree)} spec(s)"
        + (": " + ", ".join(markdown_text(n) for n in disagree) if disagree else "") + ".",
        "",
        "Our slowest: " + "; ".join(
            f"{markdown_text(r.name)} ({r.n_vars} vars): ours {_t(r.results['ours'], timeout):.2f}"
            " s, " + ", ".join(f"{p} failed" if "error" in r.results[p] else
                               f"{p} {_t(r.results[p], timeout):.2f} s" for p in peers)
            for r in slowest) + ".",
        "",
    ]
    lines += [f"Note: {n}." for n in notes]
    return "\n".join(lines).rstrip() + "\n"


def run(*, suites: list[Path], timeout: float, slugs_binary: str | None = None,
        slugs_source: str | None = None, random: bool = True,
        log_path: Path | None = None) -> str:
    """Measure and return the Markdown section."""
    slugs, slugs_note = find_slugs(slugs_binary, slugs_source)
    notes = [slugs_note]
    texts, refused, suite_notes = _suite_texts(suites)
    notes += suite_notes
    if suites and texts:
        source = (f"Suites: {', '.join(str(s) for s in suites)} ({len(texts)} specs imported, "
                  f"{refused} refused by `tli spec import`), plus 16 seeded random specs of 10 "
                  "to 40 variables.")
    else:
        source = ("No suite folder given (set TLI_GR1_SUITES): seeded random specs of 10 to "
                  "40 variables only.")
    if random:
        texts += _random_texts()
    peers = ["omega"] + (["slugs"] if slugs else [])
    log = None if log_path is None else log_path.open("w", encoding="utf-8")
    try:
        rows = measure(texts, timeout=timeout, slugs=slugs, log=log)
    finally:
        if log is not None:
            log.close()
    return report(rows, timeout=timeout, peers=peers, notes=notes, source=source)


def main(out_dir: Path) -> str:
    """The ``python -m benchmarks`` entry point (configured by the environment)."""
    suites = [Path(p) for p in os.environ.get("TLI_GR1_SUITES", "").split(os.pathsep) if p]
    section = run(suites=suites, timeout=float(os.environ.get("TLI_GR1_TIMEOUT", "60")),
                  log_path=out_dir / "gr1_peers.jsonl")
    atomic_write_text(out_dir / "gr1_peers.md", section)
    return section


def _cli(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_gr1_peers",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--suites", nargs="*", type=Path, default=None)
    ap.add_argument("--timeout", type=float, default=None)
    ap.add_argument("--slugs", default=None, help="the slugs binary")
    ap.add_argument("--slugs-src", default=None, help="a slugs source tree to build")
    ap.add_argument("--no-random", action="store_true")
    ap.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results")
    ap.add_argument("--from-log", type=Path, default=None,
                    help="rebuild the table from a gr1_peers.jsonl of an earlier (possibly "
                         "interrupted) run instead of measuring")
    ap.add_argument("--note", action="append", default=[], help="a note for the table")
    args = ap.parse_args(argv)
    if args.from_log is not None:
        rows = []
        for line in args.from_log.read_text(encoding="utf-8").splitlines():
            rec = json.loads(line)
            rows.append(Row(name=rec.pop("name"), n_vars=rec.pop("n_vars"), results=rec))
        peers = [p for p in ("omega", "slugs") if rows and p in rows[0].results]
        section = report(rows, timeout=args.timeout or 60.0, peers=peers, notes=args.note,
                         source=f"Rebuilt from {args.from_log.name}: {len(rows)} specs.")
        atomic_write_text(args.out / "gr1_peers.md", section)
        sys.stdout.write(section)
        return 0
    suites = args.suites if args.suites is not None else [
        Path(p) for p in os.environ.get("TLI_GR1_SUITES", "").split(os.pathsep) if p]
    timeout = args.timeout or float(os.environ.get("TLI_GR1_TIMEOUT", "60"))
    section = run(suites=suites, timeout=timeout, slugs_binary=args.slugs,
                  slugs_source=args.slugs_src, random=not args.no_random,
                  log_path=args.out / "gr1_peers.jsonl")
    atomic_write_text(args.out / "gr1_peers.md", section)
    sys.stdout.write(section)
    return 0


if __name__ == "__main__":
    raise SystemExit(_cli())
