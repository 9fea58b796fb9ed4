"""Simulating campaign cases: per-process loading and the vectorised closed loop.

* :func:`load` -- once per process, what the runs of a :class:`~.config.SimSpec` need
  (:class:`Loaded`: the task, automaton, certified model, base policy, oracle), each file
  re-hashed against the driver's;
* :func:`simulate` -- cases in one :func:`~tli_verify.runtime.loop.run_episodes` batch, each run
  ended at a goal mode, at the step budget, or by the :class:`LoopWatchdog`;
* :func:`simulate_batch` -- a worker's task (simulate, then the oracle on every trace);
  :func:`check_case` -- one case in this process.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import CampaignError, TliError
from tli_verify.io import sha256_file
from tli_verify.loaded import load_project
from tli_verify.logic.automaton import AssumptionViolation
from tli_verify.runtime.episodes import mode_string
from tli_verify.runtime.events import CutAdded
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.loop import run_episodes
from tli_verify.runtime.task_sensors import TaskSensors
from tli_verify.snapshot import Snapshot, current
from tli_verify.tasks.project import check_goal
from tli_verify.tasks.registry import find_task
from tli_verify.tasks.task import Task
from tli_verify.verify.config import SimSpec, task_ref
from tli_verify.verify.oracle import (
    CutRecord,
    Oracle,
    Trace,
    Verdict,
)
from tli_verify.verify.strategies import (
    Case,
    apply_push,
)

FloatArray = npt.NDArray[np.float64]

__all__ = [
    "Loaded",
    "LoopWatchdog",
    "RunOutcome",
    "check_case",
    "load",
    "load_task",
    "simulate",
    "simulate_batch",
    "start_regions",
]


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
    cuts_by_mode : tuple of (str, int)
        The cuts learned online, per mode (sorted by mode).
    """

    index: int
    verdict: Verdict
    steps: int
    cuts_added: int
    modes: str
    cuts_by_mode: tuple[tuple[str, int], ...] = ()


class LoopWatchdog:
    """A stop predicate of the closed loop (:func:`~tli_verify.runtime.loop.run_episodes`):
    ends an episode whose looping verdict is already decided (not the policy's logic).

    For episode ``i``, true once, after its step ``after[i]`` (its last perturbation), the
    executive has reported more than ``limit`` events since the last cut it learned (every such
    event comes with a mode change, at most 5 per change, so by then the run has re-entered
    visited modes more than the oracle's loop bound allows), or more than ``max_cuts`` cuts.

    Parameters
    ----------
    after : sequence of int
        Per episode, the step after which the watchdog is armed.
    limit : int
        Events allowed since the last learned cut.
    max_cuts : int
        Cuts allowed.
    """

    __slots__ = ("_after", "_cuts", "_limit", "_mark", "_max_cuts", "_seen")

    def __init__(self, after: Sequence[int], limit: int, max_cuts: int) -> None:
        self._after = [int(a) for a in after]
        self._limit = int(limit)
        self._max_cuts = int(max_cuts)
        self._mark = [-1] * len(self._after)
        self._seen = [0] * len(self._after)
        self._cuts = [0] * len(self._after)

    def __call__(self, i: int, policy: LTLDSPolicy) -> bool:
        """Whether episode ``i`` (run by ``policy``) is to end now."""
        if policy.steps < self._after[i]:
            return False
        events = policy.events
        n = len(events)
        if self._mark[i] < 0:
            self._mark[i] = self._seen[i] = n
        elif n > self._seen[i]:  # each event is looked at once
            for k in range(self._seen[i], n):
                if isinstance(events[k], CutAdded):
                    self._mark[i] = k + 1  # a learned cut restarts the loop count
                    self._cuts[i] += 1
            self._seen[i] = n
        return n - self._mark[i] > self._limit or self._cuts[i] > self._max_cuts


@dataclass(frozen=True, slots=True, eq=False)
class Loaded:
    """A loaded setup: task, automaton, certified model, base policy, oracle."""

    task: Task
    automaton: Any
    model: Any
    certificate: str
    policy: LTLDSPolicy
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
    task = find_task(spec.task)
    _, sha = task_ref(task)
    if sha != spec.task_sha256:
        raise CampaignError(f"{spec.task}: the task changed during the campaign (SHA-256 "
                            "differs)")
    return task.with_lag(spec.lag)


