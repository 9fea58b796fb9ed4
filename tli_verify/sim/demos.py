"""Scripted scooping in the simulator: the waypoints and the rigs (a mocap-driven ladle, the Panda).

The scoop (world frame of :mod:`tli_verify.sim.scene`; pose = tray position + orientation,
``(x, y, z, rx, ry, rz)``: the rotation vector in the chart at
:data:`~tli_verify.sim.scene.TRAY_REFERENCE`, where a pitch ``p`` is ``(0, p, 0)``). The
soup bowl's floor is a funnel whose flat pit lies at the far side (-y), so the beads gather
against the far wall, ahead of the ladle (:data:`~tli_verify.sim.scene.SOUP_PIT`):

1. from the start above and beside the soup bowl, down onto the funnel's near slope (front
   tipped down by ``SLOPE_PITCH``), then slide down it towards -y, front edge leading;
2. push into the pile in the pit (the beads, held by the wall behind them, ride over the open
   front onto the tray), level the tray;
3. tip the front up (-0.3 rad) and lift out of the bowl (the rim keeps the beads);
4. carry to above the target bowl, lower, and pour (front down, 1.3 rad).

Measured with the mocap-driven ladle (:class:`MocapRig`, seeds 0-3): 12-14 beads delivered
(with the beads gathered in the bowl's middle instead, 2-4). The Franka project's
demonstrations follow this script on the Panda by kinesthetic teaching
(:mod:`tli_verify.sim.teacher`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from tli_verify.errors import TliError
from tli_verify.sim.controller import DSStateMap, Gains, ImpedanceController
from tli_verify.sim.franka_limits import CartesianImpedance, FrankaLimits, LimitGuard
from tli_verify.sim.franka_sensors import make_sensors
from tli_verify.sim.passive import PassiveDSController
from tli_verify.sim.robot import BODY_HAND, HOME_QPOS, TCP_OFFSET, Panda, panda_spec
from tli_verify.sim.scene import (
    DEFAULT_PHYSICS,
    N_BEADS,
    SOUP_CENTER,
    TARGET_CENTER,
    TRAY_HALF_THICKNESS,
    TRAY_RADIUS,
    TRAY_REFERENCE,
    PhysicsOptions,
    add_ladle,
    add_scene,
    add_stand,
    build_mocap_scene,
    reset_beads,
    scene_ids,
    set_contact_options,
    soup_floor,
    tray_quat,
)
from tli_verify.sim.sensors import Reading, ScoopSensors

__all__ = [
    "CONTROL_DT",
    "PITCH_POSE_COLUMNS",
    "POSITION_SCALE",
    "MocapRig",
    "ScoopStep",
    "from_ds",
    "from_ds_velocity",
    "model_columns",
    "pitch_column",
    "scoop_waypoints",
    "to_ds",
]

FloatArray = npt.NDArray[np.float64]

SLOPE_PITCH = 0.3
"""Pitch (rad) of the tray sliding down the funnel into the pit (front down, steeper than
the funnel's ``SOUP_SLOPE``, so the front edge leads)."""
SCOOP_PITCH = 0.15
CARRY_PITCH = -0.3
POUR_PITCH = 1.5


def _tray_height(y: float, pitch: float) -> float:
    """Tray-frame height that puts the tipped front edge (tray frame at ``y``) 1 mm over the
    soup bowl's floor (:func:`~tli_verify.sim.scene.soup_floor`)."""
    front = y - TRAY_RADIUS * math.cos(pitch)
    return float(soup_floor(front) + 0.001 + TRAY_RADIUS * math.sin(pitch)
                 + 2 * TRAY_HALF_THICKNESS * math.cos(pitch))


def scoop_waypoints(rng: np.random.Generator | None = None, *, jitter: float = 0.0,
                    start: npt.ArrayLike | None = None) -> FloatArray:
    """Timed waypoints of the scripted scoop (module doc).

    Parameters
    ----------
    rng : numpy Generator, optional
        Jitters the start and the carry waypoints, and shifts the scoop along x by half as
        much, when ``jitter > 0``.
    jitter : float, optional
        Uniform jitter half-width (m).
    start : array_like, shape (6,), optional
        The first waypoint's pose ``(x, y, z, rx, ry, rz)`` instead of the nominal start (a
        recovery demonstration; jittered like the nominal one). The script turns the tray from
        there to its own orientations (roll and yaw 0) by the next waypoint.

    Returns
    -------
    ndarray, shape (K, 7)
        Rows ``(time s, x, y, z [m], rx, ry, rz [rad])``, times increasing from 0; the script
        turns about the pitch axis only (``ry``), roll and yaw 0 but at a given start.
    """
    cx, cy = float(SOUP_CENTER[0]), float(SOUP_CENTER[1])
    tx, ty = float(TARGET_CENTER[0]), float(TARGET_CENTER[1])
    near, mid, far = cy + 0.07, cy, cy - 0.085
    w = np.array([
        (0.0, cx, 0.05, 0.20, 0.0),                                    # start, between bowls
        (1.0, cx, near, _tray_height(near, SLOPE_PITCH) + 0.03, SLOPE_PITCH),  # over the slope
        (1.5, cx, near, _tray_height(near, SLOPE_PITCH) + 0.002, SLOPE_PITCH),  # onto it
        (2.3, cx, mid, _tray_height(mid, SLOPE_PITCH), SLOPE_PITCH),   # slide down the funnel
        (3.0, cx, far, _tray_height(far, SCOOP_PITCH) - 0.01, SCOOP_PITCH),  # press into the pile
        (3.3, cx, far + 0.02, _tray_height(far, 0.0) + 0.003, 0.0),    # level the tray
        (3.7, cx, far + 0.03, _tray_height(far, 0.0) + 0.02, CARRY_PITCH),  # tip back
        (4.6, cx, near, 0.12, CARRY_PITCH),                            # lift out
        (5.4, tx, ty, 0.15, -0.2),                                     # carry over the target
        (6.2, tx, ty, 0.10, -0.2),                                     # lower
        (7.2, tx, ty, 0.10, POUR_PITCH),                               # pour
        (8.0, tx, ty, 0.10, POUR_PITCH),
    ])
    zeros = np.zeros(len(w))
    w = np.column_stack((w[:, :4], zeros, w[:, 4], zeros))  # (t, x, y, z, rx, ry=pitch, rz)
    if start is not None:
        s0 = np.asarray(start, dtype=np.float64)
        if s0.shape != (6,):
            raise TliError(f"scoop start: expected a pose (x, y, z, rx, ry, rz), got {start!r}")
        w[0, 1:] = s0
    if rng is not None and jitter > 0:
        for row in (0, 7, 8):
            w[row, 1:4] += rng.uniform(-jitter, jitter, size=3)
        w[1:7, 1] += rng.uniform(-jitter, jitter) / 2  # the whole scoop shifted along x
    return w


def interpolate(waypoints: FloatArray, t: float) -> FloatArray:
    """The pose ``(x, y, z, rx, ry, rz)`` at time ``t`` (piecewise linear in the chart's
    coordinates), shape (6,)."""
    return np.array([np.interp(t, waypoints[:, 0], waypoints[:, j])
                     for j in range(1, waypoints.shape[1])])


@dataclass(frozen=True, slots=True, eq=False)
class ScoopStep:
    """One sample of a scripted run.

    Attributes
    ----------
    time : float
    pose : ndarray, shape (6,)
        The tray's actual ``(x, y, z, rx, ry, rz)``.
    reading : Reading
    command : ndarray, shape (6,)
        The commanded pose (the impedance law's target) at that time.
    """

    time: float
    pose: FloatArray
    reading: Reading
    command: FloatArray


def _sensors(kind: str, model: mujoco.MjModel, ids: Any, seed: int) -> Any:
    """The rig's r, s, t sensors (:func:`tli_verify.sim.franka_sensors.make_sensors`)."""
    if kind == "ideal":
        return ScoopSensors(model, ids)

    return make_sensors(kind, model, ids, seed=seed)


@functools.lru_cache(maxsize=8)
def tray_map(site: int) -> DSStateMap:
    """The pose map of the tray site ``site``: position, and the rotation vector in the chart
    at :data:`~tli_verify.sim.scene.TRAY_REFERENCE`."""
    r0 = np.empty(9)
    mujoco.mju_quat2Mat(r0, np.array(TRAY_REFERENCE))
    return DSStateMap(int(site), r0.reshape(3, 3))


def tray_pose(data: mujoco.MjData, site: int) -> FloatArray:
    """The tray frame's pose ``(x, y, z [m], rx, ry, rz [rad])``, shape (6,) (module doc;
    :func:`tray_map`). For a pure pitch ``p`` (the front tipped down by ``p``, along
    ``(0, -cos p, -sin p)``) it is ``(x, y, z, 0, p, 0)``."""
    return tray_map(site).ds_state(data)


PITCH_POSE_COLUMNS = (0, 1, 2, 4)
"""The pose coordinates of a 4-D ``(x, y, z, pitch)`` DS (the paper's Fig. 11 state): the
position and ``ry``; it holds roll and yaw at 0 (:func:`model_columns`)."""


def model_columns(dim: int) -> tuple[int, ...]:
    """The coordinates of the 6-D pose ``(x, y, z, rx, ry, rz)`` a DS of dimension ``dim``
    runs on: all six, or :data:`PITCH_POSE_COLUMNS` for a 4-D DS (roll and yaw held at 0,
    the paper's Fig. 11 state).

    Raises
    ------
    TliError
        Another dimension.
    """
    if dim == 6:
        return (0, 1, 2, 3, 4, 5)
    if dim == 4:
        return PITCH_POSE_COLUMNS
    raise TliError(f"franka scoop: a DS on the tray pose has 6 coordinates (x, y, z, rx, ry, "
                   f"rz) or 4 (x, y, z, pitch), not {dim}")


def pitch_column(dim: int) -> int:
    """The column of the pitch (``ry``) in a DS state of dimension ``dim`` (4 or 6)."""
    return model_columns(dim).index(4)


class MocapRig:
    """Phase 1: the ladle on a free hand body under Cartesian impedance, the scene, the sensors.

    Each physics step applies ``F = K (p* - p) - D v`` and ``tau = K_r theta - D_r omega`` to
    the carrier (``theta``: the rotation vector from the ladle's orientation to the target's),
    plus any perturbation wrench the caller sets in :attr:`push`. ``p*`` and the target
    orientation come from :meth:`command` (also shown by the mocap marker).

    Parameters
    ----------
    seed : int, optional
        Bead placement (:func:`~tli_verify.sim.scene.reset_beads`).
    stiffness, rot_stiffness : float, optional
        ``K`` (N/m) and ``K_r`` (Nm/rad); dampings are critical for the carrier's mass and
        inertia.
    start : array_like, shape (6,), optional
        Initial pose ``(x, y, z, rx, ry, rz)`` of the tray (default: the scene's start,
        the reference orientation).
    in_bowl : int, optional
        Beads in the soup bowl (:func:`~tli_verify.sim.scene.reset_beads`).
    sensors : str, optional
        ``"ideal"`` or ``"franka"`` (:func:`~tli_verify.sim.franka_sensors.make_sensors`,
        seeded with ``seed``).
    physics : PhysicsOptions, optional
        Solver settings (default: the measured ones,
        :class:`~tli_verify.sim.scene.PhysicsOptions`).
    """

    def __init__(self, seed: int = 0, *, stiffness: float = 2000.0,
                 rot_stiffness: float = 150.0, start: npt.ArrayLike | None = None,
                 in_bowl: int = N_BEADS, sensors: str = "ideal",
                 physics: PhysicsOptions = DEFAULT_PHYSICS) -> None:
        self.k = float(stiffness)
        self.kr = float(rot_stiffness)
        self.push = np.zeros(6)
        self.model = build_mocap_scene(physics)
        self.data = mujoco.MjData(self.model)
        self.ids = scene_ids(self.model)
        self.sensors = _sensors(sensors, self.model, self.ids, seed)
        self._carrier = int(mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY,
                                              "ladle_carrier"))
        jnt = int(mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, "ladle_free"))
        self._qadr = int(self.model.jnt_qposadr[jnt])
        self._dadr = int(self.model.jnt_dofadr[jnt])
        mass = float(self.model.body_subtreemass[self._carrier])
        inertia = float(self.model.body_inertia[self._carrier].max()) + 0.12 * 0.05 ** 2
        self.d = 2.0 * math.sqrt(self.k * mass)
        self.dr = 2.0 * math.sqrt(self.kr * inertia)
        self._mass, self._inertia = mass, inertia
        self._ext = np.zeros(6)
        self._ctrl = np.zeros(6)
        self._target_q = np.zeros(4)
        self._err_q = np.zeros(4)
        self._rotvec = np.zeros(3)
        # views of the arrays physics_step reads and writes, made once (MjData never
        # reallocates them; each attribute access would build a new array object)
        d, a, v = self.data, self._qadr, self._dadr
        self._wrench = d.xfrc_applied[self._carrier]
        self._lin = d.xfrc_applied[self._carrier, :3]
        self._ang = d.xfrc_applied[self._carrier, 3:]
        self._pos = d.qpos[a:a + 3]
        self._quat = d.qpos[a + 3:a + 7]
        self._vel = d.qvel[v:v + 3]
        self._omega_body = d.qvel[v + 3:v + 6]
        self._xmat = d.xmat[self._carrier].reshape(3, 3)
        self._mocap_pos = d.mocap_pos[0]
        self._mocap_quat = d.mocap_quat[0]
        self.place([*self.data.mocap_pos[0].tolist(), 0.0, 0.0, 0.0] if start is None
                   else start)
        reset_beads(self.model, self.data, self.ids, seed=seed, step=self.physics_step,
                    in_bowl=in_bowl)

    @property
    def carrier(self) -> int:
        """Body id of the free body carrying the ladle (where wrenches go)."""
        return self._carrier

    def command(self, pose: npt.ArrayLike, velocity: npt.ArrayLike | None = None) -> None:
        """Move the target to ``(x, y, z, rx, ry, rz)``; the impedance law pulls the ladle there.
        ``velocity`` is accepted for the rigs' common interface and not used (the free tool's
        law has no feed-forward: the demonstrations were recorded without it)."""
        p = np.asarray(pose, dtype=np.float64)
        self.data.mocap_pos[0] = p[:3]
        self.data.mocap_quat[0] = tray_quat(p[3:6])

    def place(self, pose: npt.ArrayLike) -> None:
        """Teleport the ladle and its target to ``(x, y, z, rx, ry, rz)`` (at rest)."""
        p = np.asarray(pose, dtype=np.float64)
        self.command(p)
        a, d = self._qadr, self._dadr
        self.data.qpos[a:a + 3] = p[:3]
        self.data.qpos[a + 3:a + 7] = tray_quat(p[3:6])
        self.data.qvel[d:d + 6] = 0.0
        mujoco.mj_forward(self.model, self.data)

    def pose(self) -> FloatArray:
        """The tray's pose ``(x, y, z, rx, ry, rz)``, shape (6,)."""
        return tray_pose(self.data, self.ids.tray_site)

    def read(self) -> Reading:
        """The sensors now."""
        return self.sensors.read(self.data)

    def physics_step(self) -> None:
        """One physics step under the impedance law plus :attr:`push`."""
        # F = K (p* - p) - D v, per component in floats (the roundings of numpy's
        # elementwise operations: the same numbers)
        k, dv = self.k, self.d
        self._lin[:] = [k * (t - p) - dv * u for t, p, u in
                        zip(self._mocap_pos.tolist(), self._pos.tolist(), self._vel.tolist(),
                            strict=True)]
        # orientation error: target * conj(current), as a rotation vector (world frame)
        mujoco.mju_negQuat(self._err_q, self._quat)
        mujoco.mju_mulQuat(self._err_q, self._mocap_quat, self._err_q)
        mujoco.mju_quat2Vel(self._rotvec, self._err_q, 1.0)
        # free-joint angular velocity is in the body frame: rotate it to the world frame
        omega = (self._xmat @ self._omega_body).tolist()
        kr, dr = self.kr, self.dr
        self._ang[:] = [kr * r - dr * o for r, o in zip(self._rotvec.tolist(), omega,
                                                         strict=True)]
        ctrl = self._wrench.copy()
        v0 = np.concatenate((self._vel, omega))
        self._wrench += self.push
        mujoco.mj_step(self.model, self.data)
        # the external wrench the rig's own model does not explain (its mass and a scalar
        # inertia; gravity is compensated), low-pass 20 ms, as the arm's estimate
        v1 = np.concatenate((self._vel, self._xmat @ self._omega_body))
        dt = float(self.model.opt.timestep)
        inertia = np.array([self._mass] * 3 + [self._inertia] * 3)
        raw = inertia * (v1 - v0) / dt - ctrl
        self._ext += dt / (0.02 + dt) * (raw - self._ext)

    def external_wrench(self) -> FloatArray:
        """The estimated external wrench on the tool (N, N m; world), shape (6,): its
        acceleration times its mass (and a scalar inertia) minus the impedance wrench applied,
        low-pass filtered (20 ms)."""
        return self._ext

    @property
    def stopped(self) -> str | None:
        """The free tool has no reflex: always None."""
        return None

    def step(self, n: int = 1, before: Callable[[int], None] | None = None) -> None:
        """``n`` physics steps; ``before(k)`` (optional) is called before step ``k`` (e.g. to
        set :attr:`push`)."""
        for k in range(n):
            if before is not None:
                before(k)
            self.physics_step()

    def follow(self, waypoints: FloatArray, *, every: int = 10, until: float | None = None
               ) -> list[ScoopStep]:
        """Follow timed waypoints from the current time; sample every ``every`` steps.

        Parameters
        ----------
        waypoints : ndarray, shape (K, 5)
            From :func:`scoop_waypoints`.
        every : int, optional
        until : float, optional
            Stop at this script time (default: the last waypoint's).

        Returns
        -------
        list of ScoopStep
        """
        dt = float(self.model.opt.timestep)
        end = float(waypoints[-1, 0]) if until is None else float(until)
        out = []
        for k in range(round(end / dt)):
            self.command(interpolate(waypoints, k * dt))
            self.physics_step()
            if (k + 1) % every == 0:
                out.append(ScoopStep(round((k + 1) * dt, 9), self.pose(), self.read(),
                                     interpolate(waypoints, (k + 1) * dt)))
        return out


