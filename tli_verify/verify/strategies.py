"""Hypothesis strategies for finite perturbation sequences (paper Asm. 2, Sec. 4.4).

A *case* is a start state and a finite sequence of perturbations ``(step, displacement)``; a
campaign simulates the closed loop on it and the oracle (:mod:`.oracle`) checks the trace. The
strategies are public and composable, so users can write their own properties::

    from hypothesis import given
    from tli_verify.verify.strategies import cases, target_robustness
    from tli_verify.tasks.registry import find_task

    @given(cases(find_task("scoop"), max_pushes=2))
    def test_my_policy(case):
        verdict = my_check(case)          # e.g. campaign.check_case(setup, case)
        target_robustness(verdict.robustness)
        assert verdict.ok

Levels of a perturbation (applied at run time by :func:`apply_push`, on the state the push
meets, using the task's *true regions*):

* ``"free"`` -- ``x + d`` clipped to the workspace (the paper's experiments: any direction,
  any magnitude up to the workspace size);
* ``"motion"`` -- a motion-level perturbation: the state stays in its true region: ``x + d``
  if it lies there, else ``x + (s/2) d`` with ``s`` the largest fraction in ``[0, 1]``
  (bisection) that keeps it there (half way to the boundary: never on it);
* ``"task"`` -- a task-level perturbation: the state is pushed into the named target region
  (adjacent or not): ``x + d`` if it lies there, else half way from the region's reference
  point towards where the segment to ``x + d`` leaves the region.

Shrinking (hypothesis shrinks lists by deleting elements, numbers towards zero, ``sampled_from``
towards its first element) is designed into the encoding, so a failing sequence shrinks toward

* **fewer** perturbations: the sequence is a list;
* **smaller** ones: ``magnitude * unit direction`` with the magnitude a float in ``[0, D]``
  (``D`` the workspace size) shrinking to 0, the level towards ``"free"``;
* **later** ones: each step is encoded as its distance *before the end of the perturbation
  window* (``step = window - early``), independently of the others; ``early`` shrinks to 0,
  i.e. perturbations move later, and deleting one perturbation never moves another (a
  delay-encoded chain, each step relative to the previous, would). Two perturbations drawn
  for one step are one (the first); the sequence is sorted by step.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 4.4 and Asm. 2 (finitely many perturbations of
any magnitude), appendix "Multi-modal Experiments" (perturbation distribution).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from hypothesis import strategies as st

from tli_verify.errors import TliError
from tli_verify.tasks.task import Task

__all__ = [
    "LEVELS",
    "Case",
    "Push",
    "apply_push",
    "case_from_json",
    "case_to_json",
    "cases",
    "directions",
    "displacements",
    "push_sequences",
    "region_anchor",
    "starts",
    "target_robustness",
    "workspace_size",
]

FloatArray = npt.NDArray[np.float64]
LEVELS: tuple[str, ...] = ("free", "motion", "task")
"""Perturbation levels, in shrinking order (hypothesis shrinks towards the first)."""


@dataclass(frozen=True, slots=True)
class Push:
    """One perturbation.

    Attributes
    ----------
    step : int
        Applied before control step ``step`` (1-based), as
        :func:`tli_verify.runtime.loop.run_episode` applies perturbations.
    displacement : tuple of float, length n
        ``magnitude * unit direction``.
    level : str
        ``"free"``, ``"motion"`` or ``"task"`` (module docstring).
    target : str or None
        The true region a task-level push sends the state into.
    """

    step: int
    displacement: tuple[float, ...]
    level: str = "free"
    target: str | None = None

    @property
    def magnitude(self) -> float:
        """``|displacement|``."""
        return math.sqrt(sum(v * v for v in self.displacement))


@dataclass(frozen=True, slots=True)
class Case:
    """A start state and a finite perturbation sequence (sorted by step, distinct steps).

    Attributes
    ----------
    start : tuple of float, length n
    pushes : tuple of Push
    """

    start: tuple[float, ...]
    pushes: tuple[Push, ...] = ()

    @property
    def last_step(self) -> int:
        """Step of the last perturbation (0 without any)."""
        return max((p.step for p in self.pushes), default=0)

    def table(self) -> dict[int, Push]:
        """``{step: push}``."""
        return {p.step: p for p in self.pushes}


def workspace_size(task: Task) -> float:
    """``D``: the largest side of the task's workspace box (16 for scoop)."""
    return float(np.max(np.asarray(task.hi, dtype=np.float64)
                        - np.asarray(task.lo, dtype=np.float64)))


