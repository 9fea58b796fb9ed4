"""Named regions of a task's state space: boxes, polytopes, balls, ellipsoids and their unions,
intersections and differences, in any dimension.

A task (:mod:`tli_verify.tasks.task`) names the regions of its workspace that its sensors read
(paper Sec. 3: a mode is a set of states sharing a sensor reading; the learner never sees these
sets, only the readings). Every region is a closed set with

* :meth:`Region.contains` -- vectorised membership over states ``X`` of shape ``(N, n)``;
* :meth:`Region.contains_one` -- the same test on one state, in plain Python (the closed loop
  calls it once per control step, where numpy's per-call overhead would dominate);
* :meth:`Region.bounds` -- an axis-aligned bounding box (entries may be infinite), so a region
  can be sampled by rejection inside its box rather than the whole workspace;
* :meth:`Region.leaves` -- the primitive shapes it is built from. The boundary of a union,
  intersection or difference lies in the union of its leaves' boundaries, so a ball around
  ``x`` that meets no leaf's boundary lies inside or outside the region as a whole: the
  oracle's certified-deadline target (:func:`tli_verify.tasks.task.Task.clearance`) rests on
  that, with the exact distances of :mod:`tli_verify.tasks.geometry`.

The TOML form (a region's table in a task file; exactly one shape key)::

    box = { lower = [2, -inf], upper = [6, 6] }          # closed; sides may be infinite
    polytope = { A = [[1, 1], [-1, 0]], b = [1, 0] }     # {x : A x <= b}
    ball = { center = [0, 0, 0.5], radius = 0.2 }
    ellipsoid = { center = [0, 0], matrix = [[4, 0], [0, 1]] }   # (x-c)^T M (x-c) <= 1
    union = ["handle", { ball = { center = [0, 1], radius = 0.5 } }]
    intersection = [...]
    difference = ["table", "hole", ...]                  # the first minus all the others

Parts of a union, intersection or difference are region names (the named region's own set) or
inline shape tables.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 3 (modes as sets of states), Lemma 2 (each
mode's attractor lies inside the next mode).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TaskError
from tli_verify.limits import MAX_ABS_COVARIANCE, MAX_ABS_VALUE
from tli_verify.tasks import geometry

__all__ = [
    "SHAPES",
    "Ball",
    "Box",
    "Difference",
    "Ellipsoid",
    "Intersection",
    "Polytope",
    "Primitive",
    "Region",
    "Union",
    "parse_region",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

SHAPES = ("box", "polytope", "ball", "ellipsoid", "union", "intersection", "difference")
"""The shape keys of a region table (exactly one per region)."""

MAX_REGION_PARTS = 64
"""Most parts of one union, intersection or difference, and most rows of a polytope's ``A``
per dimension (a polytope may have up to ``64 * n`` faces)."""

MAX_REGION_DEPTH = 8
"""Deepest nesting of inline shapes in unions, intersections and differences."""


def _states(X: npt.ArrayLike, dim: int) -> FloatArray:
    Xa = np.asarray(X, dtype=np.float64)
    if Xa.ndim == 1:
        Xa = Xa[None, :]
    if Xa.ndim != 2 or Xa.shape[1] != dim:
        raise TaskError(f"states must be (N, {dim}), got shape {np.shape(X)}")
    return Xa


class Region:
    """A closed set of states in ``R^dim`` (the base of every region type)."""

    dim: int

    def contains(self, X: npt.ArrayLike) -> BoolArray:
        """Membership of each state, shape (N,), for ``X`` of shape (N, dim)."""
        raise NotImplementedError

    def contains_one(self, x: Sequence[float]) -> bool:
        """Membership of one state (a list of ``dim`` floats), in plain Python."""
        raise NotImplementedError

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        """An axis-aligned box ``(lo, hi)`` holding the region, each shape (dim,) (may be
        infinite)."""
        raise NotImplementedError

    def leaves(self) -> tuple[Primitive, ...]:
        """The primitive shapes the region is built from."""
        raise NotImplementedError

    def to_dict(self) -> dict[str, Any]:
        """The region's TOML/JSON form (its shape table)."""
        raise NotImplementedError