CONTROL_DT = 0.02
"""Control period (s) of the loop and of the recorded demonstrations: 10 physics steps."""
POSITION_SCALE = 10.0
"""DS state units: positions in decimetres (so they span about as much as the pitch in
radians; in metres the learner's SDPs were ill-conditioned: CLARABEL 'optimal_inaccurate')."""


def to_ds(pose: npt.ArrayLike) -> FloatArray:
    """Tray pose ``(x, y, z [m], rx, ry, rz [rad])`` -> DS state ``(x, y, z [dm], rx, ry,
    rz)`` (the position scaled; any trailing coordinates unchanged)."""
    p = np.array(pose, dtype=np.float64)
    p[..., :3] *= POSITION_SCALE
    return p


def from_ds(z: npt.ArrayLike) -> FloatArray:
    """DS state -> tray pose (the inverse of :func:`to_ds`)."""
    p = np.array(z, dtype=np.float64)
    p[..., :3] /= POSITION_SCALE
    return p


def from_ds_velocity(v: npt.ArrayLike) -> FloatArray:
    """DS velocity (dm/s, rad/s) -> tray velocity (m/s, rad/s): the same scaling as
    :func:`from_ds` (no offset)."""
    return from_ds(v)


PANDA_IMPEDANCE = CartesianImpedance(stiffness_pos=2000.0, stiffness_rot=50.0,
                                     damping_ratio=1.0)
