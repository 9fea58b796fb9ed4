"""The multi-modal soup-scooping experiment (paper Sec. 7.2, Fig. 7, appendix "Multi-modal
Experiments").

Pieces:

* :func:`scoop_setup` (the bundled ``tasks/scoop.toml`` with its spec, model and certificate,
  certified at ``dt = 1/100``) and :func:`learn_setup` (learn and certify from seeded
  demonstrations of the scoop task's scripted demonstrator);
* the four policies compared (:data:`tli_verify.runtime.setup.VARIANTS`: LTL-DS,
  no-modulation, no-replan, BC) on the same perturbed episodes
  (:func:`tli_verify.runtime.episodes.random_perturbations`);
* :func:`run_experiment` (one learned model, many perturbed episodes per variant, batched with
  :func:`~tli_verify.runtime.episodes.run_variant_batch`), :func:`run_all` (a process pool over
  experiments), :func:`fig7_search` / :func:`find_loop` (paper Fig. 7: the unmodulated system
  loops a -> b -> a ... until its budget, LTL-DS ends it with one cut; :func:`fig7_record`,
  :func:`plot_fig7`), the Markdown report and figures.

This module is the paper's scoop study and names the scoop task on purpose; the generic
closed loop is :mod:`tli_verify.runtime.setup` and :mod:`tli_verify.runtime.episodes`.
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Mapping
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TliError
from tli_verify.runtime.episodes import (
    mode_runs,
    mode_string,
    random_perturbations,
    random_start,
    run_variant,
    run_variant_batch,
)
from tli_verify.runtime.events import CutAdded, InvarianceFailure
from tli_verify.runtime.executive import EpisodeResult
from tli_verify.runtime.setup import VARIANTS, Setup, load_setup
from tli_verify.tasks.task import Task

__all__ = [
    "CERT_DT",
    "FIG7_MIN_ROUNDS",
    "NOMINAL_START",
    "ExperimentConfig",
    "b_to_a_failures",
    "fig7_record",
    "fig7_search",
    "find_loop",
    "is_fig7_loop",
    "is_fig7_rescue",
    "learn_setup",
    "plot_fig7",
    "run_all",
    "run_experiment",
    "scoop_setup",
    "write_report",
]

FloatArray = npt.NDArray[np.float64]
CERT_DT = "1/100"
"""Control period the scoop models are certified for (and the loops run at)."""


def scoop_setup(*, lag: int = 0) -> Setup:
    """The bundled scoop task, spec, model and certificate (:func:`~tli_verify.tasks.project.
    resolve` of task ``scoop``)."""
    from tli_verify.tasks.project import resolve

    return load_setup(resolve(task="scoop", lag=lag))


def learn_setup(seed: int, n_demos: int, directory: str | os.PathLike[str], *,
                lag: int = 0, bc_epochs: int = 0) -> Setup:
    """Learn and certify a scoop model from ``n_demos`` seeded demonstrations.

    Writes ``scoop_<i>.csv``, ``scoop.model.json`` and ``scoop.cert.json`` (at ``dt = 1/100``)
    under ``directory``; with ``bc_epochs > 0`` also trains one BC net per DS key on the raw
    (unshifted) segments of its mode.
    """
    from tli_verify.certify.certificate import issue_certificate, write_certificate
    from tli_verify.logic.check import synthesize
    from tli_verify.logic.spec import load_spec
    from tli_verify.model import learn_model, load_model, save_model
    from tli_verify.tasks.demonstrator import write_demos
    from tli_verify.tasks.registry import find_task

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    task = find_task("scoop")
    spec_path = task.spec_path
    assert spec_path is not None
    demos = write_demos(task, d, seed=seed, n_demos=n_demos)
    mpath, cpath = d / "scoop.model.json", d / "scoop.cert.json"
    model = learn_model(demos, out_path=mpath, spec_path=spec_path, seed=seed,
                        control_dt=0.01)
    save_model(model, mpath)
    write_certificate(issue_certificate(mpath, cert_path=cpath, dt=CERT_DT), cpath)
    spec = load_spec(spec_path)
    bc: dict[str, Any] = {}
    if bc_epochs > 0:
        from tli_verify.demos import load_demo
        from tli_verify.ds.bc import train_bc
        from tli_verify.segmentation import segment_demos, spec_labeler

        labeler, modes, labels = spec_labeler(spec)
        seg = segment_demos([load_demo(p) for p in demos], labeler=labeler, modes=modes,
                            labels=labels, shift=False)
        for key, data in seg.data.items():
            bc[key] = train_bc(data.x, data.dx, seed=seed, max_epochs=bc_epochs)
    return Setup(task=task.with_lag(lag), automaton=synthesize(spec), model=load_model(mpath),
                 certificate=str(cpath), spec=str(spec_path), bc=bc)


# ----------------------------------------------------------------------------- experiment
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

    With ``fig7_tries > 0`` the Fig. 7 search (:func:`fig7_search`) runs as one more job of
    the pool; its result is under ``"fig7"`` (with the episodes, not JSON-ready).
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


def fig7_search(seed: int, tries: int, steps: int, lag: int = 0) -> dict[str, Any]:
    """The Fig. 7 search on the shipped model (:func:`find_loop`), in two stages.

    1. Perturbations of the nominal run: from :data:`NOMINAL_START`, ``tries`` seeded single
       random perturbations (:func:`random_perturbations` within the nominal run's steps,
       displacements rounded to 0.01 so the case replays from the command line).
    2. If none loops: ``tries`` seeded random starts (reading ``a``), unperturbed.

    Returns
    -------
    dict
        ``{"lag", "stage", "tries", "seed", "found", "text"}``; ``found`` is :func:`find_loop`'s
        record (with the episodes, not JSON-ready; :func:`fig7_record` makes it so) or None.
    """
    setup = scoop_setup(lag=lag)
    tried = []
    for stage, start in (("perturbed nominal run", NOMINAL_START), ("random start", None)):
        f = find_loop(setup, seed=seed, tries=tries, steps=steps, start=start,
                      perturbations=1 if start is not None else 0)
        tried.append(f"{stage}: {tries} tries, " + ("none" if f is None else
                                                    f"found at try {f['index']}"))
        if f is not None:
            return {"lag": lag, "stage": stage, "tries": tries, "seed": seed, "found": f,
                    "text": _fig7_text(f, lag, stage, tries)}
    return {"lag": lag, "stage": None, "tries": tries, "seed": seed, "found": None,
            "text": f"Fig. 7 NOT found (seed {seed}, sensor lag {lag}): no try made the "
                    f"unmodulated system loop a -> b -> a ... (>= {FIG7_MIN_ROUNDS} b -> a "
                    "failures) until its step budget ran out while LTL-DS reached d after "
                    "exactly one cut (" + "; ".join(tried) + ")."}


def _replay_args(f: Mapping[str, Any]) -> str:
    """The ``tli run`` arguments that replay a Fig. 7 case (start, perturbations)."""
    x0 = ",".join(repr(float(v)) for v in f["start"])
    parts = [f"--start={x0}"]
    for t, d in sorted(f["perturbations"].items()):
        parts.append(f"--perturb {int(t)}:" + ",".join(repr(float(v)) for v in d))
    return " ".join(parts)


def _fig7_text(f: Mapping[str, Any], lag: int, stage: str, tries: int) -> str:
    p, r = f["no_modulation"], f["ltl_ds"]
    seq_p = mode_string(p)
    return (f"Fig. 7 reproduced ({stage}, try {f['index']} of {tries}, sensor lag {lag}): from "
            f"{np.round(f['start'], 2).tolist()} with {len(f['perturbations'])} "
            f"perturbation(s), without modulation the modes run {seq_p[:12]}... -- mode b's DS "
            "leaves the soup back into white (a b -> a invariance failure) and a's DS brings "
            f"the spoon straight back, {f['loops']} times, until the budget of {p.steps} "
            f"steps runs out; LTL-DS runs {mode_string(r)}: the first b -> a failure adds "
            f"{r.cuts_added} cut to mode b, which is never crossed again, and d is reached at "
            f"step {r.steps}. Replay: tli run --task scoop {_replay_args(f)} "
            "[--no-modulation].")


# ----------------------------------------------------------------------------- Fig. 7 search
NOMINAL_START = np.array([-5.0, 4.0])
"""The documented start of the nominal scoop run (white, upper left; reaches d unperturbed)."""
FIG7_MIN_ROUNDS = 5
"""A Fig. 7 loop: at least this many ``b -> a`` invariance failures without modulation."""


def b_to_a_failures(res: EpisodeResult) -> int:
    """Number of ``b -> a`` invariance failures (the scooping DS leaving the soup into white)."""
    return sum(1 for e in res.events
               if isinstance(e, InvarianceFailure) and (e.mode, e.to_mode) == ("b", "a"))


def is_fig7_loop(res: EpisodeResult, budget: int, *,
                 min_rounds: int = FIG7_MIN_ROUNDS) -> bool:
    """Fig. 7's top row: no ``d`` within the whole step budget, at least ``min_rounds``
    ``b -> a`` invariance failures, and still looping ``a -> b -> a ...`` at the end (the last
    ``2 * min_rounds`` modes of the run-length mode sequence are a and b, so they alternate)."""
    tail = mode_string(res)[-2 * min_rounds:]
    return (not res.success and res.steps == budget
            and b_to_a_failures(res) >= min_rounds
            and len(tail) == 2 * min_rounds and set(tail) == {"a", "b"})


def is_fig7_rescue(res: EpisodeResult) -> bool:
    """Fig. 7's LTL-DS rows: ``d`` reached after exactly one invariance failure, ``b -> a``,
    and the one cut it produced (for mode b)."""
    fails = [e for e in res.events if isinstance(e, InvarianceFailure)]
    cuts = [e for e in res.events if isinstance(e, CutAdded)]
    return (res.success and res.cuts_added == 1 and len(fails) == 1
            and (fails[0].mode, fails[0].to_mode) == ("b", "a")
            and len(cuts) == 1 and cuts[0].mode == "b")


def _rounded_perturbations(rng: np.random.Generator, count: int, world: Task, *,
                           last: int) -> dict[int, FloatArray]:
    table = random_perturbations(rng, count, world, last=last)
    return {t: np.array([float(f"{v:.2f}") for v in d]) for t, d in table.items()}


def find_loop(setup: Setup, *, seed: int = 0, tries: int = 200, steps: int = 3000,
              start: npt.ArrayLike | None = None, perturbations: int = 1,
              verify: int = 20, min_rounds: int = FIG7_MIN_ROUNDS) -> dict[str, Any] | None:
    """Search seeded episodes for Fig. 7 (top row vs. second row).

    Fig. 7: without modulation the system loops ``a -> b -> a -> b ...`` (mode b's DS leaves
    the soup back into white, a's DS brings the spoon back, again and again) until its step
    budget runs out (:func:`is_fig7_loop`); LTL-DS reaches ``d`` after the one cut that the
    first ``b -> a`` failure produces (:func:`is_fig7_rescue`).

    Each try is ``start`` (default: a seeded random start reading ``a``) with ``perturbations``
    seeded random perturbations (within the unperturbed run's steps from a given ``start``,
    else within 700 steps; displacements rounded to 0.01), run without modulation (batched);
    LTL-DS runs on the first ``verify`` tries that loop, in order.

    Returns
    -------
    dict or None
        ``{"start", "perturbations", "index", "loops", "no_modulation", "ltl_ds"}`` of the
        first try that loops without modulation and is rescued by LTL-DS; None if none is.
    """
    rng = np.random.default_rng([seed, 7])
    if start is not None:
        x0 = np.asarray(start, dtype=np.float64)
        last = max(1, run_variant(setup, "no-modulation", x0, {}, steps=steps).steps)
        starts = np.tile(x0, (tries, 1))
    else:
        last = 700
        starts = np.array([random_start(setup.task, setup.automaton, rng)
                           for _ in range(tries)])
    perts = [_rounded_perturbations(rng, perturbations, setup.task, last=last)
             if perturbations else {} for _ in range(tries)]
    plain = run_variant_batch(setup, "no-modulation", starts, perts, steps=steps)
    order = [i for i in range(tries) if is_fig7_loop(plain[i], steps, min_rounds=min_rounds)]
    order = order[:verify]
    if not order:
        return None
    ours = run_variant_batch(setup, "LTL-DS", starts[order], [perts[i] for i in order],
                             steps=steps)
    for i, r in zip(order, ours, strict=True):
        if is_fig7_rescue(r):
            return {"start": starts[i], "perturbations": perts[i], "index": i,
                    "loops": b_to_a_failures(plain[i]), "no_modulation": plain[i],
                    "ltl_ds": r}
    return None


def fig7_record(search: Mapping[str, Any]) -> dict[str, Any]:
    """The JSON-ready Fig. 7 field of ``tli experiment scoop`` (from :func:`fig7_search`).

    ``found`` false: only the text. Otherwise the case (seed, stage, try, start,
    perturbations, the ``tli run`` replay arguments) and both episodes: the unmodulated one
    (mode sequence and run-length trace, ``b -> a`` failures, budget exhausted) and LTL-DS's
    (trace, its invariance failure and the cut it added).
    """
    from tli_verify.runtime.events import event_to_json

    out: dict[str, Any] = {"text": search["text"], "lag": search["lag"],
                           "found": search["found"] is not None, "seed": search["seed"],
                           "tries": search["tries"], "stage": search["stage"]}
    f = search["found"]
    if f is None:
        return out
    p, r = f["no_modulation"], f["ltl_ds"]
    out.update({
        "index": int(f["index"]),
        "start": [float(v) for v in f["start"]],
        "perturbations": [{"step": int(t), "displacement": [float(v) for v in d]}
                          for t, d in sorted(f["perturbations"].items())],
        "replay": f"tli run --task scoop {_replay_args(f)}",
        "no_modulation": {
            "success": bool(p.success), "steps": int(p.steps),
            "budget_exhausted": bool(not p.success),
            "b_to_a_failures": b_to_a_failures(p),
            "ab_rounds": mode_string(p).count("ab"),
            "mode_sequence": mode_string(p),
            "mode_trace": mode_runs(p.modes),
        },
        "ltl_ds": {
            "success": bool(r.success), "steps": int(r.steps),
            "cuts_added": int(r.cuts_added),
            "mode_sequence": mode_string(r),
            "mode_trace": mode_runs(r.modes),
            "events": [event_to_json(e) for e in r.events
                       if isinstance(e, InvarianceFailure | CutAdded)],
        },
    })
    return out


def plot_fig7(task: Task, search: Mapping[str, Any],
              path: str | os.PathLike[str]) -> None:
    """Fig. 7-style picture of a case :func:`fig7_search` found (PNG, atomic).

    Three panels (:func:`tli_verify.viz.episodes.plot_episodes`): the unmodulated run looping
    until its budget, its last 400 steps zoomed on the loop at the soup's surface, and LTL-DS
    with the cut it added (blue); the unperturbed run from the same start is dashed grey.

    Raises
    ------
    TliError
        The search found no case.
    """
    from tli_verify.viz.episodes import plot_episodes

    f = search["found"]
    if f is None:
        raise TliError("no Fig. 7 case to draw (the search found none)")
    p, r = f["no_modulation"], f["ltl_ds"]
    nominal = None
    if f["perturbations"]:
        nominal = run_variant(scoop_setup(lag=search["lag"]), "no-modulation", f["start"],
                              {}, steps=p.steps)
    plot_episodes(task, [("no modulation", p), ("LTL-DS", r)], path, nominal=nominal,
                  zoom_first=True, goal_label="d",
                  title=f"Fig. 7: without modulation a -> b -> a ... until the budget "
                        f"({b_to_a_failures(p)} b -> a failures in {p.steps} steps); LTL-DS "
                        "cuts the first b -> a failure (blue) and reaches d")


# ----------------------------------------------------------------------------- report
def write_report(summary: Mapping[str, Any], out: Path, *, fig7: Mapping[str, Any] | None,
                 fig7_png: Path | None) -> list[Path]:
    """``scoop.json``, ``scoop.md`` and ``scoop_success.png`` under ``out`` (atomic)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tli_verify.io import atomic_write_text, canonical_json
    from tli_verify.plotting import save_figure

    out.mkdir(parents=True, exist_ok=True)
    cfg = summary["config"]
    tot = summary["totals"]
    lines = [
        "# Multi-modal soup-scooping experiment (paper Sec. 7.2, appendix \"Multi-modal "
        "Experiments\")", "",
        f"{cfg['experiments']} experiments (each: LPV-DS learned and certified at dt = 1/100 "
        f"from 1-3 seeded demonstrations of the scoop world), {cfg['episodes']} perturbed "
        f"episodes per experiment and variant, 1-{cfg['max_perturbations']} perturbations per "
        "episode in uniformly random directions with magnitudes uniform up to the workspace "
        f"size (16), step budget {cfg['steps']} (dt = 0.01 s), sensor lag {cfg['lag']}, "
        f"seed {cfg['seed']}. Wall time {summary['seconds']:.1f} s on {summary['workers']} "
        "worker(s).", "",
        "| variant | success | episodes | success % | per experiment (%) | Fig. 7 loops |",
        "|---|---:|---:|---:|---|---:|",
    ]
    for v in VARIANTS:
        t = tot[v]
        per = ", ".join(f"{p:.0f}" for p in t["per_experiment"])
        lines.append(f"| {v} | {t['success']} | {t['episodes']} | {t['percent']:.1f} | {per} "
                     f"| {t['loops']} |")
    lines += ["", "Variants: **LTL-DS** = task automaton + certified DS per mode + cuts "
              "learned online + replanning; **no-modulation** = the same without cuts; "
              "**no-replan** = the demonstrated mode sequence run open loop (cuts kept); "
              "**BC** = the paper's MLP per mode under the automaton (replanning, cuts). "
              f"**Fig. 7 loops**: episodes still looping a -> b -> a ... (>= {FIG7_MIN_ROUNDS} "
              "b -> a invariance failures) when the step budget ran out.", ""]
    if fig7 is not None:
        lines += ["## Fig. 7", "", fig7["text"], ""]
        if fig7_png is not None:
            lines += [f"![Fig. 7]({fig7_png.name})", ""]
    md = out / "scoop.md"
    js = out / "scoop.json"
    png = out / "scoop_success.png"
    atomic_write_text(md, "\n".join(lines) + "\n")
    atomic_write_text(js, canonical_json(dict(summary)))
    fig, ax = plt.subplots(figsize=(5.0, 3.2))
    vals = [tot[v]["percent"] for v in VARIANTS]
    ax.bar(VARIANTS, vals, color=["tab:blue", "tab:orange", "tab:green", "tab:red"])
    for i, v in enumerate(vals):
        ax.text(i, v + 1, f"{v:.0f}%", ha="center", fontsize=8)
    ax.set_ylim(0, 110)
    ax.set_ylabel("success %")
    ax.set_title("scoop: perturbed episodes reaching d", fontsize=9)
    fig.tight_layout()
    save_figure(fig, png, dpi=90)
    return [md, js, png]