class Primitive(Region):
    """A convex shape with an exact signed distance (:mod:`tli_verify.tasks.geometry`)."""

    def signed_distance(self, X: npt.ArrayLike) -> FloatArray:
        """Signed Euclidean distance of each state to the shape, shape (N,): outside, the
        distance to the set (> 0); inside, minus the distance to its boundary."""
        raise NotImplementedError


@dataclass(frozen=True, slots=True, eq=False)
class Box(Primitive):
    """The closed box ``lower <= x <= upper`` (sides may be infinite).

    Attributes
    ----------
    lower, upper : ndarray, shape (dim,)
    """

    lower: FloatArray
    upper: FloatArray
    _pairs: tuple[tuple[float, float], ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_pairs", tuple(zip(self.lower.tolist(), self.upper.tolist(),
                                                     strict=True)))

    @property
    def dim(self) -> int:  # type: ignore[override]
        return int(self.lower.size)

    def contains(self, X: npt.ArrayLike) -> BoolArray:
        Xa = _states(X, self.dim)
        return np.asarray(np.all((Xa >= self.lower) & (Xa <= self.upper), axis=1))

    def contains_one(self, x: Sequence[float]) -> bool:
        for (a, b), v in zip(self._pairs, x, strict=True):
            if not a <= v <= b:
                return False
        return True

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        return self.lower.copy(), self.upper.copy()

    def leaves(self) -> tuple[Primitive, ...]:
        return (self,)

    def signed_distance(self, X: npt.ArrayLike) -> FloatArray:
        return np.asarray(geometry.box_signed_distance(self.lower, self.upper,
                                                       _states(X, self.dim)))

    def to_dict(self) -> dict[str, Any]:
        return {"box": {"lower": self.lower.tolist(), "upper": self.upper.tolist()}}


@dataclass(frozen=True, slots=True, eq=False)
class Polytope(Primitive):
    """The closed polytope ``{x : A x <= b}`` (non-empty; may be unbounded).

    Attributes
    ----------
    A : ndarray, shape (m, dim)
    b : ndarray, shape (m,)
    """

    A: FloatArray
    b: FloatArray

    @property
    def dim(self) -> int:  # type: ignore[override]
        return int(self.A.shape[1])

    def contains(self, X: npt.ArrayLike) -> BoolArray:
        Xa = _states(X, self.dim)
        return np.asarray(np.all(Xa @ self.A.T <= self.b, axis=1))

    def contains_one(self, x: Sequence[float]) -> bool:
        return bool(np.all(self.A @ np.asarray(x, dtype=np.float64) <= self.b))

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        lo, hi = geometry.polytope_bounds(self.A, self.b)
        return np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)

    def leaves(self) -> tuple[Primitive, ...]:
        return (self,)

    def signed_distance(self, X: npt.ArrayLike) -> FloatArray:
        return np.asarray(geometry.polytope_signed_distance(self.A, self.b,
                                                            _states(X, self.dim)))

    def to_dict(self) -> dict[str, Any]:
        return {"polytope": {"A": self.A.tolist(), "b": self.b.tolist()}}


@dataclass(frozen=True, slots=True, eq=False)
class Ball(Primitive):
    """The closed ball ``|x - center| <= radius``.

    Attributes
    ----------
    center : ndarray, shape (dim,)
    radius : float
    """

    center: FloatArray
    radius: float

    @property
    def dim(self) -> int:  # type: ignore[override]
        return int(self.center.size)

    def contains(self, X: npt.ArrayLike) -> BoolArray:
        Xa = _states(X, self.dim)
        d = Xa - self.center
        return np.asarray(np.einsum("ij,ij->i", d, d) <= self.radius * self.radius)

    def contains_one(self, x: Sequence[float]) -> bool:
        c = self.center.tolist()
        return sum((v - a) ** 2 for v, a in zip(x, c, strict=True)) <= self.radius ** 2

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        return self.center - self.radius, self.center + self.radius

    def leaves(self) -> tuple[Primitive, ...]:
        return (self,)

    def signed_distance(self, X: npt.ArrayLike) -> FloatArray:
        return np.asarray(geometry.ball_signed_distance(self.center, self.radius,
                                                        _states(X, self.dim)))

    def to_dict(self) -> dict[str, Any]:
        return {"ball": {"center": self.center.tolist(), "radius": self.radius}}


