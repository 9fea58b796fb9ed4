"""Campaign evidence: forgeries only the evidence check catches.

Every forgery below leaves the spec, the model and the certificate valid, so the gate's other
checks pass; only the ``campaign`` line may block, and must, naming the file and what differs.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.support.evidence import attach_evidence
from tli_verify.certification.certificate import issue_certificate, write_certificate
from tli_verify.cli import main
from tli_verify.commands import exit_code
from tli_verify.deploy.gate import run_gate
from tli_verify.errors import EvidenceError, OutputError
from tli_verify.io import canonical_json, sha256_file
from tli_verify.limits import MAX_INPUT_BYTES
from tli_verify.tasks.registry import find_task
from tli_verify.verify.evidence import (
    MIN_EVIDENCE_EXAMPLES,
    check_evidence,
    deployed_task_block,
    evidence_digest,
    evidence_path_for,
    task_block,
    task_content_sha256,
    write_evidence,
)

EVIDENCE = Path("certificates") / "scoop.campaign.json"


def only_campaign_blocks(project: Path) -> str:
    """The gate blocks on the campaign line of the model, and on nothing else; its message."""
    report = run_gate(project, rerun=0)
    found = [(b.kind, b.path, b.check) for b in report.blockers]
    assert found == [("model", "models/scoop.model.json", "campaign")], \
        [f"{b.path}: {b.check}: {b.message}" for b in report.blockers]
    message = report.blockers[0].message
    assert message.startswith("certificates/scoop.campaign.json: ")
    return message


def forge(project: Path, edit: Callable[[dict[str, Any]], None], *,
          redigest: bool = True) -> None:
    """Edit the evidence and (by default) make its digest consistent again."""
    path = project / EVIDENCE
    doc = json.loads(path.read_text())
    edit(doc)
    if redigest:
        doc["digest"] = evidence_digest(doc)
    path.write_text(canonical_json(doc))


def leaves(obj: Any, prefix: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from leaves(v, (*prefix, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from leaves(v, (*prefix, i))
    else:
        yield prefix


def test_fresh_evidence_passes_and_binds_the_three_files(project: Path) -> None:
    report = run_gate(project, rerun=0)
    assert report.ok, [b.message for b in report.blockers]
    line = [i for i in report.items if i.check == "campaign"]
    assert len(line) == 1 and line[0].ok
    assert f"{MIN_EVIDENCE_EXAMPLES} examples" in line[0].message
    check = check_evidence(project / EVIDENCE)
    assert check.ok, check.problems
    doc = json.loads((project / EVIDENCE).read_text())
    for key, path in (("model", "models/scoop.model.json"), ("spec", "specs/scoop.toml"),
                      ("certificate", "certificates/scoop.cert.json")):
        assert doc[key] == {"path": os.path.relpath(project / path, project / "certificates"),
                            "sha256": sha256_file(project / path)}
    assert doc["violations"] == {"total": 0, "by_kind": {}}
    assert doc["campaign"]["failure_probability_bound_95"] == pytest.approx(
        3 / MIN_EVIDENCE_EXAMPLES)


def test_evidence_for_another_models_hash_blocks(project: Path) -> None:
    other = project / "other.model.json"  # another (loadable) model: one A_k entry changed
    doc = json.loads((project / "models" / "scoop.model.json").read_text())
    doc["modes"]["a"]["components"][0]["A"][0][0] *= 1.01
    other.write_text(json.dumps(doc))
    forge(project, lambda d: d["model"].update(sha256=sha256_file(other)))
    message = only_campaign_blocks(project)
    assert "differs from the evidence's" in message
    assert "the campaign ran another model" in message


def test_evidence_naming_another_model_file_blocks(project: Path) -> None:
    """The evidence points at a copy of the model (same bytes, same hash): still not the
    deployed file."""
    shutil.copy(project / "models" / "scoop.model.json", project / "copy.model.json")
    forge(project, lambda d: d["model"].update(path="../copy.model.json"))
    message = only_campaign_blocks(project)
    assert "is not the deployed model" in message and "binds another model" in message


@pytest.mark.parametrize(("key", "said"), [
    ("spec", "the spec changed after the campaign"),
    ("certificate", "the certificate changed after the campaign"),
    ("model", "the campaign ran another model"),
])
def test_a_hash_edited_with_the_digest_recomputed_blocks(project: Path, key: str,
                                                         said: str) -> None:
    forge(project, lambda d: d[key].update(sha256="0" * 64))
    message = only_campaign_blocks(project)
    assert said in message and "0000000000" in message


def test_stale_evidence_after_the_model_was_re_certified_blocks(project: Path) -> None:
    model = project / "models" / "scoop.model.json"
    doc = json.loads(model.read_text())
    doc["modes"]["b"]["components"][0]["A"][1][1] *= 1.001
    model.write_text(json.dumps(doc))
    cert = project / "certificates" / "scoop.cert.json"
    write_certificate(issue_certificate(model, cert_path=cert, dt="1/100"), cert)
    message = only_campaign_blocks(project)
    assert "models/scoop.model.json: SHA-256" in message
    attach_evidence(project)  # a new campaign on the new files: passes again
    assert run_gate(project, rerun=0).ok


@pytest.mark.parametrize(("edit", "said"), [
    (lambda d: d["violations"].update(total=1, by_kind={"invariance": 1}),
     "found 1 violation(s) (invariance: 1)"),
    (lambda d: d["violations"].update(by_kind={"looping": 1}),  # total left at 0
     "violations.total 0 is not the sum"),
    (lambda d: d.update(counterexample={"sequence": [[3, [0.1, 0.0]]]}),
     "records a counterexample"),
    (lambda d: d["campaign"].update(examples=MIN_EVIDENCE_EXAMPLES - 1),
     f"fewer than the minimum {MIN_EVIDENCE_EXAMPLES}"),
    (lambda d: d["campaign"].update(runs=MIN_EVIDENCE_EXAMPLES - 1),
     "every example is at least one run"),
    (lambda d: d["campaign"].update(modulation=False), "ran without modulation"),
    (lambda d: d["campaign"].update(partial=True), "interrupted (partial)"),
    (lambda d: d.update(world="nowhere"), "world 'nowhere' is not the name of the task"),
    (lambda d: d.update(campaign_semantics=d["campaign_semantics"] + 1),
     "this tool's are"),
], ids=["violation", "inconsistent-total", "counterexample", "too-few-examples",
        "too-few-runs", "no-modulation", "partial", "unknown-world", "other-semantics"])
def test_a_campaign_that_is_no_evidence_blocks(project: Path, edit: Callable[[Any], None],
                                               said: str) -> None:
    forge(project, edit)
    assert said in only_campaign_blocks(project)


def test_every_field_edited_without_the_digest_is_caught(project: Path) -> None:
    doc = json.loads((project / EVIDENCE).read_text())
    paths = [p for p in leaves(doc) if p != ("digest",)]
    assert len(paths) >= 20
    for path in paths:
        target = doc
        for part in path[:-1]:
            target = target[part]
        old = target[path[-1]]
        new: Any = (not old if isinstance(old, bool) else old + 1 if isinstance(old, int)
                    else old * 2 if isinstance(old, float)
                    else ("0" * 64 if len(old) == 64 else old + "x") if isinstance(old, str)
                    else 1)
        target[path[-1]] = new
        (project / EVIDENCE).write_text(canonical_json(doc))
        problems = check_evidence(project / EVIDENCE).problems
        assert any("digest does not match the content" in p or "malformed" in p
                   for p in problems), path
        target[path[-1]] = old
    (project / EVIDENCE).write_text(canonical_json(doc))
    assert check_evidence(project / EVIDENCE).ok


def test_missing_evidence_blocks(project: Path) -> None:
    (project / EVIDENCE).unlink()
    report = run_gate(project, rerun=0)
    assert [(b.kind, b.path, b.check, b.message) for b in report.blockers] == [
        ("model", "models/scoop.model.json", "campaign",
         "no campaign evidence certificates/scoop.campaign.json (run: tli evidence ., or "
         "tli verify --model models/scoop.model.json --evidence)")]


def test_a_symlinked_evidence_file_is_refused_never_followed(project: Path,
                                                             tmp_path_factory: Any) -> None:
    elsewhere = tmp_path_factory.mktemp("elsewhere") / "scoop.campaign.json"
    shutil.copy(project / EVIDENCE, elsewhere)
    (project / EVIDENCE).unlink()
    os.symlink(elsewhere, project / EVIDENCE)
    assert "a symlink: refused, never followed" in only_campaign_blocks(project)


@pytest.mark.parametrize("content", [
    b"\x00\x01garbage\xff" * 10,
    b"{" * 5000,
    b'{"schema_version": 1}',
    b"not json at all",
], ids=["binary", "deep", "schema", "text"])
def test_garbage_evidence_blocks_with_one_line(project: Path, content: bytes,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    (project / EVIDENCE).write_bytes(content)
    assert "malformed campaign evidence" in only_campaign_blocks(project)
    code = main(["gate", str(project)])
    err = capsys.readouterr().err
    assert code == 1
    assert err.count("\n") == 1 and err.startswith("error: gate blocked: 1 problem(s)")
    assert "Traceback" not in err and "internal error" not in err


def test_a_fifo_or_directory_in_place_of_the_evidence_blocks_without_reading(
        project: Path) -> None:
    (project / EVIDENCE).unlink()
    os.mkfifo(project / EVIDENCE)  # reading it would block forever
    assert "not a regular file" in only_campaign_blocks(project)
    (project / EVIDENCE).unlink()
    (project / EVIDENCE).mkdir()
    assert "is a directory" in only_campaign_blocks(project)


def test_a_huge_evidence_file_is_not_read(project: Path) -> None:
    with open(project / EVIDENCE, "wb") as handle:
        handle.truncate(MAX_INPUT_BYTES + 1)  # sparse: nothing is written, nothing read
    message = only_campaign_blocks(project)
    assert "larger than the limit" in message and "MAX_INPUT_BYTES" in message


def test_evidence_of_no_deployed_model_blocks(project: Path) -> None:
    shutil.copy(project / EVIDENCE, project / "certificates" / "ghost.campaign.json")
    report = run_gate(project, rerun=0)
    assert [(b.kind, b.path) for b in report.blockers] == [
        ("evidence", "certificates/ghost.campaign.json")]
    assert "binds no deployed model" in report.blockers[0].message


def test_evidence_files_are_not_certificates(project: Path) -> None:
    report = run_gate(project, rerun=0)
    assert report.count("certificate") == 1  # scoop.cert.json only


def test_evidence_path_mirrors_the_model_path(tmp_path: Path) -> None:
    assert evidence_path_for(tmp_path / "models" / "scoop.model.json") == \
        tmp_path / "certificates" / "scoop.campaign.json"
    assert evidence_path_for(tmp_path / "models" / "sub" / "x.json") == \
        tmp_path / "certificates" / "sub" / "x.campaign.json"
    assert evidence_path_for(tmp_path / "elsewhere" / "x.model.json") == \
        tmp_path / "elsewhere" / "x.campaign.json"  # outside any models/ folder: next to it


def test_write_evidence_refuses_bad_output_and_missing_files(project: Path) -> None:
    fields: dict[str, Any] = {
        "world": "scoop", "task": task_block(find_task("scoop"), project),
        "spec": project / "specs" / "scoop.toml",
        "model": project / "models" / "scoop.model.json",
        "certificate": project / "certificates" / "scoop.cert.json", "seed": 1,
        "examples": 10, "runs": 10, "violations": {}, "modulation": True}
    with pytest.raises(OutputError, match="would overwrite the input file"):
        write_evidence(project / "models" / "scoop.model.json", **fields)
    with pytest.raises(EvidenceError, match="model file not found") as info:
        write_evidence(project / "x.campaign.json", **{**fields, "model": project / "nope"})
    assert exit_code(info.value) == 2
    with pytest.raises(EvidenceError, match=r"campaign\.seed") as info:
        write_evidence(project / "x.campaign.json", **{**fields, "seed": 2**32})
    assert exit_code(info.value) == 2
    assert not (project / "x.campaign.json").exists()


def test_rerun_blocks_when_the_campaign_finds_a_violation(project: Path) -> None:
    """The gate's wiring of ``--rerun``: the runner gets the evidence's seed and world, and its
    verdict is one ``rerun`` line (the real campaign: tests/integration/test_gate_rerun.py)."""
    calls: list[tuple[str | None, int | None, str, int]] = []

    def runner(check: Any, model: Path, examples: int) -> tuple[bool, str]:
        calls.append((check.world, check.seed, model.name, examples))
        return False, "re-ran: 1 violation(s) (invariance: 1)"

    report = run_gate(project, rerun=7, campaign_runner=runner)
    assert calls == [("scoop", 0, "scoop.model.json", 7)]
    assert [(b.check, b.message) for b in report.blockers] == [
        ("rerun", "re-ran: 1 violation(s) (invariance: 1)")]
    forge(project, lambda d: d["campaign"].update(partial=True))
    calls.clear()
    run_gate(project, rerun=7, campaign_runner=runner)
    assert calls == []  # no re-run from evidence that does not check


def test_gate_rerun_argument_is_checked(project: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["gate", str(project), "--rerun", "0"])
    assert info.value.code == 2
    assert "--rerun" in capsys.readouterr().err


def test_schema_version_1_evidence_without_a_task_is_refused(project: Path) -> None:
    """Evidence of a former schema (1: no ``task`` block) binds no task: it blocks, saying to
    re-run the campaign."""
    def downgrade(doc: dict[str, Any]) -> None:
        doc["schema_version"] = 1
        del doc["task"]
        del doc["campaign_semantics"]

    forge(project, downgrade)
    message = only_campaign_blocks(project)
    assert "evidence schema 1" in message and "re-run the campaign" in message


# --------------------------------------------------------------------------------------------
# The task binding: forgeries only the task check catches (the spec, model, certificate and
# campaign stay valid, the digest is recomputed)
# --------------------------------------------------------------------------------------------

YELLOW_UPPER = "upper = [inf, -4.0]"  # tasks/scoop.toml: the soup's surface (region yellow)


def edited_scoop_task(repo: Path, dest: Path) -> Path:
    """A copy of ``tasks/scoop.toml`` at ``dest`` whose yellow region ends lower."""
    text = (repo / "tasks" / "scoop.toml").read_text()
    assert text.count(YELLOW_UPPER) == 1
    dest.parent.mkdir(parents=True, exist_ok=True)
    dest.write_text(text.replace(YELLOW_UPPER, "upper = [inf, -4.5]"))
    return dest


def only_the_task_check_fails(project: Path) -> str:
    """check_evidence refuses the evidence for one reason, the task's; that problem."""
    check = check_evidence(project / EVIDENCE, model_path=project / "models" / "scoop.model.json")
    assert len(check.problems) == 1, check.problems
    assert not any(p.startswith("task ") for p in check.passed), check.passed
    assert "digest matches the content" in check.passed
    return check.problems[0]


