"""Regenerate the bundled soup-scooping demonstrations ``demos/scoop_*.csv`` (seeded).

Usage: ``.venv/bin/python scripts/make_demos.py [--seed 0] [--n 3] [--out demos]``.
Then relearn and recertify the deployed model::

    tli learn demos/scoop_*.csv --spec specs/scoop.toml -o models/scoop.model.json
    tli certify models/scoop.model.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tli_verify.demos import write_scoop_demos


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="make_demos.py")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("demos"))
    args = parser.parse_args(argv)
    for path in write_scoop_demos(args.out, seed=args.seed, n_demos=args.n):
        sys.stdout.write(f"wrote {path}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
