"""Cutting planes that inner-approximate a mode boundary (paper Sec. 5.2, appendix E.3).

A cut is a hyperplane through a last in-mode state with a unit normal pointing out of the mode.
It is learned from one *invariance failure* (paper Sec. 5.2): the triple of the mode-entry state
``x^0``, the last in-mode state ``x^{T_f-1}`` and the first state outside the mode ``x^{T_f}``.

The cut problem (paper appendix E.3, "QCQP Optimization Details")
------------------------------------------------------------------
Write ``l = x^{T_f-1}``, ``d = x* - l``, ``s = x^{T_f} - l`` and ``c_j = q_j - l`` for the points
``q_j`` that must stay on the inner side (the entry state ``x^0`` and the points of the earlier
cuts of the mode). The normal ``w`` of the plane through ``l`` solves::

    minimise    (w . d)^2                       (squared distance of the plane to x*)
    subject to  ||w|| = 1
                w . d   <= 0                    (x* inside)
                w . c_j <= 0   for all j        (x^0 and earlier cut points inside)
                w . s   >  0                    (x^{T_f} outside: the cut separates the failure)

The last constraint is not written in the appendix, but the paper's text requires it ("a cut
that separates the failure state"). A strict inequality has no minimiser when the infimum lies on
``w . s = 0``, so we ask for a margin ``w . s_hat >= mu`` (``s_hat = s / ||s||``, ``mu`` =
``margin``, default ``1e-3``): the failure state lies beyond the plane by at least ``mu ||s||``.

Exact global solution. All constraints but the norm are homogeneous, so the admissible normals
are the unit vectors of the convex cone ``K = {w : C w <= 0, s_hat . w >= mu ||w||}`` (a
polyhedral cone cut by one circular cone). On ``K`` we have ``w . d <= 0``, so minimising
``(w . d)^2`` means maximising ``w . d_hat`` over ``K`` intersected with the unit sphere:

1. *Optimum 0 (the plane passes through x*).* It is attained iff some ``w`` in ``K`` has
   ``w . d = 0``. The largest separation among such normals is
   ``max {s_hat . w : C w <= 0, d . w = 0, ||w|| <= 1} = ||Proj_K0(s_hat)||`` where ``K0`` is
   the polyhedral cone ``{C w <= 0, d . w = 0}`` (Moreau decomposition). The projection is
   ``s_hat - G^T lambda`` with ``lambda >= 0`` the non-negative least-squares solution over
   the generators ``G`` of the polar cone (rows of ``C``, ``d`` and ``-d``); Lawson-Hanson NNLS
   is a finite active-set method, so this is exact up to rounding. If the norm is ``>= mu`` the
   answer is the normalised projection: the cut through ``x*`` that separates the failure most.
2. *Otherwise* every admissible ``w`` has ``w . d < 0``. A linear function has no interior
   local maximum on a sphere restricted to a face of ``K`` (its only critical point on a great
   sphere is the global maximiser ``+Proj(d)``, which would have ``w . d > 0``), so the maximum
   lies on a 0-dimensional piece of the boundary of ``K`` on the sphere: either a ray where
   ``n-1`` independent planes ``c_j . w = 0`` meet, or a point of the circle
   ``s_hat . w = mu`` where ``k-1`` planes meet, given in closed form by the Lagrange condition
   on that circle. Where ``d . w`` is constant on such a circle (``s`` in the span of ``d``
   and the active planes' normals) all its points tie and one of them is taken: with no further
   plane meeting the circle, no 0-dimensional piece holds the optimum.

Is branch 2 a convex problem? No. The obvious relaxation, ``max d_hat . w`` over ``K`` cap
the unit *ball* (a second-order cone program), is useless here: ``d_hat . w <= 0`` on ``K``, so
its optimum is 0, attained at ``w = 0`` (or, when it has norm 1, by the plane through x* that
branch 1 already found). Away from branch 1, ``d_hat . w < 0`` on ``K`` minus the origin and
the section ``S = K cap {d_hat . w = -1}`` is compact and convex; writing ``w = -d_hat + y`` with
``y . d_hat = 0``, the unit normal is ``w / ||w||`` with ``d_hat . w / ||w|| =
-1 / sqrt(1 + ||y||^2)``, so the cut problem is *maximising the convex function ||y|| over
S*, not a convex program: its optimum lies at an extreme point of ``S`` (the 0-dimensional
pieces above). Norm maximisation over a polytope given by inequalities is NP-hard when the
dimension is part of the input (Bodlaender, Gritzmann, Klee and van Leeuwen, Combinatorica
10, 1990), so unless P = NP no polynomial-time method returns the global optimum for every
``n``; for a fixed ``n`` the faces are polynomially many.

Methods for branch 2 (``method=`` of :func:`solve_cut_detailed`):

``"enumerate"`` (the baseline)
    Every subset of planes: at most ``sum_{i < n} C(m, i)`` small linear algebra problems,
    batched, keeping the feasible candidates and taking the best. A global optimum, but
    exponential in ``n``: 0.14 s at ``n = 4`` with 40 inner points, 12-19 s at ``n = 6``
    (``benchmarks/bench_cuts.py`` measured 26 s on another machine).
``"hull"``
    Only the faces of the polyhedral cone ``P0 = {C w <= 0}``: with ``g`` interior to ``P0``
    (minus the minimum-norm point of the convex hull of the rows, one NNLS), the points
    ``c_j / (-g . c_j)`` span a polytope in ``n - 1`` dimensions whose faces are polar to those
    of ``P0`` (Qhull). Its facets give the extreme rays of ``P0``; the subsets of size
    ``<= n - 2`` of the triangulated facets span every face of ``P0`` of dimension ``>= 2``
    and so give every margin-circle candidate that can be feasible; redundant rows never
    enter. The same global optimum as the enumeration, with ``O(m^{floor((n-1)/2)})`` faces
    (upper bound theorem): about 1 ms at ``n = 4`` with 40 points, 30 ms at ``n = 6``.
    Where it does not apply (``n = 2``, ``P0`` without interior or not pointed) the
    enumeration runs if it is cheap (``<= 20,000`` subsets).
``"local"``
    Polynomial time in ``n`` and ``m``: the most separating normal ``Proj_P0(s_hat)`` (one
    NNLS; it is admissible exactly when a cut exists), a local maximiser of ``d_hat . w`` from
    it (SLSQP, bounded iterations) and that point polished to the closed form of its active
    set. The best admissible one is returned with ``optimal=False``: a verified separating
    cut, possibly not the closest to x*.
``"auto"`` (default; ``"hull"`` is the same)
    ``"hull"`` (or the cheap enumeration) while the candidate count stays within budget
    (``2^{n-1}`` times the number of hull simplices ``<= 200,000``), ``"local"`` beyond, and
    ``"local"`` also if no exact candidate survives the re-check.

Existence is decided exactly before branch 2 (except by ``"enumerate"``, which keeps its
historical rule: refuse iff no candidate is admissible): a cut exists iff ``max {s_hat . w :
C w <= 0, ||w|| <= 1} = ||Proj_P0(s_hat)|| >= mu`` (Moreau), and the NNLS multipliers are
the dual certificate of a refusal.

Every answer, from any branch and method, re-checks every constraint (unit norm, each inner
point, the margin); :class:`~tli_verify.errors.SolverError` is raised when no admissible normal
exists (the failure direction lies in the cone spanned by the inner points: no plane through
``x^{T_f-1}`` separates them).

References
----------
.. [1] Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing
   Motion Policies from Demonstrations", CoRL 2022, Sec. 5.2 and appendix E.3.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from tli_verify.errors import ModelError, SolverError

__all__ = [
    "Cut",
    "CutMethod",
    "CutSolution",
    "InvarianceFailure",
    "cut_offsets",
    "inside_cuts",
    "solve_cut",
    "solve_cut_detailed",
]

FloatArray = npt.NDArray[np.float64]

CutMethod = Literal["auto", "hull", "enumerate", "local"]
"""How :func:`solve_cut_detailed` searches the boundary of K (see the module docstring)."""

_METHODS = ("auto", "hull", "enumerate", "local")

_UNIT_TOL = 1e-6
"""Largest accepted deviation of ``||normal||`` from 1."""


def _vector(value: npt.ArrayLike, name: str, *, error: type[Exception] = ModelError) -> FloatArray:
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise error(f"{name} must be a vector of numbers") from None
    if arr.ndim != 1 or arr.size < 1:
        raise error(f"{name} must be a vector of shape (n,), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise error(f"{name} must be finite")
    return arr


@dataclass(frozen=True, slots=True)
class Cut:
    """One cutting plane ``{x : normal . (x - point) = 0}``; the mode is on the side
    ``normal . (x - point) <= 0``.

    Attributes
    ----------
    normal : ndarray, shape (n,)
        Unit outward normal ``w`` (``| ||w|| - 1 | <= 1e-6`` is enforced; stored as given).
    point : ndarray, shape (n,)
        A point on the plane (the last in-mode state ``x^{T_f - 1}``).

    Raises
    ------
    ModelError
        If the arrays are not finite vectors of one dimension ``n >= 2`` or the normal is not
        a unit vector.
    """

    normal: FloatArray
    point: FloatArray

    def __post_init__(self) -> None:
        normal = _vector(self.normal, "cut normal")
        point = _vector(self.point, "cut point")
        if normal.shape != point.shape:
            raise ModelError(f"cut normal has shape {normal.shape} but point has {point.shape}")
        if normal.size < 2:
            raise ModelError("cuts need dimension n >= 2")
        norm = float(np.linalg.norm(normal))
        if abs(norm - 1.0) > _UNIT_TOL:
            raise ModelError(f"cut normal must be a unit vector, its norm is {norm:.9g}")
        normal.setflags(write=False)
        point.setflags(write=False)
        object.__setattr__(self, "normal", normal)
        object.__setattr__(self, "point", point)

    @property
    def dim(self) -> int:
        """State dimension ``n``."""
        return int(self.normal.size)

    def offset(self, attractor: npt.ArrayLike) -> float:
        """``h = w . (p - x*)``: distance of ``x*`` inside the plane (0: the plane holds x*)."""
        x_star = _vector(attractor, "attractor")
        if x_star.shape != self.normal.shape:
            raise ModelError(f"attractor has shape {x_star.shape}, cut has dimension {self.dim}")
        return float(self.normal @ (self.point - x_star))

    def to_dict(self) -> dict[str, list[float]]:
        """JSON form ``{"normal": [...], "point": [...]}`` (the model file's cut entry)."""
        return {"normal": [float(v) for v in self.normal],
                "point": [float(v) for v in self.point]}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str = "cut") -> Cut:
        """Read the JSON form; errors name ``where`` (e.g. ``"modes.reach.cuts[2]"``).

        Raises
        ------
        ModelError
            On a missing or malformed field.
        """
        if not isinstance(data, Mapping):
            raise ModelError(f"{where}: expected an object with 'normal' and 'point'")
        extra = set(data) - {"normal", "point"}
        if extra:
            raise ModelError(f"{where}: unknown field(s) {sorted(extra)}")
        for key in ("normal", "point"):
            if key not in data:
                raise ModelError(f"{where}: missing field '{key}'")
            value = data[key]
            if not isinstance(value, list) or not all(
                isinstance(v, int | float) and not isinstance(v, bool) for v in value
            ):
                raise ModelError(f"{where}.{key}: expected a list of numbers")
        try:
            return cls(normal=np.array(data["normal"], dtype=np.float64),
                       point=np.array(data["point"], dtype=np.float64))
        except ModelError as exc:
            raise ModelError(f"{where}: {exc}") from None


