"""Bisimulation campaigns: generated perturbation sequences against the oracle (paper Sec. 4.4).

:func:`run_campaign` does, for a :class:`CampaignConfig`:

1. **draw** -- the driver draws ``examples`` cases (start + perturbation sequence,
   :func:`tli_verify.verify.strategies.cases`) with hypothesis, deterministically from the seed,
   in chunks of ``batch_size`` on a thread (:func:`draw_chunks`, :func:`draw_cases`:
   ``hypothesis.find`` with ``random=Random(chunk seed)``, a condition that never holds, and no
   example database; hypothesis generates in one process) while the workers simulate;
2. **simulate** -- the cases travel in batches (``batch_size`` runs,
   :func:`simulate_batch`: one vectorised :func:`~tli_verify.runtime.executive.run_episodes`
   call per batch, then the oracle on every trace, in the worker) to a backend
   (:mod:`.backends`); only verdicts come back;
3. **shrink** -- the first case of the most specific violation kind found
   (:data:`~tli_verify.verify.oracle.PRIORITY`: looping before a lone invariance failure) is
   shrunk by hypothesis in the driver (:func:`shrink`): the same ``find`` with the seed of its
   chunk replays that chunk's generation (the verdicts already computed are looked up, not
   re-simulated) until it meets that case, then hypothesis's shrinker minimises it -- fewer,
   smaller, later perturbations, by the encoding of :mod:`.strategies` -- keeping that
   violation kind; candidates are simulated in the driver;
4. optionally (``target_examples > 0``, no counterexample yet) a **targeted** search in the
   driver: hypothesis with ``hypothesis.target`` on the oracle's robustness margin.

Every run's budget decides reachability: the perturbation window plus the certified worst-case
deadline (:meth:`~tli_verify.verify.oracle.Oracle.budget`); a run also ends at a goal mode, and
a looping watchdog ends it once it has changed mode so often that the oracle's loop bound is
exceeded (:class:`WatchedPolicy`).

A counterexample is saved as a JSON case (:func:`case_document`): world, the files and their
SHA-256, start, perturbation sequence, seed, expected violation; :func:`replay_case` replays it
deterministically (``tli replay``).
"""

from __future__ import annotations

import contextlib
import math
import os
import queue
import random
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import Any, cast

import numpy as np
import numpy.typing as npt

from tli_verify.errors import CampaignError, TaskError, TliError
from tli_verify.limits import MAX_CAMPAIGN_STEPS, MAX_PUSHES
from tli_verify.runtime.events import CutAdded
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.verify.oracle import (
    PRIORITY,
    CutRecord,
    Oracle,
    Trace,
    Verdict,
    ViolationKind,
)
from tli_verify.verify.strategies import (
    LEVELS,
    Case,
    apply_push,
    case_from_json,
    case_to_json,
    cases,
)

__all__ = [
    "CASE_KIND",
    "CampaignConfig",
    "CampaignResult",
    "Loaded",
    "RunOutcome",
    "SimSpec",
    "WatchedPolicy",
    "case_document",
    "check_case",
    "chunk_seed",
    "draw_cases",
    "draw_chunks",
    "load",
    "read_case",
    "replay_case",
    "run_campaign",
    "shrink",
    "sim_spec",
    "simulate",
    "simulate_batch",
    "start_regions",
]

FloatArray = npt.NDArray[np.float64]
CASE_KIND = "tli-verify/bisimulation-case"
CASE_VERSION = 2
"""Version 2 binds the task (``files.task``); version 1 named a bundled world (``world``)."""


# ------------------------------------------------------------------------------ config
@dataclass(frozen=True, slots=True)
class CampaignConfig:
    """A campaign (``tli verify``).

    Attributes
    ----------
    task : str or None
        A task name or task file (:func:`tli_verify.tasks.registry.find_task`): its sensor
        model, true regions, starts and perturbation bounds (default: the task the spec names).
    spec, model, certificate : str or None
        Files, resolved by the project rules (:func:`tli_verify.tasks.project.resolve`).
    examples : int
        Cases drawn and simulated.
    seed : int
    modulation : bool
        Learn cuts online (LTL-DS); False: the no-modulation ablation.
    workers : int or None
        Worker processes (default: the CPU count).
    backend : str
        ``"process"``, ``"serial"`` or ``"dask"``.
    scheduler : str or None
        Dask scheduler address (``--backend dask``).
    batch_size : int
        Runs per batch (one task).
    max_pushes : int or None
        Perturbations per case, at most (default: the task's ``perturbations.max_pushes``).
    window : int or None
        Perturbations happen in steps ``1..window`` (default: the task's).
    levels : tuple of str
        Perturbation levels (:data:`~tli_verify.verify.strategies.LEVELS`).
    start : tuple of float or None
        Fixed start (default: the task's first nominal start).
    random_starts : bool or None
        Draw starts too (in the regions whose first reading the spec allows); default: when
        the task has no nominal start.
    lag : int or None
        Sensor lag (steps; default: the task's).
    max_cycles : int or None
        Loop bound of the oracle (default: the number of modes).
    shrink : bool
        Shrink the first counterexample.
    target_examples : int
        Extra driver-side targeted examples when nothing was found (0: none).
    """

    task: str | None = None
    spec: str | None = None
    model: str | None = None
    certificate: str | None = None
    examples: int = 200
    seed: int = 0
    modulation: bool = True
    workers: int | None = None
    backend: str = "process"
    scheduler: str | None = None
    batch_size: int = 100
    max_pushes: int | None = None
    window: int | None = None
    levels: tuple[str, ...] = LEVELS
    start: tuple[float, ...] | None = None
    random_starts: bool | None = None
    lag: int | None = None
    max_cycles: int | None = None
    shrink: bool = True
    target_examples: int = 0

    def __post_init__(self) -> None:
        """Every field's type and range, as the CLI options check them (recorded settings of
        evidence are re-run through here, so a forged one is refused, never run).

        Raises
        ------
        CampaignError
            (exit 2) Naming the field.
        """
        from tli_verify.limits import MAX_BATCH_SIZE, MAX_EXAMPLES, MAX_SEED

        def whole(name: str, lo: int, hi: int, *, optional: bool = False) -> None:
            v = getattr(self, name)
            if v is None and optional:
                return
            if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
                raise CampaignError(f"{name}: expected an integer in [{lo}, {hi}], got {v!r}")

        whole("examples", 1, MAX_EXAMPLES)
        whole("seed", 0, MAX_SEED)
        whole("batch_size", 1, MAX_BATCH_SIZE)
        whole("workers", 1, 256, optional=True)
        whole("window", 1, MAX_CAMPAIGN_STEPS, optional=True)
        whole("lag", 0, MAX_CAMPAIGN_STEPS, optional=True)
        whole("max_pushes", 0, MAX_PUSHES, optional=True)
        whole("max_cycles", 0, MAX_CAMPAIGN_STEPS, optional=True)
        whole("target_examples", 0, MAX_EXAMPLES)
        for name in ("modulation", "shrink"):
            if not isinstance(getattr(self, name), bool):
                raise CampaignError(f"{name}: expected true or false, got "
                                    f"{getattr(self, name)!r}")
        if self.random_starts is not None and not isinstance(self.random_starts, bool):
            raise CampaignError(f"random_starts: expected true or false, got "
                                f"{self.random_starts!r}")
        if self.backend not in ("process", "serial", "dask"):
            raise CampaignError(f"backend: one of process, serial, dask, got {self.backend!r}")
        if not isinstance(self.levels, tuple) or not self.levels or any(
                lv not in LEVELS for lv in self.levels) or len(set(self.levels)) != \
                len(self.levels):
            raise CampaignError(f"levels: a non-empty subset of {', '.join(LEVELS)}, got "
                                f"{self.levels!r}")
        if self.start is not None and (not isinstance(self.start, tuple) or not all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                for v in self.start)):
            raise CampaignError(f"start: expected finite numbers, got {self.start!r}")
        for name in ("task", "spec", "model", "certificate", "scheduler"):
            v = getattr(self, name)
            if v is not None and not isinstance(v, str):
                raise CampaignError(f"{name}: expected a path or name, got {v!r}")


