"""The physics oracle: does one perturbed Franka trial satisfy its task?

:func:`check_trial` passes a trial when soup was delivered (at least one bead ends in the target
bowl), the goal mode was reached, its mode trace is a run of the task automaton (it starts in
an initial mode and every mode change is one the automaton can take
(:meth:`~tli_verify.logic.automaton.TaskAutomaton.mode_transitions`), reported by the executive,
or a replan after a perturbation or a sensor change the assumptions rule out), and every
invariance failure was answered with a cut, as the bisimulation oracle of the 2-D campaigns
requires (:mod:`tli_verify.verify.oracle`, ``INVARIANCE``: without modulation every unprovoked
exit is one). What it found is a :class:`TrialVerdict` (violation kinds
:data:`VIOLATION_KINDS`).

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 7.2 (30 perturbed trials on the Panda, all
successful).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from tli_verify.sim.loop import TrialResult

__all__ = [
    "VIOLATION_KINDS",
    "TrialVerdict",
    "check_trial",
]


VIOLATION_KINDS = ("delivery", "reachability", "automaton", "limits", "invariance")
"""What the physics oracle checks (:func:`check_trial`)."""


_EVENT = re.compile(r"^(\w+) at step (\d+)$")


@dataclass(frozen=True, slots=True)
class TrialVerdict:
    """What the physics oracle found in one trial (:func:`check_trial`).

    Attributes
    ----------
    seed : int
    violations : tuple of str
        Kinds found (a subset of :data:`VIOLATION_KINDS`, in that order); empty: passed.
    messages : tuple of str
        One line per problem.
    replans : int
        Mode changes outside the automaton's mode graph that the executive answered with a
        replan after a perturbation or a sensor change (allowed).
    """

    seed: int
    violations: tuple[str, ...] = ()
    messages: tuple[str, ...] = ()
    replans: int = 0

    @property
    def ok(self) -> bool:
        """True iff no violation."""
        return not self.violations

    def to_dict(self) -> dict[str, Any]:
        """JSON record."""
        return {"seed": self.seed, "ok": self.ok, "violations": list(self.violations),
                "messages": list(self.messages), "replans": self.replans}


def _events_by_step(events: Sequence[str]) -> dict[int, set[str]]:
    out: dict[int, set[str]] = {}
    for line in events:
        m = _EVENT.match(line)
        if m is not None:
            out.setdefault(int(m.group(2)), set()).add(m.group(1))
    return out


def check_trial(result: TrialResult, automaton: Any,
                goal_modes: Sequence[str] | None = None) -> TrialVerdict:
    """The physics oracle on one trial.

    Index ``k`` of ``result.modes`` is the mode after control step ``k`` (0: the reset
    reading), the step the executive's events name.

    Checks (violation kinds):

    * ``"limits"`` -- the robot's reflex did not stop it (a joint or end-effector velocity
      beyond the Franka's limit ends the trial, failed);
    * ``"delivery"`` -- at least one bead ended in the target bowl (``success``, consistent
      with ``delivered``);
    * ``"reachability"`` -- the trace ends in a goal mode (default: the automaton's sink modes,
      :meth:`~tli_verify.logic.automaton.TaskAutomaton.sink_modes`);
    * ``"invariance"`` -- every invariance failure the executive reported (a mode exit no
      perturbation caused: ``InvarianceFailure at step k``) was answered with a cut of the mode
      at that step (``CutAdded at step k``; paper Sec. 5.2). A policy that does not modulate
      (the no-modulation ablation) fails it at its first such exit, as in the 2-D oracle;
    * ``"automaton"`` -- the trace is a run of the task automaton: every mode is one of its
      modes, the first is the mode of an initial state (or the executive reported the initial
      reading as an assumption violation), and every mode change ``m -> m'`` at step ``k`` was
      reported by the executive (``ModeChange at step k``) and is either a mode transition the
      automaton can take
      (:meth:`~tli_verify.logic.automaton.TaskAutomaton.mode_transitions`) or a replan
      (``Replan at step k``) after a perturbation or a sensor change the assumptions rule out
      (``Perturbation`` or ``AssumptionViolationEvent`` at step ``k``); a change at a step
      with a ``Stall`` (the stall rule, :mod:`tli_verify.runtime.stall`) must be a transition
      of the automaton too, and every reported stall must come with its mode change.

    Parameters
    ----------
    result : TrialResult
    automaton : TaskAutomaton
        The spec's (the one the executive ran).
    goal_modes : sequence of str, optional

    Returns
    -------
    TrialVerdict
    """
    found: dict[str, list[str]] = {}

    def fail(kind: str, message: str) -> None:
        found.setdefault(kind, []).append(message)

    if result.stopped is not None:
        fail("limits", f"the robot stopped: {result.stopped} (a limit of the Franka would have "
             "been exceeded)")
    if not result.success or result.delivered < 1:
        fail("delivery", f"{result.delivered} bead(s) in the target bowl: no soup delivered"
             if result.delivered < 1 or result.stopped is not None else
             f"{result.delivered} bead(s) delivered but the trial says it failed")
    modes = list(result.modes)
    goals = tuple(goal_modes) if goal_modes is not None else tuple(automaton.sink_modes())
    if not modes:
        fail("automaton", "empty mode trace")
        fail("reachability", "empty mode trace: no goal mode reached")
    elif modes[-1] not in goals:
        fail("reachability", f"ends in mode {modes[-1]!r}, not a goal mode "
             f"({', '.join(goals) or '-'}): the task was not completed")
    events = _events_by_step(result.events)
    known = set(automaton.modes)
    unknown = sorted({m for m in modes if m not in known})
    replans = 0
    if unknown:
        fail("automaton", f"mode {unknown[0]!r} is not a mode of the automaton "
             f"({', '.join(automaton.modes)})")
    elif modes:
        initial = {automaton.states[i].mode for i in automaton.initial}
        if modes[0] not in initial and "AssumptionViolationEvent" not in events.get(0, set()):
            fail("automaton", f"starts in mode {modes[0]!r}, not an initial mode "
                 f"({', '.join(sorted(initial))})")
        graph = {(a, b) for a, b in automaton.mode_transitions()}
        stalled: list[tuple[int, str, str]] = []  # re-entries (step, mode, via) not back yet
        for k in range(1, len(modes)):
            a, b = modes[k - 1], modes[k]
            if a == b:
                continue
            at = events.get(k, set())
            if "ModeChange" not in at:
                fail("automaton", f"step {k}: mode {a} -> {b} that the executive did not "
                     "report (no ModeChange at that step)")
            elif "Stall" in at and (a, b) not in graph:
                fail("automaton", f"step {k}: the stall rule's re-entry {a} -> {b} is no "
                     "transition of the automaton")
            elif "Stall" in at:
                stalled.append((k, a, b))
            elif "Reentered" in at and stalled and stalled[-1][1:] == (b, a):
                stalled.pop()  # the re-entry came back to the stalled mode
            elif (a, b) in graph:
                continue
            elif "Replan" in at and at & {"Perturbation", "AssumptionViolationEvent"}:
                replans += 1
            else:
                fail("automaton", f"step {k}: mode {a} -> {b} is no transition of the "
                     "automaton and no replan after a perturbation or sensor change")
    unanswered = sorted(k for k, names in events.items()
                        if "InvarianceFailure" in names and "CutAdded" not in names)
    if unanswered:
        more = f" (and {len(unanswered) - 1} more)" if len(unanswered) > 1 else ""
        fail("invariance", f"step {unanswered[0]}: an invariance failure (a mode exit no "
             f"perturbation caused) that the policy did not answer with a cut{more}")
    for k in sorted(k for k, names in events.items() if "Stall" in names):
        if k >= len(modes) or k < 1 or modes[k] == modes[k - 1]:
            fail("automaton", f"step {k}: a stall reported without the stall rule's mode "
                 "change (re-entry from the predecessor)")
    kinds = tuple(k for k in VIOLATION_KINDS if k in found)
    return TrialVerdict(seed=result.seed, violations=kinds,
                        messages=tuple(m for k in kinds for m in found[k][:3]),
                        replans=replans)
