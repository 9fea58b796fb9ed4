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

import functools
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from tli_verify.logic.ltl import Slot, gr1_body
from tli_verify.logic.spec import GR1Spec, SpecFormula

__all__ = ["Game", "Solution", "build_game", "formula_bdd", "solve"]

PRIME = "'"


def _prime(name: str) -> str:
    return name + PRIME


@functools.lru_cache(maxsize=64)
def _renaming(names: tuple[str, ...]) -> dict[str, str]:
    """``{v: v'}`` for ``names`` (cached: :meth:`Game.prime` runs in every ``cpre``; callers
    only read it)."""
    return {v: _prime(v) for v in names}


@dataclass(frozen=True, slots=True, eq=False)
class Goal:
    """A liveness goal ``GF(p)`` and its BDD."""

    formula: SpecFormula
    bdd: Any


@dataclass(frozen=True, slots=True)
class Heuristics:
    """Named switches for the GR(1) performance heuristics of Firman, Maoz and Ringert (2020).

    None of them changes the verdict or the winning set (``tests/property/
    test_gr1_heuristics.py`` checks every combination against the others and against
    omega); they change how much work the fixpoint does.

    Attributes
    ----------
    partition : bool
        Conjunctively partitioned transition relations with early quantification in the
        controllable predecessor: ``exists Y'. rho_s & Z'`` as a chain of relational
        products, each primed output quantified after the last part that mentions it, and
        the environment side dually as a chain of ``or_forall`` (paper Sec. 4.2; Burch,
        Clarke and Long 1991).
    cluster_nodes : int
        Parts are merged in order while their conjunction has at most this many nodes.
    early_fixpoint : bool
        Early detection of fixed points (paper Sec. 4.1): the outer ``nu Z`` stops once
        ``|J_s|`` consecutive goal computations (not necessarily one pass from goal 0) left
        ``Z`` unchanged, and the ``mu Y`` of goal ``j`` stops once it reaches the ``Y`` of
        goal ``j`` in the previous outer iteration (``Z`` only shrinks, so that ``Y`` bounds
        the new one from above).
    recycle : bool
        Fixed-point recycling (paper Sec. 4.3; Browne et al. 1997): the ``nu X`` of ring
        ``r``, environment goal ``i`` and system goal ``j`` starts from its value in the
        previous outer iteration instead of ``true`` (an upper bound of the new value, so the
        iteration still descends to the greatest fixed point).
    early_unrealizable : bool
        Early detection of unrealizability (paper Sec. 4.4): every outer iterate of ``Z``
        contains the winning set, so once the initial condition fails on it the spec is
        unrealizable. Only used when the caller does not ask for the exact winning set
        (``solve(..., exact=False)``).
    interleave : bool
        Variable order with each primed copy next to its variable (``x, x', y, y'``) rather
        than all current variables above all primed ones (paper Sec. 4.5).
    group_pairs : bool
        Couple each variable with its primed copy for CUDD's group sifting, so that dynamic
        reordering keeps the pairs adjacent and priming stays cheap (needs ``interleave``).
        Off by default: on the field's suites (SYNTECH15/17/19/20, slugs' examples) free
        sifting of each variable finds orders on which the fixpoint is up to 5x faster
        (roboticarm, SimpleVehicle, Elevator, CinderellaStepmother) and is rarely much
        slower (ParkingLot1, Elevator_62, EvasionOnGrid up to 2-4x); it is what slugs
        does.
    reorder : bool
        CUDD's dynamic variable reordering (group sifting) on.
    max_growth : float
        CUDD's bound on how much the BDD may grow while sifting one variable (CUDD's and
        slugs' default: 1.2). The smaller default 1.1 cuts each reordering short earlier;
        on the field's suites it is ~10% faster overall. Only set on a fresh manager.

    References
    ----------
    E. Firman, S. Maoz and J. O. Ringert, "Performance heuristics for GR(1) synthesis and
    related algorithms", Acta Informatica 57:37-79, 2020.
    """

    partition: bool = True
    cluster_nodes: int = 1000
    early_fixpoint: bool = True
    recycle: bool = True
    early_unrealizable: bool = True
    interleave: bool = True
    group_pairs: bool = False
    reorder: bool = True
    max_growth: float = 1.1

    @classmethod
    def none(cls) -> Heuristics:
        """Every heuristic off: the textbook algorithm (Bloem et al. 2012)."""
        return cls(partition=False, early_fixpoint=False, recycle=False,
                   early_unrealizable=False, interleave=True, group_pairs=False,
                   reorder=True)


