"""Regenerate the bundled demonstrations of the paper's worlds (seeded) and their pictures.

Usage: ``.venv/bin/python scripts/make_demos.py [--world scoop|cooking|color-tracing|inspection|all]
[--seed 0] [--n N] [--out demos] [--img docs/img]``.
Writes ``<out>/<world>_<i>.csv`` (:mod:`tli_verify.worlds`) and ``<img>/worlds_<world>.png``
(the true regions with the demonstrations). Then relearn and recertify the deployed scoop
model::

    tli learn demos/scoop_*.csv --spec specs/scoop.toml -o models/scoop.model.json --seed 0 \\
        --control-dt 0.01
    tli certify models/scoop.model.json --dt 0.01
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tli_verify.worlds import WORLDS
from tli_verify.worlds.base import plot_world, write_demos


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="make_demos.py")
    parser.add_argument("--world", choices=[*WORLDS, "all"], default="all")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n", type=int, default=None, help="demonstrations per world "
                        "(default: the world's own)")
    parser.add_argument("--out", type=Path, default=Path("demos"))
    parser.add_argument("--img", type=Path, default=Path("docs/img"),
                        help="where worlds_<name>.png goes ('-': no picture)")
    args = parser.parse_args(argv)
    names = list(WORLDS) if args.world == "all" else [args.world]
    for name in names:
        world = WORLDS[name]()
        paths = write_demos(world, args.out, seed=args.seed, n_demos=args.n, prefix=name)
        for path in paths:
            sys.stdout.write(f"wrote {path}\n")
        if str(args.img) != "-":
            picture = args.img / f"worlds_{name}.png"
            plot_world(world, picture, demos=world.demonstrate(args.seed, args.n))
            sys.stdout.write(f"wrote {picture}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
