"""The Franka policy behind the gate: ``tli sim franka --evidence``, ``tli gate`` and
``tli gate --rerun`` on a copy of the current ``sim/franka`` project.

Physical trials cost seconds: these run one trial with a short step budget (the soup is not
delivered in 2 s, so the oracle rejects it: the evidence is written as an honest record and the
gate blocks); the full 30-trial campaign is ``tli evidence sim/franka``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("mujoco")

from tests.support.cli import json_records, run
from tests.support.sim import copy_franka_project
from tests.unit.test_physics_evidence import attach_physics, physics_block
from tli_verify.deploy.gate import rerun_physics, rerun_seed, run_gate
from tli_verify.io import sha256_file
from tli_verify.sim.physics_checks import FRANKA_PHYSICS
from tli_verify.verify.evidence import check_evidence, deployed_task_block

pytestmark = pytest.mark.sim

EVIDENCE = "franka-scoop.campaign.json"


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """A copy of the Franka project's spec, model and certificate."""
    copy_franka_project(tmp_path)
    return tmp_path


def test_sim_writes_evidence_of_what_it_ran_and_the_gate_judges_it(
        project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    certs = project / "certificates"
    code, out, _ = run(capsys, "sim", "franka", "--certificates", str(certs), "--trials", "1",
                       "--seed", "3", "--duration", "2", "--json", "--evidence")
    trial, summary = json_records(out)
    assert code == (0 if not trial["violations"] else 1)
    assert summary["evidence"] == str(certs / EVIDENCE)
    doc = json.loads((certs / EVIDENCE).read_text())
    assert doc["world"] == "franka-physics" and doc["campaign"]["seed"] == 3
    assert doc["campaign"]["examples"] == doc["campaign"]["runs"] == 1
    phys = doc["physics"]
    assert (phys["robot"], phys["variant"], phys["duration"]) == ("panda", "LTL-DS", 2.0)
    assert (phys["retry"], phys["sensors"]) == (True, "franka")
    assert (phys["controller"]["kind"], phys["controller"]["law"]) == ("cartesian-impedance",
                                                                      "measured")
    assert phys["controller"]["impedance"]["stiffness_pos"] == 2000.0
    assert phys["stall_rule"] == {"radius": 0.3, "dwell": 1.0, "blocked_after": 1.5,
                                  "progress": 0.02}
    assert (phys["pushes"], phys["tilts"], phys["trials"]) == (1, 1, 1)
    assert phys["successes"] == int(trial["success"])
    (outcome,) = phys["outcomes"]
    assert {k: outcome[k] for k in ("seed", "success", "delivered", "violations", "retries",
                                    "stopped", "limit_ratios", "stalls", "stall_fired",
                                    "cut_gap", "tank_low")} == {
        "seed": 3, "success": trial["success"], "delivered": trial["delivered"],
        "violations": trial["violations"], "retries": trial["retries"],
        "stopped": trial["stopped"], "limit_ratios": trial["limit_ratios"],
        "stalls": trial["stalls"], "stall_fired": trial["stall_fired"],
        "cut_gap": trial["cut_gap"], "tank_low": trial["tank_low"]}
    assert set(outcome["limit_ratios"]) == {"torque", "torque_rate", "joint_velocity",
                                            "cartesian_speed", "rotation_speed"}
    assert doc["violations"]["total"] == len(trial["violations"])
    for key, path in (("model", project / "models" / "franka-scoop.model.json"),
                      ("certificate", certs / "franka-scoop.cert.json"),
                      ("spec", project / "specs" / "franka-scoop.toml")):
        assert doc[key]["sha256"] == sha256_file(path)
    # the task the spec names (the project's tasks/franka-scoop.toml), as the gate recomputes it
    assert doc["task"]["name"] == "franka-scoop"
    assert doc["task"] == deployed_task_block(project / "models" / "franka-scoop.model.json",
                                              certs)
    recorded = [(p["kind"], p["start"]) for p in trial["perturbations"]]
    assert [k for k, _ in recorded] == ["push", "tilt"]
    # one trial of 2 s is no evidence: the gate blocks, one line naming the evidence file
    code, _, err = run(capsys, "gate", str(project))
    assert code == 1 and err.count("\n") == 1 and f"certificates/{EVIDENCE}" in err
    assert "fewer than the minimum 30 (MIN_PHYSICS_TRIALS)" in err
    # the gate's re-run of the recorded trial reproduces it (same seed, settings, machine)
    check = check_evidence(certs / EVIDENCE, physical=(FRANKA_PHYSICS,))
    ok, message = rerun_physics(check, project / "models" / "franka-scoop.model.json", 1)
    assert ok == (not trial["violations"])
    assert f"{int(trial['success'])}/1 delivered soup" in message


def test_evidence_path_can_be_chosen(project: Path, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "out" / "e.json"
    code, out, _ = run(capsys, "sim", "franka", "--certificates", str(project / "certificates"),
                       "--duration", "0.5", "--evidence", str(target))
    assert code == 1 and target.is_file() and "evidence" in out  # 0.5 s: nothing delivered
    assert not (project / "certificates" / EVIDENCE).exists()


@pytest.mark.parametrize("extra", [
    ["--evidence", "{p}/models/franka-scoop.model.json"],
    ["--evidence", "{p}/certificates/franka-scoop.cert.json"],
    ["--evidence", "{p}/specs/franka-scoop.toml"],
    ["--fig9", "{p}/f.png", "--evidence", "{p}/f.png"],
    ["--evidence", "--no-perturb"],
    ["--evidence", "--no-modulation"],
    ["--evidence", "--no-replan"],
    ["--evidence", ""],  # empty: refused, not the default path in the project
], ids=["model", "certificate", "spec", "fig9", "no-perturb", "no-modulation", "no-replan",
        "empty"])
def test_evidence_is_refused_before_any_trial(project: Path, extra: list[str],
                                              capsys: pytest.CaptureFixture[str]) -> None:
    before = {p: p.read_bytes() for p in project.rglob("*") if p.is_file()}
    code, out, err = run(capsys, "sim", "franka", "--certificates",
                         str(project / "certificates"),
                         *[e.replace("{p}", str(project)) for e in extra])
    assert code == 2 and out == ""
    assert err.startswith("error: ") and err.count("\n") == 1
    assert {p: p.read_bytes() for p in project.rglob("*") if p.is_file()} == before


def test_gate_rerun_catches_evidence_whose_trials_do_not_hold(
        project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Evidence claiming 30 delivered trials with a 2 s budget binds the right files, so the
    campaign line passes; re-running one trial with its settings shows no soup is delivered."""
    attach_physics(project, physics=physics_block(duration=2.0))
    report = run_gate(project, rerun=0)
    assert report.ok, [b.message for b in report.blockers]
    code, out, err = run(capsys, "gate", str(project), "--rerun", "1")
    assert code == 1 and err.count("\n") == 1
    line = next(x for x in out.splitlines() if ": rerun: " in x)
    assert line.startswith("BLOCK")
    assert "re-ran 1 physical trial(s) from seed " in line  # the gate's own seed
    assert "(robot panda, LTL-DS, 2 s)" in line and "from seed 0 " not in line
    assert "0/1 delivered soup" in line and "delivery 1" in line
    assert "reproduce: tli sim franka --certificates" in line


@pytest.mark.slow
def test_a_full_budget_trial_reproduces_under_rerun(project: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """A trial with the full step budget (it may or may not deliver with the current model):
    the gate re-runs a trial on its own seed with the settings the evidence recorded, and its
    verdict is that of the same trial run from the CLI with those settings."""
    certs = project / "certificates"
    code, out, _ = run(capsys, "sim", "franka", "--certificates", str(certs), "--duration", "12",
                       "--json", "--evidence")
    trial, _ = json_records(out)
    assert (code == 0) == (not trial["violations"])
    check = check_evidence(certs / EVIDENCE, physical=(FRANKA_PHYSICS,))
    model = project / "models" / "franka-scoop.model.json"
    ok, message = rerun_physics(check, model, 1)
    seed = rerun_seed(check, model, 1)
    assert f"from seed {seed} (robot panda, LTL-DS, 12 s)" in message
    code2, out2, _ = run(capsys, "sim", "franka", "--certificates", str(certs), "--duration",
                         "12", "--seed", str(seed), "--json")
    again, _ = json_records(out2)
    assert ok == (not again["violations"]) == (code2 == 0), message


def test_a_certificates_directory_by_another_name_is_the_one_bound(
        project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--certificates DIR`` not named certificates/: the evidence binds the certificate the
    policy ran behind and is written next to it."""
    certs = project / "certs"
    (project / "certificates").rename(certs)
    code, _, err = run(capsys, "sim", "franka", "--certificates", str(certs), "--duration",
                       "0.5", "--evidence")
    assert code == 1 and err == ""  # 0.5 s: nothing delivered, the evidence is written
    doc = json.loads((certs / EVIDENCE).read_text())
    assert doc["certificate"] == {"path": "franka-scoop.cert.json",
                                  "sha256": sha256_file(certs / "franka-scoop.cert.json")}
