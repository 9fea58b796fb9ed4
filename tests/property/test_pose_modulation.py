"""Thm. 1 on the pose (issue 35, item 4): a certified pose DS -- a position LPV-DS and an
orientation LPV-DS in the tangent chart at ``q*``, each spun out of its regions by skew parts --
with random cuts in both parts (position planes, orientation planes in the chart, cone cuts of
a "tilted at most theta" constraint), random starts inside every cut over the whole chart and
workspace: no Euler step at the control period leaves a cut, in position or in orientation,
and the pose converges to ``(x*, q*)``. Orientation failures become cuts in the chart and the
modulated flow then keeps them. Checked with hypothesis (derandomized in CI)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.boundary.cuts import Cut
from tli_verify.ds.lpvds import LPVDS
from tli_verify.ds.quaternion import QuaternionDS, quat_exp, quat_log
from tli_verify.model.pose import PoseDS, cone_cut, tilt

DT = 0.01
TOOL, UP = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0])


def _lpvds(rng: np.random.Generator, attractor: np.ndarray, spin: float, K: int = 3) -> LPVDS:
    n = attractor.size
    M = rng.normal(size=(n, n))
    P = M @ M.T / n + np.eye(n)
    P = 0.5 * (P + P.T)
    Pinv = np.linalg.inv(P)
    A, means, covs = [], [], []
    for _ in range(K):
        S = rng.normal(scale=spin, size=(n, n))
        A.append(Pinv @ (-np.eye(n) + (S - S.T)))  # A^T P + P A = -2 I
        means.append(attractor + rng.normal(scale=0.5, size=n))
        B = rng.normal(size=(n, n))
        covs.append(B @ B.T / n * 0.2 + 0.05 * np.eye(n))
    return LPVDS(attractor=attractor, priors=np.full(K, 1.0 / K), means=np.array(means),
                 covs=np.array(covs), A=np.array(A), P=P)


def _pose(seed: int) -> PoseDS:
    rng = np.random.default_rng(seed)
    position = _lpvds(rng, rng.normal(size=3), spin=2.0)
    q_star = np.r_[1.0, 0.0, 0.0, 0.0]
    orientation = QuaternionDS(attractor=q_star, tangent=_lpvds(rng, np.zeros(3), spin=2.0))
    return PoseDS(position, orientation, dt=DT)


def _planes(rng: np.random.Generator, center: np.ndarray, count: int, lo: float,
            hi: float) -> tuple[Cut, ...]:
    out = []
    for _ in range(count):
        w = rng.normal(size=center.size)
        w /= np.linalg.norm(w)
        out.append(Cut(normal=w, point=center + rng.uniform(lo, hi) * w))
    return tuple(out)


def _inside(cuts: tuple[Cut, ...], X: np.ndarray) -> np.ndarray:
    if not cuts:
        return np.full(len(X), -np.inf)
    W = np.array([c.normal for c in cuts])
    b = np.array([c.normal @ c.point for c in cuts])
    return np.max(X @ W.T - b, axis=1)  # <= 0 inside every cut


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n_pos=st.integers(0, 4), n_ori=st.integers(0, 4))
def test_no_step_leaves_a_cut_in_position_or_orientation(seed: int, n_pos: int,
                                                         n_ori: int) -> None:
    rng = np.random.default_rng(seed)
    base = _pose(seed)
    pose = PoseDS(base.position, base.orientation,
                  _planes(rng, base.position.attractor, n_pos, 0.2, 1.0),
                  _planes(rng, np.zeros(3), n_ori, 0.2, 1.0), dt=DT)
    # starts: anywhere inside the cuts, orientations up to 0.9 pi from q* (the whole chart)
    X = base.position.attractor + rng.uniform(-2.0, 2.0, size=(400, 3))
    Xi = rng.normal(size=(400, 3))
    Xi *= (rng.uniform(0.0, 0.9 * np.pi, size=400) / np.linalg.norm(Xi, axis=1))[:, None]
    keep = (_inside(pose.position_cuts, X) < 0) & (_inside(pose.orientation_cuts, Xi) < 0)
    X, Q = X[keep][:20], quat_exp(Xi[keep][:20], pose.orientation.attractor)
    if len(X) == 0:
        return

    def energy(X: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (base.position.lyapunov(X),
                base.orientation.tangent.lyapunov(quat_log(Q, pose.orientation.attractor)))

    v0 = energy(X, Q)
    for _ in range(500):
        X, Q = pose.step(X, Q, DT)
        xi = quat_log(Q, pose.orientation.attractor)
        assert np.all(_inside(pose.position_cuts, X) <= 1e-9)
        assert np.all(_inside(pose.orientation_cuts, xi) <= 1e-9)
    # converging in both parts: each Lyapunov function well down after 5 s
    for start, end in zip(v0, energy(X, Q), strict=True):
        assert np.all(end <= 0.5 * start + 1e-12), (start, end)


def test_an_orientation_failure_becomes_a_cut_the_flow_then_keeps() -> None:
    """The tool must stay within 15 degrees of vertical; the unmodulated orientation DS tilts it
    out; the failure's cut (the QCQP in the chart) and the cone's supporting plane stop it."""
    limit = np.radians(15.0)
    found = None
    for seed in range(40):  # a pose DS and an allowed start whose nominal flow tilts out
        pose = _pose(seed)
        q_star = pose.orientation.attractor
        rng = np.random.default_rng(seed)
        for _ in range(50):
            xi = rng.normal(size=3)
            xi *= rng.uniform(0.05, 0.5) / np.linalg.norm(xi)
            q = quat_exp(xi, q_star)
            if tilt(q, TOOL, UP) >= limit:
                continue
            traj = pose.orientation.rollout(q, dt=DT, steps=400)
            out = np.flatnonzero(tilt(traj, TOOL, UP) >= limit)
            if out.size:
                found = (traj[0], traj[out[0] - 1], traj[out[0]])
                break
        if found is not None:
            break
    assert found is not None, "the test's DS never tilts out: no failure to cut"
    entry, last, outside = found
    cut_pose = pose.cut_orientation(entry, last, outside)
    cone_pose = pose.with_orientation_cut(cone_cut(last, q_star, TOOL, UP))
    for p in (cut_pose, cone_pose):
        X, Q = np.zeros((1, 3)) + p.position.attractor, entry[None, :]
        for _ in range(1500):
            X, Q = p.step(X, Q, DT)
            assert np.all(_inside(p.orientation_cuts, quat_log(Q, q_star)) <= 1e-9)
        assert float(np.linalg.norm(quat_log(Q, q_star))) < 1e-2
    # the cone cut keeps this entry's flow within the cone (it supports the cone at the exit)
    X, Q = np.zeros((1, 3)) + cone_pose.position.attractor, entry[None, :]
    worst = 0.0
    for _ in range(1500):
        X, Q = cone_pose.step(X, Q, DT)
        worst = max(worst, float(tilt(Q, TOOL, UP)[0]))
    assert worst <= limit + 1e-6, np.degrees(worst)


def test_a_cut_that_leaves_q_star_outside_is_refused() -> None:
    pose = _pose(1)
    w = np.array([1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="outside"):
        pose.with_orientation_cut(Cut(normal=w, point=-0.3 * w))
