"""The task commands and the task options of the closed-loop commands, as a user runs them.

``tli init`` (a project that goes through every command), ``tli task check``, ``tli demos``;
a model or spec that does not fit the task, a goal the automaton cannot reach and a task that
does not load are one ``error:`` line before any work; a Python sensor model named by a task
file is found by name in the campaign's worker processes.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.cli import run as run_in_process

ROOT = Path(__file__).resolve().parents[2]


def tli(*argv: str, cwd: Path, env: dict[str, str] | None = None) -> tuple[int, str, str]:
    """``tli argv...`` in a new process in ``cwd``."""
    full = {**os.environ, "MPLBACKEND": "Agg", **(env or {})}
    proc = subprocess.run([sys.executable, "-m", "tli_verify.cli", *argv], cwd=cwd, env=full,
                          capture_output=True, text=True, timeout=600, check=False)
    return proc.returncode, proc.stdout, proc.stderr


def _one_error(err: str, *fragments: str) -> None:
    assert err.startswith("error: ") and err.count("\n") == 1, err
    for f in fragments:
        assert f in err, err


@pytest.fixture(scope="module")
def learned(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 2-D project from ``tli init``, learned and certified (no campaign)."""
    root = tmp_path_factory.mktemp("init") / "proj"
    for argv in (("init", str(root), "--name", "reach"),):
        rc, _, err = tli(*argv, cwd=root.parent)
        assert rc == 0, err
    for argv in (("demos", "tasks/reach.toml"),
                 ("learn", "demos/reach_1.csv", "demos/reach_2.csv", "demos/reach_3.csv",
                  "--spec", "specs/reach.toml", "-o", "models/reach.model.json"),
                 ("certify", "models/reach.model.json")):
        rc, _, err = tli(*argv, cwd=root)
        assert rc == 0, f"{argv}: {err}"
    return root


def test_init_writes_a_project_and_refuses_to_overwrite(tmp_path: Path) -> None:
    rc, out, _ = tli("init", "p", "--name", "arm", "--dim", "4", cwd=tmp_path)
    assert rc == 0
    for rel in ("tasks/arm.toml", "specs/arm.toml", "README.md", "ci/tli-gate.yml"):
        assert (tmp_path / "p" / rel).is_file() and f"p/{rel}" in out
    for folder in ("demos", "models", "certificates"):
        assert (tmp_path / "p" / folder).is_dir()
    rc, out, _ = tli("task", "check", "p/tasks/arm.toml", "--json", cwd=tmp_path)
    rec = json.loads(out)
    assert rc == 0 and rec["dimension"] == 4 and rec["sensors"] == ["z", "g"]
    assert tli("spec", "check", "p/specs/arm.toml", cwd=tmp_path)[0] == 0
    before = (tmp_path / "p" / "tasks" / "arm.toml").read_text()
    rc, _, err = tli("init", "p", "--name", "arm", cwd=tmp_path)
    assert rc == 2
    _one_error(err, "exists; tli init never overwrites a file")
    assert (tmp_path / "p" / "tasks" / "arm.toml").read_text() == before
    rc, _, err = tli("init", "q", "--name", "bad name!", cwd=tmp_path)
    assert rc == 2 and not (tmp_path / "q").exists()


def test_the_template_runs_and_pictures_are_drawn(learned: Path) -> None:
    rc, out, err = tli("run", "--task", "reach", "--perturb", "random:2", "--seed", "3",
                       "--random-start", "--json", "--animate", "8", cwd=learned)
    rec = json.loads(out)
    assert rc == 0 and rec["success"] and rec["task"] == "reach", err
    assert rec["files"]["task"].endswith("reach.toml")
    assert (learned / "out/run/run.png").stat().st_size > 0
    assert (learned / "out/run/run.gif").stat().st_size > 0
    rc, out, _ = tli("demos", "tasks/reach.toml", "--out", "out/d", "--count", "2",
                     "--picture", "out/d/demos.png", cwd=learned)
    assert rc == 0 and sorted(p.name for p in (learned / "out/d").iterdir()) == [
        "demos.png", "reach_1.csv", "reach_2.csv"]


def test_a_model_that_does_not_fit_the_task_is_refused_before_work(learned: Path,
                                                                  tmp_path: Path) -> None:
    assert tli("init", "three", "--name", "reach", "--dim", "3", cwd=tmp_path)[0] == 0
    task3 = tmp_path / "three" / "tasks" / "reach.toml"
    for cmd in (("verify", "--examples", "5"), ("run",)):
        rc, out, err = tli(*cmd, "--task", str(task3), "--model", "models/reach.model.json",
                           "--out", str(tmp_path / "o"), cwd=learned)
        assert rc == 2 and not out
        _one_error(err, "models/reach.model.json: a 2-D model, but task 'reach'",
                   "has a 3-D state")
    assert not (tmp_path / "o").exists()  # nothing written
    # the bundled scoop model on this task: 2-D too, but the spec reads other sensors
    rc, _, err = tli("run", "--task", "tasks/reach.toml", "--model",
                     str(ROOT / "models" / "scoop.model.json"), cwd=learned)
    assert rc == 2
    _one_error(err, "are not the sensors of task 'reach'")


