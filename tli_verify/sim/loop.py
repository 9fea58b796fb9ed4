"""The closed loop in MuJoCo: LTL-DS drives the ladle through physical scooping (paper Sec. 7.2).

Per control period (``CONTROL_DT`` = 20 ms, the certified period):

1. sensors (:class:`~tli_verify.sim.sensors.ScoopSensors`, or the Franka-like ones of
   :mod:`tli_verify.sim.franka_sensors`), debounced as the executive sees them
   (:class:`~tli_verify.sim.sensors.Debounce`), the DS state ``z`` from the tray pose
   (:func:`~tli_verify.sim.demos.to_ds`), and ``perturbed`` from the robot's own estimate of
   the external wrench (:class:`ContactDetector`: 25 N or 2.5 N m, held 1.5 s) -- never from
   the simulator's list of perturbations;
2. ``v = LTLDSPolicy.step(z*, reading, perturbed)``: the automaton picks the mode, the mode's
   certified, modulated DS gives the velocity (cuts are learned online on invariance
   failures); with the stall retry on (``retry``, :class:`~tli_verify.sim.retry.StallRetry`:
   the ladle stayed put 1.5 s outside the goal mode) the certified DS leading into the mode
   takes over until its attractor, counted in the result, the executive still judged;
3. the velocity (capped per axis at ``SPEED_CAP``) is integrated to a target pose,
   ``z* <- z* + dt v``, kept on a leash of the measured state (``LEASH``: held back by a push
   or the pile, the arm pulls with a bounded force in every axis -- the wedge deadlock of a
   target that restarted at the measured state is gone) and inside the workspace
   (:func:`workspace`);
4. the rig tracks it for 10 physics steps of 2 ms: the Panda's Cartesian impedance controller
   (:class:`~tli_verify.sim.demos.PandaRig`, the default: 2,000 N/m, 50 Nm/rad, the target
   ramped within the period with the DS velocity as feed-forward -- none into a workspace bound
   the target rests at -- the Franka's torque,
   torque-rate and joint-velocity limits enforced, :mod:`tli_verify.sim.franka_limits`) or the
   free tool's impedance law (:class:`~tli_verify.sim.demos.MocapRig`). A reflex stop ends the
   trial as failed.

Perturbations (the environment's side; :mod:`tli_verify.sim.perturbations`, drawn uniformly
from the trial's seed): a person's hand grabs the ladle and drags it 10-30 cm (a push) or turns
it 0.6-1.2 rad (a tilt, a delay after the soup is carried out of the soup bowl), its wrench
recomputed every physics step.

A trial succeeds when at least one bead ends in the target bowl and the robot did not stop. It
ends when the goal mode has poured for 2.5 s and the spoon is empty, or at its step budget
(:data:`~tli_verify.sim.TRIAL_DURATION`).
"""

from __future__ import annotations

import functools
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.demos import load_demos
from tli_verify.errors import CertificateError, InputError, TliError
from tli_verify.io import atomic_write_bytes, bundled_dir
from tli_verify.runtime.events import CutAdded
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.setup import VARIANTS as RUNTIME_VARIANTS
from tli_verify.runtime.setup import load_setup, make_policy
from tli_verify.sim import TRIAL_DURATION
from tli_verify.sim.demos import (
    CONTROL_DT,
    MocapRig,
    PandaRig,
    from_ds,
    from_ds_velocity,
    to_ds,
)
from tli_verify.sim.franka_sensors import SENSOR_KINDS
from tli_verify.sim.perturbations import PersonHand, Perturbation, draw
from tli_verify.sim.render import Recorder
from tli_verify.sim.retry import StallRetry
from tli_verify.sim.scene import DEFAULT_PHYSICS, PhysicsOptions
from tli_verify.sim.sensors import Debounce
from tli_verify.tasks.project import resolve

__all__ = [
    "VARIANTS",
    "ContactDetector",
    "Perturbation",
    "Recorder",
    "TraceStep",
    "TrialResult",
    "draw_perturbations",
    "feed_forward",
    "load_policy",
    "make_rig",
    "plot_flow",
    "run_trial",
    "run_trials",
]