@dataclass(frozen=True, slots=True, eq=False)
class Ellipsoid(Primitive):
    """The closed ellipsoid ``(x - center)^T M (x - center) <= 1``, ``M`` positive definite.

    Attributes
    ----------
    center : ndarray, shape (dim,)
    matrix : ndarray, shape (dim, dim)
    """

    center: FloatArray
    matrix: FloatArray

    @property
    def dim(self) -> int:  # type: ignore[override]
        return int(self.center.size)

    def contains(self, X: npt.ArrayLike) -> BoolArray:
        d = _states(X, self.dim) - self.center
        return np.asarray(np.einsum("ij,jk,ik->i", d, self.matrix, d) <= 1.0)

    def contains_one(self, x: Sequence[float]) -> bool:
        d = np.asarray(x, dtype=np.float64) - self.center
        return float(d @ self.matrix @ d) <= 1.0

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        lo, hi = geometry.ellipsoid_bounds(self.center, self.matrix)
        return np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)

    def leaves(self) -> tuple[Primitive, ...]:
        return (self,)

    def signed_distance(self, X: npt.ArrayLike) -> FloatArray:
        return np.asarray(geometry.ellipsoid_signed_distance(self.center, self.matrix,
                                                             _states(X, self.dim)))

    def to_dict(self) -> dict[str, Any]:
        return {"ellipsoid": {"center": self.center.tolist(), "matrix": self.matrix.tolist()}}


@dataclass(frozen=True, slots=True, eq=False)
class _Composite(Region):
    """A combination of regions; ``names`` keeps how each part was written (a region name or
    None for an inline shape), for :meth:`to_dict`."""

    parts: tuple[Region, ...]
    names: tuple[str | None, ...] = ()

    @property
    def dim(self) -> int:  # type: ignore[override]
        return self.parts[0].dim

    def leaves(self) -> tuple[Primitive, ...]:
        out: list[Primitive] = []
        for p in self.parts:
            out += [leaf for leaf in p.leaves() if all(leaf is not q for q in out)]
        return tuple(out)

    def _written(self) -> list[Any]:
        names = self.names or (None,) * len(self.parts)
        return [n if n is not None else p.to_dict() for p, n in zip(self.parts, names,
                                                                    strict=True)]


class Union(_Composite):
    """The union of its parts."""

    def contains(self, X: npt.ArrayLike) -> BoolArray:
        out = self.parts[0].contains(X)
        for p in self.parts[1:]:
            out = out | p.contains(X)
        return np.asarray(out)

    def contains_one(self, x: Sequence[float]) -> bool:
        return any(p.contains_one(x) for p in self.parts)

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        boxes = [p.bounds() for p in self.parts]
        return (np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0))

    def to_dict(self) -> dict[str, Any]:
        return {"union": self._written()}


class Intersection(_Composite):
    """The intersection of its parts."""

    def contains(self, X: npt.ArrayLike) -> BoolArray:
        out = self.parts[0].contains(X)
        for p in self.parts[1:]:
            out = out & p.contains(X)
        return np.asarray(out)

    def contains_one(self, x: Sequence[float]) -> bool:
        return all(p.contains_one(x) for p in self.parts)

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        boxes = [p.bounds() for p in self.parts]
        return (np.max([b[0] for b in boxes], axis=0), np.min([b[1] for b in boxes], axis=0))

    def to_dict(self) -> dict[str, Any]:
        return {"intersection": self._written()}


class Difference(_Composite):
    """The first part minus every other part (closed: the parts removed are taken open, so a
    difference of closed sets stays closed up to the removed parts' boundaries, which belong to
    the difference)."""

    def contains(self, X: npt.ArrayLike) -> BoolArray:
        out = self.parts[0].contains(X)
        for p in self.parts[1:]:
            out = out & ~_interior(p, X)
        return np.asarray(out)

    def contains_one(self, x: Sequence[float]) -> bool:
        if not self.parts[0].contains_one(x):
            return False
        X = np.asarray([x], dtype=np.float64)
        return not any(bool(_interior(p, X)[0]) for p in self.parts[1:])

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        return self.parts[0].bounds()

    def to_dict(self) -> dict[str, Any]:
        return {"difference": self._written()}


def _interior(region: Region, X: npt.ArrayLike) -> BoolArray:
    """Membership of the open interior: inside and not on a leaf's boundary."""
    inside = region.contains(X)
    if not inside.any():
        return inside
    Xa = _states(X, region.dim)
    on_edge = np.zeros(len(Xa), dtype=bool)
    for leaf in region.leaves():
        on_edge |= leaf.signed_distance(Xa) == 0.0
    return np.asarray(inside & ~on_edge)