@dataclass(frozen=True, slots=True)
class InvarianceFailure:
    """An observed mode exit (paper Sec. 5.2).

    Attributes
    ----------
    entry : ndarray, shape (n,)
        Mode-entry state ``x^0``.
    last_inside : ndarray, shape (n,)
        Last in-mode state ``x^{T_f - 1}``.
    outside : ndarray, shape (n,)
        Failure state ``x^{T_f}``, the first state the sensor reports outside the mode.
    """

    entry: FloatArray
    last_inside: FloatArray
    outside: FloatArray

    def __post_init__(self) -> None:
        arrays = [_vector(getattr(self, k), f"failure.{k}")
                  for k in ("entry", "last_inside", "outside")]
        if len({a.shape for a in arrays}) != 1:
            raise ModelError("invariance failure states must have one dimension")
        for key, arr in zip(("entry", "last_inside", "outside"), arrays, strict=True):
            arr.setflags(write=False)
            object.__setattr__(self, key, arr)


@dataclass(frozen=True, slots=True)
class CutSolution:
    """A solved cut problem with its diagnostics.

    Attributes
    ----------
    cut : Cut
        The plane through ``x^{T_f-1}``.
    distance : float
        Distance of the plane to ``x*`` (``|w . d|``; the square root of the QCQP objective).
    separation : float
        ``w . (x^{T_f} - x^{T_f-1})``, > 0.
    through_attractor : bool
        True when the optimum is 0: the plane holds ``x*`` (a degenerate cut, see
        :mod:`tli_verify.boundary.modulation`).
    candidates : int
        Number of boundary candidates examined (0 when branch 1 answered).
    optimal : bool
        True when the cut is the global optimum of the QCQP (branch 1, or a complete candidate
        set); False for the polynomial-time local answer, which is a verified separating cut
        (every constraint re-checked) but possibly not the closest to ``x*``.
    method : str
        What produced the answer: ``"projection"`` (branch 1), ``"hull"``, ``"enumerate"``
        or ``"local"``.
    """

    cut: Cut
    distance: float
    separation: float
    through_attractor: bool
    candidates: int
    optimal: bool = True
    method: str = "enumerate"


