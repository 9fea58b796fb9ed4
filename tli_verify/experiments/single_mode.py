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
keeps the study's configuration and process pool; the statistics, report and figures are in
:mod:`tli_verify.experiments.single_mode_report`.

Every trial is seeded by ``SeedSequence([seed, trial])``, so results do not depend on the number
of worker processes.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.boundary.modulation import modulated
from tli_verify.ds.bc import train_bc
from tli_verify.ds.lpvds import learn_lpvds
from tli_verify.errors import TliError
from tli_verify.runtime.online import CutLearning
from tli_verify.runtime.online import learn_cuts as _learn_cuts
from tli_verify.runtime.rollout import EulerProtocol, Rollouts, rollout, rollout_protocol
from tli_verify.tasks.generate import make_task

__all__ = [
    "NOISE_PERCENT",
    "PAPER_TABLE",
    "POLICIES",
    "CutLearning",
    "Rollouts",
    "SingleModeConfig",
    "TrialResult",
    "learn_cuts",
    "rollout",
    "run",
    "run_trial",
    "sample_starts",
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
