"""Why a GR(1) spec is unrealizable: the failing part, a counter-strategy witness, a hint.

An unrealizable verdict is never a bare "no". The diagnosis names

* which part fails: the initial condition, the safety part (the environment can force a state
  where every system move breaks a safety guarantee), or a liveness goal;
* a witness: a finite environment play that defeats every system strategy (safety: each
  environment move is taken from its attractor, whatever the system replies), or a lasso
  (liveness: a cycle the environment can repeat forever while meeting its assumptions, in
  which the goal never holds);
* a hint where one applies (a missing physical-limit assumption, a missing fairness
  assumption).

The safety witness is a counter-strategy play (Koenighofer, Hofferek and Bloem, 2009): the
environment's moves are the ones its attractor ranks prescribe, the system's replies shown are
its lexicographically least legal ones (every other reply loses as well).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from tli_verify.logic.gr1 import (
    Game,
    _goals_or_true,
    assignments,
    closed_relation,
    least_assignment,
    minimal_init_core,
    solve,
)
from tli_verify.logic.spec import SpecFormula

__all__ = ["Diagnosis", "Step", "diagnose"]

MAX_EXPLICIT_VARS = 16
"""Witness plays are built explicitly over assignments; larger games get no lasso."""


@dataclass(frozen=True, slots=True)
class Step:
    """One position of a witness play: the true inputs and true outputs."""

    inputs: tuple[str, ...]
    outputs: tuple[str, ...]

    def to_dict(self) -> dict[str, list[str]]:
        return {"inputs": list(self.inputs), "outputs": list(self.outputs)}

    def __str__(self) -> str:
        return f"sensors [{','.join(self.inputs)}] outputs [{','.join(self.outputs)}]"


@dataclass(frozen=True, slots=True)
class Diagnosis:
    """Why a spec is unrealizable.

    Attributes
    ----------
    kind : str
        ``"initial"``, ``"safety"`` or ``"liveness"``.
    summary : str
        One sentence.
    formulas : tuple of str
        The formulas at fault, each as ``file:line section[i]: text``.
    witness : tuple of Step
        A play the environment can force (may be empty for large games).
    loop_start : int or None
        For a lasso, the index in ``witness`` where the repeated cycle starts.
    final_inputs : tuple of str or None
        For a safety witness, the last sensor reading, after which the system has no legal move.
    hint : str or None
        What to add to the spec, where a hint applies.
    """

    kind: str
    summary: str
    formulas: tuple[str, ...]
    witness: tuple[Step, ...] = ()
    loop_start: int | None = None
    final_inputs: tuple[str, ...] | None = None
    hint: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "summary": self.summary,
            "formulas": list(self.formulas),
            "witness": [s.to_dict() for s in self.witness],
            "loop_start": self.loop_start,
            "final_inputs": None if self.final_inputs is None else list(self.final_inputs),
            "hint": self.hint,
        }

    def lines(self) -> list[str]:
        """Human-readable lines (the CLI indents them under the verdict)."""
        out = [f"{self.kind}: {self.summary}"]
        out += [f"  at fault: {f}" for f in self.formulas]
        if self.witness:
            out.append("  witness play:")
            for k, step in enumerate(self.witness):
                mark = "  <- loop starts" if self.loop_start == k else ""
                out.append(f"    {k}: {step}{mark}")
            if self.loop_start is not None:
                out.append(f"    (repeats from step {self.loop_start} forever)")
            if self.final_inputs is not None:
                out.append(f"    {len(self.witness)}: sensors [{','.join(self.final_inputs)}]"
                           " -> no legal system move")
        if self.hint:
            out.append(f"  hint: {self.hint}")
        return out


def _where(f: SpecFormula, path: str | None) -> str:
    return f"{f.where(path)}: {f.text}"


def _state_formula(game: Game, inputs: dict[str, bool]) -> str:
    return " & ".join(v if inputs[v] else f"!{v}" for v in game.inputs) or "true"


def _true(names: Sequence[str], values: dict[str, bool]) -> tuple[str, ...]:
    return tuple(n for n in names if values.get(n))


def diagnose(game: Game) -> Diagnosis:
    """Diagnose an unrealizable game (call only when :func:`solve` said unrealizable)."""
    spec = game.spec
    path = spec.path
    bdd = game.manager
    X, Y = list(game.inputs), list(game.outputs)

    # 1. Initial condition: some allowed initial reading admits no initial system state
    # (the guarantees' initial condition and their safety formulas at time 0).
    bad_init = game.theta_e & ~bdd.exist(Y, game.theta_s)
    if bad_init != game.false:
        x = least_assignment(game, bad_init, X) or {}
        faulty = _initial_culprits(game, x)
        return Diagnosis(
            kind="initial",
            summary="for the initial sensor reading "
            f"[{','.join(_true(X, x))}] no system state satisfies the guarantees' initial "
            "condition together with the safety guarantees at time 0",
            formulas=tuple(_where(f, path) for f in faulty),
            witness=(Step(inputs=_true(X, x), outputs=()),),
        )

    # 2. Safety: solve without liveness goals.
    safety_game = game.with_(env_goals=(), sys_goals=())
    if not solve(safety_game, keep_iterates=False, exact=False).realizable:
        return _diagnose_safety(safety_game)

    # 3. Liveness: the first system goal that is unrealizable on its own.
    for goal in game.sys_goals:
        single = game.with_(sys_goals=(goal,))
        sol = solve(single, keep_iterates=False)
        if not sol.realizable:
            return _diagnose_liveness(single, sol.winning, goal.formula)
    return Diagnosis(
        kind="liveness",
        summary="each system liveness goal is realizable alone, but not all of them together",
        formulas=tuple(_where(g.formula, path) for g in game.sys_goals),
    )


def _initial_culprits(game: Game, x: dict[str, bool]) -> list[SpecFormula]:
    """A minimal set of guarantees (initial conditions and safety formulas, the latter at
    time 0) that no system state satisfies for the initial reading ``x``."""
    bdd = game.manager
    Y = list(game.outputs)
    parts: list[tuple[SpecFormula, Any, bool]] = (
        [(f, b, False) for f, b in game.init_s]
        + ([] if game.semantics == "textbook" else [(f, b, True) for f, b in game.safety_s]))
    return minimal_init_core(
        bdd, parts, rename={v: v + "'" for v in game.inputs + game.outputs},
        quantified=game.inputs_next + game.outputs_next,
        empty=lambda u: bdd.exist(Y, bdd.let(x, u)) == bdd.false)


def _diagnose_safety(game: Game) -> Diagnosis:
    """Environment attractor to a state where the system has no legal move."""
    bdd = game.manager
    X, Y = list(game.inputs), list(game.outputs)
    Xp, Yp = game.inputs_next, game.outputs_next
    layers = [~game.cpre(game.true)]
    while True:
        nxt = layers[-1] | ~game.cpre(~layers[-1])
        if nxt == layers[-1]:
            break
        layers.append(nxt)
    losing = layers[-1]
    # Initial reading from which every initial system choice loses.
    start = game.theta_e & bdd.forall(Y, ~game.theta_s | losing)
    x = least_assignment(game, start, X)
    if x is None:  # pragma: no cover - unrealizable safety game implies such a reading
        return Diagnosis(kind="safety", summary="the safety guarantees cannot be met",
                         formulas=tuple(_where(f, game.spec.path) for f, _ in game.safety_s))
    y = least_assignment(game, bdd.let(x, game.theta_s), Y) or {}
    steps = [Step(inputs=_true(X, x), outputs=_true(Y, y))]
    final_x: dict[str, bool] = {}
    for _ in range(len(layers) + 1):
        s = {**x, **y}
        k = next(i for i, layer in enumerate(layers) if bdd.let(s, layer) == bdd.true)
        rho_e = bdd.let(s, game.rho_e)
        rho_s = bdd.let(s, game.rho_s)
        if k == 0:
            dead = rho_e & ~bdd.exist(Yp, rho_s)
            final_x = {v[:-1]: b for v, b in (least_assignment(game, dead, Xp) or {}).items()}
            break
        lower_p = game.prime(layers[k - 1])
        forcing = rho_e & bdd.forall(Yp, ~rho_s | lower_p)
        xp = least_assignment(game, forcing, Xp) or {}
        yp = least_assignment(game, bdd.let(xp, rho_s), Yp) or {}
        x = {v[:-1]: b for v, b in xp.items()}
        y = {v[:-1]: b for v, b in yp.items()}
        steps.append(Step(inputs=_true(X, x), outputs=_true(Y, y)))
    # The minimal set of safety guarantees that rules out every move at the end.
    last = {**x, **y}
    final_p = {v + "'": b for v, b in final_x.items()}
    parts = list(game.safety_s)
    k = 0
    while k < len(parts):
        rest = parts[:k] + parts[k + 1:]
        u = closed_relation(game, [b for _, b in rest], system=True)
        if bdd.exist(Yp, bdd.let({**last, **final_p}, u)) == bdd.false:
            parts = rest
        else:
            k += 1
    cur = _state_formula(game, x)
    nxt = _state_formula(game, final_x)
    # The hint blames the sensor change: its premise is that some other legal sensor change
    # from the same state leaves the system a legal move. Otherwise the state itself is lost
    # whatever the sensors do, and no assumption about this change would help.
    others = bdd.let(last, game.rho_e) & bdd.exist(Yp, bdd.let(last, game.rho_s))
    if others != game.false:
        summary = ("the environment can force a sensor change after which every system move "
                   "violates a safety guarantee")
        hint: str | None = (
            f"the environment may change the sensors from ({cur}) to ({nxt}); if that cannot "
            f"happen physically, add the environment safety assumption "
            f"\"G(({cur}) -> X !({nxt}))\"")
    else:
        summary = ("the environment can force a state from which every legal sensor reading "
                   "leaves the system no move that keeps the safety guarantees")
        hint = None
    return Diagnosis(
        kind="safety",
        summary=summary,
        formulas=tuple(_where(f, game.spec.path) for f, _ in parts),
        witness=tuple(steps),
        final_inputs=_true(X, final_x),
        hint=hint,
    )


def _diagnose_liveness(game: Game, winning: Any, goal: SpecFormula) -> Diagnosis:
    """A lasso: a cycle the environment can keep while meeting its assumptions."""
    summary = (f"the environment can keep the system from ever satisfying {goal.text} "
               "while meeting all of its own assumptions")
    formulas = (_where(goal, game.spec.path),)
    if len(game.inputs) + len(game.outputs) > MAX_EXPLICIT_VARS:
        return Diagnosis(kind="liveness", summary=summary + " (witness omitted: too many "
                         "variables for an explicit play)", formulas=formulas)
    lasso = _find_lasso(game, winning, game.sys_goals[0].bdd)
    if lasso is None:
        return Diagnosis(kind="liveness", summary=summary, formulas=formulas)
    steps, loop_start = lasso
    cycle = steps[loop_start:]
    states = sorted({" & ".join([*s.outputs, *[v if v in s.inputs else f"!{v}"
                                               for v in game.inputs]])
                     for s in cycle})
    cyc = " | ".join(f"({c})" for c in states)
    hint = ("if this cycle cannot go on forever physically, say so with an environment "
            f"fairness (liveness) assumption that rules it out, e.g. \"GF(!({cyc}))\"")
    return Diagnosis(kind="liveness", summary=summary, formulas=formulas, witness=tuple(steps),
                     loop_start=loop_start, hint=hint)


def _find_lasso(game: Game, winning: Any, goal: Any
                ) -> tuple[list[Step], int] | None:
    """Explicit search for a fair cycle of the environment outside the system's winning set.

    Nodes are positions ``(x, y)`` losing for the system. The environment moves only to
    readings after which every legal system reply stays losing; the system's reply shown is its
    least legal one. A lasso is a path from an initial position into a strongly connected set
    of such positions that avoids the goal and meets every environment goal.
    """
    bdd = game.manager
    X, Y = list(game.inputs), list(game.outputs)
    Yp = game.outputs_next
    losing_p = game.prime(~winning)
    env_goals = _goals_or_true(game, game.env_goals)
    start = game.theta_e & bdd.forall(Y, ~game.theta_s | ~winning)
    x0 = least_assignment(game, start, X)
    if x0 is None:
        return None
    y0 = least_assignment(game, bdd.let(x0, game.theta_s), Y) or {}
    nodes: list[dict[str, bool]] = [{**x0, **y0}]
    index = {tuple(sorted(nodes[0].items())): 0}
    succ: list[list[int]] = []
    k = 0
    while k < len(nodes):
        s = nodes[k]
        rho_e = bdd.let(s, game.rho_e)
        rho_s = bdd.let(s, game.rho_s)
        out: list[int] = []
        for xn in assignments(X):
            xp = {v + "'": b for v, b in xn.items()}
            if bdd.let(xp, rho_e) == bdd.false:
                continue
            replies = bdd.let(xp, rho_s)
            if replies == bdd.false or bdd.forall(Yp, ~replies | bdd.let(xp, losing_p)) \
                    != bdd.true:
                continue
            yp = least_assignment(game, replies, Yp) or {}
            node = {**xn, **{v[:-1]: b for v, b in yp.items()}}
            key = tuple(sorted(node.items()))
            if key not in index:
                index[key] = len(nodes)
                nodes.append(node)
            out.append(index[key])
        succ.append(out)
        k += 1
    in_goal = [bdd.let(s, goal) == bdd.true for s in nodes]
    sat_env = [[bdd.let(s, g) == bdd.true for g in env_goals] for s in nodes]
    allowed = [not g for g in in_goal]
    for comp in _sccs(succ, allowed):
        members = set(comp)
        has_edge = len(comp) > 1 or comp[0] in succ[comp[0]]
        if not has_edge:
            continue
        if not all(any(sat_env[v][i] for v in comp) for i in range(len(env_goals))):
            continue
        entry_path = _bfs(succ, 0, members, None)
        if entry_path is None:
            continue
        entry = entry_path[-1]
        cycle = [entry]
        cur = entry
        for i in range(len(env_goals)):
            if any(sat_env[v][i] for v in cycle):
                continue
            targets = {v for v in comp if sat_env[v][i]}
            seg = _bfs(succ, cur, targets, members)
            if seg is None:
                break
            cycle += seg[1:]
            cur = seg[-1]
        back = _bfs(succ, cur, {entry}, members, nonempty=True)
        if back is None:
            continue
        cycle += back[1:-1]
        path = entry_path[:-1] + cycle
        steps = [Step(inputs=_true(X, nodes[v]), outputs=_true(Y, nodes[v])) for v in path]
        return steps, len(entry_path) - 1
    return None


def _bfs(succ: list[list[int]], src: int, targets: set[int], within: set[int] | None,
         *, nonempty: bool = False) -> list[int] | None:
    """Shortest path from ``src`` to a node of ``targets`` (at least one edge if ``nonempty``)."""
    if src in targets and not nonempty:
        return [src]
    parent: dict[int, int] = {}
    seen: set[int] = set() if nonempty else {src}
    frontier = [src]
    while frontier:
        nxt = []
        for u in frontier:
            for v in succ[u]:
                if (within is not None and v not in within) or v in seen:
                    continue
                seen.add(v)
                parent[v] = u
                if v in targets:
                    path = [v]
                    while True:
                        path.append(parent[path[-1]])
                        if path[-1] == src:
                            return path[::-1]
                nxt.append(v)
        frontier = nxt
    return None


def _sccs(succ: list[list[int]], allowed: list[bool]) -> list[list[int]]:
    """Strongly connected components of the subgraph on ``allowed`` nodes (Tarjan, iterative),
    in order of their smallest node."""
    n = len(succ)
    index = [-1] * n
    low = [0] * n
    on_stack = [False] * n
    stack: list[int] = []
    comps: list[list[int]] = []
    counter = 0
    for root in range(n):
        if not allowed[root] or index[root] >= 0:
            continue
        work = [(root, 0)]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack[root] = True
        while work:
            v, i = work[-1]
            nbrs = [w for w in succ[v] if allowed[w]]
            if i < len(nbrs):
                work[-1] = (v, i + 1)
                w = nbrs[i]
                if index[w] < 0:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack[w] = True
                    work.append((w, 0))
                elif on_stack[w]:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack[w] = False
                        comp.append(w)
                        if w == v:
                            break
                    comps.append(sorted(comp))
    return sorted(comps, key=lambda c: c[0])
