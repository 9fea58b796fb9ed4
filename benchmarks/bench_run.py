"""Closed-loop LTL-DS on the scoop task: one episode, batched episodes, the scoop experiment.

Side by side in one run (one core for the first three; ``threadpoolctl`` limits BLAS to one
thread):

- one scoop episode of 2,000 control steps (the shipped model and certificate, dt = 1/100,
  three fixed perturbations, run to the budget) with
  :func:`tli_verify.runtime.loop.run_episode` (target <= 50 ms);
- 200 perturbed episodes batched across starts
  (:func:`tli_verify.runtime.episodes.run_variant_batch`, i.e.
  :func:`~tli_verify.runtime.loop.run_episodes`): policy steps per second (target
  >= 100,000 on one core), against a per-step Python loop over the same policy, one episode
  at a time (:func:`~tli_verify.runtime.loop.run_episode`, on 20 of the episodes);
- the scoop experiment (``tli experiment scoop``: 10 experiments x 100 episodes x 4 variants
  and the Fig. 7 search) on 2 worker processes: wall time (target <= 2 min on 2 cores).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

from tli_verify.io import atomic_write_text, canonical_json


def _median(fn: object, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()  # type: ignore[operator]
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main(out_dir: Path) -> str:
    import threadpoolctl

    from tli_verify.experiments.scoop import ExperimentConfig, run_all
    from tli_verify.experiments.scoop_task import scoop_setup
    from tli_verify.runtime.episodes import random_perturbations, random_start, run_variant_batch
    from tli_verify.runtime.loop import run_episode
    from tli_verify.runtime.setup import make_policy
    from tli_verify.runtime.task_sensors import TaskSensors

    load = os.getloadavg()[0]  # other processes' load makes every timing below slower
    setup = scoop_setup()
    task = setup.task
    with threadpoolctl.threadpool_limits(1):
        # one episode of 2,000 steps
        policy = make_policy(setup, "LTL-DS")
        pushes = {150: np.array([6.0, 6.0]), 900: np.array([-9.0, 2.0]),
                  1500: np.array([0.0, -10.0])}
        lo, hi = np.array(task.lo), np.array(task.hi)

        def push(t: int, x: np.ndarray) -> np.ndarray | None:
            d = pushes.get(t)
            return None if d is None else np.clip(x + d, lo, hi)

        def episode() -> None:
            res = run_episode(policy.fork(), TaskSensors(task), [-5.0, 4.0], steps=2000,
                              perturb=push, stop_at_goal=False)
            assert res.steps == 2000

        episode()
        one = _median(episode, 7)
        # batched vs per-step loop
        rng = np.random.default_rng(0)
        N = 200
        starts = np.array([random_start(task, setup.automaton, rng) for _ in range(N)])
        perts = [random_perturbations(rng, 2, task) for _ in range(N)]
        t0 = time.perf_counter()
        res = run_variant_batch(setup, "LTL-DS", starts, perts, steps=3000)
        t_batch = time.perf_counter() - t0
        steps_batch = sum(r.steps for r in res)
        M = 20
        t0 = time.perf_counter()
        steps_loop = 0
        agree = 0
        for i in range(M):
            table = perts[i]

            def p1(t: int, x: np.ndarray, table: dict[int, np.ndarray] = table
                   ) -> np.ndarray | None:
                d = table.get(t)
                return None if d is None else np.clip(x + d, lo, hi)

            r = run_episode(policy.fork(), TaskSensors(task), starts[i], steps=3000,
                            perturb=p1)
            steps_loop += r.steps
            agree += int(r.success == res[i].success)
        t_loop = time.perf_counter() - t0
    # the experiment, 2 workers
    t0 = time.perf_counter()
    summary = run_all(ExperimentConfig(), workers=2, fig7_tries=200)
    t_exp = time.perf_counter() - t0
    data = {
        "episode_2000_steps_s": one,
        "batched": {"episodes": N, "steps": steps_batch, "seconds": t_batch,
                    "steps_per_s": steps_batch / t_batch},
        "loop": {"episodes": M, "steps": steps_loop, "seconds": t_loop,
                 "steps_per_s": steps_loop / t_loop, "same_outcome_as_batched": agree},
        "load_average_1min": load, "cpus": os.cpu_count(),
        "experiment": {"seconds": t_exp, "workers": 2,
                       "success_percent": {v: t["percent"]
                                           for v, t in summary["totals"].items()}},
    }
    atomic_write_text(out_dir / "run.json", canonical_json(data))
    sp = data["experiment"]["success_percent"]
    return (
        "## Closed loop on the scoop task (`bench_run`)\n\n"
        "| measurement | value | target |\n|---|---:|---:|\n"
        f"| one episode, 2,000 steps (`run_episode`, median of 7) | {one * 1e3:.1f} ms "
        "| <= 50 ms |\n"
        f"| {N} episodes batched across starts (`run_episodes`) | "
        f"{data['batched']['steps_per_s']:,.0f} steps/s ({steps_batch:,} steps, "
        f"{t_batch:.2f} s) | >= 100,000 steps/s |\n"
        f"| per-step Python loop, one episode at a time ({M} episodes) | "
        f"{data['loop']['steps_per_s']:,.0f} steps/s (same outcome as batched: {agree}/{M}) "
        "| (baseline) |\n"
        f"| `tli experiment scoop` (10 x 100 episodes x 4 variants + Fig. 7 search), 2 "
        f"workers | {t_exp:.1f} s | <= 120 s |\n\n"
        "Success %: " + ", ".join(f"{v} {p:.1f}" for v, p in sp.items()) + ".\n\n"
        f"Measured with a 1-minute load average of {load:.2f} on {os.cpu_count()} CPU(s) at "
        "the start (other processes' load slows every timing).\n"
        + "\n<!-- " + json.dumps({"batched_vs_loop": data['batched']['steps_per_s']
                                 / data['loop']['steps_per_s']}) + " -->\n"
    )
