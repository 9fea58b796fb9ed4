"""Exact rational re-check of the Lyapunov conditions (paper eq. 5)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import sympy
from hypothesis import given
from hypothesis import strategies as st

from tli_verify.certify.exact import (
    check_lyapunov,
    lyapunov_derivative,
    positive_definite,
    to_fractions,
)

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
