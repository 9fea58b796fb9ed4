"""Growing the spec online (paper appendix F): a transition the spec lacks, learned or refused.

A reading the environment assumptions rule out that shows another *known* mode (paper Asm. 3:
exactly one mode label holds for it) is a transition the spec lacks. :func:`learn_transition`
adds it to ``phi_t^s`` (:func:`tli_verify.logic.infer.regrow`: the observed sensor change joins
the assumptions, the change is marked as regressing), re-synthesizes and re-checks the spec
(realizable, well-separated), and requires the grown automaton to give every state a DS of the
certified model (:func:`~tli_verify.runtime.coverage.plan_states`, the check at construction).
The executive (:class:`~tli_verify.runtime.executive.LTLDSPolicy`, ``learn_transitions=True``)
then carries on from :attr:`Growth.state`; on a :class:`Refusal` it keeps the old spec.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from tli_verify.errors import TliError
from tli_verify.logic.automaton import PlannedStep, TaskAutomaton
from tli_verify.logic.infer import regrow
from tli_verify.logic.spec import GR1Spec, label_holds
from tli_verify.model.types import Model
from tli_verify.runtime.coverage import plan_states

__all__ = ["Growth", "Refusal", "learn_transition"]


@dataclass(frozen=True, slots=True, eq=False)
class Growth:
    """A transition learned online.

    Attributes
    ----------
    spec : GR1Spec
        The grown spec.
    automaton : TaskAutomaton
        Its automaton.
    plans : dict of int to PlannedStep
        The planner's choice in every state of it (each naming a DS of the model).
    state : int
        The state of the grown automaton to carry on from.
    to_mode : str
        The mode the reading shows.
    """

    spec: GR1Spec
    automaton: TaskAutomaton
    plans: dict[int, PlannedStep]
    state: int
    to_mode: str


@dataclass(frozen=True, slots=True)
class Refusal:
    """Nothing learned from a reading.

    Attributes
    ----------
    to_mode : str or None
        The mode the reading shows, if exactly one label holds.
    reason : str or None
        Why it was refused (reported as an event); None when there was nothing to learn (a
        change inside the mode's label, or a transition the spec already allows here).
    """

    to_mode: str | None
    reason: str | None


def learn_transition(spec: GR1Spec, automaton: TaskAutomaton, state: int, from_mode: str,
                     reading: frozenset[str], model: Model,
                     goal_modes: Sequence[str]) -> Growth | Refusal:
    """Learn the transition a reading the assumptions rule out shows, or say why not.

    Parameters
    ----------
    spec : GR1Spec
        The current spec (with a ``[modes]`` table); ``automaton`` is its automaton.
    automaton : TaskAutomaton
    state : int
        The automaton state the reading arrived in.
    from_mode : str
        The mode being run.
    reading : frozenset of str
        The true sensors.
    model : Model
        The certified model: the grown automaton must plan a DS of it in every state.
    goal_modes : sequence of str
        The planner's goal modes.

    Returns
    -------
    Growth or Refusal
    """
    values = {i: i in reading for i in spec.inputs}
    holds = [m for m in spec.mode_names if label_holds(spec, m, values)]
    if len(holds) != 1:
        return Refusal(None, "no mode label holds for it: only transitions into known modes "
                       "are valid (paper Asm. 3)" if not holds else
                       f"the labels of several modes hold for it ({', '.join(holds)})")
    to_mode = holds[0]
    if to_mode == from_mode:  # a sensor change inside the mode's label: nothing to learn
        return Refusal(to_mode, None)
    try:
        grown = regrow(spec, from_mode, to_mode, automaton.states[state], reading)
        if grown.spec is spec:  # already allowed: nothing to learn at this state
            return Refusal(to_mode, None)
        plans = plan_states(grown.automaton, model, goal_modes, f"{model.path}")
    except TliError as exc:
        return Refusal(to_mode, str(exc))
    return Growth(spec=grown.spec, automaton=grown.automaton, plans=plans, state=grown.state,
                  to_mode=to_mode)
