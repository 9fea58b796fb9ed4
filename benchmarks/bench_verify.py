"""Bisimulation campaigns (``tli verify``): throughput and search efficiency.

Side by side in one run:

- 1,000 perturbed scoop runs (LTL-DS, the shipped model and certificate, up to 3 perturbations
  in steps 1..700, batches of 100): wall time of the whole campaign (drawing, simulation,
  oracle) on 2 worker processes (target <= 20 s on 2 cores), and runs/s on 1 and 2 processes;
  a Dask column (``make_backend("dask")`` on a ``LocalCluster`` of 2 workers) when
  ``tli_verify.verify.dask_backend`` exists, else "n/a";
- Fig. 7 (the unmodulated system looping a -> b -> a -> b): over 10 seeds, the simulations
  until the first counterexample of the campaign's hypothesis drawing (generation order), next
  to plain random sampling (:func:`tli_verify.runtime.episodes.random_perturbations`: 1-3
  perturbations, uniform directions, magnitudes up to the workspace size) on the same budget;
  the median for "any violation" and for "looping" (target median <= 50 for looping).
"""

from __future__ import annotations

import json
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from tli_verify.io import atomic_write_text, canonical_json

RUNS = 1000
SEEDS = 10
BUDGET = 200


def _campaign(backend: str, workers: int, *, examples: int = RUNS, modulation: bool = True,
              seed: int = 0) -> Any:
    from tli_verify.verify.campaign import run_campaign
    from tli_verify.verify.config import CampaignConfig

    return run_campaign(CampaignConfig(task="scoop", examples=examples, seed=seed,
                                       modulation=modulation, workers=workers,
                                       backend=backend, batch_size=100, shrink=False))


def _first(outcomes: Any, kind: str | None) -> int | None:
    for o in outcomes:
        kinds = {k.value for k in o.verdict.kinds}
        if (kind is None and kinds) or (kind is not None and kind in kinds):
            return int(o.index) + 1
    return None


def _random_sampling(seed: int) -> tuple[int | None, int | None]:
    """Plain random perturbations of the nominal run, in order, same budget."""
    from tli_verify.runtime.episodes import random_perturbations
    from tli_verify.verify.config import CampaignConfig, sim_spec
    from tli_verify.verify.simulate import RunOutcome, load, simulate_batch
    from tli_verify.verify.strategies import Case, Push

    spec = sim_spec(CampaignConfig(task="scoop", modulation=False))
    task = load(spec).task
    rng = np.random.default_rng([seed, 12])
    items = []
    for i in range(BUDGET):
        table = random_perturbations(rng, int(rng.integers(1, 4)), task)
        pushes = tuple(Push(t, tuple(float(v) for v in d)) for t, d in sorted(table.items()))
        items.append((i, Case(task.starts.nominal[0], pushes)))
    outs: list[RunOutcome] = []
    for k in range(0, BUDGET, 100):
        outs += simulate_batch((spec, items[k:k + 100]))
    return _first(outs, None), _first(outs, "looping")


def _median(xs: list[int | None]) -> str:
    got = [x for x in xs if x is not None]
    if not got:
        return f"none in {BUDGET}"
    med = statistics.median([x if x is not None else BUDGET + 1 for x in xs])
    miss = len(xs) - len(got)
    return f"{med:g}" + (f" ({miss} of {len(xs)} seeds: none in {BUDGET})" if miss else "")


