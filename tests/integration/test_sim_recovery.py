"""A spilled trial in closed loop, through the command a user runs: LTL-DS replans and
delivers; the same trial without replanning carries an empty spoon (paper Sec. 7.2)."""

from __future__ import annotations

import pytest

pytest.importorskip("mujoco")

from tests.support.cli import json_records, run

pytestmark = [
    pytest.mark.sim,
    pytest.mark.slow,
    # On the 4-D policy of issue 34 the arm held roll and yaw at a fixed orientation and a
    # person's tilt no longer spilled; on the 6-D pose policy (issue 35) nothing holds them,
    # and seed 2's tilt spills again (these tests were strict xfails until it did).
]

SEED = "2"  # its tilt spills the whole scoop on the way to the target


def test_ltlds_replans_after_the_spill_and_delivers(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "sim", "franka", "--seed", SEED, "--json")
    trial, summary = json_records(out)
    assert code == 0 and trial["success"] and trial["violations"] == []
    tilt = next(p for p in trial["perturbations"] if p["kind"] == "tilt")
    assert tilt["applied_at"] is not None  # the soup was carried and tilted
    runs = trial["mode_sequence"].split()
    assert runs[-1] == "d" and runs.count("b") >= 2  # back to the bowl, scooped again
    assert summary["passed"] == 1


def test_without_replanning_the_same_trial_fails(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "sim", "franka", "--seed", SEED, "--json", "--no-replan")
    trial, summary = json_records(out)
    assert code == 1 and not trial["success"] and trial["delivered"] == 0
    assert "delivery" in trial["violations"] and summary["passed"] == 0
