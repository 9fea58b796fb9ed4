"""The deployment gate: re-verifies certificates, model coverage and specs."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest

from tests.support.evidence import attach_evidence
from tli_verify.certification.certificate import (
    check_certificate,
    issue_certificate,
    write_certificate,
)
from tli_verify.commands import exit_code
from tli_verify.deploy.gate import run_gate
from tli_verify.errors import GateError


def blockers(root: Path, *, campaign: bool = False) -> list[str]:
    """What blocks, without the campaign-evidence lines unless ``campaign`` (the tests of the
    other checks edit files, which makes the fixture's evidence stale too)."""
    return [f"{b.kind} {b.path}: {b.message}" for b in run_gate(root, rerun=0).blockers
            if campaign or b.check != "campaign"]


def edit_model(project: Path, edit: Any) -> None:
    """Edit the deployed model, re-certify it (a certificate that is itself valid) and re-bind
    the campaign evidence to the new files."""
    path = project / "models" / "scoop.model.json"
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    cert = project / "certificates" / "scoop.cert.json"
    write_certificate(issue_certificate(path, cert_path=cert, dt="1/100"), cert)  # the task's
    assert check_certificate(cert).ok
    attach_evidence(project)


def test_gate_passes_on_a_certified_project(project: Path) -> None:
    report = run_gate(project, rerun=0)
    assert report.ok
    assert [(i.kind, i.path, i.check) for i in report.items] == [
        ("spec", "specs/scoop.toml", "re-check"),
        ("certificate", "certificates/scoop.cert.json", "re-check"),
        ("model", "models/scoop.model.json", "certificate"),
        ("model", "models/scoop.model.json", "dimension"),
        ("model", "models/scoop.model.json", "spec"),
        ("model", "models/scoop.model.json", "modes"),
        ("model", "models/scoop.model.json", "task"),
        ("model", "models/scoop.model.json", "handoff"),
        ("model", "models/scoop.model.json", "campaign"),
    ]


def test_model_missing_modes_and_with_a_foreign_mode_blocks(project: Path) -> None:
    """Issue reproduction: drop modes c and d, add a mode zzz, re-certify: the gate passed."""

    def edit(doc: dict[str, Any]) -> None:
        doc["modes"]["zzz"] = dict(doc["modes"].pop("c"), mode="zzz", next_mode=None)
        del doc["modes"]["d"]

    edit_model(project, edit)
    found = blockers(project)
    assert len(found) == 1
    assert found[0].startswith("model models/scoop.model.json: DS 'zzz' names mode 'zzz', "
                               "which specs/scoop.toml lacks")
    assert "no DS for mode 'c', which the automaton can run" in found[0]
    assert "no DS for mode 'd'" in found[0]


def test_per_transition_model_needs_every_transition_out_of_its_mode(project: Path) -> None:
    def split_b(doc: dict[str, Any]) -> None:  # b's DS only towards c, none towards a
        doc["modes"]["b->c"] = dict(doc["modes"].pop("b"), mode="b", next_mode="c")

    edit_model(project, split_b)
    found = blockers(project)
    assert found == ["model models/scoop.model.json: no per-transition DS b->a for a transition "
                     "the automaton can take"]

    def add_b_a(doc: dict[str, Any]) -> None:
        doc["modes"]["b->a"] = dict(doc["modes"]["b->c"], next_mode="a")

    edit_model(project, add_b_a)
    assert run_gate(project, rerun=0).ok


def test_model_without_a_spec_or_with_an_unrealizable_one_blocks(project: Path,
                                                                 repo: Path) -> None:
    edit_model(project, lambda doc: doc.update(spec=None))
    assert blockers(project) == [
        "model models/scoop.model.json: names no spec: a deployed model must name the spec "
        "whose automaton runs it (\"spec\" field)"]
    shutil.copy(repo / "specs" / "scoop-unrealizable.toml", project / "specs")
    edit_model(project, lambda doc: doc.update(spec="../specs/scoop-unrealizable.toml"))
    assert blockers(project) == [
        "model models/scoop.model.json: its spec specs/scoop-unrealizable.toml is "
        "unrealizable: no automaton can run it"]


def test_edited_model_blocks(project: Path) -> None:
    model = project / "models" / "scoop.model.json"
    doc = json.loads(model.read_text())
    doc["modes"]["a"]["components"][0]["A"][0][0] *= 1.01  # still a loadable model
    model.write_text(json.dumps(doc))
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
    assert len(found) == 2
    assert "scoop.model.json not found" in found[0]
    assert found[1].startswith("project .: nothing to gate")


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


def test_nothing_to_gate_fails_closed_and_non_directory_is_usage_error(tmp_path: Path,
                                                                       repo: Path) -> None:
    report = run_gate(tmp_path, rerun=0)
    assert not report.ok
    assert [f"{b.kind} {b.path}: {b.message}" for b in report.blockers] == [
        "project .: nothing to gate: no model under "
        "models/ to deploy (the gate fails closed)"]
    shutil.copytree(repo / "specs", tmp_path / "specs")  # specs alone: still nothing to deploy
    assert [b.kind for b in run_gate(tmp_path, rerun=0).blockers] == ["project"]
    with pytest.raises(GateError, match="not a directory") as info:
        run_gate(tmp_path / "nope", rerun=0)
    assert exit_code(info.value) == 2


def test_repository_gate_passes(repo: Path) -> None:
    report = run_gate(repo, rerun=0)
    assert report.ok, [f"{b.path}: {b.message}" for b in report.blockers]
    assert report.count("certificate") >= 1
    assert report.count("model") >= 1


def test_irregular_files_block_instead_of_being_skipped(project: Path) -> None:
    import os

    os.mkfifo(project / "models" / "pipe.json")
    os.symlink(project / "nowhere.json", project / "certificates" / "dangling.json")
    found = blockers(project)
    assert sorted(found) == sorted([
        "model models/pipe.json: not a regular file (a device, FIFO, socket or dangling link): "
        "refused, never read",
        "certificate certificates/dangling.json: not a regular file (a "
        "device, FIFO, socket or dangling link): refused, never read"])


def test_certificate_states_the_declared_numeric_ranges(project: Path) -> None:
    cert = project / "certificates" / "scoop.cert.json"
    doc = json.loads(cert.read_text())
    assert doc["well_posed"]["velocity_finite"] is True
    doc["well_posed"]["limits"]["max_abs_value"] = 1e300  # claim a laxer range, digest redone
    from tli_verify.certification.certificate import certificate_digest
    from tli_verify.io import canonical_json

    doc["digest"] = certificate_digest(doc)
    cert.write_text(canonical_json(doc))
    problems = check_certificate(cert).problems
    assert len(problems) == 1
    assert "well_posed.limits differ from this tool's declared ranges" in problems[0]


def test_symlinked_directories_block(project: Path, tmp_path_factory: pytest.TempPathFactory
                                     ) -> None:
    import os

    hidden = tmp_path_factory.mktemp("hidden")
    shutil.copy(project / "models" / "scoop.model.json", hidden / "uncertified.json")
    os.symlink(hidden, project / "models" / "sub")
    found = blockers(project)
    assert found == ["model models/sub: not a regular file (a symlinked directory, not "
                     "followed): refused, never read"]


def test_spec_path_through_a_symlink_and_dotdot_binds_the_file_the_os_opens(
        project: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """Reviewer's forgery: ``sub/../../specs/scoop.toml`` with ``sub`` a symlink elsewhere.

    The OS follows the link first, so the spec the model names is *not* the project's. The
    certificate must bind that file, and pointing the certificate at the project's spec (hashes
    and digest redone) must not pass."""
    import os

    from tli_verify.certification.certificate import certificate_digest
    from tli_verify.io import canonical_json, sha256_file

    outside = tmp_path_factory.mktemp("outside")
    (outside / "a" / "x").mkdir(parents=True)
    (outside / "specs").mkdir()
    evil = outside / "specs" / "scoop.toml"  # what sub/../../specs opens: outside/a/x/../..
    evil.write_text((project / "specs" / "scoop.toml").read_text() + "\n# another spec\n")
    os.symlink(outside / "a" / "x", project / "models" / "sub")

    def point(doc: dict[str, Any]) -> None:
        doc["spec"] = "sub/../../specs/scoop.toml"

    # certify binds the file the OS opens (evil), and check-cert agrees with certify
    edit_model(project, point)
    cert = project / "certificates" / "scoop.cert.json"
    doc = json.loads(cert.read_text())
    assert Path(os.path.realpath(cert.parent / doc["spec"]["path"])) == evil.resolve()
    # forging the certificate onto the project's spec is caught
    doc["spec"] = {"path": "../specs/scoop.toml",
                   "sha256": sha256_file(project / "specs" / "scoop.toml")}
    doc["digest"] = certificate_digest(doc)
    cert.write_text(canonical_json(doc))
    problems = check_certificate(cert).problems
    assert any("is not the spec the model names" in p for p in problems)


def test_per_transition_goal_mode_without_a_ds_the_runtime_can_pick_blocks(
        project: Path) -> None:
    """Review finding: goal mode d keyed only 'd->a' passed the gate, but the runtime never plans
    d -> a (d only stays), so it had no DS to run in d."""

    def key_d_as_transition(doc: dict[str, Any]) -> None:
        doc["modes"]["d->a"] = dict(doc["modes"].pop("d"), mode="d", next_mode="a")

    edit_model(project, key_d_as_transition)
    found = blockers(project)
    assert len(found) == 1
    assert "no DS to run in automaton state" in found[0]
    assert "(mode 'd'): no plain DS 'd'" in found[0]
    assert "none: it only stays in the mode" in found[0]
