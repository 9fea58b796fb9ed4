"""The single-mode study's tasks (tli_verify.tasks.generate): random convex modes and
synthetic demonstrations (paper appendix E), a mode being a polytope region of a task."""

from __future__ import annotations

import numpy as np
import pytest

from tli_verify.errors import ModelError
from tli_verify.tasks.generate import ConvexMode, make_task, polygon_task, random_convex_mode
from tli_verify.tasks.regions import Polytope
from tli_verify.tasks.task import Task


def test_convex_mode_sensor() -> None:
    mode = ConvexMode.from_vertices([[0, 0], [2, 0], [2, 1], [0, 1]])
    X = np.array([[1.0, 0.5], [2.0, 0.5], [2.1, 0.5], [-0.1, 0.0]])
    np.testing.assert_array_equal(mode.contains(X), [True, True, False, False])
    np.testing.assert_allclose(mode.margin(X), [0.5, 0.0, -0.1, -0.1])
    assert isinstance(mode, Polytope)  # a task region
    assert [mode.contains_one(x) for x in X.tolist()] == [True, True, False, False]
    task = polygon_task(mode, 3.0)  # the mode as region "mode", read by the sensor "inside"
    assert isinstance(task, Task)
    assert task.region_names == ("mode", "outside") and task.sensor_names == ("inside",)
    assert (task.lo, task.hi) == ((0.0, 0.0), (3.0, 3.0))
    in_box = task.in_workspace(X)
    np.testing.assert_array_equal(in_box, [True, True, True, False])
    np.testing.assert_array_equal(task.sensors(X[in_box])[:, 0], [True, True, False])
    with pytest.raises(ModelError, match="convex"):
        ConvexMode.from_vertices([[0, 0], [2, 0], [1, 0.2], [2, 1], [0, 1]])
    with pytest.raises(ModelError, match="convex"):
        ConvexMode.from_vertices([[0, 0], [0, 1], [2, 1], [2, 0]])  # clockwise


@pytest.mark.parametrize("seed", range(8))
def test_random_task(seed: int) -> None:
    task = make_task(np.random.default_rng(seed))
    mode = task.mode
    V = mode.vertices
    assert np.all((V >= 0) & (V <= task.workspace))
    assert np.all(mode.b - mode.vertices @ mode.A.T >= -1e-9)  # vertices in all half-planes
    assert 1 <= len(task.demos) <= 3
    assert mode.margin(task.attractor[None])[0] > 0
    for d in task.demos:
        assert d.X.shape == (200, 2) and d.Xdot.shape == (200, 2)
        assert mode.contains(d.X).all()
        np.testing.assert_array_equal(d.X[-1], task.attractor)
        assert np.linalg.norm(d.Xdot[0]) < 1e-9 and np.linalg.norm(d.Xdot[-1]) == 0.0
        # velocities integrate to the path (trapezoid rule on the min-jerk timing)
        steps = np.linalg.norm(np.diff(d.X, axis=0), axis=1)
        assert np.all(steps < 0.5)
    assert task.states.shape == (200 * len(task.demos), 2)
    # the task of the mode: region "mode" is the polygon, the sensor "inside" reads it
    mode_task = task.task
    assert isinstance(mode_task, Task)
    assert mode_task.region_names == ("mode", "outside") and mode_task.sensor_names == ("inside",)
    assert (mode_task.lo, mode_task.hi) == ((0.0, 0.0), (task.workspace, task.workspace))
    X = np.concatenate([task.states,
                        np.random.default_rng(seed).uniform(0, task.workspace, (500, 2))])
    inside = mode.contains(X)
    assert inside.any() and not inside.all()
    np.testing.assert_array_equal(mode_task.in_region("mode", X), inside)
    np.testing.assert_array_equal(mode_task.sensors(X)[:, 0], inside)
    assert mode_task.sensors(task.demos[0].X).all()  # a demonstration never leaves the mode


def test_seeded_and_inside_sampling() -> None:
    a = make_task(np.random.default_rng(5))
    b = make_task(np.random.default_rng(5))
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.mode.vertices, b.mode.vertices)
    mode = random_convex_mode(np.random.default_rng(1))
    S = mode.sample_inside(np.random.default_rng(2), 500, min_margin=1.0)
    assert S.shape == (500, 2) and np.all(mode.margin(S) >= 1.0)
    with pytest.raises(ModelError):
        mode.sample_inside(np.random.default_rng(2), 5, min_margin=1e3)
