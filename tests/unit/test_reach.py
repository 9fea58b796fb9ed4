"""Certified reachability deadlines: the certificate's rate predicts the rollout (Thm. 1 (c))."""

from __future__ import annotations

import control
import numpy as np
import pytest

from tli_verify.certification.exact import certified_decay_rate
from tli_verify.certification.reach import max_v_on_box, reach_deadline
from tli_verify.ds.lpvds import LPVDS


def _ds() -> LPVDS:
    A = np.array([[[-1.0, 8.0], [0.0, -1.0]], [[-0.6, 0.0], [0.0, -0.6]]])
    P = control.lyap(A[0].T, np.eye(2))  # A_0^T P + P A_0 = -I; -0.6 I shares it
    P = 0.5 * (P + P.T)
    return LPVDS(attractor=np.array([1.0, -2.0]), priors=np.array([0.5, 0.5]),
                 means=np.array([[0.0, 0.0], [3.0, 0.0]]),
                 covs=np.array([np.eye(2), np.eye(2)]), A=A, P=P)


def test_deadline_bounds_every_rollout_from_the_box() -> None:
    ds = _ds()
    rate = certified_decay_rate(ds.P, ds.A)
    lo, hi, radius = np.array([-5.0, -6.0]), np.array([4.0, 3.0]), 0.05
    T = reach_deadline(ds.P, ds.attractor, rate, lo, hi, radius=radius)
    assert 0 < T < 1e3
    rng = np.random.default_rng(0)
    X = np.vstack([rng.uniform(lo, hi, size=(500, 2)),
                   np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], lo[1]], [hi[0], hi[1]]])])
    dt = 1e-2
    t = 0.0
    while t < T:
        X = X + dt * ds.velocity(X)
        t += dt
    assert np.linalg.norm(X - ds.attractor, axis=1).max() <= radius


def test_box_maximum_is_at_a_vertex() -> None:
    P = np.array([[2.0, 0.5], [0.5, 1.0]])
    rng = np.random.default_rng(1)
    X = rng.uniform([-1, -1], [2, 3], size=(20000, 2))
    inner = np.einsum("ni,ij,nj->n", X, P, X).max()
    assert inner <= max_v_on_box(P, np.zeros(2), [-1, -1], [2, 3]) + 1e-12
    big = max_v_on_box(np.eye(20), np.zeros(20), -np.ones(20), np.ones(20))
    assert big == pytest.approx(20.0)


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="not positive"):
        reach_deadline(np.eye(2), np.zeros(2), 0, -np.ones(2), np.ones(2), radius=1.0)
    with pytest.raises(ValueError, match="hi must be >= lo"):
        max_v_on_box(np.eye(2), np.zeros(2), np.ones(2), -np.ones(2))
    assert reach_deadline(np.eye(2), np.zeros(2), 1.0, -np.ones(2) * 0.1, np.ones(2) * 0.1,
                          radius=1.0) == 0.0
