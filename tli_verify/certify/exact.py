"""Exact re-check of the Lyapunov conditions in rational arithmetic (paper eq. 5).

A binary64 float *is* a rational number, so ``fractions.Fraction(x)`` converts the numbers of a
model or certificate without any rounding. We then decide

    P = P^T,  P > 0     and     -(A_k^T P + P A_k) > 0   for every k

exactly: the product ``A_k^T P + P A_k`` is formed in ``Fraction`` arithmetic, and positive
definiteness of a symmetric matrix is decided by Gaussian elimination without pivoting (the
``D`` of ``M = L D L^T``). The k-th pivot is the ratio of the k-th and (k-1)-th leading principal
minors, so all pivots are positive iff all leading minors are (Sylvester's criterion). No floating
point operation, tolerance or solver enters the verdict.

The cost is ``O(n^3)`` rational operations per matrix; for the small state dimensions of motion
policies (n <= 7) a mode with a dozen components checks in milliseconds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import numpy.typing as npt

__all__ = [
    "ExactMatrix",
    "LyapunovCheck",
    "PDResult",
    "check_lyapunov",
    "lyapunov_derivative",
    "positive_definite",
    "to_fractions",
]

ExactMatrix = tuple[tuple[Fraction, ...], ...]
"""A matrix of exact rationals, row-major."""


@dataclass(frozen=True, slots=True)
class PDResult:
    """Outcome of an exact positive-definiteness test.

    Attributes
    ----------
    positive : bool
        True iff the matrix is symmetric and positive definite.
    reason : str
        Empty when positive; otherwise why not (first non-positive leading minor, asymmetry).
    failing_minor : int or None
        Order (1-based) of the first leading principal minor that is ``<= 0``.
    """

    positive: bool
    reason: str = ""
    failing_minor: int | None = None


@dataclass(frozen=True, slots=True)
class LyapunovCheck:
    """Exact verdict on ``P > 0`` and ``A_k^T P + P A_k < 0`` for one mode.

    Attributes
    ----------
    p : PDResult
        Test of ``P``.
    components : tuple of PDResult
        Test of ``-(A_k^T P + P A_k)`` for each k.
    """

    p: PDResult
    components: tuple[PDResult, ...]

    @property
    def ok(self) -> bool:
        """True iff every condition holds exactly."""
        return self.p.positive and all(c.positive for c in self.components)

    def failures(self) -> list[str]:
        """One message per failed condition (empty when :attr:`ok`)."""
        out = []
        if not self.p.positive:
            out.append(f"P is not positive definite ({self.p.reason})")
        for k, c in enumerate(self.components):
            if not c.positive:
                out.append(f"component {k}: A_k^T P + P A_k is not negative definite ({c.reason})")
        return out


def to_fractions(M: npt.ArrayLike) -> ExactMatrix:
    """Convert a float matrix to exact rationals (no rounding: floats are dyadic rationals).

    Parameters
    ----------
    M : array_like, shape (r, c)
        Finite floats.

    Returns
    -------
    tuple of tuple of Fraction

    Raises
    ------
    ValueError
        If an entry is NaN or infinite, or ``M`` is not two-dimensional.
    """
    arr = np.asarray(M, dtype=np.float64)
    if arr.ndim != 2:
        raise ValueError(f"expected a matrix, got shape {arr.shape}")
    rows = []
    for row in arr.tolist():
        if not all(math.isfinite(v) for v in row):
            raise ValueError("matrix has a NaN or infinite entry")
        rows.append(tuple(Fraction(v) for v in row))
    return tuple(rows)


def positive_definite(M: Sequence[Sequence[Fraction]]) -> PDResult:
    """Decide exactly whether a rational matrix is symmetric positive definite.

    Parameters
    ----------
    M : sequence of sequence of Fraction, shape (n, n)

    Returns
    -------
    PDResult
    """
    n = len(M)
    if n == 0 or any(len(row) != n for row in M):
        return PDResult(False, "not a non-empty square matrix")
    for i in range(n):
        for j in range(i + 1, n):
            if M[i][j] != M[j][i]:
                return PDResult(False, f"not symmetric: entry [{i}][{j}] != [{j}][{i}]")
    work = [list(row) for row in M]
    for k in range(n):
        pivot = work[k][k]
        if pivot <= 0:
            return PDResult(False, f"leading principal minor of order {k + 1} is "
                            f"{'zero' if pivot == 0 else 'negative'}", k + 1)
        row_k = work[k]
        for i in range(k + 1, n):
            factor = work[i][k] / pivot
            if factor:
                row_i = work[i]
                for j in range(k + 1, n):
                    row_i[j] -= factor * row_k[j]
    return PDResult(True)


def lyapunov_derivative(A: Sequence[Sequence[Fraction]],
                        P: Sequence[Sequence[Fraction]]) -> ExactMatrix:
    """Exact ``A^T P + P A`` (the matrix of ``dV/dt`` for ``xdot = A (x - x*)``).

    Parameters
    ----------
    A, P : sequence of sequence of Fraction, shape (n, n)

    Returns
    -------
    tuple of tuple of Fraction, shape (n, n)
    """
    n = len(P)
    PA = [[sum((P[i][m] * A[m][j] for m in range(n)), Fraction(0)) for j in range(n)]
          for i in range(n)]
    return tuple(tuple(PA[j][i] + PA[i][j] for j in range(n)) for i in range(n))


def check_lyapunov(P: npt.ArrayLike, A: npt.ArrayLike) -> LyapunovCheck:
    """Exactly decide ``P = P^T > 0`` and ``A_k^T P + P A_k < 0`` for every k (paper eq. 5).

    Parameters
    ----------
    P : array_like, shape (n, n)
        Lyapunov matrix (floats, taken as the exact rationals they represent).
    A : array_like, shape (K, n, n)
        Linear systems.

    Returns
    -------
    LyapunovCheck
    """
    Pa = np.asarray(P, dtype=np.float64)
    Aa = np.asarray(A, dtype=np.float64)
    n_comp = Aa.shape[0] if Aa.ndim == 3 else 0
    try:
        if Pa.ndim != 2 or Pa.shape[0] != Pa.shape[1] or Aa.ndim != 3 \
                or Aa.shape[1:] != Pa.shape:
            raise ValueError(f"shape mismatch: P {Pa.shape}, A {Aa.shape}")
        Pq = to_fractions(Pa)
        Aq = [to_fractions(a) for a in Aa]
    except ValueError as exc:
        bad = PDResult(False, str(exc))
        return LyapunovCheck(bad, tuple(bad for _ in range(n_comp)))
    p_result = positive_definite(Pq)
    comps = []
    for a in Aq:
        S = lyapunov_derivative(a, Pq)
        comps.append(positive_definite(tuple(tuple(-v for v in row) for row in S)))
    return LyapunovCheck(p_result, tuple(comps))
