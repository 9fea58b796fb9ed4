"""GR(1) games on BDDs (``dd`` with CUDD): realizability by the 3-nested fixpoint.

Semantics (``docs/design.md``, "GR(1) semantics"; Piterman, Pnueli and Sa'ar 2006; Bloem et al.,
JCSS 2012). Variables are the inputs ``X`` (environment) and outputs ``Y`` (system) and their
primed next copies. A spec ``phi_e -> phi_s`` becomes

* ``theta_e(X)``, ``theta_s(X, Y)``: initial conditions;
* ``rho_e(X, Y, X')``, ``rho_s(X, Y, X', Y')``: transition relations (the safety formulas with
  ``X v`` read as ``v'``);
* ``J_e``, ``J_s``: the liveness goals ``GF(p)``.

Mealy semantics: the system sees the new input ``X'`` before it picks ``Y'``. The controllable
predecessor is ``cpre(Z) = forall X'. (rho_e -> exists Y'. (rho_s & Z'))`` and the winning set is

    Z = nu Z. /\\_j mu Y. \\/_i nu X. ((J_s^j & cpre(Z)) | cpre(Y) | (!J_e^i & cpre(X)))

The spec is realizable iff ``forall X. theta_e -> exists Y. theta_s & Z``.

Safety at every position, the first included (``docs/explanation/logic.md``).
``G(phi)`` means: ``phi`` holds at every position ``i >= 0``, where ``phi`` may mention the
current and the next values. Each side's safety formulas go into its transition relation as
written (``X v`` read as ``v'``), and in addition their *current-state consequence* applies
to every state of the play, the initial one included:

* ``safe_e(X)``: the sensor readings from which the safety assumptions can hold forever
  (``nu C. exists Y, X'. rho_e & C'``, for some outputs); for an ``X``-free ``G(phi)``
  over the inputs this is ``phi`` itself;
* ``safe_s(X, Y)``: the states from which the safety guarantees can hold forever
  (``nu C. exists X', Y'. rho_s & C'``); for an ``X``-free ``G(phi)`` this is ``phi``.

The game uses ``theta_e & safe_e`` and ``theta_s & safe_s`` as initial conditions and
``rho_e & safe_e'``, ``rho_s & safe_s'`` as transition relations: the textbook reading of an
``X``-free ``G(phi)`` (``phi`` added to the initial condition, ``phi'`` to the transition
relation), extended to ``phi`` with ``X``. A reading outside ``safe_e`` breaks an assumption
whatever the system does, so the environment may not pick it (at the start or later); a
state in which the environment has no legal move left is a dead end for the environment
(the system wins there), and it can only arise from the system's outputs.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from tli_verify.logic.ltl import Slot, gr1_body
from tli_verify.logic.spec import GR1Spec, SpecFormula

__all__ = ["Game", "Solution", "build_game", "solve"]

PRIME = "'"


def _prime(name: str) -> str:
    return name + PRIME


@dataclass(frozen=True, slots=True, eq=False)
class Goal:
    """A liveness goal ``GF(p)`` and its BDD."""

    formula: SpecFormula
    bdd: Any


@dataclass(frozen=True, slots=True, eq=False)
class Game:
    """A GR(1) game on a CUDD manager (built by :func:`build_game`).

    The BDD attributes are ``dd.cudd.Function`` nodes of ``manager``. ``theta_e``,
    ``theta_s``, ``rho_e`` and ``rho_s`` include the current-state consequences ``safe_e``
    (over the inputs) and ``safe_s`` (over inputs and outputs) of the safety formulas (module
    docstring); ``safety_e``/``safety_s`` and ``init_e``/``init_s`` keep each formula's own
    BDD, for diagnosis.
    """

    spec: GR1Spec
    manager: Any
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    theta_e: Any
    theta_s: Any
    rho_e: Any
    rho_s: Any
    env_goals: tuple[Goal, ...]
    sys_goals: tuple[Goal, ...]
    safety_e: tuple[tuple[SpecFormula, Any], ...] = field(default=())
    safety_s: tuple[tuple[SpecFormula, Any], ...] = field(default=())
    init_e: tuple[tuple[SpecFormula, Any], ...] = field(default=())
    init_s: tuple[tuple[SpecFormula, Any], ...] = field(default=())
    safe_e: Any = None
    safe_s: Any = None
    semantics: str = "tli"

    @property
    def inputs_next(self) -> list[str]:
        return [_prime(v) for v in self.inputs]

    @property
    def outputs_next(self) -> list[str]:
        return [_prime(v) for v in self.outputs]

    @property
    def true(self) -> Any:
        return self.manager.true

    @property
    def false(self) -> Any:
        return self.manager.false

    def prime(self, u: Any) -> Any:
        """Rename every unprimed variable of ``u`` to its primed copy."""
        rename = {v: _prime(v) for v in self.inputs + self.outputs}
        return self.manager.let(rename, u)

    def cpre(self, z: Any) -> Any:
        """Controllable predecessor (Mealy): ``forall X'. rho_e -> exists Y'. rho_s & Z'``."""
        import dd.cudd

        sys_can = dd.cudd.and_exists(self.rho_s, self.prime(z), self.outputs_next)
        return self.manager.forall(self.inputs_next, ~self.rho_e | sys_can)

    def with_(self, **changes: Any) -> Game:
        """A copy with some components replaced (same manager)."""
        fields = {name: getattr(self, name) for name in self.__dataclass_fields__}
        fields.update(changes)
        return Game(**fields)

    def conj(self, parts: Iterable[tuple[SpecFormula, Any]]) -> Any:
        u = self.true
        for _, b in parts:
            u &= b
        return u