@dataclass(frozen=True, slots=True)
class SimSpec:
    """What a worker needs to rebuild the setup (files by path and SHA-256; picklable).

    ``task`` is the task file's path, or the name of an entry-point task (a worker finds it in
    the installed metadata); ``task_sha256`` is what binds it (the file's SHA-256, or the
    entry point's source SHA-256).
    """

    task: str
    task_sha256: str
    lag: int
    spec: str
    model: str
    certificate: str
    hashes: tuple[str, str, str]
    modulation: bool
    max_cycles: int | None
    window: int


@dataclass(frozen=True, slots=True)
class RunOutcome:
    """One simulated case.

    Attributes
    ----------
    index : int
        Position in generation order.
    verdict : Verdict
    steps : int
    cuts_added : int
    modes : str
        The policy's run-length mode sequence.
    """

    index: int
    verdict: Verdict
    steps: int
    cuts_added: int
    modes: str


@dataclass(frozen=True, slots=True)
class CampaignResult:
    """What a campaign found.

    Attributes
    ----------
    config : CampaignConfig
    runs : int
        Cases simulated (fewer than ``examples`` when ``partial``).
    violations : dict of str to int
        Runs violating each kind (every kind listed; a run may count under several).
    task_satisfied : int
        Runs that reached a goal mode.
    cuts_added : int
    coverage : dict
        ``automaton_edges`` (exercised, total, list), ``mode_edges``, ``modes_perturbed``,
        ``cut_faces`` (touched, total).
    counterexample : dict or None
        The (shrunk) case document (:func:`case_document`).
    first_counterexample_at : int or None
        Simulations (in generation order) until the first counterexample.
    failure_bound : float or None
        With no violation: the 95 % upper bound ``3 / runs`` on the failure probability
        (rule of three).
    partial : bool
        Interrupted (Ctrl-C): the counts cover the runs completed.
    outcomes : tuple of RunOutcome
    seconds : float
    inconclusive : int
        Runs whose reachability was not decided (ended early, assumptions left).
    shrink_steps : int
        Simulations the shrinker ran.
    events : tuple of str
        Notable events (worker lost, ...).
    files : dict
        ``spec``, ``model``, ``certificate``: ``{"path", "sha256"}``; ``task``: ``{"path" or
        "entry_point", "sha256"}``.
    task_name : str
        The task's name.
    """

    config: CampaignConfig
    runs: int
    violations: dict[str, int]
    task_satisfied: int
    cuts_added: int
    coverage: dict[str, Any]
    counterexample: dict[str, Any] | None
    first_counterexample_at: int | None
    failure_bound: float | None
    partial: bool
    outcomes: tuple[RunOutcome, ...] = ()
    seconds: float = 0.0
    inconclusive: int = 0
    shrink_steps: int = 0
    events: tuple[str, ...] = ()
    files: dict[str, Any] = field(default_factory=dict)
    task_name: str = ""

    def to_json(self) -> dict[str, Any]:
        """The ``tli verify --json`` record."""
        c = self.config
        return {
            "task": {"name": self.task_name, **self.files.get("task", {})},
            "examples": c.examples,
            "seed": c.seed,
            "modulation": c.modulation,
            "backend": c.backend,
            "batch_size": c.batch_size,
            "max_pushes": c.max_pushes,
            "window": c.window,
            "levels": list(c.levels),
            "random_starts": c.random_starts,
            "lag": c.lag,
            "files": self.files,
            "runs": self.runs,
            "partial": self.partial,
            "violations": self.violations,
            "violating_runs": sum(1 for o in self.outcomes if not o.verdict.ok),
            "task_satisfied": self.task_satisfied,
            "cuts_added": self.cuts_added,
            "inconclusive": self.inconclusive,
            "coverage": self.coverage,
            "counterexample": self.counterexample,
            "simulations_to_first_counterexample": self.first_counterexample_at,
            "first_violation_by_kind": {
                k.value: next((o.index + 1 for o in self.outcomes if k in o.verdict.kinds),
                              None) for k in ViolationKind},
            "failure_probability_bound_95": self.failure_bound,
            "shrink_simulations": self.shrink_steps,
            "seconds": self.seconds,
            "events": list(self.events),
        }


