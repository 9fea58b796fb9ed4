"""Exact rational re-check of the Lyapunov conditions (paper eq. 5)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.linalg
import sympy
from hypothesis import given, settings
from hypothesis import strategies as st

import tli_verify.certification.exact as exact_module
from tli_verify.certification.exact import (
    MAX_EXACT_DIM,
    Dyadic,
    certified_decay_rate,
    check_lyapunov,
    int_matmul,
    lyapunov_derivative,
    positive_definite,
    positive_definite_dyadic,
    to_fractions,
)
from tli_verify.ds.lyapunov import find_p

F = Fraction


def test_floats_convert_without_rounding() -> None:
    M = to_fractions([[0.1, 2.0**-60], [1e300, -3.0]])
    assert M[0][0] == F(3602879701896397, 36028797018963968)  # the double nearest 0.1
    assert M[0][1] == F(1, 2**60)
    assert M[1][0] == F(int(1e300))


def test_to_fractions_rejects_nan() -> None:
    with pytest.raises(ValueError, match="NaN or infinite"):
        to_fractions([[1.0, float("nan")], [0.0, 1.0]])


@pytest.mark.parametrize(
    ("matrix", "positive", "minor"),
    [
        ([[2, 0], [0, 3]], True, None),
        ([[1, 1], [1, 1]], False, 2),  # singular: second minor exactly zero
        ([[0, 0], [0, 1]], False, 1),
        ([[-1, 0], [0, 5]], False, 1),
        ([[4, 2, 0], [2, 3, 1], [0, 1, 1]], True, None),
        ([[1, 2], [2, 1]], False, 2),
    ],
)
def test_positive_definite_known(matrix: list[list[int]], positive: bool,
                                 minor: int | None) -> None:
    result = positive_definite([[F(v) for v in row] for row in matrix])
    assert result.positive is positive
    assert result.failing_minor == minor


def test_decides_what_floating_point_cannot() -> None:
    # det = 2^-52 > 0: positive definite exactly, although eigvalsh says ~0
    tiny = 2.0**-52
    M = [[1.0, 1.0], [1.0, 1.0 + tiny]]
    assert positive_definite(to_fractions(M)).positive
    assert np.linalg.eigvalsh(np.array(M)).min() < 1e-15
    # and one ulp less is exactly singular
    assert not positive_definite(to_fractions([[1.0, 1.0], [1.0, 1.0]])).positive


def test_asymmetric_is_rejected() -> None:
    result = positive_definite(to_fractions([[2.0, 0.5], [0.25, 2.0]]))
    assert not result.positive
    assert "not symmetric" in result.reason


@given(st.lists(st.integers(-20, 20), min_size=9, max_size=9), st.integers(0, 8))
def test_agrees_with_sympy(entries: list[int], shift: int) -> None:
    """Sylvester/LDL^T verdict equals sympy's on random symmetric rational 3x3 matrices."""
    B = sympy.Matrix(3, 3, [sympy.Rational(v, 7) for v in entries])
    S = B + B.T + shift * sympy.eye(3)
    ours = positive_definite([[F(int(S[i, j].p), int(S[i, j].q)) for j in range(3)]
                              for i in range(3)])
    assert ours.positive == bool(S.is_positive_definite)


def test_lyapunov_derivative_exact() -> None:
    A = to_fractions([[-1.0, 2.0], [0.0, -3.0]])
    P = to_fractions([[2.0, 0.5], [0.5, 1.0]])
    S = lyapunov_derivative(A, P)
    expected = (np.array([[-1.0, 2.0], [0.0, -3.0]]).T @ np.array([[2.0, 0.5], [0.5, 1.0]]))
    expected = expected + expected.T
    assert [[float(v) for v in row] for row in S] == expected.tolist()


def test_check_lyapunov_names_failing_component() -> None:
    P = np.eye(2)
    A = np.array([[[-1.0, 0.0], [0.0, -1.0]], [[0.5, 0.0], [0.0, -1.0]]])
    verdict = check_lyapunov(P, A)
    assert verdict.p.positive
    assert [c.positive for c in verdict.components] == [True, False]
    assert verdict.failures() == [
        "component 1: A_k^T P + P A_k is not negative definite (leading principal minor of "
        "order 1 is negative)"
    ]


def test_check_lyapunov_needs_nonidentity_p() -> None:
    # stable A whose symmetric part is indefinite: P = I fails, a suitable P certifies
    A = np.array([[[-1.0, 10.0], [0.0, -1.0]]])
    assert not check_lyapunov(np.eye(2), A).ok
    P = np.array([[1.0, 0.0], [0.0, 100.0]])
    assert check_lyapunov(P, A).ok


def test_check_lyapunov_shape_mismatch() -> None:
    verdict = check_lyapunov(np.eye(2), np.zeros((1, 3, 3)))
    assert not verdict.ok
    assert "shape mismatch" in verdict.p.reason


def test_lasa_sized_model_certifies() -> None:
    """A LASA-sized model (15 components). Its speed is measured by ``make bench`` (the LASA
    table's exact-check time), not asserted here: timed tests flake on a loaded machine."""
    rng = np.random.default_rng(0)
    P = np.array([[1.3, 0.2], [0.2, 0.7]])
    A = np.stack([-np.eye(2) + 0.1 * rng.normal(size=(2, 2)) for _ in range(15)])
    verdict = check_lyapunov(P, A)
    assert verdict.ok
    assert len(verdict.components) == 15 and all(c.positive for c in verdict.components)


# --------------------------------------------------------------------------------------------
# Integer arithmetic, the fast congruence proof, sampled data and decay rates
# --------------------------------------------------------------------------------------------

big_ints = st.integers(-(2**200), 2**200)