def _previous_points(previous: Sequence[Cut | npt.ArrayLike], n: int) -> list[FloatArray]:
    points = []
    for i, item in enumerate(previous):
        p = item.point if isinstance(item, Cut) else _vector(item, f"previous[{i}]")
        if p.shape != (n,):
            raise ModelError(f"previous[{i}] has dimension {p.size}, expected {n}")
        points.append(p)
    return points


def _nnls_projection(target: FloatArray, generators: FloatArray) -> FloatArray:
    """Euclidean projection of ``target`` onto the polar of ``cone(generators)``.

    Returns ``target - G^T lambda`` with ``lambda = argmin_{>=0} ||target - G^T lambda||``.
    """
    from scipy.optimize import nnls

    if generators.shape[0] == 0:
        return target.copy()
    lam, _ = nnls(generators.T, target)
    return np.asarray(target - generators.T @ lam, dtype=np.float64)


def _null_vectors(rows: FloatArray, tol: float) -> tuple[FloatArray, FloatArray]:
    """Batched null spaces of stacked matrices.

    Parameters
    ----------
    rows : ndarray, shape (B, r, n)

    Returns
    -------
    bases : ndarray, shape (B, n, n)
        Right singular vectors (columns), last ones span the null space.
    rank : ndarray, shape (B,)
    """
    _, sv, vt = np.linalg.svd(rows, full_matrices=True)
    rank = np.sum(sv > tol, axis=1)
    return np.swapaxes(vt, 1, 2), rank


