"""Spec sanity: well-separation, minimal unrealizable cores and vacuity hints.

A "realizable" verdict is worthless when the system can win by breaking the environment's
assumptions (``phi_e -> phi_s`` then holds vacuously). The paper's own appendix-E scoop formula
has this flaw (``docs/design.md``; ``specs/scoop-paper-literal.toml``).

Well-separation (Maoz and Ringert, FSE 2016)
    The system, obeying its own initial condition and safety guarantees, tries to falsify the
    assumptions: leave the environment without a legal move (break a safety assumption) or
    keep an environment liveness goal false from some point on. The environment wins a
    generalized Buchi game ``E = nu Z. /\\_i mu Y. (J_e^i & epre(Z)) | epre(Y)`` with
    ``epre(Z) = exists X'. rho_e & forall Y'. (rho_s -> Z')``. The spec is well-separated iff
    every initial state the assumptions and guarantees allow lies in ``E``.

Unrealizable core (Maoz and Shalom, ICSE 2021, "QuickCore")
    A minimal set of guarantees that is still unrealizable, by delta debugging over the
    guarantee conjuncts. Unrealizability is monotone (fewer guarantees, easier for the system),
    so a deletion that keeps unrealizability can be committed, and the result is 1-minimal:
    removing any one of its elements gives a realizable spec.

Assumptions
    By the same monotonicity, removing assumptions keeps a spec unrealizable: no subset of
    the assumptions helps an unrealizable spec. For a realizable spec we report the minimal
    set of assumptions it needs (the others are not needed for the verdict).

Vacuity hints
    Formulas whose removal changes nothing: the assumptions a realizable spec does not need
    (those outside a minimal assumption set that keeps it realizable), and the guarantees
    outside the core of an unrealizable one. (Removing a guarantee never makes a realizable
    spec unrealizable, nor removing an assumption an unrealizable one realizable: those
    directions would flag every formula and are not reported.)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from tli_verify.logic.diagnose import Step
from tli_verify.logic.gr1 import (
    Game,
    build_game,
    closed_relation,
    least_assignment,
    minimal_init_core,
    solve,
)
from tli_verify.logic.spec import GR1Spec, SpecFormula, SpecSide

__all__ = [
    "Core",
    "Hint",
    "WellSeparation",
    "assumption_core",
    "unrealizable_core",
    "vacuity_hints",
    "well_separation",
]


@dataclass(frozen=True, slots=True)
class WellSeparation:
    """Whether the system can force a violation of the assumptions.

    Attributes
    ----------
    well_separated : bool
    kind : str or None
        What the system can break: ``"initial"`` (the assumptions' initial condition is
        unsatisfiable), ``"safety"`` or ``"liveness"``; None when well-separated.
    formulas : tuple of str
        The assumptions it breaks, as ``file:line section[i]: text``.
    witness : tuple of Step
        A play in which the system forces the violation (the environment's moves shown are its
        least legal ones).
    loop_start : int or None
        For a liveness violation, where the repeated cycle starts.
    """

    well_separated: bool
    kind: str | None = None
    formulas: tuple[str, ...] = ()
    witness: tuple[Step, ...] = ()
    loop_start: int | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "well_separated": self.well_separated,
            "kind": self.kind,
            "formulas": list(self.formulas),
            "witness": [s.to_dict() for s in self.witness],
            "loop_start": self.loop_start,
        }

    def lines(self) -> list[str]:
        if self.well_separated:
            return ["well-separated: the system cannot force a violation of the assumptions"]
        out = [f"NOT well-separated: the system can break an environment {self.kind} "
               "assumption, so it can 'win' vacuously"]
        out += [f"  breaks: {f}" for f in self.formulas]
        if self.witness:
            out.append("  witness play (system forces it):")
            for k, step in enumerate(self.witness):
                mark = "  <- loop starts" if self.loop_start == k else ""
                out.append(f"    {k}: {step}{mark}")
            if self.kind == "safety":
                out.append(f"    {len(self.witness)}: the environment has no legal move")
        return out


@dataclass(frozen=True, slots=True)
class Core:
    """A minimal set of formulas, each with where it is written."""

    formulas: tuple[SpecFormula, ...]
    path: str | None

    def to_dict(self) -> list[dict[str, Any]]:
        return [{"label": f.label, "line": f.line, "text": f.text, "origin": f.origin}
                for f in self.formulas]

    def lines(self) -> list[str]:
        return [f"  {f.where(self.path)}: {f.text}" for f in self.formulas]


@dataclass(frozen=True, slots=True)
class Hint:
    """A formula that does not affect the verdict."""

    formula: SpecFormula
    reason: str
    path: str | None

    def to_dict(self) -> dict[str, Any]:
        return {"label": self.formula.label, "line": self.formula.line,
                "text": self.formula.text, "reason": self.reason}

    def __str__(self) -> str:
        return f"{self.formula.where(self.path)}: {self.formula.text}: {self.reason}"


# --- well-separation -------------------------------------------------------------------------

def _epre(game: Game, z: Any) -> Any:
    """Environment's controllable predecessor: ``exists X'. rho_e & forall Y'. rho_s -> Z'``."""
    bdd = game.manager
    after = bdd.forall(game.outputs_next, ~game.rho_s | game.prime(z))
    return bdd.exist(game.inputs_next, game.rho_e & after)


def _env_winning(game: Game, goals: Sequence[Any]) -> Any:
    """The environment's generalized Buchi winning region (all ``goals`` infinitely often)."""
    goals = list(goals) or [game.true]
    z = game.true
    while True:
        z_old = z
        for goal in goals:
            target = goal & _epre(game, z)
            y = game.false
            while True:
                y_new = target | _epre(game, y)
                if y_new == y:
                    break
                y = y_new
            z &= y
        if z == z_old:
            return z


