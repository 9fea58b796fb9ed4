"""Pictures of a task's true regions in any dimension ``n >= 1``.

* ``n = 1``: a strip -- the region of every point of ``[lo, hi]`` -- with time upwards
  (demonstrations are drawn as ``x(t)``, time normalised to ``[0, 1]``);
* ``n = 2``: the exact partition, ``task.region_index`` on a grid, as an image;
* ``n >= 3``: one panel per coordinate pair (:func:`pairs_for`), each region drawn as its
  *shadow*, the projection onto the pair's plane. A region whose cell is one box, ball,
  ellipsoid or polytope (inside the workspace, overlapped by no region listed before it) is
  drawn exactly (:func:`exact_shadow`: a rectangle, an ellipse, or the polygon of LP support
  points); only unions, intersections, differences and overlapped cells are estimated from
  seeded uniform samples of the region (``task.sample_region``; :func:`region_shadows`,
  :func:`shadow_mask`). Shadows overlap;
  they are drawn semi-transparent, the largest region (by volume) first. A region that cannot
  be sampled is listed in the legend as ``"<name> (too small to draw)"``
  (:func:`legend_labels`), never dropped silently.

Nothing here names a bundled task: axis labels are the task's ``state_names``. Matplotlib is
imported lazily (the CLI stays fast to import); PNGs are written atomically by
:func:`tli_verify.plotting.save_figure`. A picture that cannot be drawn raises
:class:`~tli_verify.errors.TliError` with a one-line reason and writes nothing.
"""

from __future__ import annotations

import itertools
import math
import operator
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TliError
from tli_verify.plotting import save_figure

