"""Kinesthetic teaching in the scene: a scripted teacher guides the Panda, its sensors record.

The paper's robot learned the scoop from "two demonstration trajectories ... provided to the
robot via kinesthetic teaching" (appendix, Robot Experiment 1). This module records the Franka
project's demonstrations the same way, in the scene the policy runs in:

The arm
    In guiding mode: gravity and Coriolis compensated and damped, within the Franka's limits --
    the passive-DS law of :mod:`tli_verify.sim.passive` with a zero velocity field and no
    orientation servo (damping ``lambda2`` in every direction and ``d_rot`` about every axis):
    the teacher turns the tool about any axis, as on a guided Franka with no axis locked.

The teacher
    A person's hand on the arm's grip *above* the wrist force/torque sensor (its wrench acts on
    the hand body, so the F/T weighs the ladle and what it carries, not the hand; a hand on the
    ladle itself would read as tens of newtons of load). The hand is a spring-damper
    (:class:`TeacherHand`) pulling the tray towards the scripted scoop
    (:func:`~tli_verify.sim.demos.scoop_waypoints`, jittered by the seed) with the script's
    velocity as feed-forward, and the ladle's full orientation towards the script's (the
    pitch it scripts, roll and yaw 0: a recovery take starting rolled or yawed is turned
    back by the teacher). The teacher watches the spoon (its eyes are the physics' bead count; they
    are never recorded): once a bead is on the tray mid-sweep it tips the tray back about the
    front edge, lifts it clear of the pile and the far wall and holds it still
    (:func:`react`), then carries and pours.

The record (every control period, :data:`~tli_verify.sim.demos.CONTROL_DT`)
    The tray's full pose ``(x, y, z, rx, ry, rz)`` (:mod:`tli_verify.sim.demos`) by the arm's
    forward kinematics -- *measured*, not the teacher's intent --
    and the readings of the robot's own sensors (:mod:`tli_verify.sim.franka_sensors`),
    debounced as the executive sees them (:class:`~tli_verify.sim.sensors.Debounce`). The
    segmentation (appendix C) therefore puts each mode's attractor where the robot's own
    sensors read the next mode: mode b's where the wrist has weighed soup, after the lift
    (the F/T cannot weigh the soup while the tray presses on the pile), c's where the
    kinematic pose reads the target. The hold after the lift puts b's attractor clear of
    every contact, so a DS that converges there is weighed too.

A take whose soup never reaches the target (the readings do not end at ``t``), that never
reads ``s``, or whose readings go back a mode on the way (soup lost), is discarded and the next
seed is tried (:func:`write_demos`), as a teacher would redo it.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import numpy.typing as npt

from tli_verify.defaults import Stream
from tli_verify.defaults import rng as default_rng
from tli_verify.demos import Demonstration, demo_to_csv
from tli_verify.errors import TliError
from tli_verify.io import atomic_write_text
from tli_verify.sim.demos import (
    CARRY_PITCH,
    CONTROL_DT,
    PandaRig,
    interpolate,
    scoop_waypoints,
    to_ds,
)
from tli_verify.sim.robot import BODY_HAND
from tli_verify.sim.scene import N_BEADS, reset_beads
from tli_verify.sim.sensors import SENSOR_NAMES, Debounce

__all__ = ["RECOVERY_BEADS", "RECOVERY_STARTS", "TeacherHand", "react", "record_demo",
           "write_demos"]

FloatArray = npt.NDArray[np.float64]

RECOVERY_STARTS = (
    (0.5, 0.10, 0.16, 0.35, -0.7, 0.0),
    (0.5, -0.02, 0.19, 0.0, -0.5, -0.35),
    (0.5, 0.06, 0.12, -0.35, -0.25, 0.3),
)
"""Start poses ``(x, y, z [m], rx, ry, rz [rad])`` of the recovery demonstrations: where a
spilling tilt leaves the ladle between the bowls, tipped back (``ry < 0``) and turned about
its front axis (``rx``) or its normal (``rz``): a person's tilt turns it about any
near-horizontal axis. None lies over the target bowl, where the robot's kinematic ``t`` reads
(a take starting there would begin in the target's reading)."""

RECOVERY_BEADS = (18, 15, 12)
"""Beads left in the soup bowl for each recovery demonstration: a bowl already scooped from,
whose pile has receded towards the far wall (so mode b's attractor lies deep enough to reach a
depleted pile too)."""

APPROACH = 2.0
"""Seconds (unrecorded) in which the teacher brings the arm from where it stands to the take's
start and holds it there."""


@dataclass(frozen=True, slots=True)
class TeacherHand:
    """The teacher's hand: a spring-damper from the script's pose to the tray.

    Attributes
    ----------
    stiffness : float
        Translational (N/m): a firm grip (a person's arm reaches about 300-2,000 N/m).
    damping : float
        Translational (Ns/m).
    rot_stiffness : float
        Rotational (Nm/rad), about every axis (the teacher holds the full orientation).
    rot_damping : float
        Rotational (Nms/rad).
    """

    stiffness: float = 1500.0
    damping: float = 80.0
    rot_stiffness: float = 30.0
    rot_damping: float = 1.5

    def __post_init__(self) -> None:
        for name in ("stiffness", "damping", "rot_stiffness", "rot_damping"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise TliError(f"teacher hand: {name} must be a finite number >= 0, "
                               f"got {value!r}")


class _Guide:
    """The teacher's wrench on the hand body of ``rig`` (above the wrist F/T), towards a
    scripted pose."""

    def __init__(self, rig: PandaRig, hand: TeacherHand) -> None:
        self.rig, self.hand = rig, hand
        m = rig.model
        self.body = int(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, BODY_HAND))
        self.site = rig.ids.tray_site
        self._jac = np.zeros((6, m.nv))
        self._qd, self._q, self._e = np.zeros(4), np.zeros(4), np.zeros(4)

    def apply(self, pose: FloatArray, velocity: FloatArray) -> None:
        """Set the hand's wrench for the next physics step: pulling the tray towards ``pose``
        ``(x, y, z, rx, ry, rz)`` with ``velocity`` (its rates: m/s, rad/s) as feed-forward."""
        rig, h = self.rig, self.hand
        d = rig.data
        p = d.site_xpos[self.site]
        mujoco.mj_jacSite(rig.model, d, self._jac[:3], self._jac[3:], self.site)
        twist = self._jac @ d.qvel
        force = h.stiffness * (pose[:3] - p) + h.damping * (velocity[:3] - twist[:3])
        dsmap = rig.controller.map
        dsmap.target_quat_into(float(pose[3]), float(pose[4]), float(pose[5]), self._qd)
        mujoco.mju_mat2Quat(self._q, d.site_xmat[self.site])
        mujoco.mju_negQuat(self._q, self._q)
        mujoco.mju_mulQuat(self._e, self._qd, self._q)
        rotvec = np.zeros(3)
        mujoco.mju_quat2Vel(rotvec, self._e if self._e[0] >= 0 else -self._e, 1.0)
        w_d = dsmap.twist_from_ds_velocity(velocity, pose)[3:]
        torque = h.rot_stiffness * rotvec + h.rot_damping * (w_d - twist[3:])
        # the force acts at the tray; the body held takes it at its centre of mass
        torque += np.cross(p - d.xipos[self.body], force)
        d.xfrc_applied[self.body, :3] = force
        d.xfrc_applied[self.body, 3:] = torque

    def release(self) -> None:
        """The teacher lets go."""
        self.rig.data.xfrc_applied[self.body] = 0.0


def react(waypoints: FloatArray, now: float, cmd: FloatArray, *, lift: float = 0.06,
          back: float = 0.03, hold: float = 0.8) -> FloatArray:
    """The teacher sees soup on the spoon mid-sweep: the rest of the script from ``now``.

    It sweeps on 0.3 s (the beads get fully on), tips the tray back about the front edge
    (``CARRY_PITCH``), lifts it by ``lift`` (m) while drawing it ``back`` (m) from the far
    wall, holds it still for ``hold`` (s), then goes on from the script's lift out of the bowl.

    Parameters
    ----------
    waypoints : ndarray, shape (K, 5)
        The script (:func:`~tli_verify.sim.demos.scoop_waypoints`).
    now : float
        Script time (s).
    cmd : ndarray, shape (6,)
        The script's pose at ``now``.

    Returns
    -------
    ndarray, shape (K', 7)
    """
    lift_row = 7  # the row of scoop_waypoints that lifts out of the bowl
    on = interpolate(waypoints, now + 0.3)
    x, y, z, rx, _, rz = on.tolist()
    head = np.array([
        (now, *cmd.tolist()),
        (now + 0.3, *on.tolist()),
        (now + 0.8, x, y, z + 0.016, rx, CARRY_PITCH, rz),
        (now + 1.4, x, y + back, z + lift, rx, CARRY_PITCH, rz),
        (now + 1.4 + hold, x, y + back, z + lift, rx, CARRY_PITCH, rz),
    ])
    tail = waypoints[lift_row:].copy()
    tail[:, 0] += now + 2.4 + hold - tail[0, 0]
    return np.vstack([head, tail])


def record_demo(seed: int, *, name: str = "", start: npt.ArrayLike | None = None,
                in_bowl: int = N_BEADS, hand: TeacherHand | None = None,
                sensors: str = "franka") -> Demonstration:
    """One kinesthetic demonstration on the Panda in the scene (module doc).

    Parameters
    ----------
    seed : int
        Beads, the script's jitter and the sensors' noise.
    name : str, optional
        Shown in messages (``Demonstration.path``).
    start : array_like, shape (6,), optional
        Start pose ``(x, y, z, rx, ry, rz)`` (default: the script's nominal start).
    in_bowl : int, optional
        Beads in the soup bowl (the rest lie out of the task).
    hand : TeacherHand, optional
    sensors : str, optional
        The robot's sensors that record (``"franka"``, default; ``"ideal"`` for comparison).

    Returns
    -------
    Demonstration
        ``x`` shape (T, 6): the measured tray pose as DS state
        (:func:`~tli_verify.sim.demos.to_ds`); sensors ``r, s, t``; velocities by finite
        differences.
    """
    waypoints = scoop_waypoints(default_rng(seed, Stream.SIM_DEMOS), jitter=0.02, start=start)
    rig = PandaRig(seed, controller="passive", sensors=sensors)
    rig.command_velocity(np.zeros(6), None)  # guiding mode: compensated and damped
    guide = _Guide(rig, TeacherHand() if hand is None else hand)
    every = round(CONTROL_DT / float(rig.model.opt.timestep))
    here, first = rig.pose(), waypoints[0, 1:]
    still = np.zeros(6)
    periods = round(APPROACH / CONTROL_DT)
    for k in range(periods):
        goal = here + (first - here) * min(1.0, (k + 1) / (0.6 * periods))
        for _ in range(every):
            guide.apply(goal, still)
            rig.step(1)
    if in_bowl != N_BEADS:  # a bowl already scooped from, settled with the arm held still

        def held() -> None:
            guide.apply(first, still)
            rig.step(1)

        reset_beads(rig.model, rig.data, rig.ids, seed=seed, step=held, in_bowl=in_bowl)
    debounce = Debounce()
    reading = debounce.update(rig.read())
    times, poses, readings = [0.0], [rig.pose()], [reading]
    sweep = (float(waypoints[2, 0]), float(waypoints[4, 0]))
    reacted = False
    k = 0
    while k * CONTROL_DT < float(waypoints[-1, 0]) - 1e-9:
        now = k * CONTROL_DT
        cmd = interpolate(waypoints, now)
        if not reacted and sweep[0] < now < sweep[1] and \
                bool(np.any(rig.sensors.on_ladle(rig.data))):
            waypoints = react(waypoints, now, cmd)  # soup on the spoon: tip back, lift, hold
            reacted = True
        nxt = interpolate(waypoints, now + CONTROL_DT)
        velocity = (nxt - cmd) / CONTROL_DT
        for j in range(every):
            guide.apply(cmd + (nxt - cmd) * ((j + 1) / every), velocity)
            rig.step(1)
        k += 1
        times.append(round(k * CONTROL_DT, 9))
        poses.append(rig.pose())
        readings.append(debounce.update(rig.read()))
    guide.release()
    t = np.array(times)
    x = to_ds(np.array(poses))
    flags = np.array([[r.r, r.s, r.t] for r in readings], dtype=bool)
    dx = np.gradient(x, t, axis=0, edge_order=2)
    return Demonstration(path=name or f"franka demo seed {seed}", t=t, x=x, dx=dx,
                         sensor_names=SENSOR_NAMES, sensors=flags)


def _delivered(demo: Demonstration) -> bool:
    """The take reads soup, ends at the target and never goes back a mode."""
    r, s, t = demo.sensors.T
    stage = np.where(t, 3, np.where(s, 2, np.where(r, 1, 0)))  # modes a b c d
    return bool(t[-1] and s.any() and not np.any(np.diff(stage) < 0))


def write_demos(directory: str | os.PathLike[str], count: int = 3, *, first_seed: int = 1,
                max_tries: int = 20,
                recovery: tuple[tuple[float, ...], ...] = RECOVERY_STARTS,
                recovery_beads: tuple[int, ...] = RECOVERY_BEADS) -> list[Path]:
    """Record ``count`` nominal takes and one recovery take per ``recovery`` start, as
    ``franka_<k>.csv`` (each written atomically).

    The recovery takes start where a spilling tilt leaves the ladle, in a bowl already scooped
    from (``recovery_beads``), and show the whole task from there: a DS learned only from the
    nominal start reached the soup tipped back and scooped nothing.

    Returns
    -------
    list of Path

    Raises
    ------
    TliError
        Fewer than ``count`` nominal takes, or no take from a recovery start, in
        ``max_tries`` seeds.
    """
    if len(recovery_beads) != len(recovery):
        raise TliError(f"franka demos: {len(recovery)} recovery starts but "
                       f"{len(recovery_beads)} bead counts")
    plan: list[tuple[tuple[float, ...] | None, int]] = \
        [(None, N_BEADS)] * count + list(zip(recovery, recovery_beads, strict=True))
    out: list[Path] = []
    seed = first_seed
    for start, beads in plan:
        path = Path(directory) / f"franka_{len(out) + 1}.csv"
        for _ in range(max_tries):
            demo = record_demo(seed, name=str(path), start=start, in_bowl=beads)
            seed += 1
            if _delivered(demo):
                break
        else:
            raise TliError(f"franka demos: no take {len(out) + 1} "
                           f"({'nominal' if start is None else f'from {start}'}) delivered "
                           f"soup in {max_tries} seeds")
        what = "nominal" if start is None else \
            f"recovery from {list(start)} with {beads} beads in the bowl"
        head = (f"# franka scoop demonstration {len(out) + 1}, {what} (tli_verify.sim.teacher: "
                f"kinesthetic teaching on the Panda, seed {seed - 1}, dt {CONTROL_DT} s); "
                "state = measured tray pose (x, y, z in dm; rx, ry, rz in rad: the rotation vector "
                "in the chart at the ladle's pitch-0 orientation); r, s, t = the "
                "robot's sensors (franka)\n")
        atomic_write_text(path, head + demo_to_csv(demo, velocities=False))
        out.append(path)
    return out