def test_evidence_on_an_edited_copy_of_the_task_is_refused(project: Path, repo: Path) -> None:
    copy = edited_scoop_task(repo, project / "elsewhere" / "scoop.toml")
    task = find_task(copy)  # a valid task of the same name, hashed honestly
    assert task.name == "scoop" and task.source.sha256 == sha256_file(copy)
    bundled = sha256_file(repo / "tasks" / "scoop.toml")
    assert task.source.sha256 != bundled
    forge(project, lambda d: d.update(task=task_block(task, project / "certificates")))
    doc = json.loads((project / EVIDENCE).read_text())
    assert doc["task"]["path"] == "../elsewhere/scoop.toml"
    assert evidence_digest(doc) == doc["digest"]
    message = only_the_task_check_fails(project)
    assert "the campaign ran on task 'scoop' (../elsewhere/scoop.toml, SHA-256 " \
        f"{task.source.sha256[:12]}...)" in message
    assert "the deployed spec's task is 'scoop' (" in message and bundled[:12] in message
    assert "another task, or the task changed after the campaign" in message
    assert message.split(": ", 1)[1] in only_campaign_blocks(project)


def test_evidence_on_another_task_is_refused(project: Path, repo: Path) -> None:
    """The scoop model's evidence made on the cooking task (world and task block both say
    cooking: a consistent forgery)."""
    cooking = find_task("cooking")
    forge(project, lambda d: d.update(world="cooking",
                                      task=task_block(cooking, project / "certificates")))
    message = only_the_task_check_fails(project)
    assert "the campaign ran on task 'cooking' (" in message and "cooking.toml" in message
    assert sha256_file(repo / "tasks" / "cooking.toml")[:12] in message
    assert "but the deployed spec's task is 'scoop'" in message
    assert message.split(": ", 1)[1] in only_campaign_blocks(project)


