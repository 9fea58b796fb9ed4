"""Passive-DS control of the Panda: the DS evaluated at the measured pose, tracked by damping.

Kronander and Billard's passive interaction control with dynamical systems. (Not the paper's
robot's law: its appendix on Robot Experiment 1 integrates the DS velocity to a target pose that
a Cartesian pose impedance controller tracks, with the robot state from the control interface --
the loop's default *measured* law, :func:`tli_verify.sim.loop.run_trial`. This law is the
alternative the loop offers, ``controller="passive"``.) The DS ``f`` is evaluated at the
*measured* state once per control period (the loop, :mod:`tli_verify.sim.loop`, with the
executive's modulation and mode switching), and the torque loop (every physics step, 500 Hz or
1 kHz) applies::

    F_lin = -D (v - f_lin(x)),   D = Q diag(lambda1, lambda2, lambda2) Q^T,   Q e1 = f / |f|
    tau_rot = k_r e - d_r (w - w_f(x)),     w_f = R0 J_l(v) f_rot(x)   (the DS's turn rate)
    tau = J^T (F_lin, tau) + (I - J^T Jbar^T) M [Kn (q_n - q) - Dn qdot] + C qdot + g

with ``v, w`` the measured site twist ``J qdot`` (world frame), ``f_rot`` the DS's rates of
the rotation vector ``v`` of the pose (:class:`~tli_verify.sim.controller.DSStateMap`: ``w_f``
is the angular velocity they make at the measured orientation), ``e`` the rotation vector from
the tray's orientation to the orientation servo's (none without a servo: ``e = 0``), the
dynamically consistent null-space
projector of :mod:`tli_verify.sim.controller` and MuJoCo's bias (gravity and Coriolis
compensation). There is no target pose: the DS's velocity field is the reference, so the robot
goes where the DS at its *own* state sends it, and a cut learned on the measured state bounds
the robot, not an integrated target.

Passivity (the energy tank)
    Since ``D f = lambda1 f``, the controller's power into the arm is
    ``-v^T D v + lambda1 v^T f`` (plus the rotation term alike): a dissipative part and the DS
    part ``p = lambda1 v^T f + d_r w^T w_f``, which is not sign-definite for a
    non-conservative ``f`` (LPV-DS is one). A virtual tank ``s`` in ``[0, s_max]`` stores the
    energy the damping dissipates (``ds = alpha v^T D v dt`` while ``s < s_max``) and the
    energy the DS part takes back (``p < 0``); the DS part may inject energy (``p > 0``) only
    while ``s > s_min``, otherwise it is switched off for that physics step (``beta = 0``) and
    the law is pure damping. Arm plus tank then never gain energy other than through the
    external port (the person's hand, the beads) and the posture spring (a potential): the
    translational passive-DS law is passive (Kronander and Billard 2016, Sec. IV; Ferraguti
    et al. 2013 for the tank). **Not covered**: the orientation servo's reference moves (it is
    integrated from the DS's rotation rates), so its spring is not a fixed potential and the
    energy it injects is not drawn from the tank; it is bounded by the servo's leash (0.15 rad
    at 50 Nm/rad: 0.56 J of spring energy at most). Recorded per trial: the lowest tank level
    and the physics steps at which the DS part was withheld.

What carries over from the certificate, and what does not
    The certificate proves ``V`` decreasing along the sampled-data DS ``x_{k+1} = x_k + T f(x_k)``
    (modulated: Thm. 1). Under this controller ``x_{k+1} = x_k + T f(x_k) + e_k``, where
    ``e_k`` is the tracking error of one period: the arm's inertia (time constant
    ``Lambda / lambda`` of a few ms), contact forces (the pile, the bowls) and torque or force
    saturation. The certificate says nothing about ``e_k``; it is measured per trial (the
    largest distance between the measured pose and the modes' cut sets, and whether the
    robot was ever outside a cut's half-space: ``TrialResult.cut_distance``). What carries
    over: the DS, its modulation and the mode logic act on the robot's own state, so an exit
    that the certificate's invariance does not explain is the robot's and is cut where the
    robot was -- not 4-5 cm ahead of it on an integrated target.

Gains (:class:`PassiveGains`)
    ``lambda1 = 200 Ns/m`` along the flow, ``lambda2 = 150 Ns/m`` across it, ``d_r =
    6 Nms/rad`` about every axis; the servo's ``k_r = 50 Nm/rad`` (the tracking rig's); the
    tank holds up to 10 J, starts full and withholds the DS part below 0.05 J. The Franka
    documents Cartesian stiffness in 10-3,000 N/m and 1-300 Nm/rad and critically damps it; the
    damping it would apply at the top of the range on this arm's task-space inertia (about 2-4
    kg at the tray) is ``2 sqrt(3000 x 3) ~ 190 Ns/m``, and its rotational one ``2 sqrt(300 x
    0.03) ~ 6 Nms/rad``: :data:`DAMPING_RANGE` refuses more. The task wrench is capped at the
    tracking rig's 35 N / 6 N m and the joint torques pass the
    :class:`~tli_verify.sim.franka_limits.LimitGuard` (torque, torque rate, velocity, reflex).
    An orientation servo (``k_r``) holds the tray at an orientation the loop integrates from the
    DS's rotation rates on a 0.15 rad leash of the measured one
    (:meth:`PassiveDSController.set_velocity` ``orientation``): without it the pile's contact
    torques turned the tray, which pure damping does not resist.

References
----------
K. Kronander and A. Billard, "Passive Interaction Control With Dynamical Systems", IEEE RA-L
1(1), 2016. F. Ferraguti, C. Secchi, C. Fantuzzi, "A tank-based approach to impedance control
with variable stiffness", ICRA 2013.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt
from scipy.linalg import lapack

from tli_verify.errors import InputError, SolverError
from tli_verify.sim.controller import (
    TASK_FORCE_LIMIT,
    TASK_TORQUE_LIMIT,
    DSStateMap,
    Gains,
    arm_mass_index,
)
from tli_verify.sim.franka_limits import LimitGuard
from tli_verify.sim.robot import HOME_QPOS, Panda

__all__ = ["DAMPING_RANGE", "PassiveDSController", "PassiveGains"]

FloatArray = npt.NDArray[np.float64]
_dposv = lapack.dposv

DAMPING_RANGE = ((10.0, 200.0), (0.5, 6.0))
"""Translational (Ns/m) and rotational (Nms/rad) damping :class:`PassiveGains` accepts: up to
critical damping of the Franka's largest documented stiffness (3,000 N/m, 300 Nm/rad) on the
arm's task-space inertia at the tray (module doc)."""


