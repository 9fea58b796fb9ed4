"""fit_a accepts Clarabel's optimal_inaccurate only when the returned A_k meet the LMIs."""

from __future__ import annotations

import numpy as np
import pytest

from tli_verify.ds.lyapunov import SolveInfo, _check_margin, fit_a
from tli_verify.errors import SolverError

INFO = SolveInfo("A-fit", "CLARABEL", "optimal_inaccurate", 0.0, 0.0)


def _spd(rng: np.random.Generator, n: int) -> np.ndarray:
    m = rng.normal(size=(n, n))
    return m @ m.T + n * np.eye(n)


@pytest.mark.parametrize("dt", [None, 0.02])
def test_a_stable_fit_is_accepted_and_a_violating_one_refused(dt: float | None) -> None:
    rng = np.random.default_rng(3)
    n = 4
    P = _spd(rng, n)
    margin = 1e-3 * np.eye(n) + 0.1 * P
    good = -np.eye(n)[None] * 2.0  # A^T P + P A = -4P: well inside, also per step at 0.02
    _check_margin(P, good, margin, dt, INFO)  # no error
    bad = good.copy()
    bad[0] += 5.0 * np.outer(rng.normal(size=n), rng.normal(size=n))  # breaks the LMI
    Q = bad[0].T @ P + P @ bad[0] + margin
    assert np.linalg.eigvalsh(0.5 * (Q + Q.T))[-1] > 0  # the forgery really violates it
    with pytest.raises(SolverError, match=r"optimal_inaccurate.*A_0 violates"):
        _check_margin(P, bad, margin, dt, INFO)


def test_the_sampled_form_is_checked_with_its_dt_term() -> None:
    """A_k that decrease V continuously but not per step at dt: only the sampled check fails."""
    n = 2
    P = np.eye(n)
    margin = 1e-3 * np.eye(n)
    fast = np.array([[[-120.0, 0.0], [0.0, -120.0]]])  # continuous: fine; I + dt A: -1.4 at 0.02
    _check_margin(P, fast, margin, None, INFO)
    with pytest.raises(SolverError, match="violates"):
        _check_margin(P, fast, margin, 0.02, INFO)


def test_fit_a_still_returns_lmi_feasible_matrices() -> None:
    rng = np.random.default_rng(0)
    X = rng.normal(size=(60, 3))
    A_true = -np.diag([1.0, 2.0, 0.5])
    dX = X @ A_true.T
    A, info = fit_a(X, dX, np.ones((60, 1)), np.zeros(3), np.eye(3), eps=1e-3, rate=0.1, dt=0.02)
    assert info.status in ("optimal", "optimal_inaccurate")
    Q = A[0].T + A[0] + 1e-3 * np.eye(3) + 0.1 * np.eye(3)
    assert np.linalg.eigvalsh(0.5 * (Q + Q.T))[-1] <= 1e-7
    assert np.allclose(A[0], A_true, atol=0.05)
