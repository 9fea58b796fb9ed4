"""Perturbations of the Franka trials: wrenches on the hand, and their hypothesis strategies.

Two levels (:data:`LEVELS`), as wrenches in ``xfrc_applied`` on the hand:

* ``"motion"`` -- a *push*: a force of :data:`PUSH_FORCE` N in any direction for
  :data:`PUSH_DURATION` s, starting at a time in :data:`PUSH_WINDOW` s of the trial;
* ``"task"`` -- a *tilt*: a torque of :data:`TILT_TORQUE` Nm about the world ``-x`` axis for
  :data:`TILT_DURATION` s, which spills the soup; it starts a delay in :data:`TILT_DELAY` s after
  the soup is carried out of the soup bowl (:func:`tli_verify.sim.loop.run_trial` counts a
  tilt's ``start`` from there).

The encoding shrinks, as :mod:`tli_verify.verify.strategies` does, toward **fewer**
perturbations (lists), **smaller** ones (force, torque and duration toward their lower bounds)
and **later** ones. :func:`draw` gives the perturbations of one trial, deterministic in the seed
in any process. The trial loop (:mod:`tli_verify.sim.loop`) and the physical campaign
(:mod:`tli_verify.sim.campaign`) both use this module; neither imports the other's internals.

References
----------
Wang et al., "Temporal Logic Imitation", CoRL 2022, Sec. 7.2 and Asm. 2 (finitely many
perturbations).
"""

from __future__ import annotations

import contextlib
import math
import random
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from hypothesis import strategies as st

from tli_verify.errors import TliError
from tli_verify.verify.strategies import directions

__all__ = [
    "LEVELS",
    "PUSH_DURATION",
    "PUSH_FORCE",
    "PUSH_WINDOW",
    "TILT_DELAY",
    "TILT_DURATION",
    "TILT_TORQUE",
    "Perturbation",
    "draw",
    "isolated_draws",
    "pushes",
    "tilts",
    "trial_perturbations",
]


@dataclass(frozen=True, slots=True)
class Perturbation:
    """One wrench on the hand.

    Attributes
    ----------
    kind : str
        ``"push"`` (motion level) or ``"tilt"`` (task level: spills).
    start : float
        Seconds: after the trial's start (push), or after the soup is first on the spoon
        (tilt).
    duration : float
        Seconds.
    wrench : tuple of float, length 6
        Force (N) and torque (Nm) in the world frame.
    """

    kind: str
    start: float
    duration: float
    wrench: tuple[float, ...]

    def to_dict(self) -> dict[str, Any]:
        """The JSON record."""
        return {"kind": self.kind, "start": round(self.start, 4),
                "duration": self.duration, "wrench": [round(w, 4) for w in self.wrench]}


_MS = 1000.0
"""Times are drawn in whole milliseconds (a readable, replayable case)."""

LEVELS: tuple[str, ...] = ("motion", "task")
"""Physical perturbation levels: ``"motion"`` pushes, ``"task"`` tilts (they spill)."""
PUSH_FORCE = (10.0, 35.0)
"""Force of a push, N (shrinks to the lower bound)."""
PUSH_DURATION = (0.1, 0.3)
"""Duration of a push, s."""
PUSH_WINDOW = (0.5, 6.0)
"""A push starts in this window, s after the trial's start (a nominal trial scoops from about
1.5 s, carries the soup out of the bowl at about 3.3 s and is above the target at about 5.7 s)."""
TILT_TORQUE = (15.0, 25.0)
"""Magnitude of a tilt's torque about the world ``-x`` axis, Nm (-20 Nm for 0.3 s spills every
carried bead)."""
TILT_DURATION = (0.2, 0.4)
"""Duration of a tilt, s."""
TILT_DELAY = (0.0, 1.5)
"""A tilt starts this long after the soup is carried out of the soup bowl, s."""

def _check_range(name: str, lo: float, hi: float, *, positive: bool = False) -> None:
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi) or lo < 0 or (
            positive and lo <= 0):
        raise TliError(f"{name}: need {'0 < ' if positive else '0 <= '}lo <= hi, finite; got "
                       f"({lo}, {hi})")


def _later(window: tuple[float, float]) -> st.SearchStrategy[float]:
    """A time in ``window`` (s, rounded to the millisecond), encoded as its distance before the
    window's end: it shrinks to the end (later)."""
    lo, hi = window
    span = round((hi - lo) * _MS)
    return st.floats(0.0, float(span)).map(lambda early: (round(hi * _MS) - round(early)) / _MS)


def _duration(bounds: tuple[float, float]) -> st.SearchStrategy[float]:
    """A duration in ``bounds`` (s, rounded to the millisecond), shrinking to the lower bound."""
    lo, hi = (round(b * _MS) for b in bounds)
    return st.integers(lo, hi).map(lambda ms: ms / _MS)


