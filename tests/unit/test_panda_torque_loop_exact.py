"""The Panda's torque loop (:meth:`ImpedanceController.compute_fast`,
:meth:`LimitGuard.apply_lists`, :meth:`PandaRig.step`) gives *bit-identical* torques to the plain
numpy formulation.

The committed physical evidence binds the trials' outcomes, so the speed-ups of the torque loop
(floats instead of numpy on 6- and 7-vectors, ``out=`` buffers, skipped norms) must not change
one bit of what is sent to the motors. The reference here is the law written the plain way --
``mj_fullM`` for the arm's mass block, ``np.linalg.norm``, new arrays for every intermediate,
the guard's limits on numpy arrays -- with the same products and solves (the same BLAS / LAPACK
calls on the same layouts: a matrix product's rounding is BLAS's, so only those are shared).
Every elementwise operation is IEEE-rounded alike in numpy and in Python floats, so the
comparison is exact (``np.array_equal``), over sequences of seeded random states (the
external-wrench filter and the torque-rate limit carry state from call to call) that drive
every branch: the task-force and task-torque caps, torque clipping, the torque-rate clip, the
velocity brake and the reflex stop, with and without the guard, for the Franka impedance law and
the per-unit-mass gains.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

import numpy as np
import pytest

from tests.support.sim import panda_with_beads, require_panda

pytestmark = pytest.mark.sim


@pytest.fixture(scope="module")
def scene() -> Any:
    return panda_with_beads()


class _PlainGuard:
    """:class:`~tli_verify.sim.franka_limits.LimitGuard`, the plain way (numpy arrays)."""

    def __init__(self, limits: Any, dt: float, hits: Counter[str]) -> None:
        self.limits, self.dt, self.hits = limits, dt, hits
        self.last: np.ndarray | None = None
        self.max = dict.fromkeys(("torque", "torque_rate", "joint_velocity", "cartesian_speed",
                                  "rotation_speed"), 0.0)
        self.stopped: str | None = None

    def apply(self, tau: np.ndarray, qd: np.ndarray, mass_diag: np.ndarray,
              twist: np.ndarray) -> np.ndarray:
        lim, m = self.limits, self.max
        vmax = np.asarray(lim.joint_velocity, dtype=np.float64)
        vel_ratio = np.abs(qd) / vmax
        peak = float(vel_ratio.max())
        m["joint_velocity"] = max(m["joint_velocity"], peak)
        tw = twist.tolist()
        lin = math.sqrt(tw[0] ** 2 + tw[1] ** 2 + tw[2] ** 2) / lim.cartesian_speed[0]
        rot = math.sqrt(tw[3] ** 2 + tw[4] ** 2 + tw[5] ** 2) / lim.cartesian_speed[1]
        m["cartesian_speed"] = max(m["cartesian_speed"], lin)
        m["rotation_speed"] = max(m["rotation_speed"], rot)
        if lim.reflex and self.stopped is None and max(lin, rot) > 1.0:
            self.stopped = (f"end-effector speed {lin * lim.cartesian_speed[0]:.2f} m/s, "
                            f"{rot * lim.cartesian_speed[1]:.2f} rad/s beyond "
                            f"{lim.cartesian_speed[0]:g} m/s / {lim.cartesian_speed[1]:g} rad/s")
        if lim.reflex and self.stopped is None and peak > 1.0:
            j = int(np.argmax(vel_ratio))
            self.stopped = (f"joint {j + 1} velocity {abs(qd[j]):.3f} rad/s beyond "
                            f"its limit {vmax[j]:g} rad/s")
        self.hits["fast joint"] += peak > 1.0
        t = tau.copy()
        braked = vel_ratio > lim.brake_from
        if braked.any():
            excess = qd - np.copysign(lim.brake_from * vmax, qd)
            t[braked] -= (lim.brake_gain * mass_diag * excess)[braked]
            self.hits["brake"] += 1
        tmax = np.asarray(lim.torque, dtype=np.float64)
        worst = float(np.max(np.abs(t) / tmax))
        m["torque"] = max(m["torque"], worst)
        self.hits["torque clip"] += worst > 1.0
        out = np.clip(t, -tmax, tmax)
        if self.last is not None:
            step = lim.torque_rate * self.dt
            change = out - self.last
            rate = float(np.max(np.abs(change))) / step
            m["torque_rate"] = max(m["torque_rate"], rate)
            self.hits["rate clip" if rate > 1.0 else "rate free"] += 1
            out = self.last + np.clip(change, -step, step)
        self.last = out
        return out


class _PlainController:
    """The operational-space / Cartesian impedance law of :class:`ImpedanceController` (its
    module docstring), configured like ``ctl``, the plain way."""

    def __init__(self, ctl: Any, hits: Counter[str]) -> None:
        from tli_verify.sim.franka_limits import LimitGuard

        self.ctl, self.hits = ctl, hits
        self.model = ctl.model
        self.dof = np.asarray(ctl.panda.dof_adr)
        self.qadr = np.asarray(ctl.panda.qpos_adr)
        self.act = np.asarray(ctl.panda.act_ids)
        self.jac6 = np.zeros((6, self.model.nv))
        self.prev: tuple[Any, ...] | None = None
        self.ext_tau = np.zeros(7)
        self.ext = np.zeros(6)
        guard = ctl.guard
        self.guard = _PlainGuard(guard.limits, guard.dt, hits) \
            if isinstance(guard, LimitGuard) else None

    def compute(self, data: Any, pos_d: np.ndarray, quat_d: np.ndarray,
                twist_d: np.ndarray | None) -> tuple[np.ndarray, int]:
        import mujoco
        from scipy.linalg import lapack

        from tli_verify.sim.controller import TASK_FORCE_LIMIT, TASK_TORQUE_LIMIT
        from tli_verify.sim.robot import TORQUE_LIMITS

        ctl, model, dof = self.ctl, self.model, self.dof
        full = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, full)
        mass = full[np.ix_(dof, dof)]
        mujoco.mj_jacSite(model, data, self.jac6[:3], self.jac6[3:], ctl.site)
        d0 = int(dof[0])
        jac = self.jac6[:, d0:d0 + 7]  # the arm's columns (contiguous here)
        qd = data.qvel[dof]
        x = lapack.dposv(mass, jac.T)[1]                       # M^-1 J^T
        lam_inv = jac @ x + 1e-6 * np.eye(6)
        # pose error: position, rotation vector of q_d * conj(q)
        site_quat, qerr = np.empty(4), np.empty(4)
        mujoco.mju_mat2Quat(site_quat, data.site_xmat[ctl.site])
        mujoco.mju_negQuat(site_quat, site_quat)
        mujoco.mju_mulQuat(qerr, quat_d, site_quat)
        w, a, b, c = qerr.tolist()
        if w < 0.0:
            w, a, b, c = -w, -a, -b, -c
        vnorm = math.sqrt(a * a + b * b + c * c)
        angle = 2.0 * math.atan2(vnorm, w)
        k = angle / vnorm if vnorm > 1e-12 else 0.0
        err = np.concatenate([pos_d - data.site_xpos[ctl.site], [a * k, b * k, c * k]])
        twist = jac @ qd
        vel = twist if twist_d is None else twist - twist_d
        bias = data.qfrc_bias[dof]
        # external torque: M0 (qd - qd0) / dt + b0 - tau0 - p0, low-pass filtered
        if self.prev is not None:
            t0, m0, qd0, b0, tau_p, p0 = self.prev
            dt = float(data.time) - t0
            if dt > 0.0:
                raw = m0 @ ((qd - qd0) / dt) + b0 - tau_p - p0
                self.ext_tau = self.ext_tau + dt / (ctl.ext_time_constant + dt) * (
                    raw - self.ext_tau)
        g = ctl.gains
        rhs = np.zeros((6, 9))
        rhs[:, 3:] = np.eye(6)
        if ctl.impedance is None:
            kp = np.array([g.kp_pos] * 3 + [g.kp_rot] * 3)
            kd = np.array([g.kd_pos] * 3 + [g.kd_rot] * 3)
            rhs[:, 0] = kp * err - kd * vel
        tau0 = mass @ (g.kn * (ctl.posture - data.qpos[self.qadr]) - g.dn * qd)
        rhs[:, 1] = x.T @ tau0
        rhs[:, 2] = x.T @ self.ext_tau
        y = lapack.dposv(lam_inv, rhs)[1]                      # Lambda rhs
        self.ext = y[:, 2].copy()
        if ctl.impedance is not None:
            k6 = ctl.impedance.stiffness()
            damp = 2.0 * ctl.impedance.damping_ratio * np.sqrt(k6 * np.abs(np.diag(y[:, 3:])))
            force = k6 * err - damp * vel
            for part, limit in ((slice(0, 3), TASK_FORCE_LIMIT), (slice(3, 6), TASK_TORQUE_LIMIT)):
                norm = float(np.linalg.norm(force[part]))
                if norm > limit:
                    force[part] *= limit / norm
                    self.hits[f"cap {part.start}"] += 1
            tau = jac.T @ (force - y[:, 1]) + tau0 + bias
        else:
            tau = jac.T @ (y[:, 0] - y[:, 1]) + tau0 + bias
        n_sat = int(np.count_nonzero(np.abs(tau) > TORQUE_LIMITS))
        if self.guard is not None:
            out = self.guard.apply(tau, qd, np.diag(mass).copy(), twist)
        else:
            out = np.clip(tau, -TORQUE_LIMITS, TORQUE_LIMITS)
        self.prev = (float(data.time), mass, qd, bias, out, data.qfrc_passive[dof])
        return out, n_sat


def _controller(scene: Any, impedance: bool, guard: bool) -> Any:
    from tli_verify.sim.controller import Gains, ImpedanceController
    from tli_verify.sim.franka_limits import CartesianImpedance, FrankaLimits, LimitGuard

    return ImpedanceController(
        scene, gains=Gains(kn=30.0, dn=8.0),
        impedance=CartesianImpedance(2000.0, 50.0, 1.0) if impedance else None,
        guard=LimitGuard(FrankaLimits(), 0.002) if guard else None)


@pytest.mark.parametrize(("impedance", "guard"), [(True, True), (True, False), (False, True),
                                                   (False, False)])
def test_the_torque_loop_equals_the_plain_law_bit_for_bit(scene: Any, impedance: bool,
                                                          guard: bool) -> None:
    import mujoco

    from tli_verify.sim.franka_limits import JOINT_VELOCITY_LIMITS
    from tli_verify.sim.robot import HOME_QPOS

    rng = np.random.default_rng(21 + 2 * impedance + guard)
    ctl = _controller(scene, impedance, guard)
    hits: Counter[str] = Counter()
    plain = _PlainController(ctl, hits)
    data = scene.new_data()
    data.qpos[scene.qpos_adr] = HOME_QPOS
    mujoco.mj_forward(scene.model, data)
    pos, quat = ctl.target_pose_from_ds_state(ctl.ds_state(data))
    twist: np.ndarray | None = None
    for i in range(400):
        # a wandering state, now and then a fast joint (brake, reflex) or a far target (caps);
        # held for 99 calls once (the rate limit catches up: torque changes within the limit)
        data.time += 0.002 if i % 37 else 0.0  # dt = 0 once in a while: no filter update
        if 200 < i < 300:
            mujoco.mj_forward(scene.model, data)
            tau = ctl.compute(data, pos, quat, twist)
            ref, n_sat = plain.compute(data, pos, quat, twist)
            assert np.array_equal(tau, ref), (i, tau - ref)
            continue
        data.qpos[scene.qpos_adr] = HOME_QPOS + rng.uniform(-0.3, 0.3, size=7)
        qd = rng.normal(scale=0.3, size=7)
        if i % 5 == 0:
            j = rng.integers(7)
            qd[j] = np.copysign(rng.uniform(0.8, 1.05) * JOINT_VELOCITY_LIMITS[j], qd[j])
        data.qvel[:] = rng.normal(scale=0.02, size=scene.model.nv)
        data.qvel[scene.dof_adr] = qd
        mujoco.mj_forward(scene.model, data)
        far = 20.0 if i % 4 == 0 else 1.0
        z = ctl.ds_state(data) + far * rng.normal(scale=[0.005, 0.005, 0.005, 0.02, 0.02, 0.02])
        pos, quat = ctl.target_pose_from_ds_state(z)
        twist = rng.normal(scale=0.2, size=6) if i % 3 else None
        tau = ctl.compute(data, pos, quat, twist)
        ref, n_sat = plain.compute(data, pos, quat, twist)
        assert np.array_equal(tau, ref), (i, tau - ref)
        assert np.array_equal(data.ctrl[scene.act_ids], ref)
        if i % 3 == 0:  # read now and then: the solves between see a stale column 2
            assert np.array_equal(ctl.external_wrench, plain.ext)
        assert ctl.last_saturated == n_sat
        if plain.guard is not None:
            assert ctl.guard.stopped == plain.guard.stopped
            assert ctl.guard.ratios() == plain.guard.max
    # every branch ran
    assert hits["cap 0"] > 0 if impedance else True
    assert hits["cap 3"] > 0 if impedance else True
    if guard:
        for branch in ("brake", "fast joint", "torque clip", "rate clip", "rate free"):
            assert hits[branch] > 0, branch


def test_the_rig_torque_loop_equals_the_plain_control_period() -> None:
    """:meth:`PandaRig.step` (ramp and target quaternion in floats, the controller's fast
    entry) against the plain period: ramp ``z = from + (goal - from) k / n`` in numpy,
    :meth:`ImpedanceController.target_pose_from_ds_state`, ``xfrc_applied`` set by index and
    :meth:`ImpedanceController.step` per physics step; the same commands and pushes (set by the
    ``before`` hook, as a person's hand is), every physics step's torques compared."""
    require_panda()
    from tli_verify.sim.demos import PandaRig

    def plain_step(rig: Any, n: int, before: Any) -> None:
        ctl, data = rig.controller, rig.data
        for k in range(1, n + 1):
            before(k - 1)
            z = rig._from + (rig._goal - rig._from) * (k / n)
            pos, quat = ctl.target_pose_from_ds_state(z)
            data.xfrc_applied[rig.carrier] = rig.push
            ctl.step(data, pos, quat, rig._twist, substeps=1, control_every=1)
        rig._from = rig._goal

    rigs = [PandaRig(0), PandaRig(0)]
    assert np.array_equal(rigs[0].data.qpos, rigs[1].data.qpos)
    logs: list[list[np.ndarray]] = [[], []]
    rng = np.random.default_rng(7)
    pushes = rng.normal(scale=[15.0, 15.0, 15.0, 1.0, 1.0, 1.0], size=(40, 6))
    velocities = rng.normal(scale=[0.05, 0.05, 0.05, 0.2, 0.2, 0.2], size=(40, 6))
    for period in range(40):
        for r, (rig, log) in enumerate(zip(rigs, logs, strict=True)):
            def before(k: int, rig: Any = rig, log: list[np.ndarray] = log,
                       push: np.ndarray = pushes[period] if period % 3 else 0.0 * pushes[0]
                       ) -> None:
                log.append(rig.data.ctrl.copy())
                rig.push[:] = push * (k / 10)

            goal = rig.pose() + 0.02 * velocities[period]
            rig.command(goal, velocities[period] if period % 4 else None)
            if r == 0:
                rig.step(10, before=before)
            else:
                plain_step(rig, 10, before)
        assert np.array_equal(rigs[0].data.ctrl, rigs[1].data.ctrl), period
    assert np.array_equal(np.array(logs[0]), np.array(logs[1]))
    assert np.array_equal(rigs[0].data.qpos, rigs[1].data.qpos)
    assert np.array_equal(rigs[0].controller.external_wrench, rigs[1].controller.external_wrench)
    assert rigs[0].guard.ratios() == rigs[1].guard.ratios()