def build_game(spec: GR1Spec, *, manager: Any = None, semantics: str | None = None) -> Game:
    """Compile ``spec`` to a :class:`Game`.

    Parameters
    ----------
    spec : GR1Spec
    manager : dd.cudd.BDD, optional
        Reuse this CUDD manager (so that BDDs of several games over the same variables can be
        compared); a fresh one by default.
    semantics : {"tli", "textbook"}, optional
        The reading of safety at time 0 (default: the spec's ``semantics``). ``"tli"``: the
        module docstring. ``"textbook"`` (Spectra, slugs): the initial conditions are the
        ``init`` formulas alone and the transition relations the safety bodies alone, with
        no current-state consequence (``safe_e`` and ``safe_s`` are ``true``).
    """
    import dd.cudd

    reading = spec.semantics if semantics is None else semantics
    if reading not in ("tli", "textbook"):
        raise ValueError(f"semantics must be 'tli' or 'textbook', got {reading!r}")

    bdd = dd.cudd.BDD() if manager is None else manager
    order = []
    for v in spec.inputs + spec.outputs:
        order += [v, _prime(v)]
    bdd.declare(*order)

    def safety(f: SpecFormula) -> Any:
        """Transition constraint of a conjunction of ``G(phi)``."""
        trans = bdd.true
        for g in _conjuncts(f.ltl):
            trans &= _to_bdd(gr1_body(g, Slot.SAFETY), bdd, primed=False)
        return trans

    init_e = [(f, _to_bdd(f.ltl, bdd, primed=False)) for f in spec.assume.init]
    init_s = [(f, _to_bdd(f.ltl, bdd, primed=False)) for f in spec.guarantee.init]
    safety_e = [(f, safety(f)) for f in spec.assume.safety]
    safety_s = [(f, safety(f)) for f in spec.guarantee.safety]

    def goals(side: Sequence[SpecFormula]) -> tuple[Goal, ...]:
        out = []
        for f in side:
            for g in _conjuncts(f.ltl):
                out.append(Goal(formula=f, bdd=_to_bdd(gr1_body(g, Slot.LIVENESS), bdd,
                                                       primed=False)))
        return tuple(out)

    inputs, outputs = list(spec.inputs), list(spec.outputs)
    inputs_next = [_prime(v) for v in inputs]
    outputs_next = [_prime(v) for v in outputs]
    rho_e = _conj_bdd(bdd, [b for _, b in safety_e])
    rho_s = _conj_bdd(bdd, [b for _, b in safety_s])
    rename = {v: _prime(v) for v in inputs + outputs}
    if reading == "textbook":
        safe_e = safe_s = bdd.true
    else:
        safe_e = safety_closure(bdd, rho_e, {v: _prime(v) for v in inputs},
                                outputs + inputs_next)
        safe_s = safety_closure(bdd, rho_s, rename, inputs_next + outputs_next)
    return Game(
        spec=spec,
        manager=bdd,
        inputs=spec.inputs,
        outputs=spec.outputs,
        theta_e=_conj_bdd(bdd, [b for _, b in init_e]) & safe_e,
        theta_s=_conj_bdd(bdd, [b for _, b in init_s]) & safe_s,
        rho_e=rho_e & bdd.let(rename, safe_e),
        rho_s=rho_s & bdd.let(rename, safe_s),
        env_goals=goals(spec.assume.liveness),
        sys_goals=goals(spec.guarantee.liveness),
        safety_e=tuple(safety_e),
        safety_s=tuple(safety_s),
        init_e=tuple(init_e),
        init_s=tuple(init_s),
        safe_e=safe_e,
        safe_s=safe_s,
        semantics=reading,
    )


def _conj_bdd(bdd: Any, parts: Iterable[Any]) -> Any:
    u = bdd.true
    for b in parts:
        u &= b
    return u


