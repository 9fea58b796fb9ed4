"""The closed loop in MuJoCo: LTL-DS drives the ladle through physical scooping (paper Sec. 7.2).

Per control period (``CONTROL_DT`` = 20 ms, the certified period):

1. sensors (by default the Franka-like ones of :mod:`tli_verify.sim.franka_sensors`: the wrist
   F/T load and the noisy kinematic pose; ``sensors="ideal"``: the simulator's
   :class:`~tli_verify.sim.sensors.ScoopSensors`), debounced as the executive sees them
   (:class:`~tli_verify.sim.sensors.Debounce`), the measured DS state ``z`` from the tray pose
   (:func:`~tli_verify.sim.demos.to_ds`), and ``perturbed`` from the robot's own estimate of
   the external wrench (:class:`~tli_verify.sim.contact.ContactDetector`: 25 N or 2.5 N m, held
   1.5 s) -- never from the simulator's list of perturbations;
2. ``v = LTLDSPolicy.step(z, reading, perturbed)`` -- at the *measured* state ``z`` (the
   default, ``controller="measured"``, and the passive-DS law); under target tracking at the
   target ``z*``: the
   automaton picks the mode, the mode's certified, modulated DS gives the velocity (cuts are
   learned online on invariance failures); with the stall rule on (``retry``,
   :mod:`tli_verify.runtime.stall`) the executive's assumption monitor reports a converged or
   blocked DS without the next mode's reading and re-enters the mode from its predecessor;
3. the velocity is capped per axis at ``SPEED_CAP``; *measured* (``controller="measured"``,
   the default; the paper's robot: "the target velocity predicted by the DS was integrated to
   generate the target pose, which was then tracked by a Cartesian pose impedance
   controller. The robot state was provided by the control interface", appendix, Robot
   Experiment 1): it is integrated to a target pose ``z* <- z* + dt v``, the target kept on a
   leash of the measured state (``LEASH``: held back by the pile or a hand, the arm presses with
   at most stiffness x leash) and inside the workspace -- the DS and its cuts act on the
   robot's own state, the target only carries the impedance law's force; *passive*
   (``controller="passive"``,
   :mod:`tli_verify.sim.passive`): without the components leaving the workspace
   (:func:`~tli_verify.sim.target.workspace`) where the robot is at its bound, it is the
   velocity field the passive law tracks by damping until the next period (the orientation
   servo's pitch integrated on a leash of the measured pitch); *tracking*
   (``controller="tracking"``, for comparison): the DS runs on the target ``z*`` itself, which
   is integrated and leashed as under *measured* (the arm lags it by 4-5 cm, so a cut bounds
   the target, not the robot);
4. the rig runs 10 physics steps of 2 ms, torques every step within the Franka's torque,
   torque-rate and joint-velocity limits (:mod:`tli_verify.sim.franka_limits`): the passive-DS
   law, or the Panda's Cartesian impedance controller (2,000 N/m, 50 Nm/rad, the target ramped
   within the period with the DS velocity as feed-forward), or the free tool's impedance law
   (:class:`~tli_verify.sim.demos.MocapRig`). A reflex stop ends the trial as failed.

Per trial the result records the controller, the sensors, the stall rule's firings
(``stalls``), the measured pose against the running mode's cuts (:class:`CutGap`) and the
passive law's lowest tank level.

Perturbations (the environment's side; :mod:`tli_verify.sim.perturbations`, drawn uniformly
from the trial's seed): a person's hand grabs the ladle and drags it 10-30 cm (a push) or turns
it 0.6-1.2 rad (a tilt, a delay after the soup is carried out of the soup bowl), its wrench
recomputed every physics step.

A trial succeeds when at least one bead ends in the target bowl and the robot did not stop. It
ends when the goal mode has poured for 2.5 s and the spoon is empty, or at its step budget
(:data:`~tli_verify.sim.TRIAL_DURATION`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import InputError
from tli_verify.runtime.events import CutAdded, Stall
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.stall import StallRule
from tli_verify.sim import TRIAL_DURATION
from tli_verify.sim.contact import ContactDetector
from tli_verify.sim.demos import (
    CONTROL_DT,
    CONTROLLERS,
    MocapRig,
    PandaRig,
    from_ds,
    from_ds_velocity,
    model_columns,
    to_ds,
)
from tli_verify.sim.franka_project import load_policy
from tli_verify.sim.franka_sensors import SENSOR_KINDS
from tli_verify.sim.perturbations import PersonHand, Perturbation, draw, step_with_hands
from tli_verify.sim.scene import DEFAULT_PHYSICS, PhysicsOptions
from tli_verify.sim.sensors import Debounce
from tli_verify.sim.target import (
    LEASH,
    MARGIN,
    SPEED_CAP,
    clip_floats,
    feed_forward_floats,
    inside_cuts,
    workspace,
)

__all__ = [
    "GOAL_GAP",
    "ROBOTS",
    "TraceStep",
    "TrialResult",
    "draw_perturbations",
    "make_rig",
    "run_trial",
    "run_trials",
]

FloatArray = npt.NDArray[np.float64]
ROBOTS = ("panda", "free-tool")
"""The rigs: the Panda (default) and the free tool (the ladle on a free body, no arm)."""
GOAL_GAP = 1.0
"""Seconds out of the goal mode after which the pour's 2.5 s count restarts."""


