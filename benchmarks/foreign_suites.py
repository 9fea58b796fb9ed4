"""Import the field's GR(1) suites (Spectra, slugs) and compare verdicts with omega.

Usage::

    python -m benchmarks.foreign_suites DIR... [--timeout S] [--omega-max-bits N]

Every ``*.spectra``, ``*.structuredslugs`` and ``*.slugsin`` file under the given folders
(e.g. a checkout of ``SpectraSynthesizer/spectra-specs`` and slugs' ``examples/``) is imported
with ``tli spec import``'s translation; refused files are counted by reason (the first words
of the error). Imported specs are decided in both readings (``tli``, ``textbook``) by our
solver and by omega given the same formulas, each in its own process with a time limit.
A folder that does not exist is skipped with a note; nothing here is a test input.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import io
import multiprocessing as mp
import re
import sys
import time
from pathlib import Path
from typing import Any

from tli_verify.errors import SpecError
from tli_verify.logic.foreign import FORMATS, import_spec_file


def last_message(target: Any, args: tuple[Any, ...], timeout: float) -> Any:
    """Run ``target(*args, queue)`` in a forked process for at most ``timeout`` seconds (then
    killed) and return the last message it put on the queue, or None if it put none."""
    ctx = mp.get_context("fork")
    q: Any = ctx.Queue()
    proc = ctx.Process(target=target, args=(*args, q))
    proc.start()
    proc.join(timeout)
    if proc.is_alive():
        proc.kill()
        proc.join()
    last = None
    while not q.empty():
        last = q.get()
    return last


def _reason(msg: str) -> str:
    text = re.sub(r"^\S+?:(\d+:)? ", "", msg)
    text = re.sub(r"'[^']*'", "'_'", text)
    return " ".join(text.split()[:7])


def _decide(text: str, out: mp.Queue) -> None:  # type: ignore[type-arg]
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests.support.omega_oracle import omega_realizable
    from tli_verify.logic.gr1 import build_game, solve
    from tli_verify.logic.spec import parse_spec

    try:
        spec = parse_spec(text, path="imported.toml")
    except SpecError as exc:
        out.put(("load-error", _reason(str(exc))))
        return
    res = {}
    for sem in ("tli", "textbook"):
        t0 = time.perf_counter()
        ours = solve(build_game(spec, semantics=sem), keep_iterates=False).realizable
        t1 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            theirs = omega_realizable(spec, semantics=sem)
        t2 = time.perf_counter()
        res[sem] = (ours, theirs, t1 - t0, t2 - t1)
        out.put(("partial", res.copy()))
    out.put(("done", res))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", type=Path)
    ap.add_argument("--timeout", type=float, default=30.0)
    ap.add_argument("--limit", type=int, default=0, help="decide at most this many specs")
    ap.add_argument("--each", action="store_true",
                    help="one line per decided spec (verdicts so far survive an interruption)")
    args = ap.parse_args(argv)
    files: list[Path] = []
    for d in args.dirs:
        if not d.is_dir():
            print(f"note: {d} not found, skipped (fetch the suite to measure it)")
            continue
        files += sorted(p for p in d.rglob("*") if p.suffix in FORMATS and p.is_file())
    if not files:
        print("note: no suite files found; nothing measured")
        return 0
    refused: collections.Counter[str] = collections.Counter()
    imported: list[tuple[Path, str]] = []
    by_fmt: collections.Counter[str] = collections.Counter()
    for p in files:
        by_fmt[FORMATS[p.suffix]] += 1
        try:
            imported.append((p, import_spec_file(p)))
        except SpecError as exc:
            refused[_reason(str(exc))] += 1
    print(f"files: {len(files)} ({dict(by_fmt)}); imported {len(imported)}, refused "
          f"{sum(refused.values())}")
    for reason, n in refused.most_common():
        print(f"  refused {n:4d}: {reason}")
    todo = imported[: args.limit] if args.limit else imported
    agree = {s: [0, 0] for s in ("tli", "textbook")}  # agree, decided
    differ_readings = 0
    timeouts = 0
    load_errors: collections.Counter[str] = collections.Counter()
    for k, (p, text) in enumerate(todo, start=1):
        last = last_message(_decide, (text,), args.timeout)
        if last is None or last[0] == "partial":
            timeouts += 1
            res = last[1] if last else {}
        elif last[0] == "load-error":
            load_errors[last[1]] += 1
            continue
        else:
            res = last[1]
        if args.each:
            got = ", ".join(f"{s} {'R' if o else 'U'}/{'R' if t else 'U'}"
                            for s, (o, t, _, _) in res.items())
            print(f"  [{k}/{len(todo)}] {p}: {got or 'time-out'} (ours/omega)", flush=True)
        for sem, (ours, theirs, _, _) in res.items():
            agree[sem][1] += 1
            agree[sem][0] += ours == theirs
            if ours != theirs:
                print(f"  DISAGREE ({sem}): {p}")
        if len(res) == 2 and res["tli"][0] != res["textbook"][0]:
            differ_readings += 1
            print(f"  readings differ: {p}: tli {res['tli'][0]}, textbook {res['textbook'][0]}")
    for reason, n in load_errors.most_common():
        print(f"  imported but not loadable {n:4d}: {reason}")
    for sem, (a, n) in agree.items():
        print(f"verdicts ({sem}): agree with omega on {a} of {n} decided")
    print(f"readings differ on {differ_readings}; time-outs ({args.timeout:g} s): {timeouts}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
