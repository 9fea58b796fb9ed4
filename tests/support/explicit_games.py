"""Explicit-state game solving for small specs: an independent check of our BDD fixpoints.

States are full assignments of inputs and outputs; moves are enumerated and every formula is
evaluated by :mod:`tests.support.ltl_eval` (no BDDs involved).

Safety at every position, the first included: ``G(phi)`` holds at every position ``i >= 0``.
A sensor reading from which no sequence (with any outputs) keeps the safety assumptions is
never a legal reading, initial or next; a state from which no sequence keeps the safety
guarantees is never a legal system state, initial or next (the reading of
docs/explanation/logic.md, computed here by explicit greatest fixpoints).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable

from tests.support.ltl_eval import body, conjuncts, holds
from tli_verify.logic.ltl import atomic_propositions
from tli_verify.logic.spec import GR1Spec

State = tuple[bool, ...]


def safe_readings(spec: GR1Spec) -> set[tuple[bool, ...]]:
    """Readings (tuples over ``spec.inputs``) from which the safety assumptions can hold
    forever for some outputs: an explicit greatest fixpoint. Only the outputs the assumptions
    mention are enumerated (the others cannot matter)."""
    rho_e = [body(g) for f in spec.assume.safety for g in conjuncts(f.ltl)]
    used = sorted({a for f in rho_e for a in atomic_propositions(f)} & set(spec.outputs))
    xs = list(itertools.product([False, True], repeat=len(spec.inputs)))
    ys = list(itertools.product([False, True], repeat=len(used)))
    safe = set(xs)
    while True:
        new = set()
        for x in safe:
            v = dict(zip(spec.inputs, x, strict=True))
            for y in ys:
                cur = {**v, **dict(zip(used, y, strict=True))}
                if any(all(holds(f, cur, {**cur, **dict(zip(spec.inputs, xn, strict=True))})
                           for f in rho_e) for xn in safe):
                    new.add(x)
                    break
        if new == safe:
            return safe
        safe = new


class ExplicitGame:
    """The explicit game graph of a spec (Mealy: environment moves, then the system)."""

    def __init__(self, spec: GR1Spec) -> None:
        self.spec = spec
        self.names = spec.inputs + spec.outputs
        nx = len(spec.inputs)
        self.states: list[State] = list(itertools.product([False, True], repeat=len(self.names)))
        self.xs = list(itertools.product([False, True], repeat=nx))
        self.ys = list(itertools.product([False, True], repeat=len(spec.outputs)))

        def gbodies(side: Iterable) -> list:  # type: ignore[type-arg]
            return [body(g) for f in side for g in conjuncts(f.ltl)]

        self.rho_e = gbodies(spec.assume.safety)
        self.rho_s = gbodies(spec.guarantee.safety)
        self.env_goals = gbodies(spec.assume.liveness)
        self.sys_goals = gbodies(spec.guarantee.liveness)
        self.safe_e = self._safe_inputs()
        self.safe_s = self._safe_states()
        # moves[s] = list of (env-legal x', [system-legal successor states])
        self.moves: dict[State, list[tuple[State, list[State]]]] = {}
        for s in self.states:
            cur = self.val(s)
            out = []
            for x in self.xs:
                if not self.env_step(cur, x):
                    continue
                replies = [x + y for y in self.ys if self.sys_step(cur, x + y)]
                out.append((x, replies))
            self.moves[s] = out

    def env_step(self, cur: dict[str, bool], x: tuple[bool, ...]) -> bool:
        """The next reading ``x`` is legal for the environment from ``cur``."""
        nxt_in = dict(zip(self.spec.inputs, x, strict=True))
        return x in self.safe_e and all(holds(f, cur, {**cur, **nxt_in}) for f in self.rho_e)

    def sys_step(self, cur: dict[str, bool], t: State) -> bool:
        """The next state ``t`` keeps the safety guarantees (the reading already chosen)."""
        return t in self.safe_s and all(holds(f, cur, self.val(t)) for f in self.rho_s)

    def _safe_inputs(self) -> set[tuple[bool, ...]]:
        return safe_readings(self.spec)

    def _safe_states(self) -> set[State]:
        """States from which the safety guarantees can hold forever."""
        safe = set(self.states)
        while True:
            new = {s for s in safe
                   if any(all(holds(f, self.val(s), self.val(t)) for f in self.rho_s)
                          for t in safe)}
            if new == safe:
                return safe
            safe = new

    def env_initial(self, x: tuple[bool, ...]) -> bool:
        """``x`` is an initial reading the assumptions allow (time 0 included)."""
        v = dict(zip(self.spec.inputs, x, strict=True))
        return x in self.safe_e and all(holds(f.ltl, v) for f in self.spec.assume.init)

    def sys_initial(self, s: State) -> bool:
        """``s`` is an initial state the guarantees allow (time 0 included)."""
        return s in self.safe_s and all(holds(f.ltl, self.val(s))
                                        for f in self.spec.guarantee.init)

    def val(self, s: State) -> dict[str, bool]:
        return dict(zip(self.names, s, strict=True))

    def sat(self, f: object, s: State) -> bool:
        return holds(f, self.val(s))

    def epre(self, z: set[State]) -> set[State]:
        """Environment forces ``z``: some legal x' after which every legal reply is in z."""
        return {s for s in self.states
                if any(all(t in z for t in replies) for _, replies in self.moves[s])}

    def env_buchi(self, goals: list) -> set[State]:  # type: ignore[type-arg]
        """nu Z. /\\_i mu Y. (J_i & epre(Z)) | epre(Y)."""
        goals = goals or [None]
        z = set(self.states)
        while True:
            z_old = set(z)
            for g in goals:
                ez = self.epre(z)
                target = {s for s in ez if g is None or self.sat(g, s)}
                y: set[State] = set()
                while True:
                    y_new = target | self.epre(y)
                    if y_new == y:
                        break
                    y = y_new
                z &= y
            if z == z_old:
                return z

    def well_separated(self) -> bool:
        """The assumptions' initial condition is satisfiable, and every initial state allowed
        by both initial conditions is environment-winning."""
        win = self.env_buchi(self.env_goals)
        nx = len(self.spec.inputs)
        if not any(self.env_initial(x) for x in self.xs):
            return False
        for s in self.states:
            if self.env_initial(s[:nx]) and self.sys_initial(s) and s not in win:
                return False
        return True
