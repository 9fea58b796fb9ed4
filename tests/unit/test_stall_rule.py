"""The stall rule (tli_verify.runtime.stall) in the executive, on the bundled Franka scoop
model: a converged DS without the next mode's reading is reported and the mode re-entered from
its predecessor (m p m), recorded as events the physics oracle checks like any transition."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tli_verify.runtime.events import Reentered, Stall
from tli_verify.runtime.stall import StallRule, lyapunov_level
from tli_verify.sim.trial_oracle import check_trial

pytest.importorskip("mujoco")

DT = 0.02


@pytest.fixture
def policy() -> Any:
    from tli_verify.sim.franka_project import load_policy

    p = load_policy("LTL-DS")
    p.stall_rule = StallRule(radius=0.3, dwell=0.2)
    return p


def _result(policy: Any, modes: list[str]) -> Any:
    from tli_verify.sim.loop import TrialResult

    return TrialResult(seed=0, variant="LTL-DS", success=True, delivered=1, modes=tuple(modes),
                       cuts_added=0, sim_time=1.0, wall_time=1.0, perturbations=(), applied=(),
                       events=tuple(f"{type(e).__name__} at step {e.step}"
                                    for e in policy.events))


def _enter_b(policy: Any) -> tuple[list[str], np.ndarray]:
    a = policy.model.modes["a"].ds.attractor
    policy.reset(a, {})
    modes = [policy.mode]
    policy.step(a, {"r"})
    modes.append(policy.mode)
    assert policy.mode == "b"
    return modes, policy.model.modes["b"].ds.attractor.copy()


def test_a_converged_mode_is_reentered_from_its_predecessor(policy: Any) -> None:
    modes, xb = _enter_b(policy)
    dwell = round(0.2 / DT)
    for _ in range(dwell - 1):  # at b's attractor, the reading of b: V below the level
        policy.step(xb, {"r"})
        modes.append(policy.mode)
        assert policy.mode == "b"
    v = policy.step(xb, {"r"})
    modes.append(policy.mode)
    (stall,) = [e for e in policy.events if isinstance(e, Stall)]
    assert (stall.mode, stall.via, policy.mode, policy.key) == ("b", "a", "a", "a")
    assert stall.value < lyapunov_level(policy.model.modes["b"].ds.P, 0.3)
    np.testing.assert_allclose(v, policy.model.modes["a"].velocity(xb, dt=DT))
    xa = policy.model.modes["a"].ds.attractor
    policy.step(xb, {"r"})  # not converged to a's attractor yet: a's DS still runs
    modes.append(policy.mode)
    assert policy.mode == "a"
    policy.step(xa, {"r"})  # a's DS converged: back to b
    modes.append(policy.mode)
    (back,) = [e for e in policy.events if isinstance(e, Reentered)]
    assert back.converged and policy.mode == "b"
    policy.step(xa, {"s"})  # soup: the automaton's own transition b -> c
    modes.append(policy.mode)
    assert policy.mode == "c"
    assert "".join(m for i, m in enumerate(modes) if i == 0 or m != modes[i - 1]) == "ababc"
    verdict = check_trial(_result(policy, modes), policy.automaton, policy.goal_modes)
    assert "automaton" not in verdict.violations, verdict.messages


def test_a_reading_during_the_reentry_returns_to_the_mode_first(policy: Any) -> None:
    """Soup gets on during the re-entry (the lift): the executive first resumes b (its
    automaton state was kept), then takes b -> c -- never the a -> c the automaton lacks."""
    modes, xb = _enter_b(policy)
    for _ in range(round(0.2 / DT)):
        policy.step(xb, {"r"})
        modes.append(policy.mode)
    assert policy.mode == "a"
    policy.step(xb + 0.1, {"s"})
    modes.append(policy.mode)
    (back,) = [e for e in policy.events if isinstance(e, Reentered)]
    assert not back.converged and policy.mode == "b"
    policy.step(xb + 0.1, {"s"})
    modes.append(policy.mode)
    assert policy.mode == "c"
    verdict = check_trial(_result(policy, modes), policy.automaton, policy.goal_modes)
    assert "automaton" not in verdict.violations, verdict.messages


def test_a_perturbation_during_the_reentry_does_not_end_it(policy: Any) -> None:
    """The re-entry runs a's DS through reported perturbations (on the Panda: its own press on
    the bowl's slope) until a's DS converges; ending it there sent the tray back to where b
    had stalled, again and again."""
    modes, xb = _enter_b(policy)
    for _ in range(round(0.2 / DT)):
        policy.step(xb, {"r"})
        modes.append(policy.mode)
    assert policy.mode == "a"
    for _ in range(10):  # pressed on the slope, read as a push, not converged
        v = policy.step(xb + 0.05, {"r"}, perturbed=True)
        modes.append(policy.mode)
        assert policy.mode == "a"
        np.testing.assert_allclose(v, policy.model.modes["a"].velocity(xb + 0.05, dt=DT))
    assert not any(isinstance(e, Reentered) for e in policy.events)
    policy.step(policy.model.modes["a"].ds.attractor, {"r"})
    modes.append(policy.mode)
    (back,) = [e for e in policy.events if isinstance(e, Reentered)]
    assert back.converged and policy.mode == "b"
    verdict = check_trial(_result(policy, modes), policy.automaton, policy.goal_modes)
    assert "automaton" not in verdict.violations, verdict.messages


def test_no_stall_away_from_the_attractor_or_without_the_rule(policy: Any) -> None:
    _modes, xb = _enter_b(policy)
    far = xb + np.r_[0.0, 0.8, 0.5, np.zeros(xb.size - 3)]  # V far above the level
    path = [far + k * 0.02 * (xb - far) for k in range(40)]  # V falls along the way
    for x in path:
        policy.step(x, {"r"})
    assert policy.mode == "b" and not any(isinstance(e, Stall) for e in policy.events)
    policy.stall_rule = None
    for _ in range(50):
        policy.step(xb, {"r"})
    assert policy.mode == "b" and not any(isinstance(e, Stall) for e in policy.events)


def test_a_blocked_ds_is_a_stall_unless_perturbed(policy: Any) -> None:
    """Held where the DS's certified V does not fall (wedged): after blocked_after (1.5 s) a
    stall, kind blocked (V far above the converged level); a reported perturbation restarts
    the count."""
    _modes, xb = _enter_b(policy)
    far = xb + np.r_[0.0, 0.8, 0.5, np.zeros(xb.size - 3)]
    window = round(1.5 / DT)
    for k in range(window + 10):
        policy.step(far, {"r"}, perturbed=k % 20 == 0)  # a push every 0.4 s
    assert not any(isinstance(e, Stall) for e in policy.events)
    for _ in range(window):
        policy.step(far, {"r"})
    (stall,) = [e for e in policy.events if isinstance(e, Stall)]
    assert stall.value > lyapunov_level(policy.model.modes["b"].ds.P, 0.3)
    assert policy.mode == "a"


def test_the_oracle_flags_a_stall_without_its_mode_change(policy: Any) -> None:
    """A forged record: a stall reported but the trace stays in b, and a re-entry that never
    comes back but leaves a -> c (no transition of the automaton)."""
    from tli_verify.sim.loop import TrialResult

    res = TrialResult(seed=0, variant="LTL-DS", success=True, delivered=1,
                      modes=("a", "b", "b", "a", "c", "d"), cuts_added=0, sim_time=1.0,
                      wall_time=1.0, perturbations=(), applied=(),
                      events=("ModeChange at step 1", "Stall at step 2", "Stall at step 3",
                              "ModeChange at step 3", "ModeChange at step 4",
                              "ModeChange at step 5"))
    verdict = check_trial(res, policy.automaton, policy.goal_modes)
    assert "automaton" in verdict.violations
    text = " ".join(verdict.messages)
    assert "step 2: a stall reported without" in text and "a -> c" in text, text


def test_stall_rule_settings_are_checked() -> None:
    from tli_verify.errors import TliError

    with pytest.raises(TliError):
        StallRule(radius=0.0)
    with pytest.raises(TliError):
        StallRule(dwell=-1.0)
    with pytest.raises(TliError):
        StallRule(progress=1.0)
    for huge in (1e308, 1e20):  # its step count would overflow or be beyond any controller
        with pytest.raises(TliError, match="at most 3600"):
            StallRule(blocked_after=huge)
        with pytest.raises(TliError, match="at most 3600"):
            StallRule(dwell=huge)
    assert StallRule().to_dict() == {"radius": 0.3, "dwell": 1.0, "blocked_after": 1.5,
                                     "progress": 0.02}
