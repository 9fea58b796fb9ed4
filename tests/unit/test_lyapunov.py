"""The convex Lyapunov programs (paper eq. 5), solved by Clarabel and re-checked independently."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from tli_verify.certification.exact import check_lyapunov
from tli_verify.commands import exit_code
from tli_verify.ds.lyapunov import (
    data_rate,
    decay_rate,
    estimate_p,
    find_p,
    fit_a,
    sampled_growth,
)
from tli_verify.errors import SolverError


def trajectories(A: np.ndarray, x_star: np.ndarray, starts: np.ndarray,
                 t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact samples of xdot = A (x - x*)."""
    X = np.concatenate([[x_star + expm(A * ti) @ (s - x_star) for ti in t] for s in starts])
    return X, (X - x_star) @ A.T


def test_fit_a_recovers_a_stable_linear_system() -> None:
    A_true = np.array([[-1.0, 2.0], [-2.0, -1.0]])
    x_star = np.array([1.0, -2.0])
    X, V = trajectories(A_true, x_star, np.array([[5.0, 3.0], [-4.0, 0.0]]),
                        np.linspace(0, 3, 40))
    A, info = fit_a(X, V, np.ones((len(X), 1)), x_star, np.eye(2), eps=1e-3)
    assert info.status == "optimal"
    assert info.solver == "CLARABEL"
    np.testing.assert_allclose(A[0], A_true, atol=1e-5)


def test_fit_a_enforces_the_lmi_with_margin() -> None:
    A_true = np.array([[0.5, 0.0], [0.0, -1.0]])  # unstable: least squares alone would copy it
    X, V = trajectories(A_true, np.zeros(2), np.array([[1.0, 1.0], [-1.0, 2.0]]),
                        np.linspace(0, 1, 30))
    P = np.array([[2.0, 0.3], [0.3, 0.5]])
    eps = 0.05
    A, _ = fit_a(X, V, np.ones((len(X), 1)), np.zeros(2), P, eps=eps)
    lam = np.linalg.eigvalsh(A[0].T @ P + P @ A[0]).max()
    assert lam <= -eps + 1e-6  # independent re-check of the solver's answer
    assert check_lyapunov(P, A).ok


def test_estimate_p_finds_a_metric_in_which_the_data_descends() -> None:
    # non-normal stable system: |x - x*| grows at first, so P = I is violated by the data
    A_true = np.array([[-1.0, 6.0], [0.0, -1.0]])
    X, V = trajectories(A_true, np.zeros(2), np.array([[0.0, 1.0], [0.3, -1.0]]),
                        np.linspace(0.01, 4, 60))
    assert np.max(np.einsum("ni,ni->n", X, V)) > 0
    P, info = estimate_p(X, V, np.zeros(2))
    assert info.status == "optimal"
    np.testing.assert_allclose(P, P.T)
    assert np.linalg.eigvalsh(P).min() >= 0.05 - 1e-7
    assert np.trace(P) == pytest.approx(2.0, abs=1e-7)
    assert np.max(np.einsum("ni,ij,nj->n", X, P, V)) < 0  # V decreases along every sample


def test_find_p_for_fixed_systems() -> None:
    A = np.array([[[-1.0, 10.0], [0.0, -1.0]], [[-2.0, 1.0], [0.0, -1.0]]])
    assert not check_lyapunov(np.eye(2), A).ok
    P, info = find_p(A)
    assert info.status == "optimal"
    assert check_lyapunov(P, A).ok


def test_infeasible_sdp_is_a_solver_error_not_a_model() -> None:
    A = np.array([[[0.1, 0.0], [0.0, -1.0]]])  # unstable: no Lyapunov matrix exists
    with pytest.raises(SolverError, match=r"P-search: solver CLARABEL returned status "
                                          r"'infeasible', not 'optimal'") as info:
        find_p(A)
    assert exit_code(info.value) == 1


def test_shape_mismatch() -> None:
    with pytest.raises(SolverError, match="data shapes do not match"):
        estimate_p(np.zeros((3, 2)), np.zeros((3, 3)), np.zeros(2))


def _rate_by_bisection(P: np.ndarray, A: np.ndarray) -> float:
    """Independent of :func:`decay_rate`: bisect lambda on a Cholesky test of
    -(A_k^T P + P A_k) - lambda P >= 0."""

    def holds(lam: float) -> bool:
        for a in A:
            Q = -(a.T @ P + P @ a) - lam * P
            try:
                np.linalg.cholesky(0.5 * (Q + Q.T) + 1e-13 * np.eye(len(P)))
            except np.linalg.LinAlgError:
                return False
        return True

    lo, hi = -100.0, 100.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if holds(mid) else (lo, mid)
    return lo


