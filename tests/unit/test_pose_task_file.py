"""The pose-task format (issue 35, item 5): ``[state] orientation`` and the ``cone`` region.

A good file reads; every malformed orientation or cone is one error naming the file and the
field (the CLI turns it into exit 2); a cone nests in unions like any shape.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tests.support.cli import run as tli_run
from tli_verify.errors import TaskError
from tli_verify.tasks.taskfile import load_task


def _pose(state_extra: str = 'orientation = { start = 3, reference = [1, 0, 0, 0] }',
          region: str = 'cone = { axis = [0, 0, 1], toward = [0, 0, 1], within = 20 }',
          lower: str = "[-1, -1, -1, -1.5, -1.5, -1.5]",
          upper: str = "[1, 1, 1, 1.5, 1.5, 1.5]") -> str:
    return (f'name = "p"\n[state]\nlower = {lower}\nupper = {upper}\n{state_extra}\n'
            f'[regions.up]\n{region}\n[sensors]\nu = "up"\n')


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "t.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_pose_task_reads(tmp_path: Path) -> None:
    half = math.sqrt(0.5)
    task = load_task(_write(tmp_path, _pose(
        state_extra=f'orientation = {{ start = 0, reference = [{half}, {half}, 0, 0] }}',
        region='union = [{ cone = { axis = [0, 0, 1], toward = [0, -1, 0], within = 10 } }, '
               '{ box = { lower = [-1, -1, -1, 0.9, -1, -1], upper = [1, 1, 1, 1, 1, 1] } }]')))
    assert task.orientation is not None and task.orientation.start == 0
    # the reference turns the tool's z axis by 90 degrees about x: onto -y
    X = np.zeros((2, 6))
    X[1, 0] = math.radians(30)  # 30 more degrees about the (body) x axis
    up = task.partition.cells[0].region
    assert up.contains(X).tolist() == [True, False]
    assert task.sensors(X)[:, 0].tolist() == [True, False]


@pytest.mark.parametrize(("text", "message"), [
    (_pose(state_extra=""), "a cone is a region on the orientation: the task's [state] needs "
     "orientation"),
    (_pose(state_extra='orientation = { start = 4 }'), "state.orientation.start: expected a "
     "whole number from 0 to 3"),
    (_pose(state_extra='orientation = { start = 3, reference = [1, 1, 0, 0] }'),
     "state.orientation.reference: norm 1.41421356, not a unit quaternion"),
    (_pose(state_extra='orientation = { start = 3, reference = [1, 0, 0] }'),
     "state.orientation"),
    (_pose(state_extra='orientation = { start = 3, axis = 2 }'), "state.orientation"),
    (_pose(lower="[-1, -1, -1, -2, -2, -2]", upper="[1, 1, 1, 2, 2, 2]"),
     "state.orientation: the workspace box reaches |v| = 3.464 rad"),
    (_pose(region='cone = { axis = [0, 0, 1], toward = [0, 0, 1], within = 180 }'),
     "regions.up.cone"),
    (_pose(region='cone = { axis = [0, 0, 0], toward = [0, 0, 1], within = 20 }'),
     "regions.up.cone.axis: the zero vector is no direction"),
    (_pose(region='cone = { axis = [0, 0, 1], within = 20 }'), "regions.up.cone"),
])
def test_bad_pose_files_name_the_field(tmp_path: Path, text: str, message: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(TaskError) as err:
        load_task(path)
    assert message in str(err.value), str(err.value)
    assert str(path) in str(err.value)


def test_the_cli_refuses_a_bad_pose_task_in_one_line(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, _pose(state_extra=""))
    code, out, err = tli_run(capsys, "task", "check", str(path))
    assert code == 2 and out == ""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "cone" in lines[0], err


def test_a_half_turn_from_the_reference_is_refused_without_a_warning(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A recorded orientation at pi from the reference (w = 0: the chart's edge) is outside the
    workspace: one error naming the line, and no numpy warning on the way (warnings are
    errors in the suite)."""
    task = _write(tmp_path, _pose())
    pose = tmp_path / "half.csv"
    pose.write_text("# quaternion: scalar-first\ntime,x0,x1,x2,q0,q1,q2,q3\n"
                    + "".join(f"{t},0,0,0.5,0,1,0,0\n" for t in (0.0, 0.1, 0.2)),
                    encoding="utf-8")
    code, out, err = tli_run(capsys, "demos", str(task), "--from-pose", str(pose), "--out",
                             str(tmp_path / "demos"))
    assert code == 2 and out == ""
    assert err.startswith(f"error: {pose}: line 3: the pose is outside the workspace"), err
    assert not (tmp_path / "demos").exists()


