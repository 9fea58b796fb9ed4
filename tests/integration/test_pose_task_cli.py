"""A pose task the test writes (issue 35, item 5): position and orientation in the state, a cone
on the orientation, through every command a user runs and through the Python API.

The task: carry a cup upright (tool axis within 20 degrees of vertical, a cone region) to a
place over a bowl, then tip it past the cone to pour; done once poured over the bowl. Six
coordinates: position (x, y, z) and the orientation's rotation vector at the upright
reference. The demonstrator writes the demonstrations; ``tli learn``, ``tli certify``,
``tli run`` and ``tli verify`` run on the files, and the same through ``tli_verify``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import tli_verify as tli
from tests.support.cli import run as tli_run
from tli_verify.demos import demo_to_csv

TASK = """\
name = "pour"
description = "carry the cup upright over the bowl, then tip it to pour"
dt = 0.01
background = "free"
spec = "../specs/pour.toml"

[state]
names = ["x", "y", "z", "rx", "ry", "rz"]
lower = [-0.6, -0.4, 0.0, -1.2, -1.2, -1.2]
upper = [0.6, 0.4, 0.8, 1.2, 1.2, 1.2]
orientation = { start = 3, reference = [1, 0, 0, 0] }

[regions.over]
box = { lower = [0.2, -0.15, 0.3, -inf, -inf, -inf], upper = [0.5, 0.15, 0.7, inf, inf, inf] }

[regions.upright]
cone = { axis = [0, 0, 1], toward = [0, 0, 1], within = 20 }
layer = true

[latches.poured]
set = "over & !upright & prev(over) & prev(upright)"
reset = "false"

[sensors]
o = "over & upright & !poured"
d = "poured"

[goal]
modes = "sinks"

[starts]
nominal = [[-0.4, 0.0, 0.5, 0.0, 0.0, 0.0]]
region = "free"

[perturbations]
max_magnitude = 0.3
window = 600
max_pushes = 2

[demonstrator]
count = 3
duration = 8.0
dt = 0.05
sigma = 0.01

[[demonstrator.scripts]]
start = [-0.4, 0.0, 0.5, 0.0, 0.0, 0.0]
start_jitter = 0.05
waypoints = [[0.35, 0.0, 0.5, 0.0, 0.0, 0.0], [0.35, 0.0, 0.5, 0.9, 0.0, 0.0]]
jitter = [0.5, 0.0]
"""

SPEC = """\
name = "pour"
task = "pour"
inputs = ["o", "d"]
outputs = ["a", "b", "c", "p"]

[modes]
a = "!o & !d"
b = "o & !d"
c = "d"

[assume]
init = "!o & !d"
safety = ["G((!o & !d) -> X !d)", "G(d -> X d)"]
liveness = ["GF(!a | o)", "GF(!b | d)"]