FloatArray = npt.NDArray[np.float64]
VARIANTS = tuple(v for v in RUNTIME_VARIANTS if v != "BC")
"""The runtime's variants (:data:`tli_verify.runtime.setup.VARIANTS`) the robot runs: all but
``BC``, whose per-mode networks are trained on the kinematic tasks only (the Franka project
has no BC model to load)."""
ROBOTS = ("panda", "free-tool")
"""The rigs: the Panda (default) and the free tool (the ladle on a free body, no arm)."""
NOTIFY_AFTER = 1.5
"""Seconds after the estimated external wrench falls below the thresholds during which the
executive is still told "perturbed" (:class:`ContactDetector`)."""
DETECT_FORCE = 25.0
"""External force (N) beyond which the robot counts itself perturbed."""
DETECT_TORQUE = 2.5
"""External torque (N m) beyond which the robot counts itself perturbed."""
LEASH = np.array([0.3, 0.3, 0.3, 0.15])
"""Per-axis distance (dm, dm, dm, rad) the target may lead the measured DS state: held back,
the arm pulls with at most stiffness x leash (60 N and 7.5 N m on the Panda at 2,000 N/m and
50 Nm/rad: within the wrist's 12 N m)."""
GOAL_GAP = 1.0
"""Seconds out of the goal mode after which the pour's 2.5 s count restarts."""
SPEED_CAP = np.array([2.0, 2.0, 2.0, 2.0])
"""Per-axis speed limit of the DS velocity (dm/s, rad/s), direction kept."""
MARGIN = np.array([0.5, 0.5, 0.5, 0.3])
"""How far (dm, dm, dm, rad) the target may leave the demonstrations' bounding box: the
workspace limits of the hand (the DS extrapolates poorly far from its data: after a spilling
tilt it turned the ladle over and drifted 1.5 dm sideways)."""


def project_dir() -> Path:
    """The bundled Franka project: ``sim/franka`` with ``specs/``, ``models/``,
    ``certificates/`` and ``demos/franka/`` (outside the repository's deployed ``models/``:
    the gate requires campaign evidence this policy does not have yet, ``docs/howto/franka.md``)."""
    return bundled_dir("sim") / "franka"


def bundled_demos() -> list[Any]:
    """The recorded Franka demonstrations (:func:`project_dir` ``/demos/franka``)."""
    return load_demos(sorted((project_dir() / "demos" / "franka").glob("*.csv")))


def workspace(margin: npt.ArrayLike = MARGIN) -> tuple[FloatArray, FloatArray]:
    """Bounds of the target pose: the bundled demonstrations' box widened by ``margin``.

    Parameters
    ----------
    margin : array_like, shape (4,), optional
        Per axis (dm, dm, dm, rad), >= 0; default :data:`MARGIN`.

    Returns
    -------
    lo, hi : ndarray, shape (4,)
    """
    m = np.asarray(margin, dtype=np.float64)
    if m.shape != (4,) or not bool(np.all(np.isfinite(m) & (m >= 0))):
        raise TliError(f"workspace margin must be 4 finite numbers >= 0, got {margin!r}")
    box_lo, box_hi = _demo_box()
    return box_lo - m, box_hi + m


@functools.lru_cache(maxsize=1)
def _demo_box() -> tuple[FloatArray, FloatArray]:
    """The bundled demonstrations' bounding box (read once per process: every trial needs it)."""
    x = np.vstack([d.x for d in bundled_demos()])
    lo, hi = x.min(axis=0), x.max(axis=0)
    lo.setflags(write=False)
    hi.setflags(write=False)
    return lo, hi


def feed_forward(target: FloatArray, v: FloatArray, lo: FloatArray,
                 hi: FloatArray) -> FloatArray:
    """The velocity fed forward to the arm with the new target: the DS's ``v`` without the
    components that push into a workspace bound the target rests at.

    The arm is not driven on past a target the workspace holds at rest (fed the DS's velocity
    there, the tray went 1.7 cm beyond a target at the workspace's edge, across the target
    bowl's rim, and the pour left its mode on the loop's account, not the DS's).

    Parameters
    ----------
    target : ndarray, shape (4,)
        The new target, already clipped to ``[lo, hi]``.
    v : ndarray, shape (4,)
        The DS velocity it was integrated with (dm/s, rad/s).
    lo, hi : ndarray, shape (4,)
        The workspace (:func:`workspace`).

    Returns
    -------
    ndarray, shape (4,)
    """
    return np.array(_feed_forward(np.asarray(target, dtype=np.float64).tolist(),
                                  np.asarray(v, dtype=np.float64).tolist(),
                                  np.asarray(lo, dtype=np.float64).tolist(),
                                  np.asarray(hi, dtype=np.float64).tolist()))