def test_a_goal_the_automaton_cannot_reach_is_refused(learned: Path, tmp_path: Path) -> None:
    spec = (learned / "specs" / "reach.toml").read_text()
    bad = learned / "specs" / "unreachable.toml"
    # the goal: mode a only; but a is left for b, and b, c never return to a... c is a sink
    bad.write_text(spec.replace('name = "reach"', 'name = "unreachable"')
                   + '\n[goal]\nmodes = ["a"]\n')
    try:
        shutil.copy(learned / "models" / "reach.model.json",
                    learned / "models" / "unreachable.model.json")
        model = json.loads((learned / "models" / "unreachable.model.json").read_text())
        model["spec"] = "../specs/unreachable.toml"
        (learned / "models" / "unreachable.model.json").write_text(json.dumps(model))
        assert tli("certify", "models/unreachable.model.json", cwd=learned)[0] == 0
        rc, _, err = tli("run", "--spec", "specs/unreachable.toml", cwd=learned)
        assert rc == 2
        _one_error(err, "cannot reach the goal (a) from mode 'c'")
    finally:
        for p in (bad, learned / "models" / "unreachable.model.json",
                  learned / "certificates" / "unreachable.cert.json"):
            p.unlink(missing_ok=True)


def test_task_check_names_the_file_and_field(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "b"\n[state]\nlower = [0, 0]\nupper = [1, 1]\n'
                   '[regions.r]\nball = { center = [0, 0], radius = 0 }\n[sensors]\nq = "r"\n')
    code, _, err = run_in_process(capsys, "task", "check", str(bad))
    assert code == 2
    _one_error(err, f"{bad}: regions.r.ball.radius")
    code, _, err = run_in_process(capsys, "task", "check", "nope")
    assert code == 2
    _one_error(err, "unknown task 'nope'")
    code, out, _ = run_in_process(capsys, "task", "list")
    assert code == 0 and {"scoop", "cooking", "color-tracing", "inspection"} <= {
        line.split("\t")[0] for line in out.splitlines()}


def test_a_plugin_sensor_model_is_found_by_name_in_worker_processes(learned: Path,
                                                                    tmp_path: Path) -> None:
    """The task file names a Python sensor model (an entry point of an installed plug-in);
    ``tli verify --backend process`` runs it in its worker processes with no wrapper script."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "zoneplugin.py").write_text(
        "import numpy as np\n"
        "class Zone:\n"
        "    sensor_names = ('z', 'g')\n"
        "    latent_names = ('done',)\n"
        "    cell_based = False\n"
        "    def initial_latent(self, batch):\n"
        "        return np.zeros((batch, 1), dtype=bool)\n"
        "    def read(self, x_prev, x, latent):\n"
        "        def zone(X):\n"
        "            return (X[:, 0] >= 0.2) & (X[:, 0] <= 0.6) & (np.abs(X[:, 1]) <= 0.3)\n"
        "        goal = (x[:, 0] >= 0.6) & (np.abs(x[:, 1]) <= 0.3) & ~zone(x)\n"
        "        done = latent[:, 0] | (goal & zone(x_prev))\n"
        "        return np.stack([zone(x) & ~done, done], axis=1), done[:, None]\n"
        "def make(*, dim, partition):\n"
        "    return Zone()\n")
    info = site / "zoneplugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: zoneplugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[tli_verify.tasks]\nzone-sensors = zoneplugin:make\n")
    text = (learned / "tasks" / "reach.toml").read_text()
    head, rest = text.split("[state]", 1)
    body = rest.split("[latches.done]", 1)
    plugin = head + 'sensor_model = "zone-sensors"\n[state]' + body[0] + \
        "[goal]" + body[1].split("[goal]", 1)[1]
    (learned / "tasks" / "reach-py.toml").write_text(plugin)
    env = {"PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    rc, out, err = tli("verify", "--task", "tasks/reach-py.toml", "--spec", "specs/reach.toml",
                       "--examples", "40", "--backend", "process", "--workers", "2",
                       "--json", "--out", "out/py", cwd=learned, env=env)
    assert rc == 0, err
    rec = json.loads(out)
    assert rec["runs"] == 40 and rec["task"]["name"] == "reach"
    assert rec["task"]["path"].endswith("reach-py.toml")
    # the same campaign without the plug-in installed: one error line, before any work
    rc, _, err = tli("verify", "--task", "tasks/reach-py.toml", "--spec", "specs/reach.toml",
                     "--examples", "5", cwd=learned)
    assert rc == 2
    _one_error(err, "no entry point 'zone-sensors'")
