"""Every extracted strategy is checked against its spec, with an explicit evaluator.

Theorem checked: for a realizable GR(1) spec the task automaton is a winning Mealy
strategy: (1) for every initial sensor reading allowed by ``theta_e`` (and by the safety
assumptions at time 0) there is an initial state satisfying ``theta_s``, and every state
satisfies the ``X``-free safety guarantees (time 0 included); (2) from every state, every
sensor reading allowed by ``rho_e`` has a transition, and the move satisfies ``rho_s``;
(3) every cycle of the automaton that visits every environment goal (the ones the
environment's liveness allows forever) visits every system goal. Readings from which the
safety assumptions cannot hold forever are not allowed (docs/explanation/logic.md, "From
spec to automaton"); they are computed explicitly by
:func:`tests.support.explicit_games.safe_readings`.
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from tests.support.explicit_games import safe_readings
from tests.support.ltl_eval import body, conjuncts, holds
from tli_verify.logic.automaton import TaskAutomaton, Transition
from tli_verify.logic.check import check_spec, synthesize
from tli_verify.logic.generate import RandomSpecConfig, random_spec, random_spec_text
from tli_verify.logic.spec import GR1Spec, load_spec, parse_spec


def _assignment(names: tuple[str, ...], true: tuple[str, ...] | frozenset[str]
                ) -> dict[str, bool]:
    return {n: n in true for n in names}


def _all(side: tuple, cur: dict, nxt: dict | None = None) -> bool:  # type: ignore[type-arg]
    """All G(phi) formulas of ``side`` hold on the step (cur, nxt)."""
    return all(holds(body(g), cur, nxt) for f in side for g in conjuncts(f.ltl))


def _init(side: tuple, cur: dict) -> bool:  # type: ignore[type-arg]
    """All initial formulas of ``side`` hold in ``cur``."""
    return all(holds(f.ltl, cur) for f in side)


def verify_strategy(spec: GR1Spec, aut: TaskAutomaton) -> list[int]:
    """Assert the three conditions of the module docstring.

    Returns the ids of dead-end states: states where no sensor reading is legal (the system's
    outputs left the environment no legal move).
    """
    X, Y = spec.inputs, spec.outputs
    free = frozenset(aut.free_inputs)
    safe = safe_readings(spec)
    val = [{**_assignment(X, s.inputs), **_assignment(Y, s.outputs)} for s in aut.states]

    def completions(v: dict[str, bool]) -> list[dict[str, bool]]:
        """A state stands for every value of the inputs it does not record."""
        names = sorted(free)
        return [{**v, **dict(zip(names, bits, strict=True))}
                for bits in itertools.product([False, True], repeat=len(names))]

    # (1) initial states, and the X-free guarantees in every state
    init_inputs = {frozenset(aut.states[i].inputs) for i in aut.initial}
    for bits in itertools.product([False, True], repeat=len(X)):
        x = dict(zip(X, bits, strict=True))
        key = frozenset(k for k, v in x.items() if v) - free
        if _init(spec.assume.init, x) and bits in safe:
            assert key in init_inputs
        elif bits not in safe:  # safe_e is read by the strategy: it has no free input
            assert key not in init_inputs
    for i in aut.initial:
        assert all(_init(spec.guarantee.init, v) for v in completions(val[i]))
    state_only = [body(g) for f in spec.guarantee.safety for g in conjuncts(f.ltl)
                  if body(g).is_boolean()]
    for v in val:
        assert all(holds(f, c) for f in state_only for c in completions(v))
    # (2) every allowed reading has a move, and the move is legal
    out_edges: dict[int, list[Transition]] = {}
    for t in aut.transitions:
        out_edges.setdefault(t.source, []).append(t)
    dead = []
    for s in aut.states:
        n_allowed = 0
        for cur in completions(val[s.id]):
            for bits in itertools.product([False, True], repeat=len(X)):
                xn = dict(zip(X, bits, strict=True))
                key = frozenset(k for k, v in xn.items() if v)
                hits = [t.target for t in out_edges.get(s.id, []) if t.matches(key)]
                assert len(hits) <= 1, (s, key, hits)  # the cubes of a state are disjoint
                allowed = bits in safe and _all(spec.assume.safety, cur, {**cur, **xn})
                n_allowed += allowed
                if not allowed:
                    assert not hits, (s, key)
                    continue
                assert hits, (s, key)
                target = aut.states[hits[0]]
                assert frozenset(target.inputs) == key - free  # the state records the reading
                nxt = {**xn, **_assignment(Y, target.outputs)}
                assert _all(spec.guarantee.safety, cur, nxt)
        if not n_allowed:
            dead.append(s.id)
    # (3) no fair cycle avoids a system goal
    env_goals = [body(g) for f in spec.assume.liveness for g in conjuncts(f.ltl)]
    sys_goals = [body(g) for f in spec.guarantee.liveness for g in conjuncts(f.ltl)]
    n = len(aut.states)
    for goal in sys_goals:
        keep = np.array([not holds(goal, v) for v in val], dtype=bool)
        rows = [t.source for t in aut.transitions if keep[t.source] and keep[t.target]]
        cols = [t.target for t in aut.transitions if keep[t.source] and keep[t.target]]
        graph = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
        _, labels = connected_components(graph, directed=True, connection="strong")
        for comp in set(labels[keep]):
            members = [i for i in range(n) if keep[i] and labels[i] == comp]
            internal = [(a, b) for a, b in zip(rows, cols, strict=True)
                        if labels[a] == comp and labels[b] == comp]
            if not internal:
                continue
            fair = all(any(holds(g, val[i]) for i in members) for g in env_goals)
            assert not fair, f"fair cycle avoiding {goal} through states {members}"
    return dead


@pytest.mark.parametrize("name", ["scoop", "inspection", "cooking-cb", "cooking-bc",
                                  "cooking-c", "cooking-cc", "color-tracing-a",
                                  "color-tracing-b", "color-tracing-c"])
def test_shipped_strategies_win(specs_dir: Path, name: str) -> None:
    spec = load_spec(specs_dir / f"{name}.toml")
    # No dead ends (e.g. inspection reached them only by readings breaking
    # G(rel -> line), which the environment may not pick).
    assert verify_strategy(spec, synthesize(spec)) == []


@settings(max_examples=60)
@given(seed=st.integers(0, 10**6), n_in=st.integers(1, 3), n_out=st.integers(1, 3),
       n_env_live=st.integers(0, 2), n_sys_live=st.integers(0, 3))
def test_random_strategies_win(seed: int, n_in: int, n_out: int, n_env_live: int,
                               n_sys_live: int) -> None:
    config = RandomSpecConfig(n_inputs=n_in, n_outputs=n_out, n_env_live=n_env_live,
                              n_sys_live=n_sys_live, n_env_safety=1, n_sys_safety=2)
    spec = random_spec(config, seed)
    if check_spec(spec).realizable:
        verify_strategy(spec, synthesize(spec))


def test_checker_catches_a_wrong_strategy(specs_dir: Path) -> None:
    """The checker can fail: redirect one scoop transition to a forbidden mode."""
    spec = load_spec(specs_dir / "scoop.toml")
    aut = synthesize(spec)
    data = aut.to_dict()
    d_state = next(s["id"] for s in data["states"] if s["mode"] == "d")
    a_state = next(t for t in data["transitions"] if aut.states[t["from"]].mode == "a"
                   and t["sensors"] == [])
    a_state["to"] = d_state  # a -> d is not a valid mode transition
    with pytest.raises(AssertionError):
        verify_strategy(spec, TaskAutomaton.from_dict(data))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10**6), n_free=st.integers(1, 3))
def test_unread_inputs_change_nothing_but_the_cubes(seed: int, n_free: int) -> None:
    """Adding inputs no formula mentions keeps the states and stays a winning strategy, now
    over readings of the extra inputs as well (checked valuation by valuation)."""
    config = RandomSpecConfig(n_inputs=2, n_outputs=2, n_env_safety=1, n_sys_safety=2)
    text = random_spec_text(config, seed)
    spec = parse_spec(text)
    if not check_spec(spec).realizable:
        return
    extra = ", ".join(f'"free{i}"' for i in range(n_free))
    wide = parse_spec(re.sub(r"^inputs = \[(.*)\]$", lambda m: f"inputs = [{m[1]}, {extra}]",
                             text, count=1, flags=re.M))
    assert len(wide.inputs) == len(spec.inputs) + n_free
    narrow_aut, wide_aut = synthesize(spec), synthesize(wide)
    assert len(wide_aut.states) == len(narrow_aut.states)
    assert wide_aut.mode_transitions() == narrow_aut.mode_transitions()
    assert set(wide_aut.free_inputs) >= {f"free{i}" for i in range(n_free)}
    verify_strategy(wide, wide_aut)