__all__ = [
    "DEFAULT_SAMPLES",
    "MAX_PAIRS",
    "SHADOW_ALPHA",
    "TOO_SMALL",
    "Picture",
    "RegionShadow",
    "TaskLike",
    "as_task",
    "check_task",
    "cut_face_shadow",
    "cut_trace",
    "exact_shadow",
    "legend_labels",
    "pairs_for",
    "plot_task",
    "pose_pairs",
    "region_shadows",
    "shadow_mask",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
Pair = tuple[int, int]

SHADOW_ALPHA = 0.65
"""Opacity of a region's shadow (n >= 3 pictures)."""
TOO_SMALL = "(too small to draw)"
"""Legend suffix of a region :meth:`TaskLike.sample_region` cannot sample."""
DEFAULT_SAMPLES = 5000
"""States sampled per region for its shadows."""
MAX_PAIRS = 12
"""Most coordinate pairs (panels) one picture draws."""
_DEFAULT_PAIRS = 6
_VOLUME_SAMPLES = 20000
_FEWEST_SAMPLES = 100


@runtime_checkable
class TaskLike(Protocol):
    """What the pictures need from a task (duck-typed; any dimension ``n = dim >= 1``).

    Attributes
    ----------
    name : str
    dim : int
        State dimension ``n``.
    state_names : tuple of str
        Length ``n``; the axis labels.
    lo, hi : array_like of float, shape (n,)
        The workspace box ``[lo, hi]``.
    region_names : tuple of str
        The true regions (a partition of the workspace), in index order.
    region_colors : tuple of str
        Their matplotlib colours (same length).
    """

    @property
    def name(self) -> str: ...

    @property
    def dim(self) -> int: ...

    @property
    def state_names(self) -> tuple[str, ...]: ...

    @property
    def lo(self) -> npt.ArrayLike: ...

    @property
    def hi(self) -> npt.ArrayLike: ...

    @property
    def region_names(self) -> tuple[str, ...]: ...

    @property
    def region_colors(self) -> tuple[str, ...]: ...

    def region_index(self, X: FloatArray) -> npt.ArrayLike:
        """Index into :attr:`region_names` of the region of each state, (N, n) -> (N,)."""
        ...

    def sample_region(self, name: str, count: int, rng: np.random.Generator) -> npt.ArrayLike:
        """``count`` uniform states of a region, shape (count, n).

        May raise a :class:`~tli_verify.errors.TliError` when the region is too small to
        sample."""
        ...


@dataclass(frozen=True, slots=True)
class Picture:
    """What a picture function drew.

    Attributes
    ----------
    path : Path
        The file written.
    panels : int
        Panels (axes) drawn.
    pairs : tuple of (int, int)
        The coordinate pairs of the panels (``()`` for ``n = 1``; ``((0, 1),)`` for ``n = 2``).
    legend : tuple of str
        The region legend's labels, in region order.
    """

    path: Path
    panels: int
    pairs: tuple[Pair, ...]
    legend: tuple[str, ...]


@dataclass(frozen=True, slots=True, eq=False)
class RegionShadow:
    """The samples one region's shadows are drawn from.

    Attributes
    ----------
    index : int
        Index into ``task.region_names``.
    name, color : str
    points : ndarray, shape (count, n), or None
        Uniform samples of the region inside the workspace; None when it cannot be sampled.
    volume : float
        Estimated fraction of the workspace box the region fills (drawing order: largest
        first).
    reason : str
        Why it cannot be drawn ("" when it can).
    """

    index: int
    name: str
    color: str
    points: FloatArray | None
    volume: float
    reason: str = ""

    @property
    def drawable(self) -> bool:
        """Whether the region has samples to draw."""
        return self.points is not None


# ----------------------------------------------------------------------------- checks
@dataclass(frozen=True, slots=True, eq=False)
class _TaskView:
    """A task-like object completed with ``dim`` and ``state_names`` (:func:`as_task`)."""

    base: Any
    dim: int
    state_names: tuple[str, ...]

    @property
    def name(self) -> str:
        return str(getattr(self.base, "name", "task"))

    @property
    def lo(self) -> npt.ArrayLike:
        return np.asarray(self.base.lo, dtype=np.float64)

    @property
    def hi(self) -> npt.ArrayLike:
        return np.asarray(self.base.hi, dtype=np.float64)

    @property
    def region_names(self) -> tuple[str, ...]:
        return tuple(self.base.region_names)

    @property
    def region_colors(self) -> tuple[str, ...]:
        return tuple(self.base.region_colors)

    def region_index(self, X: FloatArray) -> npt.ArrayLike:
        return np.asarray(self.base.region_index(X))

    def sample_region(self, name: str, count: int, rng: np.random.Generator) -> npt.ArrayLike:
        return np.asarray(self.base.sample_region(name, count, rng))


def as_task(obj: Any, *, state_names: Sequence[str] | None = None) -> TaskLike:
    """``obj`` as a :class:`TaskLike`, adding ``dim`` and ``state_names`` when it lacks them.

    For objects with ``lo``, ``hi``, ``region_names``, ``region_colors``, ``region_index`` and
    ``sample_region`` but no ``dim`` / ``state_names`` (e.g. the 2-D tasks): ``dim`` is
    ``len(lo)`` and the state names are ``state_names`` or ``x1 .. xn``.

    Parameters
    ----------
    obj : object
    state_names : sequence of str, optional
        Override (or supply) the state names.

    Returns
    -------
    TaskLike
    """
    names = None if state_names is None else tuple(str(s) for s in state_names)
    if names is None and hasattr(obj, "dim") and hasattr(obj, "state_names"):
        return obj
    n = int(np.asarray(obj.lo).size)
    return _TaskView(base=obj, dim=n,
                     state_names=names if names is not None
                     else tuple(f"x{k + 1}" for k in range(n)))


def _box(task: TaskLike) -> tuple[FloatArray, FloatArray]:
    lo = np.asarray(task.lo, dtype=np.float64).reshape(-1)
    hi = np.asarray(task.hi, dtype=np.float64).reshape(-1)
    return lo, hi


def check_task(task: TaskLike) -> None:
    """Check that a task can be drawn (its attributes agree with each other).

    Raises
    ------
    TliError
        A one-line reason: dimension below 1, state names, workspace box or region colours of
        the wrong length, an empty or non-finite workspace box, no regions.
    """
    name = getattr(task, "name", "task")
    try:
        dim = operator.index(task.dim)
    except (AttributeError, TypeError):
        raise TliError(f"{name}: cannot draw: dim must be an int, got "
                       f"{getattr(task, 'dim', None)!r}") from None
    if dim < 1:
        raise TliError(f"{name}: cannot draw a task of dimension {dim} (need n >= 1)")
    if len(task.state_names) != dim:
        raise TliError(f"{name}: cannot draw: {len(task.state_names)} state names for "
                       f"dimension {dim}")
    lo, hi = _box(task)
    if lo.shape != (dim,) or hi.shape != (dim,):
        raise TliError(f"{name}: cannot draw: workspace box lo/hi of sizes {lo.size}/{hi.size} "
                       f"for dimension {dim}")
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi > lo)):
        raise TliError(f"{name}: cannot draw: the workspace box needs finite lo < hi on every "
                       f"axis, got lo={lo.tolist()}, hi={hi.tolist()}")
    if not task.region_names:
        raise TliError(f"{name}: cannot draw: the task has no regions")
    if len(task.region_colors) != len(task.region_names):
        raise TliError(f"{name}: cannot draw: {len(task.region_colors)} region colours for "
                       f"{len(task.region_names)} regions")


def _region_index(task: TaskLike, X: FloatArray) -> IntArray:
    """``task.region_index(X)`` checked: shape (N,), integers indexing ``region_names``."""
    idx = np.asarray(task.region_index(X))
    if idx.shape != (len(X),):
        raise TliError(f"{task.name}: cannot draw: region_index returned shape {idx.shape} "
                       f"for {len(X)} states")
    if idx.size and (not np.issubdtype(idx.dtype, np.integer)
                     or idx.min() < 0 or idx.max() >= len(task.region_names)):
        raise TliError(f"{task.name}: cannot draw: region_index returned values outside "
                       f"0..{len(task.region_names) - 1}")
    return idx.astype(np.int64)


def pose_pairs(task: TaskLike) -> tuple[Pair, ...] | None:
    """A pose task's panels: every coordinate shown, position first (the first three position
    coordinates pairwise, each further one against the first; a lone position coordinate
    against each orientation coordinate), then the orientation pairs; at most
    :data:`MAX_PAIRS`. None for a task without orientation."""
    chart = getattr(task, "orientation", None)
    if chart is None:
        return None
    cols = list(range(chart.start, chart.start + 3))
    pos = [i for i in range(task.dim) if i not in cols]
    if len(pos) == 1:
        first: list[Pair] = [(pos[0], c) for c in cols]
    else:
        first = [*itertools.combinations(pos[:3], 2), *((pos[0], p) for p in pos[3:])]
    return tuple([*first, *itertools.combinations(cols, 2)][:MAX_PAIRS])