@pytest.mark.parametrize(("text", "message"), [
    (_pose(region='cone = { axis = [1e308, 1e308, 0], toward = [0, 0, 1], within = 20 }'),
     "regions.up.cone.axis: expected three numbers of size at most"),
    (_pose(state_extra='orientation = { start = 3, reference = [1e308, 1e308, 0, 0] }'),
     "state.orientation.reference: expected four numbers"),
    (_pose(region='cone = { axis = [0, 0, 1], toward = [0, 0, 1], within = 1e-7 }'),
     "regions.up.cone.within: expected degrees from 0.01 to 179.99"),
])
def test_hostile_numbers_in_a_pose_task_are_refused(tmp_path: Path, text: str,
                                                   message: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(TaskError) as err:
        load_task(path)
    assert message in str(err.value), str(err.value)


def test_a_cone_reads_non_finite_states_as_outside_and_keeps_its_arrays(tmp_path: Path) -> None:
    task = load_task(_write(tmp_path, _pose()))
    cone = task.partition.cells[0].region
    X = np.array([[0, 0, 0.5, np.inf, 0, 0], [0, 0, 0.5, np.nan, 0, 0], [0, 0, 0.5, 0, 0, 0]])
    assert cone.contains(X).tolist() == [False, False, True]  # warnings are errors here
    assert [cone.contains_one(x.tolist()) for x in X] == [False, False, True]
    with pytest.raises(ValueError, match="read-only"):
        cone.axis[:] = [1.0, 0.0, 0.0]


def test_pictures_of_a_pose_task_show_every_coordinate() -> None:
    from dataclasses import dataclass

    from tli_verify.tasks.orientation import OrientationChart
    from tli_verify.viz.regions import pose_pairs

    @dataclass
    class Shape:
        dim: int
        orientation: OrientationChart

    one = pose_pairs(Shape(4, OrientationChart(1, (1.0, 0.0, 0.0, 0.0))))
    assert one is not None and one[:3] == ((0, 1), (0, 2), (0, 3))
    eight = pose_pairs(Shape(8, OrientationChart(2, (1.0, 0.0, 0.0, 0.0))))
    assert eight is not None
    assert {i for pair in eight for i in pair} == set(range(8))


def test_from_pose_refuses_the_demonstrator_options_and_two_conventions(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    task = _write(tmp_path, _pose())
    pose = tmp_path / "p.csv"
    rows = "".join(f"{t},0,0,0.5,1,0,0,0\n" for t in (0.0, 0.1, 0.2))
    pose.write_text("# quaternion: scalar-first\ntime,x0,x1,x2,q0,q1,q2,q3\n" + rows,
                    encoding="utf-8")
    code, out, err = tli_run(capsys, "demos", str(task), "--from-pose", str(pose), "--seed",
                             "3", "--out", str(tmp_path / "d"))
    assert code == 2 and out == "" and "--seed" in err, err
    pose.write_text("# quaternion: scalar-last\n# quaternion: scalar-first\n"
                    "time,x0,x1,x2,q0,q1,q2,q3\n" + rows, encoding="utf-8")
    code, out, err = tli_run(capsys, "demos", str(task), "--from-pose", str(pose), "--out",
                             str(tmp_path / "d"))
    assert code == 2 and out == ""
    assert "line 2: a second quaternion convention (scalar-first) after scalar-last" in err
    # time steps far too small for the states: the finite differences are refused by line,
    # as tli learn refuses them, with no numpy warning on the way
    tiny = "".join(f"{t!r},0,0,{0.5 + 0.1 * k},1,0,0,0\n"
                   for k, t in enumerate((0.0, 1e-300, 2e-300)))
    pose.write_text("# quaternion: scalar-first\ntime,x0,x1,x2,q0,q1,q2,q3\n" + tiny,
                    encoding="utf-8")
    code, out, err = tli_run(capsys, "demos", str(task), "--from-pose", str(pose), "--out",
                             str(tmp_path / "d"))
    assert code == 2 and out == "" and "finite difference" in err, err
    assert not (tmp_path / "d").exists()
