"""``tli sim franka --c-evaluator``: the exported artifact drives the Panda in MuJoCo through
the C evaluator (the Python executive supervises: same automaton, cuts), and the campaign
evidence records the artifact's hash, which the gate reports."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("mujoco")

from tests.support.cli import json_records, run
from tests.support.cpolicy import compiler
from tli_verify.deploy.export import export_policy
from tli_verify.deploy.gate import _evaluator_note
from tli_verify.io import bundled_dir
from tli_verify.sim.physics_checks import FRANKA_PHYSICS
from tli_verify.verify.evidence import check_evidence

pytestmark = [pytest.mark.sim,
              pytest.mark.skipif(compiler() is None, reason="no system C compiler")]


def test_the_c_evaluator_drives_the_panda_and_the_evidence_names_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from tests.support.sim import require_panda

    require_panda()
    franka = bundled_dir("sim") / "franka"
    ex = export_policy(franka / "models" / "franka-scoop.model.json",
                       tmp_path / "franka.tli.json", rerun=0)
    evidence = tmp_path / "run.campaign.json"
    # the artifact carries the stall rule its evidence ran; the wrapper takes that rule only
    import tempfile

    from tli_verify.deploy.cloop import in_the_loop
    from tli_verify.errors import ExportError
    from tli_verify.runtime.stall import StallRule
    from tli_verify.sim.franka_project import load_policy

    assert ex.artifact["stall"] is not None
    # the gate passes it; the rule edited and re-hashed (a longer dwell, or no rule: the C
    # loader would take either) is not what the model and its evidence export to
    from tli_verify.deploy.export import write_artifact
    from tli_verify.deploy.gate import run_gate

    def artifact_line(path: Path) -> tuple[bool, str]:
        report = run_gate(franka, rerun=0, artifacts=[path])
        item = next(i for i in report.items if i.kind == "artifact")
        return item.ok, item.message

    assert artifact_line(ex.json_path)[0]
    for edit, where in ((("dwell", 2.0), "stall.dwell"), ((None, None), "stall)")):
        art = json.loads(ex.json_path.read_text())
        if edit[0] is None:
            art["stall"] = None
        else:
            art["stall"][edit[0]] = edit[1]
        forged = write_artifact(art, tmp_path / "forged.tli.json")
        ok, why = artifact_line(forged.json_path)
        assert not ok and where in why, why
    with tempfile.TemporaryDirectory() as build:
        loop = in_the_loop(load_policy("LTL-DS"), ex.json_path, build)
        assert loop.stall_rule == StallRule()
        with pytest.raises(ExportError, match="the artifact runs the stall rule"):
            loop.stall_rule = None
        with pytest.raises(ExportError, match=r"radius 0\.3"):
            loop.stall_rule = StallRule(radius=0.2)
        loop.stall_rule = StallRule()
        assert loop.supervisor.stall_rule == StallRule()
    # ... and the command, asked to run without it, refuses before any work
    code, out, err = run(capsys, "sim", "franka", "--trials", "1", "--seed", "1",
                         "--c-evaluator", str(ex.json_path), "--no-stall-rule")
    assert code == 2 and "drop --no-stall-rule" in err and err.count("error:") == 1
    # seed 0 needs a re-entry (the scoop stalls): the C executive's stall rule fires
    code, out, err = run(capsys, "sim", "franka", "--trials", "1", "--seed", "0",
                         "--json", "--c-evaluator", str(ex.json_path),
                         "--evidence", str(evidence))
    trial, summary = json_records(out)
    assert f"artifact {ex.content_sha256}" in err
    assert code == 0 and trial["success"] and not trial["violations"]
    assert trial["stalls"] >= 1 and any(e.startswith("Reentered") for e in trial["events"])
    rec = summary["evaluator"]
    assert rec["artifact_sha256"] == ex.content_sha256 and rec["kind"] == "c"
    assert rec["steps"] > 100 and rec["max_rel_diff"] <= 1e-12
    phys = json.loads(evidence.read_text())["physics"]
    assert phys["evaluator"] == rec
    # the evidence checks (schema, digest, bindings) and the gate's line names the artifact
    check = check_evidence(evidence, model_path=franka / "models" / "franka-scoop.model.json",
                           valid_certificates=[franka / "certificates" / "franka-scoop.cert.json"],
                           physical=(FRANKA_PHYSICS,))
    # one trial: only the campaign's size blocks (the gate wants 30)
    assert len(check.problems) == 1 and "fewer than the minimum 30" in check.problems[0]
    assert ex.content_sha256 in _evaluator_note(dict(check.physics))


def test_the_gate_reruns_the_deployed_artifact_in_the_c_evaluator(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``tli gate --artifact`` on a physical campaign: the artifact itself drives the Panda in
    a re-run trial (C evaluator in the loop, its own derived seed). A broken evaluator that
    the Python executive beside it cannot mask -- velocities all zero -- blocks the gate."""
    from tests.support.sim import require_panda
    from tli_verify.deploy.cloop import CEvaluator
    from tli_verify.deploy.gate import run_gate

    require_panda()
    franka = bundled_dir("sim") / "franka"
    ex = export_policy(franka / "models" / "franka-scoop.model.json",
                       tmp_path / "franka.tli.json", rerun=0)

    def artifact_item() -> Any:
        report = run_gate(franka, rerun=1, artifacts=[ex.json_path])
        return next(i for i in report.items if i.kind == "artifact")

    item = artifact_item()
    assert item.ok and item.check == "rerun", item.message
    assert "in the C evaluator from seed" in item.message and "1/1 delivered" in item.message
    monkeypatch.setattr(CEvaluator, "velocity", lambda self: np.zeros(self.dim))
    item = artifact_item()
    assert not item.ok and "0/1 delivered" in item.message and "--c-evaluator" in item.message


def test_an_artifact_of_another_model_is_refused(tmp_path: Path, repo: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    ex = export_policy(repo / "models" / "scoop.model.json", tmp_path / "scoop.tli.json",
                       rerun=0)
    code, out, err = run(capsys, "sim", "franka", "--trials", "1", "--duration", "1",
                         "--c-evaluator", str(ex.json_path))
    assert code == 2 and out == "" and err.count("\n") == 1
    assert "not exported from the model being run" in err