def safety_closure(bdd: Any, trans: Any, rename: Mapping[str, str],
                   quantified: Sequence[str]) -> Any:
    """``nu C. exists quantified. trans & C'``: where ``G(trans)`` can still hold forever.

    Parameters
    ----------
    bdd : dd.cudd.BDD
    trans : BDD
        A transition constraint (over current and primed variables).
    rename : mapping of str to str
        The current variables ``C`` ranges over, each to its primed copy (``C'``).
    quantified : sequence of str
        Every variable of ``trans`` outside the keys of ``rename``.

    Returns
    -------
    BDD
        Over the keys of ``rename``: the states from which some infinite sequence satisfies
        ``trans`` at every step, i.e. the current-state consequence of ``G(trans)``. For the
        assumptions (``rename`` over the inputs, the outputs quantified) these are the
        readings from which they can hold for some outputs; for an ``X``-free ``G(phi)`` the
        result is ``phi`` itself (when ``phi`` is satisfiable in each step).
    """
    c = bdd.true
    while True:
        new = bdd.exist(list(quantified), trans & bdd.let(dict(rename), c))
        if new == c:
            return c
        c = new


def minimal_init_core(bdd: Any, parts: Sequence[tuple[Any, Any, bool]], *,
                      rename: Mapping[str, str], quantified: Sequence[str],
                      empty: Callable[[Any], bool]) -> list[Any]:
    """A 1-minimal subset of one side's initial conditions and safety formulas (at time 0)
    whose initial states are ``empty`` (deletion-based minimisation).

    Parameters
    ----------
    bdd : dd.cudd.BDD
    parts : sequence of (formula, BDD, is_safety)
        Initial conditions (``is_safety`` false) and safety constraints of one side.
    rename, quantified
        As in :func:`safety_closure` for that side.
    empty : callable
        ``u -> bool``: whether the initial states ``init & safety_closure(trans)`` give no
        legal start (what "no start" means differs between the two callers).

    Returns
    -------
    list
        The formulas of the minimal subset, in their original order.
    """
    def fails(subset: Sequence[tuple[Any, Any, bool]]) -> bool:
        init = bdd.true
        trans = bdd.true
        for _, b, is_safety in subset:
            if is_safety:
                trans &= b
            else:
                init &= b
        return empty(init & safety_closure(bdd, trans, rename, quantified))

    kept = list(parts)
    k = 0
    while k < len(kept):
        rest = kept[:k] + kept[k + 1:]
        if fails(rest):
            kept = rest
        else:
            k += 1
    return [f for f, _, _ in kept]


def closed_relation(game: Game, parts: Sequence[Any], *, system: bool) -> Any:
    """The transition relation of a subset of one side's safety formulas, with its
    current-state consequence on the next state (as :func:`build_game` builds ``rho_e`` and
    ``rho_s`` from all of them)."""
    bdd = game.manager
    trans = _conj_bdd(bdd, parts)
    if game.semantics == "textbook":
        return trans
    if system:
        rename = {v: _prime(v) for v in game.inputs + game.outputs}
        safe = safety_closure(bdd, trans, rename, game.inputs_next + game.outputs_next)
    else:
        rename = {v: _prime(v) for v in game.inputs}
        safe = safety_closure(bdd, trans, rename, list(game.outputs) + game.inputs_next)
    return trans & game.prime(safe)


def _conjuncts(f: Any) -> list[Any]:
    import spot

    if f.kind() == spot.op_And:
        out = []
        for c in f:
            out += _conjuncts(c)
        return out
    return [f]


def _has_next(f: Any) -> bool:
    import spot

    if f.kind() == spot.op_X:
        return True
    return any(_has_next(c) for c in f)


def _aps(f: Any) -> set[str]:
    import spot

    return {str(a.ap_name()) for a in spot.atomic_prop_collect(f)}


def _to_bdd(f: Any, bdd: Any, *, primed: bool) -> Any:
    """BDD of a propositional formula with ``X`` at depth <= 1 (``X v`` -> ``v'``)."""
    import spot

    kind = f.kind()
    if kind == spot.op_tt:
        return bdd.true
    if kind == spot.op_ff:
        return bdd.false
    if kind == spot.op_ap:
        name = str(f.ap_name())
        return bdd.var(_prime(name) if primed else name)
    if kind == spot.op_X:
        return _to_bdd(f[0], bdd, primed=True)
    args = [_to_bdd(c, bdd, primed=primed) for c in f]
    if kind == spot.op_Not:
        return ~args[0]
    if kind == spot.op_And:
        u = bdd.true
        for a in args:
            u &= a
        return u
    if kind == spot.op_Or:
        u = bdd.false
        for a in args:
            u |= a
        return u
    if kind == spot.op_Implies:
        return ~args[0] | args[1]
    if kind == spot.op_Equiv:
        return bdd.apply("<->", args[0], args[1])
    if kind == spot.op_Xor:
        return bdd.apply("xor", args[0], args[1])
    raise ValueError(f"unexpected operator {f.kindstr()} in {f}")  # classify() rules this out