def pairs_for(dim: int, pairs: Sequence[Sequence[int]] | None = None) -> tuple[Pair, ...]:
    """The coordinate pairs (panels) of an ``n``-D picture.

    Parameters
    ----------
    dim : int
        State dimension ``n >= 1``.
    pairs : sequence of (int, int), optional
        The pairs to draw (0-based coordinate indices, ``i != j``, no repeats, at most
        :data:`MAX_PAIRS`). Default: every pair ``i < j`` for ``n <= 4``, else the first 6.

    Returns
    -------
    tuple of (int, int)
        ``()`` for ``n = 1`` (the strip needs no pair), ``((0, 1),)`` by default for ``n = 2``.

    Raises
    ------
    TliError
        ``dim < 1``, or a malformed pair list.
    """
    dim = operator.index(dim)
    if dim < 1:
        raise TliError(f"cannot draw dimension {dim} (need n >= 1)")
    if dim == 1:
        if pairs:
            raise TliError("a 1-D task has no coordinate pairs to draw")
        return ()
    if pairs is None:
        every = tuple(itertools.combinations(range(dim), 2))
        return every if dim <= 4 else every[:_DEFAULT_PAIRS]
    out: list[Pair] = []
    for p in pairs:
        try:
            i, j = (operator.index(v) for v in p)
        except (TypeError, ValueError):
            raise TliError(f"coordinate pair {p!r} is not two integers") from None
        if not (0 <= i < dim and 0 <= j < dim) or i == j:
            raise TliError(f"coordinate pair ({i}, {j}) needs two different indices in "
                           f"0..{dim - 1}")
        if (i, j) in out:
            raise TliError(f"coordinate pair ({i}, {j}) given twice")
        out.append((i, j))
    if not out:
        raise TliError("no coordinate pairs to draw")
    if len(out) > MAX_PAIRS:
        raise TliError(f"{len(out)} coordinate pairs: at most {MAX_PAIRS} panels per picture")
    return tuple(out)


