"""The closed loop around the executive (paper eq. 6 integrated in time).

* :func:`run_episode` -- one episode: a sensor model, explicit Euler steps of the control
  period, a speed cap, scheduled perturbations, and the stop predicate (the goal, or a
  caller's, e.g. the campaigns' looping watchdog);
* :func:`run_episodes` -- many at once, the DS evaluated batched (same results per start);
* :class:`EpisodeResult` -- what an episode did; :class:`SensorModel` -- what a task provides.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, cast

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TliError
from tli_verify.model.types import Model
from tli_verify.runtime.events import (
    CutAdded,
    Event,
    mode_sequence,
)
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.rollout import cap_speed
from tli_verify.runtime.task_sensors import TaskSensors

FloatArray = npt.NDArray[np.float64]

__all__ = [
    "EpisodeResult",
    "Perturb",
    "SensorModel",
    "Stop",
    "StopMany",
    "batch_results",
    "run_episode",
    "run_episodes",
]


class SensorModel(Protocol):
    """What a task provides to the closed loop (tasks implement it, paper Sec. 3).

    ``reset(x0)`` starts an episode (a sensor may keep a history, e.g. a lag); ``read(x)``
    is called once per control step, in order, and returns the reading at ``x``.
    """

    def reset(self, x0: FloatArray) -> None:  # pragma: no cover - protocol
        """Start an episode at ``x0``."""
        ...

    def read(self, x: FloatArray) -> Mapping[str, bool]:  # pragma: no cover - protocol
        """The sensor reading at ``x`` (input name -> value)."""
        ...


@dataclass(frozen=True, slots=True, eq=False)
class EpisodeResult:
    """One closed-loop episode (what :func:`tli_verify.run` returns; ``tli run`` writes the
    same episode to ``run.json``).

    Attributes
    ----------
    success : bool
        A goal mode was reached (with the task's goal sensors, if any) within the step budget.
    steps : int
        Control steps taken (each ``dt`` of the task long).
    states : ndarray, shape (steps + 1, n)
        The state at each step, the start first (``states[t]`` is the state the mode
        ``modes[t]`` ran at), in the task's state coordinates.
    modes : tuple of str
        The mode run at each step, one entry per step (``len = steps + 1``; index 0 after
        ``reset``). Collapsed to the modes visited: :attr:`mode_sequence`.
    automaton_states : tuple of int
        The task automaton's state at each step (``len = steps + 1``), as numbered by
        :class:`~tli_verify.logic.automaton.TaskAutomaton`.
    events : tuple of Event
        What the executive reported, in order: mode changes, replans, invariance failures,
        cuts added (or failed), perturbations, assumption violations
        (:mod:`tli_verify.runtime.events`).
    cuts_added : int
        Cuts learned online in this episode (modulation on; 0 without it).
    model : Model
        The model at the end (with the cuts learned online).
    mode_sequence : str
        (property) The modes visited, in order, repeats collapsed (``"abcd"``; names longer
        than one character joined by ``-``): the ``mode_sequence`` of ``run.json``.
    """

    success: bool
    steps: int
    states: FloatArray
    modes: tuple[str, ...]
    automaton_states: tuple[int, ...]
    events: tuple[Event, ...]
    cuts_added: int
    model: Model

    @property
    def mode_sequence(self) -> str:
        """The modes visited, in order, repeats collapsed (``run.json``'s ``mode_sequence``)."""
        return mode_sequence(self.modes)


Perturb = Callable[[int, FloatArray], "FloatArray | None"]
Stop = Callable[[LTLDSPolicy], bool]
"""A stop predicate of :func:`run_episode`: ``stop(policy)`` before each step; true ends the
episode (unless the executive holds). It may keep state (one predicate per episode)."""
StopMany = Callable[[int, LTLDSPolicy], bool]
"""A stop predicate of :func:`run_episodes`: ``stop(i, policy)`` for episode ``i``."""


def run_episode(
    policy: LTLDSPolicy,
    sensors: SensorModel,
    x0: npt.ArrayLike,
    *,
    steps: int = 2000,
    speed_cap: float = np.inf,
    perturb: Perturb | Mapping[int, npt.ArrayLike] | None = None,
    stop_at_goal: bool = True,
    stop: Stop | None = None,
) -> EpisodeResult:
    """Run the executive in closed loop: ``x_{t+1} = x_t + dt cap(step(x_t, read(x_t)))``.

    Parameters
    ----------
    policy : LTLDSPolicy
        Its learned cuts carry over between episodes (``policy.model``).
    sensors : SensorModel
    x0 : array_like, shape (n,)
    steps : int, optional
        Step budget.
    speed_cap : float, optional
        Velocities faster than this are rescaled (direction kept).
    perturb : callable or mapping, optional
        ``perturb(t, x) -> new state or None`` before step ``t`` (1-based), or ``{t: new
        state}``; the executive is told (``perturbed=True``).
    stop_at_goal : bool, optional
        End when the executive is in a goal mode.
    stop : callable, optional
        ``stop(policy) -> bool``, asked before each step once the goal is not reached (e.g.
        :class:`tli_verify.verify.simulate.LoopWatchdog`): true ends the episode, unless the
        executive holds. The result's ``success`` stays the goal's.

    Returns
    -------
    EpisodeResult
    """
    x = np.array(x0, dtype=np.float64).reshape(-1)
    sensors.reset(x.copy())
    policy.reset(x, sensors.read(x))
    dt = policy.dt
    states = [x.copy()]
    modes = [policy.mode]
    astates = [policy.state if policy.state is not None else -1]
    table = dict(perturb) if isinstance(perturb, Mapping) else None
    capped = bool(np.isfinite(speed_cap))  # speed > inf never holds
    t = 0
    for t in range(1, steps + 1):
        if ((stop_at_goal and policy.done) or (stop is not None and stop(policy))) \
                and not policy.holding:
            t -= 1
            break
        pushed: Any = None
        if table is not None:
            pushed = table.get(t)
        elif callable(perturb):
            pushed = perturb(t, x.copy())
        if pushed is not None:
            x = np.array(pushed, dtype=np.float64).reshape(-1)
        v = policy.step(x, sensors.read(x), perturbed=pushed is not None)
        if capped:
            speed = math.sqrt(float(v @ v))  # what np.linalg.norm computes for a vector
            if speed > speed_cap:
                v = v * (speed_cap / speed)
        x = x + dt * v  # a new array each step: the history needs no copy
        states.append(x)
        modes.append(policy.mode)
        astates.append(policy.state if policy.state is not None else -1)
    added = sum(1 for e in policy.events if isinstance(e, CutAdded))
    return EpisodeResult(success=policy.done and not policy.holding, steps=t,
                         states=np.array(states), modes=tuple(modes),
                         automaton_states=tuple(astates), events=tuple(policy.events),
                         cuts_added=added, model=policy.model)


def run_episodes(
    policies: Sequence[LTLDSPolicy],
    sensors: Sequence[SensorModel],
    starts: npt.ArrayLike,
    *,
    steps: int = 2000,
    speed_cap: float = np.inf,
    perturb: Callable[[int, int, FloatArray], FloatArray | None] | None = None,
    stop: StopMany | None = None,
) -> list[EpisodeResult]:
    """Many closed-loop episodes at once: the velocities are evaluated batched.

    Each episode has its own executive (automaton state, events, learned cuts) and sensor
    model; per step the automaton and monitor advance episode by episode (cheap), and the DS
    run by episodes that share a model and a key are evaluated in one vectorised call (the
    expensive part). Same results as :func:`run_episode` per start, up to float rounding of
    the batched evaluation.

    Parameters
    ----------
    policies : sequence of LTLDSPolicy
        One per start (e.g. ``[copy.copy(p) ...]`` or policies built from one model: episodes
        that share a model object share a batch).
    sensors : sequence of SensorModel
        One per start.
    starts : array_like, shape (N, n)
    steps : int, optional
    speed_cap : float, optional
    perturb : callable, optional
        ``perturb(i, t, x) -> new state or None`` for episode ``i`` before its step ``t``
        (1-based); the executive is told (``perturbed=True``), as in :func:`run_episode`.
    stop : callable, optional
        ``stop(i, policy) -> bool`` for episode ``i``, as in :func:`run_episode`.

    Returns
    -------
    list of EpisodeResult
    """
    X = np.array(starts, dtype=np.float64)
    N = X.shape[0]
    if not (len(policies) == len(sensors) == N):
        raise TliError(f"need one policy and one sensor model per start: {len(policies)}, "
                       f"{len(sensors)}, {N}")

    for i, (pol, sen) in enumerate(zip(policies, sensors, strict=True)):
        sen.reset(X[i].copy())
        pol.reset(X[i], sen.read(X[i]))
    dts = np.array([pol.dt for pol in policies])[:, None]
    hist_x = [X.copy()]
    hist_mode = [[pol.mode for pol in policies]]
    hist_state = [[-1 if pol.state is None else pol.state for pol in policies]]
    live = list(range(N))  # the active episodes
    taken = [0] * N
    # Fast path per episode (same results): a state checked for the whole batch at once and a
    # reading as the set of true sensors (a TaskSensors whose names the automaton reads) for
    # an executive whose decide() is LTLDSPolicy's own (a subclass may override it, e.g. the
    # no-replan ablation); anything else goes through decide(), which checks and raises as
    # run_episode does.
    lean = [isinstance(sen, TaskSensors) and set(sen.names) <= pol._inputs
            and type(pol).decide is LTLDSPolicy.decide
            and X.ndim == 2 and X.shape[1] == pol.model.dim
            for pol, sen in zip(policies, sensors, strict=True)]
    for _ in range(steps):
        groups: dict[tuple[int, str], list[int]] = {}
        Xc = X.copy()  # this step's states: rows are recorded by the executives, never updated
        ok = cast("list[bool]", np.isfinite(Xc).all(axis=1).tolist())
        pts: list[list[float]] = Xc.tolist()
        still = []
        for i in live:
            pol = policies[i]
            if (pol.done or (stop is not None and stop(i, pol))) and not pol.holding:
                continue
            still.append(i)
            xi = Xc[i]
            pushed = perturb(i, taken[i] + 1, xi.copy()) if perturb is not None else None
            if pushed is not None:
                X[i] = np.asarray(pushed, dtype=np.float64).reshape(-1)
                xi[:] = X[i]
                if lean[i]:
                    pts[i] = xi.tolist()
                    ok[i] = bool(np.isfinite(xi).all())
            if lean[i] and ok[i]:
                reading = sensors[i].read_set(xi, pts[i])  # type: ignore[attr-defined]
                key = pol._decide(xi, reading, pushed is not None)
            else:
                key = pol.decide(X[i], sensors[i].read(X[i]), perturbed=pushed is not None)
            taken[i] += 1
            if key:
                groups.setdefault((id(pol._model), key), []).append(i)
        live = still
        if not live:
            break
        V = np.zeros_like(X)
        # the DS once per distinct LPV-DS (episodes whose models differ only in the cuts they
        # learned share it), then each group's own modulation
        by_ds: dict[int, tuple[Any, list[int]]] = {}
        mms = []
        for (_, key), rows in groups.items():
            mm = policies[rows[0]].model.modes[key]
            mms.append((mm, rows))
            by_ds.setdefault(id(mm.ds), (mm.ds, []))[1].extend(rows)
        F = np.zeros_like(X)
        for ds, rows in by_ds.values():
            F[rows] = ds.velocity(X[rows])
        for mm, rows in mms:
            V[rows] = mm.modulate(X[rows], F[rows], dt=policies[rows[0]].dt)
        if np.isfinite(speed_cap):

            cap_speed(V, speed_cap)
        X += dts * V  # held and finished episodes have V = 0
        hist_x.append(X.copy())
        hist_mode.append([pol.mode for pol in policies])
        hist_state.append([-1 if pol.state is None else pol.state for pol in policies])
    return batch_results(policies, hist_x, hist_mode, hist_state,
                         np.array(taken, dtype=np.int64))


def batch_results(policies: Sequence[LTLDSPolicy], hist_x: Sequence[FloatArray],
                  hist_mode: Sequence[Sequence[str]], hist_state: Sequence[Sequence[int]],
                  taken: npt.NDArray[np.int64]) -> list[EpisodeResult]:
    """The per-episode results of a batched closed loop.

    Parameters
    ----------
    policies : sequence of LTLDSPolicy, length B
    hist_x : sequence of ndarray, each shape (B, n)
        States of the whole batch at every step (the first is the starts).
    hist_mode, hist_state : sequence of sequence, each of length B
        Modes and automaton states (-1 for none) of the batch at every step.
    taken : ndarray of int, shape (B,)
        Steps each episode actually took.

    Returns
    -------
    list of EpisodeResult
    """
    path = np.array(hist_x)
    out = []
    for i, pol in enumerate(policies):
        T = int(taken[i]) + 1
        out.append(EpisodeResult(
            success=pol.done and not pol.holding, steps=T - 1, states=path[:T, i].copy(),
            modes=tuple(m[i] for m in hist_mode[:T]),
            automaton_states=tuple(s[i] for s in hist_state[:T]),
            events=tuple(pol.events),
            cuts_added=sum(1 for e in pol.events if isinstance(e, CutAdded)), model=pol.model))
    return out
