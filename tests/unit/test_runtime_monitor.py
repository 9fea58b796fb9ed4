"""The assumption monitor never crashes and reports every reading the assumptions rule out."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.integration.test_executive import _project
from tli_verify.logic.automaton import AssumptionViolation
from tli_verify.runtime.events import AssumptionViolationEvent, CutAdded, InvarianceFailure
from tli_verify.runtime.executive import LTLDSPolicy


@pytest.fixture(scope="module")
def chain(tmp_path_factory: pytest.TempPathFactory) -> LTLDSPolicy:
    aut, model, cert = _project(Path(tmp_path_factory.mktemp("chain")), [1.0, 3.0])
    return LTLDSPolicy(aut, model, cert)


READING = st.sets(st.sampled_from(["u", "v"]))
STATE = st.tuples(st.floats(-5, 8), st.floats(-4, 5))


@settings(max_examples=60)
@given(steps=st.lists(st.tuples(STATE, READING, st.booleans()), min_size=1, max_size=25))
def test_random_readings_never_crash_and_every_violation_is_reported(
        chain: LTLDSPolicy, steps: list[tuple[tuple[float, float], set[str], bool]]) -> None:
    pol = chain.fork()
    aut = pol.automaton
    pol.reset(np.array([-3.0, 4.0]), set())
    expected = 0
    for x, reading, pushed in steps:
        before = pol.state
        assert before is not None
        try:
            aut.next_mode(before, reading)
        except AssumptionViolation:
            expected += 1
        v = pol.step(np.array(x), reading, perturbed=pushed)
        assert v.shape == (2,) and np.all(np.isfinite(v))
        if pol.holding:
            assert np.array_equal(v, np.zeros(2))
        else:  # the state run is one entered with this reading
            assert frozenset(aut.states[pol.state].inputs) == frozenset(reading)
    reported = [e for e in pol.events if isinstance(e, AssumptionViolationEvent)]
    assert len(reported) == expected
    # an exit across a violation or after a push never produces a cut
    fails = [e for e in pol.events if isinstance(e, InvarianceFailure)]
    assert len([e for e in pol.events if isinstance(e, CutAdded)]) <= len(fails)