def solve_cut_detailed(
    failure: InvarianceFailure,
    attractor: npt.ArrayLike,
    *,
    previous: Sequence[Cut | npt.ArrayLike] = (),
    keep_inside: npt.ArrayLike | None = None,
    margin: float = 1e-3,
    method: CutMethod = "auto",
) -> CutSolution:
    """Solve the cut QCQP of paper appendix E.3 (see the module docstring).

    Parameters
    ----------
    failure : InvarianceFailure
        ``(x^0, x^{T_f-1}, x^{T_f})``, each of shape (n,), ``n >= 2``.
    attractor : array_like, shape (n,)
        The mode's attractor ``x*``.
    previous : sequence of Cut or array_like, optional
        Earlier cuts of this mode (their points must stay inside), or the points themselves.
    keep_inside : array_like, shape (k, n), optional
        More states that must stay on the inner side (an extension of appendix E.3: e.g. every
        observed mode-entry state, not only this failure's ``x^0``). Each adds one row to ``C``.
    margin : float, optional
        ``mu`` in ``w . (x^{T_f} - x^{T_f-1}) >= mu ||x^{T_f} - x^{T_f-1}||``; in ``(0, 1)``.
    method : {"auto", "hull", "enumerate", "local"}, optional
        ``"enumerate"``: every subset of planes (the baseline, exponential in ``n``);
        ``"hull"`` and ``"auto"`` (default): only the faces of the polyhedral cone (Qhull),
        or the enumeration where the hull does not apply and the enumeration is cheap, and
        the local answer beyond these budgets; ``"local"``: the polynomial-time verified
        separating cut. ``CutSolution.method`` tells which ran, ``CutSolution.optimal``
        whether the answer is proved globally optimal.

    Returns
    -------
    CutSolution
        ``optimal`` says whether the answer is the global optimum.

    Raises
    ------
    SolverError
        When no unit normal satisfies the constraints (no separating cut exists).
    ModelError
        On malformed input (shapes, non-finite values, bad margin).

    References
    ----------
    Paper appendix E.3 (the QCQP) and Sec. 5.2 (separation of the failure state).
    """
    if not 0.0 < margin < 1.0:
        raise ModelError(f"margin must be in (0, 1), got {margin}")
    if method not in _METHODS:
        raise ModelError(f"method must be one of {', '.join(_METHODS)}, got {method!r}")
    x_star = _vector(attractor, "attractor")
    last = failure.last_inside
    n = last.size
    if x_star.shape != (n,):
        raise ModelError(f"attractor has dimension {x_star.size}, failure has {n}")
    if n < 2:
        raise ModelError("cuts need dimension n >= 2")
    inner = [x_star, failure.entry, *_previous_points(previous, n)]
    if keep_inside is not None:
        extra = np.asarray(keep_inside, dtype=np.float64)
        if extra.ndim != 2 or extra.shape[1] != n or not np.all(np.isfinite(extra)):
            raise ModelError(f"keep_inside must be a finite (k, {n}) array, got {extra.shape}")
        inner.extend(extra)
    vecs = np.array([q - last for q in inner])  # (m0, n)
    s = failure.outside - last
    scale = max(float(np.max(np.abs(vecs), initial=0.0)), float(np.max(np.abs(s))), 1e-300)
    tiny = 1e-12 * scale
    s_norm = float(np.linalg.norm(s))
    if s_norm <= tiny:
        raise SolverError("no separating cut: the failure state equals the last in-mode state")
    s_hat = s / s_norm
    norms = np.linalg.norm(vecs, axis=1)
    keep = norms > tiny  # a point at x^{T_f-1} constrains nothing
    C = vecs[keep] / norms[keep, None]
    d_is_zero = not bool(keep[0])
    d_hat = np.zeros(n) if d_is_zero else vecs[0] / norms[0]
    feas_tol = 1e-10

    # Branch 1: a normal orthogonal to d (the plane holds x*), most separating. The cone
    # {C w <= 0, d . w = 0} lies in the complement of d: project s and the other rows there
    # (normalised; a row parallel to d up to rounding constrains nothing there), so that no
    # +-d generator pair enters the NNLS (with a row nearly parallel to d, such a pair
    # cancelled digits and the answer violated that row by 1e-4).
    if d_is_zero:
        proj = _nnls_projection(s_hat, C)
    else:
        perp = np.eye(n) - np.outer(d_hat, d_hat)
        rows = C[1:] @ perp  # C[0] is d_hat
        rn = np.linalg.norm(rows, axis=1)
        proj = _nnls_projection(perp @ s_hat, rows[rn > 1e-12] / rn[rn > 1e-12, None])
        proj -= float(proj @ d_hat) * d_hat
    pnorm = float(np.linalg.norm(proj))
    if pnorm >= margin * (1.0 + 1e-9):
        w = proj / pnorm
        return _finish(w, C, d_hat, s_hat, s_norm, norms, last, margin, 0, feas_tol,
                       degenerate=True, optimal=True, method="projection")
    if d_is_zero:
        raise SolverError(
            "no separating cut: every plane through the last in-mode state that keeps the "
            "entry state and earlier cut points inside also keeps the failure state inside"
        )

    # Branch 2: the optimum is a 0-dimensional boundary piece of K on the sphere.
    if method == "enumerate":
        W_all = _enumerated_candidates(C, d_hat, s_hat, margin)
        W_ok = _feasible(W_all, C, s_hat, margin, feas_tol)
        if W_ok.shape[0] == 0:
            raise SolverError(_NO_CUT_MESSAGE.format(margin=margin))
        return _finish(_best(W_ok, d_hat, s_hat), C, d_hat, s_hat, s_norm, norms, last, margin,
                       int(W_all.shape[0]), feas_tol, degenerate=False, optimal=True,
                       method="enumerate")

    # Existence first, exactly: max {s_hat . w : C w <= 0, ||w|| <= 1} = ||Proj_P0(s_hat)||
    # (Moreau; P0 = {C w <= 0}). Below the margin no cut exists and the NNLS multipliers are
    # the dual certificate; otherwise the normalised projection is an admissible normal.
    proj0 = _nnls_projection(s_hat, C)
    pn0 = float(np.linalg.norm(proj0))
    if pn0 < margin:
        raise SolverError(_NO_CUT_MESSAGE.format(margin=margin))
    w_sep = proj0 / pn0

    m = C.shape[0]
    W: FloatArray | None = None
    used = str(method)
    if method in ("auto", "hull"):
        W = _hull_candidates(C, d_hat, s_hat, margin, budget=_HULL_BUDGET)
        used = "hull"
    if W is None and method in ("auto", "hull") and _enumeration_size(m, n) <= _ENUM_BUDGET:
        W = _enumerated_candidates(C, d_hat, s_hat, margin)
        used = "enumerate"
    if W is not None:
        W_ok = _feasible(W, C, s_hat, margin, feas_tol)
        if W_ok.shape[0]:
            try:
                return _finish(_best(W_ok, d_hat, s_hat), C, d_hat, s_hat, s_norm, norms, last,
                               margin, int(W.shape[0]), feas_tol, degenerate=False,
                               optimal=True, method=used)
            except SolverError:
                pass  # numerically unsound candidate: fall back to the verified local answer
    # Polynomial-time fallback: local ascent from the most separating normal, re-checked.
    W_loc = _local_candidates(C, d_hat, s_hat, margin, w_sep)
    W_ok = _feasible(W_loc, C, s_hat, margin, feas_tol)
    if W_ok.shape[0] == 0:  # w_sep is admissible up to rounding; take it as it is
        W_ok = w_sep[None, :]
    return _finish(_best(W_ok, d_hat, s_hat), C, d_hat, s_hat, s_norm, norms, last, margin,
                   int(W_loc.shape[0]), feas_tol, degenerate=False, optimal=False, method="local")


