"""The Franka Panda's limits, enforced in the torque loop, with a reflex stop and per-trial ratios.

Franka Emika's "Robot and interface specifications" (Panda) give, per joint,

* torque ``|tau_i| <= 87, 87, 87, 87, 12, 12, 12`` N m
  (:data:`~tli_verify.sim.robot.TORQUE_LIMITS`),
* torque rate ``|d tau_i / dt| <= 1000`` N m/s,
* velocity ``|qdot_i| <= 2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61`` rad/s,

and for the end effector a translational speed of 1.7 m/s and a rotational one of 2.5 rad/s. The
robot's Cartesian impedance interface accepts stiffnesses of about 10-3,000 N/m and 1-300 Nm/rad
(:class:`CartesianImpedance`).

:class:`LimitGuard` sits between the controller and the motors, as the robot's own limiter does:

1. **brake near the velocity limit**: a joint faster than ``brake_from`` of its limit gets a
   damping torque ``-B M_ii (qdot_i - brake_from * limit_i sign qdot_i)`` (``B`` =
   :attr:`FrankaLimits.brake_gain`);
2. **torque clip** at the torque limits;
3. **torque-rate clip**: each torque moves at most ``1000 N m/s * dt`` from the last one sent;
4. **reflex**: a joint velocity (or the end effector's speed) beyond its limit stops the robot,
   as the Panda's reflex does ("joint_velocity_violation", "cartesian_velocity_violation"). The
   loop then ends the trial as failed (the physics oracle's ``limits`` kind): a trial that stops
   is never hidden.

Every call records the largest ratio of each *commanded* quantity (before clipping) to its limit
(:meth:`LimitGuard.ratios`): a torque ratio above 1 means the controller asked for more than the
motor gives and was clipped; a velocity ratio is the measured velocity's.

References
----------
Franka Emika, "Robot and interface specifications", Panda (joint and Cartesian limits);
libfranka ``franka::limitRate`` (torque-rate limiting). Wang et al., "Temporal Logic
Imitation", CoRL 2022, Sec. 7.2 (the Panda experiment).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from operator import truediv
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import InputError
from tli_verify.sim.robot import TORQUE_LIMITS

__all__ = [
    "JOINT_VELOCITY_LIMITS",
    "TORQUE_RATE_LIMIT",
    "CartesianImpedance",
    "FrankaLimits",
    "LimitGuard",
]

FloatArray = npt.NDArray[np.float64]

#: Joint velocity limits (rad/s), Panda specifications, shape (7,).
JOINT_VELOCITY_LIMITS: FloatArray = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
#: Joint torque-rate limit (N m/s), every joint.
TORQUE_RATE_LIMIT = 1000.0
#: End-effector speed limits: translation (m/s), rotation (rad/s).
CARTESIAN_SPEED_LIMITS = (1.7, 2.5)
#: The Cartesian impedance range the robot's interface accepts: (N/m), (Nm/rad).
STIFFNESS_RANGE = ((10.0, 3000.0), (1.0, 300.0))


@dataclass(frozen=True, slots=True)
class CartesianImpedance:
    """Cartesian stiffness and damping of the pose controller, in the robot's units.

    The task-space force is ``F = K e - D (J qdot - v_d)`` with ``K = diag(k_pos I3, k_rot
    I3)`` and ``D_jj = 2 zeta sqrt(K_jj Lambda_jj)`` (``Lambda``: the task-space inertia at the
    current posture), i.e. each axis is a spring-damper of damping ratio ``zeta`` on the arm's
    own inertia along it.

    Attributes
    ----------
    stiffness_pos : float
        N/m, within 10-3,000 (the robot's range).
    stiffness_rot : float
        Nm/rad, within 1-300.
    damping_ratio : float
        ``zeta``, within (0, 2].
    """

    stiffness_pos: float = 2000.0
    stiffness_rot: float = 150.0
    damping_ratio: float = 1.0

    def __post_init__(self) -> None:
        (plo, phi), (rlo, rhi) = STIFFNESS_RANGE
        if not plo <= self.stiffness_pos <= phi:
            raise InputError(f"impedance: field 'stiffness_pos' {self.stiffness_pos:g} N/m is "
                            f"outside the Franka's range {plo:g}-{phi:g} N/m")
        if not rlo <= self.stiffness_rot <= rhi:
            raise InputError(f"impedance: field 'stiffness_rot' {self.stiffness_rot:g} Nm/rad is "
                            f"outside the Franka's range {rlo:g}-{rhi:g} Nm/rad")
        if not 0.0 < self.damping_ratio <= 2.0:
            raise InputError(f"impedance: field 'damping_ratio' {self.damping_ratio:g}: need "
                            "0 < zeta <= 2")

    def stiffness(self) -> FloatArray:
        """``diag(K)``, shape (6,)."""
        return np.array([self.stiffness_pos] * 3 + [self.stiffness_rot] * 3)

    def to_dict(self) -> dict[str, float]:
        """The evidence's record."""
        return {"stiffness_pos": self.stiffness_pos, "stiffness_rot": self.stiffness_rot,
                "damping_ratio": self.damping_ratio}


@dataclass(frozen=True, slots=True)
class FrankaLimits:
    """The limits :class:`LimitGuard` enforces (module doc).

    Attributes
    ----------
    torque : ndarray, shape (7,)
        N m.
    torque_rate : float
        N m/s.
    joint_velocity : ndarray, shape (7,)
        rad/s.
    cartesian_speed : (float, float)
        End-effector translation (m/s) and rotation (rad/s) speed limits.
    brake_from : float
        Fraction of a joint's velocity limit beyond which it is braked.
    brake_gain : float
        ``B`` (1/s) of the brake.
    reflex : bool
        Stop at a violated velocity limit (the robot's reflex); False only records.
    """

    torque: FloatArray = field(default_factory=lambda: TORQUE_LIMITS.copy())
    torque_rate: float = TORQUE_RATE_LIMIT
    joint_velocity: FloatArray = field(default_factory=lambda: JOINT_VELOCITY_LIMITS.copy())
    cartesian_speed: tuple[float, float] = CARTESIAN_SPEED_LIMITS
    brake_from: float = 0.85
    brake_gain: float = 200.0
    reflex: bool = True

    def to_dict(self) -> dict[str, Any]:
        """The evidence's record."""
        return {"torque": [float(v) for v in self.torque], "torque_rate": self.torque_rate,
                "joint_velocity": [float(v) for v in self.joint_velocity],
                "cartesian_speed": list(self.cartesian_speed), "brake_from": self.brake_from,
                "brake_gain": self.brake_gain, "reflex": self.reflex}


RATIO_KEYS = ("torque", "torque_rate", "joint_velocity", "cartesian_speed", "rotation_speed")
"""The per-trial limit ratios (:meth:`LimitGuard.ratios`)."""


class LimitGuard:
    """Enforce :class:`FrankaLimits` on each torque command (module doc).

    Parameters
    ----------
    limits : FrankaLimits
    dt : float
        Seconds between two commands (the torque loop's period).

    Attributes
    ----------
    stopped : str or None
        The reflex that stopped the robot (e.g. ``"joint 4 velocity 2.31 rad/s > 2.175"``).
    """

    __slots__ = ("_last", "_max", "_tmax", "_vmax", "dt", "limits", "stopped")

    def __init__(self, limits: FrankaLimits, dt: float) -> None:
        self.limits = limits
        self.dt = float(dt)
        self._last: list[float] | None = None
        self._max = dict.fromkeys(RATIO_KEYS, 0.0)
        self.stopped: str | None = None
        self._tmax: list[float] = np.asarray(limits.torque, dtype=np.float64).tolist()
        self._vmax: list[float] = np.asarray(limits.joint_velocity, dtype=np.float64).tolist()

    def reset_ratios(self) -> None:
        """Zero the recorded ratios and forget a reflex (a new trial)."""
        self._max = dict.fromkeys(RATIO_KEYS, 0.0)
        self.stopped = None

    def ratios(self) -> dict[str, float]:
        """The largest ratio to each limit since :meth:`reset_ratios` (keys :data:`RATIO_KEYS`)."""
        return dict(self._max)

    def apply(self, tau: FloatArray, qdot: FloatArray, mass_diag: FloatArray,
              twist: FloatArray | None = None) -> FloatArray:
        """The torques to send for the commanded ``tau``.

        Parameters
        ----------
        tau : ndarray, shape (7,)
            Commanded torques (N m), before any limit.
        qdot : ndarray, shape (7,)
            Measured joint velocities (rad/s).
        mass_diag : ndarray, shape (7,)
            Diagonal of the joint-space mass matrix (kg m^2), for the brake.
        twist : ndarray, shape (6,), optional
            Measured end-effector twist (m/s, rad/s) for the Cartesian speed check.

        Returns
        -------
        ndarray, shape (7,)
            Within the torque and torque-rate limits; zero torque change (hold) after a reflex.
        """
        tw = None if twist is None else twist.tolist()
        return np.array(self.apply_lists(tau.tolist(), qdot.tolist(), mass_diag, tw))

    def apply_lists(self, tau: list[float], qdot: list[float], mass: FloatArray,
                    twist: list[float] | None = None) -> list[float]:
        """:meth:`apply` on lists of floats (the torque loop's entry; no conversions).

        ``mass`` is the diagonal (shape (7,)) or the whole joint-space mass matrix (7, 7),
        read only when a joint is braked. Returns the torques to send, a list of 7 floats.

        The seven joints are written out one by one (Python floats, the IEEE roundings of
        numpy's elementwise operations): numpy's per-call overhead, and a comprehension's
        frame, dominate on 7-vectors, and the torque loop runs this every physics step.
        """
        lim = self.limits
        q0, q1, q2, q3, q4, q5, q6 = qdot
        v0, v1, v2, v3, v4, v5, v6 = self._vmax
        peak = max(abs(q0) / v0, abs(q1) / v1, abs(q2) / v2, abs(q3) / v3, abs(q4) / v4,
                   abs(q5) / v5, abs(q6) / v6)
        m = self._max
        if peak > m["joint_velocity"]:
            m["joint_velocity"] = peak
        if twist is not None:
            tw = twist
            lin = math.sqrt(tw[0] ** 2 + tw[1] ** 2 + tw[2] ** 2) / lim.cartesian_speed[0]
            rot = math.sqrt(tw[3] ** 2 + tw[4] ** 2 + tw[5] ** 2) / lim.cartesian_speed[1]
            if lin > m["cartesian_speed"]:
                m["cartesian_speed"] = lin
            if rot > m["rotation_speed"]:
                m["rotation_speed"] = rot
            if lim.reflex and self.stopped is None and max(lin, rot) > 1.0:
                self.stopped = (f"end-effector speed {lin * lim.cartesian_speed[0]:.2f} m/s, "
                                f"{rot * lim.cartesian_speed[1]:.2f} rad/s beyond "
                                f"{lim.cartesian_speed[0]:g} m/s / {lim.cartesian_speed[1]:g} "
                                "rad/s")
        vmax = self._vmax
        if lim.reflex and self.stopped is None and peak > 1.0:
            j = list(map(truediv, map(abs, qdot), vmax)).index(peak)
            self.stopped = (f"joint {j + 1} velocity {abs(qdot[j]):.3f} rad/s beyond "
                            f"its limit {vmax[j]:g} rad/s")
        t = tau
        if peak > lim.brake_from:
            t = list(t)
            vel_ratio = list(map(truediv, map(abs, qdot), vmax))
            md = (mass.diagonal() if mass.ndim == 2 else mass).tolist()
            for j in range(7):
                if vel_ratio[j] > lim.brake_from:
                    excess = qdot[j] - math.copysign(lim.brake_from * vmax[j], qdot[j])
                    t[j] -= lim.brake_gain * md[j] * excess
        t0, t1, t2, t3, t4, t5, t6 = t
        l0, l1, l2, l3, l4, l5, l6 = self._tmax
        worst = max(abs(t0) / l0, abs(t1) / l1, abs(t2) / l2, abs(t3) / l3, abs(t4) / l4,
                    abs(t5) / l5, abs(t6) / l6)
        if worst > m["torque"]:
            m["torque"] = worst
        # |a| / b <= 1 (rounded) implies |a| <= b: then the clip is the identity
        if worst > 1.0:
            t0, t1, t2, t3, t4, t5, t6 = (min(max(a, -b), b)
                                          for a, b in zip(t, self._tmax, strict=True))
        last = self._last
        if last is None:
            out = [t0, t1, t2, t3, t4, t5, t6]
        else:
            step = lim.torque_rate * self.dt
            b0, b1, b2, b3, b4, b5, b6 = last
            c0, c1, c2, c3, c4, c5, c6 = t0 - b0, t1 - b1, t2 - b2, t3 - b3, t4 - b4, t5 - b5, \
                t6 - b6
            rate = max(abs(c0), abs(c1), abs(c2), abs(c3), abs(c4), abs(c5), abs(c6)) / step
            if rate > m["torque_rate"]:
                m["torque_rate"] = rate
            if rate <= 1.0:  # last + (out - last), as sent: not always out itself
                out = [b0 + c0, b1 + c1, b2 + c2, b3 + c3, b4 + c4, b5 + c5, b6 + c6]
            else:
                out = [b + min(max(c, -step), step) for b, c in
                       zip(last, (c0, c1, c2, c3, c4, c5, c6), strict=True)]
        self._last = out
        return out