@dataclass(frozen=True, slots=True, eq=False)
class Solution:
    """The solved game: winning set and the iterates the strategy is built from.

    Attributes
    ----------
    game : Game
    winning : BDD
        ``Z``, the system's winning states.
    realizable : bool
        ``forall X. theta_e -> exists Y. theta_s & Z``.
    rings : tuple of tuple of BDD
        ``rings[j][r]`` is ``Y^j_{r+1}``, the states that reach goal ``j`` in at most ``r+1``
        rounds (the mu-iterates of the last outer iteration).
    traps : tuple of tuple of tuple of BDD
        ``traps[j][r][i]`` is ``X^j_{r+1,i}``: states that stay until goal ``j`` or a lower ring
        is forced, while environment goal ``i`` is never met.
    """

    game: Game
    winning: Any
    realizable: bool
    rings: tuple[tuple[Any, ...], ...]
    traps: tuple[tuple[tuple[Any, ...], ...], ...]

    def rank(self, j: int, state: Any) -> tuple[int, int] | None:
        """Lexicographically least ``(r, i)`` with ``state`` (a cube) in ``traps[j][r][i]``."""
        for r, ring in enumerate(self.traps[j]):
            for i, trap in enumerate(ring):
                if (trap & state) != self.game.false:
                    return (r, i)
        return None


def _goals_or_true(game: Game, goals: tuple[Goal, ...]) -> list[Any]:
    return [g.bdd for g in goals] or [game.true]


def _nu_trap(game: Game, unless: Any, avoid_goal: Any) -> Any:
    """``nu X. unless | (!J_e^i & cpre(X))``."""
    x = game.true
    while True:
        new = unless | (~avoid_goal & game.cpre(x))
        if new == x:
            return x
        x = new


def solve(game: Game, *, keep_iterates: bool = True) -> Solution:
    """Solve the GR(1) game by the 3-nested fixpoint (Bloem et al. 2012, Sec. 3).

    Parameters
    ----------
    game : Game
    keep_iterates : bool
        Keep the rings and traps of the final outer iteration (needed for strategies).
    """
    env_goals = _goals_or_true(game, game.env_goals)
    sys_goals = _goals_or_true(game, game.sys_goals)
    z = game.true
    rings: list[tuple[Any, ...]] = []
    traps: list[tuple[tuple[Any, ...], ...]] = []
    while True:
        z_old = z
        rings, traps = [], []
        for goal in sys_goals:
            target = goal & game.cpre(z)
            y = game.false
            ring_list: list[Any] = []
            trap_list: list[tuple[Any, ...]] = []
            while True:
                unless = target | game.cpre(y)
                layer = tuple(_nu_trap(game, unless, eg) for eg in env_goals)
                y_new = game.false
                for x in layer:
                    y_new |= x
                if y_new == y:
                    break
                y = y_new
                ring_list.append(y)
                trap_list.append(layer)
            z &= y
            rings.append(tuple(ring_list))
            traps.append(tuple(trap_list))
        if z == z_old:
            break
    bdd = game.manager
    init_ok = bdd.forall(
        list(game.inputs), ~game.theta_e | bdd.exist(list(game.outputs), game.theta_s & z)
    )
    realizable = init_ok == bdd.true
    if not keep_iterates:
        rings, traps = [], []
    return Solution(game=game, winning=z, realizable=realizable, rings=tuple(rings),
                    traps=tuple(traps))


def cube(game: Game, values: Mapping[str, bool]) -> Any:
    """BDD of the assignment ``values`` (names may be primed)."""
    u = game.true
    for name, val in values.items():
        v = game.manager.var(name)
        u &= v if val else ~v
    return u


def least_assignment(game: Game, u: Any, names: Sequence[str]) -> dict[str, bool] | None:
    """Lexicographically least assignment (False < True, in ``names`` order) inside ``u``.

    Returns None when ``u`` is empty. Deterministic: it does not depend on the BDD's variable
    order or on CUDD's internal choices.
    """
    if u == game.false:
        return None
    out: dict[str, bool] = {}
    for name in names:
        low = game.manager.let({name: False}, u)
        if low != game.false:
            out[name] = False
            u = low
        else:
            out[name] = True
            u = game.manager.let({name: True}, u)
    return out


def assignments(names: Sequence[str]) -> list[dict[str, bool]]:
    """All assignments of ``names``, in lexicographic order (False < True)."""
    out: list[dict[str, bool]] = [{}]
    for name in names:
        out = [{**a, name: val} for a in out for val in (False, True)]
    return out