@dataclass(frozen=True, slots=True)
class PassiveGains:
    """Gains of the passive-DS law (module doc).

    Attributes
    ----------
    lambda1 : float
        Damping along the DS's velocity (Ns/m).
    lambda2 : float
        Damping across it (Ns/m).
    k_rot : float
        The orientation servo's stiffness (Nm/rad), within the Franka's 1-300 Nm/rad.
    d_rot : float
        Damping of the angular velocity about the DS's (Nms/rad), every axis.
    tank_max, tank_min, tank_start : float
        Energy tank bounds and initial level (J).
    """

    lambda1: float = 200.0
    lambda2: float = 150.0
    k_rot: float = 50.0
    d_rot: float = 6.0
    tank_max: float = 10.0
    tank_min: float = 0.05
    tank_start: float = 10.0

    def __post_init__(self) -> None:
        (tlo, thi), (rlo, rhi) = DAMPING_RANGE
        for name, value, lo, hi in (("lambda1", self.lambda1, tlo, thi),
                                    ("lambda2", self.lambda2, tlo, thi),
                                    ("d_rot", self.d_rot, rlo, rhi),
                                    ("k_rot", self.k_rot, 1.0, 300.0)):
            if not (math.isfinite(value) and lo <= value <= hi):
                raise InputError(f"passive gains: field {name!r} = {value!r} outside "
                                 f"[{lo:g}, {hi:g}]")
        if not (0.0 <= self.tank_min < self.tank_start <= self.tank_max):
            raise InputError("passive gains: need 0 <= tank_min < tank_start <= tank_max, got "
                             f"{self.tank_min}, {self.tank_start}, {self.tank_max}")

    def to_dict(self) -> dict[str, float]:
        """The evidence's record."""
        return {"lambda1": self.lambda1, "lambda2": self.lambda2,
                "k_rot": self.k_rot, "d_rot": self.d_rot, "tank_max": self.tank_max,
                "tank_min": self.tank_min, "tank_start": self.tank_start}