# ------------------------------------------------------------------------------ parsing
def _vector(raw: Any, dim: int, where: str, *, allow_inf: bool = False,
            bound: float = MAX_ABS_VALUE, limit: str = "MAX_ABS_VALUE") -> FloatArray:
    if not isinstance(raw, list) or len(raw) != dim or not all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in raw):
        raise TaskError(f"{where}: expected a list of {dim} numbers")
    try:
        out = np.array(raw, dtype=np.float64)
    except OverflowError:
        raise TaskError(f"{where}: a number too large for a double") from None
    if np.isnan(out).any() or (not allow_inf and not np.isfinite(out).all()):
        raise TaskError(f"{where}: expected {dim} finite numbers"
                        + (" (or +/-inf)" if allow_inf else ""))
    finite = out[np.isfinite(out)]
    if finite.size and float(np.abs(finite).max()) > bound:
        raise TaskError(f"{where}: {float(np.abs(finite).max()):g} is outside the declared "
                        f"range |v| <= {bound:g} ({limit})")
    out.setflags(write=False)
    return out


def _matrix(raw: Any, rows: int | None, cols: int, where: str) -> FloatArray:
    if not isinstance(raw, list) or not raw or (rows is not None and len(raw) != rows):
        want = f"{rows} rows" if rows is not None else "a non-empty list of rows"
        raise TaskError(f"{where}: expected {want} of {cols} numbers")
    return np.vstack([_vector(r, cols, f"{where}[{i}]", bound=MAX_ABS_COVARIANCE,
                              limit="MAX_ABS_COVARIANCE") for i, r in enumerate(raw)])


def _table(raw: Any, keys: Sequence[str], where: str) -> Mapping[str, Any]:
    if not isinstance(raw, dict):
        raise TaskError(f"{where}: expected a table with {', '.join(keys)}")
    unknown = sorted(set(raw) - set(keys))
    missing = [k for k in keys if k not in raw]
    if unknown:
        raise TaskError(f"{where}: unknown key {unknown[0]!r} (allowed: {', '.join(keys)})")
    if missing:
        raise TaskError(f"{where}: missing {missing[0]!r}")
    return raw