def draw_perturbations(seed: int, *, pushes: int = 1, tilts: int = 1) -> list[Perturbation]:
    """Seeded perturbations of one trial, drawn by the campaign strategies.

    :func:`tli_verify.sim.perturbations.draw`, uniform in the bounds (pushes of 0.10-0.30 m in
    a direction within 30 degrees of the horizontal over 0.5-3 s, starting at 0.5-6 s; tilts of
    0.6-1.2 rad about an axis within 30 degrees of the horizontal over 0.5-1.5 s, 0-1.5 s after
    the soup is carried out of the bowl), deterministic in ``seed`` in any process.

    Parameters
    ----------
    seed : int
    pushes, tilts : int, optional

    Returns
    -------
    list of Perturbation
    """
    return draw(seed, pushes=pushes, tilts=tilts)


@dataclass(frozen=True, slots=True, eq=False)
class TrialResult:
    """One perturbed trial in the simulator.

    Attributes
    ----------
    seed : int
    variant : str
    success : bool
        At least one bead ended in the target bowl.
    delivered : int
        Beads in the target bowl at the end.
    modes : tuple of str
        The mode run at each control step.
    cuts_added : int
    sim_time : float
        Simulated seconds.
    wall_time : float
        Seconds of computation.
    perturbations : tuple of Perturbation
    applied : tuple of float
        When each perturbation was applied (simulated seconds; NaN: never, e.g. a tilt in a
        trial where the soup never got on the spoon).
    events : tuple of str
        The executive's events, one line each.
    retries : int
        The stall rule's re-entries (the same as ``stalls``; the record's old name).
    robot : str
        The rig (:data:`ROBOTS`).
    retry : bool
        Whether the stall rule was on (:mod:`tli_verify.runtime.stall`).
    stopped : str or None
        The reflex stop that ended the trial (a failed trial), if one did.
    limit_ratios : dict of str to float
        Largest ratio to each of the Franka's limits
        (:meth:`~tli_verify.sim.franka_limits.LimitGuard.ratios`; empty for the free tool).
    perturbed_steps : int
        Control periods in which the robot counted itself perturbed
        (:class:`~tli_verify.sim.contact.ContactDetector`).
    controller : str
        The control law (:data:`~tli_verify.sim.demos.CONTROLLERS`).
    sensors : str
        The sensor model (:data:`~tli_verify.sim.franka_sensors.SENSOR_KINDS`).
    cut_gap : dict of str to float or None
        The measured pose against the cut set of the mode being run (:class:`CutGap`).
    tank_low : float or None
        The passive-DS law's lowest energy-tank level (J; None under target tracking).
    stalls : int
        Stalls the assumption monitor reported (the stall rule fired:
        :mod:`tli_verify.runtime.stall`).
    start : tuple of float or None
        The tray pose ``(x, y, z [m], rx, ry, rz [rad])`` the trial started from, when it was
        not the demonstrations' start (``run_trial(start=...)``).
    """

    seed: int
    variant: str
    success: bool
    delivered: int
    modes: tuple[str, ...]
    cuts_added: int
    sim_time: float
    wall_time: float
    perturbations: tuple[Perturbation, ...]
    applied: tuple[float, ...]
    events: tuple[str, ...] = field(default=())
    retries: int = 0
    robot: str = "panda"
    retry: bool = True
    stopped: str | None = None
    limit_ratios: dict[str, float] = field(default_factory=dict)
    perturbed_steps: int = 0
    controller: str = "tracking"
    sensors: str = "ideal"
    cut_gap: dict[str, float | None] = field(default_factory=dict)
    tank_low: float | None = None
    stalls: int = 0
    start: tuple[float, ...] | None = None

    def mode_sequence(self) -> str:
        """The mode trace as runs: ``"a b c b c d"``."""
        runs = [m for i, m in enumerate(self.modes) if i == 0 or m != self.modes[i - 1]]
        return " ".join(runs)

    def to_dict(self) -> dict[str, Any]:
        """The per-trial JSON record of ``tli sim franka --json``."""
        return {
            "seed": self.seed, "variant": self.variant, "success": self.success,
            "delivered": self.delivered, "mode_sequence": self.mode_sequence(),
            "mode_trace": "".join(self.modes), "cuts_added": self.cuts_added,
            "sim_time": round(self.sim_time, 3), "wall_time": round(self.wall_time, 3),
            "perturbations": [dict(p.to_dict(), applied_at=None if math.isnan(a) else
                                   round(a, 3))
                              for p, a in zip(self.perturbations, self.applied, strict=True)],
            "events": list(self.events), "retries": self.retries, "robot": self.robot,
            "retry": self.retry, "stopped": self.stopped,
            "limit_ratios": dict(self.limit_ratios), "perturbed_steps": self.perturbed_steps,
            "controller": self.controller, "sensors": self.sensors,
            "cut_gap": dict(self.cut_gap), "tank_low": self.tank_low, "stalls": self.stalls,
            "stall_fired": self.stalls > 0,
        } | ({} if self.start is None else {"start": list(self.start)})