# ------------------------------------------------------------------------------ strategies
def directions(dim: int) -> st.SearchStrategy[tuple[float, ...]]:
    """Unit vectors in ``R^dim``; in 2-D ``(cos a, sin a)`` with the angle shrinking to 0.

    Parameters
    ----------
    dim : int, >= 1

    Returns
    -------
    SearchStrategy of tuple of float, length dim
    """
    if dim < 1:
        raise TliError(f"directions: dim must be >= 1, got {dim}")
    if dim == 2:
        return st.floats(0.0, 2.0 * math.pi, exclude_max=True).map(
            lambda a: (math.cos(a), math.sin(a)))

    def unit(v: list[float]) -> tuple[float, ...]:
        n = math.sqrt(sum(c * c for c in v))
        if n < 1e-9:
            return tuple(1.0 if i == 0 else 0.0 for i in range(dim))
        return tuple(c / n for c in v)

    return st.lists(st.floats(-1.0, 1.0), min_size=dim, max_size=dim).map(unit)


def displacements(dim: int, max_magnitude: float, *, min_magnitude: float = 0.0
                  ) -> st.SearchStrategy[tuple[float, ...]]:
    """``magnitude * unit direction`` with ``magnitude`` in ``[min, max]`` shrinking to ``min``.

    Parameters
    ----------
    dim : int
    max_magnitude : float
        E.g. :func:`workspace_size` (the paper's "up to the dimension of the entire
        workspace").
    min_magnitude : float, optional

    Returns
    -------
    SearchStrategy of tuple of float, length dim
    """
    if not (0.0 <= min_magnitude <= max_magnitude and math.isfinite(max_magnitude)):
        raise TliError(f"displacements: need 0 <= min_magnitude <= max_magnitude < inf, got "
                       f"{min_magnitude}, {max_magnitude}")
    return st.tuples(st.floats(min_magnitude, max_magnitude), directions(dim)).map(
        lambda md: tuple(md[0] * c for c in md[1]))


def push_sequences(task: Task, *, max_pushes: int = 3, window: int = 700,
                   levels: Sequence[str] = LEVELS, max_magnitude: float | None = None,
                   min_pushes: int = 0) -> st.SearchStrategy[tuple[Push, ...]]:
    """Finite perturbation sequences over steps ``1..window`` (sorted, distinct steps).

    Parameters
    ----------
    task : Task
        Its dimension, workspace box (magnitudes up to its size) and region names (targets
        of task-level pushes).
    max_pushes : int, optional
        At most this many perturbations (paper Asm. 2: finitely many).
    window : int, optional
        Perturbations happen before step ``window`` at the latest.
    levels : sequence of str, optional
        Subset of :data:`LEVELS` (order kept: shrinking goes to the first).
    max_magnitude : float, optional
        Default: the workspace size.
    min_pushes : int, optional

    Returns
    -------
    SearchStrategy of tuple of Push
        Shrinks toward fewer, smaller, later perturbations (module docstring).
    """
    if window < 1 or max_pushes < 0 or not 0 <= min_pushes <= max_pushes:
        raise TliError(f"push_sequences: need window >= 1 and 0 <= min_pushes <= max_pushes, "
                       f"got window={window}, min_pushes={min_pushes}, max_pushes={max_pushes}")
    bad = [lv for lv in levels if lv not in LEVELS]
    if bad or not levels:
        raise TliError(f"push_sequences: levels must be a non-empty subset of {LEVELS}, got "
                       f"{list(levels)}")
    dim = len(task.lo)
    size = workspace_size(task) if max_magnitude is None else float(max_magnitude)
    regions = tuple(task.region_names)
    ordered = tuple(lv for lv in LEVELS if lv in levels)

    early_s = st.integers(0, window - 1)
    disp_s = displacements(dim, size)
    level_s = st.sampled_from(ordered)
    target_s = st.sampled_from(regions)

    @st.composite
    def one(draw: st.DrawFn) -> tuple[int, tuple[float, ...], str, str | None]:
        early = draw(early_s)
        disp = draw(disp_s)
        level = draw(level_s)
        target = draw(target_s) if level == "task" else None
        return early, disp, level, target

    def build(items: list[tuple[int, tuple[float, ...], str, str | None]]
              ) -> tuple[Push, ...]:
        out: dict[int, Push] = {}
        for early, disp, level, target in items:  # steps back from the window's end
            step = window - early
            out.setdefault(step, Push(step, disp, level, target))  # one push per step
        return tuple(out[t] for t in sorted(out))

    return st.lists(one(), min_size=min_pushes, max_size=max_pushes).map(build).filter(
        lambda seq: len(seq) >= min_pushes)