# ----------------------------------------------------------------------------- shadows
def region_shadows(task: TaskLike, *, samples: int = DEFAULT_SAMPLES, seed: int = 0
                   ) -> tuple[RegionShadow, ...]:
    """Sample every region of a task for its shadows (seeded, one generator per region).

    Parameters
    ----------
    task : TaskLike
    samples : int, optional
        States per region.
    seed : int, optional

    Returns
    -------
    tuple of RegionShadow
        In region order. A region whose ``sample_region`` raises a
        :class:`~tli_verify.errors.TliError` for ``samples`` states is asked for a tenth as
        many (at least 100); if that fails too, or it returns no state inside the workspace, it
        has ``points = None`` and a ``reason``.

    Raises
    ------
    TliError
        The task is malformed (:func:`check_task`), ``sample_region`` returns an array of the
        wrong shape or states outside the region, or no region can be sampled at all.
    """
    check_task(task)
    if samples < 1:
        raise TliError(f"{task.name}: cannot draw shadows from {samples} samples")
    lo, hi = _box(task)
    n = lo.size
    vol_rng = np.random.default_rng([seed, 0x5EED])
    U = vol_rng.uniform(lo, hi, size=(_VOLUME_SAMPLES, n))
    volume = np.bincount(_region_index(task, U), minlength=len(task.region_names)) / len(U)
    out: list[RegionShadow] = []
    for k, (name, color) in enumerate(zip(task.region_names, task.region_colors, strict=True)):
        raw: npt.ArrayLike | None = None
        reason = "cannot be sampled"
        for count in dict.fromkeys((samples, max(samples // 10, _FEWEST_SAMPLES))):
            if count > samples:
                break
            try:  # a region too small for `samples` states may still give a tenth of them
                raw = task.sample_region(name, count, np.random.default_rng([seed, k]))
                break
            except TliError as exc:
                reason = str(exc) or reason
        if raw is None:
            out.append(RegionShadow(k, name, color, None, float(volume[k]), reason=reason))
            continue
        P = np.asarray(raw, dtype=np.float64)
        if P.ndim != 2 or P.shape[1] != n:
            raise TliError(f"{task.name}: cannot draw: sample_region({name!r}) returned shape "
                           f"{P.shape}, expected (count, {n})")
        P = P[np.all(np.isfinite(P), axis=1) & np.all((P >= lo) & (P <= hi), axis=1)]
        if len(P) == 0:
            out.append(RegionShadow(k, name, color, None, float(volume[k]),
                                    reason="no sample inside the workspace"))
            continue
        inside = _region_index(task, P) == k
        if not np.all(inside):
            raise TliError(f"{task.name}: cannot draw: sample_region({name!r}) returned "
                           f"{int(np.sum(~inside))} of {len(P)} states outside the region")
        out.append(RegionShadow(k, name, color, P, float(volume[k])))
    if not any(s.drawable for s in out):
        raise TliError(f"{task.name}: cannot draw: no region can be sampled "
                       f"({out[0].name}: {out[0].reason})")
    return tuple(out)


def legend_labels(shadows: Sequence[RegionShadow]) -> tuple[str, ...]:
    """The region legend: the names, ``"<name> (too small to draw)"`` for an unsampled one."""
    return tuple(s.name if s.drawable else f"{s.name} {TOO_SMALL}" for s in shadows)


def shadow_mask(points: npt.ArrayLike, i: int, j: int, lo: npt.ArrayLike, hi: npt.ArrayLike
                ) -> BoolArray:
    """The cells of the ``(x_i, x_j)`` plane a region's samples project into.

    The grid is the finest (of 96 down to 16 cells a side over the workspace) with at least 3
    samples per occupied cell on average; an empty cell with most of its neighbours occupied
    is filled (sampling holes).

    Parameters
    ----------
    points : array_like, shape (N, n)
    i, j : int
        The coordinates of the plane (horizontal, vertical).
    lo, hi : array_like, shape (n,)
        The workspace box.

    Returns
    -------
    ndarray of bool, shape (b, b)
        ``mask[row, col]``: row along ``x_j`` (from ``lo[j]`` up), column along ``x_i``.
    """
    P = np.asarray(points, dtype=np.float64)
    lo_a, hi_a = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    rng_x, rng_y = (lo_a[i], hi_a[i]), (lo_a[j], hi_a[j])
    H = np.zeros((16, 16))
    for bins in (96, 72, 56, 48, 40, 32, 24, 16):
        H, _, _ = np.histogram2d(P[:, i], P[:, j], bins=bins, range=[rng_x, rng_y])
        occupied = int(np.count_nonzero(H))
        if occupied and len(P) / occupied >= 3.0:
            break
    mask = H.T > 0
    padded = np.pad(mask, 1).astype(np.int64)
    valid = np.pad(np.ones_like(mask, dtype=np.int64), 1)
    b0, b1 = mask.shape
    near = sum(padded[1 + di:1 + di + b0, 1 + dj:1 + dj + b1]
               for di in (-1, 0, 1) for dj in (-1, 0, 1) if (di, dj) != (0, 0))
    room = sum(valid[1 + di:1 + di + b0, 1 + dj:1 + dj + b1]
               for di in (-1, 0, 1) for dj in (-1, 0, 1) if (di, dj) != (0, 0))
    return np.asarray(mask | (near >= 0.6 * np.asarray(room)), dtype=bool)


def cut_trace(normal: npt.ArrayLike, point: npt.ArrayLike, i: int, j: int,
              lo: npt.ArrayLike, hi: npt.ArrayLike) -> FloatArray | None:
    """Where a cut's hyperplane meets a coordinate plane, clipped to the workspace.

    The plane is the 2-D slice through the cut point ``p`` spanned by the axes ``e_i`` and
    ``e_j``; the hyperplane ``{x : w . (x - p) = 0}`` meets it in the line
    ``w_i (u - p_i) + w_j (v - p_j) = 0`` (when ``(w_i, w_j) != 0``).

    Parameters
    ----------
    normal : array_like, shape (n,)
        ``w``.
    point : array_like, shape (n,)
        ``p``.
    i, j : int
        The coordinates of the plane (``u = x_i`` horizontal, ``v = x_j`` vertical).
    lo, hi : array_like, shape (n,)
        The workspace box.

    Returns
    -------
    ndarray, shape (2, 2), or None
        The segment's end points ``[[u0, v0], [u1, v1]]``; None when the normal has no
        component in the plane (the hyperplane contains it, or misses it) or the line misses
        the workspace rectangle.
    """
    w = np.asarray(normal, dtype=np.float64)
    p = np.asarray(point, dtype=np.float64)
    lo_a, hi_a = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    scale = max(float(np.linalg.norm(w)), 1e-300)
    wi, wj = float(w[i]) / scale, float(w[j]) / scale
    if math.hypot(wi, wj) <= 1e-9:
        return None
    origin = np.array([p[i], p[j]])
    d = np.array([-wj, wi]) / math.hypot(wi, wj)
    box_lo = np.array([lo_a[i], lo_a[j]])
    box_hi = np.array([hi_a[i], hi_a[j]])
    s0, s1 = -math.inf, math.inf
    for k in range(2):  # Liang-Barsky: clip origin + s d to the rectangle
        if abs(d[k]) <= 1e-12:
            if origin[k] < box_lo[k] or origin[k] > box_hi[k]:
                return None
            continue
        a = (box_lo[k] - origin[k]) / d[k]
        b = (box_hi[k] - origin[k]) / d[k]
        s0, s1 = max(s0, min(a, b)), min(s1, max(a, b))
    size = float(np.max(box_hi - box_lo))
    if not s1 - s0 > 1e-12 * size:
        return None
    return np.array([origin + s0 * d, origin + s1 * d], dtype=np.float64)


def cut_face_shadow(normal: npt.ArrayLike, point: npt.ArrayLike, i: int, j: int,
                    lo: npt.ArrayLike, hi: npt.ArrayLike,
                    others: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]] = (),
                    *, max_lps: int = 64) -> FloatArray | None:
    """The shadow of a cut's *face* on the ``(x_i, x_j)`` plane: the projection of the part of
    its plane that bounds the mode's region, ``F = {x in [lo, hi] : w . (x - p) = 0,
    w_k . (x - p_k) <= 0 for the mode's other cuts}`` (n >= 3 pictures; exact, no sampling).

    ``F`` is a polytope; its projection is the convex polygon found by support LPs: the four
    axis directions, then the outward normal of every edge found so far until no LP moves an
    edge (each LP confirms an edge or adds a vertex), as for the polytope regions
    (:func:`exact_shadow`).

    Parameters
    ----------
    normal, point : array_like, shape (n,)
        The cut ``w``, ``p`` (the mode on the side ``w . (x - p) <= 0``).
    i, j : int
        The plane's coordinates.
    lo, hi : array_like, shape (n,)
        The workspace box.
    others : sequence of (normal, point)
        The mode's other cuts.
    max_lps : int, optional
        Most LPs; past them the polygon found so far is returned (inside the true one).

    Returns
    -------
    ndarray, shape (2, 2) or (m, 2) with m >= 3, or None
        A segment (the face projects to a line: its normal lies in the plane), the polygon in
        counter-clockwise order, or None: the face is empty (another cut removes it), a point,
        covers the whole panel, or an LP fails.
    """
    from scipy.optimize import linprog

    w = np.asarray(normal, dtype=np.float64)
    p = np.asarray(point, dtype=np.float64)
    lo_a, hi_a = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    rows = [np.asarray(a, dtype=np.float64) for a, _ in others]
    A_ub = np.array(rows) if rows else None
    b_ub = (np.array([float(np.asarray(a, dtype=np.float64) @ np.asarray(q, dtype=np.float64))
                      for a, q in others]) if rows else None)
    bounds = list(zip(lo_a.tolist(), hi_a.tolist(), strict=True))
    span = float(max(hi_a[i] - lo_a[i], hi_a[j] - lo_a[j]))
    tol = 1e-9 * span
    used = 0

    def support(d: FloatArray) -> FloatArray | None:
        nonlocal used
        used += 1
        cost = np.zeros(w.size)
        cost[i], cost[j] = -d[0], -d[1]
        res = linprog(cost, A_ub=A_ub, b_ub=b_ub, A_eq=w[None, :], b_eq=[float(w @ p)],
                      bounds=bounds, method="highs")
        return None if res.status != 0 else np.array([res.x[i], res.x[j]])

    hull: list[FloatArray] = []
    for d in ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)):
        y = support(np.array(d))
        if y is None:
            return None
        if not any(float(np.max(np.abs(y - h))) <= tol for h in hull):
            hull.append(y)
    if len(hull) == 1:
        return None
    k = 0
    while k < len(hull) and used < max_lps:  # edge hull[k] -> hull[k + 1]
        P, Q = hull[k], hull[(k + 1) % len(hull)]
        e = Q - P
        out = np.array([e[1], -e[0]])  # outward for a counter-clockwise hull
        norm = float(np.hypot(*out))
        if norm <= tol:
            k += 1
            continue
        y = support(out / norm)
        if y is None:
            return None
        if float(out @ (y - P)) / norm > tol:
            hull.insert(k + 1, y)
        else:
            k += 1
    poly = np.array(hull, dtype=np.float64)
    area = 0.5 * abs(float(np.dot(poly[:, 0], np.roll(poly[:, 1], -1))
                           - np.dot(poly[:, 1], np.roll(poly[:, 0], -1))))
    panel = float((hi_a[i] - lo_a[i]) * (hi_a[j] - lo_a[j]))
    if area >= panel * (1.0 - 1e-9):
        return None
    if area <= 1e-9 * panel:  # a segment: its two farthest points
        far = max(itertools.combinations(range(len(poly)), 2),
                  key=lambda ab: float(np.linalg.norm(poly[ab[0]] - poly[ab[1]])))
        return np.asarray(poly[list(far)], dtype=np.float64)
    return poly


