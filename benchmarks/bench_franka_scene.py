"""The MuJoCo soup-scooping scene with 30 beads: bare physics vs the LTL-DS closed loop.

Side by side in one run, one core each (issue 13 targets); rates per CPU second
(``time.process_time``), so a shared machine does not distort them:

- bare ``mj_step`` of the scene with 30 settled beads and the ladle held (steps/s);
- the closed loop (sensors, :class:`~tli_verify.runtime.executive.LTLDSPolicy`, the impedance
  law and 10 ``mj_step`` per 20 ms control period) on one nominal trial: physics steps/s
  (target >= 60% of bare) and the real-time factor (target >= 5x);
- ``TRIALS`` perturbed LTL-DS trials (default 30; ``TLI_BENCH_FRANKA_TRIALS``) on 2 worker
  processes (seeds split in two halves, each with its own executive): wall time (target
  < 10 min on 2 cores) and the success count.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from tli_verify.errors import TliError
from tli_verify.io import atomic_write_text, canonical_json


def main(out_dir: Path) -> str:
    import mujoco
    import threadpoolctl

    from tli_verify.sim.demos import MocapRig
    from tli_verify.sim.loop import load_policy, run_trial, run_trials

    trials = int(os.environ.get("TLI_BENCH_FRANKA_TRIALS", "30"))
    with threadpoolctl.threadpool_limits(1):
        rig = MocapRig(0)
        n = 3000
        t0 = time.process_time()  # CPU time: the machine may be shared
        for _ in range(n):
            mujoco.mj_step(rig.model, rig.data)
        bare = n / (time.process_time() - t0)
        policy = load_policy("LTL-DS")
        c0 = time.process_time()
        res = run_trial(policy, 1, perturbations=[], duration=14.0)
        cpu = time.process_time() - c0
        steps = res.sim_time / float(rig.model.opt.timestep)
        closed = steps / cpu
        arm: dict[str, float] = {}
        try:  # the same with the ladle on the Panda (needs the Menagerie assets)
            from tli_verify.sim.demos import PandaRig

            prig = PandaRig(0)
            t0 = time.process_time()
            for _ in range(n):
                mujoco.mj_step(prig.model, prig.data)
            arm["bare"] = n / (time.process_time() - t0)
            c0 = time.process_time()
            pres = run_trial(load_policy("LTL-DS"), 2, perturbations=[], duration=14.0,
                             robot="panda")
            pcpu = time.process_time() - c0
            arm["closed"] = pres.sim_time / float(prig.model.opt.timestep) / pcpu
            arm["rtf"] = pres.sim_time / pcpu
        except TliError:
            pass
    t0 = time.perf_counter()
    halves = [list(range(0, trials, 2)), list(range(1, trials, 2))]
    with ProcessPoolExecutor(2) as pool:
        recs = [r for part in pool.map(run_trials, halves) for r in part]
    t_trials = time.perf_counter() - t0
    ok = sum(bool(r["success"]) for r in recs)
    data = {"bare_steps_per_s": bare, "closed_loop_steps_per_s": closed,
            "closed_over_bare": closed / bare, "real_time_factor": res.sim_time / cpu,
            "closed_loop_wall_s": res.wall_time, "closed_loop_cpu_s": cpu,
            "nominal_trial": res.to_json(), "trials": trials, "trials_wall_s": t_trials,
            "successes": ok}
    data["panda"] = arm
    rows = "" if not arm else (
        f"| bare `mj_step`, 30 beads + the Panda | {arm['bare']:,.0f} steps/s | (baseline) |\n"
        f"| closed loop with the Panda (operational-space controller every step) | "
        f"{arm['closed']:,.0f} steps/s ({arm['closed'] / arm['bare']:.0%} of bare), "
        f"{arm['rtf']:.1f}x real time | >= 60%, >= 5x |\n")
    atomic_write_text(out_dir / "franka_scene.json", canonical_json(data))
    return (
        "## The soup-scooping scene in MuJoCo, 30 beads (`bench_franka_scene`)\n\n"
        "| measurement | value | target |\n|---|---:|---:|\n"
        f"| bare `mj_step`, 30 beads | {bare:,.0f} steps/s | (baseline) |\n"
        f"| closed loop (sensors + LTL-DS + impedance + `mj_step`), one nominal trial | "
        f"{closed:,.0f} steps/s ({closed / bare:.0%} of bare) | >= 60% |\n"
        f"| real-time factor of the closed loop | {res.sim_time / cpu:.1f}x | "
        ">= 5x |\n"
        + rows +
        f"| {trials} perturbed LTL-DS trials, 2 workers | {t_trials:.0f} s, {ok}/{trials} "
        "delivered | < 600 s |\n"
    )