def _feed_forward(target: list[float], v: list[float], lo: list[float],
                  hi: list[float]) -> list[float]:
    """:func:`feed_forward` on lists of floats (the loop's; the same comparisons)."""
    return [0.0 if (t >= h and a > 0.0) or (t <= low and a < 0.0) else a
            for t, a, low, h in zip(target, v, lo, hi, strict=True)]


def _clip(x: list[float], lo: list[float], hi: list[float]) -> list[float]:
    """``np.clip(x, lo, hi)`` of arrays, on floats, by numpy's rule: ``max(a, low)`` is ``a``
    when ``a > low`` or ``a`` is NaN, else ``low``; then ``min(., h)`` alike with ``<``
    (signed zeros and NaNs come out as numpy's; tested against it)."""
    out = []
    for a, low, h in zip(x, lo, hi, strict=True):
        a = a if a > low or a != a else low
        out.append(a if a < h or a != a else h)
    return out


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
        Stalled modes retried from their entry (:mod:`tli_verify.sim.retry`).
    robot : str
        The rig (:data:`ROBOTS`).
    retry : bool
        Whether the stall retry was on.
    stopped : str or None
        The reflex stop that ended the trial (a failed trial), if one did.
    limit_ratios : dict of str to float
        Largest ratio to each of the Franka's limits
        (:meth:`~tli_verify.sim.franka_limits.LimitGuard.ratios`; empty for the free tool).
    perturbed_steps : int
        Control periods in which the robot counted itself perturbed (:class:`ContactDetector`).
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
        }


@dataclass(frozen=True, slots=True)
class TraceStep:
    """One control period of a trial as the robot saw it (``run_trial(trace=...)``).

    Attributes
    ----------
    time : float
        Seconds since the trial's start, at the period's start.
    mode : str
        The mode the executive ran in this period (after its decision).
    target : ndarray, shape (4,)
        The DS state ``z*`` the executive was given (the target pose, DS units: dm, rad).
    measured : ndarray, shape (4,)
        The measured DS state ``z`` (:func:`~tli_verify.sim.demos.to_ds` of the tray pose).
    perturbed : bool
        The robot's own estimate (:class:`ContactDetector`).
    """

    time: float
    mode: str
    target: FloatArray
    measured: FloatArray
    perturbed: bool


def load_policy(variant: str, *, root: str | os.PathLike[str] | None = None,
                certificates: str | os.PathLike[str] | None = None) -> LTLDSPolicy:
    """The executive of ``variant`` for the bundled Franka scoop model, behind its certificate.

    Parameters
    ----------
    variant : str
        One of :data:`VARIANTS`.
    root : path-like, optional
        Project directory with ``specs/``, ``models/`` (default: the parent of
        ``certificates`` when given, else the bundled ``sim/franka``).
    certificates : path-like, optional
        Directory of ``franka-scoop.cert.json`` (default ``<root>/certificates``).

    Raises
    ------
    CertificateError
        (exit 1) The certificate is missing, does not re-check, or does not cover the model
        (naming the certificate).
    """
    if variant not in VARIANTS:
        raise TliError(f"unknown variant {variant!r} (one of {', '.join(VARIANTS)})")
    if root is not None:
        base = Path(root)
    elif certificates is not None:
        base = Path(certificates).parent  # a project: models/ and specs/ next to it
    else:
        base = project_dir()
    model = base / "models" / "franka-scoop.model.json"
    cert = (Path(certificates) / "franka-scoop.cert.json" if certificates is not None
            else None)
    if cert is not None and not cert.is_file():
        raise CertificateError(f"{cert}: refused: no certificate for models/"
                               "franka-scoop.model.json (certify it with tli certify)")
    try:
        resolved = resolve(model=model, certificate=cert)
    except TliError as exc:
        if "certificate" in str(exc):
            raise CertificateError(f"refused: {exc}") from None
        raise
    setup = load_setup(resolved)
    if abs(setup.task.dt - CONTROL_DT) > 1e-12:
        raise TliError(f"{setup.task.where}: dt {setup.task.dt:g} s, but the Franka loop "
                       f"controls at {CONTROL_DT:g} s")
    return make_policy(setup, variant)


