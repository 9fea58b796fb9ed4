"""The multi-modal soup-scooping experiment: the four policies on the same perturbed episodes.

:func:`run_experiment` learns and certifies one scoop model from 1-3 seeded demonstrations
(:func:`tli_verify.experiments.scoop_task.learn_setup`) and runs every policy variant
(:data:`tli_verify.runtime.setup.VARIANTS`: LTL-DS, no-modulation, no-replan, BC) on the same
perturbed episodes (:func:`tli_verify.runtime.episodes.random_perturbations`, batched with
:func:`~tli_verify.runtime.episodes.run_variant_batch`), counting the Fig. 7 loops
(:func:`tli_verify.experiments.fig7.is_fig7_loop`); :func:`run_all` runs the experiments of an
:class:`ExperimentConfig` (and the Fig. 7 search) in a process pool and totals them per variant.
The generic closed loop is :mod:`tli_verify.runtime.setup` and :mod:`tli_verify.runtime.episodes`.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 7.2, Fig. 7 and appendix "Multi-modal
Experiments".
"""

from __future__ import annotations

import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.experiments.fig7 import fig7_search, is_fig7_loop
from tli_verify.experiments.scoop_task import learn_setup
from tli_verify.runtime.episodes import random_perturbations, random_start, run_variant_batch
from tli_verify.runtime.setup import VARIANTS, Setup

__all__ = [
    "ExperimentConfig",
    "run_all",
    "run_experiment",
]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class ExperimentConfig:
    """The multi-modal experiment (paper appendix "Multi-modal Experiments").

    Attributes
    ----------
    experiments : int
        Learned models (10 in the paper), each from 1-3 demonstrations.
    episodes : int
        Perturbed episodes per experiment and variant (>= 100).
    max_perturbations : int
        Each episode gets 1..this many perturbations (paper Asm. 2: finitely many).
    steps : int
        Step budget per episode (at dt = 1/100 s).
    bc_epochs : int
        BC training epochs (paper: at most 5000).
    seed : int
    lag : int
        Sensor lag of the world (steps).
    """

    experiments: int = 10
    episodes: int = 100
    max_perturbations: int = 3
    steps: int = 3000
    bc_epochs: int = 300
    seed: int = 0
    lag: int = 0


def _episode_plan(cfg: ExperimentConfig, exp: int, setup: Setup
                  ) -> tuple[FloatArray, list[dict[int, FloatArray]]]:
    rng = np.random.default_rng([cfg.seed, exp, 1])
    starts = np.array([random_start(setup.task, setup.automaton, rng)
                       for _ in range(cfg.episodes)])
    perts = [random_perturbations(rng, int(rng.integers(1, cfg.max_perturbations + 1)),
                                  setup.task)
             for _ in range(cfg.episodes)]
    return starts, perts


def run_experiment(cfg: ExperimentConfig, exp: int) -> dict[str, Any]:
    """One experiment: learn + certify from 1-3 seeded demonstrations, then every variant on
    the same perturbed episodes. Returns a JSON-ready record."""
    t0 = time.perf_counter()
    n_demos = 1 + (cfg.seed + exp) % 3
    with tempfile.TemporaryDirectory(prefix="tli-scoop-") as tmp:
        setup = learn_setup(cfg.seed * 1000 + exp, n_demos, tmp, lag=cfg.lag,
                            bc_epochs=cfg.bc_epochs)
        starts, perts = _episode_plan(cfg, exp, setup)
        out: dict[str, Any] = {"experiment": exp, "demos": n_demos, "variants": {}}
        for variant in VARIANTS:
            res = run_variant_batch(setup, variant, starts, perts, steps=cfg.steps)
            out["variants"][variant] = {
                "success": sum(r.success for r in res),
                "episodes": len(res),
                "cuts_mean": float(np.mean([r.cuts_added for r in res])),
                "steps": int(sum(r.steps for r in res)),
                "loops": sum(is_fig7_loop(r, cfg.steps) for r in res),
            }
    out["seconds"] = time.perf_counter() - t0
    return out


def _run_one(args: tuple[Any, ...]) -> dict[str, Any]:
    import threadpoolctl

    with threadpoolctl.threadpool_limits(1):
        if args[0] == "fig7":
            return fig7_search(*args[1:])
        return run_experiment(*args)


def run_all(cfg: ExperimentConfig, *, workers: int = 2, fig7_tries: int = 0
            ) -> dict[str, Any]:
    """Every experiment (a process pool of ``workers``) and the totals per variant.

    With ``fig7_tries > 0`` the Fig. 7 search
    (:func:`~tli_verify.experiments.fig7.fig7_search`) runs as one more job of the pool; its
    result is under ``"fig7"`` (with the episodes, not JSON-ready).
    """
    t0 = time.perf_counter()
    jobs: list[tuple[Any, ...]] = [(cfg, e) for e in range(cfg.experiments)]
    if fig7_tries > 0:
        jobs.insert(0, ("fig7", cfg.seed, fig7_tries, cfg.steps, cfg.lag))
    if workers <= 1:
        done = [_run_one(j) for j in jobs]
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            done = list(pool.map(_run_one, jobs))
    fig7 = done.pop(0) if fig7_tries > 0 else None
    rows = done
    totals = {}
    for v in VARIANTS:
        ok = sum(r["variants"][v]["success"] for r in rows)
        n = sum(r["variants"][v]["episodes"] for r in rows)
        totals[v] = {"success": ok, "episodes": n, "percent": 100.0 * ok / max(n, 1),
                     "loops": sum(r["variants"][v]["loops"] for r in rows),
                     "per_experiment": [100.0 * r["variants"][v]["success"]
                                        / max(r["variants"][v]["episodes"], 1) for r in rows],
                     "policy_steps": sum(r["variants"][v]["steps"] for r in rows)}
    return {"config": {f: getattr(cfg, f) for f in cfg.__dataclass_fields__},
            "workers": workers, "seconds": time.perf_counter() - t0,
            "experiments": rows, "totals": totals, "fig7": fig7}