_NO_CUT_MESSAGE = (
    "no separating cut: no plane through the last in-mode state keeps x*, the entry "
    "state and earlier cut points inside while putting the failure state outside "
    "(margin {margin:g})"
)

_HULL_BUDGET = 200_000
"""Largest number of boundary candidates the hull method generates before giving up."""

_ENUM_BUDGET = 20_000
"""Largest ``sum_{i<n} C(m, i)`` for which ``method="auto"`` enumerates without the hull."""


def _enumeration_size(m: int, n: int) -> int:
    """Number of subsets the plain enumeration visits: ``sum_{i < n} C(m, i)``."""
    return sum(math.comb(m, i) for i in range(n))


def _feasible(W: FloatArray, C: FloatArray, s_hat: FloatArray, margin: float,
              tol: float) -> FloatArray:
    """Rows of ``W`` (normalised) meeting every constraint up to ``tol``."""
    if W.shape[0] == 0:
        return W
    norms = np.linalg.norm(W, axis=1, keepdims=True)
    W = W[norms[:, 0] > 0] / norms[norms[:, 0] > 0]
    ok = np.all(W @ C.T <= tol, axis=1) & (W @ s_hat >= margin - tol)
    return np.asarray(W[ok], dtype=np.float64)


def _best(W_ok: FloatArray, d_hat: FloatArray, s_hat: FloatArray) -> FloatArray:
    """Largest ``d_hat . w``; among ties (1e-12) the most separating."""
    obj = W_ok @ d_hat
    best = float(np.max(obj))
    ties = obj >= best - 1e-12
    return np.asarray(W_ok[int(np.argmax(np.where(ties, W_ok @ s_hat, -np.inf)))])