def run_trial(policy: LTLDSPolicy, seed: int, *, variant: str = "LTL-DS",
              perturbations: list[Perturbation] | None = None, duration: float = TRIAL_DURATION,
              settle: float = 1.0, frame: Callable[[Any], None] | None = None,
              robot: str = "panda", retry: bool = True,
              detector: ContactDetector | None = None, sensors: str = "ideal",
              physics: PhysicsOptions | None = None,
              trace: list[TraceStep] | None = None,
              margin: npt.ArrayLike = MARGIN) -> TrialResult:
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
        The stall retry (:class:`~tli_verify.sim.retry.StallRetry`, part of the documented
        policy); ``False``: ``--no-retry``.
    detector : ContactDetector, optional
        How ``perturbed`` is estimated (default :class:`ContactDetector` ``()``).
    sensors : str, optional
        ``"ideal"`` (noise-free, privileged) or ``"franka"`` (the wrist F/T load and the noisy
        kinematic pose: :mod:`tli_verify.sim.franka_sensors`).
    physics : PhysicsOptions, optional
        The scene's solver settings (default: the measured ones,
        :class:`~tli_verify.sim.scene.PhysicsOptions`).
    trace : list, optional
        Appended with one :class:`TraceStep` per control period (what the robot saw and
        commanded: the Fig. 9-style pictures of :mod:`tli_verify.sim.scenario`).
    margin : array_like, shape (4,), optional
        How far the target may leave the demonstrations' box (:func:`workspace`; default
        :data:`MARGIN`).

    Returns
    -------
    TrialResult
    """
    t0 = time.perf_counter()
    perts = draw_perturbations(seed) if perturbations is None else list(perturbations)
    rig: Any = make_rig(robot, seed, sensors=sensors, physics=physics)
    substeps = round(CONTROL_DT / float(rig.model.opt.timestep))
    debounce = Debounce()
    reading = debounce.update(rig.read())
    ref = to_ds(rig.pose())
    lo, hi = workspace(margin)
    lo_l, hi_l = lo.tolist(), hi.tolist()
    leash, cap = LEASH.tolist(), SPEED_CAP.tolist()
    policy.reset(ref, reading.to_dict())
    stall = StallRetry(policy.model, CONTROL_DT) if retry else None
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
            start = p.start if p.kind == "push" else (
                p.start + soup_at if soup_at is not None else math.inf)
            if hands[i] is None and start < t + CONTROL_DT and t < start + p.duration:
                hands[i] = PersonHand(p, start=start)  # it grabs in this control period
        # the robot's side: what it measures
        z = to_ds(rig.pose())
        perturbed = detect.update(rig.external_wrench(), CONTROL_DT)
        perturbed_steps += perturbed
        # the target stays on a leash of the measured state: held back (a push, the pile),
        # the arm pulls with a bounded force, in every axis, towards where the DS leads
        # (4-vectors on floats: numpy's elementwise roundings and clip rule, less overhead)
        zl = z.tolist()
        ref = np.array(_clip(ref.tolist(), [a - b for a, b in zip(zl, leash, strict=True)],
                             [a + b for a, b in zip(zl, leash, strict=True)]))
        v = policy.step(ref, reading.to_dict(), perturbed=perturbed)
        if trace is not None:
            trace.append(TraceStep(t, policy.mode, ref.copy(), z, perturbed))
        if stall is not None:
            retreat = stall.update(policy.mode, policy.done, ref, z)
            if retreat is not None:
                v = retreat  # the mode stalled at its attractor: back to its entry (sim.retry)
        vl = np.asarray(v, dtype=np.float64).tolist()
        speed = max([abs(a) / c for a, c in zip(vl, cap, strict=True)])
        if speed > 1.0:
            vl = [a / speed for a in vl]
        refl = _clip([r + CONTROL_DT * a for r, a in zip(ref.tolist(), vl, strict=True)],
                     lo_l, hi_l)
        ref = np.array(refl)
        rig.command(from_ds(ref), from_ds_velocity(_feed_forward(refl, vl, lo_l, hi_l)))
        _step_with_hands(rig, substeps, t, hands, applied)
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
    return TrialResult(
        seed=seed, variant=variant, success=delivered >= 1 and stopped is None,
        delivered=delivered, modes=tuple(modes),
        cuts_added=sum(isinstance(e, CutAdded) for e in policy.events),
        sim_time=t, wall_time=time.perf_counter() - t0, perturbations=tuple(perts),
        applied=tuple(applied), events=events,
        retries=stall.retries if stall is not None else 0, robot=robot, retry=retry,
        stopped=stopped, limit_ratios={k: round(v, 4) for k, v in ratios.items()},
        perturbed_steps=perturbed_steps)


def make_rig(robot: str, seed: int, *, sensors: str = "ideal",
             physics: PhysicsOptions | None = None) -> Any:
    """The rig of ``robot`` (:data:`ROBOTS`) with the beads of ``seed``, ``sensors`` and the
    solver settings ``physics`` (default: the measured ones).

    Raises
    ------
    InputError
        An unknown robot (``"hand"``, the free tool's old name, says so).
    """
    if robot == "hand":
        raise InputError("robot 'hand' is now called 'free-tool' (the ladle on a free body, no "
                         "arm); the default is the Panda ('panda')")
    if robot not in ROBOTS:
        raise InputError(f"robot {robot!r}: one of {', '.join(ROBOTS)}")
    if sensors not in SENSOR_KINDS:
        raise InputError(f"sensors {sensors!r}: one of {', '.join(SENSOR_KINDS)}")
    options = DEFAULT_PHYSICS if physics is None else physics
    return PandaRig(seed, sensors=sensors, physics=options) if robot == "panda" else \
        MocapRig(seed, sensors=sensors, physics=options)


class ContactDetector:
    """``perturbed`` as the robot can know it: the estimated external wrench beyond a threshold.

    The rig's estimate (:meth:`~tli_verify.sim.demos.PandaRig.external_wrench`: joint torques
    and the arm's model, as the Panda's ``O_F_ext_hat_K``) is compared with
    ``force`` (N) and ``torque`` (N m); the executive is told ``perturbed`` from the first
    period beyond either until ``hold`` seconds after the last (spilled beads take that long to
    leave the tray). Scooping presses the tray into the beads with less than the thresholds, so
    a nominal trial is never "perturbed" (tested).

    Parameters
    ----------
    force : float, optional
    torque : float, optional
    hold : float, optional
    """

    __slots__ = ("_since", "force", "hold", "torque")

    def __init__(self, force: float = DETECT_FORCE, torque: float = DETECT_TORQUE,
                 hold: float = NOTIFY_AFTER) -> None:
        if not (force > 0 and torque > 0 and hold >= 0):
            raise InputError(f"contact detector: need force > 0, torque > 0, hold >= 0; got "
                             f"{force}, {torque}, {hold}")
        self.force, self.torque, self.hold = float(force), float(torque), float(hold)
        self._since = math.inf

    def reset(self) -> None:
        """Forget the last contact (a new trial)."""
        self._since = math.inf

    def update(self, wrench: FloatArray, dt: float) -> bool:
        """Advance one period with the estimated wrench ``(F, tau)`` (shape (6,)); perturbed?

        A part is beyond its threshold when its norm (``np.linalg.norm``) is; the norm is
        computed only when the sum of squares in floats is within a relative 1e-9 of the
        threshold's square (farther, the answer does not depend on the roundings)."""
        w = np.asarray(wrench, dtype=np.float64)
        if _beyond(w, 0, self.force) or _beyond(w, 3, self.torque):
            self._since = 0.0
        else:
            self._since += dt
        return self._since <= self.hold

    def to_dict(self) -> dict[str, float]:
        """The evidence's record."""
        return {"force": self.force, "torque": self.torque, "hold": self.hold}