# ------------------------------------------------------------------------------ setup
def task_ref(task: Any) -> tuple[str, str]:
    """How a worker finds a task again, and what binds it: ``(task file path, its SHA-256)``,
    or ``(entry point name, its source SHA-256)``.

    Raises
    ------
    CampaignError
        (exit 2) A task built in memory (it cannot be bound or found by a worker).
    """
    src = task.source
    if src.kind == "file" and src.path is not None and src.sha256 is not None:
        return src.path, src.sha256
    if src.kind == "entry-point" and src.entry_point is not None and src.source_sha256:
        return src.entry_point, src.source_sha256
    raise CampaignError(f"task {task.name!r} was built in memory: campaigns need a task file "
                        "or an entry-point task")


def resolve_config(cfg: CampaignConfig) -> tuple[Any, CampaignConfig]:
    """The config's files by the project rules, and the config with the task's defaults
    filled in (window, max_pushes, lag, start or random starts).

    Raises
    ------
    TaskError, CampaignError
        (exit 2) Missing files, a model or spec that does not fit the task, a start outside
        the workspace or of the wrong dimension.
    """
    from tli_verify.tasks.project import resolve

    resolved = resolve(task=cfg.task, spec=cfg.spec, model=cfg.model,
                       certificate=cfg.certificate, lag=cfg.lag)
    task = resolved.task
    start = cfg.start
    random_starts = cfg.random_starts
    if random_starts is None:
        random_starts = start is None and not task.starts.nominal
    if not random_starts and start is None:
        if not task.starts.nominal:
            raise CampaignError(f"task {task.name!r} has no nominal start ([starts] nominal): "
                                "pass a start or use random starts")
        start = task.starts.nominal[0]
    if start is not None:
        if len(start) != task.dim:
            raise CampaignError(f"start: expected {task.dim} coordinates (task "
                                f"{task.name!r}), got {len(start)}")
        if not bool(task.in_workspace(np.asarray(start, dtype=np.float64)[None])[0]):
            raise CampaignError(f"start {list(start)}: outside the workspace of task "
                                f"{task.name!r}")
    filled = replace(cfg, window=task.perturbations.window if cfg.window is None else cfg.window,
                     max_pushes=(task.perturbations.max_pushes if cfg.max_pushes is None
                                 else cfg.max_pushes),
                     lag=task.lag, random_starts=bool(random_starts),
                     start=None if random_starts else tuple(float(v) for v in start or ()))
    return resolved, filled


def sim_spec(cfg: CampaignConfig) -> SimSpec:
    """Resolve the files of a config (its task defaults filled in) and hash them.

    Raises
    ------
    CampaignError, TaskError
        (exit 2) Unknown task, missing files, files that do not fit.
    """
    from tli_verify.io import sha256_file

    resolved, filled = resolve_config(cfg)
    ref, sha = task_ref(resolved.task)
    assert filled.window is not None
    assert filled.lag is not None
    return SimSpec(task=ref, task_sha256=sha, lag=filled.lag, spec=str(resolved.spec),
                   model=str(resolved.model), certificate=str(resolved.certificate),
                   hashes=(sha256_file(resolved.spec), sha256_file(resolved.model),
                           sha256_file(resolved.certificate)),
                   modulation=cfg.modulation, max_cycles=cfg.max_cycles, window=filled.window)


class WatchedPolicy(LTLDSPolicy):
    """The executive, with a looping watchdog that ends the episode (not the policy's logic).

    :attr:`done` is also true once, after step ``after`` (the last perturbation), the executive
    has reported more than ``limit`` events since the last cut it learned (every such event
    comes with a mode change, at most 5 per change, so by then the run has re-entered visited
    modes more than the oracle's loop bound allows), or more than ``max_cuts`` cuts: either way
    the oracle's looping verdict is decided.
    """

    __slots__ = ("_after", "_cuts", "_limit", "_mark", "_max_cuts", "_seen")
    _after: int
    _limit: int
    _mark: int
    _seen: int
    _cuts: int
    _max_cuts: int

    def watch(self, after: int, limit: int, max_cuts: int) -> WatchedPolicy:
        """A fork for one episode with the watchdog armed."""
        new = cast(WatchedPolicy, self.fork())
        new._after = int(after)
        new._limit = int(limit)
        new._max_cuts = int(max_cuts)
        new._mark = -1
        new._seen = 0
        new._cuts = 0
        return new

    @property
    def done(self) -> bool:
        """At the goal (a goal mode with the goal's sensors read), or the watchdog fired."""
        if LTLDSPolicy.done.fget(self):  # type: ignore[attr-defined]
            return True
        if self._steps >= self._after:
            n = len(self.events)
            if self._mark < 0:
                self._mark = self._seen = n
            elif n > self._seen:  # each event is looked at once
                for k in range(self._seen, n):
                    if isinstance(self.events[k], CutAdded):
                        self._mark = k + 1  # a learned cut restarts the loop count
                        self._cuts += 1
                self._seen = n
            if n - self._mark > self._limit or self._cuts > self._max_cuts:
                return True
        return False


@dataclass(frozen=True, slots=True, eq=False)
class Loaded:
    """A loaded setup: world, automaton, certified model, base policy, oracle."""

    world: Any
    automaton: Any
    model: Any
    certificate: str
    policy: WatchedPolicy
    oracle: Oracle
    budget: int
    limit: int


def load_task(spec: SimSpec) -> Any:
    """The task of a :class:`SimSpec`, checked against the hash the driver bound.

    Raises
    ------
    CampaignError
        (exit 2) The task changed since the campaign resolved it.
    """
    from tli_verify.tasks.registry import find_task

    task = find_task(spec.task)
    _, sha = task_ref(task)
    if sha != spec.task_sha256:
        raise CampaignError(f"{spec.task}: the task changed during the campaign (SHA-256 "
                            "differs)")
    return task.with_lag(spec.lag)