class PassiveDSController:
    """The passive-DS torque law at the tray site (module doc).

    Parameters
    ----------
    panda : Panda
    site : int
        The controlled site (the tray).
    dsmap : DSStateMap
        Its DS state map (position and the rotation vector in its chart).
    gains : PassiveGains, optional
    posture : Gains, optional
        Null-space posture gains (``kn``, ``dn``; per unit joint mass).
    guard : LimitGuard, optional
        The Franka's limits on every command.
    ext_time_constant : float, optional
        Low-pass time constant (s) of the external wrench estimate.

    Attributes
    ----------
    tank : float
        The tank's level (J).
    tank_low : float
        Its lowest level since :meth:`reset_tank`.
    withheld : int
        Physics steps at which the DS part was switched off (empty tank).
    """

    def __init__(self, panda: Panda, site: int, dsmap: DSStateMap, *,
                 gains: PassiveGains | None = None, posture: Gains | None = None,
                 guard: LimitGuard | None = None, ext_time_constant: float = 0.02) -> None:
        self.panda, self.model, self.site, self.map = panda, panda.model, int(site), dsmap
        self.gains = PassiveGains() if gains is None else gains
        pg = Gains() if posture is None else posture
        self.kn, self.dn = float(pg.kn), float(pg.dn)
        self.posture = np.array(HOME_QPOS, dtype=np.float64)
        self.guard = guard
        self.ext_time_constant = float(ext_time_constant)
        self._dof = panda.dof_adr
        self._qadr = panda.qpos_adr
        self._act = panda.act_ids
        self._idx_m = arm_mass_index(self.model, self._dof)
        self._jac6 = np.zeros((6, self.model.nv))
        self._f = np.zeros(6)  # the DS velocity (m/s, rad/s) held over the control period
        self._servo: tuple[float, float, float] | None = None  # the servo's rotation vector
        self._quat = np.zeros(4)
        self._qd = np.zeros(4)
        self._qerr = np.zeros(4)
        self._prev: tuple[float, FloatArray, FloatArray, FloatArray, FloatArray,
                          FloatArray] | None = None
        self._ext_tau = np.zeros(7)
        self._lam_inv = np.eye(6)
        self._x = np.zeros((7, 6))
        self.reset_tank()

    def reset_tank(self) -> None:
        """Fill the tank to its start level and zero its record (a new trial)."""
        self.tank = self.gains.tank_start
        self.tank_low = self.tank
        self.withheld = 0

    def set_velocity(self, f: npt.ArrayLike, orientation: npt.ArrayLike | None = None
                     ) -> None:
        """The DS velocity ``(vx, vy, vz [m/s], rates of rx, ry, rz [rad/s])`` to track until
        the next call (evaluated by the loop at the measured state), shape (6,), and the
        orientation servo's rotation vector (shape (3,), rad; None: no orientation spring)."""
        fa = np.asarray(f, dtype=np.float64).reshape(-1)
        if fa.shape != (6,) or not np.all(np.isfinite(fa)):
            raise SolverError(f"passive control: DS velocity must be 6 finite numbers, got {f!r}")
        self._f[:] = fa
        if orientation is None:
            self._servo = None
        else:
            oa = np.asarray(orientation, dtype=np.float64).reshape(-1)
            if oa.shape != (3,) or not np.all(np.isfinite(oa)):
                raise SolverError("passive control: the servo's orientation must be 3 finite "
                                  f"numbers, got {orientation!r}")
            self._servo = (float(oa[0]), float(oa[1]), float(oa[2]))

    def compute(self, data: Any) -> list[float]:
        """Joint torques of the law at the current state (after ``mj_step1``), written to the
        motors; returns them (7 floats)."""
        g = self.gains
        m = self.model
        mujoco.mj_jacSite(m, data, self._jac6[:3], self._jac6[3:], self.site)
        jac = self._jac6[:, self._dof]
        qd = data.qvel[self._dof].copy()
        q = data.qpos[self._qadr]
        mass = data.M[self._idx_m]
        bias = data.qfrc_bias[self._dof].copy()
        _, x, info = _dposv(mass, jac.T)
        if info != 0:
            raise SolverError(f"model: the arm mass matrix is not positive definite (info {info})")
        lam_inv = jac @ x
        lam_inv[np.diag_indices(6)] += 1e-6
        twist = jac @ qd
        v, w = twist[:3], twist[3:]
        f_lin = self._f[:3]
        # the DS's turn rate at the measured orientation (world frame)
        w_f = self.map.twist_from_ds_velocity(self._f, self.map.ds_state(data))[3:]
        dt = float(m.opt.timestep)
        # D = Q diag(l1, l2, l2) Q^T with Q e1 = f / |f|: l2 I + (l1 - l2) e1 e1^T; below
        # 1 mm/s the direction fades out (D -> l2 I ... l1 along f, continuous in f)
        speed = float(np.linalg.norm(f_lin))
        blend = min(1.0, speed / 1e-3)
        e1 = f_lin / speed if speed > 0.0 else np.zeros(3)
        dv = v @ e1
        damp_v = g.lambda2 * v + (g.lambda1 - g.lambda2) * blend * dv * e1  # D v
        lam_f = g.lambda1 * f_lin if blend >= 1.0 else \
            g.lambda2 * f_lin + (g.lambda1 - g.lambda2) * blend * (f_lin @ e1) * e1  # D f
        p_ds = float(v @ lam_f) + g.d_rot * float(w @ w_f)  # the DS part's power (W)
        dissipated = float(v @ damp_v) + g.d_rot * float(w @ w)
        beta = 1.0
        if p_ds > 0.0 and self.tank <= g.tank_min:
            beta = 0.0
            self.withheld += 1
        gain = dissipated - beta * p_ds  # into the tank (>= -p_ds when injecting)
        self.tank = min(g.tank_max, self.tank + dt * gain)
        self.tank_low = min(self.tank_low, self.tank)
        force = -damp_v + beta * lam_f
        # orientation: the turn rate towards the DS's, and the servo's spring
        torque = g.d_rot * (beta * w_f - w)
        if self._servo is not None:
            self.map.target_quat_into(*self._servo, self._qd)
            mujoco.mju_mat2Quat(self._quat, data.site_xmat[self.site])
            mujoco.mju_negQuat(self._quat, self._quat)
            mujoco.mju_mulQuat(self._qerr, self._qd, self._quat)
            ew, ea, eb, ec = self._qerr.tolist()
            if ew < 0.0:
                ea, eb, ec, ew = -ea, -eb, -ec, -ew
            vn = math.sqrt(ea * ea + eb * eb + ec * ec)
            k = 2.0 * math.atan2(vn, ew) / vn if vn > 1e-12 else 2.0
            torque = torque + g.k_rot * k * np.array((ea, eb, ec))
        fn, tn = float(np.linalg.norm(force)), float(np.linalg.norm(torque))
        if fn > TASK_FORCE_LIMIT:
            force *= TASK_FORCE_LIMIT / fn
        if tn > TASK_TORQUE_LIMIT:
            torque *= TASK_TORQUE_LIMIT / tn
        wrench = np.concatenate((force, torque))
        # posture in the dynamically consistent null space (as sim.controller)
        tau0 = mass @ (self.kn * (self.posture - q) - self.dn * qd)
        _, y, info = _dposv(lam_inv, x.T @ tau0)
        if info != 0:
            raise SolverError(f"model: task-space inertia singular at the site (info {info})")
        tau = jac.T @ wrench + tau0 - jac.T @ y.ravel() + bias
        self._estimate_external(float(data.time), qd)
        self._lam_inv, self._x = lam_inv, x
        out = tau.tolist()
        if self.guard is not None:
            out = self.guard.apply_lists(out, qd.tolist(), mass, twist.tolist())
        self._prev = (float(data.time), mass.copy(), qd, bias, np.array(out),
                      data.qfrc_passive[self._dof].copy())
        data.ctrl[self._act] = out
        return out

    def _estimate_external(self, time: float, qd: FloatArray) -> None:
        """The filtered joint-space external torque (as
        :attr:`~tli_verify.sim.controller.ImpedanceController.external_wrench`)."""
        prev = self._prev
        if prev is None:
            return
        t0, m0, qd0, b0, tau0, p0 = prev
        dt = time - t0
        if dt <= 0.0:
            return
        raw = m0 @ ((qd - qd0) / dt) + b0 - tau0 - p0
        self._ext_tau += dt / (self.ext_time_constant + dt) * (raw - self._ext_tau)

    @property
    def external_wrench(self) -> FloatArray:
        """The estimated external wrench at the site ``(F, tau)`` (N, N m; world), shape (6,):
        ``Jbar^T tau_ext`` of the last call, from joint torques and the arm's model only."""
        y, info = _dposv(self._lam_inv, self._x.T @ self._ext_tau)[1:]
        if info != 0:  # pragma: no cover - the call's own solve succeeded on it
            raise SolverError(f"model: task-space inertia singular at the site (info {info})")
        return np.asarray(y, dtype=np.float64).ravel()