# ----------------------------------------------------------------------------- exact shadows
_PRIMITIVES = ("Box", "Ball", "Ellipsoid", "Polytope")
_ELLIPSE_POINTS = 181
_LP_DIRECTIONS = 96


def exact_shapes(task: TaskLike, *, seed: int = 0, samples: int = 4000) -> tuple[Any, ...]:
    """Per region of ``task``: its shape when the region's cell *is* that shape (one box, ball,
    ellipsoid or polytope inside the workspace) and so its shadow can be drawn exactly, else
    None (drawn from samples).

    A cell is the shape minus the regions listed before it (a state lies in the first listed
    region holding it). The cell equals the shape when no such region overlaps it: checked on
    ``samples`` seeded uniform states of the shape (of its bounding box, kept where the shape
    holds them) -- every one must lie in the region's cell. Tasks without a ``partition``
    (duck-typed tasks) have no shapes.
    """
    partition = getattr(task, "partition", None)
    cells = getattr(partition, "cells", None)
    if not cells:
        return ()
    lo, hi = _box(task)
    names = tuple(task.region_names)
    out: list[Any] = []
    for k, name in enumerate(names):
        cell = next((c for c in cells if c.name == name), None)
        shape = None if cell is None else cell.region
        if shape is None or type(shape).__name__ not in _PRIMITIVES:
            out.append(None)
            continue
        b_lo, b_hi = (np.asarray(v, dtype=np.float64) for v in shape.bounds())
        b_lo, b_hi = np.maximum(b_lo, lo), np.minimum(b_hi, hi)
        inside_box = bool(np.all(np.asarray(shape.bounds()[0]) >= lo - 1e-12) and
                          np.all(np.asarray(shape.bounds()[1]) <= hi + 1e-12))
        if type(shape).__name__ in ("Ball", "Ellipsoid") and not inside_box:
            out.append(None)  # an ellipsoid cut by the workspace: its shadow is not an ellipse
            continue
        if not np.all(b_hi > b_lo):
            out.append(None)
            continue
        rng = np.random.default_rng([seed, 0xE7AC, k])
        X = rng.uniform(b_lo, b_hi, size=(samples, lo.size))
        X = X[np.asarray(shape.contains(X), dtype=bool)]
        ok = len(X) > 0 and bool(np.all(_region_index(task, X) == k))
        out.append(shape if ok else None)
    return tuple(out)


