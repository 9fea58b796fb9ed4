"""Campaign evidence of the Franka policy's physical campaign (world franka-physics).

The evidence here binds a copy of the current ``sim/franka`` spec, model and certificate exactly
as ``tli sim franka --evidence`` does, but its trial outcomes are stated, not simulated (the
physical trials themselves are run in ``tests/integration/test_franka_evidence.py``): these tests
check what the gate accepts. Every forgery leaves the spec, model and certificate valid unless
the test tampers with them, so only the campaign line blocks, naming the file and what is wrong.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.support.cli import run
from tests.support.sim import copy_franka_project
from tli_verify.deploy.gate import run_gate
from tli_verify.io import bundled_dir, canonical_json
from tli_verify.sim.physics_checks import FRANKA_PHYSICS, MIN_PHYSICS_TRIALS
from tli_verify.sim.physics_options import DEFAULT_PHYSICS
from tli_verify.verify.evidence import (
    check_evidence,
    deployed_task_block,
    evidence_digest,
    write_evidence,
)

REPO = bundled_dir("models").parent
EVIDENCE = Path("certificates") / "franka-scoop.campaign.json"
MODEL = "models/franka-scoop.model.json"


def physics_block(trials: int = MIN_PHYSICS_TRIALS, *, seed: int = 0, failed: int = 0,
                  **overrides: Any) -> dict[str, Any]:
    block: dict[str, Any] = {
        "robot": "panda", "variant": "LTL-DS", "duration": 40.0, "pushes": 1, "tilts": 1,
        "retry": True, "sensors": "franka", "trials": trials, "successes": trials - failed,
        "controller": {"kind": "cartesian-impedance", "law": "measured",
                       "ds_at": "measured pose"},
        "delivered": 4 * (trials - failed),
        "cuts_added": 0, "mujoco": "3.17.0", "wall_time": 1.0,
        "scene": DEFAULT_PHYSICS.to_dict(),
        "outcomes": [{"seed": seed + k, "success": k >= failed,
                      "delivered": 4 if k >= failed else 0,
                      "violations": [] if k >= failed else ["delivery", "reachability"]}
                     for k in range(trials)],
    }
    block.update(overrides)
    return block


def attach_physics(project: Path, *, trials: int = MIN_PHYSICS_TRIALS, failed: int = 0,
                   spec: Path | None = None, model: Path | None = None,
                   certificate: Path | None = None, **overrides: Any) -> Path:
    """Write ``certificates/franka-scoop.campaign.json`` binding the project's current files
    (and, as ``tli sim franka --evidence`` does, the task the model's spec names)."""
    path = project / EVIDENCE
    model = model or project / MODEL
    fields: dict[str, Any] = {
        "world": "franka-physics",
        "task": deployed_task_block(model, path.parent),
        "spec": spec or project / "specs" / "franka-scoop.toml",
        "model": model,
        "certificate": certificate or project / "certificates" / "franka-scoop.cert.json",
        "seed": 0, "examples": trials, "runs": trials,
        "violations": {"delivery": failed, "reachability": failed, "automaton": 0},
        "modulation": True, "backend": "serial", "workers": 1,
        "physics": physics_block(trials, failed=failed),
    }
    fields.update(overrides)
    write_evidence(path, **fields)
    return path


@pytest.fixture
def franka(tmp_path: Path) -> Path:
    """A copy of the Franka project (spec, model, certificate) with valid physical evidence."""
    copy_franka_project(tmp_path)
    attach_physics(tmp_path)
    return tmp_path


def forge(project: Path, edit: Callable[[dict[str, Any]], None]) -> None:
    """Edit the evidence and make its digest consistent again."""
    path = project / EVIDENCE
    doc = json.loads(path.read_text())
    edit(doc)
    doc["digest"] = evidence_digest(doc)
    path.write_text(canonical_json(doc))


def only_campaign_blocks(project: Path) -> str:
    report = run_gate(project, rerun=0)
    found = [(b.kind, b.path, b.check) for b in report.blockers]
    assert found == [("model", MODEL, "campaign")], \
        [f"{b.path}: {b.check}: {b.message}" for b in report.blockers]
    return report.blockers[0].message


def test_valid_physical_evidence_passes_the_gate(franka: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    report = run_gate(franka, rerun=0)
    assert report.ok, [b.message for b in report.blockers]
    line = next(i for i in report.items if i.check == "campaign")
    assert "physical campaign 'franka-physics'" in line.message
    assert f"{MIN_PHYSICS_TRIALS} perturbed trials from seed 0" in line.message
    # the CLI: the evidence line passes; the gate's own re-run trial is the next test's
    code, out, err = run(capsys, "gate", str(franka))
    assert "ok    model       models/franka-scoop.model.json: campaign: certificates/franka-" \
        "scoop.campaign.json: physical campaign 'franka-physics'" in out, out
    assert code == 0 or ("rerun: re-ran 1 physical trial(s)" in out and out.count("BLOCK") == 1), \
        (out, err)
    check = check_evidence(franka / EVIDENCE, physical=(FRANKA_PHYSICS,))
    assert check.ok and dict(check.physics) == {"robot": "panda", "variant": "LTL-DS",
                                                "duration": 40.0, "pushes": 1, "tilts": 1,
                                                "retry": True, "sensors": "franka"}


@pytest.mark.slow
@pytest.mark.sim
def test_the_gates_rerun_trial_passes(franka: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "gate", str(franka))
    assert code == 0 and out.rstrip().endswith("model(s), 1 spec(s))") and err == "", (out, err)


def test_evidence_made_on_the_free_tool_is_refused(franka: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """30 passing trials, every file bound, digest right -- but made on the free tool, not the
    arm: only the robot check catches it."""
    attach_physics(franka, physics=physics_block(robot="free-tool"))
    report = run_gate(franka, rerun=0)
    assert not report.ok
    (blocker,) = [b for b in report.blockers if b.check == "campaign"]
    assert "'free-tool' rig, not the Panda" in blocker.message
    code, _, err = run(capsys, "gate", str(franka))
    assert code == 1 and err.count("\n") == 1
    attach_physics(franka, physics=physics_block(robot="panda"))
    assert run_gate(franka, rerun=0).ok


@pytest.mark.parametrize(("field", "value", "says"), [
    ("controller", {"kind": "cartesian-impedance"}, "'tracking' control law"),
    ("controller", {"kind": "cartesian-impedance", "law": "tracking", "ds_at": "target"},
     "'tracking' control law"),
    ("controller", {"kind": "passive-ds", "law": "passive"}, "'passive' control law"),
    ("sensors", "ideal", "'ideal' sensors"),
    ("controller", None, "does not say which controller and sensors"),
])
def test_evidence_of_another_controller_or_sensor_model_is_refused(
        franka: Path, capsys: pytest.CaptureFixture[str], field: str, value: Any,
        says: str) -> None:
    """A forged record (digest recomputed, every file still bound) made with another control law
    (the target-tracking one, recorded before the law was named or after; the passive-DS law) or
    the simulator's ideal sensors is not evidence for the project's robot."""
    assert run_gate(franka, rerun=0).ok

    def edit(doc: dict[str, Any]) -> None:
        if value is None:
            del doc["physics"][field]
        else:
            doc["physics"][field] = value

    forge(franka, edit)
    message = only_campaign_blocks(franka)
    assert says in message, message
    code, _, err = run(capsys, "gate", str(franka))
    assert code == 1 and err.count("\n") == 1 and says in err, err


def test_a_tampered_model_blocks_naming_it(franka: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    model = franka / MODEL
    doc = json.loads(model.read_text())
    first = next(iter(doc["modes"].values()))
    first["components"][0]["A"][0][0] *= 1.01
    model.write_text(json.dumps(doc))
    report = run_gate(franka, rerun=0)
    campaign = next(b for b in report.blockers if b.check == "campaign")
    assert "differs from the evidence's" in campaign.message
    assert "the campaign ran another model" in campaign.message
    code, _, err = run(capsys, "gate", str(franka))
    assert code == 1 and err.startswith("error: gate blocked") and err.count("\n") == 1
    assert MODEL in err


def test_a_rewritten_certificate_blocks(franka: Path) -> None:
    """The same certificate content in other bytes still re-checks; the evidence ran the old
    bytes, so only the campaign line blocks."""
    cert = franka / "certificates" / "franka-scoop.cert.json"
    cert.write_text(json.dumps(json.loads(cert.read_text()), indent=1))
    assert "the certificate changed after the campaign" in only_campaign_blocks(franka)


def test_a_tampered_certificate_blocks_naming_it(franka: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    cert = franka / "certificates" / "franka-scoop.cert.json"
    doc = json.loads(cert.read_text())
    doc["dt"] = "1/10"  # claims a longer control period than was proven
    cert.write_text(json.dumps(doc))
    code, _, err = run(capsys, "gate", str(franka))
    assert code == 1 and err.count("\n") == 1 and "franka-scoop.cert.json" in err
    assert any(b.check == "campaign" for b in run_gate(franka, rerun=0).blockers)


def test_evidence_of_another_model_blocks(franka: Path, tmp_path: Path) -> None:
    """Evidence of the repository's 2-D scoop model placed where the Franka model's belongs."""
    other = tmp_path / "other"
    for sub, name in (("specs", "scoop.toml"), ("models", "scoop.model.json"),
                      ("certificates", "scoop.cert.json")):
        (other / sub).mkdir(parents=True)
        shutil.copy(REPO / sub / name, other / sub / name)
    attach_physics(franka, spec=other / "specs" / "scoop.toml",
                   model=other / "models" / "scoop.model.json",
                   certificate=other / "certificates" / "scoop.cert.json")
    message = only_campaign_blocks(franka)
    assert "is not the deployed model" in message and "binds another model" in message


@pytest.mark.parametrize(("edit", "said"), [
    (lambda d: (d["violations"].update(total=2, by_kind={"delivery": 1, "reachability": 1}),
                d["physics"].update(successes=29),
                d["physics"]["outcomes"][0].update(success=False, delivered=0,
                                                    violations=["delivery", "reachability"])),
     "physical trials failed the oracle (trials per kind: delivery: 1, reachability: 1)"),
    (lambda d: d["physics"].update(successes=29),
     "1 of 30 physical trial(s) delivered no soup"),
    (lambda d: d["physics"]["outcomes"][3].update(success=False),
     "physics.outcomes disagree"),
    (lambda d: d["physics"]["outcomes"].pop(), "physics.outcomes lists 29 trial(s)"),
    (lambda d: d["physics"].update(variant="no-replan"), "'no-replan' ablation"),
    (lambda d: d["physics"].update(tilts=0), "must perturb at both levels"),
    (lambda d: d["physics"].update(pushes=0), "must perturb at both levels"),
    (lambda d: d["physics"].update(trials=31), "physics.trials 31 differs"),
    (lambda d: (d["campaign"].update(examples=29, runs=29), d["physics"].update(
        trials=29, successes=29), d["physics"]["outcomes"].pop()),
     "fewer than the minimum 30 (MIN_PHYSICS_TRIALS)"),
    (lambda d: d.pop("physics"), "'physics' is a required property"),
    (lambda d: d.update(world="scoop"), "a physics block for world 'scoop'"),
], ids=["failed-trial", "successes-short", "outcomes-disagree", "outcomes-missing",
        "ablation", "no-tilts", "no-pushes", "trials-mismatch", "too-few-trials",
        "no-physics-block", "physics-on-2d-world"])
def test_physical_evidence_that_is_no_evidence_blocks(franka: Path,
                                                      edit: Callable[[Any], None],
                                                      said: str) -> None:
    forge(franka, edit)
    assert said in only_campaign_blocks(franka)


def test_evidence_with_failures_is_written_and_blocks(franka: Path) -> None:
    attach_physics(franka, failed=2)
    assert "trials per kind: delivery: 2, reachability: 2" in only_campaign_blocks(franka)


@pytest.mark.parametrize("scene", [
    dict(DEFAULT_PHYSICS.to_dict(), sleep=not DEFAULT_PHYSICS.sleep),
    dict(DEFAULT_PHYSICS.to_dict(), solver="cg" if DEFAULT_PHYSICS.solver != "cg" else "newton"),
    None,
])
def test_evidence_made_in_other_solver_settings_is_refused(
        franka: Path, scene: dict[str, Any] | None, capsys: pytest.CaptureFixture[str]) -> None:
    """30 passing trials on the Panda, every file bound -- but run in solver settings that are
    not the scene's default (or not saying which): only the scene check catches it."""
    block = physics_block()
    if scene is None:
        del block["scene"]
    else:
        block["scene"] = scene
    attach_physics(franka, physics=block)
    report = run_gate(franka, rerun=0)
    assert not report.ok
    (blocker,) = [b for b in report.blockers if b.check == "campaign"]
    assert ("physics.scene is missing" if scene is None else "the trials ran the scene with") \
        in blocker.message
    code, _, err = run(capsys, "gate", str(franka))
    assert code == 1 and err.count("\n") == 1
    attach_physics(franka, physics=physics_block())
    assert run_gate(franka, rerun=0).ok