@lru_cache(maxsize=4)
def load(spec: SimSpec) -> Loaded:
    """Load (once per process) what the runs of a :class:`SimSpec` need, through the project
    loader (:func:`tli_verify.loaded.load_project`) inside one snapshot: the SHA-256 checked
    and the files parsed are the same bytes.

    Raises
    ------
    CampaignError
        (exit 2) A file's SHA-256 differs from the driver's (the files changed under the
        campaign).
    """
    snap = current() or Snapshot()  # the driver's (serial backend), else this worker's
    with snap.use():
        for path, want in zip((spec.spec, spec.model, spec.certificate), spec.hashes,
                              strict=True):
            if sha256_file(path) != want:
                raise CampaignError(f"{path}: changed during the campaign (SHA-256 differs)")
        task = load_task(spec)
        project = load_project(task=task, spec=spec.spec, model=spec.model,
                               certificate=spec.certificate)
        automaton = project.automaton  # synthesized once, its goal checked reachable
        # one goal for the policy and the oracle: the spec's, else the task's, else the sinks
        goal_modes = check_goal(automaton, project.goal, where=spec.spec)
        goal_inputs = project.goal.sensors
        base = LTLDSPolicy(automaton, project.model, spec.certificate,
                           learn_cuts=spec.modulation, goal_modes=goal_modes,
                           goal_inputs=goal_inputs, dt=task.dt)
        if not spec.modulation:  # the ablation runs the nominal DS (make_policy's rule)
            base.drop_cuts()
        oracle = Oracle.build(task, automaton, project.model, spec.certificate, dt=base.dt,
                              max_cycles=spec.max_cycles, goal_modes=goal_modes,
                              goal_inputs=goal_inputs)
    limit = 5 * (oracle.max_cycles + len(automaton.modes) + 1)
    return Loaded(task=task, automaton=automaton, model=project.model,
                  certificate=spec.certificate, policy=base, oracle=oracle,
                  budget=oracle.budget(spec.window), limit=limit)


def start_regions(task: Task, automaton: Any) -> tuple[str, ...]:
    """The true regions whose first reading (from the initial latent state) is one the spec's
    initial assumption allows."""
    out = []
    for name in task.region_names:
        try:
            x = task.sample_region(name, 1, np.random.default_rng(0))
        except TliError:
            continue
        reading = task.sensors(x)[0]
        true = [n for n, v in zip(task.sensor_names, reading.tolist(), strict=True) if v]
        try:
            automaton.initial_state(true)
        except AssumptionViolation:
            continue
        out.append(name)
    return tuple(out)


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
    ld = load(spec)
    if not cases_:
        return []
    X = np.array([c.start for c in cases_], dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != ld.model.dim:
        raise CampaignError(f"case start: expected {ld.model.dim} coordinates")
    tables = [c.table() for c in cases_]
    pushed: list[dict[int, FloatArray]] = [{} for _ in cases_]
    task = ld.task

    def perturb(i: int, t: int, x: FloatArray) -> FloatArray | None:
        p = tables[i].get(t)
        if p is None:
            return None
        new = apply_push(task, x, p)
        pushed[i][t] = new
        return new

    policies = [ld.policy.fork() for _ in cases_]
    watchdog = LoopWatchdog([c.last_step for c in cases_], ld.limit, ld.oracle.max_cuts)
    memo: dict[Any, Any] = {}
    sensors = [TaskSensors(task, cache=memo) for _ in cases_]
    results = run_episodes(policies, sensors, X, steps=ld.budget if budget is None else budget,
                           perturb=perturb, stop=watchdog)
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

    spec, items = job
    with threadpoolctl.threadpool_limits(1):
        sims = simulate(spec, [c for _, c in items])
        verdicts = load(spec).oracle.check_many([tr for tr, _ in sims])
    from collections import Counter

    return [RunOutcome(index=i, verdict=v, steps=res.steps, cuts_added=res.cuts_added,
                       modes=mode_string(res),
                       cuts_by_mode=tuple(sorted(Counter(
                           e.mode for e in res.events if isinstance(e, CutAdded)).items())))
            for (i, _), (_, res), v in zip(items, sims, verdicts, strict=True)]


def check_case(spec: SimSpec, case: Case) -> Verdict:
    """Simulate one case in this process and return the oracle's verdict."""
    (trace, _), = simulate(spec, [case])
    return load(spec).oracle.check(trace)
