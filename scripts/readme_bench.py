"""Copy the latest ``make bench`` tables (benchmarks/results/RESULTS.md) into the README.

Replaces everything between ``## Benchmarks`` and the next ``## `` heading of README.md with a
short introduction and the sections of RESULTS.md (their ``##`` headings demoted to ``###``).
Run after ``make bench``: ``.venv/bin/python scripts/readme_bench.py``.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
INTRO = ("`make bench` runs every `benchmarks/bench_*.py` side by side against its named "
         "baseline in one run and writes `benchmarks/results/RESULTS.md`; "
         "`scripts/readme_bench.py` copies it here. Latest tables (2 cores, medians; timings "
         "were taken on a shared, loaded machine and vary by up to about 2x):\n")


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from tli_verify.io import atomic_write_text

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    results = (ROOT / "benchmarks" / "results" / "RESULTS.md").read_text(encoding="utf-8")
    body = re.sub(r"^# Benchmark results\n+", "", results)
    body = re.sub(r"^## ", "### ", body, flags=re.MULTILINE)
    start = readme.index("\n## Benchmarks\n")
    end = readme.index("\n## ", start + 5)
    new = readme[:start] + "\n## Benchmarks\n\n" + INTRO + "\n" + body.rstrip() + "\n" \
        + readme[end:]
    atomic_write_text(ROOT / "README.md", new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