"""The Panda rig's Cartesian impedance: 2,000 N/m and 50 Nm/rad (within the robot's range of
about 10-3,000 N/m and 1-300 Nm/rad), critically damped on the arm's task-space inertia. The
translational stiffness is the free tool's (:class:`MocapRig`, with which the demonstrations
were recorded); the rotational one is a third of its 150 Nm/rad, so that the loop's leash
(0.15 rad) asks at most 7.5 N m of the wrist joints' 12 N m (at 150 Nm/rad the wrist saturated,
lost its damping and its joint velocities tripped the reflex under a push)."""

PANDA_POSTURE_GAINS = Gains(kn=25.0, dn=10.0)
"""Null-space posture gains of the Panda rig (per unit joint mass); its task-space gains are
:data:`PANDA_IMPEDANCE`."""

CONTROLLERS = ("measured", "passive", "tracking")
"""The loop's control laws (:func:`tli_verify.sim.loop.run_trial`): *measured* (the paper's:
the DS at the measured pose, its velocity integrated to a target pose the Cartesian impedance
law tracks), *passive* (passive-DS: the DS at the measured pose tracked by damping,
:mod:`.passive`; the Panda only) and *tracking* (the DS run on its own integrated target, which
the impedance law tracks). The rig itself runs two: the impedance law on a commanded pose
(measured, tracking) or the passive-DS law."""

