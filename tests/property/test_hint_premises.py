"""Every diagnosis claim and hint holds in the game, checked by the explicit-state game.

The BDD diagnosis states facts about the game: the witness is a play, the final sensor change
is legal and leaves the system no legal move, a lasso is fair and avoids the goal. The hint
"add ``G(cur -> X !nxt)``" has a premise: some *other* legal sensor change from the same state
leaves the system a legal move (otherwise the state itself is lost and no assumption about
this change helps; following such a hint only yields the opposite hint). All of it is
re-checked on :class:`tests.support.explicit_games.ExplicitGame`, which enumerates moves and
evaluates formulas without BDDs, with safety applied at every position, the first included.
"""

from __future__ import annotations

import itertools

from hypothesis import given, settings
from hypothesis import strategies as st

from tests.support.explicit_games import ExplicitGame, State
from tests.support.ltl_eval import body, conjuncts
from tli_verify.logic.check import check_spec
from tli_verify.logic.diagnose import Diagnosis, Step
from tli_verify.logic.generate import RandomSpecConfig, random_spec
from tli_verify.logic.spec import GR1Spec, parse_spec


def _state(game: ExplicitGame, step: Step) -> State:
    return tuple(v in step.inputs or v in step.outputs for v in game.names)


def _reading(game: ExplicitGame, true: tuple[str, ...]) -> tuple[bool, ...]:
    return tuple(v in true for v in game.spec.inputs)


def _legal_step(game: ExplicitGame, s: State, t: State) -> bool:
    nx = len(game.spec.inputs)
    return game.env_step(game.val(s), t[:nx]) and game.sys_step(game.val(s), t)


def check_premises(spec: GR1Spec, d: Diagnosis) -> None:
    """Assert every claim of ``d`` on the explicit game of ``spec``."""
    game = ExplicitGame(spec)
    nx = len(spec.inputs)
    states = [_state(game, s) for s in d.witness]
    if d.kind == "initial":
        x0 = _reading(game, d.witness[0].inputs)
        assert game.env_initial(x0)
        assert not any(game.sys_initial(x0 + y) for y in game.ys)
        assert d.hint is None
        return
    if states:
        assert game.env_initial(states[0][:nx]) and game.sys_initial(states[0])
        for s, t in itertools.pairwise(states):
            assert _legal_step(game, s, t), (s, t)
    if d.kind == "safety":
        assert d.final_inputs is not None
        last = game.val(states[-1])
        final = _reading(game, d.final_inputs)
        assert game.env_step(last, final)
        assert not any(game.sys_step(last, final + y) for y in game.ys)
        survivable = any(game.env_step(last, x) and any(game.sys_step(last, x + y)
                                                        for y in game.ys) for x in game.xs)
        assert (d.hint is not None) == survivable, d.hint
    elif d.kind == "liveness" and d.loop_start is not None:
        cycle = states[d.loop_start:]
        assert _legal_step(game, states[-1], states[d.loop_start])
        formula = next(f for f in spec.guarantee.liveness
                       if any(f.text in at for at in d.formulas))
        goals = [body(g) for g in conjuncts(formula.ltl)]
        assert not all(any(game.sat(g, s) for s in cycle) for g in goals)
        for g in game.env_goals:
            assert any(game.sat(g, s) for s in cycle)
        assert d.hint is not None


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 10**6), n_in=st.integers(1, 3), n_out=st.integers(1, 3),
       n_env_safety=st.integers(0, 3), n_sys_safety=st.integers(1, 4))
def test_random_diagnoses_hold_in_the_game(seed: int, n_in: int, n_out: int,
                                           n_env_safety: int, n_sys_safety: int) -> None:
    config = RandomSpecConfig(n_inputs=n_in, n_outputs=n_out, n_env_safety=n_env_safety,
                              n_sys_safety=n_sys_safety, n_env_live=1, n_sys_live=1)
    result = check_spec(random_spec(config, seed))
    if result.diagnosis is not None:
        check_premises(result.spec, result.diagnosis)


def _spec(body_text: str) -> GR1Spec:
    return parse_spec('inputs = ["r"]\noutputs = ["a"]\n' + body_text, path="t.toml")


def test_issue_initial_condition_against_time_zero_safety() -> None:
    """``init = "a"`` with ``G(!a)``: an initial failure naming both, no absurd hint."""
    d = check_spec(_spec('[guarantee]\ninit = "a"\nsafety = ["G(!a)"]')).diagnosis
    assert d is not None and d.kind == "initial" and d.hint is None
    assert any("guarantee.init[0]" in f for f in d.formulas)
    assert any("guarantee.safety[0]: G(!a)" in f for f in d.formulas)
    check_premises(_spec('[guarantee]\ninit = "a"\nsafety = ["G(!a)"]'), d)


def test_hint_is_withheld_when_every_sensor_change_loses() -> None:
    """A state lost whatever the sensors do gets no sensor-change hint (the premise fails)."""
    spec = _spec('[assume]\nsafety = ["G(X !r)"]\n[guarantee]\ninit = "a"\n'
                 'safety = ["G(a -> X r)"]')
    d = check_spec(spec).diagnosis
    assert d is not None and d.kind == "safety" and d.hint is None
    check_premises(spec, d)


def test_hint_is_given_when_its_premise_holds() -> None:
    """The sensors may jump to r; from there the system has no move, but staying is fine."""
    spec = _spec('[guarantee]\ninit = "a"\nsafety = ["G(a -> X a)", "G(X r -> X !a)"]')
    d = check_spec(spec).diagnosis
    assert d is not None and d.kind == "safety" and d.hint is not None
    assert "X !(r)" in d.hint
    check_premises(spec, d)