@given(st.integers(1, 40), st.integers(1, 6), st.integers(0, 2**32))
def test_int_matmul_is_exact(n: int, bits_exp: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    bound = 2 ** (10 * bits_exp)
    a = np.array([[int(v) * bound + 1 for v in row]
                  for row in rng.integers(-(2**60), 2**60, size=(n, n))], dtype=object)
    b = np.array([[int(v) for v in row] for row in rng.integers(-(2**62), 2**62, size=(n, 3))],
                 dtype=object)
    assert (int_matmul(a, b) == a.dot(b)).all()


def test_dyadic_round_trips_floats_exactly() -> None:
    M = np.array([[0.1, -2.0**-1074], [1e300, 3.0]])
    D = Dyadic.from_floats(M)
    assert D.to_fractions() == to_fractions(M)
    assert [[Fraction(v) for v in row] for row in M.tolist()] == [list(r) for r in
                                                                  D.to_fractions()]


@settings(max_examples=60)
@given(n=st.integers(13, 24), seed=st.integers(0, 2**32), shift=st.floats(-3.0, 3.0))
def test_large_matrices_agree_with_elimination(n: int, seed: int, shift: float) -> None:
    """Above 12 the verdict comes from the congruence proof or an exact witness: it must agree
    with plain fraction-free elimination (Sylvester's criterion) on the same integers."""
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, n))
    M = X @ X.T / n + shift * np.eye(n)
    M = 0.5 * (M + M.T)
    D = Dyadic.from_floats(M)
    fast = positive_definite_dyadic(D)
    slow = exact_module._bareiss(D.m)
    assert fast.positive == slow.positive


def test_congruence_proof_is_what_decides_large_positive_matrices() -> None:
    rng = np.random.default_rng(3)
    X = rng.normal(size=(40, 40))
    M = X @ X.T + np.eye(40)
    D = Dyadic.from_floats(M)
    assert exact_module._congruence_proof(D.m, M)
    # a matrix one ulp-scale step from singular is not proven by the congruence, and the
    # elimination still decides it exactly
    v = rng.normal(size=(40, 1))
    S = Dyadic.from_floats(v @ v.T)
    assert not exact_module._congruence_proof(S.m, v @ v.T)
    assert not positive_definite_dyadic(S).positive


def test_dimension_limit_is_a_verdict_not_a_stall() -> None:
    n = MAX_EXACT_DIM + 1
    check = check_lyapunov(np.eye(n), -np.eye(n)[None])
    assert not check.ok
    assert f"exceeds the exact check's limit {MAX_EXACT_DIM}" in check.failures()[0]


def test_sampled_data_condition_matches_python_control() -> None:
    """Cross-check with python-control: a P from dlyap proves the sampled condition, and the
    exact verdict flips where the discrete Lyapunov margin does."""
    import control

    A = np.array([[-1.0, 8.0], [0.0, -1.0]])
    Pc = control.lyap(A.T, np.eye(2))  # A^T P + P A + I = 0
    Pc = 0.5 * (Pc + Pc.T)
    assert check_lyapunov(Pc, A[None]).ok
    for dt in ("1/1000", "1/100", "1/10"):
        B = np.eye(2) + float(Fraction(dt)) * A
        Pd = control.dlyap(B.T, np.eye(2))  # B^T P B - P + I = 0
        Pd = 0.5 * (Pd + Pd.T)
        assert check_lyapunov(Pd, A[None], dt=dt).ok
    # P from the continuous equation, at a period too long for it: float margin and exact
    # verdict agree
    for dt in ("1/1000", "1/10", "1/2", "2"):
        B = np.eye(2) + float(Fraction(dt)) * A
        margin = np.linalg.eigvalsh(Pc - B.T @ Pc @ B).min()
        assert abs(margin) > 1e-9
        assert check_lyapunov(Pc, A[None], dt=dt).ok == (margin > 0)


def test_sampled_certificate_covers_shorter_periods() -> None:
    A = np.array([[[-1.0, 8.0], [0.0, -1.0]], [[-2.0, 0.0], [0.0, -1.5]]])
    P, _ = find_p(A, dt=0.01)
    assert check_lyapunov(P, A, dt="1/100").ok
    for dt in ("1/200", "1/1000", "1/1000000"):
        assert check_lyapunov(P, A, dt=dt).ok


def test_certified_decay_rate_is_tight_and_predicts_the_rollout() -> None:
    rng = np.random.default_rng(0)
    A = np.array([[[-1.0, 8.0], [0.0, -1.0]], [[-0.5, 0.0], [0.0, -0.7]]])
    P, _ = find_p(A)
    lam = certified_decay_rate(P, A)
    best = min(float(scipy.linalg.eigh(-(a.T @ P + P @ a), P, eigvals_only=True)[0]) for a in A)
    assert 0 < float(lam) <= best
    assert float(lam) >= 0.999 * best  # 4 significant digits
    assert check_lyapunov(P, A, rate=lam).ok
    assert not check_lyapunov(P, A, rate=Fraction(best) * Fraction(1001, 1000)).ok
    # V(x(t)) <= V(x0) exp(-lam t) along the switched system x' = A_{k(t)} x
    x = rng.normal(size=2) * 5
    V0 = x @ P @ x
    dt = 1e-4
    for i in range(20000):
        a = A[(i // 700) % 2]
        x = x + dt * (a @ x)  # Euler at a period the sampled condition covers
    assert x @ P @ x <= V0 * np.exp(-float(lam) * 20000 * dt) * (1 + 1e-6)


def test_decay_rate_of_an_unstable_system_is_zero() -> None:
    A = np.array([[[0.1, 0.0], [0.0, -1.0]]])
    assert certified_decay_rate(np.eye(2), A) == 0