def _beyond(w: FloatArray, i: int, limit: float) -> bool:
    """``np.linalg.norm(w[i:i + 3]) > limit``, the norm computed only near ``limit``."""
    a, b, c = w[i:i + 3].tolist()
    sq, lim2 = a * a + b * b + c * c, limit * limit
    if sq < lim2 * (1.0 - 1e-9):
        return False
    if sq > lim2 * (1.0 + 1e-9):
        return True
    return float(np.linalg.norm(w[i:i + 3])) > limit

# --- the perturbing hands, every physics step (kept apart from the control loop) ----------


def _step_with_hands(rig: Any, substeps: int, t: float, hands: list[PersonHand | None],
                     applied: list[float]) -> None:
    """``substeps`` physics steps from time ``t``, the active hands' wrench recomputed at each.

    A hand reads the carrier's centre of mass (``xipos``, where ``xfrc_applied`` acts), its
    orientation (``ximat``) and its velocity there (``mj_objectVelocity``, world frame) -- the
    state of the last ``mj_forward``, i.e. one physics step (2 ms) old after an ``mj_step`` --
    and the sum of the active hands' wrenches goes in ``rig.push``. ``applied[i]`` gets the time
    hand ``i`` first acted. Without an active hand this is ``rig.step(substeps)``.
    """
    live = [(i, h) for i, h in enumerate(hands)
            if h is not None and h.start < t + substeps * float(rig.model.opt.timestep)
            and h.end > t]
    if not live:
        rig.push[:] = 0.0
        rig.step(substeps)
        return
    import mujoco

    model, data = rig.model, rig.data
    dt = float(model.opt.timestep)
    body, kind = rig.carrier, mujoco.mjtObj.mjOBJ_BODY
    vel6 = np.zeros(6)
    omega, vel = vel6[:3], vel6[3:]  # views: mj_objectVelocity writes (rotation, translation)
    # views of the carrier's rows (MjData never reallocates; the hand copies what it keeps)
    pos, orientation = data.xipos[body], data.ximat[body]
    push, object_velocity = rig.push, mujoco.mj_objectVelocity

    def before(j: int) -> None:
        tj = t + j * dt
        total = np.zeros(6)
        for i, hand in live:
            if hand.active(tj):
                object_velocity(model, data, kind, body, vel6, 0)
                total += hand.wrench(tj, pos, orientation, vel, omega)
                if math.isnan(applied[i]):
                    applied[i] = tj
        push[:] = total

    rig.step(substeps, before=before)
    rig.push[:] = 0.0


