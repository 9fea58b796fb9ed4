"""No command writes over a file it reads, named, defaulted or implied (issue class: data loss).

Each command knows every file it reads -- the files on its command line, the defaults (the
bundled task, spec, model, certificate), the implied ones (the spec a model names, the task a
spec names, the certificate by the project layout) -- and every file it writes (``-o``, the
sidecar certificate of ``tli run -o``, the files inside ``--out``, evidence, pictures). Before
any work it refuses an output that is one of its inputs or another of its outputs: exit 2, one
``error:`` line, every file unchanged. The cases are drawn by hypothesis from the product of
commands, the outputs they write, and the inputs they read.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.support.cli import run

REPO = Path(__file__).resolve().parents[2]

INPUTS = {  # what a scoop run reads, relative to the project
    "task": "tasks/scoop.toml",
    "spec": "specs/scoop.toml",
    "model": "models/scoop.model.json",
    "certificate": "certificates/scoop.cert.json",
    "evidence": "certificates/scoop.campaign.json",
}


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("hostile") / "p"
    for sub in ("tasks", "specs", "models", "certificates"):
        (root / sub).mkdir(parents=True)
    for rel in INPUTS.values():
        shutil.copy(REPO / rel, root / rel)
    return root


def _snapshot(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def _refused(capsys: pytest.CaptureFixture[str], root: Path, argv: list[str],
             *fragments: str) -> None:
    before = _snapshot(root)
    code, out, err = run(capsys, *argv)
    assert code == 2, (argv, code, out, err)
    assert err.startswith("error: ") and err.count("\n") == 1, err
    for f in fragments:
        assert f in err, (argv, err)
    assert _snapshot(root) == before, argv  # nothing lost, nothing written


def _cmd(name: str, root: Path, output: str) -> list[str]:
    """A command of the scoop project writing ``output`` (relative to the project)."""
    o = str(root / output)
    spec, model = str(root / INPUTS["spec"]), str(root / INPUTS["model"])
    return {
        "run -o": ["run", "--model", model, "--out", str(root / "out"), "-o", o],
        "run --grown-spec": ["run", "--model", model, "--spec", spec, "--learn-transitions",
                             "--out", str(root / "out"), "--grown-spec", o],
        "verify --evidence": ["verify", "--model", model, "--examples", "5", "--out",
                              str(root / "out"), "--evidence", o],
        "certify -o": ["certify", model, "-o", o],
        "certify --repair": ["certify", model, "--repair", o],
        "task check --picture": ["task", "check", str(root / INPUTS["task"]), "--picture", o],
        "spec automaton -o": ["spec", "automaton", spec, "-o", o],
    }[name]


COMMANDS = ["run -o", "run --grown-spec", "verify --evidence", "certify -o", "certify --repair",
            "task check --picture", "spec automaton -o"]
READS = {  # which of the inputs each command reads (named or implied)
    "run -o": ["task", "spec", "model", "certificate"],
    "run --grown-spec": ["task", "spec", "model", "certificate"],
    "verify --evidence": ["task", "spec", "model", "certificate"],
    "certify -o": ["task", "spec", "model"],
    "certify --repair": ["task", "spec", "model"],
    "task check --picture": ["task"],
    "spec automaton -o": ["spec"],
}


@settings(max_examples=40, deadline=None, suppress_health_check=[
    HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_no_command_writes_over_a_file_it_reads(project: Path,
                                                capsys: pytest.CaptureFixture[str],
                                                data: st.DataObject) -> None:
    command = data.draw(st.sampled_from(COMMANDS), label="command")
    victim = data.draw(st.sampled_from(READS[command]), label="input")
    _refused(capsys, project, _cmd(command, project, INPUTS[victim]), "input file")


def test_run_files_inside_out_are_outputs_too(project: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """``tli run --out D`` writes D/run.json and D/run.png: a model named D/run.json is not
    turned into the episode record."""
    d = project / "out-inside"
    d.mkdir(exist_ok=True)
    moved = d / "run.json"
    shutil.copy(project / INPUTS["model"], moved)
    try:
        _refused(capsys, project, ["run", "--model", str(moved), "--certificate",
                                   str(project / INPUTS["certificate"]), "--out", str(d)],
                 "run.json", "input file")
    finally:
        moved.unlink()


def test_verify_report_inside_out_never_overwrites_its_evidence(
        project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--evidence D/campaign.json --out D``: the evidence and the report would be one file."""
    d = project / "out-ev"
    _refused(capsys, project, ["verify", "--model", str(project / INPUTS["model"]),
                               "--examples", "5", "--out", str(d), "--evidence",
                               str(d / "campaign.json")],
             "would be the same file")


def test_a_sidecar_certificate_over_an_input_is_refused(project: Path,
                                                        capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    """``tli run -o models/X.model.json`` writes its certificate where the project layout puts
    it (certificates/X.cert.json): when that is the certificate the run reads, refused."""
    _refused(capsys, project, ["run", "--model", str(project / INPUTS["model"]),
                               "--certificate", str(project / INPUTS["certificate"]),
                               "--out", str(project / "out"),
                               "-o", str(project / "models" / "scoop.model.json")],
             "input file")


def test_outputs_never_collide_with_each_other(project: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    d = project / "out-col"
    _refused(capsys, project, ["run", "--model", str(project / INPUTS["model"]), "--out",
                               str(d), "-o", str(d / "run.json")], "would be the same file")
    _refused(capsys, project, ["demos", "scoop", "--out", str(d), "--count", "1",
                               "--picture", str(d / "scoop_1.csv")], "would be the same file")


@pytest.mark.parametrize("folder", ["models", "certificates", "specs", "tasks"])
def test_reports_never_land_in_a_projects_gated_folders(project: Path, folder: str,
                                                        capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    _refused(capsys, project, ["verify", "--model", str(project / INPUTS["model"]),
                               "--examples", "5", "--out", str(project / folder)],
             f"inside a project's {folder}/ folder")


def test_an_interrupted_campaign_never_replaces_complete_evidence(
        project: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Ctrl-C during ``tli verify --evidence``: the partial report goes to OUT/partial/ and the
    existing (complete) evidence and report stay as they were."""
    from tli_verify.verify import campaign

    evidence = project / INPUTS["evidence"]
    out = project / "out-int"
    out.mkdir(exist_ok=True)
    (out / "campaign.md").write_text("the complete report\n")
    before = evidence.read_bytes()
    real = campaign.simulate_batch
    calls = [0]

    def interrupting(job):  # the second batch is interrupted, as Ctrl-C does
        calls[0] += 1
        if calls[0] == 2:
            raise KeyboardInterrupt
        return real(job)

    monkeypatch.setattr(campaign, "simulate_batch", interrupting)
    code, _, err = run(capsys, "verify", "--model", str(project / INPUTS["model"]),
                       "--examples", "30", "--batch-size", "10", "--backend", "serial",
                       "--out", str(out), "--evidence", str(evidence),
                       "--force")  # the evidence there is stronger: replacing it is asked for
    assert code == 130 and "no evidence written" in err
    assert evidence.read_bytes() == before
    assert (out / "campaign.md").read_text() == "the complete report\n"
    assert "PARTIAL" in (out / "partial" / "campaign.md").read_text()