def well_separation(game: Game) -> WellSeparation:
    """Decide well-separation of ``game`` and explain a violation (see module docstring)."""
    bdd = game.manager
    path = game.spec.path
    X = list(game.inputs)
    if bdd.exist(X, game.theta_e) == bdd.false:
        # No initial reading satisfies the initial assumptions and lets the safety
        # assumptions hold from time 0 on.
        return WellSeparation(False, "initial",
                              tuple(f"{f.where(path)}: {f.text}" for f in _initial_culprits(game)))
    env_goals = [g.bdd for g in game.env_goals]
    winning = _env_winning(game, env_goals)
    bad_start = game.theta_e & game.theta_s & ~winning
    if bad_start == bdd.false:
        return WellSeparation(True)
    # Which kind: can the system break safety alone?
    safe_only = _env_winning(game, [])
    kind = "safety" if (game.theta_e & game.theta_s & ~safe_only) != bdd.false else "liveness"
    steps, loop_start, dead = _system_play(game, ~(safe_only if kind == "safety" else winning),
                                           [] if kind == "safety" else env_goals)
    if kind == "safety":
        formulas = _broken_safety(game, dead)
    else:
        cycle = steps[loop_start:] if loop_start is not None else steps
        formulas = tuple(
            f"{g.formula.where(path)}: {g.formula.text}" for g in game.env_goals
            if not any(bdd.let(_assign(game, s), g.bdd) == bdd.true for s in cycle)
        )
    return WellSeparation(False, kind, formulas, tuple(steps), loop_start)


def _initial_culprits(game: Game) -> list[SpecFormula]:
    """A minimal set of assumptions (initial conditions, and safety formulas at time 0) that
    no initial reading satisfies."""
    bdd = game.manager
    parts: list[tuple[SpecFormula, Any, bool]] = (
        [(f, b, False) for f, b in game.init_e]
        + ([] if game.semantics == "textbook" else [(f, b, True) for f, b in game.safety_e]))
    return minimal_init_core(
        bdd, parts, rename={v: v + "'" for v in game.inputs},
        quantified=list(game.outputs) + game.inputs_next,
        empty=lambda u: bdd.exist(list(game.inputs), u) == bdd.false)


