"""Exact re-check of the Lyapunov conditions in rational arithmetic (paper eq. 5, Thm. 1).

A binary64 float *is* a rational number -- an integer times a power of two -- so the numbers of
a model or certificate convert without rounding. A matrix of floats is held as one integer
matrix and one binary exponent (:class:`Dyadic`), and every condition is decided on integers:

* ``P = P^T > 0``;
* continuous time: ``-(A_k^T P + P A_k) > 0`` for every component k (paper eq. 5);
* sampled data at a control period ``dt`` (a rational, e.g. ``1/1000``):
  ``P - (I + dt A_k)^T P (I + dt A_k) > 0`` for every k. The P-norm is convex, so these vertex
  conditions cover every mixture ``sum_k gamma_k A_k`` of the LPV-DS: one explicit Euler step of
  the nominal DS strictly decreases ``V``. Since ``A_k^T P A_k >= 0``, a certificate at ``dt``
  also covers every shorter period;
* a decay rate ``lambda`` (a rational): ``-(A_k^T P + P A_k) - lambda P > 0`` for every k, so
  along the DS ``dV/dt <= -lambda V`` and ``V(x(t)) <= V(x(0)) exp(-lambda t)``.

**How positive definiteness is decided.** Two exact methods, the fast one first:

1. *Congruence + Gershgorin.* A floating-point Cholesky factor gives a unit lower-triangular
   ``T`` (its entries taken as the exact floats they are) and a power-of-two scaling ``S`` with
   ``N = (S T) M (S T)^T`` close to the identity. ``S T`` is invertible, so by Sylvester's law of
   inertia ``M > 0`` iff ``N > 0``; ``N`` is formed exactly on integers, and if it is strictly
   diagonally dominant with a positive diagonal it is positive definite (Gershgorin). Floats only
   *choose* ``T``; the verdict is exact. Cost: two integer matrix products, ``O(n^3)``
   operations on small integers.
2. *Fraction-free elimination* (Bareiss) on the integer matrix, for what the first method
   cannot settle (indefinite matrices, near-singular margins): the k-th pivot is the k-th leading
   principal minor, so ``M > 0`` iff all are positive (Sylvester's criterion), and the first
   non-positive one is named.

Neither method uses a tolerance or a solver in the verdict.

References
----------
.. [1] E. H. Bareiss, "Sylvester's identity and multistep integer-preserving Gaussian
   elimination", Math. Comp. 22 (1968).
.. [2] Wang et al., "Temporal Logic Imitation", CoRL 2022, eq. 5 and Thm. 1.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import numpy.typing as npt
import scipy.linalg

__all__ = [
    "MAX_EXACT_DIM",
    "Dyadic",
    "ExactMatrix",
    "LyapunovCheck",
    "PDResult",
    "certified_decay_rate",
    "check_lyapunov",
    "lyapunov_derivative",
    "parse_rational",
    "positive_definite",
    "positive_definite_dyadic",
    "to_fractions",
]

ExactMatrix = tuple[tuple[Fraction, ...], ...]
"""A matrix of exact rationals, row-major."""

MAX_RATIONAL = 10**20
"""Bound on the numerator and denominator of a control period or decay rate (cost of the
exact check grows with their size; a certificate's ``dt`` and rates have a few digits)."""

MAX_EXACT_DIM = 128
"""Largest state dimension the exact check accepts (a model above it is refused, not stalled).

The congruence method decides a 120 x 120 positive definite matrix in well under a second;
the fallback elimination of an *indefinite* one of that size takes seconds. Motion policies
have n <= 7."""


# --------------------------------------------------------------------------------------------
# Exact numbers
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class Dyadic:
    """An exact matrix ``m * 2**e`` with integer entries ``m`` (numpy ``object`` array).

    Attributes
    ----------
    m : ndarray of int (dtype object), shape (r, c)
    e : int
        Common binary exponent.
    """

    m: npt.NDArray[np.object_]
    e: int

    @classmethod
    def from_floats(cls, M: npt.ArrayLike) -> Dyadic:
        """Exact conversion of a finite float matrix (raises ``ValueError`` on NaN/inf)."""
        arr = np.asarray(M, dtype=np.float64)
        if arr.ndim != 2:
            raise ValueError(f"expected a matrix, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError("matrix has a NaN or infinite entry")
        mant, expo = np.frexp(arr)  # arr = mant * 2**expo, 0.5 <= |mant| < 1 (or 0)
        ints = np.ldexp(mant, 53).astype(np.int64)  # exact: 53-bit mantissas
        shift = expo.astype(np.int64) - 53
        nz = ints != 0
        e = int(shift[nz].min()) if nz.any() else 0
        m = np.left_shift(ints.astype(object), np.where(nz, shift - e, 0).astype(object))
        return cls(np.asarray(m, dtype=object).reshape(arr.shape), e)

    @classmethod
    def from_fractions(cls, M: Sequence[Sequence[Fraction]]) -> tuple[Dyadic, int]:
        """Integer matrix ``m`` and positive denominator ``d`` with ``M = m / d`` (``e = 0``)."""
        den = 1
        for row in M:
            for v in row:
                den = den * v.denominator // math.gcd(den, v.denominator)
        m = np.array([[int(v * den) for v in row] for row in M], dtype=object)
        return cls(m.reshape(len(M), -1), 0), den

    def align(self, other: Dyadic) -> tuple[npt.NDArray[np.object_], npt.NDArray[np.object_],
                                            int]:
        """Both integer matrices at the smaller common exponent."""
        e = min(self.e, other.e)
        return _shift(self.m, self.e - e), _shift(other.m, other.e - e), e

    def __add__(self, other: Dyadic) -> Dyadic:
        a, b, e = self.align(other)
        return Dyadic(a + b, e)

    def __sub__(self, other: Dyadic) -> Dyadic:
        a, b, e = self.align(other)
        return Dyadic(a - b, e)

    def __matmul__(self, other: Dyadic) -> Dyadic:
        return Dyadic(int_matmul(self.m, other.m), self.e + other.e)

    def scale(self, k: int) -> Dyadic:
        """``k * self`` for an integer ``k``."""
        return Dyadic(self.m * k, self.e)

    @property
    def T(self) -> Dyadic:
        """The transpose."""
        return Dyadic(self.m.T.copy(), self.e)

    def to_fractions(self) -> ExactMatrix:
        """As a tuple of tuples of ``Fraction``."""
        f = Fraction(2) ** self.e
        return tuple(tuple(Fraction(int(v)) * f for v in row) for row in self.m)


_LIMB = 23
"""Bits per limb of :func:`int_matmul`: ``2 * 23 + 7 = 53``, so a sum of 128 limb products is
an exact float64."""


def _limbs(m: npt.NDArray[np.object_]) -> list[npt.NDArray[np.float64]]:
    """Signed base-``2**23`` limbs of an integer matrix, least significant first, as floats."""
    sign = np.where(m < 0, -1, 1).astype(np.int64)
    mag = np.abs(m)
    bits = max((int(v).bit_length() for v in mag.flat), default=0)
    out = []
    mask = (1 << _LIMB) - 1
    for _ in range(max(1, -(-bits // _LIMB))):
        out.append((np.bitwise_and(mag, mask).astype(np.int64) * sign).astype(np.float64))
        mag = np.right_shift(mag, _LIMB)
    return out


def int_matmul(a: npt.NDArray[np.object_], b: npt.NDArray[np.object_]
               ) -> npt.NDArray[np.object_]:
    """Exact product of two integer matrices (``object`` arrays of Python ints).

    Both are split into signed 23-bit limbs; every limb product ``A_i @ B_j`` is a float64
    matrix product (BLAS) whose entries are sums of at most 128 terms below ``2**46``, hence
    exact integers below ``2**53``. The limb products are recombined on Python integers.
    Small (inner dimension <= 16) and very large (> 128) products use ``object`` arithmetic.
    """
    if a.shape[1] > 128 or a.shape[1] <= 16 or a.size == 0 or b.size == 0:
        return np.asarray(a.dot(b), dtype=object)
    la, lb = _limbs(a), _limbs(b)
    acc: dict[int, npt.NDArray[np.int64]] = {}
    for i, ai in enumerate(la):
        for j, bj in enumerate(lb):
            prod = (ai @ bj).astype(np.int64)
            acc[i + j] = acc[i + j] + prod if i + j in acc else prod
    out = np.zeros((a.shape[0], b.shape[1]), dtype=object)
    for s_, part in acc.items():
        out = out + np.left_shift(part.astype(object), _LIMB * s_)
    return out


def _shift(m: npt.NDArray[np.object_], k: int) -> npt.NDArray[np.object_]:
    return m if k == 0 else np.left_shift(m, k)


def _eye(n: int) -> Dyadic:
    m = np.zeros((n, n), dtype=object)
    for i in range(n):
        m[i, i] = 1
    return Dyadic(m, 0)


def parse_rational(value: str | int | float | Fraction, *, what: str = "value") -> Fraction:
    """An exact rational from a decimal string (``"0.001"`` is ``1/1000``), fraction or number.

    Raises
    ------
    ValueError
        Not a finite rational.
    """
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"{what}: {value!r} is not a finite number")
    if isinstance(value, str) and len(value) > 64:
        raise ValueError(f"{what}: {value[:20]!r}... is too long (at most 64 characters)")
    try:
        q = value if isinstance(value, Fraction) else Fraction(value)
    except (ValueError, ZeroDivisionError, TypeError):
        raise ValueError(f"{what}: {value!r} is not a rational number "
                         "(e.g. 0.001 or 1/1000)") from None
    if max(abs(q.numerator), q.denominator) >= MAX_RATIONAL:
        raise ValueError(f"{what}: {value!r} has a numerator or denominator of 20 digits or "
                         "more (a certificate states dt and rates with fewer)")
    return q


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
    return Dyadic.from_floats(M).to_fractions()


# --------------------------------------------------------------------------------------------
# Positive definiteness
# --------------------------------------------------------------------------------------------

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


def _bareiss(m: npt.NDArray[np.object_]) -> PDResult:
    """Sylvester's criterion by fraction-free elimination on a symmetric integer matrix."""
    n = m.shape[0]
    work = m.copy()
    prev = 1
    for k in range(n):
        pivot = work[k, k]
        if pivot <= 0:
            return PDResult(False, f"leading principal minor of order {k + 1} is "
                            f"{'zero' if pivot == 0 else 'negative'}", k + 1)
        if k + 1 < n:
            rest = work[k + 1:, k + 1:]
            col = work[k + 1:, k]
            row = work[k, k + 1:]
            # exact division (Sylvester's identity): the quotients are minors, hence integers
            work[k + 1:, k + 1:] = (rest * pivot - np.outer(col, row)) // prev
        prev = pivot
    return PDResult(True)


def _congruence_proof(m: npt.NDArray[np.object_], approx: npt.NDArray[np.float64]) -> bool:
    """True if ``(S T) m (S T)^T`` is strictly diagonally dominant with a positive diagonal.

    ``approx`` is any float approximation of ``m`` up to a positive factor; it only chooses the
    congruence. ``True`` proves ``m > 0`` exactly; ``False`` proves nothing.
    """
    n = m.shape[0]
    try:
        scale = np.abs(approx).max()
        if not np.isfinite(scale) or scale == 0:
            return False
        C = np.linalg.cholesky(approx / scale)
    except np.linalg.LinAlgError:
        return False
    d = np.diag(C).copy()
    if not np.all(d > 0) or not np.all(np.isfinite(C)):
        return False
    L = C / d  # unit lower-triangular up to rounding
    with np.errstate(all="ignore"):
        try:
            Tf = np.linalg.inv(np.tril(L, -1) + np.eye(n))
        except np.linalg.LinAlgError:
            return False
    if not np.all(np.isfinite(Tf)):
        return False
    # T: unit lower-triangular with entries on a 2**-30 grid (any such T is invertible; the
    # grid keeps the integers short), so T_int = 2**30 T is an integer matrix
    T_int = np.round(np.tril(Tf, -1) * 2.0**_GRID).astype(np.int64) \
        + (np.eye(n, dtype=np.int64) << _GRID)
    Tm = T_int.astype(object)
    N = int_matmul(int_matmul(Tm, m), np.ascontiguousarray(Tm.T))
    # power-of-two congruence scaling S = diag(2**sig) so that S N S is near the identity
    sig = -np.round(np.log2(d)).astype(np.int64)
    sh = (sig[:, None] + sig[None, :] - 2 * sig.min()).astype(object)
    N = np.left_shift(N, sh)
    diag = np.array([N[i, i] for i in range(n)], dtype=object)
    if not all(v > 0 for v in diag):
        return False
    off = np.abs(N).sum(axis=1) - diag
    return bool(all(diag[i] > off[i] for i in range(n)))


def positive_definite_dyadic(M: Dyadic, approx: npt.ArrayLike | None = None) -> PDResult:
    """Decide exactly whether ``M`` (``m * 2**e``) is symmetric positive definite.

    Parameters
    ----------
    M : Dyadic, shape (n, n)
    approx : array_like, shape (n, n), optional
        Float approximation of ``M`` (up to a positive factor) that picks the congruence of the
        fast proof; computed from ``M`` when omitted.

    Returns
    -------
    PDResult
    """
    m = M.m
    n = m.shape[0]
    if m.ndim != 2 or n == 0 or m.shape[1] != n:
        return PDResult(False, "not a non-empty square matrix")
    if n > MAX_EXACT_DIM:
        return PDResult(False, f"dimension {n} exceeds the exact check's limit "
                        f"{MAX_EXACT_DIM} (tli_verify.certification.exact.MAX_EXACT_DIM)")
    bad = [(i, j) for i in range(n) for j in range(i + 1, n) if m[i, j] != m[j, i]]
    if bad:
        i, j = bad[0]
        return PDResult(False, f"not symmetric: entry [{i}][{j}] != [{j}][{i}]")
    if approx is None:
        approx = _approx(m)
    approx_f = np.asarray(approx, dtype=np.float64)
    if _congruence_proof(m, approx_f):
        return PDResult(True)
    if n > _SMALL:
        witness = _negative_witness(m, approx_f)
        if witness is not None:
            return PDResult(False, f"x^T M x = {witness} <= 0 for an exact witness x (a float "
                            "eigenvector of the smallest eigenvalue, evaluated exactly)")
    return _bareiss(m)


_SMALL = 12
_GRID = 30
"""Up to this dimension a failing matrix is always explained by its first bad leading minor."""


def _negative_witness(m: npt.NDArray[np.object_], approx: npt.NDArray[np.float64]
                      ) -> str | None:
    """Sign of ``x^T m x`` for the float eigenvector ``x`` of the smallest eigenvalue.

    Returns ``"0"`` or ``"negative"`` when that exact quadratic form is ``<= 0`` (which proves
    ``m`` is not positive definite), else None.
    """
    scale = np.abs(approx).max()
    if not np.isfinite(scale) or scale == 0:
        return None
    try:
        _, vecs = np.linalg.eigh(approx / scale)
    except np.linalg.LinAlgError:
        return None
    x = Dyadic.from_floats(vecs[:, :1]).m[:, 0]
    value = int(int_matmul(int_matmul(x[None, :], m), x[:, None])[0, 0])
    if value > 0:
        return None
    return "0" if value == 0 else "negative"


def _approx(m: npt.NDArray[np.object_]) -> npt.NDArray[np.float64]:
    """Float approximation of an integer matrix up to a power-of-two factor."""
    bits = max((abs(int(v)).bit_length() for v in m.flat), default=0)
    k = max(0, bits - 900)
    return np.array([[float(int(v) >> k) if v >= 0 else -float((-int(v)) >> k) for v in row]
                     for row in m], dtype=np.float64)


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
    D, _ = Dyadic.from_fractions(M)
    return positive_definite_dyadic(D)


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


# --------------------------------------------------------------------------------------------
# The Lyapunov conditions of one DS
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class LyapunovCheck:
    """Exact verdict on the Lyapunov conditions of one DS.

    Attributes
    ----------
    p : PDResult
        Test of ``P``.
    components : tuple of PDResult
        Test of ``-(A_k^T P + P A_k)`` for each k (continuous time).
    dt : Fraction or None
        The control period of the sampled-data conditions, if checked.
    sampled : tuple of PDResult
        Test of ``P - (I + dt A_k)^T P (I + dt A_k)`` for each k (empty without ``dt``).
    rate : Fraction or None
        The decay rate checked, if any.
    decay : tuple of PDResult
        Test of ``-(A_k^T P + P A_k) - rate P`` for each k (empty without ``rate``).
    """

    p: PDResult
    components: tuple[PDResult, ...]
    dt: Fraction | None = None
    sampled: tuple[PDResult, ...] = ()
    rate: Fraction | None = None
    decay: tuple[PDResult, ...] = ()

    @property
    def ok(self) -> bool:
        """True iff every condition checked holds exactly."""
        return (self.p.positive and all(c.positive for c in self.components)
                and all(c.positive for c in self.sampled)
                and all(c.positive for c in self.decay))

    def failures(self) -> list[str]:
        """One message per failed condition (empty when :attr:`ok`)."""
        out = []
        if not self.p.positive:
            out.append(f"P is not positive definite ({self.p.reason})")
        for k, c in enumerate(self.components):
            if not c.positive:
                out.append(f"component {k}: A_k^T P + P A_k is not negative definite ({c.reason})")
        for k, c in enumerate(self.sampled):
            if not c.positive:
                out.append(f"component {k}: (I + dt A_k)^T P (I + dt A_k) - P is not negative "
                           f"definite at dt = {self.dt} ({c.reason}): one Euler step at this "
                           "control period may increase V")
        for k, c in enumerate(self.decay):
            if not c.positive:
                out.append(f"component {k}: A_k^T P + P A_k + lambda P is not negative definite "
                           f"at the claimed decay rate lambda = {self.rate} ({c.reason})")
        return out


@dataclass(frozen=True, slots=True)
class _System:
    """``P`` and ``A_k`` of one DS, exact and as floats."""

    P: Dyadic
    A: tuple[Dyadic, ...]
    Pf: npt.NDArray[np.float64]
    Af: npt.NDArray[np.float64]

    @classmethod
    def build(cls, P: npt.ArrayLike, A: npt.ArrayLike) -> _System:
        Pf = np.asarray(P, dtype=np.float64)
        Af = np.asarray(A, dtype=np.float64)
        if Pf.ndim != 2 or Pf.shape[0] != Pf.shape[1] or Af.ndim != 3 \
                or Af.shape[1:] != Pf.shape:
            raise ValueError(f"shape mismatch: P {Pf.shape}, A {Af.shape}")
        if Pf.shape[0] > MAX_EXACT_DIM:
            raise ValueError(f"dimension {Pf.shape[0]} exceeds the exact check's limit "
                             f"{MAX_EXACT_DIM}")
        return cls(Dyadic.from_floats(Pf), tuple(Dyadic.from_floats(a) for a in Af), Pf, Af)

    def neg_derivative(self, k: int) -> tuple[Dyadic, npt.NDArray[np.float64]]:
        """Exact ``-(A_k^T P + P A_k)`` and its float approximation."""
        PA = self.P @ self.A[k]
        a = self.Af[k]
        return Dyadic(-(PA.m + PA.m.T), PA.e), -(a.T @ self.Pf + self.Pf @ a)

    def sampled(self, k: int, dt: Fraction) -> tuple[Dyadic, npt.NDArray[np.float64]]:
        """Exact ``q^2 (P - (I + dt A_k)^T P (I + dt A_k))`` for ``dt = p/q``."""
        p, q = dt.numerator, dt.denominator
        B = _eye(self.P.m.shape[0]).scale(q) + self.A[k].scale(p)  # q (I + dt A_k)
        M = self.P.scale(q * q) - B.T @ self.P @ B
        Bf = np.eye(self.Pf.shape[0]) + float(dt) * self.Af[k]
        return M, self.Pf - Bf.T @ self.Pf @ Bf

    def decay(self, k: int, rate: Fraction) -> tuple[Dyadic, npt.NDArray[np.float64]]:
        """Exact ``s (-(A_k^T P + P A_k)) - r P`` for ``rate = r/s``."""
        Q, Qf = self.neg_derivative(k)
        r, s = rate.numerator, rate.denominator
        return Q.scale(s) - self.P.scale(r), Qf - float(rate) * self.Pf


def check_lyapunov(P: npt.ArrayLike, A: npt.ArrayLike, *,
                   dt: Fraction | str | None = None,
                   rate: Fraction | str | None = None) -> LyapunovCheck:
    """Exactly decide the Lyapunov conditions of one LPV-DS (paper eq. 5, Thm. 1).

    Parameters
    ----------
    P : array_like, shape (n, n)
        Lyapunov matrix (floats, taken as the exact rationals they represent).
    A : array_like, shape (K, n, n)
        Linear systems.
    dt : Fraction or str, optional
        Control period: also decide ``(I + dt A_k)^T P (I + dt A_k) - P < 0`` for every k.
    rate : Fraction or str, optional
        Decay rate: also decide ``A_k^T P + P A_k + rate P < 0`` for every k.

    Returns
    -------
    LyapunovCheck
    """
    Aa = np.asarray(A, dtype=np.float64)
    n_comp = Aa.shape[0] if Aa.ndim == 3 else 0
    dt_q = parse_rational(dt, what="dt") if dt is not None else None
    rate_q = parse_rational(rate, what="rate") if rate is not None else None
    try:
        sys_ = _System.build(P, Aa)
    except ValueError as exc:
        bad = PDResult(False, str(exc))
        many = tuple(bad for _ in range(n_comp))
        return LyapunovCheck(bad, many, dt_q, many if dt_q is not None else (), rate_q,
                             many if rate_q is not None else ())
    p_result = positive_definite_dyadic(sys_.P, sys_.Pf)
    comps = tuple(positive_definite_dyadic(*sys_.neg_derivative(k)) for k in range(n_comp))
    sampled: tuple[PDResult, ...] = ()
    if dt_q is not None:
        if dt_q <= 0:
            sampled = tuple(PDResult(False, f"control period {dt_q} is not positive")
                            for _ in range(n_comp))
        else:
            sampled = tuple(positive_definite_dyadic(*sys_.sampled(k, dt_q))
                            for k in range(n_comp))
    decay: tuple[PDResult, ...] = ()
    if rate_q is not None:
        decay = tuple(positive_definite_dyadic(*sys_.decay(k, rate_q)) for k in range(n_comp))
    return LyapunovCheck(p_result, comps, dt_q, sampled, rate_q, decay)


def certified_decay_rate(P: npt.ArrayLike, A: npt.ArrayLike, *,
                         digits: int = 4) -> Fraction:
    """The largest decay rate (to ``digits`` significant digits) that checks exactly.

    The best rate is ``lambda* = min_k lambda_min(-(A_k^T P + P A_k), P)`` (a generalized
    eigenvalue). It is rounded *down* to a short decimal and verified with
    :func:`check_lyapunov`; if rounding was not enough, it is lowered until it verifies.

    Parameters
    ----------
    P : array_like, shape (n, n)
    A : array_like, shape (K, n, n)
    digits : int, optional
        Significant decimal digits of the result.

    Returns
    -------
    Fraction
        ``lambda >= 0`` with ``A_k^T P + P A_k + lambda P < 0`` for all k, exactly; ``0`` when
        the continuous-time conditions themselves fail or no positive rate verifies.
    """
    Pf = np.asarray(P, dtype=np.float64)
    Af = np.asarray(A, dtype=np.float64)
    try:
        best = min(float(scipy.linalg.eigh(-(a.T @ Pf + Pf @ a), Pf, eigvals_only=True)[0])
                   for a in Af)
    except (np.linalg.LinAlgError, ValueError):
        return Fraction(0)
    if not math.isfinite(best) or best <= 0:
        return Fraction(0)
    lam = best * (1.0 - 10.0 ** -(digits + 1))
    for _ in range(60):
        exp10 = math.floor(math.log10(lam)) - digits + 1
        unit = Fraction(10) ** exp10
        cand = Fraction(math.floor(Fraction(lam) / unit)) * unit
        if cand.denominator >= MAX_RATIONAL or cand.numerator >= MAX_RATIONAL:
            cand = Fraction(1, MAX_RATIONAL // 10)  # the smallest rate a certificate states
        if cand > 0 and check_lyapunov(Pf, Af, rate=cand).ok:
            return cand
        lam /= 2.0
    return Fraction(0)
