"""Task automata: Mealy machines extracted from a won GR(1) game (paper Sec. 5.1, Fig. 3(a)).

The automaton ``Omega_phi`` of paper eq. 6 answers, given its current state and the new sensor
reading ``alpha``, which mode policy runs next. States carry the mode they run, the sensor
reading they were entered with and the system goal they pursue (the strategy's memory).

The strategy is the standard one for the 3-nested fixpoint (Bloem et al., JCSS 2012, Sec. 5):
with memory ``j`` the system moves to the lowest ring of goal ``j`` it can force, stays inside
the trap set of the least ``(ring, environment goal)`` pair otherwise, and advances ``j`` each
time goal ``j`` is met. Among those moves it prefers one that leaves the environment a legal
move (no vacuous dead ends where it can avoid them), then the lowest ring, then the
lexicographically least outputs, so the same spec gives the same automaton,
byte for byte.

Transitions are built symbolically: the strategy's choice is computed as a
BDD over the next readings, and each edge carries a *cube* of readings (inputs required true,
inputs required false, the rest free), not one edge per valuation. A state records only the
inputs the strategy ever reads (:attr:`TaskAutomaton.free_inputs` lists the others), so a spec
with hundreds of unconstrained inputs has as many states as one with none. Automata larger
than :data:`MAX_AUTOMATON_STATES` states or :data:`MAX_AUTOMATON_EDGES` edges are refused with
a :class:`~tli_verify.errors.SpecError` naming the limit.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from tli_verify.errors import CheckFailed, SpecError
from tli_verify.logic.escape import dot_string
from tli_verify.logic.gr1 import Solution, _goals_or_true, cube, disjoint_cubes

__all__ = [
    "MAX_AUTOMATON_EDGES",
    "MAX_AUTOMATON_STATES",
    "AssumptionViolation",
    "AutomatonState",
    "PlannedStep",
    "TaskAutomaton",
    "Transition",
    "extract_automaton",
    "plan_progress",
]

MAX_AUTOMATON_STATES = 5_000
"""Most states an extracted task automaton may have."""

MAX_AUTOMATON_EDGES = 50_000
"""Most edges (reading cubes) an extracted task automaton may have."""


class AssumptionViolation(CheckFailed):
    """A sensor reading the environment assumptions rule out (no transition for it)."""


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
        The inputs that are true in this state (among those the strategy reads; the
        automaton's ``free_inputs`` are not recorded).
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
    """``source --cube--> target``: on a reading in the cube go to ``target``.

    Attributes
    ----------
    source, target : int
        State ids.
    sensors : tuple of str
        Inputs the reading must have true.
    off : tuple of str
        Inputs the reading must have false. Inputs in neither list may have any value.
    """

    source: int
    sensors: tuple[str, ...]
    target: int
    off: tuple[str, ...] = ()

    def matches(self, reading: frozenset[str]) -> bool:
        """Whether the reading (its set of true inputs) lies in this edge's cube."""
        return all(v in reading for v in self.sensors) and not any(v in reading
                                                                  for v in self.off)

    def label(self, inputs: tuple[str, ...]) -> str:
        """Readable cube: the true inputs (``-`` for none) when it fixes every input, else
        its literals (``r,!s``; ``*`` for any reading)."""
        if len(self.sensors) + len(self.off) == len(inputs):
            return ",".join(self.sensors) or "-"
        lits = [v if v in self.sensors else f"!{v}" for v in inputs
                if v in self.sensors or v in self.off]
        return ",".join(lits) or "*"


@dataclass(frozen=True, slots=True)
class PlannedStep:
    """What the runtime runs in one automaton state (:meth:`TaskAutomaton.planned_mode`).

    Attributes
    ----------
    state : int
        The automaton state.
    mode : str
        Its mode.
    next_mode : str or None
        The mode planned next (None in a goal mode, or when the state can only stay).
    key : str or None
        The DS key the runtime runs there: the per-transition DS ``mode -> next_mode`` when
        the model has it, else the mode's plain DS; None when the model has neither (the
        state cannot run: the gate blocks such a model, the executive refuses it).
    moves : tuple of str
        The other modes this state can move to (sorted).
    """

    state: int
    mode: str
    next_mode: str | None
    key: str | None
    moves: tuple[str, ...]