def parse_region(raw: Mapping[str, Any], *, dim: int, where: str,
                 named: Callable[[str, str], Region], depth: int = 0,
                 shapes: Mapping[str, Callable[[Any, str], Region]] | None = None) -> Region:
    """Build a region from its shape table (module docstring).

    Parameters
    ----------
    raw : mapping
        The region's table with exactly one shape key (other keys are the caller's).
    dim : int
        The task's state dimension.
    where : str
        ``file: regions.NAME`` for messages.
    named : callable
        ``(name, where) -> Region``: the region of that name (for parts written by name);
        raises :class:`TaskError` for an unknown name or a cycle.
    depth : int, optional
        Nesting depth of inline shapes (limit :data:`MAX_REGION_DEPTH`).
    shapes : mapping of str to callable, optional
        More shape keys and their readers ``(table, where) -> Region``, e.g. a pose task's
        ``cone`` (:func:`tli_verify.tasks.orientation.parse_cone`).

    Raises
    ------
    TaskError
        (exit 2) Naming the field: no or several shape keys, wrong sizes, non-finite numbers, a
        ball with a non-positive radius, an ellipsoid matrix that is not symmetric positive
        definite, an empty polytope or box.
    """
    if depth > MAX_REGION_DEPTH:
        raise TaskError(f"{where}: shapes nested deeper than {MAX_REGION_DEPTH} levels")
    extra = dict(shapes or {})
    keys = (*SHAPES, *extra)
    given = [k for k in keys if k in raw]
    if len(given) != 1:
        raise TaskError(f"{where}: needs exactly one shape key of {', '.join(keys)}"
                        + (f", got {', '.join(given)}" if given else ""))
    kind = given[0]
    spec = raw[kind]
    here = f"{where}.{kind}"
    if kind in extra:
        return extra[kind](spec, here)
    if kind == "box":
        t = _table(spec, ("lower", "upper"), here)
        lo = _vector(t["lower"], dim, f"{here}.lower", allow_inf=True)
        hi = _vector(t["upper"], dim, f"{here}.upper", allow_inf=True)
        if not np.all(lo <= hi) or np.any(lo == np.inf) or np.any(hi == -np.inf):
            raise TaskError(f"{here}: empty box (need lower <= upper, finite or -inf/+inf on "
                            "the right side)")
        return Box(lo, hi)
    if kind == "ball":
        t = _table(spec, ("center", "radius"), here)
        c = _vector(t["center"], dim, f"{here}.center")
        r = t["radius"]
        if not isinstance(r, int | float) or isinstance(r, bool) or \
                not 0 < r <= MAX_ABS_VALUE:
            raise TaskError(f"{here}.radius: expected a number in (0, {MAX_ABS_VALUE:g}] "
                            f"(MAX_ABS_VALUE), got {r!r}")
        return Ball(c, float(r))
    if kind == "ellipsoid":
        t = _table(spec, ("center", "matrix"), here)
        c = _vector(t["center"], dim, f"{here}.center")
        M = _matrix(t["matrix"], dim, dim, f"{here}.matrix")
        if not np.allclose(M, M.T, rtol=1e-12, atol=1e-12 * max(1.0, float(np.abs(M).max()))):
            raise TaskError(f"{here}.matrix: not symmetric")
        M = 0.5 * (M + M.T)
        eig = np.linalg.eigvalsh(M)
        if not eig.min() > 1e-12 * eig.max():
            raise TaskError(f"{here}.matrix: not positive definite (smallest eigenvalue "
                            f"{eig.min():.3g})")
        M.setflags(write=False)
        return Ellipsoid(c, M)
    if kind == "polytope":
        t = _table(spec, ("A", "b"), here)
        A = _matrix(t["A"], None, dim, f"{here}.A")
        if len(A) > MAX_REGION_PARTS * dim:
            raise TaskError(f"{here}.A: more than {MAX_REGION_PARTS * dim} rows")
        b = _vector(t["b"], len(A), f"{here}.b", bound=MAX_ABS_COVARIANCE,
                    limit="MAX_ABS_COVARIANCE")
        norms = np.linalg.norm(A, axis=1)
        if not np.all(norms > 0):
            raise TaskError(f"{here}.A: row {int(np.argmin(norms))} is zero")
        found = _polytope_nonempty(A, b)
        if found is None:
            raise TaskError(f"{here}: cannot decide whether the polytope is empty (the LP "
                            "solver failed on these rows; rescale A and b)")
        if not found:
            raise TaskError(f"{here}: empty polytope (no x with A x <= b)")
        A.setflags(write=False)
        return Polytope(A, b)
    if not isinstance(spec, list) or not spec:
        raise TaskError(f"{here}: expected a non-empty list of region names or shape tables")
    if len(spec) > MAX_REGION_PARTS:
        raise TaskError(f"{here}: more than {MAX_REGION_PARTS} parts")
    if kind == "difference" and len(spec) < 2:
        raise TaskError(f"{here}: needs a region and at least one region to remove")
    parts: list[Region] = []
    names: list[str | None] = []
    for i, item in enumerate(spec):
        at = f"{here}[{i}]"
        if isinstance(item, str):
            parts.append(named(item, at))
            names.append(item)
        elif isinstance(item, dict):
            parts.append(parse_region(item, dim=dim, where=at, named=named, depth=depth + 1,
                                      shapes=extra))
            names.append(None)
        else:
            raise TaskError(f"{at}: expected a region name or a shape table")
    cls = {"union": Union, "intersection": Intersection, "difference": Difference}[kind]
    return cls(tuple(parts), tuple(names))


def _polytope_nonempty(A: FloatArray, b: FloatArray) -> bool | None:
    """Whether ``A x <= b`` has a solution (rows scaled to unit norm first, so the LP is well
    conditioned); None when the solver cannot tell (never "empty" for a failure)."""
    from scipy.optimize import linprog

    norms = np.linalg.norm(A, axis=1)
    An, bn = A / norms[:, None], b / norms
    res = linprog(np.zeros(A.shape[1]), A_ub=An, b_ub=bn, bounds=[(None, None)] * A.shape[1],
                  method="highs")
    if res.status in (0, 3):  # optimal, or unbounded (a feasible point exists)
        return True
    if res.status == 2:  # infeasible
        return False
    return None