def pushes(*, force: tuple[float, float] = PUSH_FORCE,
           duration: tuple[float, float] = PUSH_DURATION,
           window: tuple[float, float] = PUSH_WINDOW) -> st.SearchStrategy[Perturbation]:
    """Motion-level pushes: a force in any direction on the hand.

    Parameters
    ----------
    force : (float, float), optional
        Bounds of ``|F|``, N.
    duration : (float, float), optional
        Bounds, s.
    window : (float, float), optional
        Start times, s after the trial's start.

    Returns
    -------
    SearchStrategy of Perturbation
        ``kind = "push"``, ``wrench = (F_x, F_y, F_z, 0, 0, 0)`` with ``|F|`` in ``force``;
        shrinks toward the smallest force, the shortest duration and the latest start, the
        direction toward ``+x``.
    """
    _check_range("push force", *force, positive=True)
    _check_range("push duration", *duration, positive=True)
    _check_range("push window", *window)

    def build(parts: tuple[float, float, float, tuple[float, ...]]) -> Perturbation:
        start, length, f, unit = parts
        return Perturbation("push", start, length,
                            (*(float(f * c) for c in unit), 0.0, 0.0, 0.0))

    return st.tuples(_later(window), _duration(duration), st.floats(*force),
                     directions(3)).map(build)


def tilts(*, torque: tuple[float, float] = TILT_TORQUE,
          duration: tuple[float, float] = TILT_DURATION,
          delay: tuple[float, float] = TILT_DELAY) -> st.SearchStrategy[Perturbation]:
    """Task-level tilts: a torque about the world ``-x`` axis on the hand (spills the soup).

    Parameters
    ----------
    torque : (float, float), optional
        Bounds of the torque's magnitude, Nm (applied as ``-torque`` about ``x``).
    duration : (float, float), optional
        Bounds, s.
    delay : (float, float), optional
        Start, s after the soup is carried out of the soup bowl.

    Returns
    -------
    SearchStrategy of Perturbation
        ``kind = "tilt"``, ``wrench = (0, 0, 0, -torque, 0, 0)``; shrinks toward the smallest
        torque, the shortest duration and the longest delay.
    """
    _check_range("tilt torque", *torque, positive=True)
    _check_range("tilt duration", *duration, positive=True)
    _check_range("tilt delay", *delay)

    def build(parts: tuple[float, float, float]) -> Perturbation:
        start, length, m = parts
        return Perturbation("tilt", start, length, (0.0, 0.0, 0.0, -float(m), 0.0, 0.0))

    return st.tuples(_later(delay), _duration(duration), st.floats(*torque)).map(build)


def trial_perturbations(*, max_pushes: int = 1, max_tilts: int = 1, min_pushes: int = 0,
                        min_tilts: int = 0, levels: Sequence[str] = LEVELS,
                        push: st.SearchStrategy[Perturbation] | None = None,
                        tilt: st.SearchStrategy[Perturbation] | None = None,
                        ) -> st.SearchStrategy[tuple[Perturbation, ...]]:
    """The perturbations of one physical trial: pushes, then tilts, each sorted by start.

    Parameters
    ----------
    max_pushes, max_tilts : int, optional
        At most this many of each (paper Asm. 2: finitely many).
    min_pushes, min_tilts : int, optional
        At least this many.
    levels : sequence of str, optional
        Subset of :data:`LEVELS`: without ``"motion"`` no push, without ``"task"`` no tilt.
    push, tilt : SearchStrategy of Perturbation, optional
        Default :func:`pushes` and :func:`tilts` with the module's bounds.

    Returns
    -------
    SearchStrategy of tuple of Perturbation
        Shrinks toward fewer, smaller, later perturbations (module doc); two perturbations of
        one kind drawn with the same start are one (the first).
    """
    bad = [lv for lv in levels if lv not in LEVELS]
    if bad or not levels:
        raise TliError(f"trial_perturbations: levels must be a non-empty subset of {LEVELS}, "
                       f"got {list(levels)}")
    if not (0 <= min_pushes <= max_pushes and 0 <= min_tilts <= max_tilts):
        raise TliError("trial_perturbations: need 0 <= min <= max pushes and tilts, got "
                       f"pushes {min_pushes}..{max_pushes}, tilts {min_tilts}..{max_tilts}")
    if "motion" not in levels:
        if min_pushes:
            raise TliError("trial_perturbations: min_pushes > 0 without the motion level")
        max_pushes = 0
    if "task" not in levels:
        if min_tilts:
            raise TliError("trial_perturbations: min_tilts > 0 without the task level")
        max_tilts = 0

    def unique(items: list[Perturbation]) -> tuple[Perturbation, ...]:
        by_start: dict[float, Perturbation] = {}
        for p in items:
            by_start.setdefault(p.start, p)
        return tuple(by_start[s] for s in sorted(by_start))

    push_list = st.lists(push if push is not None else pushes(), min_size=min_pushes,
                         max_size=max_pushes).map(unique)
    tilt_list = st.lists(tilt if tilt is not None else tilts(), min_size=min_tilts,
                         max_size=max_tilts).map(unique)
    return st.tuples(push_list, tilt_list).map(lambda pt: pt[0] + pt[1]).filter(
        lambda ps: sum(p.kind == "push" for p in ps) >= min_pushes
        and sum(p.kind == "tilt" for p in ps) >= min_tilts)