def starts(task: Task, *, regions: Sequence[str] | None = None
           ) -> st.SearchStrategy[tuple[float, ...]]:
    """Start states in the workspace box, in the given true regions.

    Parameters
    ----------
    task : Task
    regions : sequence of str, optional
        Default: every region. A campaign passes the regions whose first reading the spec's
        initial assumption allows (:func:`tli_verify.verify.simulate.start_regions`; scoop:
        all but yellow).

    Returns
    -------
    SearchStrategy of tuple of float
    """
    lo = np.asarray(task.lo, dtype=np.float64)
    hi = np.asarray(task.hi, dtype=np.float64)
    names = tuple(task.region_names)
    if regions is None:
        regions = names
    allowed = {names.index(r) for r in regions}

    def point(u: list[float]) -> tuple[float, ...]:
        return tuple(float(v) for v in lo + np.asarray(u) * (hi - lo))

    return (st.lists(st.floats(0.0, 1.0), min_size=lo.size, max_size=lo.size).map(point)
            .filter(lambda x: int(task.region_index(np.asarray(x)[None])[0]) in allowed))


def cases(task: Task, *, start: Sequence[float] | None = None, max_pushes: int = 3,
          window: int = 700, levels: Sequence[str] = LEVELS,
          max_magnitude: float | None = None, min_pushes: int = 0,
          start_regions: Sequence[str] | None = None) -> st.SearchStrategy[Case]:
    """Cases: a start (fixed, or drawn by :func:`starts`) and a perturbation sequence.

    Parameters
    ----------
    task : Task
    start : sequence of float, optional
        A fixed start; default: drawn in ``start_regions``.
    max_pushes, window, levels, max_magnitude, min_pushes
        See :func:`push_sequences`.
    start_regions : sequence of str, optional
        See :func:`starts`.

    Returns
    -------
    SearchStrategy of Case
    """
    seqs = push_sequences(task, max_pushes=max_pushes, window=window, levels=levels,
                          max_magnitude=max_magnitude, min_pushes=min_pushes)
    if start is not None:
        x0 = tuple(float(v) for v in start)
        return seqs.map(lambda s: Case(x0, s))
    return st.builds(Case, starts(task, regions=start_regions), seqs)


def target_robustness(robustness: float, *, label: str = "negated robustness") -> None:
    """Feed a run's robustness margin to :func:`hypothesis.target` (search maximises
    ``-robustness``: toward runs close to leaving a mode or the cut set, or missing the
    reachability deadline). Call it inside a ``@given`` test."""
    from hypothesis import target

    if math.isfinite(robustness):
        target(-float(robustness), label=label)


# ------------------------------------------------------------------------------ applying
def region_anchor(task: Task, region: str) -> FloatArray:
    """A reference point inside a true region (deterministic): the sampled state of the region
    nearest the mean of 400 uniform samples (seed 0), shape (n,)."""
    src = getattr(task, "source", None)
    key = (str(getattr(task, "name", type(task).__name__)),
           str(getattr(src, "sha256", None) or getattr(src, "source_sha256", None) or id(task)),
           region)
    hit = _ANCHORS.get(key)
    if hit is None:
        pts = task.sample_region(region, 400, np.random.default_rng(0))
        mean = pts.mean(axis=0)
        hit = pts[int(np.argmin(np.linalg.norm(pts - mean, axis=1)))].copy()
        _ANCHORS[key] = hit
    return hit


_ANCHORS: dict[tuple[str, str, str], FloatArray] = {}


_SEGMENT_SAMPLES = 256
"""Points along a push's segment where :func:`_bisect_inside` looks for its first exit from a
non-convex region."""


def _last_fraction_inside(inside: Callable[[FloatArray], npt.NDArray[np.int_]], a: FloatArray,
                          b: FloatArray, region: int, lo_s: float, hi_s: float) -> float:
    """Bisection (40 halvings) of the fraction ``s`` in ``[lo_s, hi_s]`` of the segment
    ``a + s (b - a)``: the last fraction found in ``region`` (``lo_s`` is in it)."""
    for _ in range(40):
        mid = 0.5 * (lo_s + hi_s)
        if int(inside((a + mid * (b - a))[None])[0]) == region:
            lo_s = mid
        else:
            hi_s = mid
    return lo_s