def test_a_spec_naming_no_task_blocks_its_models_evidence(project: Path) -> None:
    spec = project / "specs" / "scoop.toml"
    lines = spec.read_text().splitlines(keepends=True)
    kept = [line for line in lines if not line.startswith("task = ")]
    assert len(kept) == len(lines) - 1
    spec.write_text("".join(kept))
    model = project / "models" / "scoop.model.json"
    cert = project / "certificates" / "scoop.cert.json"
    dt = json.loads(cert.read_text())["control_period"]["dt"]  # the task's period (1/100 s)
    write_certificate(issue_certificate(model, cert_path=cert, dt=dt), cert)  # the new spec
    attach_evidence(project)  # binds the new files (and the bundled scoop task)
    message = only_the_task_check_fails(project)
    assert "the deployed task cannot be resolved" in message
    assert "the spec names no task" in message
    report = run_gate(project, rerun=0)  # the model's own task check blocks too, saying why
    found = {(b.check, b.message) for b in report.blockers}
    assert {c for c, _ in found} == {"task", "campaign"}
    assert any(c == "task" and "names no task" in m for c, m in found)
    assert any(c == "campaign" and message.split(": ", 1)[1] in m for c, m in found)


def test_honest_evidence_binds_the_deployed_specs_task(project: Path, repo: Path) -> None:
    model = project / "models" / "scoop.model.json"
    check = check_evidence(project / EVIDENCE, model_path=model)
    assert check.ok, check.problems
    assert "task 'scoop' is the deployed spec's and matches its SHA-256" in check.passed
    doc = json.loads((project / EVIDENCE).read_text())
    bundled = (repo / "tasks" / "scoop.toml").resolve()
    assert doc["task"] == {
        "name": "scoop", "kind": "file",
        "path": Path(os.path.relpath(bundled, (project / "certificates").resolve())).as_posix(),
        "sha256": sha256_file(bundled), "content_sha256": task_content_sha256(bundled)}
    assert deployed_task_block(model, project / "certificates") == doc["task"]
    report = run_gate(project, rerun=0)
    assert report.ok, [b.message for b in report.blockers]
    line = next(i for i in report.items if i.check == "campaign")
    assert "campaign on task 'scoop'" in line.message
    assert "binds its task, spec, model and certificate" in line.message