def test_decay_rate_and_sampled_growth_match_independent_computations() -> None:
    rng = np.random.default_rng(7)
    for _ in range(20):
        M = rng.normal(size=(3, 3))
        P = M @ M.T + 0.5 * np.eye(3)
        A = rng.normal(size=(4, 3, 3)) - 2.0 * np.eye(3)
        assert decay_rate(P, A) == pytest.approx(_rate_by_bisection(P, A), abs=1e-8)
        dt = 10.0 ** rng.uniform(-3, -1)
        R = np.linalg.cholesky(P)  # |F|_P = spectral norm of R^T F R^-T
        norms = [np.linalg.norm(R.T @ (np.eye(3) + dt * a) @ np.linalg.inv(R.T), 2)
                 for a in A]
        assert sampled_growth(P, A, dt) == pytest.approx(max(norms) ** 2 - 1.0, abs=1e-10)


def test_fit_a_rate_certifies_a_decay_rate_that_the_plain_margin_does_not() -> None:
    # a slow, non-normal demonstration: the least-squares fit sits near the stability boundary
    A_true = np.array([[-0.02, 1.0], [-1.0, -0.02]])
    X, V = trajectories(A_true, np.zeros(2), np.array([[1.0, 0.0], [0.0, 2.0]]),
                        np.linspace(0, 3, 40))
    gamma = np.ones((len(X), 1))
    plain, _ = fit_a(X, V, gamma, np.zeros(2), np.eye(2), eps=1e-3)
    assert decay_rate(np.eye(2), plain) < 0.05
    fast, info = fit_a(X, V, gamma, np.zeros(2), np.eye(2), eps=1e-3, rate=0.5)
    assert info.status == "optimal"
    assert decay_rate(np.eye(2), fast) >= 0.5 - 1e-6
    assert check_lyapunov(np.eye(2), fast).ok


@pytest.mark.parametrize("unit", [1.0, 1000.0])  # metres and millimetres: same program
def test_fit_a_sampled_constraint_binds_where_the_continuous_optimum_overshoots(
        unit: float) -> None:
    # a fast rotation: A^T + A = -2 I certifies rate 2, but one explicit step of 10 ms
    # multiplies |x| by |1 + 0.01 (-1 + 300 i)| > 1
    A_true = np.array([[-1.0, 300.0], [-300.0, -1.0]])
    X, V = trajectories(A_true, np.zeros(2), unit * np.array([[1.0, 0.0], [0.0, 2.0]]),
                        np.linspace(0, 0.05, 60))
    gamma = np.ones((len(X), 1))
    dt, rate = 1e-2, 0.5
    cont, _ = fit_a(X, V, gamma, np.zeros(2), np.eye(2), eps=1e-3, rate=rate)
    assert decay_rate(np.eye(2), cont) >= rate
    assert sampled_growth(np.eye(2), cont, dt) > 0  # continuous-time only: steps grow V
    sampled, info = fit_a(X, V, gamma, np.zeros(2), np.eye(2), eps=1e-3, rate=rate, dt=dt)
    assert info.problem == "A-fit (sampled)"
    assert sampled_growth(np.eye(2), sampled, dt) <= -dt * rate * (1 - 1e-4)
    assert sampled_growth(np.eye(2), sampled, dt / 7) < 0  # and at every shorter period
    assert decay_rate(np.eye(2), sampled) >= rate * (1 - 1e-4)  # implies the continuous one


def test_fit_a_keeps_the_continuous_optimum_when_it_already_steps_down() -> None:
    A_true = np.array([[-1.0, 2.0], [-2.0, -1.0]])
    X, V = trajectories(A_true, np.zeros(2), np.array([[5.0, 3.0], [-4.0, 0.0]]),
                        np.linspace(0, 3, 40))
    gamma = np.ones((len(X), 1))
    with_dt, info = fit_a(X, V, gamma, np.zeros(2), np.eye(2), rate=0.5, dt=1e-3)
    without, _ = fit_a(X, V, gamma, np.zeros(2), np.eye(2), rate=0.5)
    assert info.problem == "A-fit"
    np.testing.assert_allclose(with_dt, without, atol=1e-9)
    np.testing.assert_allclose(with_dt[0], A_true, atol=1e-4)


def test_fit_a_rejects_meaningless_margins() -> None:
    X = np.ones((4, 2))
    with pytest.raises(SolverError, match="eps >= 0 and rate >= 0, not both 0"):
        fit_a(X, X, np.ones((4, 1)), np.zeros(2), np.eye(2), eps=0.0, rate=0.0)
    with pytest.raises(SolverError, match="control period dt must be positive"):
        fit_a(X, X, np.ones((4, 1)), np.zeros(2), np.eye(2), rate=1.0, dt=0.0)


def test_data_rate_is_the_rate_of_an_exponential_approach() -> None:
    t = np.linspace(0, 5, 200)
    z = np.exp(-0.8 * t)[:, None] * np.array([3.0, -4.0])
    x_star = np.array([1.0, 2.0])
    assert data_rate(x_star + z, -0.8 * z, x_star) == pytest.approx(0.8)
    assert data_rate(x_star + 1000 * z, -800 * z, x_star) == pytest.approx(0.8)  # unit-free
    assert data_rate(np.tile(x_star, (3, 1)), np.zeros((3, 2)), x_star) == 0.0
