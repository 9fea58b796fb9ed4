"""The hand-off step's geometry (:mod:`tli_verify.runtime.handoff`): the cut for an exit across
a region's boundary is the supporting plane of the shape crossed, and only when it keeps the
attractor strictly inside."""

from __future__ import annotations

import numpy as np
import pytest

from tli_verify.runtime import handoff
from tli_verify.tasks.regions import Ball, Box, Ellipsoid, Polytope


@pytest.mark.parametrize("dim", [2, 3, 5])
def test_box_face_is_the_plane_crossed(dim: int) -> None:
    box = Box(lower=-np.ones(dim), upper=np.ones(dim))
    y = np.zeros(dim)
    y[1] = 1.0
    n, p = handoff._support(box, y)
    assert np.allclose(n, np.eye(dim)[1]) and np.isclose(p[1], 1.0)


def test_polytope_ball_ellipsoid_normals_are_outward_and_on_the_boundary() -> None:
    rng = np.random.default_rng(0)
    A = rng.normal(size=(7, 3))
    poly = Polytope(A=A, b=np.ones(7))
    ball = Ball(center=np.array([0.5, 0.0, 0.0]), radius=0.7)
    M = np.diag([4.0, 1.0, 9.0])
    ell = Ellipsoid(center=np.zeros(3), matrix=M)
    for shape in (poly, ball, ell):
        for _ in range(20):
            d = rng.normal(size=3)
            a = np.array(shape.center) if isinstance(shape, Ball | Ellipsoid) else np.zeros(3)
            b = a + 10.0 * d
            y = handoff._crossing(shape, a, b)
            n, p = handoff._support(shape, y)
            assert abs(np.linalg.norm(n) - 1.0) < 1e-12
            assert np.linalg.norm(p - y) < 1e-6  # the plane passes the crossing point
            assert float(n @ (b - y)) > 0.0  # outward: towards the outside point
            # the shape lies on the inner side of its supporting plane (convexity)
            X = rng.uniform(-2, 2, size=(4000, 3))
            X = X[shape.contains(X)]
            assert np.all((X - p) @ n <= 1e-9)


def test_plane_beyond_the_attractor_is_not_a_cut() -> None:
    from tli_verify.tasks.taskfile import parse_task

    task = parse_task("""
name = "t"
[state]
lower = [-1.0, -1.0]
upper = [1.0, 1.0]
[regions.zone]
box = { lower = [0.0, -0.2], upper = [0.4, 0.2] }
[sensors]
z = "zone"
""")
    last = np.array([-0.05, 0.0])
    out = np.array([0.05, 0.0])  # entering the zone across its face x = 0
    keep_out = handoff._face_cut(task, [np.array([-0.5, 0.0])], last, out, [])
    assert keep_out is not None
    cut, name = keep_out
    assert name == "zone" and np.allclose(cut.normal, [1.0, 0.0])
    assert float(cut.normal @ (np.array([-0.5, 0.0]) - cut.point)) < 0.0
    # the attractor beyond that face: no face cut (the QCQP's turn)
    assert handoff._face_cut(task, [np.array([0.3, 0.0])], last, out, []) is None
