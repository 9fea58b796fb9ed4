"""Run every ``benchmarks/bench_*.py`` and collect their Markdown tables.

Each benchmark module exposes ``main(out_dir: Path) -> str`` that runs its side-by-side
comparison, writes its own files under ``out_dir`` (at least ``<name>.md``) and returns a
Markdown section. This runner then writes ``out_dir/RESULTS.md`` from every section file in
``out_dir``, so ``--only`` refreshes some sections and keeps the others.

Usage: ``python -m benchmarks [--out DIR] [--only NAME ...]``.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import platform
import sys
import time
from pathlib import Path

from tli_verify.io import atomic_write_text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results"))
    parser.add_argument("--only", nargs="*", default=None, help="benchmark names (e.g. gr1)")
    args = parser.parse_args(argv)
    here = Path(__file__).resolve().parent
    names = sorted(
        m.name for m in pkgutil.iter_modules([str(here)]) if m.name.startswith("bench_")
    )
    if args.only:
        names = [n for n in names if n.removeprefix("bench_") in args.only]
    args.out.mkdir(parents=True, exist_ok=True)
    sections = [
        "# Benchmark results\n",
        f"Machine: {platform.machine()}, Python {platform.python_version()}, "
        f"written {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} by `make bench`.\n",
    ]
    for name in names:
        sys.stdout.write(f"== {name}\n")
        sys.stdout.flush()
        module = importlib.import_module(f"benchmarks.{name}")
        section = module.main(args.out)
        atomic_write_text(args.out / f"{name.removeprefix('bench_')}.md", section.rstrip() + "\n")
        sys.stdout.write(section + "\n")
    for path in sorted(args.out.glob("*.md")):
        if path.name != "RESULTS.md":
            sections.append(path.read_text(encoding="utf-8"))
    atomic_write_text(args.out / "RESULTS.md", "\n".join(sections))
    return 0


if __name__ == "__main__":
    sys.exit(main())