@lru_cache(maxsize=4)
def load(spec: SimSpec) -> Loaded:
    """Load (once per process) what the runs of a :class:`SimSpec` need.

    Raises
    ------
    CampaignError
        (exit 2) A file's SHA-256 differs from the driver's (the files changed under the
        campaign).
    """
    from tli_verify.io import sha256_file
    from tli_verify.runtime.setup import check_goal
    from tli_verify.tasks.project import resolve

    for path, want in zip((spec.spec, spec.model, spec.certificate), spec.hashes, strict=True):
        if sha256_file(path) != want:
            raise CampaignError(f"{path}: changed during the campaign (SHA-256 differs)")
    task = load_task(spec)
    resolved = resolve(task=task, spec=spec.spec, model=spec.model,
                       certificate=spec.certificate)
    from tli_verify.logic.check import synthesize
    from tli_verify.logic.spec import load_spec
    from tli_verify.model import load_model

    automaton = synthesize(load_spec(spec.spec))
    model = load_model(spec.model)
    # one goal for the policy and the oracle: the spec's, else the task's, else the sinks
    goal_modes = check_goal(automaton, resolved.goal, where=spec.spec)
    goal_inputs = resolved.goal.sensors
    base = WatchedPolicy(automaton, model, spec.certificate, learn_cuts=spec.modulation,
                         goal_modes=goal_modes, goal_inputs=goal_inputs, dt=task.dt)
    oracle = Oracle.build(task, automaton, model, spec.certificate, dt=base.dt,
                          max_cycles=spec.max_cycles, goal_modes=goal_modes,
                          goal_inputs=goal_inputs)
    limit = 5 * (oracle.max_cycles + len(automaton.modes) + 1)
    return Loaded(world=task, automaton=automaton, model=model,
                  certificate=spec.certificate, policy=base, oracle=oracle,
                  budget=oracle.budget(spec.window), limit=limit)


def start_regions(world: Any, automaton: Any) -> tuple[str, ...]:
    """The true regions whose first reading (from the initial latent state) is one the spec's
    initial assumption allows."""
    from tli_verify.logic.automaton import AssumptionViolation

    out = []
    for name in world.region_names:
        try:
            x = world.sample_region(name, 1, np.random.default_rng(0))
        except TliError:
            continue
        reading = world.sensors(x)[0]
        true = [n for n, v in zip(world.sensor_names, reading.tolist(), strict=True) if v]
        try:
            automaton.initial_state(true)
        except AssumptionViolation:
            continue
        out.append(name)
    return tuple(out)


