"""What the LTL-DS executive reports, step by step (frozen values; see :mod:`.executive`).

Every event carries the control step ``step`` (0 = the ``reset`` reading) at which it happened.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.boundary.cuts import Cut

__all__ = [
    "AssumptionViolationEvent",
    "CutAdded",
    "CutFailed",
    "Event",
    "InvarianceFailure",
    "ModeChange",
    "Perturbation",
    "Reentered",
    "Replan",
    "Stall",
    "TransitionLearned",
    "TransitionRefused",
    "event_to_json",
    "mode_sequence",
]

FloatArray = npt.NDArray[np.float64]


def mode_sequence(modes: Sequence[str]) -> str:
    """The modes visited, in order, run-length collapsed: ``"abcd"`` when every name is one
    character, else joined by ``-`` (``"w1-y-d1"``). The one form every report uses."""
    runs: list[str] = []
    for m in modes:
        if not runs or runs[-1] != m:
            runs.append(str(m))
    return "".join(runs) if all(len(m) == 1 for m in runs) else "-".join(runs)


@dataclass(frozen=True, slots=True)
class ModeChange:
    """The automaton moved to another mode.

    Attributes
    ----------
    step : int
    from_mode, to_mode : str
    state : int
        The automaton state entered.
    expected : bool
        ``to_mode`` was the planned next mode (a nominal transition).
    """

    step: int
    from_mode: str
    to_mode: str
    state: int
    expected: bool


@dataclass(frozen=True, slots=True)
class Replan:
    """The reading showed a mode other than the planned one; the automaton replans from it
    (receding horizon, paper Sec. 1 and Fig. 3(b)).

    Attributes
    ----------
    step : int
    from_mode, to_mode : str
        The mode left and the mode the reading shows.
    planned : str or None
        The mode that was planned next.
    new_plan : str or None
        The next mode planned from ``to_mode``.
    cause : str
        ``"perturbation"``, ``"invariance failure"`` or ``"assumption violation"``.
    """

    step: int
    from_mode: str
    to_mode: str
    planned: str | None
    new_plan: str | None
    cause: str


@dataclass(frozen=True, slots=True, eq=False)
class InvarianceFailure:
    """A mode exit no perturbation caused, to a mode other than the planned next one
    (paper Sec. 5.2).

    Attributes
    ----------
    step : int
    mode : str
        The mode left.
    key : str
        The DS that was running.
    to_mode : str
        The mode the reading shows.
    entry, last_inside, outside : ndarray, shape (n,)
        ``x^0`` (mode entry), ``x^{T_f-1}`` (last in-mode state), ``x^{T_f}`` (failure state).
    """

    step: int
    mode: str
    key: str
    to_mode: str
    entry: FloatArray
    last_inside: FloatArray
    outside: FloatArray


@dataclass(frozen=True, slots=True, eq=False)
class CutAdded:
    """A cut learned from an invariance failure and applied at once (a new model).

    Attributes
    ----------
    step : int
    mode : str
        The mode whose region the cut bounds.
    keys : tuple of str
        The DS of that mode that got it (they share the region's cuts).
    cut : Cut
    cuts : int
        The mode's number of cuts now.
    fallback : bool
        Solved keeping only this failure's ``x^0`` inside (not every recorded entry state).
    shift : float
        0, or the fraction of the exit step the plane was moved off ``x^{T_f-1}`` because no
        plane through it separates the failure (``tli_verify.runtime.online.SHIFTS``).
    """

    step: int
    mode: str
    keys: tuple[str, ...]
    cut: Cut
    cuts: int
    fallback: bool
    shift: float = 0.0


@dataclass(frozen=True, slots=True)
class CutFailed:
    """No separating cut exists for an invariance failure (the failure is reported, not cut).

    Attributes
    ----------
    step : int
    mode : str
    reason : str
    """

    step: int
    mode: str
    reason: str


@dataclass(frozen=True, slots=True)
class AssumptionViolationEvent:
    """A sensor reading the spec's environment assumptions rule out.

    Attributes
    ----------
    step : int
    state : int
        The automaton state it was read in.
    reading : tuple of str
        The true sensors.
    message : str
    resynced : int or None
        The automaton state consistent with the reading the executive moved to, or None when
        none exists (then it holds: zero velocity, same state, until a reading it can follow).
    """

    step: int
    state: int
    reading: tuple[str, ...]
    message: str
    resynced: int | None


@dataclass(frozen=True, slots=True)
class Perturbation:
    """The caller reported a perturbation before this step's reading.

    Attributes
    ----------
    step : int
    mode : str
        The mode the executive was in.
    """

    step: int
    mode: str


@dataclass(frozen=True, slots=True)
class TransitionLearned:
    """``--learn-transitions``: a mode change the spec lacked was added to ``phi_t^s``, the
    spec re-synthesized (realizable, well-separated, every state covered by the model's DS)
    and the run carried on in the new automaton (paper appendix F, "a new automaton will be
    re-synthesized"; :func:`tli_verify.logic.infer.regrow`).

    Attributes
    ----------
    step : int
    from_mode, to_mode : str
        The edge added.
    reading : tuple of str
        The true sensors of the reading that showed it.
    state : int
        The state of the new automaton the run carries on from.
    states, edges : int
        The new automaton's size (states, reading-cube edges).
    mode_edges : int
        Its distinct mode changes (``from != to``) now.
    perturbed : bool
        A reported perturbation caused the change.
    """

    step: int
    from_mode: str
    to_mode: str
    reading: tuple[str, ...]
    state: int
    states: int
    edges: int
    mode_edges: int
    perturbed: bool


@dataclass(frozen=True, slots=True)
class TransitionRefused:
    """``--learn-transitions``: a mode change the spec lacks was *not* added; the spec and the
    automaton are kept and the reading is handled as an assumption violation.

    Attributes
    ----------
    step : int
    from_mode : str
    to_mode : str or None
        The mode the reading shows (None: no mode label holds, paper Asm. 3).
    reading : tuple of str
    reason : str
        Why (unrealizable or not well-separated grown spec, no DS for a state of the grown
        automaton, assumptions that cannot be relaxed, a reading no mode label covers).
    """

    step: int
    from_mode: str
    to_mode: str | None
    reading: tuple[str, ...]
    reason: str


@dataclass(frozen=True, slots=True)
class Stall:
    """The assumption monitor: the mode's certified DS has converged (``V`` below the stall
    rule's level for its dwell time) and the reading of the next mode has not come -- the
    environment's liveness assumption for the mode is being broken. The executive answers by
    the stall rule (:class:`~tli_verify.runtime.stall.StallRule`): it re-enters the mode from
    its predecessor (a ``ModeChange`` to ``via`` at the same step).

    Attributes
    ----------
    step : int
    mode : str
        The stalled mode.
    key : str
        Its DS.
    value : float
        The certified ``V`` of ``key`` at the state (the last of the dwell).
    via : str
        The predecessor mode whose DS (``via_key``) runs back to the mode's entry.
    via_key : str
    """

    step: int
    mode: str
    key: str
    value: float
    via: str
    via_key: str


@dataclass(frozen=True, slots=True)
class Reentered:
    """The stall rule's re-entry ended: the predecessor's DS converged (or the reading
    changed) and the executive resumed the automaton's mode (a ``ModeChange`` at the same
    step, from ``via``).

    Attributes
    ----------
    step : int
    mode : str
        The mode re-entered (the stalled one).
    via : str
    converged : bool
        The predecessor's DS converged (False: the reading changed first).
    """

    step: int
    mode: str
    via: str
    converged: bool


Event = (ModeChange | Replan | InvarianceFailure | CutAdded | CutFailed
         | AssumptionViolationEvent | Perturbation | TransitionLearned | TransitionRefused
         | Stall | Reentered)


def event_to_json(event: Event) -> dict[str, Any]:
    """JSON-ready record ``{"event": <class name>, ...fields}`` (arrays as lists)."""
    out: dict[str, Any] = {"event": type(event).__name__}
    for name in event.__slots__:
        value = getattr(event, name)
        if isinstance(value, np.ndarray):
            value = value.tolist()
        elif isinstance(value, Cut):
            value = value.to_dict()
        elif isinstance(value, tuple):
            value = list(value)
        out[name] = value
    return out
