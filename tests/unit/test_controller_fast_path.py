"""The impedance controller's fast path (views of MjData bound once, float arithmetic on the
6-vectors) against the textbook operational-space law computed the straightforward way
(``mj_fullM``, explicit inverses, scipy's rotation vector), on seeded random states of a
scene with free bodies (so ``data.M`` is not the arm's alone), alternating two ``MjData``
(a view cache bound to the wrong data would read the other's state)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.support.sim import panda_with_beads

pytestmark = pytest.mark.sim


@pytest.fixture(scope="module")
def scene() -> Any:
    return panda_with_beads()


def _reference(robot: Any, data: Any, ctl: Any, pos_d: Any, quat_d: Any,
               twist_d: Any) -> tuple[np.ndarray, int]:
    """``tau = J^T F + (I - J^T Jbar^T) M (Kn (q_n - q) - Dn qdot) + bias``, saturated, with
    ``F = Lambda (Kp e - Kd (J qdot - v_d))`` (controller module docstring), computed with
    explicit inverses; and the number of saturated joints."""
    import mujoco
    from scipy.spatial.transform import Rotation

    from tli_verify.sim.robot import TORQUE_LIMITS

    model, dof = robot.model, robot.dof_adr
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    mass = full[np.ix_(dof, dof)]
    jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jp, jr, ctl.site)
    jac = np.vstack([jp, jr])[:, dof]
    minv = np.linalg.inv(mass)
    lam = np.linalg.inv(jac @ minv @ jac.T + 1e-6 * np.eye(6))
    rot = data.site_xmat[ctl.site].reshape(3, 3)
    rd = Rotation.from_quat(np.asarray(quat_d)[[1, 2, 3, 0]]).as_matrix()
    e = np.concatenate([pos_d - data.site_xpos[ctl.site],
                        Rotation.from_matrix(rd @ rot.T).as_rotvec()])
    qd = data.qvel[dof]
    vel = jac @ qd - (0.0 if twist_d is None else twist_d)
    g = ctl.gains
    kp = np.array([g.kp_pos] * 3 + [g.kp_rot] * 3)
    kd = np.array([g.kd_pos] * 3 + [g.kd_rot] * 3)
    force = lam @ (kp * e - kd * vel)
    jbar = minv @ jac.T @ lam
    tau0 = mass @ (g.kn * (ctl.posture - data.qpos[robot.qpos_adr]) - g.dn * qd)
    tau = jac.T @ force + (np.eye(7) - jac.T @ jbar.T) @ tau0 + data.qfrc_bias[dof]
    return np.clip(tau, -TORQUE_LIMITS, TORQUE_LIMITS), int(np.sum(np.abs(tau) > TORQUE_LIMITS))


def test_fast_path_equals_the_textbook_law(scene: Any) -> None:
    import mujoco

    from tli_verify.sim.controller import ImpedanceController
    from tli_verify.sim.robot import HOME_QPOS

    rng = np.random.default_rng(13)
    ctl = ImpedanceController(scene)
    datas = [scene.new_data(), scene.new_data()]
    saturated = 0
    for trial in range(40):
        data = datas[trial % 2]
        data.qpos[scene.qpos_adr] = HOME_QPOS + rng.uniform(-0.4, 0.4, size=7)
        data.qvel[:] = rng.normal(scale=0.05, size=scene.model.nv)
        mujoco.mj_forward(scene.model, data)
        # near targets, and every fourth one far away (those saturate)
        far = 10.0 if trial % 4 == 0 else 1.0
        z = ctl.ds_state(data) + far * rng.normal(scale=[0.005, 0.005, 0.005, 0.02, 0.02, 0.02])
        pos, quat = ctl.target_pose_from_ds_state(z)
        twist = rng.normal(scale=0.2, size=6) if trial % 3 else None
        tau = ctl.compute(data, pos, quat, twist)
        ref, n_sat = _reference(scene, data, ctl, pos, quat, twist)
        np.testing.assert_allclose(tau, ref, rtol=1e-8, atol=1e-8)
        np.testing.assert_array_equal(data.ctrl[scene.act_ids], tau)
        assert ctl.last_saturated == n_sat
        saturated += n_sat > 0
    assert 0 < saturated < 40  # both branches of the saturation ran