def _enumerated_candidates(C: FloatArray, d_hat: FloatArray, s_hat: FloatArray,
                           margin: float) -> FloatArray:
    """Every 0-dimensional boundary piece of K on the sphere, by plain enumeration.

    The baseline (``method="enumerate"``): ``sum_{i < n} C(m, i)`` subsets of the rows of
    ``C``, shape (m, n). Returns candidate normals, shape (N, n), not yet checked.
    """
    m, n = C.shape
    cands: list[FloatArray] = []
    # (i) rays where n-1 constraint planes meet
    if m >= n - 1:
        idx = np.array(list(itertools.combinations(range(m), n - 1)), dtype=np.intp)
        bases, rank = _null_vectors(C[idx], 1e-12)
        ok = rank == n - 1
        u = bases[ok, :, -1]
        cands.extend([u, -u])
    # (ii) points of the circle s_hat . w = mu where k-1 planes meet (k = dim of null space)
    for size in range(0, min(n - 1, m + 1)):
        if size == 0:
            subsets = [np.eye(n)]
            dims = [n]
        else:
            idx = np.array(list(itertools.combinations(range(m), size)), dtype=np.intp)
            bases, rank = _null_vectors(C[idx], 1e-12)
            subsets = [bases[b, :, int(rank[b]):] for b in range(len(idx))]
            dims = [n - int(r) for r in rank]
        for B, k in zip(subsets, dims, strict=True):
            if k < 2:
                continue
            a = B.T @ s_hat
            b = B.T @ d_hat
            aa = float(a @ a)
            if aa < margin * margin:
                continue
            y0 = (margin / aa) * a
            rho = np.sqrt(max(0.0, 1.0 - margin * margin / aa))
            if k == 2:  # the 'circle' is two points: both are candidates
                z = np.array([-a[1], a[0]]) / np.sqrt(aa)
                cands.append(np.array([B @ (y0 + rho * z), B @ (y0 - rho * z)]))
                continue
            b_perp = b - (float(b @ a) / aa) * a
            # twice: when b is nearly parallel to a the first pass leaves a part along a of
            # relative size eps / ||b_perp||, enough to move the point off the margin circle
            b_perp -= (float(b_perp @ a) / aa) * a
            bp = float(np.linalg.norm(b_perp))
            if bp > 1e-12:
                cands.append((B @ (y0 + rho * b_perp / bp))[None, :])
            else:
                # d . w is constant on this circle: every point of it is as good. Where other
                # planes cut the circle, the pieces with more planes hold the feasible points;
                # where none does (every plane already in the subset, e.g. m < n - 2 inner
                # points), any point of the circle is one, so offer one.
                i = int(np.argmin(np.abs(a)))
                u = -(a[i] / aa) * a
                u[i] += 1.0
                u -= (float(u @ a) / aa) * a
                cands.append((B @ (y0 + rho * u / np.linalg.norm(u)))[None, :])
    return np.vstack(cands) if cands else np.zeros((0, n))


def _ray_candidates(C: FloatArray, idx: npt.NDArray[np.intp]) -> FloatArray:
    """``+-u`` for every subset (rows of ``idx``, shape (B, n-1)) whose planes meet in a ray."""
    n = C.shape[1]
    if idx.shape[0] == 0:
        return np.zeros((0, n))
    bases, rank = _null_vectors(C[idx], 1e-12)
    u = bases[rank == n - 1, :, -1]
    return np.vstack([u, -u])


def _circle_candidates(C: FloatArray, idx: npt.NDArray[np.intp], d_hat: FloatArray,
                       s_hat: FloatArray, margin: float) -> FloatArray:
    """Maximiser of ``d_hat . w`` on the circle ``{s_hat . w = mu, ||w|| = 1}`` of the null
    space of each subset of planes (rows of ``idx``, shape (B, size)); batched form of the
    circle branch of :func:`_enumerated_candidates` (same closed forms, same tie rule)."""
    n = C.shape[1]
    if idx.shape[1] == 0:
        bases = np.eye(n)[None, :, :]
        rank = np.zeros(1)
    else:
        bases, rank = _null_vectors(C[idx], 1e-12)
    out: list[FloatArray] = []
    for r in np.unique(rank):
        k = n - int(r)
        if k < 2:
            continue
        B = bases[rank == r][:, :, int(r):]  # (G, n, k)
        a = np.einsum("gnk,n->gk", B, s_hat)
        b = np.einsum("gnk,n->gk", B, d_hat)
        aa = np.einsum("gk,gk->g", a, a)
        keep = aa >= margin * margin
        B, a, b, aa = B[keep], a[keep], b[keep], aa[keep]
        if B.shape[0] == 0:
            continue
        y0 = (margin / aa)[:, None] * a
        rho = np.sqrt(np.maximum(0.0, 1.0 - margin * margin / aa))[:, None]
        if k == 2:
            z = np.column_stack([-a[:, 1], a[:, 0]]) / np.sqrt(aa)[:, None]
            out.append(np.einsum("gnk,gk->gn", B, y0 + rho * z))
            out.append(np.einsum("gnk,gk->gn", B, y0 - rho * z))
            continue
        b_perp = b - (np.einsum("gk,gk->g", b, a) / aa)[:, None] * a
        b_perp -= (np.einsum("gk,gk->g", b_perp, a) / aa)[:, None] * a
        bp = np.linalg.norm(b_perp, axis=1)
        # constant d . w on the circle: one point of it (as in _enumerated_candidates)
        i = np.argmin(np.abs(a), axis=1)
        ai = a[np.arange(a.shape[0]), i]
        u = -(ai / aa)[:, None] * a
        u[np.arange(a.shape[0]), i] += 1.0
        u -= (np.einsum("gk,gk->g", u, a) / aa)[:, None] * a
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        direction = np.where((bp > 1e-12)[:, None], b_perp / np.maximum(bp, 1e-300)[:, None], u)
        out.append(np.einsum("gnk,gk->gn", B, y0 + rho * direction))
    return np.vstack(out) if out else np.zeros((0, n))