# ------------------------------------------------------------------------------ simulation
def simulate(spec: SimSpec, cases_: Sequence[Case], *, budget: int | None = None
             ) -> list[tuple[Trace, Any]]:
    """Simulate cases in one vectorised batch; return each run's trace and episode result.

    Parameters
    ----------
    spec : SimSpec
    cases_ : sequence of Case
    budget : int, optional
        Step budget (default: the certified one, :meth:`Oracle.budget`).

    Returns
    -------
    list of (Trace, EpisodeResult)
    """
    from tli_verify.runtime.executive import run_episodes
    from tli_verify.runtime.worlds import WorldSensors

    ld = load(spec)
    if not cases_:
        return []
    X = np.array([c.start for c in cases_], dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != ld.model.dim:
        raise CampaignError(f"case start: expected {ld.model.dim} coordinates")
    tables = [c.table() for c in cases_]
    pushed: list[dict[int, FloatArray]] = [{} for _ in cases_]
    world = ld.world

    def perturb(i: int, t: int, x: FloatArray) -> FloatArray | None:
        p = tables[i].get(t)
        if p is None:
            return None
        new = apply_push(world, x, p)
        pushed[i][t] = new
        return new

    policies = [ld.policy.watch(c.last_step, ld.limit, ld.oracle.max_cuts) for c in cases_]
    memo: dict[Any, Any] = {}
    sensors = [WorldSensors(world, cache=memo) for _ in cases_]
    results = run_episodes(policies, sensors, X, steps=ld.budget if budget is None else budget,
                           perturb=perturb)
    out = []
    for i, res in enumerate(results):
        S = res.states
        R = np.empty_like(S)
        R[0] = S[0]
        R[1:] = S[:-1]
        for t, x in pushed[i].items():
            if t < len(R):
                R[t] = x
        cuts = tuple(CutRecord(e.step, e.mode, tuple(e.cut.normal.tolist()),
                               tuple(e.cut.point.tolist()))
                     for e in res.events if isinstance(e, CutAdded))
        if res.success and not LTLDSPolicy.done.fget(policies[i]):  # type: ignore[attr-defined]
            # the watchdog ended the run, not the goal
            res = replace(res, success=False)
        out.append((Trace(states=S, read_states=R, modes=res.modes,
                          pushes=tuple(sorted(t for t in pushed[i] if t <= res.steps)),
                          cuts=cuts, budget=ld.budget), res))
    return out


def simulate_batch(job: tuple[SimSpec, Sequence[tuple[int, Case]]]) -> list[RunOutcome]:
    """A worker's task: simulate a batch and check every trace with the oracle.

    Parameters
    ----------
    job : (SimSpec, sequence of (index, Case))

    Returns
    -------
    list of RunOutcome
    """
    import threadpoolctl

    from tli_verify.runtime.episodes import mode_string

    spec, items = job
    with threadpoolctl.threadpool_limits(1):
        sims = simulate(spec, [c for _, c in items])
        verdicts = load(spec).oracle.check_many([tr for tr, _ in sims])
    return [RunOutcome(index=i, verdict=v, steps=res.steps, cuts_added=res.cuts_added,
                       modes=mode_string(res))
            for (i, _), (_, res), v in zip(items, sims, verdicts, strict=True)]


def check_case(spec: SimSpec, case: Case) -> Verdict:
    """Simulate one case in this process and return the oracle's verdict."""
    (trace, _), = simulate(spec, [case])
    return load(spec).oracle.check(trace)


# ------------------------------------------------------------------------------ drawing
def _strategy(cfg: CampaignConfig, ld: Loaded) -> Any:
    """The cases of a filled-in config (:func:`resolve_config`): its start or random starts,
    the task's perturbation bound."""
    task = ld.world
    assert cfg.max_pushes is not None
    assert cfg.window is not None
    regions = None
    if cfg.random_starts:
        regions = start_regions(task, ld.automaton)
        if task.starts.region is not None:
            regions = tuple(r for r in regions if r == task.starts.region) or regions
    return cases(task, start=None if cfg.random_starts else cfg.start,
                 max_pushes=cfg.max_pushes, window=cfg.window, levels=cfg.levels,
                 max_magnitude=task.perturbations.max_magnitude, start_regions=regions)


def _settings(n: int, phases: Sequence[Any]) -> Any:
    from hypothesis import HealthCheck, settings

    return settings(max_examples=n, database=None, deadline=None, derandomize=False,
                    phases=list(phases), suppress_health_check=list(HealthCheck),
                    report_multiple_bugs=False, print_blob=False)


def _budget(n: int) -> int:
    """Examples hypothesis is asked for to yield ``n`` distinct cases (different choice
    sequences can give one case, e.g. the empty sequence)."""
    return math.ceil(1.3 * n) + 10


@contextlib.contextmanager
def import_independent_draws() -> Iterator[None]:
    """Hypothesis generation that does not depend on which modules are imported.

    Hypothesis (6.13x+) sometimes (p = 0.05 a choice) draws a "local constant" harvested from
    every non-library module in ``sys.modules``, a pool that grows as modules are imported.
    A campaign that lazily imports a module while running would then draw other cases from the
    same seed later in the process (measured: the first campaign of a process differed from the
    next ones). Inside this context that pool is empty, so a seed gives the same cases in any
    process state. The module-level ``CONSTANTS_CACHE`` (constants allowed per choice kind,
    filled by any earlier draw with the same bounds: a ``@given`` test, an unguarded ``find``)
    is swapped for a fresh one for the same reason (measured: a draw after a module's property
    tests differed from the same draw in a fresh process). Without the (private) hooks the
    draws still run, only less reproducibly.
    """
    try:
        from hypothesis.internal.conjecture import providers
    except ImportError:  # pragma: no cover - a hypothesis without the module
        yield
        return
    getter = getattr(providers, "_get_local_constants", None)
    empty_type = getattr(providers, "Constants", None)
    if getter is None or empty_type is None:  # pragma: no cover - hypothesis changed
        yield
        return
    empty = empty_type()
    providers._get_local_constants = lambda: empty
    cache = getattr(providers, "CONSTANTS_CACHE", None)
    if cache is not None:
        providers.CONSTANTS_CACHE = type(cache)(1024)
    try:
        yield
    finally:
        providers._get_local_constants = getter
        if cache is not None:
            providers.CONSTANTS_CACHE = cache


def draw_cases(strategy: Any, n: int, seed: int | str) -> list[Case]:
    """``n`` cases from ``strategy``, deterministic in ``seed`` (hypothesis in this process).

    ``hypothesis.find`` with ``random=Random(seed)``, no example database, the generate phase
    only and a condition that never holds: every example it generates is collected, in order.
    Hypothesis may generate fewer than ``n`` when the strategy's space is exhausted.
    """
    from hypothesis import Phase, find
    from hypothesis.errors import NoSuchExample

    out: list[Case] = []
    seen: set[Case] = set()

    def collect(c: Case) -> bool:
        if c not in seen:
            seen.add(c)
            out.append(c)
        return False

    try:
        with import_independent_draws():
            find(strategy, collect, settings=_settings(_budget(n), [Phase.generate]),
                 random=random.Random(seed))
    except NoSuchExample:
        pass
    return out[:n]


def chunk_seed(seed: int, chunk: int) -> str:
    """The hypothesis seed of chunk ``chunk`` of a campaign seeded ``seed``."""
    return f"tli-verify:{seed}:{chunk}"


def draw_chunks(strategy: Any, n: int, seed: int, size: int
                ) -> Iterator[list[tuple[int, Case]]]:
    """The campaign's cases in chunks of ``size``: ``[(index, case), ...]`` per chunk.

    Chunk ``j`` is the first cases of :func:`draw_cases` ``(strategy, size + 10,
    chunk_seed(seed, j))`` (so a
    chunk can be replayed on its own to shrink, and drawing overlaps the simulation); cases
    drawn by an earlier chunk are skipped (each chunk starts from hypothesis's simplest case),
    so every index is a distinct case.
    """
    seen: set[Case] = set()
    index = 0
    j = 0
    while index < n:
        want = min(size, n - index)
        fresh = [c for c in draw_cases(strategy, size + 10, chunk_seed(seed, j))
                 if c not in seen][:want]
        if not fresh:
            return
        seen.update(fresh)
        yield [(index + k, c) for k, c in enumerate(fresh)]
        index += len(fresh)
        j += 1


class _Shrinker:
    """The condition hypothesis shrinks with: 'the case violates ``kind``' (cached)."""

    def __init__(self, spec: SimSpec, kind: ViolationKind, known: Mapping[Case, Verdict]
                 ) -> None:
        self.spec = spec
        self.kind = kind
        self.known = dict(known)
        self.simulated = 0

    def verdict(self, case: Case) -> Verdict:
        v = self.known.get(case)
        if v is None:
            v = check_case(self.spec, case)
            self.known[case] = v
            self.simulated += 1
        return v

    def __call__(self, case: Case) -> bool:
        return self.kind in self.verdict(case).kinds


def shrink(spec: SimSpec, strategy: Any, seed: int | str, examples: int, kind: ViolationKind,
           known: Mapping[Case, Verdict]) -> tuple[Case | None, Verdict | None, int]:
    """Shrink the first case violating ``kind`` in the seeded generation order.

    Replays :func:`draw_cases`'s generation of ``examples`` cases with ``seed`` (a campaign
    replays the chunk, :func:`chunk_seed`, of its first counterexample; same strategy and
    settings; verdicts in ``known`` are looked up, not simulated) with the condition "violates
    ``kind``", so hypothesis stops at the same first failing case and shrinks it (candidates
    simulated here).

    Returns
    -------
    (Case or None, Verdict or None, int)
        The minimal case, its verdict, and the simulations the shrinker ran.
    """
    from hypothesis import Phase, find
    from hypothesis.errors import NoSuchExample

    cond = _Shrinker(spec, kind, known)
    try:
        with import_independent_draws():
            found = find(strategy, cond, settings=_settings(_budget(examples),
                                                            [Phase.generate, Phase.shrink]),
                         random=random.Random(seed))
    except NoSuchExample:
        return None, None, cond.simulated
    return found, cond.verdict(found), cond.simulated


def _targeted(spec: SimSpec, strategy: Any, seed: int, n: int
              ) -> tuple[Case | None, Verdict | None, int]:
    """Driver-side search with ``hypothesis.target`` on the robustness margin."""
    from hypothesis import Phase, find, target
    from hypothesis.errors import NoSuchExample

    count = [0]
    cache: dict[Case, Verdict] = {}

    def cond(case: Case) -> bool:
        v = cache.get(case)
        if v is None:
            v = check_case(spec, case)
            cache[case] = v
            count[0] += 1
        if math.isfinite(v.robustness):
            target(-v.robustness, label="negated robustness")
        return not v.ok

    try:
        with import_independent_draws():
            found = find(strategy, cond, settings=_settings(n, [Phase.generate, Phase.target,
                                                                Phase.shrink]),
                         random=random.Random(seed + 7919))
    except NoSuchExample:
        return None, None, count[0]
    return found, cache.get(found) or check_case(spec, found), count[0]


# ------------------------------------------------------------------------------ cases
def _shown_path(path: str) -> str:
    """A file's path relative to the repository root when under it, else absolute."""
    from tli_verify.io import bundled_dir

    try:
        root = Path(os.path.realpath(bundled_dir("models").parent))
    except TliError:
        root = None
    real = Path(os.path.realpath(path))
    return str(real.relative_to(root)) if root is not None and real.is_relative_to(root) \
        else str(real)


def _files(spec: SimSpec) -> dict[str, dict[str, str]]:
    """The files of a run (paths relative to the repository root when under it) and the task
    (a file, or an entry point by name), each with the SHA-256 that binds it."""
    out: dict[str, dict[str, str]] = {}
    for name, path, h in zip(("spec", "model", "certificate"),
                             (spec.spec, spec.model, spec.certificate), spec.hashes,
                             strict=True):
        out[name] = {"path": _shown_path(path), "sha256": h}
    if os.path.isfile(spec.task):
        out["task"] = {"path": _shown_path(spec.task), "sha256": spec.task_sha256}
    else:
        out["task"] = {"entry_point": spec.task, "sha256": spec.task_sha256}
    return out


_MAX_MESSAGE = 4000
"""Longest oracle message a case keeps (``expected.messages``, informational)."""


def case_document(spec: SimSpec, case: Case, verdict: Verdict, *, seed: int,
                  index: int | None = None, shrunk: bool = False,
                  kind: ViolationKind | None = None) -> dict[str, Any]:
    """The JSON case file of a counterexample (``tli replay`` reads it; schema
    ``tli_verify/schemas/case.schema.json``); the expected violation is ``kind`` (the one the
    shrinker kept), default the verdict's primary one.

    Raises
    ------
    ValueError
        The verdict has no violation (a case documents one).
    """
    primary = kind if kind is not None and kind in verdict.kinds else verdict.primary
    if primary is None:
        raise ValueError("case_document: the verdict violates nothing: not a counterexample")
    return {
        "kind": CASE_KIND,
        "version": CASE_VERSION,
        "lag": int(spec.lag),
        "modulation": bool(spec.modulation),
        "max_cycles": None if spec.max_cycles is None else int(spec.max_cycles),
        "window": int(spec.window),
        "files": _files(spec),
        "seed": int(seed),
        "index": None if index is None else int(index),
        "shrunk": bool(shrunk),
        **case_to_json(case),
        "expected": {"violation": primary.value,
                     "violations": sorted(k.value for k in verdict.kinds),
                     "messages": [v.message[:_MAX_MESSAGE] for v in verdict.violations][:5],
                     "oracle_modes": verdict.oracle_modes[:200]},
    }


def _located(case_path: Path, fp: Path) -> Path:
    """A file a case names: absolute, else relative to the case file's directory, else to the
    repository root (the bundled files' parent)."""
    if fp.is_absolute():
        return fp
    from tli_verify.io import bundled_dir

    candidates = [case_path.parent / fp]
    with contextlib.suppress(TliError):
        candidates.append(bundled_dir("models").parent / fp)
    return next((c for c in candidates if c.is_file()), candidates[0])


def _check_case_fields(doc: dict[str, Any], p: Path) -> None:
    """What the schema does not say of a case (after it validated): integers written as floats
    (``700.0``), the limits, one way to name the task per version, and an expected violation
    the run showed.

    Raises
    ------
    CampaignError
        (exit 2) Naming the case file, the field and the limit.
    """
    pushes = doc["perturbations"]
    ints: list[tuple[str, Any, bool]] = [  # (field, value, bounded by MAX_CAMPAIGN_STEPS)
        ("version", doc["version"], False), ("lag", doc["lag"], True),
        ("window", doc["window"], True), ("max_cycles", doc["max_cycles"], True),
        ("seed", doc["seed"], False), ("index", doc["index"], False),
        *((f"perturbations[{i}].step", push["step"], True) for i, push in enumerate(pushes))]
    for name, value, bounded in ints:
        if value is None:
            continue
        if not isinstance(value, int):  # the schema's integers include 700.0
            raise CampaignError(f"{p}: {name}: expected an integer, got {value!r}")
        if bounded and value > MAX_CAMPAIGN_STEPS:
            raise CampaignError(f"{p}: {name}: {value} is above MAX_CAMPAIGN_STEPS "
                                f"({MAX_CAMPAIGN_STEPS} steps)")
    if len(pushes) > MAX_PUSHES:
        raise CampaignError(f"{p}: perturbations: {len(pushes)} perturbations, more than "
                            f"MAX_PUSHES ({MAX_PUSHES})")
    task = doc["files"].get("task")
    if doc["version"] == 1 and task is not None:
        raise CampaignError(f"{p}: files.task: a version 1 case names its task by world; "
                            "files.task is for version 2")
    if doc["version"] == 2:  # the schema requires files.task
        if "world" in doc:
            raise CampaignError(f"{p}: world: a version 2 case binds its task by files.task; "
                                "world is for version 1")
        if ("path" in task) == ("entry_point" in task):
            raise CampaignError(f"{p}: files.task: expected a task path or an entry_point "
                                "(one of the two)")
    expected = doc["expected"]
    if expected["violation"] not in expected["violations"]:
        raise CampaignError(f"{p}: expected.violation: {expected['violation']!r} is not one of "
                            f"expected.violations ({', '.join(expected['violations'])})")


def _hash_input(fp: Path, p: Path, field_: str) -> str:
    """SHA-256 of a file a case names, read like any input: at most ``MAX_INPUT_BYTES``.

    Raises
    ------
    CampaignError
        (exit 2) Unreadable or larger than the limit (``/proc/kcore`` would never end).
    """
    import hashlib

    from tli_verify.limits import MAX_INPUT_BYTES

    try:
        with open(fp, "rb") as handle:
            data = handle.read(MAX_INPUT_BYTES + 1)
    except OSError as exc:
        raise CampaignError(f"{p}: {field_}: {fp}: cannot read ({exc.strerror or exc})"
                            ) from None
    if len(data) > MAX_INPUT_BYTES:
        raise CampaignError(f"{p}: {field_}: {fp}: larger than the limit of {MAX_INPUT_BYTES} "
                            "bytes (MAX_INPUT_BYTES)")
    return hashlib.sha256(data).hexdigest()


def _case_task(doc: dict[str, Any], p: Path) -> tuple[Any, str]:
    """The task a (validated) case names, and the field that names it.

    Raises
    ------
    CampaignError
        (exit 2) A missing task file, an unknown task or one that does not load.
    """
    from tli_verify.tasks.registry import find_task

    if doc["version"] == 1:  # a bundled world by name
        field_, ref = "world", doc["world"]
    else:
        entry = doc["files"]["task"]
        if "path" in entry:
            field_ = "files.task.path"
            ref = _located(p, Path(entry["path"]))
            if not ref.is_file():
                raise CampaignError(f"{p}: {field_}: {ref}: no such task file")
        else:
            field_, ref = "files.task.entry_point", entry["entry_point"]
    try:
        return find_task(ref), field_
    except TliError as exc:
        raise CampaignError(f"{p}: {field_}: {exc}") from None


def read_case(path: str | os.PathLike[str]) -> tuple[dict[str, Any], SimSpec, Case]:
    """Read a case file; the files it names are resolved relative to it when not absolute (else
    to the repository root).

    The file is read with :func:`tli_verify.io.read_json` (bounded; NaN, Infinity and numbers
    that overflow refused) and checked against ``case.schema.json`` before its meaning: the
    limits (``MAX_CAMPAIGN_STEPS``, ``MAX_PUSHES``), the files, the task and their fit
    (:func:`tli_verify.tasks.project.resolve`: the model's dimension, the spec's inputs are the
    task's sensors), the start in the task's workspace, every vector of the task's dimension,
    every target a region of the task.

    Raises
    ------
    CampaignError
        (exit 2) Unreadable, malformed, or naming missing files or files that do not fit; one
        line naming the case file and the field.
    """
    from tli_verify.io import read_json, validate_schema
    from tli_verify.tasks.project import resolve

    p = Path(path)
    if not p.is_file():
        raise CampaignError(f"{p}: no such case file")
    doc = read_json(p, what="case", error=CampaignError)
    validate_schema(doc, "case.schema.json", where=str(p), error=CampaignError)
    _check_case_fields(doc, p)
    paths: list[str] = []
    for name in ("spec", "model", "certificate"):
        fp = _located(p, Path(doc["files"][name]["path"]))
        if not fp.is_file():
            raise CampaignError(f"{p}: files.{name}.path: {fp}: no such file")
        paths.append(str(fp))
    task, task_field = _case_task(doc, p)
    try:  # the files load and fit the task (dimension, sensors = the spec's inputs, goal)
        resolve(task=task, spec=paths[0], model=paths[1], certificate=paths[2])
    except TaskError as exc:  # a misfit (the message names the file and the task)
        raise CampaignError(f"{p}: files and {task_field} do not fit: {exc}") from None
    except TliError as exc:  # a spec or model that does not load (the message names it)
        raise CampaignError(f"{p}: {exc}") from None
    hashes = [_hash_input(Path(fp), p, f"files.{name}.path")
              for name, fp in zip(("spec", "model", "certificate"), paths, strict=True)]
    task_path, task_sha = task_ref(task)
    lag, mc, window = doc["lag"], doc["max_cycles"], doc["window"]
    try:
        case = case_from_json(doc, dim=task.dim, where=str(p))
    except TliError as exc:
        raise CampaignError(str(exc)) from None
    if not bool(task.in_workspace(np.asarray(case.start)[None])[0]):
        raise CampaignError(f"{p}: start {list(case.start)}: outside the workspace of task "
                            f"{task.name!r}")
    for i, push in enumerate(case.pushes):
        if push.target is not None and push.target not in task.region_names:
            raise CampaignError(f"{p}: perturbations[{i}].target: unknown region "
                                f"{push.target!r} of task {task.name!r} (regions: "
                                f"{', '.join(task.region_names)})")
    spec = SimSpec(task=task_path, task_sha256=task_sha, lag=lag, spec=paths[0],
                   model=paths[1], certificate=paths[2],
                   hashes=(hashes[0], hashes[1], hashes[2]),
                   modulation=doc["modulation"], max_cycles=mc,
                   window=max(window, case.last_step))
    return doc, spec, case


def replay_case(path: str | os.PathLike[str], *, modulation: bool | None = None
                ) -> tuple[dict[str, Any], Verdict, bool, list[str]]:
    """Replay a saved case deterministically.

    Parameters
    ----------
    path : path-like
    modulation : bool, optional
        Override the case's setting (e.g. check that LTL-DS fixes a no-modulation case).

    Returns
    -------
    (doc, Verdict, bool, list of str)
        The case document, the verdict now, whether the expected violation reproduced, and
        notes (files whose SHA-256 changed since the case was saved).

    Raises
    ------
    CampaignError
        (exit 2) A bad case file (:func:`read_case`), before anything is simulated.
    """
    doc, spec, case = read_case(path)
    files = doc["files"]
    notes = [f"{name}: {spec_path} changed since the case was saved (SHA-256 differs)"
             for name, spec_path, h in
             zip(("spec", "model", "certificate"), (spec.spec, spec.model, spec.certificate),
                 spec.hashes, strict=True) if files[name]["sha256"] != h]
    if "task" in files and files["task"]["sha256"] != spec.task_sha256:
        notes.append(f"task: {spec.task} changed since the case was saved (SHA-256 differs)")
    if modulation is not None:
        spec = replace(spec, modulation=modulation)
    want = ViolationKind(doc["expected"]["violation"])  # validated: a kind
    verdict = check_case(spec, case)
    return doc, verdict, want in verdict.kinds, notes


# ------------------------------------------------------------------------------ campaign
def _coverage(outcomes: Sequence[RunOutcome], automaton: Any) -> dict[str, Any]:
    edges: set[tuple[int, int]] = set()
    mode_edges: set[tuple[str, str]] = set()
    perturbed: set[str] = set()
    touched = total = 0
    for o in outcomes:
        v = o.verdict
        edges.update(v.edges)
        mode_edges.update(v.mode_edges)
        perturbed.update(v.modes_perturbed)
        touched += v.cut_faces_touched
        total += v.cut_faces
    all_edges = {(t.source, t.target) for t in automaton.transitions if t.source != t.target}
    all_modes = {(a, b) for a, b in automaton.mode_transitions() if a != b}
    run_modes = sorted({s.mode for s in automaton.states})
    return {
        "automaton_edges": {"exercised": len(edges & all_edges), "total": len(all_edges),
                            "list": [list(e) for e in sorted(edges)]},
        "mode_edges": {"exercised": len(mode_edges & all_modes), "total": len(all_modes),
                       "list": ["->".join(e) for e in sorted(mode_edges)]},
        "modes_perturbed": {"perturbed": sorted(perturbed), "modes": run_modes},
        "cut_faces": {"touched": touched, "total": total},
    }


def run_campaign(config: CampaignConfig, *, progress: bool = False,
                 on_event: Callable[[str], None] | None = None) -> CampaignResult:
    """Run a campaign (module docstring).

    Parameters
    ----------
    config : CampaignConfig
    progress : bool, optional
        A tqdm progress bar on stderr.
    on_event : callable, optional
        Called with one line per notable event.

    Returns
    -------
    CampaignResult
        ``partial`` when interrupted by Ctrl-C (the results so far are kept).

    Raises
    ------
    CampaignError, TliError
        (exit 2) Bad configuration or files; (exit 1) the certificate does not cover the model.
    WorkerLost
        A batch's worker died more than twice.
    """
    from tli_verify.verify.backends import make_backend

    t0 = time.perf_counter()
    events: list[str] = []

    def emit(text: str) -> None:
        events.append(text)
        if on_event is not None:
            on_event(text)

    _, config = resolve_config(config)  # the task's defaults filled in (recorded as run)
    spec = sim_spec(config)
    ld = load(spec)
    strategy = _strategy(config, ld)
    outcomes: dict[int, RunOutcome] = {}
    partial = False
    backend = make_backend(config.backend, workers=config.workers,
                           scheduler=config.scheduler, on_event=emit)
    emit(f"drawing {config.examples} cases (seed {config.seed}) and simulating them in "
         f"batches of {config.batch_size} ({config.backend})")
    drawn: dict[int, Case] = {}
    chunk_of: dict[int, int] = {}
    feed: queue.Queue[Any] = queue.Queue()
    stop = threading.Event()

    def produce() -> None:  # hypothesis draws here while the workers simulate
        try:
            for j, chunk in enumerate(draw_chunks(strategy, config.examples, config.seed,
                                                  config.batch_size)):
                if stop.is_set():
                    return
                feed.put((j, chunk))
            feed.put(None)
        except BaseException as exc:  # handed to the driver thread
            feed.put(exc)

    producer = threading.Thread(target=produce, name="tli-verify-draw", daemon=True)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=config.examples, unit="run", desc="campaign", leave=False)
    producer.start()
    try:
        finished = False
        while not finished:
            wave = [feed.get()]
            while True:  # everything drawn meanwhile joins this wave
                try:
                    wave.append(feed.get_nowait())
                except queue.Empty:
                    break
            jobs = []
            for item in wave:
                if item is None:
                    finished = True
                elif isinstance(item, BaseException):
                    raise item
                else:
                    j, chunk = item
                    for i, c in chunk:
                        drawn[i] = c
                        chunk_of[i] = j
                    jobs.append((spec, chunk))
            for _, batch in backend.map_unordered(simulate_batch, jobs):
                for o in batch:
                    outcomes[o.index] = o
                if bar is not None:
                    bar.update(len(batch))
    except KeyboardInterrupt:
        partial = True
        emit(f"interrupted after {len(outcomes)} of {config.examples} runs: partial results")
    finally:
        stop.set()
        backend.close()
        if bar is not None:
            bar.close()
    ordered = tuple(outcomes[i] for i in sorted(outcomes))
    failing = [o for o in ordered if not o.verdict.ok]
    first_any = failing[0] if failing else None
    # the counterexample: the first run of the most specific kind found (PRIORITY), so a
    # campaign that finds Fig. 7's looping shrinks a looping run, not an earlier lone failure
    kind = next((k for k in PRIORITY if any(k in o.verdict.kinds for o in failing)), None)
    first = next((o for o in failing if kind in o.verdict.kinds), None)
    counterexample = None
    first_at = None
    shrink_steps = 0
    known = {drawn[o.index]: o.verdict for o in ordered}
    if first is not None and kind is not None and first_any is not None:
        first_at = first_any.index + 1
        case, verdict = drawn[first.index], first.verdict
        shrunk = False
        if config.shrink and not partial:
            j = chunk_of[first.index]
            try:
                small, v, shrink_steps = shrink(spec, strategy, chunk_seed(config.seed, j),
                                                config.batch_size + 10, kind, known)
            except KeyboardInterrupt:
                small, v = None, None
                partial = True
                emit("interrupted while shrinking: the counterexample is not shrunk")
            if small is not None and v is not None:
                case, verdict, shrunk = small, v, True
        counterexample = case_document(spec, case, verdict, seed=config.seed,
                                       index=first.index, shrunk=shrunk, kind=kind)
    elif config.target_examples > 0 and not partial:
        found, v, shrink_steps = _targeted(spec, strategy, config.seed,
                                           config.target_examples)
        if found is not None and v is not None:
            counterexample = case_document(spec, found, v, seed=config.seed, shrunk=True)
            first_at = len(ordered) + shrink_steps
    violations = {k.value: sum(1 for o in ordered if k in o.verdict.kinds)
                  for k in ViolationKind}
    runs = len(ordered)
    return CampaignResult(
        config=config, runs=runs, violations=violations,
        task_satisfied=sum(1 for o in ordered if o.verdict.reached),
        cuts_added=sum(o.cuts_added for o in ordered),
        coverage=_coverage(ordered, ld.automaton), counterexample=counterexample,
        first_counterexample_at=first_at,
        failure_bound=(3.0 / runs if counterexample is None and runs > 0 else None),
        partial=partial, outcomes=ordered, seconds=time.perf_counter() - t0,
        inconclusive=sum(1 for o in ordered if not o.verdict.conclusive),
        shrink_steps=shrink_steps, events=tuple(events),
        files=_files(spec), task_name=ld.world.name)