def exact_shadow(shape: Any, i: int, j: int, lo: npt.ArrayLike, hi: npt.ArrayLike
                 ) -> FloatArray | None:
    """The exact projection of ``shape`` (clipped to the workspace box) onto the
    ``(x_i, x_j)`` plane, as a closed polygon.

    * a box: the rectangle of its ``i``, ``j`` sides (clipped);
    * a ball or an ellipsoid ``(x - c)^T M (x - c) <= 1`` inside the workspace: the ellipse
      ``(y - c_ij)^T (S_ij)^{-1} (y - c_ij) <= 1`` with ``S = M^{-1}`` (the projection of an
      ellipsoid is the ellipse of the marginal of its shape matrix's inverse), 181 points;
    * a polytope ``A x <= b`` (with the workspace box): its support points in 96 directions of
      the plane, one LP each (every one a vertex of the projection), in angular order.

    Returns
    -------
    ndarray, shape (m, 2), or None
        None for another kind of shape, an empty shadow, or an LP that fails.
    """
    lo_a, hi_a = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    kind = type(shape).__name__
    if kind == "Box":
        a = np.maximum(np.asarray(shape.lower, dtype=np.float64), lo_a)
        b = np.minimum(np.asarray(shape.upper, dtype=np.float64), hi_a)
        if not (b[i] > a[i] and b[j] > a[j]):
            return None
        return np.array([[a[i], a[j]], [b[i], a[j]], [b[i], b[j]], [a[i], b[j]]])
    if kind in ("Ball", "Ellipsoid"):
        c = np.asarray(shape.center, dtype=np.float64)
        if kind == "Ball":
            S2 = np.eye(2) * float(shape.radius) ** 2
        else:
            S = np.linalg.inv(np.asarray(shape.matrix, dtype=np.float64))
            S2 = S[np.ix_([i, j], [i, j])]
            S2 = 0.5 * (S2 + S2.T)
        L = np.linalg.cholesky(S2)
        t = np.linspace(0.0, 2.0 * math.pi, _ELLIPSE_POINTS)[:-1]
        return np.asarray(np.array([c[i], c[j]]) + (L @ np.vstack([np.cos(t), np.sin(t)])).T,
                          dtype=np.float64)
    if kind == "Polytope":
        from scipy.optimize import linprog

        A = np.asarray(shape.A, dtype=np.float64)
        b = np.asarray(shape.b, dtype=np.float64).ravel()
        bounds = list(zip(lo_a.tolist(), hi_a.tolist(), strict=True))
        pts = []
        for t in np.linspace(0.0, 2.0 * math.pi, _LP_DIRECTIONS, endpoint=False):
            cost = np.zeros(lo_a.size)
            cost[i], cost[j] = -math.cos(t), -math.sin(t)  # maximise the direction
            res = linprog(cost, A_ub=A, b_ub=b, bounds=bounds, method="highs")
            if res.status != 0:
                return None
            pts.append((float(res.x[i]), float(res.x[j])))
        P = np.unique(np.round(np.array(pts), 12), axis=0)
        if len(P) < 3:
            return None
        mid = P.mean(axis=0)
        order = np.argsort(np.arctan2(P[:, 1] - mid[1], P[:, 0] - mid[0]))
        return np.asarray(P[order], dtype=np.float64)
    return None


# ----------------------------------------------------------------------------- drawing
def _aspect(lo: FloatArray, hi: FloatArray, i: int, j: int) -> str:
    """``"equal"`` unless the pair's ranges differ by more than 4x (then ``"auto"``)."""
    ratio = (hi[j] - lo[j]) / (hi[i] - lo[i])
    return "equal" if 0.25 <= ratio <= 4.0 else "auto"


def _blur(F: FloatArray) -> FloatArray:
    """A 3 x 3 binomial blur (edges repeated), to round the shadows' staircase edges."""
    for axis in (0, 1):
        P = np.pad(F, [(1, 1) if a == axis else (0, 0) for a in (0, 1)], mode="edge")
        lo, mid, hi = (np.take(P, range(k, k + F.shape[axis]), axis=axis) for k in (0, 1, 2))
        F = 0.25 * lo + 0.5 * mid + 0.25 * hi
    return F


def _darker(color: str) -> tuple[float, float, float]:
    from matplotlib.colors import to_rgb

    r, g, b = to_rgb(color)
    return (0.6 * r, 0.6 * g, 0.6 * b)


