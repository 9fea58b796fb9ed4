"""The picture of a pose task in the docs (``docs/img/pose_task_run.png``).

Writes the 6-D "pour" task of ``tests/integration/test_pose_task_cli.py`` into a temporary
project, then runs what a user runs: ``tli demos``, ``tli learn`` (with the offline hand-off
step), ``tli certify`` and ``tli run`` with a seeded random push; the run's picture (position
pairs with the tool axis as arrows, then the orientation pairs) is copied into the docs::

    .venv/bin/python scripts/pose_task_picture.py [OUT.png]
"""

from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

from tli_verify.cli import main

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the checkout: its tests
from tests.integration.test_pose_task_cli import SPEC, TASK


def run(*argv: str) -> None:
    """One ``tli`` command; stop on failure."""
    code = main(list(argv))
    if code != 0:
        raise SystemExit(f"tli {' '.join(argv)}: exit {code}")


def picture(out: Path) -> None:
    """Make the project, learn, certify, run; copy the run's picture to ``out``."""
    with tempfile.TemporaryDirectory(prefix="tli-pose-") as tmp:
        root = Path(tmp)
        for sub in ("tasks", "specs", "models", "certificates", "demos"):
            (root / sub).mkdir()
        (root / "tasks" / "pour.toml").write_text(TASK, encoding="utf-8")
        (root / "specs" / "pour.toml").write_text(SPEC, encoding="utf-8")
        run("demos", str(root / "tasks" / "pour.toml"), "--out", str(root / "demos"))
        model = root / "models" / "pour.model.json"
        run("learn", *sorted(str(p) for p in (root / "demos").glob("*.csv")), "--spec",
            str(root / "specs" / "pour.toml"), "-o", str(model))
        run("certify", str(model))
        run("run", "--model", str(model), "--perturb", "random:2", "--seed", "3", "--out",
            str(root / "run"))
        shutil.copyfile(root / "run" / "run.png", out)
    print(f"wrote {out}")


if __name__ == "__main__":
    picture(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/img/pose_task_run.png"))