def _hull_candidates(C: FloatArray, d_hat: FloatArray, s_hat: FloatArray, margin: float,
                     *, budget: int) -> FloatArray | None:
    """The 0-dimensional boundary pieces of K that can hold the optimum, from the face
    lattice of ``P0 = {C w <= 0}`` (convex hull by Qhull); None where the method does not
    apply (``n < 3``, ``P0`` without interior or not pointed, Qhull failing, over budget).

    With ``g`` interior to ``P0`` (``C g < 0``), the points ``p_j = c_j / (-g . c_j)`` lie on
    the hyperplane ``g . x = -1``; the faces of their convex hull (dimension ``n - 1``) are the
    sections of the faces of ``cone(rows of C)``, which are polar to the faces of ``P0``: a
    facet gives an extreme ray of ``P0`` (its planes meet in it), a face of dimension
    ``n - 1 - k`` a face of ``P0`` of dimension ``k`` whose linear span is the null space of
    the planes of any ``n - k`` affinely independent points of it. Every face of a
    triangulated facet is spanned by a subset of one simplex, so the simplices of the
    triangulated hull and their subsets of size ``<= n - 2`` give every candidate of
    :func:`_enumerated_candidates` that can be feasible, and rows inside the hull (redundant
    constraints) are never enumerated.
    """
    from scipy.spatial import ConvexHull, QhullError

    m, n = C.shape
    if n < 3 or m < n:
        return None
    # g: minus the minimum-norm point p of conv(rows) (c_j . p >= ||p||^2 > 0 for every j)
    from scipy.optimize import nnls

    weight = 1e3
    A = np.vstack([C.T, weight * np.ones((1, m))])
    lam, _ = nnls(A, np.concatenate([np.zeros(n), [weight]]))
    if lam.sum() <= 0.0:
        return None
    g = -(C.T @ lam) / lam.sum()
    g_norm = float(np.linalg.norm(g))
    if g_norm < 1e-9:
        return None
    g /= g_norm
    h = -(C @ g)
    if float(np.min(h)) <= 1e-9:
        return None
    _, _, vt = np.linalg.svd(g[None, :])
    Y = (C / h[:, None]) @ vt[1:].T  # (m, n-1) section coordinates
    try:
        hull = ConvexHull(Y)
    except (QhullError, ValueError):
        return None
    simplices = np.asarray(hull.simplices, dtype=np.intp)  # (F, n-1)
    if simplices.shape[0] * 2 ** (n - 1) > budget:
        return None
    parts = [_ray_candidates(C, simplices)]
    parts.append(_circle_candidates(C, np.zeros((1, 0), dtype=np.intp), d_hat, s_hat, margin))
    for size in range(1, n - 1):
        cols = np.array(list(itertools.combinations(range(n - 1), size)), dtype=np.intp)
        sub = np.sort(simplices[:, cols].reshape(-1, size), axis=1)
        if float(m) ** size < 2.0**62:  # one integer key per subset: a 1-D unique is faster
            keys = sub @ (m ** np.arange(size - 1, -1, -1, dtype=np.int64))
            _, first = np.unique(keys, return_index=True)
            sub = sub[first]
        else:
            sub = np.unique(sub, axis=0)
        parts.append(_circle_candidates(C, sub, d_hat, s_hat, margin))
    return np.vstack(parts)


