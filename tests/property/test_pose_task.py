"""Pose tasks (issue 35, item 5): the orientation chart and the cone region's signed distance.

The cone's signed distance is a bound, not the exact distance: ``tilt(v) - theta``. The oracle's
certified deadline needs only that a ball of that radius around a state meets no boundary of
the cone, which holds when ``tilt`` is 1-Lipschitz in the state (``tli_verify.tasks.orientation``
states why). Both are checked here on random charts, cones and states, against the exact
membership, and the chart's round trip against the quaternion maps.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.rotations import quat_multiply, tilt
from tli_verify.tasks.orientation import Cone, OrientationChart

FINITE = st.floats(-1.0, 1.0, allow_nan=False)


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-6 else np.array([0.0, 0.0, 1.0])


@st.composite
def cones(draw: st.DrawFn) -> Cone:
    raw = np.array(draw(st.lists(FINITE, min_size=4, max_size=4)), dtype=np.float64)
    norm = float(np.linalg.norm(raw))
    ref = raw / norm if norm > 1e-3 else np.array([1.0, 0.0, 0.0, 0.0])
    start = draw(st.integers(0, 2))
    chart = OrientationChart(start=start, reference=tuple(float(v) for v in ref))  # type: ignore[arg-type]
    axis = _unit(np.array(draw(st.lists(FINITE, min_size=3, max_size=3))))
    toward = _unit(np.array(draw(st.lists(FINITE, min_size=3, max_size=3))))
    within = math.radians(draw(st.floats(1.0, 179.0)))
    return Cone(dim=start + 4, chart=chart, axis=axis, toward=toward, within=within)


def _states(rng: np.random.Generator, cone: Cone, n: int, radius: float) -> np.ndarray:
    X = rng.uniform(-1.0, 1.0, size=(n, cone.dim))
    v = rng.normal(size=(n, 3))
    v *= (radius * rng.uniform(0, 1, size=(n, 1)) ** (1 / 3)) / np.linalg.norm(v, axis=1,
                                                                              keepdims=True)
    X[:, cone.chart.columns] = v
    return X


@settings(max_examples=60, deadline=None)
@given(cone=cones(), seed=st.integers(0, 2**32 - 1))
def test_the_tilt_is_one_lipschitz_in_the_state(cone: Cone, seed: int) -> None:
    rng = np.random.default_rng(seed)
    A = _states(rng, cone, 400, 0.99 * math.pi)
    B = A + rng.normal(scale=rng.choice([1e-3, 0.05, 0.5]), size=A.shape)
    gap = np.abs(cone.tilt(A) - cone.tilt(B))
    assert np.all(gap <= np.linalg.norm(A - B, axis=1) + 1e-9)
    # Rodrigues' closed form (what the loop reads) against the quaternions'
    ref = tilt(cone.chart.quaternions(A), cone.axis, cone.toward)
    np.testing.assert_allclose(cone.tilt(A), ref, atol=1e-7)
    ones = [cone.contains_one(x.tolist()) for x in A[:50]]
    assert ones == cone.contains(A[:50]).tolist()


@settings(max_examples=60, deadline=None)
@given(cone=cones(), seed=st.integers(0, 2**32 - 1))
def test_a_ball_of_the_signed_distance_meets_no_boundary(cone: Cone, seed: int) -> None:
    """Every state within |signed distance| of a state is on the same side of the cone."""
    rng = np.random.default_rng(seed)
    X = _states(rng, cone, 200, 0.99 * math.pi)
    d = cone.signed_distance(X)
    inside = cone.contains(X)
    assert np.array_equal(inside, d <= 0.0)
    for _ in range(5):
        u = rng.normal(size=X.shape)
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        Y = X + 0.999 * np.abs(d)[:, None] * rng.uniform(0, 1, size=(len(X), 1)) * u
        assert np.array_equal(cone.contains(Y), inside)


@settings(max_examples=40, deadline=None)
@given(cone=cones(), seed=st.integers(0, 2**32 - 1))
def test_the_chart_maps_states_and_orientations_both_ways(cone: Cone, seed: int) -> None:
    rng = np.random.default_rng(seed)
    chart = cone.chart
    X = _states(rng, cone, 100, 0.95 * math.pi)
    Q = chart.quaternions(X)
    np.testing.assert_allclose(np.linalg.norm(Q, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(chart.coordinates(Q), X[:, chart.columns], atol=1e-9)
    np.testing.assert_allclose(chart.coordinates(-Q), X[:, chart.columns], atol=1e-9)
    # the chart is at the reference: the zero coordinates are the reference's orientation,
    # and q(v) = q_ref (x) Exp(v)
    zero = np.zeros((1, cone.dim))
    q0 = chart.quaternions(zero)[0]
    assert abs(abs(float(q0 @ np.array(chart.reference))) - 1.0) < 1e-12
    v = X[0, chart.columns]
    th = float(np.linalg.norm(v))
    e = np.concatenate([[math.cos(th / 2)], math.sin(th / 2) * v / th])
    np.testing.assert_allclose(Q[0], quat_multiply(np.array(chart.reference), e), atol=1e-12)