@dataclass(frozen=True, slots=True)
class TraceStep:
    """One control period of a trial as the robot saw it (``run_trial(trace=...)``).

    Attributes
    ----------
    time : float
        Seconds since the trial's start, at the period's start.
    mode : str
        The mode the executive ran in this period (after its decision).
    target : ndarray, shape (n,)
        The DS state ``z*`` the executive was given (the target pose, DS units: dm, rad).
    measured : ndarray, shape (n,)
        The measured DS state ``z`` (:func:`~tli_verify.sim.demos.to_ds` of the tray pose).
    perturbed : bool
        The robot's own estimate (:class:`~tli_verify.sim.contact.ContactDetector`).
    """

    time: float
    mode: str
    target: FloatArray
    measured: FloatArray
    perturbed: bool


def run_trial(policy: LTLDSPolicy, seed: int, *, variant: str = "LTL-DS",
              perturbations: list[Perturbation] | None = None, duration: float = TRIAL_DURATION,
              settle: float = 1.0, frame: Callable[[Any], None] | None = None,
              robot: str = "panda", retry: bool = True,
              detector: ContactDetector | None = None, sensors: str = "franka",
              physics: PhysicsOptions | None = None,
              trace: list[TraceStep] | None = None,
              margin: npt.ArrayLike = MARGIN, controller: str | None = None,
              start: npt.ArrayLike | None = None) -> TrialResult:
    """One closed-loop trial (module doc).

    Parameters
    ----------
    policy : LTLDSPolicy
        Cuts learned in earlier trials carry over (as on the robot).
    seed : int
        Bead placement; the perturbations are drawn with it unless given.
    variant : str, optional
        Recorded in the result.
    perturbations : list of Perturbation, optional
        Default :func:`draw_perturbations` ``(seed)``; ``[]`` for none.
    duration : float, optional
        Step budget (simulated seconds).
    settle : float, optional
        Seconds simulated after the goal mode's pour, before counting the beads.
    frame : callable, optional
        Called with the rig every control step (video frames).
    robot : str, optional
        ``"panda"`` (default: :class:`~tli_verify.sim.demos.PandaRig`, the arm under the
        Cartesian impedance controller within the Franka's limits) or ``"free-tool"``
        (:class:`~tli_verify.sim.demos.MocapRig`, the ladle on a free body under an impedance
        law: the rig the demonstrations were recorded with).
    retry : bool, optional
        The stall rule (:class:`~tli_verify.runtime.stall.StallRule`, the executive's
        documented answer to a converged or blocked DS without the next reading);
        ``False``: ``--no-stall-rule``.
    detector : ContactDetector, optional
        How ``perturbed`` is estimated (default
        :class:`~tli_verify.sim.contact.ContactDetector` ``()``).
    sensors : str, optional
        ``"ideal"`` (noise-free, privileged) or ``"franka"`` (the wrist F/T load and the noisy
        kinematic pose: :mod:`tli_verify.sim.franka_sensors`).
    physics : PhysicsOptions, optional
        The scene's solver settings (default: the measured ones,
        :class:`~tli_verify.sim.scene.PhysicsOptions`).
    trace : list, optional
        Appended with one :class:`TraceStep` per control period (what the robot saw and
        commanded: the Fig. 9-style pictures of :mod:`tli_verify.sim.scenario`).
    margin : array_like, shape (6,), optional
        How far the target may leave the demonstrations' box, per pose coordinate
        (:func:`~tli_verify.sim.target.workspace`; default :data:`~tli_verify.sim.target.MARGIN`).
    controller : str, optional
        ``"measured"`` (default: the DS at the measured pose, integrated to the impedance
        law's target), ``"passive"`` (the Panda only: the DS at the measured pose tracked by
        the passive-DS law, :mod:`tli_verify.sim.passive`) or ``"tracking"`` (the DS run on
        its integrated target, for comparison).
    start : array_like, shape (6,), optional
        The tray pose ``(x, y, z [m], rx, ry, rz [rad])`` to start from (default: the
        demonstrations' start): before the trial the arm moves there while the beads settle.

    Returns
    -------
    TrialResult
    """
    t0 = time.perf_counter()
    control = default_controller(robot) if controller is None else controller
    perts = draw_perturbations(seed) if perturbations is None else list(perturbations)
    rig: Any = make_rig(robot, seed, sensors=sensors, physics=physics, controller=control,
                        start=start)
    passive = control == "passive"
    measured = control == "measured"  # the DS at the measured pose, integrated to a target
    cut_gap = CutGap()
    substeps = round(CONTROL_DT / float(rig.model.opt.timestep))
    debounce = Debounce()
    reading = debounce.update(rig.read())
    # the DS's coordinates of the pose (x, y, z, rx, ry, rz): all six, or a 4-D DS's
    # (x, y, z, pitch), roll and yaw held at 0 (demos.model_columns)
    cols = list(model_columns(policy.model.dim))
    lift = _lifter(cols)
    ref = to_ds(rig.pose())[cols]
    lo, hi = workspace(margin)
    lo_l, hi_l = lo[cols].tolist(), hi[cols].tolist()
    servo = ref.copy()  # the passive law's orientation servo (its rotation columns)
    leash, cap = LEASH[cols].tolist(), SPEED_CAP[cols].tolist()
    policy.reset(ref, reading.to_dict())
    policy.stall_rule = StallRule() if retry else None  # the stall rule (runtime.stall)
    detect = ContactDetector() if detector is None else detector
    detect.reset()
    modes = [policy.mode]
    applied = [math.nan] * len(perts)
    hands: list[PersonHand | None] = [None] * len(perts)
    soup_at: float | None = None
    n = round(duration / CONTROL_DT)
    goal_for = away = 0
    done_steps = round(2.5 / CONTROL_DT)  # pour for 2.5 s in the goal mode, until empty
    t = 0.0
    perturbed_steps = 0
    stopped: str | None = None
    for _ in range(n):
        if reading.s and not reading.r and soup_at is None:
            soup_at = t  # the soup is carried out of the bowl: tilts count from here
        # the environment (the oracle's side): the person's wrench on the hand
        for i, p in enumerate(perts):
            grab = p.start if p.kind == "push" else (
                p.start + soup_at if soup_at is not None else math.inf)
            if hands[i] is None and grab < t + CONTROL_DT and t < grab + p.duration:
                hands[i] = PersonHand(p, start=grab)  # it grabs in this control period
        # the robot's side: what it measures
        z = to_ds(rig.pose())[cols]
        perturbed = detect.update(rig.external_wrench(), CONTROL_DT)
        perturbed_steps += perturbed
        # the target stays on a leash of the measured state: held back (a push, the pile),
        # the arm pulls with a bounded force, in every axis, towards where the DS leads
        # (n-vectors on floats: numpy's elementwise roundings and clip rule, less overhead)
        zl = z.tolist()
        if passive:  # the DS at the measured state: no target
            ref = z
        else:
            ref = np.array(clip_floats(ref.tolist(),
                                 [a - b for a, b in zip(zl, leash, strict=True)],
                                 [a + b for a, b in zip(zl, leash, strict=True)]))
        v = policy.step(z if measured else ref, reading.to_dict(), perturbed=perturbed)
        cuts = policy.model.region_cuts(policy.mode)  # the running mode's, after its step
        cut_gap.update(cuts, z)
        if trace is not None:
            trace.append(TraceStep(t, policy.mode, ref.copy(), z, perturbed))
        vl = np.asarray(v, dtype=np.float64).tolist()
        speed = max([abs(a) / c for a, c in zip(vl, cap, strict=True)])
        if speed > 1.0:
            vl = [a / speed for a in vl]
        if passive:  # no velocity out of the workspace where the robot is at or beyond it
            vl = feed_forward_floats(zl, vl, lo_l, hi_l)
            # the orientation servo: integrated from the DS's rotation rates, on a leash of
            # the measured orientation (the position has no target: passive-DS)
            servo = np.array(clip_floats(
                [r + CONTROL_DT * a for r, a in zip(servo.tolist(), vl, strict=True)],
                [a - b for a, b in zip(zl, leash, strict=True)],
                [a + b for a, b in zip(zl, leash, strict=True)]))
            rig.command_velocity(from_ds_velocity(lift(vl)), lift(servo.tolist())[3:])
        else:
            refl = clip_floats([r + CONTROL_DT * a for r, a in zip(ref.tolist(), vl, strict=True)],
                         lo_l, hi_l)
            ref = np.array(refl)
            if measured and cuts:  # the target, too, inside the running mode's cut set
                ref = inside_cuts(ref, cuts, z)
                refl = ref.tolist()
            rig.command(from_ds(lift(refl)),
                        from_ds_velocity(lift(feed_forward_floats(refl, vl, lo_l, hi_l))))
        step_with_hands(rig, substeps, t, hands, applied)
        t += CONTROL_DT
        if frame is not None:
            frame(rig)
        reading = debounce.update(rig.read())
        modes.append(policy.mode)
        if rig.stopped is not None:  # the robot's reflex: the trial fails here
            stopped = f"reflex stop at {t:.2f} s: {rig.stopped}"
            break
        # in the goal mode for 2.5 s (a blink of t while the beads fall out does not restart
        # the count; leaving the goal mode for more than GOAL_GAP does), spoon empty: poured
        if policy.done:
            goal_for, away = goal_for + 1, 0
        else:
            away += 1
            if away > round(GOAL_GAP / CONTROL_DT):
                goal_for = 0
        if goal_for >= done_steps and not reading.s:  # poured: nothing left on the spoon
            break
    rig.push[:] = 0.0
    if passive:
        rig.command_velocity(np.zeros(6))  # the settle: the arm held by damping alone
    if stopped is None:
        for _ in range(round(settle / CONTROL_DT)):
            rig.step(substeps)
            t += CONTROL_DT
            if frame is not None:
                frame(rig)
    delivered = int(rig.sensors.in_target(rig.data).sum())
    events = tuple(f"{type(e).__name__} at step {getattr(e, 'step', '?')}"
                   for e in policy.events)
    ratios = rig.guard.ratios() if hasattr(rig, "guard") else {}
    stalls = sum(isinstance(e, Stall) for e in policy.events)
    return TrialResult(
        seed=seed, variant=variant, success=delivered >= 1 and stopped is None,
        delivered=delivered, modes=tuple(modes),
        cuts_added=sum(isinstance(e, CutAdded) for e in policy.events),
        sim_time=t, wall_time=time.perf_counter() - t0, perturbations=tuple(perts),
        applied=tuple(applied), events=events,
        retries=stalls, robot=robot, retry=retry, stalls=stalls,
        stopped=stopped, limit_ratios={k: round(v, 4) for k, v in ratios.items()},
        perturbed_steps=perturbed_steps, controller=control,
        sensors=sensors, cut_gap=cut_gap.to_dict(),
        tank_low=round(rig.passive.tank_low, 4) if passive else None,
        start=None if start is None else tuple(float(v) for v in np.ravel(start)))