def test_a_project_task_edited_after_the_campaign_blocks(project: Path, repo: Path) -> None:
    """The spec's task found in the project's own ``tasks/``: bound by that file; a region
    edited there after the campaign blocks."""
    (project / "tasks").mkdir()
    shutil.copy(repo / "tasks" / "scoop.toml", project / "tasks" / "scoop.toml")
    attach_evidence(project)
    doc = json.loads((project / EVIDENCE).read_text())
    assert doc["task"]["path"] == "../tasks/scoop.toml"
    assert run_gate(project, rerun=0).ok
    edited_scoop_task(repo, project / "tasks" / "scoop.toml")
    message = only_the_task_check_fails(project)
    assert "the deployed spec's task is 'scoop' (../tasks/scoop.toml, SHA-256 " \
        f"{sha256_file(project / 'tasks' / 'scoop.toml')[:12]}...)" in message
    assert "its content changed since the campaign (not only comments" in message
    assert message.split(": ", 1)[1] in only_campaign_blocks(project)


FORGED_SETTINGS = [
    ("target_examples", 2.5), ("target_examples", 10**9), ("target_examples", -1),
    ("target_examples", True), ("batch_size", 0), ("batch_size", 10**9), ("window", 10**12),
    ("window", 700.0), ("max_pushes", 10**6), ("lag", -1), ("lag", "0"), ("max_cycles", -3),
    ("levels", ["push", "teleport"]), ("levels", []), ("shrink", 1), ("random_starts", "yes"),
    ("start", [0.0, "x"]), ("workers_per_batch", 2),
]