[guarantee]
init = "a & !p"
safety = [
  "G(a -> X(a | b))",
  "G(b -> X(a | b | c))",
  "G(c -> X c)",
  "G(X p <-> (b & X a))",
]
liveness = ["GF(c | p)"]
"""


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("pour")
    for sub in ("tasks", "specs", "models", "certificates", "demos"):
        (root / sub).mkdir()
    (root / "tasks" / "pour.toml").write_text(TASK, encoding="utf-8")
    (root / "specs" / "pour.toml").write_text(SPEC, encoding="utf-8")
    return root


def test_the_task_reads_orientation_and_the_cone(project: Path) -> None:
    task = tli.load_task(project / "tasks" / "pour.toml")
    assert task.dim == 6 and task.orientation is not None
    upright = next(r for r in task.partition.layers if r.name == "upright").region
    tilt = math.radians(30.0)
    X = np.array([[0.0, 0.0, 0.5, 0.0, 0.0, 0.0],            # upright
                  [0.0, 0.0, 0.5, 0.0, 0.0, 1.0],            # turned about vertical: upright
                  [0.0, 0.0, 0.5, math.radians(15), 0, 0],   # tilted 15 degrees
                  [0.0, 0.0, 0.5, tilt, 0.0, 0.0]])          # tilted 30 degrees
    assert upright.contains(X).tolist() == [True, True, True, False]
    assert [upright.contains_one(x.tolist()) for x in X] == [True, True, True, False]


def _pose_csv(path: Path, t: np.ndarray, pos: np.ndarray, quat: np.ndarray) -> None:
    """A recorded pose demonstration as a robot would log it: scalar-last quaternions, a
    hemisphere flip half-way and one quaternion a little off unit norm."""
    q = quat[:, [1, 2, 3, 0]].copy()
    q[len(q) // 2:] *= -1.0
    q[3] *= 1.01
    rows = [f"{a:.6f}," + ",".join(f"{v:.9f}" for v in (*p_, *q_))
            for a, p_, q_ in zip(t, pos, q, strict=True)]
    path.write_text("# quaternion: scalar-last\ntime,x0,x1,x2,q0,q1,q2,q3\n"
                    + "\n".join(rows) + "\n", encoding="utf-8")


def test_a_pose_task_goes_through_learn_certify_run_and_verify(
        project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    task = tli.load_task(project / "tasks" / "pour.toml")
    assert task.orientation is not None
    recorded = project / "recorded"
    recorded.mkdir()
    for i, demo in enumerate(task.demonstrate(seed=0, n_demos=3), start=1):
        _pose_csv(recorded / f"pour_{i}.csv", demo.t, demo.x[:, :3],
                  task.orientation.quaternions(demo.x))
    pose_files = sorted(recorded.glob("*.csv"))
    code, out, err = tli_run(capsys, "demos", str(project / "tasks" / "pour.toml"),
                             "--from-pose", *map(str, pose_files), "--out",
                             str(project / "demos"))
    assert code == 0, err
    assert "hemisphere" in err and "normalised" in err, err  # the cleaning, said
    demos = sorted((project / "demos").glob("*.csv"))
    assert [d.name for d in demos] == [f.name for f in pose_files]
    # the conversion gives back the task's states (the flip and the norm undone)
    back = tli.load_demos(demos)
    for demo, again in zip(task.demonstrate(seed=0, n_demos=3), back, strict=True):
        np.testing.assert_allclose(again.x, demo.x, atol=2e-6)
    model = project / "models" / "pour.model.json"
    code, out, err = tli_run(capsys, "learn", *map(str, demos), "--spec",
                             str(project / "specs" / "pour.toml"), "-o", str(model),
                             "--no-handoff")  # the offline step: the slow test below
    assert code == 0, err
    # a pose task: position and orientation decoupled in every A_k, recorded in the fit; the
    # model names its coordinates as the task does (not x0 .. x5)
    learned = tli.load_model(model)
    assert learned.state_names == ("x", "y", "z", "rx", "ry", "rz")
    for mm in learned.modes.values():
        assert mm.fit["blocks"] == [[3, 4, 5]]
        A = np.asarray(mm.ds.A)
        assert np.all(A[:, :3, 3:] == 0.0) and np.all(A[:, 3:, :3] == 0.0)
    coupled = project / "models" / "coupled.model.json"
    code, out, err = tli_run(capsys, "learn", *map(str, demos), "--spec",
                             str(project / "specs" / "pour.toml"), "-o", str(coupled),
                             "--no-handoff", "--blocks", "none")
    assert code == 0, err
    assert all("blocks" not in (mm.fit or {}) for mm in tli.load_model(coupled).modes.values())
    coupled.unlink()
    code, out, err = tli_run(capsys, "certify", str(model))
    assert code == 0, err
    cert = project / "certificates" / "pour.cert.json"
    code, out, err = tli_run(capsys, "check-cert", str(cert))  # the exact re-check
    assert code == 0, err + out
    code, out, err = tli_run(capsys, "run", "--model", str(model), "--out",
                             str(project / "out" / "run"))
    assert code == 0, err
    assert "reached the goal" in out
    assert (project / "out" / "run" / "run.png").is_file()
    code, out, err = tli_run(capsys, "verify", "--model", str(model), "--examples", "30",
                             "--out", str(project / "out" / "verify"))
    assert code == 0, err + out
    assert "no violation found" in out


@pytest.mark.slow
def test_the_offline_hand_off_step_holds_on_the_pose_task_from_random_starts(
        project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``tli learn`` with its default offline step (every mode's exits found and cut,
    position and orientation alike), then a campaign from random starts over the whole
    workspace: every hand-off claim holds and no run violates the spec."""
    task = tli.load_task(project / "tasks" / "pour.toml")
    demos = project / "demos-slow"
    demos.mkdir()
    files = []
    for i, demo in enumerate(task.demonstrate(seed=0, n_demos=3), start=1):
        files.append(demos / f"pour_{i}.csv")
        files[-1].write_text(demo_to_csv(demo), encoding="utf-8")
    model = project / "models" / "handoff.model.json"
    code, out, err = tli_run(capsys, "learn", *map(str, files), "--spec",
                             str(project / "specs" / "pour.toml"), "-o", str(model), "--json")
    assert code == 0, err
    claims = [json.loads(ln)["handoff"] for ln in out.splitlines() if '"handoff"' in ln]
    assert {c["mode"] for c in claims} == {"a", "b", "c"}
    assert all(c["exits"] == 0 and c["rests"] == 0 for c in claims), claims
    code, out, err = tli_run(capsys, "certify", str(model))
    assert code == 0, err
    code, out, err = tli_run(capsys, "verify", "--model", str(model), "--examples", "150",
                             "--random-starts", "--out", str(project / "out" / "verify-rs"))
    assert code == 0, err + out
    assert "no violation found" in out


