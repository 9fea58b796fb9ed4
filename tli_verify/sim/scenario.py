"""Modulation at work in physics: the pour that sweeps past the bowl (paper Fig. 9).

The regression scenario (:data:`POUR_SCENARIO`): one nominal Panda trial of a Franka policy (the
one it was found with: the DS learned from the mocap rig's commanded poses, kept as the test
project ``tests/support/franka_pour``; the DS relearned from kinesthetic takes on the Panda does
not sweep past the bowl), bead seed 0, no perturbation, no stall retry, in a cell that gives the
arm room beyond the target bowl (the target may leave the demonstrations' box by 1.5 dm in ``y``
instead of the default 0.5 dm, :data:`~tli_verify.sim.target.MARGIN`). Its pour (mode ``d``;
``t``: the tray over the target bowl with soup to deliver) enters ``t`` on the near side of the
bowl, and the certified pour DS, integrated from there, sweeps the tray about 7 cm past the
bowl's rim before it turns back to its attractor over the bowl's centre: ``t`` turns off with
soup still on the spoon (``c``), the transport DS brings the tray back, ``t`` turns on, and the
pour sweeps out again. (In the default workspace the bound on the target stops the sweep 2 cm
inside the rim: the hand-set bound hides what the DS does.) No perturbation causes it, so each
exit is an
*invariance failure* of ``d`` (paper Sec. 5):

* without modulation (``no-modulation``) the pour leaves ``d`` again and again (14 times on bead
  seed 0: 7 times at the rim, then 7 times with the spoon empty; 6-14 times on seeds 0-9);
* LTL-DS cuts ``d``'s region at each failure (appendix E.3: the plane through the last in-mode
  state that passes closest to the attractor and separates the failure) and modulates the
  pour DS with the cuts (eq. 7): each failure happens once, the next one at a state the earlier
  cuts admit, and after 3 cuts (3-4 on seeds 0-9) the pour stays inside the column to the
  end. It is not one cut: the plane the QCQP picks runs through the attractor and tilts into
  pitch (the failure step moves the target in ``y`` *and* pitch), so it leaves room to sweep
  out a little further in ``y`` at a lower height or a larger pitch.

:func:`run_scenario` runs it for a variant and returns the trace the robot saw
(:class:`~tli_verify.sim.loop.TraceStep`), the invariance failures and the cuts learned;
:func:`plot_scenario` draws the runs side by side in the style of the paper's Fig. 9 (the
pour in ``(y, z, pitch)``: the column's rim, the learned cut planes, the failures, the
attractor). ``scripts/franka_modulation.py`` writes ``docs/img/franka_modulation.png`` and
``tests/integration/test_sim_modulation.py`` is the regression case.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022: Sec. 5 (invariance failures and cutting planes),
eq. 7 (modulation), appendix E.3 (the cut QCQP), Fig. 9 (modulation of the robot's DS in
``y``, ``z`` and pitch: before it trajectories leave the mode, after it they stay inside).
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TliError
from tli_verify.io import atomic_write_bytes
from tli_verify.runtime.events import Replan
from tli_verify.runtime.repeats import FailureCheck, check_repeats
from tli_verify.sim.demos import POSITION_SCALE, pitch_column
from tli_verify.sim.franka_project import load_policy
from tli_verify.sim.loop import TraceStep, TrialResult, run_trial
from tli_verify.sim.scene import TARGET_BOWL

__all__ = ["POUR_SCENARIO", "Failure", "Scenario", "ScenarioRun",
           "plot_scenario", "run_scenario"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Scenario:
    """A seeded physical scenario: one trial's settings.

    Attributes
    ----------
    name : str
    seed : int
        Bead placement (and the trial's seed).
    mode : str
        The mode whose invariance failures the scenario is about.
    duration : float
        Step budget, simulated seconds.
    robot : str
        ``"panda"`` or ``"free-tool"``.
    retry : bool
        The executive's stall rule (:mod:`tli_verify.runtime.stall`; off: the automaton's
        transitions only).
    margin : tuple of float, length 6
        How far the target (tracking) or the robot (passive: the velocity leaving it is
        dropped) may leave the demonstrations' box (dm, dm, dm, rad x 3, per pose coordinate:
        :func:`~tli_verify.sim.target.workspace`).
    controller : str
        ``"tracking"`` (default: the loop the scenario was found in), ``"measured"`` or
        ``"passive"`` (:func:`~tli_verify.sim.loop.run_trial`).
    sensors : str
        ``"ideal"`` (default) or ``"franka"``.
    """

    name: str
    seed: int
    mode: str
    duration: float = 14.0
    robot: str = "panda"
    retry: bool = False
    margin: tuple[float, float, float, float, float, float] = (0.5, 0.5, 0.5, 0.3, 0.3, 0.3)
    controller: str = "tracking"
    sensors: str = "ideal"


POUR_SCENARIO = Scenario(name="pour-sweeps-past-the-bowl", seed=0, mode="d",
                         margin=(0.5, 1.5, 0.5, 0.3, 0.3, 0.3))
"""The pour scenario as it was found: the target-tracking loop, the ideal sensors."""

"""The regression scenario of the module doc."""


@dataclass(frozen=True, slots=True)
class Failure:
    """One invariance failure of the scenario's mode, as the executive reported it.

    Attributes
    ----------
    step : int
        Control period (0-based index into :attr:`ScenarioRun.trace`).
    to_mode : str
        The mode the reading showed.
    target, measured : ndarray, shape (n,)
        The DS state the executive was given and the measured one at that period.
    """

    step: int
    to_mode: str
    target: FloatArray
    measured: FloatArray


@dataclass(frozen=True, slots=True)
class ScenarioRun:
    """One variant's run of a :class:`Scenario`.

    Attributes
    ----------
    scenario : Scenario
    variant : str
    result : TrialResult
    trace : tuple of TraceStep
    failures : tuple of Failure
        The invariance failures of ``scenario.mode``, in order.
    cuts : tuple
        The cuts of ``scenario.mode``'s region at the end (:class:`~tli_verify.model.types.Cut`).
    attractor : ndarray, shape (n,)
        The mode's DS attractor.
    checks : tuple of FailureCheck
        Each failure against the cuts learned before it (for a variant that learns none: the
        cuts LTL-DS would have learned from the same failures;
        :func:`~tli_verify.runtime.repeats.check_repeats`).
    """

    scenario: Scenario
    variant: str
    result: TrialResult
    trace: tuple[TraceStep, ...]
    failures: tuple[Failure, ...]
    cuts: tuple[Any, ...]
    attractor: FloatArray
    checks: tuple[FailureCheck, ...] = ()

    @property
    def exits(self) -> int:
        """How many times the mode was left by an invariance failure."""
        return len(self.failures)

    @property
    def repeats(self) -> int:
        """How many failures crossed a cut learned from an earlier one: the same invariance
        failure again (paper Sec. 7.2: with modulation, none)."""
        return sum(c.repeated for c in self.checks)

    @property
    def invariance_ok(self) -> bool:
        """Each invariance failure happened once (:attr:`repeats` is 0)."""
        return self.repeats == 0


def run_scenario(variant: str, scenario: Scenario = POUR_SCENARIO, *,
                 root: str | os.PathLike[str] | None = None) -> ScenarioRun:
    """Run ``scenario`` with a fresh executive of ``variant`` (no cuts carried in).

    Parameters
    ----------
    variant : str
        ``"LTL-DS"``, ``"no-modulation"`` or ``"no-replan"``
        (:data:`~tli_verify.sim.franka_project.VARIANTS`).
    scenario : Scenario, optional
    root : path-like, optional
        A Franka project (default: the bundled one), as
        :func:`~tli_verify.sim.franka_project.load_policy`.

    Returns
    -------
    ScenarioRun
    """
    policy = load_policy(variant, root=root)
    keys = [k for k in policy.model.modes if k.split("->")[0] == scenario.mode]
    if not keys:
        raise TliError(f"scenario {scenario.name}: the model has no DS for mode "
                       f"{scenario.mode!r}")
    start_model = policy.model  # the model before any cut of this run (for the replay)
    trace: list[TraceStep] = []
    result = run_trial(policy, scenario.seed, variant=variant, perturbations=[],
                       duration=scenario.duration, robot=scenario.robot,
                       retry=scenario.retry, trace=trace, margin=scenario.margin,
                       controller=scenario.controller, sensors=scenario.sensors)
    failures = []
    for event in policy.events:
        if isinstance(event, Replan) and event.from_mode == scenario.mode \
                and event.cause == "invariance failure":
            k = event.step - 1  # the executive counts its steps from 1
            failures.append(Failure(k, event.to_mode, trace[k].target, trace[k].measured))
    checks = check_repeats(policy.events, scenario.mode,
                           replay_from=None if policy.learn_cuts else start_model)
    return ScenarioRun(scenario, variant, result, tuple(trace), tuple(failures),
                       tuple(policy.model.region_cuts(scenario.mode)),
                       np.asarray(policy.model.modes[keys[0]].ds.attractor, dtype=np.float64),
                       checks)


def _axes(dim: int) -> list[int]:
    """The columns drawn: y, z and the pitch (``ry``) of a DS state of dimension ``dim``."""
    return [1, 2, pitch_column(dim)]


def _plane(ax: Any, normal: FloatArray, point: FloatArray, lo: FloatArray, hi: FloatArray,
           **style: Any) -> None:
    """Draw ``normal . (q - point) = 0`` restricted to ``(y, z, pitch)`` (the other
    coordinates at the point's) in the box ``[lo, hi]`` (shape (3,)): solved for the axis with
    the largest normal component."""
    axes = _axes(len(normal))
    n = np.asarray(normal, dtype=np.float64)[axes]
    p = np.asarray(point, dtype=np.float64)[axes]
    k = int(np.argmax(np.abs(n)))
    if abs(n[k]) < 1e-12:
        return
    i, j = [a for a in range(3) if a != k]
    u, v = np.meshgrid(np.linspace(lo[i], hi[i], 2), np.linspace(lo[j], hi[j], 2))
    w = p[k] - (n[i] * (u - p[i]) + n[j] * (v - p[j])) / n[k]
    grid = [np.empty_like(u)] * 3
    grid[i], grid[j], grid[k] = u, v, np.clip(w, lo[k], hi[k])
    ax.plot_surface(grid[0], grid[1], grid[2], **style)


def _time_panel(ax: Any, run: ScenarioRun, steps: tuple[TraceStep, ...], rim: float) -> None:
    """The tray's ``y`` over time against the rim; failures and cuts marked."""
    t = np.array([s.time for s in steps])
    ax.plot(t, [s.measured[1] for s in steps], color="0.4", lw=1.0, label="measured tray y")
    ax.plot(t, [s.target[1] for s in steps], color="tab:green", lw=1.0, ls="--",
            label="target y")
    ax.axhline(rim, color="tab:orange", lw=1.5, label="rim of the target column")
    shade = [s.mode == run.scenario.mode for s in steps]
    ax.fill_between(t, 0, 1, where=shade, transform=ax.get_xaxis_transform(),
                    color="tab:green", alpha=0.08, label=f"in mode {run.scenario.mode}")
    labelled: set[bool] = set()
    for k, f in enumerate(run.failures):
        when = run.trace[f.step].time
        again = k < len(run.checks) and run.checks[k].repeated
        ax.plot([when], [f.measured[1]], "o" if again else "x", color="red", ms=8 if not again
                else 6, label=None if again in labelled else
                ("repeated failure (beyond an earlier failure's cut)" if again
                 else "invariance failure"))
        labelled.add(again)
        if run.cuts:
            ax.axvline(when, color="tab:blue", lw=0.8, ls=":",
                       label="cut learned" if k == 0 else None)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("y (dm)")
    ax.legend(loc="lower right", fontsize=7)


def plot_scenario(runs: list[ScenarioRun], path: str | os.PathLike[str]) -> None:
    """Fig. 9-style panels, one per run: the pour in ``(y, z, pitch)``.

    Top, each run in 3-D: the target states the DS was evaluated at while the scenario's mode ran
    (green) and while the transport brought the tray back (red), the measured tray (grey), the
    invariance failures (red crosses at the measured state), the rim of the column above the
    target bowl that ``t`` ends at (orange plane, ``y`` = bowl centre + radius), the cut planes
    learned in the mode (blue) and its attractor (pink diamond). Below, the tray's ``y`` over
    time against the rim, with the failures and the cuts.

    Parameters
    ----------
    runs : list of ScenarioRun
    path : path-like
        PNG to write (atomically).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not runs:
        raise TliError("plot_scenario: no runs to plot")
    fig = plt.figure(figsize=(6.2 * len(runs), 9.6))
    rim = float((TARGET_BOWL.center[1] + TARGET_BOWL.radius) * POSITION_SCALE)
    for n, run in enumerate(runs):
        ax = fig.add_subplot(2, len(runs), n + 1, projection="3d")
        start = next((i for i, s in enumerate(run.trace) if s.mode == run.scenario.mode), 0)
        steps = run.trace[max(0, start - 25):]
        tgt = np.array([s.target for s in steps])
        meas = np.array([s.measured for s in steps])
        pts_all = np.vstack([tgt, meas, run.attractor[None, :]])
        dim = pts_all.shape[1]
        pc = pitch_column(dim)
        lo = pts_all.min(axis=0)[_axes(dim)] - 0.1
        hi = pts_all.max(axis=0)[_axes(dim)] + 0.1
        lo[0], hi[0] = min(lo[0], rim - 0.3), max(hi[0], rim + 0.2)
        ax.plot(meas[:, 1], meas[:, 2], meas[:, pc], color="0.55", lw=0.8,
                label="measured tray")
        in_mode = np.array([s.mode == run.scenario.mode for s in steps])
        for flag, color, label in ((True, "tab:green", f"target, mode {run.scenario.mode}"),
                                   (False, "tab:red", "target, other modes")):
            pts = np.where(in_mode == flag, 1.0, np.nan)[:, None] * tgt
            ax.plot(pts[:, 1], pts[:, 2], pts[:, pc], color=color, lw=1.6, label=label)
        _plane(ax, np.eye(dim)[1], np.eye(dim)[1] * rim, lo, hi,
               color="tab:orange", alpha=0.25)
        for cut in run.cuts:
            _plane(ax, np.asarray(cut.normal), np.asarray(cut.point), lo, hi,
                   color="tab:blue", alpha=0.18)
        if run.failures:
            f = np.array([x.measured for x in run.failures])
            ax.scatter(f[:, 1], f[:, 2], f[:, pc], color="red", marker="x", s=70,
                       label=f"invariance failures ({len(run.failures)})")
        a = run.attractor
        ax.scatter([a[1]], [a[2]], [a[pc]], color="violet", marker="D", s=60,
                   edgecolor="k", label="attractor")
        ax.plot([], [], color="tab:orange", lw=6, alpha=0.4, label="rim of the target column")
        if run.cuts:
            ax.plot([], [], color="tab:blue", lw=6, alpha=0.4,
                    label=f"learned cuts ({len(run.cuts)})")
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_zlim(lo[2], hi[2])
        ax.view_init(elev=18, azim=-62)
        ax.set_xlabel("y (dm)")
        ax.set_ylabel("z (dm)")
        ax.set_zlabel("pitch (rad)")
        ax.set_title(f"{run.variant}: {run.exits} exit(s) of {run.scenario.mode}, "
                     f"{run.repeats} repeated; {run.result.delivered} bead(s) delivered",
                     fontsize=10)
        ax.legend(loc="upper left", fontsize=7)
        _time_panel(fig.add_subplot(2, len(runs), len(runs) + n + 1), run, steps, rim)
    fig.suptitle(f"Scenario {runs[0].scenario.name} (seed {runs[0].scenario.seed}, Panda, "
                 "nominal): the pour with and without modulation", fontsize=11)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
