"""``tli gate --rerun N`` with the real campaign: evidence that checks does not save a model a
short seeded re-run catches."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.support.evidence import attach_evidence
from tli_verify.certification.certificate import issue_certificate, write_certificate
from tli_verify.cli import main


def test_rerun_blocks_a_model_whose_ds_leaves_its_mode(project: Path,
                                                       capsys: pytest.CaptureFixture[str]
                                                       ) -> None:
    """Mode c's attractor moved into white (mode a's region): c's DS leaves its mode unprovoked.
    The model is re-certified (still Lyapunov-stable) and its evidence re-bound, so every other
    gate check passes; only the re-run campaign finds the invariance failures."""
    model = project / "models" / "scoop.model.json"
    doc = json.loads(model.read_text())
    doc["modes"]["c"]["attractor"] = [-3.0, 0.0]
    model.write_text(json.dumps(doc))
    cert = project / "certificates" / "scoop.cert.json"
    dt = json.loads(cert.read_text())["control_period"]["dt"]  # the task's period (1/100 s)
    write_certificate(issue_certificate(model, cert_path=cert, dt=dt), cert)
    attach_evidence(project)
    from tli_verify.deploy.gate import run_gate

    assert run_gate(project, rerun=0).ok  # without a re-run nothing notices: hashes only
    code = main(["gate", str(project), "--rerun", "4", "--json"])
    out, err = capsys.readouterr()
    assert code == 1
    records = [json.loads(line) for line in out.splitlines()]
    blocked = [r for r in records if r.get("ok") is False]
    assert [(r["check"], r["path"]) for r in blocked] == [("rerun", "models/scoop.model.json")]
    assert "re-ran 4 examples on the gate's own seed" in blocked[0]["message"]
    assert "task 'scoop'" in blocked[0]["message"] and "its own starts" in blocked[0]["message"]
    assert "violations by kind" in blocked[0]["message"]
    assert err.startswith("error: gate blocked: 1 problem(s)") and err.count("\n") == 1


def test_forged_clean_evidence_is_caught_by_the_default_re_run(
        project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Mode b runs mode a's DS (every run fails), the model is re-certified, and its evidence is
    forged clean -- 500 examples, 0 violations, a correct digest, every hash right. Every check
    of the evidence passes; the gate's own re-run, on a seed it derives from the files, blocks
    without being asked to."""
    from tli_verify.deploy.gate import run_gate

    model = project / "models" / "scoop.model.json"
    doc = json.loads(model.read_text())
    doc["modes"]["b"] = dict(doc["modes"]["a"], mode="b", next_mode="c")
    model.write_text(json.dumps(doc))
    cert = project / "certificates" / "scoop.cert.json"
    write_certificate(issue_certificate(model, cert_path=cert, dt="1/100"), cert)
    attach_evidence(project)
    assert run_gate(project, rerun=0).ok  # the hashes and claims alone: it would pass
    code = main(["gate", str(project), "--json"])
    out, err = capsys.readouterr()
    assert code == 1 and err.startswith("error: gate blocked: 1 problem(s)")
    blocked = [r for r in (json.loads(x) for x in out.splitlines()) if r.get("ok") is False]
    assert [(r["check"], r["path"]) for r in blocked] == [("rerun", "models/scoop.model.json")]
    assert "re-ran 50 examples on the gate's own seed" in blocked[0]["message"]
