"""The stall rule: a mode whose DS has converged without the next mode's reading.

LTL-DS guarantees that each mode's certified DS reaches its attractor, and the demonstrations
put that attractor where the next mode's reading comes (paper Asm. 3, Sec. 4.4). The spec's
environment liveness assumptions (``GF(!b | s)``: "while scooping, soup eventually gets on the
spoon") say the reading does come. When the DS has converged and the reading has not come, the
environment is breaking that assumption, and the runtime assumption monitor says so
(:class:`~tli_verify.runtime.events.Stall`). The executive answers by one rule, the same for
every task, stated on the automaton and the model:

    **Stall rule.** In a non-goal mode ``m`` run by DS ``k``, when the certified Lyapunov
    function of ``k`` stays below ``level(k) = lambda_min(P_k) r^2`` for ``dwell`` seconds
    (so the state is within ``r`` of ``k``'s attractor, in the state's units) -- *converged* --
    or falls by less than a fraction ``progress`` of itself over ``blocked_after`` seconds
    with no perturbation reported -- *blocked*: the certificate's decrease is not happening on
    the robot -- with the automaton state unchanged, the executive re-enters ``m`` from its
    predecessor: it runs the
    DS ``p -> m`` (``p`` a mode the automaton can go from to ``m`` and back, ``m -> p`` and
    ``p -> m`` both mode transitions, the model having a DS of ``p`` planned into ``m``) until
    that DS converges by the same test (``V`` below its level, no dwell) or the reading
    changes, then resumes ``m`` (the automaton state of ``m`` is kept throughout; a changed
    reading is the next period's automaton step, from ``m``). A perturbation reported during
    the re-entry does not end it: it is a motion-level disturbance the certified DS of ``p``
    rides out (on the Panda the robot's own contact with the bowl's slope, pressing with up to
    the leash's force, read as one, and ended every re-entry within 0.5 s, so that ``m``
    resumed where it had stalled and stalled again, 12 times in a trial). The mode
    trace shows ``m p m``, both changes reported by the executive (``ModeChange``), the first
    with a :class:`~tli_verify.runtime.events.Stall` at its step, the second with a
    :class:`~tli_verify.runtime.events.Reentered`.

The rule uses only what the robot knows: its measured state, the certified ``V`` and the
reading. It is the paper's "LTL replans the scooping DS until the robot enters the
transferring mode successfully" (appendix, Robot Experiment 1), made an event the oracle checks
(:func:`tli_verify.sim.trial_oracle.check_trial`), not a heuristic outside the executive.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TliError

if TYPE_CHECKING:
    from tli_verify.logic.automaton import TaskAutomaton
    from tli_verify.model.types import Model

__all__ = ["MAX_STALL_SECONDS", "STALL_PARAMETERS", "StallRule", "lyapunov_level",
           "lyapunov_value", "reentry_route"]

FloatArray = npt.NDArray[np.float64]

STALL_PARAMETERS = ("radius", "dwell", "blocked_after", "progress")
"""The rule's fields, as the evidence and the exported artifact record them."""

MAX_STALL_SECONDS = 3600.0
"""Longest ``dwell`` or ``blocked_after`` (s): the step counts stay integers a controller can
hold (1e308 s overflowed the count)."""


@dataclass(frozen=True, slots=True)
class StallRule:
    """The stall rule's parameters (module doc).

    Attributes
    ----------
    radius : float
        ``r``: the DS has converged when ``V < lambda_min(P) r^2`` (state units).
    dwell : float
        Seconds ``V`` must stay below the level before a stall is reported.
    blocked_after : float
        Seconds over which ``V`` must fall by at least ``progress`` (a fraction) of its value,
        no perturbation reported and the automaton state unchanged; otherwise the DS is
        blocked (the robot does not follow the certified decrease: wedged against the pile or
        a slope) and a stall is reported too.
    progress : float
    """

    radius: float = 0.3
    dwell: float = 1.0
    blocked_after: float = 1.5
    progress: float = 0.02

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius) and self.radius > 0 and math.isfinite(self.dwell)
                and self.dwell >= 0):
            raise TliError(f"stall rule: need radius > 0 and dwell >= 0, got {self.radius}, "
                           f"{self.dwell}")
        if not (math.isfinite(self.blocked_after) and self.blocked_after > 0
                and 0.0 <= self.progress < 1.0):
            raise TliError(f"stall rule: need blocked_after > 0 and 0 <= progress < 1, got "
                           f"{self.blocked_after}, {self.progress}")
        if max(self.dwell, self.blocked_after) > MAX_STALL_SECONDS:
            raise TliError(f"stall rule: dwell and blocked_after at most {MAX_STALL_SECONDS:g} "
                           f"s, got {self.dwell}, {self.blocked_after}")

    def periods(self, dt: float) -> tuple[int, int]:
        """``(dwell_steps, window)`` at control period ``dt``: the control steps ``V`` must stay
        below the level (at least 1) and the steps the blocked test looks back over (at least
        2), as the executive counts them (Python's ``round``: half to even). The exported C
        evaluator reads these integers, never recomputes them."""
        return max(1, round(self.dwell / dt)), max(2, round(self.blocked_after / dt))

    def to_dict(self) -> dict[str, float]:
        """The evidence's record."""
        return {"radius": self.radius, "dwell": self.dwell,
                "blocked_after": self.blocked_after, "progress": self.progress}


def lyapunov_value(attractor: FloatArray, P: FloatArray, x: FloatArray) -> float:
    """``V(x) = (x - x*)^T P (x - x*)``, the DS's certified Lyapunov function.

    Summed in a fixed order, the exported C evaluator's (``tli_policy.c``, ``lyapunov``):
    ``c_j = sum_i d_i P_ij`` over ``i`` in turn, then ``sum_j c_j d_j`` over ``j`` in turn,
    each product and sum rounded once. ``d @ P @ d`` goes through BLAS, whose kernels sum in
    other orders, so its last bit differed from the C loop's for a third to two thirds of
    states, and at ``V`` within a rounding of a level the stall rule fired on one side only.
    """
    d = np.asarray(x, dtype=np.float64) - attractor
    Pm = np.asarray(P, dtype=np.float64)
    c = d[0] * Pm[0]
    for i in range(1, d.shape[0]):
        c = c + d[i] * Pm[i]
    v = 0.0
    for cj, dj in zip(c.tolist(), d.tolist(), strict=True):
        v += cj * dj
    return v


def lyapunov_level(P: FloatArray, radius: float) -> float:
    """``lambda_min(P) r^2``: ``V`` below it puts the state within ``r`` of the attractor."""
    return float(np.linalg.eigvalsh(np.asarray(P, dtype=np.float64))[0]) * radius * radius


def reentry_route(automaton: TaskAutomaton, model: Model, mode: str) -> tuple[str, str] | None:
    """The stall rule's way back into ``mode``: ``(p, key)``, a mode ``p`` with ``p -> mode``
    and ``mode -> p`` mode transitions of the automaton and a DS ``key`` of ``p`` planned into
    ``mode`` (the first by key), or None (``mode`` has no such predecessor: the rule does not
    fire there). The one definition the executive and the exported artifact
    (:mod:`tli_verify.deploy.export`) share."""
    graph = {(a, b) for a, b in automaton.mode_transitions()}
    keys = sorted(k for k, mm in model.modes.items()
                  if mm.next_mode == mode and mm.mode != mode
                  and (mm.mode, mode) in graph and (mode, mm.mode) in graph)
    return (model.modes[keys[0]].mode, keys[0]) if keys else None