PANDA_TIMESTEPS = (0.002, 0.001)
"""Physics (and torque-loop) periods the Panda rig offers: 500 Hz (default) and 1 kHz, the
robot's own torque-loop rate."""


class PandaRig:
    """Phase 2: the ladle on the Panda hand, tracked by the Cartesian impedance controller.

    The same interface as :class:`MocapRig` (``command``, ``physics_step``, ``step``, ``pose``,
    ``read``, ``push``, ``carrier``, ``external_wrench``), so
    :func:`tli_verify.sim.loop.run_trial` runs either. The ladle is fixed under the hand with
    its grip at Franka's ``tcp`` frame (tool z down, the tray 15 cm below and 12 cm towards -y);
    the controller (:class:`tli_verify.sim.controller.ImpedanceController` with
    :data:`PANDA_IMPEDANCE` and a :class:`~tli_verify.sim.franka_limits.LimitGuard`) controls
    the tray site ``ladle_tray`` directly, with the nominal orientation of the ladle frame at
    pitch 0, so its DS state is this module's pose ``(x, y, z, rx, ry, rz)`` of the tray (the
    chart at :data:`~tli_verify.sim.scene.TRAY_REFERENCE`). Torques are
    computed at every physics step (the torque loop); the target moves linearly within each
    control period from the last commanded pose to the new one, with the DS velocity as
    feed-forward (a passive-DS controller tracks the DS's velocity). Before the trial the arm
    moves from the home posture to the demonstrations' start while the beads settle.

    Parameters
    ----------
    seed : int, optional
        Bead placement.
    assets : Path, optional
        Menagerie assets (default ``$TLI_SIM_ASSETS`` or ``sim/assets``; see
        :mod:`tli_verify.sim.assets`).
    timestep : float, optional
        Physics and torque-loop period, one of :data:`PANDA_TIMESTEPS` (s).
    impedance : CartesianImpedance, optional
        Default :data:`PANDA_IMPEDANCE`.
    limits : FrankaLimits, optional
        Default the Panda's (:class:`~tli_verify.sim.franka_limits.FrankaLimits`).
    sensors : str, optional
        ``"ideal"`` or ``"franka"`` (:func:`~tli_verify.sim.franka_sensors.make_sensors`,
        seeded with ``seed``).
    physics : PhysicsOptions, optional
        Solver settings (default: the measured ones,
        :class:`~tli_verify.sim.scene.PhysicsOptions`).
    controller : str, optional
        ``"tracking"`` (default here) or ``"measured"``: the Cartesian impedance law tracks
        the commanded pose (:meth:`command`; where the loop evaluates the DS is the loop's
        business), or ``"passive"``: after the setup move, the passive-DS law
        (:class:`~tli_verify.sim.passive.PassiveDSController`) tracks the DS velocity given by
        :meth:`command_velocity` at the measured pose.
    passive_gains : PassiveGains, optional
        Gains of the passive-DS law.
    start : array_like, shape (6,), optional
        The tray pose the setup moves the arm to (default: the scripted scoop's start).
    """

    def __init__(self, seed: int = 0, *, assets: Path | None = None, timestep: float = 0.002,
                 impedance: CartesianImpedance | None = None,
                 limits: FrankaLimits | None = None, sensors: str = "ideal",
                 physics: PhysicsOptions = DEFAULT_PHYSICS, controller: str = "tracking",
                 passive_gains: Any = None, start: npt.ArrayLike | None = None) -> None:

        if not any(abs(timestep - t) < 1e-12 for t in PANDA_TIMESTEPS):
            raise TliError(f"timestep {timestep:g} s: one of "
                           f"{', '.join(f'{t:g}' for t in PANDA_TIMESTEPS)}")
        spec = panda_spec(assets)
        set_contact_options(spec, physics)
        spec.option.timestep = float(timestep)
        add_scene(spec)
        back = 0.035 + 0.004 + 0.16 * 0.5
        up = 0.015 + 0.16 * math.sin(math.pi / 3)
        add_ladle(spec.body(BODY_HAND), pos=(-back, 0.0, TCP_OFFSET + up),
                  quat=(0.0, 0.0, 1.0, 0.0))
        for other in (BODY_HAND, "left_finger", "right_finger"):
            if spec.body(other) is not None:
                ex = spec.add_exclude()
                ex.bodyname1, ex.bodyname2 = "ladle", other
        add_stand(spec)  # drawn only: the physics is that of the scene without it
        spec.worldbody.add_light(pos=[0.5, 0.0, 1.5], dir=[0, 0, -1])
        try:
            self.model = spec.compile()
        except ValueError as exc:  # pragma: no cover - a bug in this module
            raise TliError(f"sim scene: MuJoCo refused the Panda scene: {exc}") from exc
        self.data = mujoco.MjData(self.model)
        self.panda = Panda.from_model(self.model)
        self.ids = scene_ids(self.model)
        self.sensors = _sensors(sensors, self.model, self.ids, seed)
        self.impedance = PANDA_IMPEDANCE if impedance is None else impedance
        self.limits = FrankaLimits() if limits is None else limits
        self.guard = LimitGuard(self.limits, float(timestep))
        self.controller = ImpedanceController(self.panda, site=self.ids.tray_site,
                                              r0=tray_map(self.ids.tray_site).r0,
                                              gains=PANDA_POSTURE_GAINS,
                                              impedance=self.impedance, guard=self.guard)
        self.push = np.zeros(6)
        # a person grabs the ladle, not the hand: their wrench acts at the ladle's centre of
        # mass (on the hand it levers about the tray, which the wrist's 12 N m cannot hold)
        self._carrier = int(mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, "ladle"))
        self._xfrc = self.data.xfrc_applied[self._carrier]  # a view (MjData never reallocates)
        self._quat_d = np.zeros(4)  # the target quaternion of the torque loop (a buffer)
        self.data.qpos[self.panda.qpos_adr] = HOME_QPOS
        mujoco.mj_forward(self.model, self.data)
        self._from = self.pose()
        self._goal = self._from.copy()
        self._twist: FloatArray | None = None
        start = scoop_waypoints()[0, 1:] if start is None else \
            np.asarray(start, dtype=np.float64).reshape(6)
        here = self.pose()
        for k in range(1, 51):  # 1 s to the start, then hold while the beads settle
            self.command(here + (start - here) * k / 50)
            self.step(round(CONTROL_DT / timestep))
        reset_beads(self.model, self.data, self.ids, seed=seed, step=self.physics_step)
        self.guard.reset_ratios()
        if controller not in CONTROLLERS:
            raise TliError(f"controller {controller!r}: one of {', '.join(CONTROLLERS)}")
        self.control_kind = controller  # measured and tracking: the impedance law on the
        # pose the loop commands (where it evaluates the DS is the loop's business)
        self.passive: Any = None
        if controller == "passive":
            self.passive = PassiveDSController(
                self.panda, self.ids.tray_site, self.controller.map, gains=passive_gains,
                posture=PANDA_POSTURE_GAINS, guard=self.guard)
            self.passive.posture = self.controller.posture

    def command_velocity(self, velocity: npt.ArrayLike,
                         orientation: npt.ArrayLike | None = None) -> None:
        """The DS velocity ``(dx, dy, dz [m/s], drx, dry, drz [rad/s])`` the passive-DS law
        tracks from the next :meth:`step` on (``controller="passive"``), and the orientation
        servo's rotation vector ``(rx, ry, rz)`` (rad; None: no orientation spring)."""
        if self.passive is None:
            raise TliError("command_velocity needs the passive-DS controller "
                           "(PandaRig(controller='passive'))")
        self.passive.set_velocity(velocity, orientation)

    @property
    def carrier(self) -> int:
        """Body id of the ladle (where a person's wrenches go)."""
        return self._carrier

    def command(self, pose: npt.ArrayLike, velocity: npt.ArrayLike | None = None) -> None:
        """The tray pose ``(x, y, z, rx, ry, rz)`` to reach by the end of the next
        :meth:`step` call (the target ramps there from the last one, linearly in the chart's
        coordinates), and the pose velocity ``(dx, dy, dz, drx, dry, drz)`` (m/s, rad/s;
        optional) as feed-forward (turned into the tray's twist at the new pose)."""
        self._from = self._goal
        self._goal = np.asarray(pose, dtype=np.float64).reshape(6).copy()
        self._twist = None if velocity is None else self.controller.map.twist_from_ds_velocity(
            np.asarray(velocity, dtype=np.float64), self._goal)

    def physics_step(self) -> None:
        """One physics step at the commanded pose: torques plus :attr:`push` on the hand."""
        self._from = self._goal
        self.step(1)

    def step(self, n: int = 1, before: Callable[[int], None] | None = None) -> None:
        """``n`` physics steps, torques computed every step; the target ramps from the last
        commanded pose to the new one over them. ``before(k)`` (optional) is called before step
        ``k`` (0-based; e.g. to set :attr:`push`)."""
        # What ImpedanceController.step(substeps=1) does per physics step (mj_step1, the
        # torques, mj_step2), with the ramp z = from + (goal - from) k / n and the target quat
        # on floats (the roundings of the numpy version; bit-identical torques)
        ctl, data, model = self.controller, self.data, self.model
        step1, step2 = mujoco.mj_step1, mujoco.mj_step2  # looked up per call (benchmark probes)
        passive = getattr(self, "passive", None)
        if passive is not None:  # the passive-DS law: no target pose
            xfrc = self._xfrc
            if before is None and n > 0:
                xfrc[:] = self.push
            for k in range(n):
                if before is not None:
                    before(k)
                    xfrc[:] = self.push
                step1(model, data)
                passive.compute(data)
                step2(model, data)
            return
        x0, y0, z0, a0, b0, c0 = self._from.tolist()
        dx, dy, dz, da, db, dc = (self._goal - self._from).tolist()
        twist = None if self._twist is None else self._twist.tolist()
        quat, xfrc, set_quat = self._quat_d, self._xfrc, ctl.map.target_quat_into
        control = ctl.compute_fast
        out = None
        if before is None and n > 0:
            xfrc[:] = self.push  # held over the steps (mj_step never writes xfrc_applied)
        for k in range(1, n + 1):
            if before is not None:
                before(k - 1)
                xfrc[:] = self.push
            r = k / n
            set_quat(a0 + da * r, b0 + db * r, c0 + dc * r, quat)
            x, y, z = x0 + dx * r, y0 + dy * r, z0 + dz * r
            step1(model, data)
            out = control(data, x, y, z, quat, twist)
            step2(model, data)
        if out is not None:
            ctl._last_tau = np.array(out)
        self._from = self._goal

    def pose(self) -> FloatArray:
        """The tray's pose ``(x, y, z, rx, ry, rz)``, shape (6,)."""
        return self.controller.map.ds_state(self.data)

    def external_wrench(self) -> FloatArray:
        """The controller's external wrench estimate at the tray (N, N m; world), shape (6,)
        (:attr:`~tli_verify.sim.controller.ImpedanceController.external_wrench`, or the
        passive-DS law's alike)."""
        if self.passive is not None:
            return self.passive.external_wrench
        return self.controller.external_wrench

    @property
    def person_wrench(self) -> FloatArray:
        """The wrench a person's hand applied in the last physics step (N, N m; world, at the
        ladle's centre of mass), shape (6,): what :attr:`push` held then (the loop resets
        :attr:`push` after each control period); zero without a perturbation. Drawn by
        :class:`tli_verify.sim.render.Recorder`; the robot does not read it."""
        return np.array(self.data.xfrc_applied[self._carrier], dtype=np.float64)

    @property
    def stopped(self) -> str | None:
        """The reflex that stopped the robot, if one did."""
        return self.guard.stopped

    def read(self) -> Reading:
        """The sensors now."""
        return self.sensors.read(self.data)

    follow = MocapRig.follow
