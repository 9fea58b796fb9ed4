"""StallRetry (tli_verify.sim.retry) on the bundled Franka scoop model."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mujoco")

from tli_verify.model.serialize import load_model
from tli_verify.sim.franka_project import project_dir
from tli_verify.sim.retry import StallRetry

DT = 0.02


@pytest.fixture(scope="module")
def model():  # type: ignore[no-untyped-def]
    return load_model(project_dir() / "models" / "franka-scoop.model.json")


def _steps(n: int) -> int:
    return round(n / DT)


def test_a_mode_at_rest_is_retried_from_the_mode_leading_into_it(model) -> None:  # type: ignore[no-untyped-def]
    retry = StallRetry(model, DT, stall_after=1.0)
    x = np.asarray(model.modes["b"].ds.attractor, dtype=float)  # parked at b's attractor
    outs = [retry.update("b", False, x, x) for _ in range(_steps(1.0) - 1)]
    assert all(o is None for o in outs) and not retry.active
    v = retry.update("b", False, x, x)  # the window is full: b stalled
    assert retry.active and retry.retries == 1
    np.testing.assert_allclose(v, model.modes["a"].velocity(x, dt=DT))  # a's DS leads into b
    # the retreat runs a's DS until its attractor is reached, then hands back
    y = x.copy()
    for _ in range(_steps(10.0)):
        v = retry.update("b", False, y, y)
        if v is None:
            break
        y = y + DT * v
    assert not retry.active
    assert float(np.max(np.abs(y - model.modes["a"].ds.attractor))) < 0.05 + 1e-9


def test_moving_goal_and_unpreceded_modes_are_not_retried(model) -> None:  # type: ignore[no-untyped-def]
    x = np.asarray(model.modes["b"].ds.attractor, dtype=float)
    moving = StallRetry(model, DT, stall_after=1.0)
    for k in range(_steps(3.0)):  # 3 dm/s along y: never put
        z = x + np.array([0.0, 0.06 * k, 0.0, 0.0])
        assert moving.update("b", False, z, z) is None
    goal = StallRetry(model, DT, stall_after=1.0)
    first = StallRetry(model, DT, stall_after=1.0)
    for _ in range(_steps(3.0)):
        assert goal.update("d", True, x, x) is None
        assert first.update("a", False, x, x) is None  # no DS leads into the initial mode
    assert moving.retries == goal.retries == first.retries == 0


def test_a_mode_change_resets_the_window(model) -> None:  # type: ignore[no-untyped-def]
    retry = StallRetry(model, DT, stall_after=1.0)
    x = np.asarray(model.modes["b"].ds.attractor, dtype=float)
    for k in range(_steps(3.0)):
        mode = "b" if (k // 25) % 2 == 0 else "c"  # changes every 0.5 s
        assert retry.update(mode, False, x, x) is None
    assert retry.retries == 0