def _assign(game: Game, step: Step) -> dict[str, bool]:
    return {**{v: v in step.inputs for v in game.inputs},
            **{v: v in step.outputs for v in game.outputs}}


def _broken_safety(game: Game, state: dict[str, bool] | None) -> tuple[str, ...]:
    """A minimal set of safety assumptions that leaves the environment no move at ``state``."""
    path = game.spec.path
    parts = list(game.safety_e)
    if state is None:
        return tuple(f"{f.where(path)}: {f.text}" for f, _ in parts)
    bdd = game.manager
    k = 0
    while k < len(parts):
        rest = parts[:k] + parts[k + 1:]
        u = closed_relation(game, [b for _, b in rest], system=False)
        if bdd.exist(game.inputs_next, bdd.let(state, u)) == bdd.false:
            parts = rest
        else:
            k += 1
    return tuple(f"{f.where(path)}: {f.text}" for f, _ in parts)


def _system_play(game: Game, sys_region: Any, env_goals: list[Any], max_steps: int = 64
                 ) -> tuple[list[Step], int | None, dict[str, bool] | None]:
    """A play in which the system, from ``sys_region``, forces a violation.

    The system's strategy is the dual fixpoint's: it moves to a lower layer of its attractor
    when it can, otherwise it stays inside the trap where an environment goal stays false.
    The environment's moves are its least legal ones. Returns the steps, the loop start (for
    a lasso) and the state where the environment has no legal move (for a safety violation).
    """
    bdd = game.manager
    X, Y = list(game.inputs), list(game.outputs)
    Xp, Yp = game.inputs_next, game.outputs_next
    goals = env_goals or [bdd.true]
    # Layers of the system's attractor: Z_{k+1} = \/_i nu Y. (!J_i & cpre(Y)) | cpre(Z_k).
    layers: list[Any] = [bdd.false]
    traps: list[list[Any]] = [[]]
    while True:
        lower = game.cpre(layers[-1])
        level = []
        for goal in goals:
            y = bdd.true
            while True:
                y_new = lower | (~goal & game.cpre(y)) if env_goals else lower
                if y_new == y:
                    break
                y = y_new
            level.append(y)
        z = bdd.false
        for y in level:
            z |= y
        if z == layers[-1]:
            break
        layers.append(z)
        traps.append(level)
    start = game.theta_e & game.theta_s & sys_region
    x = least_assignment(game, start, X) or {}
    y = least_assignment(game, bdd.let(x, game.theta_s & sys_region), Y) or {}
    seen: dict[tuple[tuple[str, bool], ...], int] = {}
    steps: list[Step] = []
    state = {**x, **y}
    for _ in range(max_steps):
        key = tuple(sorted(state.items()))
        if key in seen:
            return steps, seen[key], None
        seen[key] = len(steps)
        steps.append(Step(inputs=tuple(v for v in X if state[v]),
                          outputs=tuple(v for v in Y if state[v])))
        rho_e = bdd.let(state, game.rho_e)
        if rho_e == bdd.false:
            return steps, None, state
        k = next((i for i in range(1, len(layers)) if bdd.let(state, layers[i]) == bdd.true),
                 len(layers) - 1)
        if bdd.let(state, game.cpre(layers[k - 1])) == bdd.true:
            target = layers[k - 1]
        else:
            target = next((t for t in traps[k] if bdd.let(state, t) == bdd.true), layers[k])
        xp = least_assignment(game, rho_e, Xp) or {}
        moves = bdd.let(xp, bdd.let(state, game.rho_s) & game.prime(target))
        yp = least_assignment(game, moves, Yp)
        if yp is None:  # pragma: no cover - the fixpoint guarantees a move
            return steps, None, None
        state = {**{v[:-1]: b for v, b in xp.items()}, **{v[:-1]: b for v, b in yp.items()}}
    return steps, None, None


# --- cores and vacuity -----------------------------------------------------------------------

