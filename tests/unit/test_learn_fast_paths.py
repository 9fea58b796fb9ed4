"""The learner's fast paths (issue 35, part A) against the reference implementations they replace.

* :func:`tli_verify.ds.gmm._dp_responsibilities` is scikit-learn's ``BayesianGaussianMixture``
  (variational Dirichlet process, full covariances, k-means init) vectorised over the
  components: same responsibilities to float rounding, same number of components kept.
* :func:`tli_verify.ds.lyapunov.fit_a` states its SDP to Clarabel directly; the same program
  written in cvxpy (the former implementation) reaches the same optimum.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tli_verify.ds.gmm import _dp_responsibilities
from tli_verify.ds.lyapunov import fit_a, sampled_growth


def _clusters(seed: int, n_per: int = 80, d: int = 4) -> np.ndarray:
    rng = np.random.default_rng(seed)
    centres = rng.normal(scale=4.0, size=(4, d))
    return np.concatenate([c + rng.normal(scale=0.3 + 0.4 * i, size=(n_per, d))
                           for i, c in enumerate(centres)])


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("truncation", [3, 8])
def test_dp_responsibilities_match_scikit_learn(seed: int, truncation: int) -> None:
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.mixture import BayesianGaussianMixture

    F = _clusters(seed)
    ref = BayesianGaussianMixture(
        n_components=truncation, covariance_type="full",
        weight_concentration_prior_type="dirichlet_process", weight_concentration_prior=1.0,
        init_params="kmeans", max_iter=300, tol=1e-4, reg_covar=1e-6, random_state=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        expected = ref.fit(F).predict_proba(F)
    got = _dp_responsibilities(F, truncation, seed=seed, concentration=1.0)
    assert got.shape == expected.shape
    np.testing.assert_allclose(got, expected, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(got.sum(axis=1), 1.0, atol=1e-12)
    # the pruning rule of fit_pcgmm sees the same component masses
    np.testing.assert_allclose(got.sum(axis=0), expected.sum(axis=0), atol=1e-7)


def _cvxpy_fit_a(X: np.ndarray, dX: np.ndarray, G: np.ndarray, P: np.ndarray, *, eps: float,
                 rate: float, dt: float | None) -> float:
    """Optimal value of the A-fit written in cvxpy (the former implementation's program)."""
    import cvxpy as cp

    N, n = X.shape
    K = G.shape[1]
    D = np.einsum("ik,ib,ac->iakbc", G, X, np.eye(n)).reshape(N * n, K * n * n)
    H = D.T @ D / N
    g = D.T @ dX.reshape(N * n) / N
    H[np.diag_indices_from(H)] += 1e-6 * np.trace(H) / H.shape[0]
    L = np.linalg.cholesky(H)
    rhs = np.linalg.solve(L, g)
    scale = float(np.linalg.norm(rhs))
    A = [cp.Variable((n, n)) for _ in range(K)]
    theta = cp.hstack([cp.vec(a, order="F") for a in A])
    margin = eps * np.eye(n) + rate * P
    R = np.linalg.cholesky(P)
    cons = []
    for a in A:
        M = P @ a
        if dt is None:
            cons.append(M + M.T << -margin)
        else:
            C = np.sqrt(dt) * (R.T @ a)
            Z = cp.bmat([[-(M + M.T) - margin, C.T], [C, np.eye(n)]])
            cons.append(0.5 * (Z + Z.T) >> 0)
    prob = cp.Problem(cp.Minimize(cp.sum_squares((L.T @ theta - rhs) / scale)), cons)
    prob.solve(solver=cp.CLARABEL)
    assert prob.status == cp.OPTIMAL
    return float(prob.value)


@pytest.mark.parametrize("n", [2, 3])
def test_direct_clarabel_a_fit_reaches_the_cvxpy_optimum(n: int) -> None:
    rng = np.random.default_rng(10 + n)
    X = rng.normal(size=(90, n))
    A_true = -30.0 * np.eye(n) + 40.0 * rng.normal(size=(n, n))  # unstable parts: LMIs bind
    dX = X @ A_true.T + 0.1 * rng.normal(size=X.shape)
    w = 1.0 / (1.0 + np.exp(2.0 * X[:, 0]))
    G = np.column_stack([w, 1.0 - w])
    P = np.eye(n) + 0.3 * np.ones((n, n))
    A, info = fit_a(X, dX, G, np.zeros(n), P, eps=1e-3, rate=1.0, dt=0.01)
    # this data needs the sampled-data program (the continuous optimum does not step down)
    assert info.problem == "A-fit (sampled)" and info.status == "optimal"
    assert sampled_growth(P, A, 0.01) < 0.0
    for a in A:
        Q = a.T @ P + P @ a + 1e-3 * np.eye(n) + P
        assert np.linalg.eigvalsh(0.5 * (Q + Q.T))[-1] <= 1e-7
    reference = _cvxpy_fit_a(X, dX, G, P, eps=1e-3, rate=1.0, dt=0.01)
    assert info.objective == pytest.approx(reference, rel=1e-6, abs=1e-9)
    # and the continuous program alone
    A0, info0 = fit_a(X, dX, G, np.zeros(n), P, eps=1e-3, rate=0.0)
    assert info0.problem == "A-fit"
    reference0 = _cvxpy_fit_a(X, dX, G, P, eps=1e-3, rate=0.0, dt=None)
    assert info0.objective == pytest.approx(reference0, rel=1e-6, abs=1e-9)
    for a in A0:
        Q = a.T @ P + P @ a + 1e-3 * np.eye(n)
        assert np.linalg.eigvalsh(0.5 * (Q + Q.T))[-1] <= 1e-7
