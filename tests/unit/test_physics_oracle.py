"""The physics oracle of the Franka trials: forged trials that only one check catches.

A nominal trial's shape (measured: ``tli sim franka --no-perturb``, seed 0: the soup bowl
reached at step 77, soup on the spoon at step 97, above the target at step 286) is the valid
reference; each forgery changes one thing and must be flagged by exactly one check.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import pytest

pytest.importorskip("mujoco")

from tli_verify.io import bundled_dir
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import load_spec
from tli_verify.sim.loop import TrialResult
from tli_verify.sim.perturbations import Perturbation
from tli_verify.sim.trial_oracle import check_trial

SPEC = bundled_dir("sim") / "franka" / "specs" / "franka-scoop.toml"
GOALS = load_spec(SPEC).goal_modes
"""The spec's ``[goal]`` (``d``: the pour may leave it, so it is not a sink)."""


@pytest.fixture(scope="module")
def automaton() -> Any:
    return synthesize(load_spec(SPEC))


def trace(*runs: tuple[str, int]) -> tuple[str, ...]:
    return tuple(m for mode, n in runs for m in mode * n)


def changes(modes: tuple[str, ...]) -> tuple[str, ...]:
    return tuple(f"ModeChange at step {k}" for k in range(1, len(modes))
                 if modes[k] != modes[k - 1])


NOMINAL_MODES = trace(("a", 77), ("b", 20), ("c", 189), ("d", 125))
NOMINAL = TrialResult(
    seed=0, variant="LTL-DS", success=True, delivered=3, modes=NOMINAL_MODES, cuts_added=0,
    sim_time=9.2, wall_time=2.6,
    perturbations=(Perturbation("push", 2.0, 1.0, displacement=(0.2, 0.0, 0.0)),),
    applied=(2.0,), events=changes(NOMINAL_MODES))


def jump(extra: tuple[str, ...] = ()) -> TrialResult:
    """Soup bowl skipped: a -> c at step 77 (no transition of the automaton)."""
    modes = trace(("a", 77), ("c", 209), ("d", 125))
    return replace(NOMINAL, modes=modes, events=changes(modes) + extra)


def test_the_nominal_trial_passes(automaton: Any) -> None:
    verdict = check_trial(NOMINAL, automaton, goal_modes=GOALS)
    assert verdict.ok and verdict.violations == () and verdict.replans == 0


FORGERIES: list[tuple[str, Callable[[], TrialResult], str, str]] = [
    ("no bead delivered", lambda: replace(NOMINAL, success=False, delivered=0),
     "delivery", "no soup delivered"),
    ("success claimed with no bead", lambda: replace(NOMINAL, delivered=0),
     "delivery", "no soup delivered"),
    ("beads delivered but the trial failed", lambda: replace(NOMINAL, success=False),
     "delivery", "the trial says it failed"),
    ("the run stops in transport", lambda: replace(
        NOMINAL, modes=NOMINAL_MODES[:200], events=changes(NOMINAL_MODES[:200])),
     "reachability", "ends in mode 'c'"),
    ("a -> c without a replan", jump, "automaton", "no transition of the automaton"),
    ("a -> c replanned without a cause", lambda: jump(("Replan at step 77",)),
     "automaton", "no transition of the automaton"),
    ("a mode change the executive did not report", lambda: replace(
        NOMINAL, events=tuple(e for e in NOMINAL.events if e != "ModeChange at step 97")),
     "automaton", "did not report"),
    ("starts in the scooping mode", lambda: replace(
        NOMINAL, modes=("b", *NOMINAL_MODES[1:])), "automaton", "not an initial mode"),
    ("an exit of the pour no cut answered", lambda: replace(
        NOMINAL, events=(*NOMINAL.events, "InvarianceFailure at step 300")),
     "invariance", "did not answer with a cut"),
    ("a mode the spec lacks", lambda: replace(
        NOMINAL, modes=(*NOMINAL_MODES[:150], "z", *NOMINAL_MODES[151:])),
     "automaton", "'z' is not a mode"),
]


@pytest.mark.parametrize(("name", "forge", "kind", "message"), FORGERIES,
                         ids=[f[0] for f in FORGERIES])
def test_each_forgery_is_caught_by_exactly_one_check(
        automaton: Any, name: str, forge: Callable[[], TrialResult], kind: str,
        message: str) -> None:
    verdict = check_trial(forge(), automaton, goal_modes=GOALS)
    assert verdict.violations == (kind,), (name, verdict)
    assert not verdict.ok
    assert any(message in m for m in verdict.messages), verdict.messages


@pytest.mark.parametrize("cause", ["Perturbation", "AssumptionViolationEvent"])
def test_a_jump_replanned_after_a_perturbation_or_sensor_change_is_a_run(
        automaton: Any, cause: str) -> None:
    verdict = check_trial(jump(("Replan at step 77", f"{cause} at step 77")), automaton,
                          goal_modes=GOALS)
    assert verdict.ok and verdict.replans == 1


def test_the_goal_modes_can_be_given(automaton: Any) -> None:
    stopped = replace(NOMINAL, modes=NOMINAL_MODES[:200], events=changes(NOMINAL_MODES[:200]))
    assert check_trial(stopped, automaton, goal_modes=("c", "d")).ok
    assert check_trial(NOMINAL, automaton, goal_modes=("c",)).violations == ("reachability",)


def test_the_pour_is_not_a_sink_so_the_goal_comes_from_the_spec(automaton: Any) -> None:
    assert GOALS == ("d",) and "d" not in automaton.sink_modes()
    verdict = check_trial(NOMINAL, automaton)  # default: the sinks, of which there are none
    assert verdict.violations == ("reachability",) and "not a goal mode (-)" in \
        verdict.messages[0]
    # the pour swept past the bowl twice (d -> c, invariance failures) and came back: a run
    modes = trace(("a", 77), ("b", 20), ("c", 189), ("d", 20), ("c", 10), ("d", 20), ("c", 8),
                  ("d", 60))
    exits = [k for k in range(1, len(modes)) if modes[k - 1] == "d" and modes[k] == "c"]
    failures = tuple(f"InvarianceFailure at step {k}" for k in exits)
    cuts = tuple(f"CutAdded at step {k}" for k in exits)
    swept = replace(NOMINAL, modes=modes, events=changes(modes) + failures + cuts)
    assert check_trial(swept, automaton, goal_modes=GOALS).ok  # LTL-DS: each exit cut
    # without modulation the same exits are answered by no cut: the 2-D oracle's INVARIANCE
    blind = check_trial(replace(swept, events=changes(modes) + failures), automaton,
                        goal_modes=GOALS)
    assert blind.violations == ("invariance",)
    assert f"step {exits[0]}:" in blind.messages[0] and "(and 1 more)" in blind.messages[0]