def _with(spec: GR1Spec, *, assume: Sequence[SpecFormula] | None = None,
          guarantee: Sequence[SpecFormula] | None = None) -> GR1Spec:
    def side(formulas: Sequence[SpecFormula]) -> SpecSide:
        return SpecSide(
            init=tuple(f for f in formulas if f.section.endswith(".init")),
            safety=tuple(f for f in formulas if f.section.endswith(".safety")),
            liveness=tuple(f for f in formulas if f.section.endswith(".liveness")),
        )

    return dataclasses.replace(
        spec,
        assume=side(assume) if assume is not None else spec.assume,
        guarantee=side(guarantee) if guarantee is not None else spec.guarantee,
    )


def _realizable(spec: GR1Spec, manager: Any = None) -> bool:
    return solve(build_game(spec, manager=manager), keep_iterates=False, exact=False).realizable


def _shared_manager(spec: GR1Spec) -> Any:
    """One CUDD manager for the many games of a core search (its caches carry over)."""
    return build_game(spec).manager


def _ddmin(items: list[SpecFormula], keeps: Callable[[list[SpecFormula]], bool]
           ) -> list[SpecFormula]:
    """Delta debugging (Zeller): a 1-minimal sublist for a monotone property ``keeps``."""
    n = 2
    while len(items) >= 2:
        chunk = max(1, len(items) // n)
        reduced = False
        for start in range(0, len(items), chunk):
            complement = items[:start] + items[start + chunk:]
            if complement and keeps(complement):
                items = complement
                n = max(n - 1, 2)
                reduced = True
                break
        if not reduced:
            if chunk == 1:
                break
            n = min(len(items), 2 * n)
    # Monotone property: a final single-deletion pass makes the result 1-minimal.
    k = 0
    while k < len(items):
        rest = items[:k] + items[k + 1:]
        if keeps(rest):
            items = rest
        else:
            k += 1
    return items


def unrealizable_core(spec: GR1Spec) -> Core:
    """A minimal unrealizable set of guarantees (``spec`` must be unrealizable)."""
    guarantees = list(spec.guarantee.all())
    manager = _shared_manager(spec)

    def unrealizable(subset: list[SpecFormula]) -> bool:
        return not _realizable(_with(spec, guarantee=subset), manager)

    if not unrealizable(guarantees):
        raise ValueError("the spec is realizable; it has no unrealizable core")
    core = [] if unrealizable([]) else _ddmin(guarantees, unrealizable)
    return Core(formulas=tuple(core), path=spec.path)


def assumption_core(spec: GR1Spec) -> Core:
    """A minimal set of assumptions a realizable ``spec`` needs to stay realizable."""
    assumptions = list(spec.assume.all())
    manager = _shared_manager(spec)

    def realizable(subset: list[SpecFormula]) -> bool:
        return _realizable(_with(spec, assume=subset), manager)

    if not realizable(assumptions):
        raise ValueError("the spec is unrealizable; no assumptions core for realizability")
    core = [] if realizable([]) else _ddmin(assumptions, realizable)
    return Core(formulas=tuple(core), path=spec.path)


def vacuity_hints(spec: GR1Spec, *, realizable: bool, core: Core | None = None) -> list[Hint]:
    """Formulas written in the file whose removal changes nothing (see module docstring)."""
    path = spec.path
    hints: list[Hint] = []
    if realizable:
        needed = set(map(id, assumption_core(spec).formulas))
        for f in spec.assume.all():
            if f.origin == "file" and id(f) not in needed:
                hints.append(Hint(f, "not needed for realizability (removing it keeps the "
                                     "spec realizable)", path))
    else:
        core = core or unrealizable_core(spec)
        in_core = set(map(id, core.formulas))
        for f in spec.guarantee.all():
            if f.origin == "file" and id(f) not in in_core:
                hints.append(Hint(f, "not in the unrealizable core (removing it keeps the spec "
                                     "unrealizable)", path))
    return hints
