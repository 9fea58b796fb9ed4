"""Kinesthetic teaching on the Panda (tli_verify.sim.teacher): the robot's own sensors and
kinematics record, so the segmentation puts each attractor where they read the next mode."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco")

from tli_verify.demos import load_demo
from tli_verify.errors import TliError
from tli_verify.sim.demos import from_ds, scoop_waypoints
from tli_verify.sim.scene import SOUP_BOWL
from tli_verify.sim.teacher import TeacherHand, record_demo, write_demos

pytestmark = pytest.mark.sim


def _stages(demo: object) -> np.ndarray:
    r, s, t = demo.sensors.T  # type: ignore[attr-defined]
    return np.where(t, 3, np.where(s, 2, np.where(r, 1, 0)))


@pytest.fixture(scope="module")
def take() -> object:
    return record_demo(1)


def test_a_take_reads_the_modes_in_order_with_the_robots_sensors(take: object) -> None:
    stage = _stages(take)
    assert stage[0] == 0 and stage[-1] == 3 and not np.any(np.diff(stage) < 0)
    assert set(stage.tolist()) == {0, 1, 2, 3}


def test_soup_reads_only_after_the_lift_clear_of_the_bowls_floor(take: object) -> None:
    """The wrist F/T cannot weigh beads while the tray presses on the pile: the first s sample
    (mode b's attractor after segmentation) lies well above the bowl's floor, and after the
    deepest point of the scoop."""
    stage = _stages(take)
    first_s = int(np.argmax(stage == 2))
    pose = from_ds(take.x)  # type: ignore[attr-defined]
    deepest = int(np.argmin(np.where(stage == 1, pose[:, 2], np.inf)))
    assert first_s > deepest
    assert pose[first_s, 2] > SOUP_BOWL.floor + 0.02, pose[first_s]


def test_the_record_is_the_measured_pose_not_the_script(take: object) -> None:
    """The teacher's hand is a spring: the measured tray lags and deviates from the script
    (the mocap takes recorded the script itself)."""
    w = scoop_waypoints()
    pose = from_ds(take.x)  # type: ignore[attr-defined]
    assert np.allclose(pose[0], w[0, 1:], atol=0.03)  # the nominal start, within the jitter
    assert np.abs(np.diff(pose[:, 2])).max() < 0.02  # a measured path: no jumps
    # pressed into the pile the tray stays above the script's target (1 cm under the
    # surface), where the floor and the beads hold it
    deepest = float(pose[_stages(take) == 1, 2].min())
    assert deepest > float(w[4, 3]) + 0.002, (deepest, w[4, 3])


def test_write_demos_writes_measured_takes_that_learn(tmp_path: Path) -> None:
    paths = write_demos(tmp_path, count=1, recovery=((0.5, 0.06, 0.12, -0.3, -0.25, 0.3),),
                        recovery_beads=(15,))
    assert [p.name for p in paths] == ["franka_1.csv", "franka_2.csv"]
    head = paths[0].read_text().splitlines()[0]
    assert "measured tray pose" in head and "kinesthetic" in head
    demo = load_demo(str(paths[1]))
    assert _stages(demo)[-1] == 3 and demo.x.shape[1] == 6
    # the full pose is recorded: the take starts rolled and yawed as asked, and the teacher
    # turns the tray back (the script's roll and yaw are 0)
    assert abs(demo.x[0, 3] + 0.3) < 0.05 and abs(demo.x[0, 5] - 0.3) < 0.05
    assert np.all(np.abs(demo.x[-50:, [3, 5]]) < 0.15)


def test_bad_teacher_settings_are_one_error() -> None:
    with pytest.raises(TliError, match="stiffness"):
        TeacherHand(stiffness=-1.0)
