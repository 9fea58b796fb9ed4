"""Interleaved GR(1) timings on a few specs: ours (and a baseline checkout's) vs omega and slugs.

Usage::

    python -m benchmarks.gr1_subset FILE... [--reps N] [--slugs PATH] [--timeout S]
                                    [--baseline DIR] [--log OUT.jsonl]

A quick check of issue 22's targets on a subset instead of the whole suite
(:mod:`benchmarks.gr1_suite_verdicts` takes about an hour). ``FILE`` is a suite file
(``.spectra``, ``.structuredslugs``, ``.slugsin``, imported as ``tli spec import`` does) or an
imported ``.toml``. Each of ``--reps`` rounds decides every spec with every tool in turn, in the
textbook reading, each as :mod:`benchmarks.bench_gr1_peers` times it (its own forked process,
the median of up to 3 runs while a run takes under 1 s; slugs the whole process on the same
formulas): ours, the baseline's ours when ``--baseline`` names another checkout (run with
``PYTHONPATH`` set to it, e.g. a ``git archive`` of ``main``), omega, slugs (when a binary is
found, see :func:`benchmarks.bench_gr1_peers.find_slugs`). Interleaving keeps a busy machine's
noise out of the ratios. Prints per spec the medians over the rounds and ours / the faster
peer (where that peer needs more than 0.1 s), and the median fixed cost (parse + build).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Any

from benchmarks.bench_gr1_peers import MIN_PEER, _in_process, _slugs, find_slugs

_BASELINE = """\
import json, sys
from benchmarks.bench_gr1_peers import _in_process
text = sys.stdin.read()
print(json.dumps(_in_process("ours", text, float(sys.argv[1]), semantics="textbook")))
"""


def _text(path: Path) -> str:
    if path.suffix == ".toml":
        return path.read_text(encoding="utf-8")
    from tli_verify.logic.foreign import import_spec_file

    return str(import_spec_file(path))


def _baseline(checkout: Path, text: str, timeout: float) -> dict[str, Any]:
    """Ours as ``checkout``'s code decides ``text`` (its own ``bench_gr1_peers`` timing)."""
    env = dict(os.environ, PYTHONPATH=str(checkout))
    done = subprocess.run([sys.executable, "-c", _BASELINE, str(timeout)], input=text,
                          capture_output=True, text=True, cwd=checkout, env=env, check=False,
                          timeout=3 * timeout + 60)
    lines = done.stdout.strip().splitlines()
    if done.returncode != 0 or not lines:
        return {"timeout": False, "error": " ".join(done.stderr.split()[-12:])}
    out: dict[str, Any] = json.loads(lines[-1])
    return out


def measure(files: list[Path], *, reps: int, timeout: float, slugs: str | None,
            baseline: Path | None, log: Any = None) -> list[dict[str, Any]]:
    """Every tool on every spec, ``reps`` interleaved rounds; one record per run."""
    texts = [(p.name, _text(p)) for p in files]
    records = []
    for rep in range(reps):
        for name, text in texts:
            runs: dict[str, dict[str, Any]] = {
                "ours": _in_process("ours", text, timeout, semantics="textbook")}
            if baseline is not None:
                runs["baseline"] = _baseline(baseline, text, timeout)
            runs["omega"] = _in_process("omega", text, timeout, semantics="textbook")
            if slugs is not None:
                runs["slugs"] = _slugs(slugs, text, timeout)
            for tool, result in runs.items():
                record = {"spec": name, "tool": tool, "rep": rep, **result}
                records.append(record)
                if log is not None:
                    log.write(json.dumps(record) + "\n")
                    log.flush()
    return records


def summary(records: list[dict[str, Any]], timeout: float) -> str:
    """Per-spec medians, ratios to the faster peer and the median fixed cost, as text."""
    tools = list(dict.fromkeys(r["tool"] for r in records))
    specs = list(dict.fromkeys(r["spec"] for r in records))

    def med(spec: str, tool: str, key: str = "total") -> float | None:
        vals = [timeout if r.get("timeout") else r[key] for r in records
                if r["spec"] == spec and r["tool"] == tool and (key in r or r.get("timeout"))]
        return statistics.median(vals) if vals else None

    lines = ["spec | " + " | ".join(tools) + " | ours / faster peer"
             + (" | baseline / faster peer" if "baseline" in tools else "")]
    fixed: dict[str, list[float]] = {t: [] for t in ("ours", "baseline") if t in tools}
    for spec in specs:
        times = {t: med(spec, t) for t in tools}
        peers = [v for t, v in times.items() if t in ("omega", "slugs") and v is not None]
        best = min(peers) if peers else None
        cells = [f"{v:.3f}" if v is not None else "-" for v in times.values()]
        for t in fixed:
            parse, build = med(spec, t, "parse"), med(spec, t, "build")
            if parse is not None and build is not None:
                fixed[t].append(parse + build)
        ratios = [f"{times[t] / best:.2f}x" if best and best > MIN_PEER and times[t] else "-"
                  for t in ("ours", "baseline") if t in tools]
        lines.append(f"{spec} | " + " | ".join(cells) + " | " + " | ".join(ratios))
    for t, vals in fixed.items():
        if vals:
            lines.append(f"{t}: median fixed cost (parse + build) "
                         f"{statistics.median(vals) * 1000:.1f} ms over {len(vals)} specs")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+", type=Path)
    parser.add_argument("--reps", type=int, default=3)
    parser.add_argument("--timeout", type=float, default=60.0)
    parser.add_argument("--slugs", default=None, help="slugs binary (see find_slugs)")
    parser.add_argument("--baseline", type=Path, default=None,
                        help="another checkout whose tli_verify to time as well")
    parser.add_argument("--log", type=Path, default=None, help="append the runs (JSON lines)")
    args = parser.parse_args(argv)
    slugs, note = find_slugs(args.slugs)
    print(note, file=sys.stderr)
    log = args.log.open("a", encoding="utf-8") if args.log else None
    try:
        records = measure(args.files, reps=args.reps, timeout=args.timeout, slugs=slugs,
                          baseline=args.baseline, log=log)
    finally:
        if log is not None:
            log.close()
    print(summary(records, args.timeout))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
