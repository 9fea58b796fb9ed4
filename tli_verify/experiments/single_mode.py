"""The paper's single-mode study (Sec. 7.1, Figs. 5-6, appendix E), reproduced.

Protocol (one *trial* = one random convex mode):

1. Draw a convex polygon mode, an attractor inside it and 1-3 synthetic demonstrations
   (:func:`tli_verify.tasks.generate.make_task`).
2. Learn an LPV-DS (:func:`tli_verify.ds.lpvds.learn_lpvds`) and the BC baseline
   (:func:`tli_verify.ds.bc.train_bc`) from the demonstrations.
3. For each noise level (0%, 5%, 30% of the workspace side) draw 100 start states: demonstrated
   states plus Gaussian noise, redrawn until they lie in the mode ("sampling with large noise
   corresponds to sampling from the entire mode region").
4. Roll out every policy from the starts: explicit Euler, ``dt = 0.01``, 1000 steps, speed capped
   at 20, goal tolerance 0.4 (the protocol of the authors' MATLAB code). A rollout succeeds iff
   it reaches the goal before it ever leaves the mode.
5. BC+mod and DS+mod: while some rollout leaves the mode, pick one such *invariance failure*
   at random (seeded), solve its cut (:func:`tli_verify.boundary.cuts.solve_cut`, keeping earlier
   cut points inside), add it, re-roll all starts with the modulated policy
   (:func:`tli_verify.boundary.modulation.modulated`: eq. 7 with the corner guard, told the
   Euler step ``dt`` so that no step crosses a cut); stop when no rollout leaves the mode or
   after ``max_cuts`` cuts. The success rate after each cut gives the curve of paper Fig. 6
   (right); the rate with the final cuts is the table entry.

Success is measured on the same starts the cuts were learned from, as in the paper. We also
report it on 100 fresh *held-out* starts per noise level (same distribution), with the final
cuts, which the paper does not.

Rollouts and cut learning run on the runtime's engine (:mod:`tli_verify.runtime.rollout`,
:mod:`tli_verify.runtime.online`), the one the executive and the campaigns share; this module
keeps the study's configuration, process pool, statistics, report and figures.

Every trial is seeded by ``SeedSequence([seed, trial])``, so results do not depend on the number
of worker processes.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TliError
from tli_verify.logic.escape import markdown_text, markdown_url
from tli_verify.runtime.online import CutLearning
from tli_verify.runtime.online import learn_cuts as _learn_cuts
from tli_verify.runtime.rollout import EulerProtocol, Rollouts, rollout, rollout_protocol

__all__ = [
    "NOISE_PERCENT",
    "PAPER_TABLE",
    "POLICIES",
    "CutLearning",
    "Rollouts",
    "SingleModeConfig",
    "TrialResult",
    "learn_cuts",
    "markdown",
    "rollout",
    "run",
    "run_trial",
    "sample_starts",
    "summarize",
    "write_outputs",
]

FloatArray = npt.NDArray[np.float64]
Policy = Callable[[FloatArray], FloatArray]
# Rollouts, rollout and CutLearning live in the runtime engine (tli_verify.runtime) and are
# re-exported here for the study's callers.

NOISE_PERCENT: tuple[int, ...] = (0, 5, 30)
POLICIES: tuple[str, ...] = ("BC", "BC+mod", "DS", "DS+mod")
PAPER_TABLE: dict[str, dict[str, float]] = {
    "BC": {"0": 88.9, "5": 72.4, "30": 58.6},
    "BC+mod": {"0": 91.9, "5": 83.6, "30": 76.0},
    "DS": {"0": 100.0, "5": 97.0, "30": 86.9},
    "DS+mod": {"0": 100.0, "5": 100.0, "30": 100.0},
}
"""Paper Fig. 6 (left), success rates in percent."""


@dataclass(frozen=True, slots=True)
class SingleModeConfig:
    """Parameters of the study (defaults: the paper's protocol).

    Attributes
    ----------
    trials : int
        Random modes (50 in the paper).
    seed : int
        Master seed.
    starts : int
        Start states per noise level and trial (100).
    noise_percent : tuple of int
        Start noise, percent of the workspace side (0, 5, 30).
    workspace : float
        Side of the square workspace (20 units: 5% is a standard deviation of 1 unit).
    dt, steps, speed_cap, goal_tolerance : float, int, float, float
        Euler step, number of steps, speed limit, goal radius (0.01, 1000, 20, 0.4).
    max_cuts : int
        Cap on cuts per (policy, noise level) (20).
    cut_margin : float
        Separation margin of the cut QCQP (see :mod:`tli_verify.boundary.cuts`).
    cut_constraints : {"entries", "paper"}
        Which states a new cut keeps inside besides ``x*`` and the earlier cut points:
        ``"paper"`` -- the failure's own entry state ``x^0`` (appendix E.3 as written);
        ``"entries"`` -- every observed mode-entry state (all start states of the batch), which
        keeps every start inside the cuts (see ``docs/boundary.md`` for why this matters).
    ds_eps : float
        Stability margin of the LPV-DS, ``A_k^T P + P A_k <= -eps I`` (1e-3, the default of
        :func:`tli_verify.ds.lpvds.learn_lpvds`). A larger margin bounds the convergence time.
    bc_max_epochs : int
        Epoch limit of BC training (5000).
    heldout : bool
        Also evaluate on fresh start states.
    """

    trials: int = 50
    seed: int = 0
    starts: int = 100
    noise_percent: tuple[int, ...] = NOISE_PERCENT
    workspace: float = 20.0
    dt: float = 0.01
    steps: int = 1000
    speed_cap: float = 20.0
    goal_tolerance: float = 0.4
    max_cuts: int = 20
    cut_margin: float = 1e-3
    cut_constraints: str = "entries"
    ds_eps: float = 1e-3
    bc_max_epochs: int = 5000
    heldout: bool = True

    def validate(self) -> None:
        """Raise :class:`~tli_verify.errors.TliError` (exit code 2) on a bad parameter."""
        checks: list[tuple[bool, str]] = [
            (self.trials >= 1, f"trials must be >= 1, got {self.trials}"),
            (self.seed >= 0, f"seed must be >= 0, got {self.seed}"),
            (self.starts >= 1, f"starts must be >= 1, got {self.starts}"),
            (len(self.noise_percent) >= 1 and all(0 <= p <= 100 for p in self.noise_percent),
             f"noise levels must be percentages in [0, 100], got {self.noise_percent}"),
            (self.workspace > 0, "workspace must be positive"),
            (self.dt > 0 and self.steps >= 1, "dt must be positive and steps >= 1"),
            (self.speed_cap > 0 and self.goal_tolerance > 0,
             "speed cap and goal tolerance must be positive"),
            (self.max_cuts >= 0, f"max cuts must be >= 0, got {self.max_cuts}"),
            (0 < self.cut_margin < 1, "cut margin must be in (0, 1)"),
            (self.cut_constraints in ("entries", "paper"),
             f"cut constraints must be 'entries' or 'paper', got {self.cut_constraints!r}"),
            (bool(np.isfinite(self.ds_eps)) and self.ds_eps > 0,
             f"DS stability margin must be positive, got {self.ds_eps}"),
            (self.bc_max_epochs >= 1, "BC epochs must be >= 1"),
        ]
        for ok, message in checks:
            if not ok:
                raise TliError(message)


def _roll(
    config: SingleModeConfig,
    policy: Policy,
    starts: FloatArray,
    contains: Callable[[FloatArray], npt.NDArray[np.bool_]],
    goal: FloatArray,
    *,
    record: bool = False,
) -> Rollouts:
    return rollout_protocol(policy, starts, contains, goal, _protocol(config), record=record)


def sample_starts(
    states: npt.ArrayLike,
    contains: Callable[[FloatArray], npt.NDArray[np.bool_]],
    rng: np.random.Generator,
    *,
    count: int,
    std: float,
    max_rounds: int = 1000,
) -> FloatArray:
    """Start states: random demonstrated states plus ``N(0, std^2 I)``, redrawn until inside.

    Parameters
    ----------
    states : array_like, shape (M, n)
        Demonstrated states.
    contains : callable
        Mode sensor.
    rng : numpy.random.Generator
    count : int
    std : float
        Noise standard deviation (workspace units).
    max_rounds : int, optional
        Redraws before a start falls back to its (noise-free) demonstrated state.

    Returns
    -------
    ndarray, shape (count, n)
    """
    S = np.asarray(states, dtype=np.float64)
    base = S[rng.integers(0, S.shape[0], size=count)]
    out = base.copy()
    todo = np.ones(count, dtype=bool)
    for _ in range(max_rounds):
        idx = np.flatnonzero(todo)
        if idx.size == 0:
            break
        cand = base[idx] + std * rng.standard_normal((idx.size, S.shape[1]))
        ok = contains(cand)
        out[idx[ok]] = cand[ok]
        todo[idx[ok]] = False
    return out


def _protocol(config: SingleModeConfig) -> EulerProtocol:
    return EulerProtocol(dt=config.dt, steps=config.steps, speed_cap=config.speed_cap,
                         goal_tolerance=config.goal_tolerance)


def learn_cuts(
    base: Policy,
    starts: FloatArray,
    contains: Callable[[FloatArray], npt.NDArray[np.bool_]],
    attractor: FloatArray,
    rng: np.random.Generator,
    *,
    config: SingleModeConfig,
    lyapunov: FloatArray | None = None,
    record: bool = False,
) -> CutLearning:
    """Add cuts from sampled invariance failures one at a time (paper appendix E.1).

    The study's parameters around :func:`tli_verify.runtime.online.learn_cuts` (the engine
    the executive shares).

    Parameters
    ----------
    base : callable
        Nominal policy.
    starts : ndarray, shape (N, n)
    contains : callable
        Mode sensor.
    attractor : ndarray, shape (n,)
    rng : numpy.random.Generator
        Picks which failure to cut next.
    config : SingleModeConfig
    lyapunov : ndarray, shape (n, n), optional
        The DS's ``P`` (None for BC).
    record : bool, optional
        Record paths of the final rollouts.

    Returns
    -------
    CutLearning
    """
    return _learn_cuts(base, starts, contains, attractor, rng, protocol=_protocol(config),
                       max_cuts=config.max_cuts, cut_margin=config.cut_margin,
                       cut_constraints=config.cut_constraints, lyapunov=lyapunov,
                       record=record)


@dataclass(frozen=True, slots=True)
class TrialResult:
    """Numbers of one trial (one random mode); all keys of the dicts are strings.

    Attributes
    ----------
    trial : int
    n_demos : int
    ds_components : int
    bc_epochs : int
    success : dict
        ``{policy: {noise: rate}}`` on the starts the cuts were learned from.
    heldout : dict
        ``{policy: {noise: rate}}`` on fresh starts (empty if disabled).
    cuts : dict
        ``{"BC+mod"|"DS+mod": {noise: number of cuts}}``.
    converged : dict
        ``{"BC+mod"|"DS+mod": {noise: bool}}``: no invariance failure left.
    curve : dict
        ``{"BC+mod"|"DS+mod": {noise: [rate after 0, 1, ... cuts]}}``.
    invariance_failures, reachability_failures : dict
        ``{policy: {noise: count}}``.
    unsolved_cuts : int
        Failures with no separating cut (skipped).
    seconds : float
    """

    trial: int
    n_demos: int
    ds_components: int
    bc_epochs: int
    success: dict[str, dict[str, float]]
    heldout: dict[str, dict[str, float]]
    cuts: dict[str, dict[str, int]]
    converged: dict[str, dict[str, bool]]
    curve: dict[str, dict[str, list[float]]]
    invariance_failures: dict[str, dict[str, int]]
    reachability_failures: dict[str, dict[str, int]]
    unsolved_cuts: int
    seconds: float


def _trial_seeds(seed: int, trial: int) -> tuple[list[np.random.Generator], int, int]:
    ss = np.random.SeedSequence([seed, trial])
    rngs = [np.random.default_rng(s) for s in ss.spawn(4)]
    words = ss.generate_state(2)
    return rngs, int(words[0] % (2**31 - 1)), int(words[1] % (2**31 - 1))


def run_trial(
    config: SingleModeConfig, trial: int, *, record: bool = False
) -> tuple[TrialResult, dict[str, Any] | None]:
    """Run one trial (one random mode) of the study.

    Parameters
    ----------
    config : SingleModeConfig
    trial : int
        Trial index; with ``config.seed`` it fixes every random draw.
    record : bool, optional
        Also return the data of the rollout figure (paper Fig. 5).

    Returns
    -------
    result : TrialResult
    record : dict or None
    """
    from tli_verify.ds.bc import train_bc
    from tli_verify.ds.lpvds import learn_lpvds
    from tli_verify.tasks.generate import make_task

    t0 = time.perf_counter()
    (task_rng, start_rng, cut_rng, held_rng), ds_seed, bc_seed = _trial_seeds(config.seed, trial)
    task = make_task(task_rng, workspace=config.workspace)
    goal = task.attractor
    contains = task.mode.contains
    ds, fit = learn_lpvds(task.states, task.velocities, goal, seed=ds_seed, eps=config.ds_eps)
    bc = train_bc(task.states, task.velocities, seed=bc_seed, max_epochs=config.bc_max_epochs)
    bases: dict[str, tuple[Policy, FloatArray | None]] = {
        "BC": (bc.velocity, None), "DS": (ds.velocity, np.asarray(ds.P))}
    success: dict[str, dict[str, float]] = {p: {} for p in POLICIES}
    heldout: dict[str, dict[str, float]] = {p: {} for p in POLICIES} if config.heldout else {}
    inv: dict[str, dict[str, int]] = {p: {} for p in POLICIES}
    reach: dict[str, dict[str, int]] = {p: {} for p in POLICIES}
    ncuts: dict[str, dict[str, int]] = {"BC+mod": {}, "DS+mod": {}}
    conv: dict[str, dict[str, bool]] = {"BC+mod": {}, "DS+mod": {}}
    curve: dict[str, dict[str, list[float]]] = {"BC+mod": {}, "DS+mod": {}}
    unsolved = 0
    rec: dict[str, Any] | None = None
    if record:
        rec = {"vertices": task.mode.vertices.copy(), "attractor": goal.copy(),
               "demos": [d.X.copy() for d in task.demos], "noise": {},
               "ds": ds, "bc": bc, "workspace": config.workspace}
    for pct in config.noise_percent:
        key = str(pct)
        std = pct / 100.0 * config.workspace
        starts = sample_starts(task.states, contains, start_rng, count=config.starts, std=std)
        held = (sample_starts(task.states, contains, held_rng, count=config.starts, std=std)
                if config.heldout else None)
        rec_noise: dict[str, Any] = {"starts": starts}
        for name, (fn, P) in bases.items():
            res = _roll(config, fn, starts, contains, goal, record=record)
            success[name][key] = float(res.success.mean())
            inv[name][key] = int(res.left.sum())
            reach[name][key] = int(res.reachability_failures.sum())
            mod_name = f"{name}+mod"
            learned = learn_cuts(fn, starts, contains, goal, cut_rng, config=config,
                                 lyapunov=P, record=record)
            fin = learned.final
            success[mod_name][key] = float(fin.success.mean())
            inv[mod_name][key] = int(fin.left.sum())
            reach[mod_name][key] = int(fin.reachability_failures.sum())
            ncuts[mod_name][key] = len(learned.cuts)
            conv[mod_name][key] = learned.converged
            curve[mod_name][key] = learned.curve
            unsolved += learned.unsolved
            if held is not None:
                from tli_verify.boundary.modulation import modulated

                h_nom = _roll(config, fn, held, contains, goal)
                h_mod = _roll(config, modulated(fn, learned.cuts, goal, lyapunov=P,
                                                 dt=config.dt).velocity,
                              held, contains, goal)
                heldout[name][key] = float(h_nom.success.mean())
                heldout[mod_name][key] = float(h_mod.success.mean())
            if record:
                rec_noise[name] = res
                rec_noise[mod_name] = learned
        if rec is not None:
            rec["noise"][key] = rec_noise
    result = TrialResult(
        trial=trial, n_demos=len(task.demos), ds_components=fit.n_components,
        bc_epochs=bc.epochs, success=success, heldout=heldout, cuts=ncuts, converged=conv,
        curve=curve, invariance_failures=inv, reachability_failures=reach,
        unsolved_cuts=unsolved, seconds=time.perf_counter() - t0,
    )
    return result, rec


def _init_worker() -> None:  # pragma: no cover - runs in worker processes
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
    except ImportError:
        pass


def _trial_job(args: tuple[SingleModeConfig, int, bool]) -> tuple[TrialResult, Any]:
    config, trial, record = args
    return run_trial(config, trial, record=record)


def run(
    config: SingleModeConfig,
    *,
    workers: int = 1,
    progress: Callable[[int, int], None] | None = None,
    record_trial: int | None = 0,
) -> tuple[list[TrialResult], dict[str, Any] | None]:
    """Run all trials, in parallel worker processes when ``workers > 1``.

    Parameters
    ----------
    config : SingleModeConfig
    workers : int, optional
        Processes; results do not depend on it (per-trial seeds).
    progress : callable, optional
        Called as ``progress(done, total)`` after each trial.
    record_trial : int or None, optional
        Trial whose figure data to record.

    Returns
    -------
    trials : list of TrialResult
        Sorted by trial index.
    record : dict or None
    """
    config.validate()
    if workers < 1:
        raise TliError(f"workers must be >= 1, got {workers}")
    jobs = [(config, t, t == record_trial) for t in range(config.trials)]
    results: list[TrialResult] = []
    record: dict[str, Any] | None = None
    done = 0
    if progress is not None:
        progress(0, len(jobs))
    if workers == 1 or len(jobs) == 1:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(1):
            for job in jobs:
                res, rec = _trial_job(job)
                results.append(res)
                record = rec if rec is not None else record
                done += 1
                if progress is not None:
                    progress(done, len(jobs))
    else:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor, as_completed

        ctx = mp.get_context("spawn")
        with ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=ctx,
                                 initializer=_init_worker) as pool:
            futures = [pool.submit(_trial_job, job) for job in jobs]
            for fut in as_completed(futures):
                res, rec = fut.result()
                results.append(res)
                record = rec if rec is not None else record
                done += 1
                if progress is not None:
                    progress(done, len(jobs))
    results.sort(key=lambda r: r.trial)
    return results, record


def _stats(values: Sequence[float]) -> dict[str, float]:
    a = np.asarray(values, dtype=np.float64)
    return {"mean": float(a.mean()), "median": float(np.median(a)),
            "q25": float(np.quantile(a, 0.25)), "q75": float(np.quantile(a, 0.75)),
            "min": float(a.min()), "max": float(a.max())}


def summarize(
    trials: Sequence[TrialResult], config: SingleModeConfig, *, seconds: float | None = None,
    workers: int | None = None,
) -> dict[str, Any]:
    """Aggregate trials: mean and IQR per policy and noise level, cut counts, curves.

    Returns
    -------
    dict
        JSON-ready. ``success[policy][noise]`` is the mean success rate in [0, 1];
        ``cuts[policy][noise]`` holds statistics of the number of cuts.
    """
    noises = [str(p) for p in config.noise_percent]
    success = {p: {k: float(np.mean([t.success[p][k] for t in trials])) for k in noises}
               for p in POLICIES}
    iqr = {p: {k: [_stats([t.success[p][k] for t in trials])["q25"],
                   _stats([t.success[p][k] for t in trials])["q75"]] for k in noises}
           for p in POLICIES}
    heldout = ({p: {k: float(np.mean([t.heldout[p][k] for t in trials])) for k in noises}
                for p in POLICIES} if config.heldout else {})
    cuts: dict[str, dict[str, Any]] = {}
    curves: dict[str, dict[str, Any]] = {}
    for p in ("BC+mod", "DS+mod"):
        cuts[p] = {}
        curves[p] = {}
        for k in noises:
            counts = [t.cuts[p][k] for t in trials]
            st = _stats(counts)
            st["converged"] = float(np.mean([t.converged[p][k] for t in trials]))
            cuts[p][k] = st
            length = max(len(t.curve[p][k]) for t in trials)
            padded = np.array([t.curve[p][k] + [t.curve[p][k][-1]] * (length - len(t.curve[p][k]))
                               for t in trials])
            curves[p][k] = {"mean": padded.mean(axis=0).tolist(),
                            "q25": np.quantile(padded, 0.25, axis=0).tolist(),
                            "q75": np.quantile(padded, 0.75, axis=0).tolist()}
    failures = {p: {k: {"invariance": int(sum(t.invariance_failures[p][k] for t in trials)),
                        "reachability": int(sum(t.reachability_failures[p][k] for t in trials))}
                    for k in noises} for p in POLICIES}
    top = noises[-1]
    shape = {
        "DS+mod is 100% at every noise level": all(success["DS+mod"][k] == 1.0 for k in noises),
        "DS+mod never leaves the mode (0 invariance failures)": all(
            failures["DS+mod"][k]["invariance"] == 0 for k in noises),
        "DS+mod has no invariance failure left after at most 5 cuts": all(
            cuts["DS+mod"][k]["max"] <= 5 and cuts["DS+mod"][k]["converged"] == 1.0
            for k in noises),
        "DS below 100% at the largest noise": success["DS"][top] < 1.0,
        "BC below DS at every noise level": all(success["BC"][k] <= success["DS"][k]
                                                for k in noises),
        "BC+mod below 100% at the largest noise": success["BC+mod"][top] < 1.0,
    }
    return {
        "config": asdict(config),
        "trials_run": len(trials),
        "success": success,
        "success_iqr": iqr,
        "heldout": heldout,
        "cuts": cuts,
        "curve": curves,
        "failures": failures,
        "unsolved_cuts": int(sum(t.unsolved_cuts for t in trials)),
        "expected_shape": shape,
        "paper": PAPER_TABLE,
        "seconds": seconds,
        "workers": workers,
        "per_trial": [asdict(t) for t in trials],
    }


def _pct(x: float) -> str:
    return f"{100.0 * x:.1f}"


def markdown(summary: dict[str, Any], *, figures: Sequence[str] = ()) -> str:
    """The Markdown report: table (mean [IQR]), paper numbers, cuts, held-out, shape checks."""
    cfg = summary["config"]
    noises = [str(p) for p in cfg["noise_percent"]]
    lines = [
        "# Single-mode study (paper Sec. 7.1, Fig. 6)",
        "",
        f"{summary['trials_run']} random convex modes, {cfg['starts']} starts per noise level, "
        f"seed {cfg['seed']}; Euler dt {cfg['dt']}, {cfg['steps']} steps, speed cap "
        f"{cfg['speed_cap']}, goal tolerance {cfg['goal_tolerance']}; cuts keep "
        f"{cfg['cut_constraints']}; DS margin eps {cfg.get('ds_eps', 1e-3):g}; "
        "noise = percent of the "
        f"{cfg['workspace']:g}-unit workspace side. Success rate in % (mean over trials, "
        "[25th-75th percentile]); paper values in parentheses.",
        "",
        "| Policy | " + " | ".join(f"noise {k}%" for k in noises) + " |",
        "|---|" + "---|" * len(noises),
    ]
    for p in POLICIES:
        cells = []
        for k in noises:
            q25, q75 = summary["success_iqr"][p][k]
            paper = PAPER_TABLE.get(p, {}).get(k)
            ref = f" ({paper:g})" if paper is not None else ""
            cells.append(f"{_pct(summary['success'][p][k])} [{_pct(q25)}-{_pct(q75)}]{ref}")
        lines.append(f"| {markdown_text(p)} | " + " | ".join(cells) + " |")
    lines += ["", "Cuts learned per mode (mean / max; share of trials with no invariance failure "
              "left):", "", "| Policy | " + " | ".join(f"noise {k}%" for k in noises) + " |",
              "|---|" + "---|" * len(noises)]
    for p in ("BC+mod", "DS+mod"):
        cells = [f"{summary['cuts'][p][k]['mean']:.2f} / {summary['cuts'][p][k]['max']:.0f}; "
                 f"{_pct(summary['cuts'][p][k]['converged'])}%" for k in noises]
        lines.append(f"| {p} | " + " | ".join(cells) + " |")
    lines += ["", "Success (mean %) after k cuts (paper Fig. 6 right; a trial that stopped "
              "early keeps its last value):", ""]
    for p in ("DS+mod", "BC+mod"):
        for k in noises:
            mean = summary["curve"][p][k]["mean"][:8]
            lines.append(f"- {p}, noise {k}%: " + ", ".join(_pct(v) for v in mean))
    if summary.get("heldout"):
        lines += ["", "Held-out starts (fresh draws, final cuts):", "",
                  "| Policy | " + " | ".join(f"noise {k}%" for k in noises) + " |",
                  "|---|" + "---|" * len(noises)]
        for p in POLICIES:
            lines.append(f"| {p} | " + " | ".join(_pct(summary["heldout"][p][k])
                                                  for k in noises) + " |")
    lines += ["", "Failures over all trials (invariance = left the mode; reachability = stayed "
              "but missed the goal):", ""]
    for p in POLICIES:
        parts = [f"{k}%: {summary['failures'][p][k]['invariance']} inv / "
                 f"{summary['failures'][p][k]['reachability']} reach" for k in noises]
        lines.append(f"- {p}: " + "; ".join(parts))
    lines += ["", "Expected shape (paper):", ""]
    for name, ok in summary["expected_shape"].items():
        lines.append(f"- [{'x' if ok else ' '}] {name}")
    if summary.get("unsolved_cuts"):
        lines += ["", "Cut attempts that found no separating plane (that failure was skipped): "
                  f"{summary['unsolved_cuts']}"]
    if summary.get("seconds") is not None:
        lines += ["", f"Wall time {summary['seconds']:.1f} s with {summary['workers']} "
                  "worker process(es)."]
    for fig in figures:
        lines += ["", f"![{markdown_text(fig)}]({markdown_url(fig)})"]
    return "\n".join(lines) + "\n"


def _plot_rollouts(record: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tli_verify.plotting import save_figure

    noises = list(record["noise"].keys())
    top = noises[-1]
    ncols = len(noises) + 2
    fig, axes = plt.subplots(2, ncols, figsize=(3.0 * ncols, 6.2), squeeze=False)
    V = record["vertices"]
    goal = record["attractor"]
    W = record["workspace"]
    grid = np.linspace(0.0, W, 40)
    GX, GY = np.meshgrid(grid, grid)
    G = np.column_stack([GX.ravel(), GY.ravel()])
    for r, name in enumerate(("BC", "DS")):
        pol = record["bc"] if name == "BC" else record["ds"]
        for c in range(ncols):
            ax = axes[r, c]
            ax.fill(V[:, 0], V[:, 1], facecolor="0.94", edgecolor="k", linestyle="--", lw=1.0)
            ax.set_xlim(0, W)
            ax.set_ylim(0, W)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
        ax = axes[r, 0]
        U = pol.velocity(G)
        ax.streamplot(GX, GY, U[:, 0].reshape(GX.shape), U[:, 1].reshape(GX.shape),
                      color="0.6", density=0.8, linewidth=0.6, arrowsize=0.6)
        for d in record["demos"]:
            ax.plot(d[:, 0], d[:, 1], "k-", lw=1.8)
        ax.set_title(f"{name}: nominal + demos", fontsize=9)
        panels: list[tuple[str, Any, Any]] = [(f"{name}, noise {k}%", record["noise"][k][name],
                                               None) for k in noises]
        learned = record["noise"][top][f"{name}+mod"]
        panels.append((f"{name}+mod, noise {top}%, {len(learned.cuts)} cuts", learned.final,
                       learned))
        for c, (title, res, learn) in enumerate(panels, start=1):
            ax = axes[r, c]
            P = res.paths
            for j in range(P.shape[1]):
                end = res.exit_step[j] if res.left[j] else P.shape[0] - 1
                color = "tab:blue" if res.success[j] else "tab:red"
                ax.plot(P[: end + 1, j, 0], P[: end + 1, j, 1], color=color, lw=0.6, alpha=0.7)
            if learn is not None:
                for cut in learn.cuts:
                    w, p = cut.normal, cut.point
                    t = np.array([-w[1], w[0]])
                    seg = p + np.outer(np.linspace(-2 * W, 2 * W, 2), t)
                    ax.plot(seg[:, 0], seg[:, 1], color="tab:cyan", lw=1.2)
                for _, last, out in learn.failures:
                    ax.plot(*last, "o", color="gold", mec="k", ms=5, zorder=5)
                    ax.plot(*out, "x", color="tab:red", ms=6, mew=2, zorder=5)
            ax.set_title(f"{title}: {_pct(float(res.success.mean()))}%", fontsize=9)
        for c in range(ncols):
            axes[r, c].plot(*goal, "o", color="tab:orange", mec="k", ms=8, zorder=6)
    fig.suptitle("Single-mode rollouts (cf. paper Fig. 5): blue = success, red = failure; "
                 "cyan = cuts, yellow = last in-mode state, red x = failure state", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def _plot_curve(summary: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tli_verify.plotting import save_figure

    noises = [str(p) for p in summary["config"]["noise_percent"]]
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4), sharey=True)
    colors = ["tab:green", "tab:blue", "tab:red", "tab:purple", "tab:brown"]
    for ax, p in zip(axes, ("DS+mod", "BC+mod"), strict=True):
        for k, col in zip(noises, colors, strict=False):
            cur = summary["curve"][p][k]
            L = 11  # a study that stopped early keeps its last value

            def pad(v: list[float], L: int = L) -> FloatArray:
                return 100 * np.array((v + [v[-1]] * L)[:L])

            xs = np.arange(L)
            ax.plot(xs, pad(cur["mean"]), color=col, lw=2, marker="o", ms=3,
                    label=f"noise {k}%")
            ax.fill_between(xs, pad(cur["q25"]), pad(cur["q75"]), color=col, alpha=0.2)
        ax.set_title(p)
        ax.set_xlabel("number of cuts")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("success rate (%)")
    axes[0].legend(loc="lower right", fontsize=8)
    fig.suptitle("Success vs. number of cuts (cf. paper Fig. 6 right): mean, shaded IQR",
                 fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def write_outputs(
    summary: dict[str, Any], record: dict[str, Any] | None, out_dir: Path, *,
    figures: bool = True,
) -> list[Path]:
    """Write ``single_mode.json``, ``single_mode.md`` and the PNG figures (atomically).

    Parameters
    ----------
    summary : dict
        From :func:`summarize`.
    record : dict or None
        Figure data of one trial (from :func:`run`); no rollout figure without it.
    out_dir : Path
    figures : bool, optional
        Write the PNG figures.

    Returns
    -------
    list of Path
        The files written (JSON, Markdown, then figures).
    """
    from tli_verify.io import atomic_write_text, canonical_json

    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    figs: list[str] = []
    if figures:
        curve_png = out_dir / "single_mode_cuts.png"
        _plot_curve(summary, curve_png)
        written.append(curve_png)
        figs.append(curve_png.name)
    if figures and record is not None:
        roll_png = out_dir / "single_mode_rollouts.png"
        _plot_rollouts(record, roll_png)
        written.append(roll_png)
        figs.append(roll_png.name)
    js = out_dir / "single_mode.json"
    atomic_write_text(js, canonical_json(summary))
    md = out_dir / "single_mode.md"
    atomic_write_text(md, markdown(summary, figures=figs))
    return [js, md, *written]

