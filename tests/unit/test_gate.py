"""The deployment gate: re-verifies certificates, model coverage and specs."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tli_verify.certify.gate import run_gate
from tli_verify.errors import GateError


def blockers(root: Path) -> list[str]:
    return [f"{b.kind} {b.path}: {b.message}" for b in run_gate(root).blockers]


def test_gate_passes_on_a_certified_project(project: Path) -> None:
    report = run_gate(project)
    assert report.ok
    assert [(i.kind, i.path) for i in report.items] == [
        ("certificate", "certificates/scoop.cert.json"),
        ("model", "models/scoop.model.json"),
        ("spec", "specs/scoop.toml"),
    ]


def test_edited_model_blocks(project: Path) -> None:
    model = project / "models" / "scoop.model.json"
    model.write_text(model.read_text().replace('"prior": 0.', '"prior": 0.0', 1))
    found = blockers(project)
    assert any(b.startswith("certificate certificates/scoop.cert.json:") and "SHA-256" in b
               for b in found)
    assert "model models/scoop.model.json: no valid certificate covers it" in found[-1]


def test_uncertified_model_blocks(project: Path) -> None:
    shutil.copy(project / "models" / "scoop.model.json", project / "models" / "copy.json")
    found = blockers(project)
    assert len(found) == 1
    assert found[0].startswith("model models/copy.json: no valid certificate covers it")


def test_certificate_of_a_missing_model_blocks(project: Path) -> None:
    (project / "models" / "scoop.model.json").unlink()
    found = blockers(project)
    assert len(found) == 1
    assert "scoop.model.json not found" in found[0]


def test_spec_with_the_wrong_declared_verdict_blocks(project: Path, repo: Path) -> None:
    text = (repo / "specs" / "scoop-unrealizable.toml").read_text()
    assert 'expect = "unrealizable"' in text
    (project / "specs" / "lying.toml").write_text(text.replace('expect = "unrealizable"', ""))
    found = blockers(project)
    assert found == ["spec specs/lying.toml: unrealizable, but the spec declares realizable"]


def test_malformed_spec_blocks(project: Path) -> None:
    (project / "specs" / "broken.toml").write_text("this is = not [valid")
    found = blockers(project)
    assert len(found) == 1
    assert found[0].startswith("spec specs/broken.toml: does not load:")


def test_tampered_certificate_blocks(project: Path) -> None:
    cert = project / "certificates" / "scoop.cert.json"
    doc = json.loads(cert.read_text())
    doc["modes"]["c"]["lambda_min_P"] = 0.5
    cert.write_text(json.dumps(doc))
    found = blockers(project)
    assert any("digest does not match" in b for b in found)
    assert any(b.startswith("model models/scoop.model.json") for b in found)


def test_empty_project_passes_and_non_directory_is_usage_error(tmp_path: Path) -> None:
    assert run_gate(tmp_path).ok
    assert run_gate(tmp_path).items == ()
    with pytest.raises(GateError, match="not a directory") as info:
        run_gate(tmp_path / "nope")
    assert info.value.exit_code == 2


def test_repository_gate_passes(repo: Path) -> None:
    report = run_gate(repo)
    assert report.ok, [f"{b.path}: {b.message}" for b in report.blockers]
    assert report.count("certificate") >= 1
    assert report.count("model") >= 1
