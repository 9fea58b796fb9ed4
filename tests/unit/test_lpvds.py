"""LPV-DS evaluation (paper eq. 4) and learning."""

from __future__ import annotations

import numpy as np
import pytest

from tli_verify.defaults import DEFAULT_DT_FLOAT
from tli_verify.ds.lpvds import LPVDS, learn_lpvds
from tli_verify.errors import ModelError


def small_ds() -> LPVDS:
    return LPVDS(attractor=np.array([1.0, 2.0]), priors=np.array([0.4, 0.6]),
                 means=np.array([[0.0, 0.0], [3.0, 3.0]]),
                 covs=np.array([np.eye(2), [[2.0, 0.3], [0.3, 1.0]]]),
                 A=np.array([[[-1.0, 1.0], [-1.0, -1.0]], [[-2.0, 0.0], [0.5, -1.0]]]),
                 P=np.eye(2))


def test_velocity_is_the_gamma_weighted_sum() -> None:
    ds = small_ds()
    X = np.random.default_rng(0).normal(scale=4, size=(30, 2))
    gamma = ds.gamma(X)
    expected = np.array([sum(gamma[i, k] * ds.A[k] @ (X[i] - ds.attractor) for k in range(2))
                         for i in range(len(X))])
    np.testing.assert_allclose(ds.velocity(X), expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(gamma.sum(axis=1), 1.0)


def test_shapes_and_exact_equilibrium() -> None:
    ds = small_ds()
    assert ds.velocity(np.zeros((5, 2))).shape == (5, 2)
    single = ds.velocity(np.array([0.5, 0.5]))
    assert single.shape == (2,)
    np.testing.assert_array_equal(single, ds.velocity(np.array([[0.5, 0.5]]))[0])
    np.testing.assert_array_equal(ds.velocity(ds.attractor), [0.0, 0.0])
    assert ds.lyapunov(ds.attractor) == 0.0
    with pytest.raises(ModelError, match=r"states must have shape \(N, 2\)"):
        ds.velocity(np.zeros((4, 3)))


def test_invalid_parameters() -> None:
    ds = small_ds()
    with pytest.raises(ModelError, match=r"A must have shape \(2, 2, 2\)"):
        LPVDS(attractor=ds.attractor, priors=ds.priors, means=ds.means, covs=ds.covs,
              A=ds.A[:1], P=ds.P)
    with pytest.raises(ModelError, match="finite"):
        LPVDS(attractor=np.array([np.inf, 0.0]), priors=ds.priors, means=ds.means,
              covs=ds.covs, A=ds.A, P=ds.P)


def arc_data() -> tuple[np.ndarray, np.ndarray]:
    """Three spiral strokes into the origin, timed slow-fast-slow."""
    rng = np.random.default_rng(5)
    t = np.linspace(0, 5, 80)
    u = 0.5 - 0.5 * np.cos(np.pi * t / 5)
    xs, vs = [], []
    for r in (4.0, 5.0, 6.0):
        th = np.pi * (0.5 + u)
        x = (r * (1 - u))[:, None] * np.column_stack([np.cos(th), np.sin(th)])
        xs.append(x + rng.normal(scale=0.01, size=x.shape))
        vs.append(np.gradient(x, t, axis=0))
    return np.concatenate(xs), np.concatenate(vs)


def test_learning_is_stable_accurate_and_deterministic() -> None:
    X, V = arc_data()
    ds, info = learn_lpvds(X, V, np.zeros(2), seed=3, eps=1e-3)
    assert info.clustering == "pc-gmm"
    assert info.status == "optimal"
    assert info.n_components == ds.n_components >= 2
    assert np.linalg.eigvalsh(ds.P).min() > 0
    for A in ds.A:
        assert np.linalg.eigvalsh(A.T @ ds.P + ds.P @ A).max() <= -1e-3 + 1e-7
    rmse = np.sqrt(np.mean(np.sum((ds.velocity(X) - V) ** 2, axis=1)))
    assert rmse < 0.25 * np.sqrt(np.mean(np.sum(V**2, axis=1)))
    again, _ = learn_lpvds(X, V, np.zeros(2), seed=3, eps=1e-3)
    np.testing.assert_array_equal(again.A, ds.A)
    np.testing.assert_array_equal(again.P, ds.P)


def test_baseline_uses_identity_p() -> None:
    X, V = arc_data()
    ds, info = learn_lpvds(X, V, np.zeros(2), seed=0, clustering="em-bic",
                           lyapunov="identity")
    assert info.clustering == "em-bic"
    np.testing.assert_array_equal(ds.P, np.eye(2))
    for A in ds.A:
        assert np.linalg.eigvalsh(A + A.T).max() < 0


def test_bad_learning_arguments() -> None:
    X, V = arc_data()
    with pytest.raises(ModelError, match="unknown clustering 'kmeans'"):
        learn_lpvds(X, V, np.zeros(2), clustering="kmeans")  # type: ignore[arg-type]
    with pytest.raises(ModelError, match="learning data shapes do not match"):
        learn_lpvds(X, V[:-1], np.zeros(2))


def test_default_learning_certifies_a_decay_rate_and_steps_at_the_default_period_and_shorter(
        ) -> None:
    from tli_verify.ds.lyapunov import RATE_FACTOR, data_rate, decay_rate, sampled_growth

    X, V = arc_data()
    ds, info = learn_lpvds(X, V, np.zeros(2), seed=3)
    assert info.rate == pytest.approx(RATE_FACTOR * data_rate(X, V, np.zeros(2)))
    assert info.rate > 0.1
    assert info.control_dt == DEFAULT_DT_FLOAT
    assert decay_rate(ds.P, ds.A) >= info.rate * (1 - 1e-4)
    for dt in (DEFAULT_DT_FLOAT, 1e-3):  # the default period, and a shorter one it covers
        assert sampled_growth(ds.P, ds.A, dt) < -0.5 * dt * info.rate
    rmse = np.sqrt(np.mean(np.sum((ds.velocity(X) - V) ** 2, axis=1)))
    assert rmse < 0.25 * np.sqrt(np.mean(np.sum(V**2, axis=1)))


def test_rate_zero_is_the_plain_margin_learner() -> None:
    from tli_verify.ds.lyapunov import decay_rate, estimate_p, fit_a

    X, V = arc_data()
    ds, info = learn_lpvds(X, V, np.zeros(2), seed=3, rate=0.0)
    assert (info.rate, info.control_dt, info.eps) == (0.0, None, 1e-3)
    P, _ = estimate_p(X, V, np.zeros(2))
    A, _ = fit_a(X, V, ds.gamma(X), np.zeros(2), P, eps=1e-3)
    np.testing.assert_allclose(ds.A, A, atol=1e-9)
    fast, _ = learn_lpvds(X, V, np.zeros(2), seed=3)
    assert decay_rate(fast.P, fast.A) > 10 * decay_rate(ds.P, ds.A)
    with pytest.raises(ModelError, match="decay rate must be finite and >= 0"):
        learn_lpvds(X, V, np.zeros(2), rate=-1.0)