def _lifter(cols: list[int]) -> Callable[[list[float]], FloatArray]:
    """The map from a DS's coordinates (the pose's columns ``cols``) to the 6-D pose: the
    columns a 4-D DS does not have (roll and yaw) held at 0."""
    if len(cols) == 6:
        return lambda values: np.array(values)

    def lift(values: list[float]) -> FloatArray:
        out = np.zeros(6)
        out[cols] = values
        return out

    return lift


def default_controller(robot: str) -> str:
    """The control law a rig runs by default: ``"measured"`` (the paper's: the DS at the
    measured pose, integrated to the impedance law's target) on either rig."""
    del robot  # the same on both: the free tool has every law but the passive one
    return "measured"


def make_rig(robot: str, seed: int, *, sensors: str = "ideal",
             physics: PhysicsOptions | None = None, controller: str | None = None,
             start: npt.ArrayLike | None = None) -> Any:
    """The rig of ``robot`` (:data:`ROBOTS`) with the beads of ``seed``, ``sensors``, the
    solver settings ``physics`` (default: the measured ones), the control law
    ``controller`` (:data:`CONTROLLERS`; default :func:`default_controller`) and the tray at
    ``start`` (a pose ``(x, y, z, rx, ry, rz)``; default the demonstrations' start).

    Raises
    ------
    InputError
        An unknown robot (``"hand"``, the free tool's old name, says so), or the passive law
        on the free tool.
    """
    if robot == "hand":
        raise InputError("robot 'hand' is now called 'free-tool' (the ladle on a free body, no "
                         "arm); the default is the Panda ('panda')")
    if robot not in ROBOTS:
        raise InputError(f"robot {robot!r}: one of {', '.join(ROBOTS)}")
    if sensors not in SENSOR_KINDS:
        raise InputError(f"sensors {sensors!r}: one of {', '.join(SENSOR_KINDS)}")
    control = default_controller(robot) if controller is None else controller
    if control not in CONTROLLERS:
        raise InputError(f"controller {control!r}: one of {', '.join(CONTROLLERS)}")
    if robot == "free-tool" and control == "passive":
        raise InputError("controller 'passive' runs on the Panda only; the free tool tracks a "
                         "target (--controller measured or tracking)")
    options = DEFAULT_PHYSICS if physics is None else physics
    if start is not None:
        pose = np.asarray(start, dtype=np.float64)
        if pose.shape != (6,) or not bool(np.all(np.isfinite(pose))):
            raise InputError(f"start: expected the tray pose (x, y, z [m], rx, ry, rz [rad]), "
                             f"got {start!r}")
    return PandaRig(seed, sensors=sensors, physics=options, controller=control, start=start) \
        if robot == "panda" else MocapRig(seed, sensors=sensors, physics=options, start=start)


