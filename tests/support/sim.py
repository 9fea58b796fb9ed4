"""Shared helpers for the MuJoCo tests: the Panda, skipped cleanly without assets."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest


def require_panda() -> Any:
    """The arm-only :class:`~tli_verify.sim.robot.Panda`; skips the test when mujoco is not
    installed or the Menagerie files are not fetched (``make sim-assets``)."""
    pytest.importorskip("mujoco")
    from tli_verify.errors import AssetError
    from tli_verify.sim.robot import load_panda

    try:
        return load_panda()
    except AssetError as exc:
        pytest.skip(f"Panda assets not fetched (run `make sim-assets`): {exc}")


def panda_with_beads(beads: int = 3) -> Any:
    """The arm-only Panda with ``beads`` free spheres in its model (free joints after the arm's,
    so the controller's index bookkeeping is exercised); skips like :func:`require_panda`."""
    require_panda()
    import mujoco

    from tli_verify.sim.robot import Panda, panda_spec

    spec = panda_spec()
    for i in range(beads):
        bead = spec.worldbody.add_body(name=f"bead{i}", pos=[0.5, 0.1 * i, 0.05])
        bead.add_freejoint()
        bead.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.008, 0, 0], mass=0.002)
    return Panda.from_model(spec.compile())


FRANKA_FILES = (("specs", "franka-scoop.toml"), ("tasks", "franka-scoop.toml"),
                ("models", "franka-scoop.model.json"),
                ("certificates", "franka-scoop.cert.json"))
"""The Franka project's files a copy needs: spec, task, model and certificate."""


def copy_franka_project(dest: Path) -> Path:
    """Copy the bundled Franka project's :data:`FRANKA_FILES` into ``dest``; returns ``dest``."""
    from tli_verify.io import bundled_dir

    src = bundled_dir("sim") / "franka"
    for sub, name in FRANKA_FILES:
        (dest / sub).mkdir(exist_ok=True)
        shutil.copy(src / sub / name, dest / sub / name)
    return dest