def _bisect_inside(task: Task, a: FloatArray, b: FloatArray, region: int) -> FloatArray:
    """``b`` if it lies in ``region``; else ``a + s/2 (b - a)`` with ``s`` a fraction in
    [0, 1] (bisection) keeping the segment's point in ``region`` (``a`` lies in it): half
    way to the region's boundary, so a push never lands on a mode boundary.

    The bisection assumes one crossing of the boundary along the segment. In a non-convex
    region (the scoop task's white region wraps around the others) the segment can leave and
    re-enter it, and the half-way point of the bisection's fraction can lie outside; then the
    first exit is found on :data:`_SEGMENT_SAMPLES` points of the segment and refined by
    bisection, and the result is halved towards ``a`` until it lies in ``region``.
    """
    inside = task.region_index
    if int(inside(b[None])[0]) == region:
        return b
    lo_s = _last_fraction_inside(inside, a, b, region, 0.0, 1.0)
    y = np.asarray(a + 0.5 * lo_s * (b - a), dtype=np.float64)
    if int(inside(y[None])[0]) == region:
        return y
    # more than one crossing: the first exit along the segment
    fr = np.linspace(0.0, 1.0, _SEGMENT_SAMPLES + 1)
    out = np.flatnonzero(inside(a[None, :] + fr[:, None] * (b - a)[None, :]) != region)
    k = int(out[0]) if out.size else _SEGMENT_SAMPLES
    lo_s = _last_fraction_inside(inside, a, b, region, float(fr[max(k - 1, 0)]), float(fr[k]))
    for _ in range(64):
        y = np.asarray(a + 0.5 * lo_s * (b - a), dtype=np.float64)
        if int(inside(y[None])[0]) == region:
            return y
        lo_s *= 0.5
    return np.asarray(a, dtype=np.float64).copy()


def apply_push(task: Task, x: npt.ArrayLike, push: Push) -> FloatArray:
    """The state after a perturbation at ``x`` (module docstring), inside the workspace box.

    Parameters
    ----------
    task : Task
    x : array_like, shape (n,)
    push : Push

    Returns
    -------
    ndarray, shape (n,)
    """
    lo = np.asarray(task.lo, dtype=np.float64)
    hi = np.asarray(task.hi, dtype=np.float64)
    xa = np.asarray(x, dtype=np.float64).reshape(-1)
    d = np.asarray(push.displacement, dtype=np.float64)
    free = np.clip(xa + d, lo, hi)
    if push.level == "free":
        return np.asarray(free, dtype=np.float64)
    if push.level == "motion":
        here = int(task.region_index(xa[None])[0])
        return _bisect_inside(task, xa, free, here)
    if push.level == "task":
        if push.target is None or push.target not in task.region_names:
            raise TliError(f"task-level push at step {push.step}: unknown target region "
                           f"{push.target!r}")
        region = list(task.region_names).index(push.target)
        return _bisect_inside(task, region_anchor(task, push.target), free, region)
    raise TliError(f"push at step {push.step}: unknown level {push.level!r} (one of "
                   f"{', '.join(LEVELS)})")


# ------------------------------------------------------------------------------ JSON
def case_to_json(case: Case) -> dict[str, Any]:
    """JSON-ready ``{"start": [...], "perturbations": [{"step", "displacement", "level",
    "target"}]}``."""
    return {"start": list(case.start),
            "perturbations": [{"step": p.step, "displacement": list(p.displacement),
                               "level": p.level, "target": p.target} for p in case.pushes]}


def case_from_json(data: Mapping[str, Any], *, dim: int, where: str = "case") -> Case:
    """Read :func:`case_to_json`'s form back; errors name the field.

    Raises
    ------
    TliError
        (exit 2) A missing or malformed field.
    """
    def vec(v: Any, field: str) -> tuple[float, ...]:
        if not isinstance(v, list) or len(v) != dim or not all(
                isinstance(c, int | float) and not isinstance(c, bool) and math.isfinite(c)
                for c in v):
            raise TliError(f"{where}: {field}: expected {dim} finite numbers")
        return tuple(float(c) for c in v)

    if not isinstance(data, Mapping):
        raise TliError(f"{where}: expected an object")
    start = vec(data.get("start"), "start")
    raw = data.get("perturbations")
    if not isinstance(raw, list):
        raise TliError(f"{where}: perturbations: expected a list")
    pushes = []
    last = 0
    for i, item in enumerate(raw):
        f = f"perturbations[{i}]"
        if not isinstance(item, Mapping):
            raise TliError(f"{where}: {f}: expected an object")
        step = item.get("step")
        if not isinstance(step, int) or isinstance(step, bool) or step <= last:
            raise TliError(f"{where}: {f}.step: expected an int > {last} (steps increase)")
        level = item.get("level", "free")
        if level not in LEVELS:
            raise TliError(f"{where}: {f}.level: one of {', '.join(LEVELS)}")
        target = item.get("target")
        if level == "task" and not isinstance(target, str):
            raise TliError(f"{where}: {f}.target: a task-level push needs a region name")
        pushes.append(Push(step, vec(item.get("displacement"), f"{f}.displacement"), level,
                           target if level == "task" else None))
        last = step
    return Case(start, tuple(pushes))
