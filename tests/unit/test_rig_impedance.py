"""The free hand's impedance law (:meth:`tli_verify.sim.demos.MocapRig.physics_step`) against
the straightforward computation, on seeded random states: ``F = K (p* - p) - D v`` and
``tau = K_r theta - D_r omega`` (``theta`` the rotation vector of ``q* conj(q)``, scipy;
``omega`` the free joint's body-frame angular velocity rotated to the world frame), plus the
push; the commanded pose ``(x, y, z, rx, ry, rz)`` is the target ``p*``,
``TRAY_REFERENCE Exp(v)``. Guards any per-step fast path of the rig (views of ``MjData``
bound once, float arithmetic instead of numpy on 3-vectors)."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.sim


def test_wrench_equals_the_straightforward_law() -> None:
    pytest.importorskip("mujoco")
    import mujoco
    from scipy.spatial.transform import Rotation

    from tli_verify.sim.demos import MocapRig
    from tli_verify.sim.scene import TRAY_REFERENCE

    rig = MocapRig(0)
    d = rig.data
    a, v = rig._qadr, rig._dadr
    rng = np.random.default_rng(5)
    ref = Rotation.from_quat(np.asarray(TRAY_REFERENCE)[[1, 2, 3, 0]])
    for _ in range(25):
        quat = rng.normal(size=4)
        d.qpos[a:a + 3] = d.qpos[a:a + 3] + rng.normal(scale=0.005, size=3)
        d.qpos[a + 3:a + 7] = quat / np.linalg.norm(quat)
        d.qvel[v:v + 6] = rng.normal(scale=0.2, size=6)
        cmd = rng.normal(scale=[0.01, 0.01, 0.01, 0.5, 0.5, 0.5]) + rig.pose()
        rig.command(cmd)
        rig.push[:] = rng.normal(scale=5.0, size=6)
        mujoco.mj_forward(rig.model, d)  # xmat of the new pose
        p, vel = d.qpos[a:a + 3].copy(), d.qvel[v:v + 3].copy()
        q, omega_b = d.qpos[a + 3:a + 7].copy(), d.qvel[v + 3:v + 6].copy()
        xmat = d.xmat[rig.carrier].reshape(3, 3).copy()
        target_p, target_q = d.mocap_pos[0].copy(), d.mocap_quat[0].copy()
        push = rig.push.copy()
        # the commanded pose is the target: TRAY_REFERENCE Exp(v) (the chart, scipy's)
        np.testing.assert_array_equal(target_p, cmd[:3])
        want = ref * Rotation.from_rotvec(cmd[3:])
        assert (Rotation.from_quat(target_q[[1, 2, 3, 0]]) * want.inv()).magnitude() < 1e-9
        rig.physics_step()
        err = Rotation.from_quat(target_q[[1, 2, 3, 0]]) * \
            Rotation.from_quat(q[[1, 2, 3, 0]]).inv()
        force = rig.k * (target_p - p) - rig.d * vel + push[:3]
        torque = rig.kr * err.as_rotvec() - rig.dr * (xmat @ omega_b) + push[3:]
        np.testing.assert_allclose(d.xfrc_applied[rig.carrier], np.concatenate([force, torque]),
                                   rtol=1e-9, atol=1e-9)
