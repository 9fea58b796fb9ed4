"""The bisimulation oracle on forged traces: each violation kind is caught by its check, and only
by it (paper Sec. 4.4, Thm. 2: invariance, reachability, automaton run, no looping).

Traces are forged by hand on the scoop world (white = mode a, yellow = b, pink with soup = c,
green = d); the oracle recomputes the readings from the states, runs the automaton itself and
reads the cut records as data.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tli_verify.verify.config import CampaignConfig, sim_spec
from tli_verify.verify.oracle import CutRecord, Oracle, Trace, ViolationKind
from tli_verify.verify.simulate import load

WHITE = (-5.0, 4.5)
WHITE_LOW = (-3.0, -3.0)
YELLOW = (-3.0, -5.0)
PINK = (4.0, -5.5)
GREEN = (4.0, 7.0)


@pytest.fixture(scope="module")
def oracle() -> Oracle:
    return load(sim_spec(CampaignConfig(task="scoop", modulation=True))).oracle


def forge(segments: list[tuple[tuple[float, float], str, int]], *,
          pushes: tuple[int, ...] = (), cuts: tuple[CutRecord, ...] = (),
          modes: list[str] | None = None) -> Trace:
    """A trace whose read states sit at ``point`` for ``count`` steps per segment."""
    pts: list[tuple[float, float]] = []
    ms: list[str] = []
    for point, mode, count in segments:
        pts += [point] * count
        ms += [mode] * count
    R = np.array(pts, dtype=np.float64)
    S = np.vstack([R[1:], R[-1:]])
    return Trace(states=S, read_states=R, modes=tuple(modes or ms), pushes=pushes, cuts=cuts,
                 budget=len(ms))


def kinds(oracle: Oracle, trace: Trace) -> set[ViolationKind]:
    return set(oracle.check(trace).kinds)


def nominal() -> list[tuple[tuple[float, float], str, int]]:
    return [(WHITE, "a", 5), (YELLOW, "b", 5), (PINK, "c", 5), (GREEN, "d", 1)]


def test_nominal_trace_is_clean(oracle: Oracle) -> None:
    v = oracle.check(forge(nominal()))
    assert v.ok, v.violations
    assert v.reached and v.goal_step == 15
    assert v.oracle_modes == "abcd"
    assert v.robustness > 0


def test_automaton_check_catches_a_wrong_mode(oracle: Oracle) -> None:
    modes = ["a"] * 5 + ["b"] * 5 + ["c"] * 5 + ["d"]
    modes[7] = "c"  # the policy ran c while the reading shows contact (b)
    assert kinds(oracle, forge(nominal(), modes=modes)) == {ViolationKind.AUTOMATON}


def test_unprovoked_exit_is_an_invariance_failure(oracle: Oracle) -> None:
    trace = forge([(WHITE, "a", 5), (YELLOW, "b", 5), (WHITE_LOW, "a", 5)])
    assert kinds(oracle, trace) == {ViolationKind.INVARIANCE}
    v = oracle.check(trace)
    assert v.failures == 1
    assert v.violations[0].step == 10


def test_exit_caused_by_a_perturbation_is_not_a_failure(oracle: Oracle) -> None:
    trace = forge([(WHITE, "a", 5), (YELLOW, "b", 5), (WHITE_LOW, "a", 5)], pushes=(10,))
    v = oracle.check(trace)
    assert v.ok and v.failures == 0


def test_exit_answered_with_a_cut_is_not_a_violation(oracle: Oracle) -> None:
    cut = CutRecord(10, "b", (0.0, 1.0), (-3.0, -4.5))
    v = oracle.check(forge([(WHITE, "a", 5), (YELLOW, "b", 5), (WHITE_LOW, "a", 5)],
                           cuts=(cut,)))
    assert v.ok and v.failures == 1


def test_same_exit_after_its_cut_is_a_repeated_exit(oracle: Oracle) -> None:
    # the cut of b (x2 <= -4.5) exists from step 3; the state is inside it at the last in-mode
    # reading and outside at the failure reading, no perturbation: the cut did not hold
    cut = CutRecord(3, "b", (0.0, 1.0), (-3.0, -4.5))
    trace = forge([(WHITE, "a", 5), (YELLOW, "b", 5), (WHITE_LOW, "a", 5)], cuts=(cut,))
    assert kinds(oracle, trace) == {ViolationKind.REPEATED_EXIT}


def test_looping_after_the_last_perturbation(oracle: Oracle) -> None:
    # a -> b -> a -> ... where b -> a counts as planned (so no exit is unprovoked): only the
    # number of re-entries into visited modes is left to object
    planned = dict(oracle.planned)
    planned["b"] = frozenset({"a", "c"})
    lenient = replace(oracle, planned=planned)
    segs: list[tuple[tuple[float, float], str, int]] = [(WHITE, "a", 3)]
    for _ in range(oracle.max_cycles):
        segs += [(YELLOW, "b", 3), (WHITE_LOW, "a", 3)]
    assert kinds(lenient, forge(segs)) == {ViolationKind.LOOPING}
    assert lenient.check(forge(segs[: 1 + 2 * (oracle.max_cycles // 2)])).ok
    # the same loop before a perturbation is not looping "after the last perturbation"
    assert lenient.check(forge([*segs, (WHITE, "a", 3)], pushes=(len(segs) * 3,))).ok


def test_cuts_that_never_stop_are_looping(oracle: Oracle) -> None:
    # every b -> a exit answered by a (far-away) cut: each is progress (the loop count
    # restarts), but more than max_cuts of them after the last perturbation is not
    def looped(rounds: int) -> Trace:
        segs: list[tuple[tuple[float, float], str, int]] = [(WHITE, "a", 3)]
        cuts = []
        t = 3
        for _ in range(rounds):
            segs += [(YELLOW, "b", 3), (WHITE_LOW, "a", 3)]
            cuts.append(CutRecord(t + 3, "b", (1.0, 0.0), (100.0, 0.0)))
            t += 6
        return forge(segs, cuts=tuple(cuts))

    assert oracle.check(looped(oracle.max_cuts)).ok
    assert kinds(oracle, looped(oracle.max_cuts + 1)) == {ViolationKind.LOOPING}


def test_missing_the_certified_deadline_is_a_reachability_failure(oracle: Oracle) -> None:
    n = oracle.deadline_steps("a", np.array(WHITE))
    stuck = forge([(WHITE, "a", n + 2)])
    assert kinds(oracle, stuck) == {ViolationKind.REACHABILITY}
    early = forge([(WHITE, "a", n - 10)])  # ended before the deadline: undecided, no verdict
    v = oracle.check(early)
    assert v.ok and not v.conclusive


def test_goal_after_the_deadline_is_late(oracle: Oracle) -> None:
    n = oracle.deadline_steps("c", np.array(PINK))
    segs = [(WHITE, "a", 2), (YELLOW, "b", 2), (PINK, "c", 3)]
    in_time = forge([*segs, (GREEN, "d", 1)], pushes=(5,))
    assert oracle.check(in_time).ok
    late = forge([(WHITE, "a", 2), (YELLOW, "b", 2), (PINK, "c", n + 10), (GREEN, "d", 1)],
                 pushes=(5,))
    assert kinds(oracle, late) == {ViolationKind.REACHABILITY}


def test_deadline_is_certified_and_grows_with_distance(oracle: Oracle) -> None:
    near = oracle.deadline_steps("b", oracle.params["b"].attractor + 0.01)
    far = oracle.deadline_steps("b", np.array([-7.5, -7.5]))
    worst = oracle.deadline_steps("b")
    assert near < far <= worst
    # the sampled per-step rate is certified (< 1) and no faster than the continuous rate
    for p in oracle.params.values():
        assert 0.0 < p.rho < 1.0
        assert -np.log(p.rho) <= p.rate * oracle.dt * 1.01


def test_reading_outside_the_assumptions_stops_the_checks(oracle: Oracle) -> None:
    # a jump white -> green with soup is impossible; a reading of t from mode a violates the
    # assumptions: here the start already reads contact (b), which the initial assumption
    # rules out: no guarantee is owed, nothing is decided
    v = oracle.check(forge([(YELLOW, "b", 5)]))
    assert not v.assumptions_ok
    assert v.ok and not v.conclusive


def test_certified_deadline_holds_on_simulated_runs(oracle: Oracle) -> None:
    # the certificate predicts the rollout: on real closed-loop runs (LTL-DS, the shipped
    # model) the goal is reached before the oracle's certified deadline, from every
    # disturbed state drawn here
    from tli_verify.verify.config import resolve_config
    from tli_verify.verify.draws import config_strategy, draw_cases
    from tli_verify.verify.simulate import simulate

    # the strategy draws from a config with the task's defaults filled in
    _, cfg = resolve_config(CampaignConfig(task="scoop", modulation=True))
    spec = sim_spec(cfg)
    cases = draw_cases(config_strategy(cfg, load(spec)), 12, "deadline-check")
    for trace, _ in simulate(spec, cases):
        v = oracle.check(trace)
        assert v.reached and v.conclusive
        if v.deadline_step is not None:
            assert v.goal_step is not None and v.goal_step <= v.deadline_step
        assert ViolationKind.REACHABILITY not in v.kinds
