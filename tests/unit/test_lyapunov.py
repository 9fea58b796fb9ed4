"""The convex Lyapunov programs (paper eq. 5), solved by Clarabel and re-checked independently."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from tli_verify.certify.exact import check_lyapunov
from tli_verify.ds.lyapunov import estimate_p, find_p, fit_a
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
    assert info.value.exit_code == 1


def test_shape_mismatch() -> None:
    with pytest.raises(SolverError, match="data shapes do not match"):
        estimate_p(np.zeros((3, 2)), np.zeros((3, 3)), np.zeros(2))
