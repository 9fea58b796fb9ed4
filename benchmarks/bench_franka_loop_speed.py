"""The Franka loop's speed per control law, side by side on the same perturbed trials.

Issue 34 asks for a perturbed trial at least 10x real time on one core, side by side with
the loop before it. For each control law of :func:`tli_verify.sim.loop.run_trial` --
*measured* (the default: the DS at the measured pose integrated to the impedance law's target),
*passive* (the passive-DS law) and *tracking* (the DS on its own target: the loop before issue
34) -- the same seeds' perturbed trials (one push and one tilt each, the robot's sensors, the
stall rule; a fresh executive per law), one BLAS thread, one process:

- **sim/wall**: simulated seconds over wall-clock seconds of each trial (the rig's
  construction -- scene compilation, the arm's move to the start, the beads settling -- is in
  the wall time, as a user waits for it; it is not simulated trial time), median over the seeds;
- **MuJoCo share**: the share of the trial's CPU time (the rig's construction excluded) inside
  ``mj_step1`` + ``mj_step2`` (the probe of :mod:`benchmarks.bench_franka_scene`, which wraps
  the calls the rig looks up per step);
- **MuJoCo-only ceiling**: simulated seconds over the CPU seconds inside MuJoCo: the real-time
  factor the trial would reach with every line of Python free. Where it is below 10x, 10x real
  time needs other physics (solver, tolerance, contact model, time step, bead count), not
  faster code.

``TLI_BENCH_FRANKA_LOOP_SEEDS`` (default ``0,1,2,3,4``) sets the seeds. Machine load moves every
wall-clock figure: the medians are of one run.
"""

from __future__ import annotations

import os
import statistics
import time
from pathlib import Path
from typing import Any

from benchmarks.bench_franka_scene import Probe, probed
from tli_verify.io import atomic_write_text, canonical_json

LAWS = ("measured", "passive", "tracking")


def _law_rows(law: str, seeds: list[int]) -> dict[str, Any]:
    from threadpoolctl import threadpool_limits

    from tli_verify.sim.franka_project import load_policy
    from tli_verify.sim.loop import run_trial

    trials = []
    with threadpool_limits(1):
        policy = load_policy("LTL-DS")
        for seed in seeds:
            probe = Probe(record=False, timing=True)
            with probed(probe):
                t0, c0 = time.perf_counter(), time.process_time()
                res = run_trial(policy, seed, controller=law)
                wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            trials.append({"seed": seed, "sim_s": res.sim_time, "wall_s": wall,
                           "trial_cpu_s": cpu - probe.build_cpu, "mujoco_cpu_s": probe.in_step,
                           "success": res.success})
    return {
        "law": law,
        "trials": trials,
        "sim_over_wall": statistics.median(t["sim_s"] / t["wall_s"] for t in trials),
        "mujoco_share": statistics.median(t["mujoco_cpu_s"] / t["trial_cpu_s"]
                                          for t in trials),
        "ceiling": statistics.median(t["sim_s"] / t["mujoco_cpu_s"] for t in trials),
        "successes": sum(bool(t["success"]) for t in trials),
    }


def main(out_dir: Path) -> str:
    seeds = [int(s) for s in os.environ.get("TLI_BENCH_FRANKA_LOOP_SEEDS", "0,1,2,3,4")
             .split(",") if s.strip()]
    rows = [_law_rows(law, seeds) for law in LAWS]
    atomic_write_text(out_dir / "franka_loop_speed.json",
                      canonical_json({"seeds": seeds, "rows": rows}))
    return format_results(seeds, rows)


def format_results(seeds: list[int], rows: list[dict[str, Any]]) -> str:
    lines = [
        "## The Franka loop per control law: speed on one core (issue 34)\n",
        f"Perturbed trials on seeds {seeds[0]}-{seeds[-1]} (one push, one tilt, the robot's "
        "sensors, the stall rule), one process, one BLAS thread; medians over the seeds. "
        "*tracking* is the loop before issue 34. Target: 10x real time.\n",
        "| control law | sim/wall (median) | per trial | MuJoCo share of trial CPU | MuJoCo-only "
        "ceiling | delivered | >= 10x |",
        "|---|---:|---|---:|---:|---:|---|",
    ]
    for r in rows:
        per = ", ".join(f"{t['sim_s'] / t['wall_s']:.1f}" for t in r["trials"])
        lines.append(
            f"| {r['law']} | {r['sim_over_wall']:.1f}x | {per} | {100 * r['mujoco_share']:.0f}% "
            f"| {r['ceiling']:.1f}x | {r['successes']}/{len(r['trials'])} | "
            f"{'yes' if r['sim_over_wall'] >= 10 else 'no'} |")
    lines.append("")
    lines.append("The ceiling is the sim/wall with no Python at all (simulated seconds over "
                 "CPU seconds inside `mj_step1` + `mj_step2`); where it is below 10x the target "
                 "needs other physics, not faster code.")
    return "\n".join(lines) + "\n"