class CutGap:
    """The measured pose against the cuts of the mode being run, per control period.

    For the cuts ``{x : n . (x - p) <= 0}`` of the running mode's region (the model's after the
    executive's step), the signed distance of the measured DS state ``z`` to the nearest plane
    (DS units: dm and rad mixed, as the cuts are; positive inside).

    Attributes (of :meth:`to_dict`)
    -------------------------------
    min_margin : the smallest such distance over the trial (NaN-free: ``inf`` without cuts);
    outside_steps : control periods in which ``z`` was outside a cut's half-space;
    max_outside : the farthest it was outside (0 when never).
    """

    __slots__ = ("max_outside", "min_margin", "outside_steps", "steps")

    def __init__(self) -> None:
        self.min_margin = math.inf
        self.max_outside = 0.0
        self.outside_steps = 0
        self.steps = 0

    def update(self, cuts: Any, z: FloatArray) -> None:
        """One period: the running mode's cuts and the measured state (shape (n,))."""
        if not cuts:
            return
        self.steps += 1
        d = min(-float(np.dot(c.normal, z - c.point)) for c in cuts)
        self.min_margin = min(self.min_margin, d)
        if d < 0.0:
            self.outside_steps += 1
            self.max_outside = max(self.max_outside, -d)

    def to_dict(self) -> dict[str, float | None]:
        """The trial record's ``cut_gap``."""
        return {"steps_with_cuts": self.steps,
                "min_margin": None if math.isinf(self.min_margin) else round(self.min_margin, 4),
                "outside_steps": self.outside_steps, "max_outside": round(self.max_outside, 4)}


def run_trials(seeds: list[int], variant: str = "LTL-DS", *, perturb: bool = True,
               duration: float = TRIAL_DURATION, robot: str = "panda",
               retry: bool = True, sensors: str = "franka",
               physics: PhysicsOptions | None = None, controller: str | None = None
               ) -> list[dict[str, Any]]:
    """Trials with one executive (cuts carry over), as JSON records; for worker processes.

    Parameters
    ----------
    seeds : list of int
    variant : str, optional
    perturb : bool, optional
    duration : float, optional
    robot : str, optional
    retry : bool, optional
    sensors : str, optional
    physics : PhysicsOptions, optional

    Returns
    -------
    list of dict
        :meth:`TrialResult.to_dict` per seed.
    """
    policy = load_policy(variant)
    return [run_trial(policy, s, variant=variant, perturbations=None if perturb else [],
                      duration=duration, robot=robot, retry=retry, sensors=sensors,
                      physics=physics, controller=controller).to_dict()
            for s in seeds]