HEURISTIC_SWITCHES = ("partition", "early_fixpoint", "recycle", "early_unrealizable",
                      "interleave", "group_pairs", "reorder")
"""The Boolean fields of :class:`Heuristics`."""

DEFAULT_HEURISTICS = Heuristics()


@dataclass(frozen=True, slots=True, eq=False)
class Schedule:
    """A partitioned relation and when to quantify each variable (:meth:`Game.cpre`).

    ``steps[k]`` is ``(part, names)``: fold ``part`` in at step ``k`` and quantify
    ``names`` with it (the variables no later part mentions)."""

    steps: tuple[tuple[Any, tuple[str, ...]], ...]
    first: tuple[str, ...] = ()
    """Variables no part mentions, quantified before the first step (environment side)."""


@dataclass(frozen=True, slots=True, eq=False)
class Game:
    """A GR(1) game on a CUDD manager (built by :func:`build_game`).

    The BDD attributes are ``dd.cudd.Function`` nodes of ``manager``. ``theta_e``,
    ``theta_s``, ``rho_e`` and ``rho_s`` include the current-state consequences ``safe_e``
    (over the inputs) and ``safe_s`` (over inputs and outputs) of the safety formulas (module
    docstring); ``safety_e``/``safety_s`` and ``init_e``/``init_s`` keep each formula's own
    BDD, for diagnosis.

    The transition relations are kept as their conjuncts (``env_parts``, ``sys_parts``): the
    fixpoint only needs the partition (:class:`Schedule`), and the monolithic ``rho_e`` and
    ``rho_s``, which can cost more than the whole fixpoint to build, are conjoined on first
    use (diagnosis, strategies, the monolithic ``cpre``) and kept.
    """

    spec: GR1Spec
    manager: Any
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    theta_e: Any
    theta_s: Any
    env_parts: tuple[Any, ...]
    """Conjuncts of ``rho_e``: the safety assumptions and ``safe_e'``."""
    sys_parts: tuple[Any, ...]
    """Conjuncts of ``rho_s``: the safety guarantees and ``safe_s'``."""
    env_goals: tuple[Goal, ...]
    sys_goals: tuple[Goal, ...]
    safety_e: tuple[tuple[SpecFormula, Any], ...] = field(default=())
    safety_s: tuple[tuple[SpecFormula, Any], ...] = field(default=())
    init_e: tuple[tuple[SpecFormula, Any], ...] = field(default=())
    init_s: tuple[tuple[SpecFormula, Any], ...] = field(default=())
    safe_e: Any = None
    safe_s: Any = None
    semantics: str = "tli"
    heuristics: Heuristics = DEFAULT_HEURISTICS
    env_schedule: Schedule | None = None
    """``~rho_e`` partitioned (:class:`Heuristics` ``partition``); None: monolithic."""
    sys_schedule: Schedule | None = None
    """``rho_s`` partitioned; None: monolithic."""
    relations: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)
    """``rho_e`` and ``rho_s`` once conjoined (:attr:`rho_e`, :attr:`rho_s`)."""

    @property
    def rho_e(self) -> Any:
        """``rho_e(X, Y, X')``: the conjunction of :attr:`env_parts` (built on first use)."""
        return self._relation("rho_e", self.env_parts)

    @property
    def rho_s(self) -> Any:
        """``rho_s(X, Y, X', Y')``: the conjunction of :attr:`sys_parts` (built on first
        use)."""
        return self._relation("rho_s", self.sys_parts)

    def _relation(self, key: str, parts: tuple[Any, ...]) -> Any:
        u = self.relations.get(key)
        if u is None:
            u = self.relations[key] = _conj_bdd(self.manager, parts)
        return u

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
        return self.manager.let(_renaming(self.inputs + self.outputs), u)

    def cpre(self, z: Any) -> Any:
        """Controllable predecessor (Mealy): ``forall X'. rho_e -> exists Y'. rho_s & Z'``.

        With partitioned relations (:class:`Heuristics` ``partition``) this is computed as
        ``forall X'_m. ~rho_e^m | ... forall X'_1. ~rho_e^1 | forall X'_0. S`` with
        ``S = exists Y'_n. rho_s^n & ... exists Y'_1. rho_s^1 & Z'``: each variable is
        quantified right after the last part that mentions it (early quantification, Burch,
        Clarke and Long 1991; Firman, Maoz and Ringert 2020, Sec. 4.2). Same function as
        the monolithic formula; BDDs are canonical, so the same node.
        """
        import dd.cudd

        zp = self.prime(z)
        if self.sys_schedule is None:
            sys_can = dd.cudd.and_exists(self.rho_s, zp, self.outputs_next)
        else:
            sys_can = zp
            for part, names in self.sys_schedule.steps:
                sys_can = dd.cudd.and_exists(part, sys_can, names)
        if self.env_schedule is None:
            return self.manager.forall(self.inputs_next, ~self.rho_e | sys_can)
        out = self.manager.forall(self.env_schedule.first, sys_can)
        for neg_part, names in self.env_schedule.steps:
            out = dd.cudd.or_forall(neg_part, out, names)
        return out

    def with_(self, **changes: Any) -> Game:
        """A copy with some components replaced (same manager). Replacing ``rho_e`` or
        ``rho_s`` makes it that side's only part and drops that side's partition (unless one
        is given)."""
        fields = {name: getattr(self, name) for name in self.__dataclass_fields__}
        relations = dict(self.relations)
        changes = dict(changes)
        for key, parts, schedule in (("rho_e", "env_parts", "env_schedule"),
                                     ("rho_s", "sys_parts", "sys_schedule")):
            if key in changes:
                changes[parts] = (changes[key],)
                changes.setdefault(schedule, None)
                relations[key] = changes.pop(key)
            elif parts in changes:
                relations.pop(key, None)
        fields.update(changes)
        fields["relations"] = relations
        return Game(**fields)

    def conj(self, parts: Iterable[tuple[SpecFormula, Any]]) -> Any:
        u = self.true
        for _, b in parts:
            u &= b
        return u


