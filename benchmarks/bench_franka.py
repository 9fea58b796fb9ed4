"""The MuJoCo Franka loop: bare ``mj_step`` against the closed loop, controller cost.

Side by side in one run (one core; ``threadpoolctl`` limits BLAS to one thread; CPU time,
``time.process_time``, so a shared machine distorts it less), on the arm-only
scene (:func:`tli_verify.sim.robot.load_panda`: the Menagerie Panda, torque motors, 2 ms step):

- bare ``mj_step`` steps per second (torques held at the initial gravity compensation);
- the Cartesian impedance controller alone (:meth:`ImpedanceController.compute`), us per call;
- the closed loop: a DS target (a linear DS stand-in for the policy on the 6-D pose, moving
  the position and the pitch, integrated each control period) tracked by the controller,
  ``mj_step1`` / controller / ``mj_step2`` and the held substeps, at a control period of 2 ms
  (every step), 10 ms (5 substeps) and 20 ms (10 substeps, the scene's period), in physics
  steps per second, as a
  fraction of the bare rate, and as a real-time factor (simulated / wall time); the largest
  tracking error is reported with it.

Targets: closed loop >= 60 % of the bare ``mj_step`` rate, >= 5x real time. The
scene with the beads is benchmarked by the scene's own rows when it lands.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from tli_verify.io import atomic_write_text, canonical_json


def _best_rate(fn: Callable[[], int], repeats: int) -> tuple[float, float]:
    """Median and best of ``repeats`` runs of ``fn`` (which returns its step count), steps per
    CPU second."""
    rates = []
    for _ in range(repeats):
        t0 = time.process_time()
        n = fn()
        rates.append(n / (time.process_time() - t0))
    return float(np.median(rates)), float(np.max(rates))


def _closed_loop(panda: Any, substeps: int, seconds: float) -> tuple[int, float, float, int]:
    """Run the DS-tracking closed loop for ``seconds`` of simulated time.

    Returns physics steps, the largest position and rotation tracking error (norm of the
    rotation-vector gap), saturated calls.
    """
    from tli_verify.sim.controller import ImpedanceController, integrate_ds_target

    data = panda.new_data()
    ctl = ImpedanceController(panda)
    period = panda.model.opt.timestep * substeps
    z0 = ctl.ds_state(data)
    goals = [z0 + np.array([0.0, 0.15, -0.10, 0.0, 0.4, 0.0]),
             z0 + np.array([0.05, -0.15, 0.05, 0.0, -0.3, 0.0])]
    z_t = z0.copy()
    n_periods = round(seconds / period)
    worst_p = worst_r = 0.0
    for k in range(n_periods):
        goal = goals[(k * len(goals)) // n_periods]
        zdot = -2.0 * (z_t - goal)
        speed = float(np.linalg.norm(zdot[:3]))
        if speed > 0.25:
            zdot[:3] *= 0.25 / speed
        z_t = integrate_ds_target(z_t, zdot, period)
        pos, quat = ctl.target_pose_from_ds_state(z_t)
        ctl.step(data, pos, quat, ctl.map.twist_from_ds_velocity(zdot, z_t), substeps=substeps)
        z = ctl.ds_state(data)
        worst_p = max(worst_p, float(np.linalg.norm(z[:3] - z_t[:3])))
        worst_r = max(worst_r, float(np.linalg.norm(z[3:] - z_t[3:])))
    return n_periods * substeps, worst_p, worst_r, ctl.stats().saturated_calls


def main(out_dir: Path) -> str:
    import mujoco
    from threadpoolctl import threadpool_limits

    from tli_verify.errors import AssetError
    from tli_verify.sim.controller import ImpedanceController
    from tli_verify.sim.robot import load_panda

    try:
        panda = load_panda()
    except AssetError as exc:  # not fetched: say so instead of failing the whole `make bench`
        return ("## The MuJoCo Franka loop: robot and controller\n\n"
                f"Skipped: {exc}\n")
    model = panda.model
    dt = float(model.opt.timestep)
    results: dict[str, Any] = {"timestep_s": dt, "nv": int(model.nv)}
    with threadpool_limits(1):
        n_bare = 20000

        def bare() -> int:
            data = panda.new_data()
            panda.set_torque(data, panda.bias(data))
            for _ in range(n_bare):
                mujoco.mj_step(model, data)
            return n_bare

        bare_med, _ = _best_rate(bare, 5)
        # controller alone
        data = panda.new_data()
        ctl = ImpedanceController(panda)
        pos, quat = ctl.target_pose_from_ds_state(ctl.ds_state(data)
                                                  + np.array([0.0, 0.02, 0.0, 0.0, 0.1, 0.0]))
        mujoco.mj_step1(model, data)
        n_ctl = 20000
        times = []
        for _ in range(5):
            t0 = time.process_time()
            for _ in range(n_ctl):
                ctl.compute(data, pos, quat)
            times.append((time.process_time() - t0) / n_ctl)
        ctl_us = 1e6 * float(np.median(times))
        loops = {}
        for substeps in (1, 5, 10):
            track: list[tuple[float, float, int]] = []

            def run(substeps: int = substeps, track: list[tuple[float, float, int]] = track
                    ) -> int:
                steps, wp, wr, sat = _closed_loop(panda, substeps, 20.0)
                track.append((wp, wr, sat))
                return steps

            rate, _ = _best_rate(run, 3)
            loops[substeps] = dict(
                steps_per_s=rate, fraction_of_bare=rate / bare_med, realtime_factor=rate * dt,
                max_pos_error_m=max(t[0] for t in track),
                max_rot_error_rad=max(t[1] for t in track),
                saturated_calls=max(t[2] for t in track))
    results.update(bare_steps_per_s=bare_med, bare_realtime_factor=bare_med * dt,
                   controller_us_per_call=ctl_us,
                   closed_loop={f"period_{1000 * dt * s:g}ms": v for s, v in loops.items()})
    atomic_write_text(out_dir / "franka.json", canonical_json(json.loads(json.dumps(results))))

    def ok(v: bool) -> str:
        return "met" if v else "**not met**"

    rows = [
        "| Measure | Result | Baseline | Note |",
        "|---|---|---|---|",
        f"| Bare `mj_step`, arm alone (nv = {model.nv}) | {bare_med:,.0f} steps/s "
        f"({bare_med * dt:.0f}x real time) | - | torques held |",
        f"| Impedance controller, one call | {ctl_us:.0f} us | 50-75 us (possible) "
        "| Jacobian, 7x7 arm block of M, two Cholesky solves, saturation |",
    ]
    for s, v in loops.items():
        rows.append(
            f"| Closed loop, control every {1000 * dt * s:g} ms "
            f"({s} substep{'s' if s > 1 else ''}) "
            f"| {v['steps_per_s']:,.0f} steps/s ({v['realtime_factor']:.0f}x real time) "
            f"| {100 * v['fraction_of_bare']:.0f}% of bare `mj_step` "
            f"| >= 60%: {ok(v['fraction_of_bare'] >= 0.6)}; >= 5x real time: "
            f"{ok(v['realtime_factor'] >= 5)}; tracking <= {1000 * v['max_pos_error_m']:.1f} mm, "
            f"{v['max_rot_error_rad']:.3f} rad; saturated calls {v['saturated_calls']} |")
    return (
        "## The MuJoCo Franka loop: robot and controller\n\n"
        "Arm-only scene (Menagerie Panda, torque motors, 2 ms `implicitfast` step); closed loop = "
        "a 6-D pose DS target (position + pitch moving, linear DS stand-in for the policy, speed "
        "<= 0.25 m/s) "
        "integrated each control period, `mj_step1` / controller / `mj_step2` + held substeps, "
        "20 s of simulated time; medians, one core, CPU time. The scene with the beads and the "
        "policy: `bench_franka_scene`.\n\n" + "\n".join(rows) + "\n"
    )
