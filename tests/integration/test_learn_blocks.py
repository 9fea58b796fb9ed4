"""The A-fit's structure through `tli learn`, on a pose task the test writes: 5-D (x, y and
the orientation at coordinates 2-4), so the default blocks follow the task's own chart."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import tli_verify as tli
from tests.support.cli import run as tli_run
from tli_verify.errors import ModelError
from tli_verify.tasks.project import pose_blocks

TASK = """\
name = "tilt5"
description = "slide along x upright, then tip about y over the target"
dt = 0.01
background = "free"
spec = "../specs/tilt5.toml"

[state]
names = ["x", "y", "rx", "ry", "rz"]
lower = [-0.6, -0.4, -1.0, -1.0, -1.0]
upper = [0.6, 0.4, 1.0, 1.0, 1.0]
orientation = { start = 2, reference = [0, 1, 0, 0] }

[regions.over]
box = { lower = [0.2, -0.15, -inf, -inf, -inf], upper = [0.5, 0.15, inf, inf, inf] }

[regions.upright]
cone = { axis = [0, 0, 1], toward = [0, 0, -1], within = 20 }
layer = true

[sensors]
o = "over & upright"
d = "over & !upright"

[goal]
modes = "sinks"

[starts]
nominal = [[-0.4, 0.1, 0.0, 0.0, 0.0]]
region = "free"

[demonstrator]
count = 3
duration = 6.0
dt = 0.05
sigma = 0.01

[[demonstrator.scripts]]
start = [-0.4, 0.1, 0.0, 0.0, 0.0]
start_jitter = 0.05
waypoints = [[0.35, 0.0, 0.0, 0.0, 0.0], [0.35, 0.0, 0.0, 0.8, 0.0]]
jitter = [0.5, 0.0]
"""

SPEC = """\
name = "tilt5"
task = "tilt5"
inputs = ["o", "d"]
outputs = ["a", "b", "c", "p"]

[modes]
a = "!o & !d"
b = "o & !d"
c = "d"

[assume]
init = "!o & !d"
safety = ["G((!o & !d) -> X !d)"]
liveness = ["GF(!a | o)", "GF(!b | d)"]

[guarantee]
init = "a & !p"
safety = [
  "G(a -> X(a | b))",
  "G(b -> X(a | b | c))",
  "G(c -> X(c | b | a))",
  "G(X p <-> ((b & X a) | (c & X b) | (c & X a)))",
]
"""


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("tilt5")
    for sub in ("tasks", "specs", "models", "demos"):
        (root / sub).mkdir()
    (root / "tasks" / "tilt5.toml").write_text(TASK, encoding="utf-8")
    (root / "specs" / "tilt5.toml").write_text(SPEC, encoding="utf-8")
    return root


def test_the_default_blocks_are_the_tasks_orientation_coordinates(
        project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = project / "specs" / "tilt5.toml"
    assert pose_blocks(spec) == ((2, 3, 4),)
    assert pose_blocks(None) == ()
    code, _, err = tli_run(capsys, "demos", str(project / "tasks" / "tilt5.toml"), "--out",
                           str(project / "demos"))
    assert code == 0, err
    demos = sorted((project / "demos").glob("*.csv"))
    model = project / "models" / "tilt5.model.json"
    code, _, err = tli_run(capsys, "learn", *map(str, demos), "--spec", str(spec), "-o",
                           str(model), "--no-handoff")
    assert code == 0, err
    for mm in tli.load_model(model).modes.values():
        assert mm.fit["blocks"] == [[2, 3, 4]]
        A = np.asarray(mm.ds.A)
        assert np.all(A[:, :2, 2:] == 0.0) and np.all(A[:, 2:, :2] == 0.0)
        assert np.any(A[:, :2, :2] != 0.0) and np.any(A[:, 2:, 2:] != 0.0)
    # a group of the user's own: only ry and rz apart from the rest
    code, _, err = tli_run(capsys, "learn", *map(str, demos), "--spec", str(spec), "-o",
                           str(project / "models" / "own.model.json"), "--no-handoff",
                           "--blocks", "3,4")
    assert code == 0, err
    for mm in tli.load_model(project / "models" / "own.model.json").modes.values():
        A = np.asarray(mm.ds.A)
        assert mm.fit["blocks"] == [[3, 4]]
        assert np.all(A[:, :3, 3:] == 0.0) and np.all(A[:, 3:, :3] == 0.0)
    # a coordinate the state does not have: one error line, exit 2, no model written
    bad = project / "models" / "bad.model.json"
    code, _, err = tli_run(capsys, "learn", *map(str, demos), "--spec", str(spec), "-o",
                             str(bad), "--no-handoff", "--blocks", "2,7")
    assert code == 2 and err.count("error:") == 1 and "coordinate 7" in err, err
    assert not bad.exists()


@pytest.mark.parametrize("blocks", [[[2], [2]], "2,3", [[2.5]], [[True]]])
def test_bad_blocks_through_the_python_api_are_one_model_error(
        project: Path, blocks: object) -> None:
    task = tli.load_task(project / "tasks" / "tilt5.toml")
    demos = task.demonstrate(seed=0, n_demos=1)
    with pytest.raises(ModelError, match="blocks"):
        tli.learn(demos, spec=project / "specs" / "tilt5.toml", handoff=False,
                  blocks=blocks)  # type: ignore[arg-type]


def test_a_model_names_its_coordinates_as_its_task_does(project: Path) -> None:
    """Through the Python API: the learned model's ``state_names`` are the task's (the
    artifact, pictures and the gate's messages read them), and demonstrations of another
    dimension than the task's are one ModelError naming both."""
    task = tli.load_task(project / "tasks" / "tilt5.toml")
    spec = project / "specs" / "tilt5.toml"
    model = tli.learn(task.demonstrate(seed=0, n_demos=1), spec=spec, handoff=False)
    assert model.state_names == ("x", "y", "rx", "ry", "rz")
    short = [dataclasses.replace(d, x=d.x[:, :4], dx=d.dx[:, :4])
             for d in task.demonstrate(seed=0, n_demos=1)]
    with pytest.raises(ModelError, match=r"task names 5 state coordinates \(x, y, rx, ry, rz\)"
                                         r", the demonstrations have 4"):
        tli.learn(short, spec=spec, handoff=False)
