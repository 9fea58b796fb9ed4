"""Explicit-state game solving for small specs: an independent check of our BDD fixpoints.

States are full assignments of inputs and outputs; moves are enumerated and every formula is
evaluated by :mod:`tests.support.ltl_eval` (no BDDs involved).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable

from tests.support.ltl_eval import body, conjuncts, holds
from tli_verify.logic.spec import GR1Spec

State = tuple[bool, ...]


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
        # moves[s] = list of (env-legal x', [system-legal successor states])
        self.moves: dict[State, list[tuple[State, list[State]]]] = {}
        for s in self.states:
            cur = self.val(s)
            out = []
            for x in self.xs:
                nxt_in = dict(zip(spec.inputs, x, strict=True))
                if not all(holds(f, cur, {**cur, **nxt_in}) for f in self.rho_e):
                    continue
                replies = []
                for y in self.ys:
                    t = x + y
                    if all(holds(f, cur, self.val(t)) for f in self.rho_s):
                        replies.append(t)
                out.append((x, replies))
            self.moves[s] = out

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
        theta_e = [f.ltl for f in self.spec.assume.init]
        theta_s = [f.ltl for f in self.spec.guarantee.init]
        if not any(all(holds(f, self.val(s)) for f in theta_e) for s in self.states):
            return False
        for s in self.states:
            v = self.val(s)
            if all(holds(f, v) for f in theta_e) and all(holds(f, v) for f in theta_s) \
                    and s not in win:
                return False
        return True