@contextlib.contextmanager
def isolated_draws() -> Iterator[None]:
    """Hypothesis generation independent of the process's history: no local constants and a
    fresh ``CONSTANTS_CACHE`` (:func:`~tli_verify.verify.draws.import_independent_draws`,
    which the 2-D campaigns use too)."""
    from tli_verify.verify.draws import import_independent_draws

    with import_independent_draws():
        yield


_ATTEMPTS = 20
"""Fresh random states :func:`draw` tries when the strategy rejects a draw (two pushes drawn
with the same start, when more than one is asked for)."""


def draw(seed: int, *, pushes: int = 1, tilts: int = 1) -> list[Perturbation]:
    """The perturbations of trial ``seed``: deterministic in ``seed``, in any process.

    One example of :func:`trial_perturbations` (exactly ``pushes`` pushes and ``tilts`` tilts)
    generated by hypothesis's own provider from ``Random("tli-verify:franka:<seed>")`` -- every
    choice drawn afresh, with hypothesis's bias toward the bounds -- under
    :func:`~tli_verify.verify.draws.import_independent_draws` (no "local constants" from
    whatever modules happen to be imported, nor from earlier draws: :func:`isolated_draws`, so
    the draw does not depend on the process).
    ``hypothesis.find`` is not used for a single draw: its first examples are the simplest one
    and variations of it, a poor sample of one trial's perturbations. Should hypothesis's
    internal data API change, :func:`_draw_by_find` (public API only) takes over.

    Parameters
    ----------
    seed : int
    pushes, tilts : int, optional
        How many of each (the paper's trials: one push, one tilt).

    Returns
    -------
    list of Perturbation
    """
    if pushes < 0 or tilts < 0:
        raise TliError(f"draw: pushes and tilts must be >= 0, got {pushes}, {tilts}")
    if pushes == 0 and tilts == 0:
        return []
    strategy = trial_perturbations(min_pushes=pushes, max_pushes=pushes, min_tilts=tilts,
                                   max_tilts=tilts)
    try:
        from hypothesis.control import BuildContext
        from hypothesis.errors import StopTest, UnsatisfiedAssumption
        from hypothesis.internal.conjecture.data import ConjectureData
    except ImportError:  # pragma: no cover - hypothesis moved its internals
        return _draw_by_find(strategy, seed)
    with isolated_draws():
        for attempt in range(_ATTEMPTS):
            key = f"tli-verify:franka:{int(seed)}" + (f":{attempt}" if attempt else "")
            try:
                data = ConjectureData(random=random.Random(key))
                with BuildContext(data, wrapped_test=lambda: None):
                    return list(data.draw(strategy))
            except (StopTest, UnsatisfiedAssumption):
                continue
            except TypeError:  # pragma: no cover - hypothesis changed the signatures
                return _draw_by_find(strategy, seed)
    raise TliError(  # pragma: no cover - 20 rejections in a row
        f"draw: no perturbations of {pushes} push(es) and {tilts} tilt(s) with distinct starts "
        f"in {_ATTEMPTS} attempts (seed {seed})")


def _draw_by_find(strategy: st.SearchStrategy[tuple[Perturbation, ...]], seed: int
                  ) -> list[Perturbation]:
    """The fallback of :func:`draw`, public hypothesis API only: the sixth distinct example
    ``hypothesis.find`` generates with ``random=Random(seed)`` (the first are the simplest
    example and variations of it)."""
    from hypothesis import HealthCheck, Phase, find, settings
    from hypothesis.errors import NoSuchExample

    seen: list[tuple[Perturbation, ...]] = []

    def collect(example: tuple[Perturbation, ...]) -> bool:
        if example not in seen:
            seen.append(example)
        return len(seen) > 5

    config = settings(max_examples=60, database=None, deadline=None, derandomize=False,
                      phases=[Phase.generate], suppress_health_check=list(HealthCheck),
                      report_multiple_bugs=False, print_blob=False)
    try:
        with isolated_draws():
            find(strategy, collect, settings=config,
                 random=random.Random(f"tli-verify:franka:{int(seed)}"))
    except NoSuchExample:
        pass
    if not seen:
        raise TliError(f"draw: hypothesis generated no perturbations (seed {seed})")
    return list(seen[-1])