def build_game(spec: GR1Spec, *, manager: Any = None, semantics: str | None = None,
               heuristics: Heuristics = DEFAULT_HEURISTICS) -> Game:
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
    heuristics : Heuristics
        Variable order, reordering and partitioning of the transition relations (and the
        default of :func:`solve`); none of them changes an answer.
    """
    reading = spec.semantics if semantics is None else semantics
    if reading not in ("tli", "textbook"):
        raise ValueError(f"semantics must be 'tli' or 'textbook', got {reading!r}")

    fresh = manager is None
    bdd = new_manager() if fresh else manager
    names = spec.inputs + spec.outputs
    if heuristics.interleave:
        bdd.declare(*[w for v in names for w in (v, _prime(v))])
    else:
        bdd.declare(*names, *[_prime(v) for v in names])
    if fresh:
        if heuristics.interleave and heuristics.group_pairs and names:
            bdd.group({v: 2 for v in names})
        if heuristics.reorder:
            bdd.configure(max_growth=heuristics.max_growth)
        else:
            bdd.configure(reordering=False)
    memo: dict[tuple[int, bool], tuple[Any, Any]] = {}

    def safety(f: SpecFormula) -> Any:
        """Transition constraint of a conjunction of ``G(phi)``."""
        trans = bdd.true
        for g in _conjuncts(f.ltl):
            trans &= formula_bdd(gr1_body(g, Slot.SAFETY), bdd, primed=False, memo=memo)
        return trans

    init_e = [(f, formula_bdd(f.ltl, bdd, primed=False, memo=memo)) for f in spec.assume.init]
    init_s = [(f, formula_bdd(f.ltl, bdd, primed=False, memo=memo)) for f in spec.guarantee.init]
    safety_e = [(f, safety(f)) for f in spec.assume.safety]
    safety_s = [(f, safety(f)) for f in spec.guarantee.safety]

    def goals(side: Sequence[SpecFormula]) -> tuple[Goal, ...]:
        out = []
        for f in side:
            for g in _conjuncts(f.ltl):
                out.append(Goal(formula=f, bdd=formula_bdd(gr1_body(g, Slot.LIVENESS), bdd,
                                                       primed=False, memo=memo)))
        return tuple(out)

    inputs, outputs = list(spec.inputs), list(spec.outputs)
    inputs_next = [_prime(v) for v in inputs]
    outputs_next = [_prime(v) for v in outputs]
    rename = {v: _prime(v) for v in inputs + outputs}
    if reading == "textbook":
        safe_e = safe_s = bdd.true
    else:
        safe_e = safety_closure(bdd, _conj_bdd(bdd, [b for _, b in safety_e]),
                                {v: _prime(v) for v in inputs}, outputs + inputs_next)
        safe_s = safety_closure(bdd, _conj_bdd(bdd, [b for _, b in safety_s]), rename,
                                inputs_next + outputs_next)
    parts_e = tuple(b for b in [*(b for _, b in safety_e), bdd.let(rename, safe_e)]
                    if b != bdd.true)
    parts_s = tuple(b for b in [*(b for _, b in safety_s), bdd.let(rename, safe_s)]
                    if b != bdd.true)
    env_schedule = sys_schedule = None
    if heuristics.partition:
        env_schedule = _schedule(bdd, parts_e, inputs_next, heuristics.cluster_nodes,
                                 negate=True)
        sys_schedule = _schedule(bdd, parts_s, outputs_next, heuristics.cluster_nodes,
                                 negate=False)
    return Game(
        spec=spec,
        manager=bdd,
        inputs=spec.inputs,
        outputs=spec.outputs,
        theta_e=_conj_bdd(bdd, [b for _, b in init_e]) & safe_e,
        theta_s=_conj_bdd(bdd, [b for _, b in init_s]) & safe_s,
        env_parts=parts_e,
        sys_parts=parts_s,
        env_goals=goals(spec.assume.liveness),
        sys_goals=goals(spec.guarantee.liveness),
        safety_e=tuple(safety_e),
        safety_s=tuple(safety_s),
        init_e=tuple(init_e),
        init_s=tuple(init_s),
        safe_e=safe_e,
        safe_s=safe_s,
        semantics=reading,
        heuristics=heuristics,
        env_schedule=env_schedule,
        sys_schedule=sys_schedule,
    )


def _clusters(bdd: Any, parts: Sequence[Any], max_nodes: int) -> list[Any]:
    """Merge consecutive ``parts`` while their conjunction stays within ``max_nodes``."""
    out: list[Any] = []
    current = bdd.true
    for b in parts:
        if b == bdd.true:
            continue
        merged = current & b
        if current != bdd.true and merged.dag_size > max_nodes:
            out.append(current)
            current = b
        else:
            current = merged
    if current != bdd.true or not out:
        out.append(current)
    return out


def _schedule(bdd: Any, parts: Sequence[Any], quantified: Sequence[str], max_nodes: int, *,
              negate: bool) -> Schedule:
    """The early-quantification schedule of a conjunction of ``parts`` for ``quantified``
    (:meth:`Game.cpre`): clusters in order, each with the variables of ``quantified`` that
    it mentions and no later cluster does. The system side (``negate`` false) quantifies
    the variables no cluster mentions with the first cluster (``Z'`` comes first in the
    chain); the environment side (``negate``: the parts are stored negated, for
    ``or_forall``) quantifies them first, in :attr:`Schedule.first`."""
    clusters = _clusters(bdd, parts, max_nodes)
    wanted = set(quantified)
    supports = [bdd.support(c) & wanted for c in clusters]
    later: set[str] = set()
    names: list[tuple[str, ...]] = [()] * len(clusters)
    for k in range(len(clusters) - 1, -1, -1):
        names[k] = tuple(sorted(supports[k] - later))
        later |= supports[k]
    rest = tuple(sorted(wanted - later))
    if negate:
        return Schedule(steps=tuple((~c, n) for c, n in zip(clusters, names, strict=True)),
                        first=rest)
    names[0] = tuple(sorted(set(names[0]) | set(rest)))
    return Schedule(steps=tuple(zip(clusters, names, strict=True)))


MANAGER_MEMORY = 2**26
"""Bytes a fresh CUDD manager is sized for at creation (:func:`new_manager`)."""
MANAGER_CACHE = 2**14
"""Initial slots of a fresh manager's computed table (CUDD grows it while it pays)."""