def main(out_dir: Path) -> str:
    import os

    data: dict[str, Any] = {}
    load_before = os.getloadavg()[0]
    # CPU cost per run, in this process (independent of what else the machine runs)
    from tli_verify.verify.config import CampaignConfig, resolve_config, sim_spec
    from tli_verify.verify.draws import config_strategy, draw_cases
    from tli_verify.verify.simulate import load
    from tli_verify.verify.simulate import simulate_batch as _batch

    _, filled = resolve_config(CampaignConfig(task="scoop"))
    spec = sim_spec(filled)
    ld = load(spec)
    strategy = config_strategy(filled, ld)
    c0 = time.process_time()
    sample = draw_cases(strategy, 200, 0)
    draw_cpu = (time.process_time() - c0) / len(sample)
    c0 = time.process_time()
    _batch((spec, list(enumerate(sample))))
    sim_cpu = (time.process_time() - c0) / len(sample)
    data["cpu_per_run_s"] = {"draw": draw_cpu, "simulate_and_check": sim_cpu}
    # throughput
    t0 = time.perf_counter()
    r2 = _campaign("process", 2)
    wall2 = time.perf_counter() - t0
    t0 = time.perf_counter()
    _campaign("process", 1)
    wall1 = time.perf_counter() - t0
    data["runs"] = RUNS
    data["process_2"] = {"seconds": wall2, "runs_per_s": RUNS / wall2,
                         "violations": r2.violations}
    data["process_1"] = {"seconds": wall1, "runs_per_s": RUNS / wall1}
    try:
        import tli_verify.verify.dask_backend  # type: ignore[import-not-found,unused-ignore]  # noqa: F401

        t0 = time.perf_counter()
        _campaign("dask", 2)
        walld = time.perf_counter() - t0
        dask_cell = f"{RUNS / walld:.0f} runs/s ({walld:.1f} s)"
        data["dask_2"] = {"seconds": walld, "runs_per_s": RUNS / walld}
    except ImportError:
        dask_cell = "n/a (tli_verify.verify.dask_backend not present)"
    # Fig. 7 search efficiency
    hyp_any, hyp_loop, rnd_any, rnd_loop = [], [], [], []
    for seed in range(SEEDS):
        res = _campaign("process", 2, examples=BUDGET, modulation=False, seed=seed)
        hyp_any.append(_first(res.outcomes, None))
        hyp_loop.append(_first(res.outcomes, "looping"))
        a, lp = _random_sampling(seed)
        rnd_any.append(a)
        rnd_loop.append(lp)
    load_after = os.getloadavg()[0]
    data["load_average"] = [load_before, load_after]
    data["fig7"] = {"budget": BUDGET, "seeds": SEEDS, "hypothesis_any": hyp_any,
                    "hypothesis_looping": hyp_loop, "random_any": rnd_any,
                    "random_looping": rnd_loop}
    atomic_write_text(out_dir / "verify.json", canonical_json(data))
    return (
        "## Bisimulation campaigns (`bench_verify`)\n\n"
        f"{RUNS} perturbed scoop runs (LTL-DS, up to 3 perturbations in steps 1..700, batches "
        "of 100; drawing + simulation + oracle, wall time of `run_campaign`):\n\n"
        "| backend | wall time | runs/s | target |\n|---|---:|---:|---:|\n"
        f"| 2 processes | {wall2:.1f} s | {RUNS / wall2:.0f} | <= 20 s |\n"
        f"| 1 process | {wall1:.1f} s | {RUNS / wall1:.0f} | |\n"
        f"| Dask LocalCluster, 2 workers | {dask_cell} | | |\n\n"
        f"CPU time per run (one core, in-process): drawing {draw_cpu * 1e3:.1f} ms (driver), "
        f"simulation + oracle {sim_cpu * 1e3:.1f} ms (worker), i.e. "
        f"{1 / sim_cpu:.0f} runs/s per worker core. Load average of the machine during the "
        f"measurement: {load_before:.1f} -> {load_after:.1f} (2 cores; wall times above "
        "include it).\n\n"
        f"Fig. 7 without modulation: simulations until the first counterexample, median over "
        f"{SEEDS} seeds, budget {BUDGET} runs each:\n\n"
        "| search | any violation | looping (Fig. 7) | target |\n|---|---:|---:|---:|\n"
        f"| `tli verify` (hypothesis, seeded) | {_median(hyp_any)} | {_median(hyp_loop)} "
        "| <= 50 (looping) |\n"
        f"| plain random perturbations | {_median(rnd_any)} | {_median(rnd_loop)} | |\n"
        + "\n<!-- " + json.dumps({"per_seed": data["fig7"]}) + " -->\n"
    )
