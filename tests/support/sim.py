"""Shared helpers for the MuJoCo tests: the Panda, skipped cleanly without assets."""

from __future__ import annotations

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