def new_manager() -> Any:
    """A fresh ``dd.cudd.BDD`` manager, cheap to create and free to grow.

    ``dd.cudd.BDD()`` sizes the manager for 1 GiB with a computed table of 2^18 slots,
    which costs 70-80 ms to allocate and free: most of the fixed cost of a small spec.
    CUDD grows its unique and computed tables on demand (the computed table while its hit
    rate pays, up to ``max_cache_hard``), so a manager sized for :data:`MANAGER_MEMORY`
    with :data:`MANAGER_CACHE` slots, with the loose growth limit ``loose_up_to`` of the
    1 GiB default restored, solves large games as fast and starts in well under 1 ms.
    """
    import dd.cudd

    bdd = dd.cudd.BDD(memory_estimate=MANAGER_MEMORY, initial_cache_size=MANAGER_CACHE)
    bdd.configure(loose_up_to=dd.cudd.DEFAULT_MEMORY // 32 // 5)  # CUDD's default rule
    return bdd


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
    from tli_verify.logic.spot_import import spot

    if f.kind() == spot.op_And:
        out = []
        for c in f:
            out += _conjuncts(c)
        return out
    return [f]


def _has_next(f: Any) -> bool:
    from tli_verify.logic.spot_import import spot

    if f.kind() == spot.op_X:
        return True
    return any(_has_next(c) for c in f)


def _aps(f: Any) -> set[str]:
    from tli_verify.logic.spot_import import spot

    return {str(a.ap_name()) for a in spot.atomic_prop_collect(f)}


def formula_bdd(f: Any, bdd: Any, *, primed: bool,
            memo: dict[tuple[int, bool], tuple[Any, Any]] | None = None) -> Any:
    """BDD of a propositional formula with ``X`` at depth <= 1 (``X v`` -> ``v'``).

    ``memo`` ((Spot's formula id, primed) -> the BDD and the formula, kept alive so that the
    id stays its own) may be shared by the formulas of one game: Spot shares equal
    sub-formulas, so each is translated once."""
    if memo is None:
        return _to_bdd_memo(f, bdd, primed, {})
    return _to_bdd_memo(f, bdd, primed, memo)


def _to_bdd_memo(f: Any, bdd: Any, primed: bool,
                 memo: dict[tuple[int, bool], tuple[Any, Any]]) -> Any:
    key = (f.id(), primed)
    hit = memo.get(key)
    if hit is not None:
        return hit[0]
    u = _to_bdd_node(f, bdd, primed, memo)
    memo[key] = (u, f)
    return u


def _to_bdd_node(f: Any, bdd: Any, primed: bool,
                 memo: dict[tuple[int, bool], tuple[Any, Any]]) -> Any:
    from tli_verify.logic.spot_import import spot

    kind = f.kind()
    if kind == spot.op_tt:
        return bdd.true
    if kind == spot.op_ff:
        return bdd.false
    if kind == spot.op_ap:
        name = str(f.ap_name())
        return bdd.var(_prime(name) if primed else name)
    if kind == spot.op_X:
        return _to_bdd_memo(f[0], bdd, True, memo)
    args = [_to_bdd_memo(c, bdd, primed, memo) for c in f]
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
        ``Z``, the system's winning states (when ``exact``; else a superset of them).
    realizable : bool
        ``forall X. theta_e -> exists Y. theta_s & Z``.
    rings : tuple of tuple of BDD
        ``rings[j][r]`` is ``Y^j_{r+1}``, the states that reach goal ``j`` in at most ``r+1``
        rounds (the mu-iterates of the last outer iteration).
    traps : tuple of tuple of tuple of BDD
        ``traps[j][r][i]`` is ``X^j_{r+1,i}``: states that stay until goal ``j`` or a lower ring
        is forced, while environment goal ``i`` is never met.
    exact : bool
        False when early unrealizability detection stopped the fixpoint (``solve(...,
        exact=False)``): the verdict is exact, ``winning`` only contains the winning set and
        the iterates are empty.
    """

    game: Game
    winning: Any
    realizable: bool
    rings: tuple[tuple[Any, ...], ...]
    traps: tuple[tuple[tuple[Any, ...], ...], ...]
    exact: bool = True

    def rank(self, j: int, state: Any) -> tuple[int, int] | None:
        """Lexicographically least ``(r, i)`` with ``state`` (a cube) in ``traps[j][r][i]``."""
        for r, ring in enumerate(self.traps[j]):
            for i, trap in enumerate(ring):
                if (trap & state) != self.game.false:
                    return (r, i)
        return None


def _goals_or_true(game: Game, goals: tuple[Goal, ...]) -> list[Any]:
    return [g.bdd for g in goals] or [game.true]


def _nu_trap(game: Game, unless: Any, not_goal: Any, start: Any) -> Any:
    """``nu X. unless | (!J_e^i & cpre(X))``, iterated down from ``start`` (``true``, or with
    fixed-point recycling an upper bound of the result that the step does not enlarge).

    Without environment goals ``J_e`` is ``true`` and the fixed point is ``unless`` itself,
    returned without computing a ``cpre``."""
    if not_goal == game.false:
        return unless
    x = start
    while True:
        new = unless | (not_goal & game.cpre(x))
        if new == x:
            return x
        x = new


def _init_ok(game: Game, z: Any) -> bool:
    """``forall X. theta_e -> exists Y. theta_s & z`` (the realizability test on ``z``)."""
    bdd = game.manager
    ok = bdd.forall(list(game.inputs),
                    ~game.theta_e | bdd.exist(list(game.outputs), game.theta_s & z))
    return bool(ok == bdd.true)


def solve(game: Game, *, keep_iterates: bool = True, exact: bool = True,
          heuristics: Heuristics | None = None) -> Solution:
    """Solve the GR(1) game by the 3-nested fixpoint (Bloem et al. 2012, Sec. 3).

    Parameters
    ----------
    game : Game
    keep_iterates : bool
        Keep the rings and traps of the final outer iteration (needed for strategies).
    exact : bool
        Compute the exact winning set. False lets early unrealizability detection stop as
        soon as the verdict is known (:attr:`Solution.exact`).
    heuristics : Heuristics, optional
        The fixpoint heuristics to use (default: the game's); see :class:`Heuristics`. The
        partitioning and the variable order are the game's (:func:`build_game`).

    Returns
    -------
    Solution
        The same verdict, winning set and iterates for every choice of heuristics.

    Notes
    -----
    Goals are processed in rounds ``j = 0, 1, ..., n-1, 0, 1, ...`` with ``Z`` narrowed after
    each (``Z &= Y^j``, Gauss-Seidel); every iterate contains the greatest fixed point, and
    a ``Z`` that ``n`` consecutive goals leave unchanged is a post-fixed point, hence the
    greatest one. The heuristics of Firman, Maoz and Ringert (2020) rely on ``Z`` only
    shrinking: the ``Y``, rings and traps of goal ``j`` computed from a smaller ``Z`` are
    subsets of the previous ones, ring by ring.

    References
    ----------
    R. Bloem, B. Jobstmann, N. Piterman, A. Pnueli and Y. Sa'ar, "Synthesis of Reactive(1)
    designs", JCSS 78(3), 2012. E. Firman, S. Maoz and J. O. Ringert, "Performance
    heuristics for GR(1) synthesis and related algorithms", Acta Informatica 57, 2020.
    """
    h = game.heuristics if heuristics is None else heuristics
    not_env = [~g for g in _goals_or_true(game, game.env_goals)]
    sys_goals = _goals_or_true(game, game.sys_goals)
    n = len(sys_goals)
    z = game.true
    rings: list[tuple[Any, ...]] = [()] * n
    traps: list[tuple[tuple[Any, ...], ...]] = [()] * n
    last_y: list[Any] = [None] * n  # Y^j of the previous computation of goal j
    last_x: list[list[tuple[Any, ...]]] = [[] for _ in range(n)]  # its X layers, by ring
    unchanged = 0  # consecutive goal computations that left z as it was
    j = 0
    pass_start = z
    while True:
        goal = sys_goals[j]
        target = goal & game.cpre(z)
        y = game.false
        ring_list: list[Any] = []
        trap_list: list[tuple[Any, ...]] = []
        layers: list[tuple[Any, ...]] = []
        old_x = last_x[j] if h.recycle else []
        while True:
            unless = target | game.cpre(y)
            r = len(layers)
            layer = tuple(
                _nu_trap(game, unless, ne,
                         old_x[r][i] if r < len(old_x) else game.true)
                for i, ne in enumerate(not_env))
            layers.append(layer)
            y_new = game.false
            for x in layer:
                y_new |= x
            if y_new == y:
                break
            y = y_new
            ring_list.append(y)
            trap_list.append(layer)
            if h.early_fixpoint and last_y[j] is not None and y == last_y[j]:
                break  # y <= Y^j(new z) <= Y^j(old z) = y
        last_y[j] = y
        last_x[j] = layers
        rings[j] = tuple(ring_list)
        traps[j] = tuple(trap_list)
        z_next = z & y
        if z_next == z:
            unchanged += 1
        else:
            unchanged = 0
            z = z_next
            if not exact and h.early_unrealizable and not _init_ok(game, z):
                return Solution(game=game, winning=z, realizable=False, rings=(), traps=(),
                                exact=False)
        j = (j + 1) % n
        if h.early_fixpoint:
            if unchanged >= n:
                break
        elif j == 0:
            if z == pass_start:
                break
            pass_start = z
            unchanged = 0
    realizable = _init_ok(game, z)
    if not keep_iterates:
        rings, traps = [], []
    return Solution(game=game, winning=z, realizable=realizable, rings=tuple(rings),
                    traps=tuple(traps))


def disjoint_cubes(bdd: Any, u: Any, names: list[str],
                   budget: int) -> list[dict[str, bool]] | None:
    """Disjoint cubes covering ``u`` (Shannon expansion in ``names`` order, False first);
    None if there are more than ``budget``. ``names`` must hold ``u``'s support."""
    out: list[dict[str, bool]] = []
    stack: list[tuple[Any, dict[str, bool], int]] = [(u, {}, 0)]
    while stack:
        w, fixed, k = stack.pop()
        if w == bdd.false:
            continue
        if w == bdd.true:
            out.append(fixed)
            if len(out) > budget:
                return None
            continue
        supp = bdd.support(w)
        while names[k] not in supp:
            k += 1
        v = names[k]
        stack.append((bdd.let({v: True}, w), {**fixed, v: True}, k + 1))
        stack.append((bdd.let({v: False}, w), {**fixed, v: False}, k + 1))
    return out


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