def test_pose_files_for_a_task_without_orientation_are_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    root = tmp_path / "p"
    code, _, err = tli_run(capsys, "init", str(root), "--name", "flat", "--dim", "3")
    assert code == 0, err
    f = tmp_path / "pose.csv"
    _pose_csv(f, np.arange(4.0), np.zeros((4, 3)), np.tile([1.0, 0, 0, 0], (4, 1)))
    code, out, err = tli_run(capsys, "demos", str(root / "tasks" / "flat.toml"),
                             "--from-pose", str(f))
    assert code == 2 and out == ""
    assert err.startswith("error: ") and "--from-pose needs a pose task" in err, err
    assert not (root / "demos" / "pose.csv").exists()


def test_the_python_api_runs_the_pose_task(project: Path) -> None:
    task = tli.load_task(project / "tasks" / "pour.toml")
    demos = task.demonstrate(seed=1, n_demos=3)
    model = tli.learn(demos, spec=project / "specs" / "pour.toml", handoff=False,
                      out=project / "models" / "api.model.json")
    tli.certify(model, out=project / "certificates" / "api.cert.json")
    session = tli.open_project(project / "models" / "api.model.json")
    episode = session.run(seed=0)
    assert episode.success
    last = np.asarray(episode.states[-1])
    assert task.orientation is not None
    upright = next(r for r in task.partition.layers if r.name == "upright").region
    assert not upright.contains(last[None])[0]  # poured: tipped past the cone, over the bowl


def test_tli_init_pose_starts_a_pose_project_that_runs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``tli init --pose``: the template's zone counts only with the tool upright, its nominal
    start is tilted; demonstrations, learning, certification and a perturbed run work."""
    root = tmp_path / "turn"
    code, _, err = tli_run(capsys, "init", str(root), "--name", "turn", "--pose")
    assert code == 0, err
    task = tli.load_task(root / "tasks" / "turn.toml")
    assert task.dim == 6 and task.orientation is not None and task.orientation.start == 3
    zone = next(r for r in task.partition.cells if r.name == "zone").region
    x = np.array([[0.4, 0.0, 0.0, 0.0, 0.0, 0.0], [0.4, 0.0, 0.0, 0.5, 0.0, 0.0]])
    assert zone.contains(x).tolist() == [True, False]  # upright counts, tilted does not
    code, _, err = tli_run(capsys, "demos", str(root / "tasks" / "turn.toml"))
    assert code == 0, err
    model = root / "models" / "turn.model.json"
    code, _, err = tli_run(capsys, "learn", *sorted(str(p) for p in (root / "demos").glob("*.csv")),
                           "--spec", str(root / "specs" / "turn.toml"), "-o", str(model),
                           "--no-handoff")
    assert code == 0, err
    code, _, err = tli_run(capsys, "certify", str(model))
    assert code == 0, err
    code, out, err = tli_run(capsys, "run", "--spec", str(root / "specs" / "turn.toml"),
                             "--perturb", "random:2", "--out", str(root / "out"))
    assert code == 0, err
    assert "reached the goal" in out
