"""A user's own task, written only as files, through every command to the gate.

The task is one no shipped file has: 3-D, four modes (reach the handle, pull the drawer, retract
to the home pose, done), a ball among boxes, a latch, and a goal mode that is NOT a sink (the
automaton leaves ``d`` under perturbations, so the goal is declared). The test writes the task
and the spec, and runs ``tli task check``, ``spec check``, ``demos``, ``learn``, ``certify``,
``run`` (3-D start and pushes), ``verify --evidence`` and ``gate`` -- no Python of the user's.
Then it edits one region of the task, and the gate blocks: the evidence binds the task.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.drawer3d import TASK, write_project


def run(*argv: str, cwd: Path) -> tuple[int, str, str]:
    """``tli argv...`` as a user runs it (a new process in ``cwd``)."""
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, "-m", "tli_verify.cli", *argv], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600, check=False)
    return proc.returncode, proc.stdout, proc.stderr


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project(tmp_path_factory.mktemp("drawer"))


def _ok(*argv: str, cwd: Path, code: int = 0) -> str:
    rc, out, err = run(*argv, cwd=cwd)
    assert rc == code, f"tli {' '.join(argv)}: exit {rc}\n{out}\n{err}"
    return out


def test_a_3d_task_of_its_own_through_every_command_to_the_gate(project: Path) -> None:
    out = _ok("task", "check", "tasks/drawer.toml", "--picture", "out/task.png", cwd=project)
    assert "3-D" in out and "goal d" in out and (project / "out/task.png").stat().st_size > 0
    _ok("spec", "check", "specs/drawer.toml", cwd=project)
    out = _ok("spec", "automaton", "specs/drawer.toml", cwd=project)
    assert "d->a" in out  # the goal mode is not a sink
    _ok("demos", "tasks/drawer.toml", cwd=project)
    assert sorted(p.name for p in (project / "demos").iterdir()) == [
        "drawer_1.csv", "drawer_2.csv", "drawer_3.csv"]
    _ok("learn", "demos/drawer_1.csv", "demos/drawer_2.csv", "demos/drawer_3.csv", "--spec",
        "specs/drawer.toml", "-o", "models/drawer.model.json", cwd=project)
    out = _ok("certify", "models/drawer.model.json", cwd=project)
    assert "dt = 1/100" in out  # the task's control period, by default
    assert (project / "certificates" / "drawer.cert.json").is_file()
    # a nominal run, and one pushed back out of the slide in 3-D: replanning finishes it
    out = _ok("run", "--task", "drawer", "--start", "0.2,0.5,0.8", "--json", "--out", "out/a",
              cwd=project)
    rec = json.loads(out)
    assert rec["success"] and rec["mode_sequence"] == "abcd" and len(rec["start"]) == 3
    out = _ok("run", "--spec", "specs/drawer.toml", "--start", "0.2,0.5,0.8", "--perturb",
              "300:-0.3,0,0.2", "--json", "--out", "out/b", cwd=project)
    rec = json.loads(out)
    assert rec["success"] and rec["perturbations"][0]["displacement"] == [-0.3, 0.0, 0.2]
    assert rec["mode_sequence"].startswith("abc") and rec["mode_sequence"].endswith("d")
    assert (project / "out/b/run.png").stat().st_size > 0
    # a 2-number push in 3-D is refused with one line naming the option
    rc, _, err = run("run", "--task", "drawer", "--perturb", "5:1,1", "--out", "out/c",
                     cwd=project)
    assert rc == 2 and err.startswith("error: --perturb '5:1,1': expected 3 ") and \
        err.count("\n") == 1
    out = _ok("verify", "--spec", "specs/drawer.toml", "--examples", "500", "--workers", "2",
              "--evidence", "--json", cwd=project)
    rec = json.loads(out)
    assert rec["runs"] == 500 and rec["violating_runs"] == 0 and rec["inconclusive"] == 0
    evidence = json.loads((project / "certificates" / "drawer.campaign.json").read_text())
    assert evidence["task"]["name"] == "drawer" and evidence["task"]["kind"] == "file"
    out = _ok("gate", ".", cwd=project)
    assert "gate: pass" in out
    # edit one region of the task: the evidence no longer binds it, the gate blocks
    task = project / "tasks" / "drawer.toml"
    original = task.read_text()
    task.write_text(original.replace("radius = 0.17", "radius = 0.19"))
    try:
        rc, out, _ = run("gate", ".", cwd=project)
        assert rc == 1
        assert "its content changed since the campaign (not only comments" in out
        # a comment only: the content hash still matches, and the gate says so
        task.write_text(original + "# tuned the home ball on the robot\n")
        rc, out, _ = run("gate", ".", cwd=project)
        assert rc == 0 and "only its comments or formatting changed" in out
    finally:
        task.write_text(original)
    assert run("gate", ".", cwd=project)[0] == 0


@pytest.mark.slow
def test_evidence_of_another_task_is_refused(project: Path) -> None:
    """Evidence made on a renamed copy of the task (another world) does not pass for the
    deployed spec's task."""
    evidence = project / "certificates" / "drawer.campaign.json"
    if not evidence.is_file():
        pytest.skip("needs the evidence of the first test")
    (project / "tasks" / "drawer2.toml").write_text(TASK.replace('name = "drawer"',
                                                                 'name = "drawer2"'))
    saved = evidence.read_bytes()
    try:
        _ok("verify", "--spec", "specs/drawer.toml", "--task", "drawer2", "--examples", "500",
            "--workers", "2", "--evidence", "--out", "out/v2", cwd=project)
        doc = json.loads(evidence.read_text())
        assert doc["task"]["name"] == "drawer2"
        rc, out, _ = run("gate", ".", cwd=project)
        assert rc == 1 and "campaign ran on task 'drawer2'" in out
    finally:
        evidence.write_bytes(saved)
