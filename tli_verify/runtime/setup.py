"""What a closed-loop run needs, loaded once: the task, its automaton, the certified model.

A :class:`Setup` holds the task, the automaton synthesized from the spec, the model, its
certificate and the goal (the project loader makes it once:
:attr:`tli_verify.loaded.LoadedProject.setup`). :func:`make_policy` builds the executive of one
of the policies compared in the paper (:data:`VARIANTS`):

- ``LTL-DS``: the executive (:class:`~tli_verify.runtime.executive.LTLDSPolicy`): replanning
  and cuts learned online;
- ``no-modulation``: the executive without cuts (``learn_cuts=False``, and the model's own
  cuts, offline ones included, dropped: :meth:`LTLDSPolicy.drop_cuts`): replanning only;
- ``no-replan``: :class:`SequencePolicy`, the demonstrated mode sequence run open loop (a
  mode's DS runs until the reading shows the planned next mode; an unexpected reading does not
  change the DS run), cuts learned as in LTL-DS;
- ``BC``: the paper's MLP per mode under the automaton (replanning, cuts; a BC policy has no
  certificate, so the executive runs the certified DS model for its bookkeeping and the BC nets
  move the state; :func:`tli_verify.runtime.episodes.run_variant_batch`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy.typing as npt

from tli_verify.errors import TliError, bad_input
from tli_verify.logic.automaton import TaskAutomaton
from tli_verify.model.types import Model
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.tasks.project import check_goal
from tli_verify.tasks.task import Goal, Task

__all__ = ["VARIANTS", "SequencePolicy", "Setup", "check_goal", "make_policy"]

VARIANTS: tuple[str, ...] = ("LTL-DS", "no-modulation", "no-replan", "BC")


@dataclass(frozen=True, slots=True, eq=False)
class Setup:
    """What a closed-loop episode runs.

    Attributes
    ----------
    task : Task
        The task: sensors, true regions, workspace (its ``lag`` is the run's).
    automaton : TaskAutomaton
    model : Model
    certificate : str
        The certificate file covering the model.
    goal : Goal
    spec : str
        The spec file the automaton comes from.
    bc : mapping of str to BCPolicy, optional
        Per-DS-key MLPs (the BC variant).
    """

    task: Task
    automaton: TaskAutomaton
    model: Model
    certificate: str
    goal: Goal = field(default_factory=Goal)
    spec: str = ""
    bc: Mapping[str, Any] = field(default_factory=dict)

    def with_lag(self, lag: int) -> Setup:
        """The same setup with another sensor lag."""
        return replace(self, task=self.task.with_lag(lag))


class SequencePolicy(LTLDSPolicy):
    """The ``no-replan`` ablation: the demonstrated mode sequence, run open loop.

    The executive's automaton, monitor and cuts run as in LTL-DS (events, ``mode``, ``done``
    follow the readings), but the DS run is the plan's: mode ``k`` of the sequence (each
    mode's ``next_mode`` from the initial mode) until the reading shows mode ``k + 1``. An
    unexpected reading (a spill, a knock) changes nothing.
    """

    __slots__ = ("_idx", "_seq")

    def __init__(self, automaton: TaskAutomaton, model: Model,
                 certificate: str | os.PathLike[str], **kwargs: Any) -> None:
        super().__init__(automaton, model, certificate, **kwargs)
        state: int | None = automaton.initial[0]
        seq = [automaton.states[automaton.initial[0]].mode]
        while len(seq) <= len(model.modes) and state is not None:
            mm = model.modes.get(seq[-1])
            # a mode with per-transition DS only (cooking's w1 -> y): the automaton's plan
            nxt = mm.next_mode if mm is not None else self._plan(state)
            if nxt is None:
                break
            seq.append(nxt)
            state = next((t.target for t in automaton.transitions if t.source == state
                          and automaton.states[t.target].mode == nxt), None)
        self._seq: tuple[str, ...] = tuple(seq)
        self._idx = 0

    def reset(self, x0: npt.ArrayLike, sensors: Any) -> None:
        """Start at ``x0``; the sequence starts at the mode the reading shows (if in it)."""
        super().reset(x0, sensors)
        self._idx = self._seq.index(self.mode) if self.mode in self._seq else 0

    def decide(self, x: npt.ArrayLike, sensors: Any, *, perturbed: bool = False) -> str:
        """Advance the automaton on the reading; return the sequence's DS key."""
        key = super().decide(x, sensors, perturbed=perturbed)
        if not key:
            return key
        if self._idx + 1 < len(self._seq) and self.mode == self._seq[self._idx + 1]:
            self._idx += 1
        mode = self._seq[self._idx]
        nxt = self._seq[self._idx + 1] if self._idx + 1 < len(self._seq) else None
        return self.model.key(mode, nxt)


def make_policy(setup: Setup, variant: str, **kwargs: Any) -> LTLDSPolicy:
    """The executive of one variant, with the setup's goal and control period.

    Parameters
    ----------
    setup : Setup
    variant : str
        One of :data:`VARIANTS` (``BC`` runs the executive's bookkeeping with cuts).
    **kwargs
        More keyword arguments of :class:`~tli_verify.runtime.executive.LTLDSPolicy`
        (``spec``, ``learn_transitions``).

    Raises
    ------
    CertificateError
        (exit 1) The certificate does not cover the model, or not the task's control period.
    """
    if variant not in VARIANTS:
        raise bad_input(TliError, f"variant: unknown variant {variant!r} (one of "
                        f"{', '.join(VARIANTS)})")
    if variant == "no-replan":
        return SequencePolicy(setup.automaton, setup.model, setup.certificate,
                              goal_modes=setup.goal.modes, goal_inputs=setup.goal.sensors,
                              dt=setup.task.dt, **kwargs)
    policy = LTLDSPolicy(setup.automaton, setup.model, setup.certificate,
                         learn_cuts=variant != "no-modulation", goal_modes=setup.goal.modes,
                         goal_inputs=setup.goal.sensors, dt=setup.task.dt, **kwargs)
    if variant == "no-modulation":  # the nominal DS: no cut of the model either (offline ones)
        policy.drop_cuts()
    return policy
