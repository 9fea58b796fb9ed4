"""Regenerate the bundled demonstrations of the paper's tasks (seeded) and their pictures.

Usage: ``.venv/bin/python scripts/make_demos.py [--task scoop|cooking|color-tracing|inspection|all]
[--seed 0] [--n N] [--out demos] [--img docs/img]``: for each bundled task, the same as
``tli demos TASK --out demos --seed 0 --picture docs/img/task_TASK.png``. The scoop and
inspection demonstrators reproduce the shipped CSVs bit for bit; cooking's detour script and the
color-tracing scripts draw other noise than the recorded files (see the task files). Then
relearn and recertify, e.g. for scoop::

    tli learn demos/scoop_*.csv --spec specs/scoop.toml -o models/scoop.model.json --seed 0
    tli certify models/scoop.model.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tli_verify.cli import main as tli
from tli_verify.tasks.registry import bundled_tasks


def main(argv: list[str] | None = None) -> int:
    names = sorted(bundled_tasks())
    parser = argparse.ArgumentParser(prog="make_demos.py")
    parser.add_argument("--task", choices=[*names, "all"], default="all")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n", type=int, default=None, help="demonstrations per task "
                        "(default: the task's own)")
    parser.add_argument("--out", type=Path, default=Path("demos"))
    parser.add_argument("--img", type=Path, default=Path("docs/img"),
                        help="where task_<name>.png goes ('-': no picture)")
    args = parser.parse_args(argv)
    for name in names if args.task == "all" else [args.task]:
        cmd = ["demos", name, "--out", str(args.out), "--seed", str(args.seed)]
        if args.n is not None:
            cmd += ["--count", str(args.n)]
        if str(args.img) != "-":
            cmd += ["--picture", str(args.img / f"task_{name}.png")]
        code = tli(cmd)
        if code:
            return code
    return 0


if __name__ == "__main__":
    sys.exit(main())