DSKeys = Mapping[str, tuple[str, "str | None"]]
"""A model's DS keys as the planner sees them: key -> ``(mode, next_mode)``. A key equal to its
mode is a plain DS (``next_mode``: the demonstrated next mode, or None); any other key is a
per-transition DS ``mode -> next_mode`` (paper appendix G)."""


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
        Initial state ids, one per class of initial sensor readings the assumptions allow
        (readings that differ only in ``free_inputs`` share their initial state).
    transitions : tuple of Transition
        Sorted by source, then target, then cube; the cubes of one state are disjoint.
    free_inputs : tuple of str
        Inputs the strategy never reads: states do not record them. They may still appear in
        transition cubes (when the assumptions constrain their next value).
    """

    name: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    modes: tuple[str, ...]
    states: tuple[AutomatonState, ...]
    initial: tuple[int, ...]
    transitions: tuple[Transition, ...]
    free_inputs: tuple[str, ...] = ()
    _index: dict[int, list[Transition]] = field(default_factory=dict, compare=False,
                                                repr=False)
    _lookup: dict[tuple[int, frozenset[str]], int | None] = field(
        default_factory=dict, init=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        for t in self.transitions:
            self._index.setdefault(t.source, []).append(t)

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
        reading = self._reading(sensors) - frozenset(self.free_inputs)
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
        if isinstance(sensors, frozenset):
            # lookup cache: (state, reading) -> target, filled lazily below (a reading is
            # cached only after it was validated, so a hit needs no checks)
            hit = self._lookup.get((state, sensors), -1)
            if hit is not None and hit >= 0:
                return hit, self.states[hit].mode
        if not 0 <= state < len(self.states):
            raise SpecError(f"no automaton state {state}")
        reading = self._reading(sensors)
        target = next((t.target for t in self._index.get(state, ()) if t.matches(reading)),
                      None)
        if len(self._lookup) < 4096:
            self._lookup[(state, reading)] = target
        if target is None:
            raise AssumptionViolation(
                f"sensor reading {sorted(reading)} from state {state} (mode "
                f"{self.states[state].mode}) violates the environment assumptions"
            )
        return target, self.states[target].mode

    # ------------------------------------------------------------------ the planner
    def successor_modes(self) -> tuple[tuple[str, ...], ...]:
        """Per state, the other modes it can move to in one step (sorted)."""
        succ: list[set[str]] = [set() for _ in self.states]
        for t in self.transitions:
            succ[t.source].add(self.states[t.target].mode)
        return tuple(tuple(sorted(m - {s.mode})) for m, s in zip(succ, self.states,
                                                                 strict=True))

    def sink_modes(self) -> tuple[str, ...]:
        """Modes the automaton runs that no transition leaves (the default goal modes of the
        runtime), in sorted order."""
        run = sorted({s.mode for s in self.states})
        left = {a for a, b in self.mode_transitions() if a != b}
        return tuple(m for m in run if m not in left)

    def mode_distances(self, goal_modes: Iterable[str]) -> dict[str, int]:
        """Fewest mode changes from each mode to a goal mode in the mode graph (modes that
        cannot reach one are absent)."""
        preds: dict[str, set[str]] = {}
        for a, b in self.mode_transitions():
            if a != b:
                preds.setdefault(b, set()).add(a)
        goals = list(dict.fromkeys(goal_modes))
        dist = {g: 0 for g in goals}
        queue = deque(goals)
        while queue:
            m = queue.popleft()
            for p in sorted(preds.get(m, ())):
                if p not in dist:
                    dist[p] = dist[m] + 1
                    queue.append(p)
        return dist

    def planned_keys(self, ds: DSKeys, goal_modes: Sequence[str] | None = None
                     ) -> tuple[PlannedStep, ...]:
        """The planner: per state, the next mode to run towards and the DS key to run.

        This is the one planner of the toolkit: the executive runs what it returns
        (:class:`tli_verify.runtime.executive.LTLDSPolicy`) and the deployment gate checks
        its coverage with it (:func:`tli_verify.deploy.gate.run_gate`, check ``modes``), so
        a model the gate passes has a DS in every state the executive can enter.

        Rules, in state ``s`` of mode ``m`` with the other modes ``M`` it can move to:

        1. among the modes of ``M`` with a per-transition DS ``m -> n``: the closest to a goal
           mode (then the least name); run that DS;
        2. else, with a plain DS ``m``: its demonstrated next mode if it is in ``M``, else
           the closest mode of ``M`` (none in a goal mode); run the plain DS (never a
           per-transition DS towards a mode ``s`` cannot move to);
        3. else no DS (``key`` None); the closest mode of ``M`` is still reported.

        Parameters
        ----------
        ds : mapping of str to (str, str or None)
            The model's DS keys (:data:`DSKeys`; ``{k: (mm.mode, mm.next_mode) for k, mm in
            model.modes.items()}``).
        goal_modes : sequence of str, optional
            Modes that complete the task (default: :meth:`sink_modes`).

        Returns
        -------
        tuple of PlannedStep
            One per state, indexed by state id.
        """
        goals = tuple(self.sink_modes() if goal_modes is None else goal_modes)
        dist = self.mode_distances(goals)
        far = len(self.modes) + len(self.states) + 1
        per: dict[str, dict[str, str]] = {}
        plain: dict[str, str | None] = {}
        for k, (mode, demo) in ds.items():
            if k == mode:
                plain[mode] = demo
            elif demo is not None:
                per.setdefault(mode, {})[demo] = k

        def rank(n: str) -> tuple[int, str]:
            return (dist.get(n, far), n)

        out = []
        for s, moves in zip(self.states, self.successor_modes(), strict=True):
            m = s.mode
            towards = per.get(m, {})
            with_ds = [n for n in moves if n in towards]
            nxt: str | None
            key: str | None
            closest = min(moves, key=rank) if moves and m not in goals else None
            if with_ds:
                nxt = min(with_ds, key=rank)
                key = towards[nxt]
            elif m in plain:
                demo = plain[m]
                nxt = demo if demo is not None and demo in moves else closest
                key = m
            else:
                nxt, key = closest, None
            out.append(PlannedStep(state=s.id, mode=m, next_mode=nxt, key=key, moves=moves))
        return tuple(out)

    def planned_mode(self, state: int, ds: DSKeys, *, goal_modes: Sequence[str] | None = None
                     ) -> PlannedStep:
        """:meth:`planned_keys` of one state."""
        if not 0 <= state < len(self.states):
            raise SpecError(f"no automaton state {state}")
        return self.planned_keys(ds, goal_modes)[state]

    def mode_transitions(self) -> list[list[str]]:
        """Sorted distinct ``[from_mode, to_mode]`` pairs, self-loops included."""
        pairs = {(self.states[t.source].mode, self.states[t.target].mode)
                 for t in self.transitions}
        return [list(p) for p in sorted(pairs)]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (``docs/reference/file-formats.md``)."""
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
                {"from": t.source, "sensors": list(t.sensors), "off": list(t.off),
                 "to": t.target}
                for t in self.transitions
            ],
            "free_inputs": list(self.free_inputs),
            "mode_transitions": self.mode_transitions(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> TaskAutomaton:
        """Inverse of :meth:`to_dict`.

        Files written before transition cubes (no ``"off"``) list full readings: every
        input not in ``"sensors"`` is false.
        """
        try:
            inputs = tuple(str(v) for v in data["inputs"])
            states = tuple(
                AutomatonState(id=int(s["id"]), mode=str(s["mode"]),
                               inputs=tuple(s["inputs"]), outputs=tuple(s["outputs"]),
                               goal=int(s["goal"]))
                for s in data["states"]
            )
            return cls(
                name=str(data["name"]),
                inputs=inputs,
                outputs=tuple(data["outputs"]),
                modes=tuple(data["modes"]),
                states=states,
                initial=tuple(int(i) for i in data["initial"]),
                transitions=tuple(
                    Transition(source=int(t["from"]), sensors=tuple(t["sensors"]),
                               target=int(t["to"]),
                               off=tuple(t["off"]) if "off" in t else
                               tuple(v for v in inputs if v not in t["sensors"]))
                    for t in data["transitions"]
                ),
                free_inputs=tuple(str(v) for v in data.get("free_inputs", ())),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise SpecError(f"malformed automaton JSON: {exc}") from None

    def to_dot(self) -> str:
        """Graphviz DOT text; parallel edges are merged, labelled by their sensor readings.

        Every name and label is written with :func:`~tli_verify.logic.escape.dot_string`, so
        a spec name with quotes or backslashes cannot change the graph's structure.
        """
        lines = [f"digraph {dot_string(self.name)} {{", "  rankdir=LR;",
                 '  node [shape=circle, fontname="Helvetica"];',
                 '  edge [fontname="Helvetica", fontsize=9];',
                 '  __init [shape=point];']
        for s in self.states:
            label = f"{s.mode}\n#{s.id} [{','.join(s.inputs) or '-'}]"
            lines.append(f"  s{s.id} [label={dot_string(label)}];")
        for sid in self.initial:
            lines.append(f"  __init -> s{sid};")
        merged: dict[tuple[int, int], list[str]] = {}
        for t in self.transitions:
            merged.setdefault((t.source, t.target), []).append(t.label(self.inputs))
        for (a, b), labels in sorted(merged.items()):
            lines.append(f"  s{a} -> s{b} [label={dot_string(' | '.join(labels))}];")
        lines.append("}")
        return "\n".join(lines) + "\n"


def _mode_of(outputs: dict[str, bool], mode_names: tuple[str, ...], has_modes: bool) -> str:
    true = [o for o in mode_names if outputs.get(o)]
    if has_modes and len(true) == 1:
        return true[0]
    return "+".join(true) or "-"


def extract_automaton(solution: Solution) -> TaskAutomaton:
    """Extract the task automaton from a realizable solution (symbolic over readings).

    Raises
    ------
    ValueError
        If the solution is not realizable (callers check first).
    SpecError
        If the automaton would exceed :data:`MAX_AUTOMATON_STATES` states or
        :data:`MAX_AUTOMATON_EDGES` edges.
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
    # Prefer moves after which the environment still has a legal move (no dead ends).
    alive_p = game.prime(bdd.exist(Xp, game.rho_e))
    mode_names = spec.mode_names
    has_modes = spec.modes is not None

    # The inputs the strategy reads: the support of every set it consults at a state.
    consulted = [game.theta_e, game.theta_s, game.rho_e, game.rho_s, z, *goals,
                 *goal_target, *(r for rings in solution.rings for r in rings),
                 *(c for row in cpre_lower for c in row),
                 *(t for ring in solution.traps for layer in ring for t in layer)]
    support: set[str] = set()
    for u in consulted:
        support |= bdd.support(u)
    read = [v for v in X if v in support]
    read_p = [v + "'" for v in read]
    free = tuple(v for v in X if v not in support)

    def resolve(cand: Any, j: int) -> Any:
        """The strategy's choice as a BDD over (next readings, next outputs): for each
        reading with a candidate, exactly one next output (a move that leaves the
        environment a move if there is one, then the lowest ring, then the least outputs).
        Every candidate is already a winning move (``cand`` lies in the strategy's target),
        so these preferences never cost the win."""
        c = cand & alive_p
        cand = c | (cand & ~bdd.exist(Yp, c))
        chosen = game.false
        remaining = game.true
        for ring in rings_p[j]:
            c = cand & ring
            chosen |= c & remaining
            remaining &= ~bdd.exist(Yp, c)
        cand = chosen | (cand & remaining)
        for v in Yp:
            low = cand & ~bdd.var(v)
            cand = low | (cand & bdd.var(v) & ~bdd.exist(Yp, low))
        return cand

    keys: dict[tuple[tuple[bool, ...], tuple[bool, ...], int], int] = {}
    order: list[tuple[dict[str, bool], dict[str, bool], int]] = []

    def state_id(x: dict[str, bool], y: dict[str, bool], j: int) -> int:
        key = (tuple(x[v] for v in read), tuple(y[v] for v in Y), j)
        if key not in keys:
            if len(order) >= MAX_AUTOMATON_STATES:
                raise SpecError(f"{spec.path or spec.name}: the task automaton has more than "
                                f"{MAX_AUTOMATON_STATES} states (the limit); the strategy "
                                f"reads {len(read)} of the {len(X)} inputs")
            keys[key] = len(order)
            order.append((x, y, j))
        return keys[key]

    def targets(choice: Any) -> list[tuple[dict[str, bool], dict[str, bool], Any]]:
        """Split a resolved choice by target: (read inputs, outputs, the readings' BDD)."""
        proj = bdd.exist([v for v in Xp if v not in read_p], choice)
        n_targets = bdd.count(proj, nvars=len(read_p) + len(Yp))
        if len(transitions) + n_targets > MAX_AUTOMATON_EDGES:
            raise SpecError(f"{spec.path or spec.name}: the task automaton has more than "
                            f"{MAX_AUTOMATON_EDGES} edges (the limit); the strategy reads "
                            f"{len(read)} of the {len(X)} inputs")
        found = []
        for a in bdd.pick_iter(proj, care_vars=read_p + Yp):
            xr = {v: bool(a[v + "'"]) for v in read}
            yv = {v: bool(a[v + "'"]) for v in Y}
            readings = bdd.exist(Yp, choice & cube(game, {**{v + "'": b for v, b in xr.items()},
                                                          **{v + "'": b for v, b in yv.items()}}))
            found.append((xr, yv, readings))
        found.sort(key=lambda t: (tuple(t[0][v] for v in read), tuple(t[1][v] for v in Y)))
        return found

    transitions: list[Transition] = []
    initial: list[int] = []
    start = resolve(game.prime(game.theta_e & game.theta_s & z), 0)
    for xr, yv, _ in targets(start):
        sid = state_id(xr, yv, 0)
        if sid not in initial:
            initial.append(sid)

    k = 0
    while k < len(order):
        x, y, j = order[k]
        cur = {**x, **y}
        s = cube(game, cur)
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
        legal = bdd.let(cur, game.rho_e)
        choice = resolve(bdd.let(cur, game.rho_s) & target_p & legal, j2)
        if bdd.exist(Yp, choice) != legal:  # pragma: no cover - the fixpoint guarantees it
            raise RuntimeError("internal error: winning state without a winning move")
        for xr, yv, readings in targets(choice):
            dst = state_id(xr, yv, j2)
            cubes = disjoint_cubes(bdd, readings, Xp, MAX_AUTOMATON_EDGES - len(transitions))
            if cubes is None:
                raise SpecError(f"{spec.path or spec.name}: the task automaton has more than "
                                f"{MAX_AUTOMATON_EDGES} edges (the limit)")
            for c in cubes:
                transitions.append(Transition(
                    source=k, target=dst,
                    sensors=tuple(v for v in X if c.get(v + "'") is True),
                    off=tuple(v for v in X if c.get(v + "'") is False)))
        k += 1

    states = tuple(
        AutomatonState(id=i, mode=_mode_of(y, mode_names, has_modes),
                       inputs=tuple(v for v in read if x[v]),
                       outputs=tuple(v for v in Y if y[v]), goal=j)
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
        free_inputs=free,
    )


def plan_progress(steps: Iterable[PlannedStep]) -> dict[str, frozenset[str]]:
    """The mode changes that are planned progress, per mode: the modes *later on the mode's
    planned path* (following the planner's next modes, :meth:`TaskAutomaton.planned_keys`,
    from every state of the mode).

    One rule for the executive (such a change is a replan, never an invariance failure to
    cut) and the offline hand-off step (an exit there is an allowed hand-off,
    :mod:`tli_verify.runtime.handoff`). A change to a later mode of the plan moves strictly
    forward along a path the plan follows anyway, so such changes cannot cycle; the mode graph's
    distance to the goal would not do (a spec that allows a shortcut from the first mode makes
    it as near the goal as a later mode, and the two could hand the state back and forth).
    """
    nxt: dict[str, set[str]] = {}
    for st in steps:
        nxt.setdefault(st.mode, set())
        if st.next_mode is not None:
            nxt[st.mode].add(st.next_mode)
    out: dict[str, frozenset[str]] = {}
    for m in nxt:
        seen: set[str] = set()
        todo = list(nxt[m])
        while todo:
            n = todo.pop()
            if n in seen or n == m:
                continue
            seen.add(n)
            todo.extend(nxt.get(n, ()))
        out[m] = frozenset(seen)
    return out