@dataclass(frozen=True, slots=True, eq=False)
class _Background:
    """What a panel's regions are drawn from: the exact 2-D partition, or shadows (n >= 3),
    or the 1-D strip."""

    task: TaskLike
    lo: FloatArray
    hi: FloatArray
    grid: IntArray | None
    shadows: tuple[RegionShadow, ...]
    exact: tuple[Any, ...] = ()
    """Per region: its primitive shape when its shadow is drawn exactly, else None."""

    @property
    def legend(self) -> tuple[str, ...]:
        if self.shadows:
            return legend_labels(self.shadows)
        return tuple(self.task.region_names)

    def legend_handles(self) -> list[Any]:
        from matplotlib.patches import Patch

        hatch = {s.index for s in self.shadows if not s.drawable}
        out = [Patch(facecolor="none" if k in hatch else c, edgecolor="0.3",
                     hatch="//" if k in hatch else None, label=label)
               for k, (c, label) in enumerate(zip(self.task.region_colors, self.legend,
                                                  strict=True))]
        if self.shadows:  # n >= 3: say what a panel shows
            exact = sum(1 for s in self.exact if s is not None)
            out.append(Patch(facecolor="none", edgecolor="none",
                             label=f"regions: shadows (projections; {exact} exact, "
                             f"{len(self.shadows) - exact} sampled)"))
        return out

    def draw(self, ax: Any, pair: Pair | None, *, t_range: tuple[float, float] = (0.0, 1.0)
             ) -> None:
        """Draw the regions on ``ax`` (``pair`` None: the 1-D strip over ``t_range``)."""
        from matplotlib.colors import ListedColormap

        task, lo, hi = self.task, self.lo, self.hi
        cmap = ListedColormap(list(task.region_colors))
        vmax = len(task.region_names) - 0.5
        if pair is None:
            assert self.grid is not None
            ax.imshow(self.grid[None, :], origin="lower", extent=(lo[0], hi[0], *t_range),
                      cmap=cmap, vmin=-0.5, vmax=vmax, interpolation="nearest", aspect="auto")
            return
        i, j = pair
        if self.grid is not None:
            grid = self.grid if i < j else self.grid.T
            ax.imshow(grid, origin="lower", extent=(lo[i], hi[i], lo[j], hi[j]), cmap=cmap,
                      vmin=-0.5, vmax=vmax, interpolation="nearest",
                      aspect=_aspect(lo, hi, i, j))
            return
        for s in sorted((s for s in self.shadows if s.drawable), key=lambda s: -s.volume):
            assert s.points is not None
            self._draw_shadow(ax, s, i, j)
        ax.set_xlim(lo[i], hi[i])
        ax.set_ylim(lo[j], hi[j])
        ax.set_aspect(_aspect(lo, hi, i, j))

    def _draw_shadow(self, ax: Any, s: RegionShadow, i: int, j: int) -> None:
        assert s.points is not None
        lo, hi = self.lo, self.hi
        shape = self.exact[s.index] if s.index < len(self.exact) else None
        poly = None if shape is None else exact_shadow(shape, i, j, lo, hi)
        if poly is not None:
            ax.fill(poly[:, 0], poly[:, 1], color=s.color, alpha=SHADOW_ALPHA, lw=0,
                    zorder=0.5)
            ax.plot([*poly[:, 0], poly[0, 0]], [*poly[:, 1], poly[0, 1]],
                    color=_darker(s.color), lw=0.7, zorder=0.6)
            return
        mask = shadow_mask(s.points, i, j, lo, hi)
        if not mask.any():
            return
        field = _blur(mask.astype(np.float64))
        field = np.pad(field, 1, mode="edge")  # extend to the workspace edges
        b0, b1 = mask.shape
        xs = np.concatenate([[lo[i]], lo[i] + (np.arange(b1) + 0.5) * (hi[i] - lo[i]) / b1,
                             [hi[i]]])
        ys = np.concatenate([[lo[j]], lo[j] + (np.arange(b0) + 0.5) * (hi[j] - lo[j]) / b0,
                             [hi[j]]])
        if float(field.max()) < 0.5:
            field = field / float(field.max())  # a one-cell shadow: keep it visible
        ax.contourf(xs, ys, field, levels=[0.5, 2.0], colors=[s.color], alpha=SHADOW_ALPHA,
                    antialiased=True, zorder=0.5)
        if float(field.min()) < 0.5:  # an outline where the shadow ends inside the panel
            ax.contour(xs, ys, field, levels=[0.5], colors=[_darker(s.color)],
                       linewidths=0.7, zorder=0.6)


def _background(task: TaskLike, *, resolution: int = 300, samples: int = DEFAULT_SAMPLES,
                seed: int = 0) -> _Background:
    """The regions of a checked task, ready to draw in any panel."""
    check_task(task)
    lo, hi = _box(task)
    n = lo.size
    if resolution < 2:
        raise TliError(f"{task.name}: cannot draw at resolution {resolution} (need >= 2)")
    if n == 1:
        X = np.linspace(lo[0], hi[0], resolution)[:, None]
        return _Background(task, lo, hi, _region_index(task, X), ())
    if n == 2:
        gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], resolution),
                             np.linspace(lo[1], hi[1], resolution))
        X = np.column_stack([gx.ravel(), gy.ravel()])
        return _Background(task, lo, hi, _region_index(task, X).reshape(gx.shape), ())
    return _Background(task, lo, hi, None, region_shadows(task, samples=samples, seed=seed),
                       exact_shapes(task, seed=seed))