def _local_candidates(C: FloatArray, d_hat: FloatArray, s_hat: FloatArray, margin: float,
                      w_start: FloatArray) -> FloatArray:
    """Polynomial-time candidates: the most separating normal ``w_start``, a local maximiser
    of ``d_hat . w`` from it (SLSQP on the sphere) and that point polished to the closed form
    of its active set (a ray or a margin-circle point). Shape (N, n), not yet checked."""
    from scipy.optimize import minimize

    n = C.shape[1]
    cons: list[dict[str, Any]] = [
        {"type": "eq", "fun": lambda w: w @ w - 1.0, "jac": lambda w: 2.0 * w},
        {"type": "ineq", "fun": lambda w: s_hat @ w - margin, "jac": lambda w: s_hat},
        {"type": "ineq", "fun": lambda w: -(C @ w), "jac": lambda w: -C},
    ]
    out = [w_start[None, :]]
    res = minimize(lambda w: -(d_hat @ w), w_start, jac=lambda w: -d_hat, constraints=cons,
                   method="SLSQP", options={"maxiter": 200, "ftol": 1e-13})
    w = np.asarray(res.x, dtype=np.float64)
    if np.all(np.isfinite(w)) and np.linalg.norm(w) > 0:
        w = w / np.linalg.norm(w)
        out.append(w[None, :])
        active = np.flatnonzero(C @ w > -1e-7)
        if float(s_hat @ w) - margin < 1e-7 and active.size <= n - 2:
            out.append(_circle_candidates(C, active[None, :], d_hat, s_hat, margin))
        elif active.size >= n - 1:
            rows = C[active]
            _, sv, vt = np.linalg.svd(rows)
            if sv.size >= n - 1 and sv[n - 2] > 1e-12 and (sv.size < n or sv[-1] <= 1e-9):
                out.append(np.vstack([vt[-1], -vt[-1]]))
    return np.vstack(out)


def _finish(
    w: FloatArray,
    C: FloatArray,
    d_hat: FloatArray,
    s_hat: FloatArray,
    s_norm: float,
    norms: FloatArray,
    last: FloatArray,
    margin: float,
    candidates: int,
    tol: float,
    *,
    degenerate: bool,
    optimal: bool,
    method: str,
) -> CutSolution:
    """Re-check every constraint of the answer independently of how it was found."""
    w = w / np.linalg.norm(w)
    if not np.all(np.isfinite(w)):
        raise SolverError("cut solver produced a non-finite normal")
    viol = float(np.max(C @ w, initial=-np.inf))
    if viol > tol:
        raise SolverError(f"cut re-check failed: an inner point lies {viol:.3g} outside")
    sep = float(w @ s_hat)
    if not sep >= margin - tol or sep <= 0.0:
        raise SolverError(f"cut re-check failed: failure state not separated ({sep:.3g})")
    dist = abs(float(w @ d_hat)) * float(norms[0])
    if degenerate:
        dist = 0.0
    return CutSolution(
        cut=Cut(normal=w, point=last.copy()),
        distance=dist,
        separation=sep * s_norm,
        through_attractor=degenerate,
        candidates=candidates,
        optimal=optimal,
        method=method,
    )


def solve_cut(
    failure: InvarianceFailure,
    attractor: npt.ArrayLike,
    *,
    previous: Sequence[Cut | npt.ArrayLike] = (),
    keep_inside: npt.ArrayLike | None = None,
    margin: float = 1e-3,
    method: CutMethod = "auto",
) -> Cut:
    """Cut for one invariance failure: :func:`solve_cut_detailed` without the diagnostics.

    Parameters
    ----------
    failure : InvarianceFailure
    attractor : array_like, shape (n,)
    previous : sequence of Cut or array_like, optional
    keep_inside : array_like, shape (k, n), optional
    margin : float, optional
    method : {"auto", "hull", "enumerate", "local"}, optional

    Returns
    -------
    Cut

    Raises
    ------
    SolverError
        When no separating cut exists.
    """
    return solve_cut_detailed(failure, attractor, previous=previous, keep_inside=keep_inside,
                              margin=margin, method=method).cut


def cut_offsets(cuts: Sequence[Cut], attractor: npt.ArrayLike) -> FloatArray:
    """``h_i = w_i . (p_i - x*)`` for every cut, shape (m,).

    ``h_i > 0``: ``x*`` strictly inside cut i; ``h_i = 0``: the plane holds ``x*``.
    """
    return np.array([c.offset(attractor) for c in cuts], dtype=np.float64)


def inside_cuts(
    X: npt.ArrayLike, cuts: Sequence[Cut], *, tol: float = 0.0
) -> npt.NDArray[np.bool_]:
    """Whether each state lies in the closed region bounded by the cuts.

    Parameters
    ----------
    X : array_like, shape (N, n)
    cuts : sequence of Cut
    tol : float, optional
        Accept ``w . (x - p) <= tol``.

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    Xa = np.asarray(X, dtype=np.float64)
    if Xa.ndim != 2:
        raise ModelError(f"states must have shape (N, n), got {Xa.shape}")
    if not cuts:
        return np.ones(Xa.shape[0], dtype=bool)
    W = np.array([c.normal for c in cuts])
    b = np.einsum("ij,ij->i", W, np.array([c.point for c in cuts]))
    return np.asarray(np.all(Xa @ W.T - b <= tol, axis=1))
