"""Closed-loop episodes on a task: starts, perturbation tables, runners and records.

* starts: :func:`random_start` -- a seeded uniform state of the task's start region whose first
  reading the spec's initial assumption allows;
* perturbations: ``{step: displacement}`` tables, :func:`random_perturbations` (directions
  uniform on the sphere ``S^{n-1}``, magnitudes uniform up to the task's bound, the paper's
  "uniformly sampled in all directions of any magnitudes up to the dimension of the entire
  workspace"); :func:`pusher` applies a table, keeping states in the workspace box;
* :func:`run_variant` / :func:`run_variant_batch` -- one or many episodes of a policy variant
  (:data:`tli_verify.runtime.setup.VARIANTS`), batched with
  :func:`~tli_verify.runtime.loop.run_episodes`;
* :func:`mode_runs`, :func:`mode_string`, :func:`episode_json` -- what an episode did.

The policy only sees what the task's sensors read
(:class:`~tli_verify.runtime.task_sensors.TaskSensors`) and is told when a perturbation happened
(as a robot's controller notices a push).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.boundary.modulation import modulated
from tli_verify.errors import TaskError, TliError
from tli_verify.logic.automaton import AssumptionViolation
from tli_verify.runtime.events import event_to_json, mode_sequence
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.loop import EpisodeResult, batch_results, run_episode, run_episodes
from tli_verify.runtime.setup import Setup, make_policy
from tli_verify.runtime.task_sensors import TaskSensors
from tli_verify.tasks.task import Task

__all__ = [
    "MAX_START_DRAWS",
    "episode_json",
    "mode_runs",
    "mode_string",
    "pusher",
    "random_direction",
    "random_perturbations",
    "random_start",
    "run_variant",
    "run_variant_batch",
]

FloatArray = npt.NDArray[np.float64]
MAX_START_DRAWS = 10_000
"""Uniform draws :func:`random_start` tries before it gives up."""


def random_start(task: Task, automaton: Any, rng: np.random.Generator, *,
                 tries: int = MAX_START_DRAWS) -> FloatArray:
    """A uniform random state (in the task's start region, default its workspace) whose first
    reading is an initial one of the automaton (the spec's ``assume.init``), shape (n,).

    Raises
    ------
    TaskError
        (exit 2) No such state in ``tries`` draws.
    """
    lo, hi = np.array(task.lo), np.array(task.hi)
    region = task.starts.region
    if region is not None:
        lo, hi = task._region_box(region)
    names = task.sensor_names
    for _ in range(tries):
        x = rng.uniform(lo, hi)
        if region is not None and not bool(task.in_region(region, x[None])[0]):
            continue
        reading = task.sensors(x[None])[0]
        try:
            automaton.initial_state({n: bool(v) for n, v in zip(names, reading, strict=True)})
        except AssumptionViolation:
            continue
        return np.asarray(x, dtype=np.float64)
    raise TaskError(f"{task.where}: no start with an initial reading in {tries} uniform draws"
                    + (f" of region {region!r}" if region is not None else ""))


def random_direction(rng: np.random.Generator, dim: int) -> FloatArray:
    """A uniform unit vector of ``R^dim``, shape (dim,): by angle in 2-D, a normalised normal
    draw otherwise (redrawn if it is near zero)."""
    if dim == 2:
        ang = rng.uniform(0.0, 2.0 * np.pi)
        return np.array([np.cos(ang), np.sin(ang)])
    while True:
        v = rng.normal(size=dim)
        n = float(np.linalg.norm(v))
        if n > 1e-12:
            return np.asarray(v / n, dtype=np.float64)


def random_perturbations(rng: np.random.Generator, count: int, task: Task, *, first: int = 1,
                         last: int = 700, max_magnitude: float | None = None
                         ) -> dict[int, FloatArray]:
    """``count`` perturbations at distinct random steps in ``[first, last]``.

    Directions uniform on the sphere (:func:`random_direction`), magnitudes uniform in
    ``[0, D]`` with ``D`` the task's bound (default: ``perturbations.max_magnitude``, else the
    workspace's largest side).

    Returns
    -------
    dict of int to ndarray, shape (n,)
        Step (1-based) -> displacement.

    Raises
    ------
    TaskError
        ``count`` exceeds the steps of the window (each step is perturbed at most once).
    """
    size = (max_magnitude if max_magnitude is not None
            else task.perturbations.max_magnitude if task.perturbations.max_magnitude is not None
            else task.size)
    span = last - first + 1
    if count > span:
        raise TaskError(f"{count} perturbations in steps {first}..{last}: at most one per "
                        f"step ({span})")
    steps = rng.choice(np.arange(first, last + 1), size=count, replace=False)
    out = {}
    for t in sorted(int(s) for s in steps):
        d = random_direction(rng, task.dim)  # the direction first, then the magnitude
        out[t] = rng.uniform(0.0, size) * d
    return out


def pusher(task: Task, table: Mapping[int, npt.ArrayLike]
           ) -> Callable[[int, FloatArray], FloatArray | None]:
    """``push(t, x)``: the state after the perturbation of step ``t`` (clipped to the
    workspace box), or None at a step without one."""
    lo, hi = np.array(task.lo), np.array(task.hi)

    def push(t: int, x: FloatArray) -> FloatArray | None:
        d = table.get(t)
        if d is None:
            return None
        return np.asarray(np.clip(x + np.asarray(d, dtype=np.float64), lo, hi))

    return push


def run_variant(setup: Setup, variant: str, x0: npt.ArrayLike,
                perturbations: Mapping[int, npt.ArrayLike] | None = None, *,
                steps: int = 3000, policy: LTLDSPolicy | None = None) -> EpisodeResult:
    """One closed-loop episode of a variant (:func:`run_variant_batch` for many)."""
    if variant == "BC":
        return run_variant_batch(setup, variant, np.atleast_2d(np.asarray(x0, float)),
                                 [dict(perturbations or {})], steps=steps, policy=policy)[0]
    pol = policy if policy is not None else make_policy(setup, variant)
    return run_episode(pol, TaskSensors(setup.task), x0, steps=steps,
                       perturb=pusher(setup.task, perturbations or {}))


def run_variant_batch(setup: Setup, variant: str, starts: npt.ArrayLike,
                      perturbations: Sequence[Mapping[int, npt.ArrayLike]], *,
                      steps: int = 3000, policy: LTLDSPolicy | None = None
                      ) -> list[EpisodeResult]:
    """Episodes from many starts at once, each with its own perturbation table.

    Every episode starts from the same (fresh) policy: cuts learned in one episode do not carry
    to the others (each episode is an independent trial).
    """
    X = np.asarray(starts, dtype=np.float64)
    base = policy if policy is not None else make_policy(setup, variant)
    policies = [base.fork() for _ in range(len(X))]
    memo: dict[Any, Any] = {}
    sensors = [TaskSensors(setup.task, cache=memo) for _ in range(len(X))]
    pushers = [pusher(setup.task, p) for p in perturbations]

    def perturb(i: int, t: int, x: FloatArray) -> FloatArray | None:
        return pushers[i](t, x)

    if variant != "BC":
        return run_episodes(policies, sensors, X, steps=steps, perturb=perturb)
    return _run_bc(setup, policies, sensors, X, steps=steps, perturb=perturb)


def _run_bc(setup: Setup, policies: Sequence[LTLDSPolicy], sensors: Sequence[TaskSensors],
            X: FloatArray, *, steps: int,
            perturb: Callable[[int, int, FloatArray], FloatArray | None]
            ) -> list[EpisodeResult]:
    """:func:`run_episodes` with the BC nets moving the state (modulated by the cuts the
    executive learns for the mode's region, :func:`tli_verify.boundary.modulation.modulated`)."""
    if not setup.bc:
        raise TliError("the BC variant needs BC nets (Setup.bc)")
    X = X.copy()
    N = len(X)
    for i, (pol, sen) in enumerate(zip(policies, sensors, strict=True)):
        sen.reset(X[i].copy())
        pol.reset(X[i], sen.read(X[i]))
    dt = policies[0].dt
    cache: dict[tuple[str, int], tuple[Any, Any]] = {}
    hist = [X.copy()]
    modes = [[p.mode for p in policies]]
    astates = [[-1 if p.state is None else p.state for p in policies]]
    active = np.ones(N, dtype=bool)
    taken = np.zeros(N, dtype=np.int64)
    for _ in range(steps):
        groups: dict[tuple[str, int, int], list[int]] = {}
        for i in np.flatnonzero(active).tolist():
            pol = policies[i]
            if pol.done and not pol.holding:
                active[i] = False
                continue
            pushed = perturb(i, int(taken[i]) + 1, X[i].copy())
            if pushed is not None:
                X[i] = pushed
            key = pol.decide(X[i], sensors[i].read(X[i]), perturbed=pushed is not None)
            taken[i] += 1
            if key:
                groups.setdefault((key, id(pol.model), i if pol.model.modes[key].cuts else -1),
                                  []).append(i)
        if not active.any():
            break
        V = np.zeros_like(X)
        for (key, _, _), rows in groups.items():
            mm = policies[rows[0]].model.modes[key]
            net = setup.bc.get(key) or setup.bc[mm.mode]
            if not mm.cuts:
                V[rows] = net.velocity(X[rows])
                continue
            # keyed by the mode model's identity; the entry keeps the object alive, so its id
            # cannot be reused by a later model (with other cuts) while the entry exists
            ck = (key, id(mm))
            hit = cache.get(ck)
            if hit is None or hit[0] is not mm:
                hit = (mm, modulated(net, mm.cuts, mm.ds.attractor, dt=dt))
                cache[ck] = hit
            V[rows] = hit[1].velocity(X[rows])
        X += dt * V
        hist.append(X.copy())
        modes.append([p.mode for p in policies])
        astates.append([-1 if p.state is None else p.state for p in policies])
    return batch_results(policies, hist, modes, astates, taken)


def mode_runs(seq: Sequence[Any]) -> list[list[Any]]:
    """Run-length form ``[[value, first_step], ...]`` of a per-step sequence."""
    out: list[list[Any]] = []
    for t, v in enumerate(seq):
        if not out or out[-1][0] != v:
            out.append([v, t])
    return out


def mode_string(res: EpisodeResult) -> str:
    """The modes an episode visited (:func:`tli_verify.runtime.events.mode_sequence`)."""
    return mode_sequence(res.modes)


def episode_json(res: EpisodeResult, *, task: str, variant: str, seconds: float,
                 x0: FloatArray, perturbations: Mapping[int, npt.ArrayLike],
                 dt: float) -> dict[str, Any]:
    """The ``tli run --json`` record of one episode."""
    return {
        "task": task,
        "variant": variant,
        "success": bool(res.success),
        "steps": int(res.steps),
        "dt": dt,
        "sim_time": res.steps * dt,
        "seconds": seconds,
        "start": [float(v) for v in x0],
        "final_state": [float(v) for v in res.states[-1]],
        "perturbations": [{"step": int(t),
                           "displacement": np.asarray(d, dtype=np.float64).tolist()}
                          for t, d in sorted(perturbations.items())],
        "mode_sequence": mode_string(res),
        "mode_trace": mode_runs(res.modes),
        "automaton_states": mode_runs(res.automaton_states),
        "cuts_added": int(res.cuts_added),
        "cuts": {m: [c.to_dict() for c in res.model.region_cuts(m)]
                 for m in sorted({mm.mode for mm in res.model.modes.values()})
                 if res.model.region_cuts(m)},
        "events": [event_to_json(e) for e in res.events],
    }
