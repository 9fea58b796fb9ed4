"""The torque-actuated Menagerie Panda: forward kinematics against Franka's published
modified DH parameters, motors and torque limits, gravity/Coriolis compensation."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.support.sim import require_panda

pytestmark = pytest.mark.sim


@pytest.fixture(scope="module")
def panda() -> Any:
    return require_panda()


def test_fk_matches_published_dh(panda: Any) -> None:
    """Flange and TCP poses at 50 seeded random postures within the joint limits: 1e-6 m, 1e-6."""
    import mujoco

    from tli_verify.sim.robot import JOINT_LOWER, JOINT_UPPER, dh_flange_pose

    rng = np.random.default_rng(20221130)
    data = mujoco.MjData(panda.model)
    for q in rng.uniform(JOINT_LOWER, JOINT_UPPER, size=(50, 7)):
        for tcp, site in ((False, panda.flange_site), (True, panda.tcp_site)):
            pos, rot = panda.fk(q, site, data)
            pos_dh, rot_dh = dh_flange_pose(q, tcp=tcp)
            np.testing.assert_allclose(pos, pos_dh, rtol=0, atol=1e-6)
            np.testing.assert_allclose(rot, rot_dh, rtol=0, atol=1e-6)


def test_dh_reference_is_not_trivially_equal(panda: Any) -> None:
    """The DH reference can fail: one wrong parameter (d3 + 1 mm) is seen."""
    import tli_verify.sim.robot as robot

    q = np.array([0.3, -0.5, 0.2, -2.0, 0.4, 1.8, -0.6])
    pos, _ = panda.fk(q)
    saved = robot.DH_CRAIG.copy()
    try:
        robot.DH_CRAIG[2, 1] += 1e-3
        bad, _ = robot.dh_flange_pose(q)
    finally:
        robot.DH_CRAIG[:] = saved
    assert np.linalg.norm(bad - pos) > 5e-4


def test_torque_motors_and_rigid_fingers(panda: Any) -> None:
    from tli_verify.sim.robot import TORQUE_LIMITS

    m = panda.model
    assert (m.nq, m.nv, m.nu) == (7, 7, 7)  # finger joints removed, one motor per joint
    np.testing.assert_array_equal(m.actuator_gear[panda.act_ids, 0], np.ones(7))
    np.testing.assert_array_equal(m.actuator_ctrlrange[panda.act_ids],
                                  np.stack([-TORQUE_LIMITS, TORQUE_LIMITS], axis=1))
    np.testing.assert_array_equal(m.actuator_biastype[panda.act_ids], np.zeros(7))  # no servo
    assert m.opt.timestep == pytest.approx(0.002)


def test_bias_compensation_holds_the_arm(panda: Any) -> None:
    """tau = qfrc_bias (gravity + Coriolis) holds a posture for 1 s; zero torque does not."""
    import mujoco

    q0 = np.array([0.2, -0.3, 0.1, -2.0, 0.1, 1.7, 0.5])
    drift = {}
    for compensate in (True, False):
        data = panda.new_data(q0)
        for _ in range(500):
            mujoco.mj_step1(panda.model, data)
            sat = panda.set_torque(data, panda.bias(data) if compensate else np.zeros(7))
            assert sat == 0
            mujoco.mj_step2(panda.model, data)
        drift[compensate] = float(np.abs(panda.q(data) - q0).max())
    assert drift[True] < 1e-6
    assert drift[False] > 0.05


def test_set_torque_saturates_at_the_limits(panda: Any) -> None:
    from tli_verify.sim.robot import TORQUE_LIMITS

    data = panda.new_data()
    tau = np.array([100.0, -50.0, 0.0, -90.0, 13.0, 11.0, -20.0])
    assert panda.set_torque(data, tau) == 4
    np.testing.assert_array_equal(data.ctrl[panda.act_ids],
                                  np.clip(tau, -TORQUE_LIMITS, TORQUE_LIMITS))


def test_ik_reaches_workspace_poses(panda: Any) -> None:
    """IK (damped least squares) puts the TCP on 20 seeded poses of the scooping workspace
    (the DS state box: position and pitch ``ry``, with some roll and yaw) within 1e-6, inside
    the joint limits; an unreachable pose reports it."""
    import mujoco

    from tli_verify.sim.controller import DSStateMap
    from tli_verify.sim.robot import JOINT_LOWER, JOINT_UPPER

    dmap = DSStateMap(panda.tcp_site)
    rng = np.random.default_rng(7)
    data = mujoco.MjData(panda.model)
    for z in rng.uniform([0.35, -0.3, 0.05, -0.3, -0.5, -0.3], [0.6, 0.3, 0.4, 0.3, 1.0, 0.3],
                         size=(20, 6)):
        pos, quat = dmap.target_pose_from_ds_state(z)
        q, err = panda.ik(pos, quat)
        assert err < 1e-6
        assert np.all(q >= JOINT_LOWER) and np.all(q <= JOINT_UPPER)
        got_pos, _ = panda.fk(q, panda.tcp_site, data)
        np.testing.assert_allclose(got_pos, pos, atol=1e-6)
        np.testing.assert_allclose(dmap.ds_state(data), z, atol=1e-6)
    pos, quat = dmap.target_pose_from_ds_state(np.array([2.0, 0.0, 0.3, 0.0, 0.0, 0.0]))  # 2 m
    _, err = panda.ik(pos, quat, max_iter=50)
    assert err > 0.5