@pytest.mark.parametrize(("key", "value"), FORGED_SETTINGS)
def test_every_recorded_setting_is_validated_with_the_cli_limits(project: Path, key: str,
                                                                 value: Any) -> None:
    """A setting forged with the digest recomputed blocks the gate, without a re-run (issue 32:
    ``target_examples`` 2.5 or 1e9 passed, since only the settings the re-run used were
    checked)."""
    forge(project, lambda doc: doc["campaign"]["settings"].__setitem__(key, value))
    message = only_campaign_blocks(project)
    assert "campaign.settings" in message and key in message, message


def _with_task(project: Path, repo: Path) -> Path:
    (project / "tasks").mkdir()
    task = project / "tasks" / "scoop.toml"
    shutil.copy(repo / "tasks" / "scoop.toml", task)
    attach_evidence(project)  # binds the project's own task file
    assert run_gate(project, rerun=0).ok
    return task


@pytest.mark.parametrize("edit", [
    lambda t: t + "\n# a note on the task\n",
    lambda t: "# header comment\n\n" + t.replace("\n", "\n\n", 3),
    lambda t: t.replace("\n", "  # trailing\n", 1) if t.split("\n", 1)[0].strip() and
    not t.split("\n", 1)[0].rstrip().endswith(('"""', "'''")) else t + "#\n",
])
def test_a_comment_only_edit_of_the_task_does_not_block(project: Path, repo: Path,
                                                        edit: Callable[[str], str]) -> None:
    """Issue 32: editing a comment of the task file blocked the gate (the hash covered bytes,
    not meaning). The evidence's content hash matches: it passes, and the line says why."""
    task = _with_task(project, repo)
    task.write_text(edit(task.read_text()))
    report = run_gate(project, rerun=0)
    assert report.ok, [b.message for b in report.blockers]
    line = next(i for i in report.items if i.check == "campaign")
    assert "only its comments or formatting changed" in line.message


def test_a_change_of_the_task_blocks_and_says_it_is_not_a_comment(project: Path,
                                                                 repo: Path) -> None:
    task = _with_task(project, repo)
    text = task.read_text()
    assert "max_pushes = 3" in text
    task.write_text(text.replace("max_pushes = 3", "max_pushes = 2"))
    message = only_campaign_blocks(project)
    assert "its content changed since the campaign (not only comments" in message
    assert message.count("certificates/scoop.campaign.json") == 1  # the path once


def test_old_evidence_without_a_content_hash_says_what_to_do(project: Path,
                                                            repo: Path) -> None:
    task = _with_task(project, repo)
    forge(project, lambda doc: doc["task"].pop("content_sha256"))
    task.write_text(task.read_text() + "# a comment\n")
    message = only_campaign_blocks(project)
    assert "records no content hash" in message and "tli evidence" in message