def run_trials(seeds: list[int], variant: str = "LTL-DS", *, perturb: bool = True,
               duration: float = TRIAL_DURATION, robot: str = "panda",
               retry: bool = True, sensors: str = "ideal",
               physics: PhysicsOptions | None = None) -> list[dict[str, Any]]:
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
                      physics=physics).to_dict()
            for s in seeds]


def plot_flow(model: Any, path: str | os.PathLike[str], *,
              demos: list[Any] | None = None, title: str = "") -> None:
    """A Fig. 11-style picture: each mode's modulated DS flow in (y, z, pitch), with the cuts.

    Streamlines: the certified DS of each mode (``model.modes[mode].velocity``, cuts
    included) integrated at the control period from a grid of starts around its demonstrated
    region, in the slice ``x`` = the attractor's; the learned cut planes of each mode drawn as
    patches of their hyperplane in that slice; the demonstrations in black.

    Parameters
    ----------
    model : Model
        E.g. ``policy.model`` after trials (with the cuts learned online).
    path : path-like
        PNG to write (atomically).
    demos : list of Demonstration, optional
    title : str, optional
    """
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colors = {"a": "tab:gray", "b": "tab:orange", "c": "tab:red", "d": "tab:green"}
    fig = plt.figure(figsize=(8, 6.5))
    ax = fig.add_subplot(projection="3d")
    rng = np.random.default_rng(0)
    for key, mm in sorted(model.modes.items()):
        mode = key.split("->")[0]
        x_star = mm.ds.attractor
        means = np.asarray(mm.ds.means)
        starts = means[rng.integers(0, len(means), size=10)] + \
            rng.normal(scale=[0.0, 0.15, 0.1, 0.1], size=(10, 4))
        starts[:, 0] = x_star[0]
        for z in starts:
            pts = [z.copy()]
            for _ in range(400):
                v = mm.velocity(pts[-1], dt=CONTROL_DT)
                pts.append(pts[-1] + CONTROL_DT * v)
            arr = np.array(pts)
            ax.plot(arr[:, 1], arr[:, 2], arr[:, 3], color=colors.get(mode, "b"), lw=0.8,
                    alpha=0.8)
        ax.scatter([x_star[1]], [x_star[2]], [x_star[3]], color=colors.get(mode, "b"),
                   marker="*", s=120, edgecolor="k", label=f"mode {mode}: DS and x*")
        for cut in model.region_cuts(mode):
            n, p = np.asarray(cut.normal), np.asarray(cut.point)
            if abs(n[3]) < 1e-9:
                continue
            u = np.linspace(-0.4, 0.4, 2)
            yy, zz = np.meshgrid(p[1] + u, p[2] + u)
            pp = p[3] - (n[1] * (yy - p[1]) + n[2] * (zz - p[2]) + n[0] * (x_star[0] - p[0])) \
                / n[3]
            pp = np.clip(pp, -1.0, 2.0)  # a plane nearly along the pitch axis: clipped
            ax.plot_surface(yy, zz, pp, color=colors.get(mode, "b"), alpha=0.3)
    for demo in demos or []:
        ax.plot(demo.x[:, 1], demo.x[:, 2], demo.x[:, 3], color="k", lw=1.2, alpha=0.7)
    ax.set_xlabel("y (dm)")
    ax.set_ylabel("z (dm)")
    ax.set_zlabel("pitch (rad)")
    ax.set_zlim(-1.0, 2.0)
    ax.set_title(title or "Modulated LTL-DS flow per mode (y, z, pitch) with learned cuts")
    ax.legend(loc="upper left", fontsize=8)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