def _grid_shape(count: int, max_cols: int = 3) -> tuple[int, int]:
    ncols = max(1, min(max_cols, count))
    return math.ceil(count / ncols), ncols


def _check_demos(task: TaskLike, demos: Sequence[Any]) -> list[FloatArray]:
    out = []
    for k, d in enumerate(demos):
        x = np.asarray(getattr(d, "x", None), dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != task.dim or len(x) == 0:
            raise TliError(f"{task.name}: cannot draw demonstration {k + 1}: states of shape "
                           f"{x.shape}, expected (T, {task.dim})")
        out.append(x)
    return out


def plot_task(task: TaskLike, path: str | os.PathLike[str], *, demos: Sequence[Any] = (),
              title: str | None = None, resolution: int = 400,
              pairs: Sequence[Sequence[int]] | None = None, samples: int = DEFAULT_SAMPLES,
              seed: int = 0) -> Picture:
    """Draw a task's true regions (and demonstrations) to a PNG, in any dimension.

    ``n = 1``: the strip of regions along ``x1``, demonstrations as ``x(t)`` with time
    (normalised) upwards. ``n = 2``: the exact partition as an image.
    ``n >= 3``: one panel per coordinate pair, each region drawn as its shadow (projection)
    from ``samples`` seeded uniform samples; a region that cannot be sampled appears in the
    legend as ``"<name> (too small to draw)"``.

    Parameters
    ----------
    task : TaskLike
    path : path-like
        Output PNG (written atomically by :func:`tli_verify.plotting.save_figure`).
    demos : sequence of objects with ``.x``, shape (T, n), optional
        Drawn in black in every panel, their start marked.
    title : str, optional
        Default ``"<name>: true regions and demonstrations"``.
    resolution : int, optional
        Grid points per axis (n <= 2).
    pairs : sequence of (int, int), optional
        The coordinate pairs (n >= 2; see :func:`pairs_for`).
    samples : int, optional
        States sampled per region (n >= 3).
    seed : int, optional
        Seed of the region samples.

    Returns
    -------
    Picture

    Raises
    ------
    TliError
        The task cannot be drawn (one-line reason); nothing is written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    check_task(task)
    chosen = pairs_for(task.dim, pairs if pairs is not None else pose_pairs(task))
    xs = _check_demos(task, demos)
    bg = _background(task, resolution=resolution, samples=samples, seed=seed)
    lo, hi = bg.lo, bg.hi
    heading = title or f"{task.name}: true regions and demonstrations"
    if task.dim == 1:
        fig, ax = plt.subplots(figsize=(8.0, 3.0))
        panels = [ax]
    elif task.dim == 2 and len(chosen) == 1:
        i, j = chosen[0]
        width = 5.0 * (hi[i] - lo[i]) / max(hi[j] - lo[j], 1e-9)
        fig, ax = plt.subplots(figsize=(min(max(width, 4.0), 10.0) + 1.8, 5.0))
        panels = [ax]
    else:
        nrows, ncols = _grid_shape(len(chosen))
        side = min(3.6, 13.0 / ncols, 11.0 / nrows)
        fig, grid = plt.subplots(nrows, ncols, figsize=(ncols * side + 2.0, nrows * side + 0.6),
                                 squeeze=False, layout="constrained")
        flat = list(grid.ravel())
        panels = flat[:len(chosen)]
        for extra in flat[len(chosen):]:
            extra.axis("off")
    try:
        if task.dim == 1:
            ax = panels[0]
            bg.draw(ax, None)
            for x in xs:
                tt = np.linspace(0.0, 1.0, len(x))
                ax.plot(x[:, 0], tt, color="k", linewidth=1.0)
                ax.plot(x[0, 0], 0.0, marker="o", color="k", markersize=4)
            ax.set_xlim(lo[0], hi[0])
            ax.set_ylim(0.0, 1.0)
            ax.set_xlabel(task.state_names[0])
            ax.set_ylabel("time (normalised)")
        for ax, (i, j) in zip(panels, chosen, strict=False):
            bg.draw(ax, (i, j))
            for x in xs:
                ax.plot(x[:, i], x[:, j], color="k", linewidth=1.0)
                ax.plot(x[0, i], x[0, j], marker="o", color="k", markersize=4)
            ax.set_xlim(lo[i], hi[i])
            ax.set_ylim(lo[j], hi[j])
            ax.set_xlabel(task.state_names[i], fontsize=8 if len(panels) > 1 else None)
            ax.set_ylabel(task.state_names[j], fontsize=8 if len(panels) > 1 else None)
            if len(panels) > 1:
                ax.tick_params(labelsize=7)
        handles = bg.legend_handles()
        if len(panels) == 1:
            panels[0].legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                             fontsize=8, frameon=False)
            panels[0].set_title(heading, fontsize=9)
            fig.tight_layout()
        else:
            fig.legend(handles=handles, loc="outside right upper", fontsize=8, frameon=False)
            fig.suptitle(heading + (" (regions as shadows: projections onto each plane)"
                                    if task.dim >= 3 else ""), fontsize=9)
    except BaseException:
        plt.close(fig)
        raise
    save_figure(fig, path, dpi=90)
    return Picture(path=Path(path), panels=len(panels), pairs=chosen, legend=bg.legend)
