"""Task automata: Mealy machines extracted from a won GR(1) game (paper Sec. 5.1, Fig. 4(a)).

The automaton ``Omega_phi`` of paper eq. 6 answers, given its current state and the new sensor
reading ``alpha``, which mode policy runs next. States carry the mode they run, the sensor
reading they were entered with and the system goal they pursue (the strategy's memory).

The strategy is the standard one for the 3-nested fixpoint (Bloem et al., JCSS 2012, Sec. 5):
with memory ``j`` the system moves to the lowest ring of goal ``j`` it can force, stays inside
the trap set of the least ``(ring, environment goal)`` pair otherwise, and advances ``j`` each
time goal ``j`` is met. Choices are the lexicographically least outputs, so the same spec gives
the same automaton, byte for byte.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from tli_verify.errors import SpecError, TliError
from tli_verify.logic.gr1 import (
    Solution,
    _goals_or_true,
    assignments,
    cube,
    least_assignment,
)

__all__ = [
    "AssumptionViolation",
    "AutomatonState",
    "TaskAutomaton",
    "Transition",
    "extract_automaton",
]


class AssumptionViolation(TliError):
    """A sensor reading the environment assumptions rule out (no transition for it)."""

    exit_code = 1


@dataclass(frozen=True, slots=True)
class AutomatonState:
    """One state of a task automaton.

    Attributes
    ----------
    id : int
        Index in :attr:`TaskAutomaton.states`.
    mode : str
        The mode this state runs (``"a"``; without ``[modes]`` the true outputs joined by
        ``+``, or ``"-"`` when none is true).
    inputs : tuple of str
        The inputs that are true in this state.
    outputs : tuple of str
        The outputs that are true in this state.
    goal : int
        The system liveness goal pursued (strategy memory).
    """

    id: int
    mode: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    goal: int


@dataclass(frozen=True, slots=True)
class Transition:
    """``source --sensors--> target``: on reading ``sensors`` (the true inputs) go to ``target``."""

    source: int
    sensors: tuple[str, ...]
    target: int


@dataclass(frozen=True, slots=True)
class TaskAutomaton:
    """A Mealy task automaton (sensor readings -> next mode).

    Attributes
    ----------
    name : str
    inputs, outputs : tuple of str
    modes : tuple of str
        Mode names in spec order.
    states : tuple of AutomatonState
    initial : tuple of int
        Initial state ids, one per initial sensor reading the assumptions allow.
    transitions : tuple of Transition
        Sorted by source, then sensor reading.
    """

    name: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    modes: tuple[str, ...]
    states: tuple[AutomatonState, ...]
    initial: tuple[int, ...]
    transitions: tuple[Transition, ...]
    _index: dict[tuple[int, frozenset[str]], int] = field(
        default_factory=dict, compare=False, repr=False
    )

    def __post_init__(self) -> None:
        self._index.update(
            {(t.source, frozenset(t.sensors)): t.target for t in self.transitions}
        )

    def _reading(self, sensors: Mapping[str, bool] | Iterable[str]) -> frozenset[str]:
        if isinstance(sensors, Mapping):
            unknown = sorted(set(sensors) - set(self.inputs))
            if unknown:
                raise SpecError(f"unknown sensor {unknown[0]!r} (inputs: {list(self.inputs)})")
            return frozenset(k for k, v in sensors.items() if v)
        reading = frozenset(sensors)
        unknown = sorted(reading - set(self.inputs))
        if unknown:
            raise SpecError(f"unknown sensor {unknown[0]!r} (inputs: {list(self.inputs)})")
        return reading

    def initial_state(self, sensors: Mapping[str, bool] | Iterable[str]) -> int:
        """The initial state for the first sensor reading.

        Raises
        ------
        AssumptionViolation
            If the environment's initial condition rules the reading out.
        """
        reading = self._reading(sensors)
        for sid in self.initial:
            if frozenset(self.states[sid].inputs) == reading:
                return sid
        raise AssumptionViolation(
            f"sensor reading {sorted(reading)} is not an initial reading the assumptions allow"
        )

    def next_mode(self, state: int, sensors: Mapping[str, bool] | Iterable[str]
                  ) -> tuple[int, str]:
        """Next state and the mode to run, given the new sensor reading (Mealy step).

        Parameters
        ----------
        state : int
            Current state id.
        sensors : mapping of str to bool, or iterable of str
            The new reading (values of the inputs, or the set of true inputs).

        Returns
        -------
        (int, str)
            The next state id and its mode.

        Raises
        ------
        AssumptionViolation
            If the environment assumptions rule this sensor change out.
        """
        if not 0 <= state < len(self.states):
            raise SpecError(f"no automaton state {state}")
        reading = self._reading(sensors)
        target = self._index.get((state, reading))
        if target is None:
            raise AssumptionViolation(
                f"sensor reading {sorted(reading)} from state {state} (mode "
                f"{self.states[state].mode}) violates the environment assumptions"
            )
        return target, self.states[target].mode

    def mode_transitions(self) -> list[list[str]]:
        """Sorted distinct ``[from_mode, to_mode]`` pairs, self-loops included."""
        pairs = {(self.states[t.source].mode, self.states[t.target].mode)
                 for t in self.transitions}
        return [list(p) for p in sorted(pairs)]

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict (see README, "Task automaton")."""
        return {
            "name": self.name,
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
            "modes": list(self.modes),
            "states": [
                {"id": s.id, "mode": s.mode, "inputs": list(s.inputs),
                 "outputs": list(s.outputs), "goal": s.goal}
                for s in self.states
            ],
            "initial": list(self.initial),
            "transitions": [
                {"from": t.source, "sensors": list(t.sensors), "to": t.target}
                for t in self.transitions
            ],
            "mode_transitions": self.mode_transitions(),
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> TaskAutomaton:
        """Inverse of :meth:`to_json`."""
        try:
            states = tuple(
                AutomatonState(id=int(s["id"]), mode=str(s["mode"]),
                               inputs=tuple(s["inputs"]), outputs=tuple(s["outputs"]),
                               goal=int(s["goal"]))
                for s in data["states"]
            )
            return cls(
                name=str(data["name"]),
                inputs=tuple(data["inputs"]),
                outputs=tuple(data["outputs"]),
                modes=tuple(data["modes"]),
                states=states,
                initial=tuple(int(i) for i in data["initial"]),
                transitions=tuple(
                    Transition(source=int(t["from"]), sensors=tuple(t["sensors"]),
                               target=int(t["to"]))
                    for t in data["transitions"]
                ),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise SpecError(f"malformed automaton JSON: {exc}") from None

    def to_dot(self) -> str:
        """Graphviz DOT text; parallel edges are merged, labelled by their sensor readings."""
        lines = [f'digraph "{self.name}" {{', "  rankdir=LR;",
                 '  node [shape=circle, fontname="Helvetica"];',
                 '  edge [fontname="Helvetica", fontsize=9];',
                 '  __init [shape=point];']
        for s in self.states:
            sensors = ",".join(s.inputs) or "-"
            lines.append(f'  s{s.id} [label="{s.mode}\\n#{s.id} [{sensors}]"];')
        for sid in self.initial:
            lines.append(f"  __init -> s{sid};")
        merged: dict[tuple[int, int], list[str]] = {}
        for t in self.transitions:
            merged.setdefault((t.source, t.target), []).append("".join(t.sensors) or "-")
        for (a, b), labels in sorted(merged.items()):
            lines.append(f'  s{a} -> s{b} [label="{" | ".join(labels)}"];')
        lines.append("}")
        return "\n".join(lines) + "\n"


def _mode_of(outputs: dict[str, bool], mode_names: tuple[str, ...], has_modes: bool) -> str:
    true = [o for o in mode_names if outputs.get(o)]
    if has_modes and len(true) == 1:
        return true[0]
    return "+".join(true) or "-"


def extract_automaton(solution: Solution) -> TaskAutomaton:
    """Extract the task automaton from a realizable solution (explicit over sensor readings).

    Raises
    ------
    ValueError
        If the solution is not realizable (callers check first).
    """
    if not solution.realizable:
        raise ValueError("cannot extract a strategy from an unrealizable game")
    game = solution.game
    bdd = game.manager
    spec = game.spec
    X, Y = list(game.inputs), list(game.outputs)
    Xp, Yp = game.inputs_next, game.outputs_next
    z = solution.winning
    goals = _goals_or_true(game, game.sys_goals)
    n_goals = len(goals)
    cpre_z = game.cpre(z)
    goal_target = [g & cpre_z for g in goals]
    rings_p = [[game.prime(r & z) for r in rings] for rings in solution.rings]
    cpre_lower = [[game.cpre(rings[r - 1]) if r else game.cpre(game.false)
                   for r in range(len(rings))] for rings in solution.rings]
    z_p = game.prime(z)
    mode_names = spec.mode_names
    has_modes = spec.modes is not None

    def choose(cand: Any, j: int) -> dict[str, bool]:
        for ring in rings_p[j]:
            c = cand & ring
            if c != game.false:
                cand = c
                break
        picked = least_assignment(game, cand, Yp)
        if picked is None:  # pragma: no cover - the fixpoint guarantees a move
            raise RuntimeError("internal error: winning state without a winning move")
        return {k[:-1]: v for k, v in picked.items()}

    keys: dict[tuple[tuple[bool, ...], tuple[bool, ...], int], int] = {}
    order: list[tuple[dict[str, bool], dict[str, bool], int]] = []

    def state_id(x: dict[str, bool], y: dict[str, bool], j: int) -> int:
        key = (tuple(x[v] for v in X), tuple(y[v] for v in Y), j)
        if key not in keys:
            keys[key] = len(order)
            order.append((x, y, j))
        return keys[key]

    initial: list[int] = []
    for x in assignments(X):
        cx = cube(game, x)
        if (game.theta_e & cx) == game.false:
            continue
        cand = game.prime(game.theta_s & z & cx)
        cand = bdd.let({v: x[v[:-1]] for v in Xp}, cand)
        initial.append(state_id(x, choose(cand, 0), 0))

    transitions: list[Transition] = []
    k = 0
    while k < len(order):
        x, y, j = order[k]
        s = cube(game, {**x, **y})
        j2 = (j + 1) % n_goals if (s & goals[j]) != game.false else j
        if (s & goal_target[j2]) != game.false:
            target_p = z_p
        else:
            rank = solution.rank(j2, s)
            if rank is None:  # pragma: no cover
                raise RuntimeError("internal error: reachable state outside the winning set")
            r, i = rank
            if (s & cpre_lower[j2][r]) != game.false:
                target_p = rings_p[j2][r - 1] if r else game.false
            else:
                target_p = game.prime(solution.traps[j2][r][i] & z)
        cur = {**x, **y}
        rho_e_s = bdd.let(cur, game.rho_e)
        move_s = bdd.let(cur, game.rho_s) & target_p
        for xn in assignments(X):
            xn_p = {v + "'": val for v, val in xn.items()}
            if bdd.let(xn_p, rho_e_s) == game.false:
                continue
            yn = choose(bdd.let(xn_p, move_s), j2)
            dst = state_id(xn, yn, j2)
            transitions.append(Transition(source=k, sensors=tuple(v for v in X if xn[v]),
                                          target=dst))
        k += 1

    states = tuple(
        AutomatonState(id=i, mode=_mode_of(y, mode_names, has_modes),
                       inputs=tuple(v for v in X if x[v]), outputs=tuple(v for v in Y if y[v]),
                       goal=j)
        for i, (x, y, j) in enumerate(order)
    )
    return TaskAutomaton(
        name=spec.name,
        inputs=game.inputs,
        outputs=game.outputs,
        modes=mode_names,
        states=states,
        initial=tuple(initial),
        transitions=tuple(transitions),
    )
