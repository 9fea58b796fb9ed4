"""The bisimulation oracle: four checks on every closed-loop trace (paper Sec. 4.4, Thm. 2).

The oracle is independent of the policy code (:mod:`tli_verify.runtime.executive`). It reads

* the **trace**: the states, the state each sensor reading was taken at, the modes the policy
  ran, the steps that were perturbed, and the cuts the policy reported (data, re-checked
  geometrically);
* the **task's true regions and sensor model** (:meth:`~tli_verify.tasks.task.Task.sensors`,
  the vectorised whole-history scan, not the runtime's incremental reader);
* the **task automaton** (:mod:`tli_verify.logic.automaton`), run by the oracle itself on the
  recomputed readings;
* the **certificate** (``P`` and the decay rate of each DS) and the model's DS parameters
  (attractors, ``A_k``) for the reachability deadline.

Checks (violation kinds, :class:`ViolationKind`):

1. **Invariance** -- every mode change (of the oracle's own automaton run) is planned (a move
   toward the goal: a successor of the mode at the least distance to a goal mode in the
   automaton's mode graph, or the model's ``next_mode``) or caused by a perturbation (one in
   the ``lag + 1`` steps before). Any other change is an *unprovoked exit*:

   - ``INVARIANCE``: the policy did not answer it with a cut of the mode left, at that step
     (without modulation every unprovoked exit is one);
   - ``REPEATED_EXIT``: the exit crossed a cut of the mode that existed before -- the state
     was inside the cut (``w . (x - p) <= 0``) at the last in-mode reading and outside at the
     failure reading, without a perturbation: the same exit repeated once its cut existed.

2. **Reachability** (``REACHABILITY``) -- after the last *disturbance* (perturbation, or an
   unprovoked exit answered with a cut: paper Thm. 2 allows finitely many of both), the run
   enters a goal mode by a certified deadline (:meth:`Oracle.deadline_steps`), not an
   arbitrary horizon.
3. **The trace is a run of the automaton** (``AUTOMATON``) -- the policy ran, at every step,
   the mode the automaton picks for the readings (so the discrete trace satisfies the spec's
   guarantees, which the synthesized automaton does by construction). Guarantees are owed
   only while the readings satisfy the assumptions: at a reading the assumptions rule out the
   oracle stops (``assumptions_ok = False``; checks 1, 2 and 4 are then decided on the prefix).
4. **No looping** (``LOOPING``) -- after the last disturbance (perturbation, or an unprovoked
   exit answered with a cut: learning a cut is progress, Thm. 2) the run re-enters a mode it
   already visited at most ``max_cycles`` times (default: the number of modes), and after the
   last perturbation the policy learns at most ``max_cuts`` cuts (default: 3 x the number of
   modes, in total over all modes, so a task with 5 modes allows 15 cuts wherever they fall;
   the failures must stop).

The reachability deadline (sampled time)
----------------------------------------
The certificate proves ``A_k^T P + P A_k + lambda P < 0`` (continuous time:
``V(x(t)) <= V(x0) e^{-lambda t}``) and ``(I + dt A_k)^T P (I + dt A_k) < P`` at the loop's
``dt``. The loop is sampled, so the oracle also computes the **sampled per-step rate**
``rho = max_k lambda_max(P^{-1} (I + dt A_k)^T P (I + dt A_k))`` (floating point, a generalized
eigenvalue problem): since ``V`` is convex and ``x + dt f(x) - x* = sum_k gamma_k (I + dt A_k)
(x - x*)`` is a convex combination, ``V(x_{t+1}) <= rho V(x_t)`` for every nominal Euler step.
Per mode on the planned path to the goal, from the entry value ``v``::

    N_mode = max(ln(v / c) / (lambda dt), ln(v / c) / -ln(rho)) + lag + 1   steps,

with ``c = lambda_min(P) r^2`` and ``r`` the radius of a ball around ``x*`` inside the true
region that contains ``x*`` (Lemma 2: the next mode's region), computed exactly per region
shape in any dimension (:meth:`tli_verify.tasks.task.Task.clearance`: the distance from ``x*``
to the nearest boundary of a shape that decides its region; exact for a convex region, a
guaranteed lower bound for unions and differences). The first ``v`` is ``V`` at the
disturbed state; a later mode's entry value is bounded by
``lambda_max(P_j) (|x*_i - x*_j| + sqrt(v_i / lambda_min(P_i)))^2`` (the state stays in the
previous sublevel set). The deadline is ``ceil(factor * sum N_mode) + slack`` with a
documented margin (default ``factor = 1.5``, ``slack = 50`` steps) for what neither rate
covers: the modulated step in discrete time (Thm. 1 is continuous-time).
"""

from __future__ import annotations

import enum
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.certification.reach import max_v_on_box
from tli_verify.errors import CertificateError, TliError
from tli_verify.io import read_json
from tli_verify.logic.automaton import AssumptionViolation
from tli_verify.runtime.events import mode_sequence
from tli_verify.tasks.task import Task

__all__ = [
    "PRIORITY",
    "CutRecord",
    "Oracle",
    "Trace",
    "Verdict",
    "Violation",
    "ViolationKind",
    "cut_bound_message",
]

FloatArray = npt.NDArray[np.float64]
_EPS = 1e-9


class ViolationKind(enum.Enum):
    """What a run violated (module docstring)."""

    INVARIANCE = "invariance"
    REPEATED_EXIT = "repeated-exit"
    REACHABILITY = "reachability"
    AUTOMATON = "automaton"
    LOOPING = "looping"


PRIORITY: tuple[ViolationKind, ...] = (
    ViolationKind.AUTOMATON,
    ViolationKind.REPEATED_EXIT,
    ViolationKind.LOOPING,
    ViolationKind.REACHABILITY,
    ViolationKind.INVARIANCE,
)
"""Which kind a run's counterexample is filed under when it has several (most specific
first): a wrong mode is an executive bug; a repeated exit defeats modulation; looping is Fig. 7;
a missed deadline; a first, unanswered invariance failure."""


@dataclass(frozen=True, slots=True)
class Violation:
    """One violation of a run.

    Attributes
    ----------
    kind : ViolationKind
    step : int
        The control step at which it was decided.
    message : str
    """

    kind: ViolationKind
    step: int
    message: str


@dataclass(frozen=True, slots=True)
class CutRecord:
    """A cut the policy reported (``CutAdded``), as data.

    Attributes
    ----------
    step : int
        The step it was learned (and applied) at.
    mode : str
    normal, point : tuple of float
        ``{x : normal . (x - point) = 0}``; the mode keeps ``normal . (x - point) <= 0``.
    """

    step: int
    mode: str
    normal: tuple[float, ...]
    point: tuple[float, ...]

    def side(self, X: FloatArray) -> FloatArray:
        """``w . (x - p)`` for states ``X`` of shape (N, n) (> 0: outside), shape (N,)."""
        return np.asarray((X - np.asarray(self.point)) @ np.asarray(self.normal),
                          dtype=np.float64)


@dataclass(frozen=True, slots=True, eq=False)
class Trace:
    """One closed-loop run, as the oracle reads it.

    Attributes
    ----------
    states : ndarray, shape (T + 1, n)
        ``states[t]`` after step ``t`` (``states[0]`` the start).
    read_states : ndarray, shape (T + 1, n)
        The state the reading of step ``t`` was taken at: ``states[t - 1]``, or the perturbed
        state when step ``t`` was perturbed (``read_states[0]`` the start).
    modes : tuple of str, length T + 1
        The mode the policy ran at each step.
    pushes : tuple of int
        Perturbed steps (sorted).
    cuts : tuple of CutRecord
    budget : int
        The step budget the run had (it may end earlier: goal reached, or a watchdog).
    """

    states: FloatArray
    read_states: FloatArray
    modes: tuple[str, ...]
    pushes: tuple[int, ...] = ()
    cuts: tuple[CutRecord, ...] = ()
    budget: int = 0

    @property
    def steps(self) -> int:
        """``T``: control steps taken."""
        return len(self.modes) - 1


@dataclass(frozen=True, slots=True)
class Verdict:
    """The oracle's answer for one run.

    Attributes
    ----------
    violations : tuple of Violation
    reached : bool
        A goal mode was entered.
    goal_step : int or None
    deadline_step : int or None
        The certified reachability deadline (absolute step), when one applies.
    conclusive : bool
        Reachability was decided (the goal was reached, or the run lasted past the deadline);
        False when the run ended earlier (a budget or looping watchdog) or the readings left
        the assumptions.
    assumptions_ok : bool
        Every reading satisfied the spec's environment assumptions.
    cycles : int
        Re-entries into an already visited mode after the last perturbation.
    failures : int
        Unprovoked exits (answered with a cut or not).
    robustness : float
        ``> 0`` the run satisfied every check, with this margin (the smallest of: slack to the
        deadline / the deadline's length, distance to leaving the cut set / workspace size,
        ``(max_cycles - cycles) / (max_cycles + 1)``); ``< 0`` it violated one.
    edges : tuple of (int, int)
        Automaton-state transitions exercised (state changes).
    mode_edges : tuple of (str, str)
    modes_perturbed : tuple of str
        Modes the run was in when perturbed.
    cut_faces : int
        Cuts at the end of the run.
    cut_faces_touched : int
        Of those, cuts the state came within ``touch_tol`` of while in their mode.
    oracle_modes : str
        The run-length mode sequence of the oracle's automaton run (``"abcd"``).
    diagnosis : str
        For a looping, undecided or assumption-breaking run: the mode, the region it leaves
        through, where it entered it, and the class (composition gap, invariance,
        reachability, or an assumption the task breaks); ``""`` otherwise
        (:meth:`Oracle.diagnose`).
    beyond_workspace : int
        States of the trace outside the task's workspace box (a bound: flagged, never
        clipped; joint limits in a joint-space task).
    """

    violations: tuple[Violation, ...]
    reached: bool
    goal_step: int | None
    deadline_step: int | None
    conclusive: bool
    assumptions_ok: bool
    cycles: int
    failures: int
    robustness: float
    edges: tuple[tuple[int, int], ...] = ()
    mode_edges: tuple[tuple[str, str], ...] = ()
    modes_perturbed: tuple[str, ...] = ()
    cut_faces: int = 0
    cut_faces_touched: int = 0
    oracle_modes: str = ""
    diagnosis: str = ""
    beyond_workspace: int = 0

    @property
    def ok(self) -> bool:
        """No violation (an undecided run is ok too: see :attr:`satisfied`)."""
        return not self.violations

    @property
    def satisfied(self) -> bool:
        """The run satisfies the spec: decided, a goal mode reached, no violation (what a
        property test asserts, :func:`tli_verify.testing.assert_satisfies`)."""
        return self.conclusive and self.reached and not self.violations

    @property
    def kinds(self) -> frozenset[ViolationKind]:
        """The kinds violated."""
        return frozenset(v.kind for v in self.violations)

    @property
    def primary(self) -> ViolationKind | None:
        """The most specific kind violated (:data:`PRIORITY`), None when ok."""
        kinds = self.kinds
        return next((k for k in PRIORITY if k in kinds), None)


@dataclass(frozen=True, slots=True)
class _ModeParams:
    P: FloatArray
    attractor: FloatArray
    rate: float
    rho: float
    radius: float
    lam_min: float
    lam_max: float


@dataclass(frozen=True, slots=True, eq=False)
class Oracle:
    """The four checks (module docstring) for one task, automaton, model and certificate.

    Build it with :meth:`build`. Attributes are the precomputed data; :meth:`check` is pure.

    Attributes
    ----------
    task : Task
    automaton : TaskAutomaton
    dt : float
        The loop's control period.
    goals : frozenset of str
        Goal modes (default: the sink modes of the automaton's mode graph).
    goal_inputs : frozenset of str
        Sensors that must also read true in a goal mode for the goal to count (a cyclic
        task, e.g. inspection's ``b & rel``); empty: the goal mode alone.
    planned : mapping of str to frozenset of str
        The planned successors of each mode.
    path : mapping of str to tuple of str
        The planned path from each mode to a goal (for the deadline).
    params : mapping of str to _ModeParams
        Per mode: the DS the plan runs (certificate's ``P`` and rate, sampled rate).
    max_cycles : int
        Re-entries into visited modes allowed after the last disturbance.
    max_cuts : int
        Cuts allowed after the last perturbation, in total over all modes.
    factor, slack : float, int
        Deadline margin.
    touch_tol : float
        Distance under which a cut face counts as touched.
    """

    task: Task
    automaton: Any
    dt: float
    goals: frozenset[str]
    planned: Mapping[str, frozenset[str]]
    path: Mapping[str, tuple[str, ...]]
    params: Mapping[str, _ModeParams]
    max_cycles: int
    max_cuts: int = 12
    factor: float = 1.5
    slack: int = 50
    touch_tol: float = 0.05
    goal_inputs: frozenset[str] = frozenset()
    _names: tuple[str, ...] = field(default=(), repr=False)

    # ------------------------------------------------------------------ construction
    @classmethod
    def build(cls, task: Task, automaton: Any, model: Any,
              certificate: str | os.PathLike[str] | Mapping[str, Any], *, dt: float,
              max_cycles: int | None = None, max_cuts: int | None = None,
              factor: float = 1.5, slack: int = 50,
              touch_tol: float = 0.05, goal_modes: Sequence[str] | None = None,
              goal_inputs: Sequence[str] = ()) -> Oracle:
        """Precompute the plan, the goal modes and the per-mode deadline data.

        Parameters
        ----------
        task : Task
        automaton : TaskAutomaton
        model : Model
            The certified model (attractors, ``A_k``; ``next_mode`` of each DS).
        certificate : path-like or mapping
            The certificate (its ``P`` and ``decay_rate`` per DS key).
        dt : float
        max_cycles : int, optional
            Default: the number of modes.
        max_cuts : int, optional
            Cuts the policy may learn after the last perturbation (default: 3 x the number of
            modes, in total over all modes).
        goal_modes : sequence of str, optional
            The task's goal modes (default: the sink modes; a cyclic task has none).
        goal_inputs : sequence of str, optional
            Sensors that must also read true there
            (:class:`tli_verify.runtime.bundles.Bundle`).

        Raises
        ------
        TliError
            (exit 2) The certificate lacks a DS the plan runs, or cannot be read.
        """
        if isinstance(certificate, Mapping):
            doc: Mapping[str, Any] = certificate
        else:

            doc = read_json(certificate, what="certificate", error=CertificateError)
        run_modes = sorted({s.mode for s in automaton.states})
        succ: dict[str, set[str]] = {m: set() for m in run_modes}
        for a, b in automaton.mode_transitions():
            if a != b and a in succ:
                succ[a].add(b)
        # the same distances the runtime's planner ranks by (logic layer, not policy code)
        goals = (frozenset(automaton.sink_modes()) if goal_modes is None
                 else frozenset(goal_modes))
        dist = automaton.mode_distances(sorted(goals))
        far = len(run_modes) + 1
        planned: dict[str, frozenset[str]] = {}
        nxt: dict[str, str | None] = {}
        for m in run_modes:
            best = min((dist.get(s, far) for s in succ[m]), default=far)
            plan = {s for s in succ[m] if dist.get(s, far) == best}
            named = [mm.next_mode for mm in model.modes.values()
                     if mm.mode == m and mm.next_mode is not None]
            plan |= {s for s in named if s in succ[m]}
            planned[m] = frozenset(plan)
            pick = [s for s in named if s in plan] or sorted(s for s in plan
                                                             if dist.get(s, far) == best)
            nxt[m] = pick[0] if pick and m not in goals else None
        path: dict[str, tuple[str, ...]] = {}
        for m in run_modes:
            seq = [m]
            while nxt.get(seq[-1]) is not None and len(seq) <= len(run_modes):
                seq.append(str(nxt[seq[-1]]))
            path[m] = tuple(seq)
        params: dict[str, _ModeParams] = {}
        cert_modes = doc.get("modes", {})
        for m in run_modes:
            if m in goals and not goal_inputs:  # a goal with sensors: its DS brings them
                continue
            key = model.key(m, nxt[m])
            entry = cert_modes.get(key)
            if entry is None:
                raise TliError(f"certificate: no DS {key!r} (mode {m}) to take its decay rate "
                               "from")
            P = np.asarray(entry["P"], dtype=np.float64)
            rate = float(Fraction(entry["decay_rate"]))
            ds = model.modes[key].ds
            rho = _sampled_rate(P, np.asarray(ds.A, dtype=np.float64), dt)
            eig = np.linalg.eigvalsh(P)
            params[m] = _ModeParams(P=P, attractor=np.asarray(ds.attractor, dtype=np.float64),
                                    rate=rate, rho=rho,
                                    radius=max(float(task.clearance(ds.attractor)), 1e-9),
                                    lam_min=float(eig.min()), lam_max=float(eig.max()))
        return cls(task=task, automaton=automaton, dt=float(dt), goals=goals,
                   planned=planned, path=path, params=params,
                   max_cycles=len(automaton.modes) if max_cycles is None else int(max_cycles),
                   max_cuts=(3 * len(automaton.modes) if max_cuts is None else int(max_cuts)),
                   factor=float(factor), slack=int(slack), touch_tol=float(touch_tol),
                   goal_inputs=frozenset(goal_inputs), _names=tuple(task.sensor_names))

    # ------------------------------------------------------------------ deadlines
    def deadline_steps(self, mode: str, x: npt.ArrayLike | None = None) -> int:
        """Certified steps to a goal mode from state ``x`` in ``mode`` (module docstring);
        ``x = None``: from the worst start in the workspace box.

        Returns
        -------
        int
            0 in a goal mode (of a goal without sensors; a goal with sensors, e.g. a cyclic
            task's release, counts its own DS too: the sensors read true where it converges).
        """
        seq = self.path.get(mode, (mode,))
        total = 0.0
        v = 0.0
        prev: _ModeParams | None = None
        lag = int(getattr(self.task, "lag", 0))
        for m in seq:
            if m in self.goals and (not self.goal_inputs or m not in self.params):
                break
            p = self.params[m]
            if prev is None:
                if x is None:
                    v = max_v_on_box(p.P, p.attractor, self.task.lo, self.task.hi)
                else:
                    e = np.asarray(x, dtype=np.float64) - p.attractor
                    v = float(e @ p.P @ e)
            else:
                reach = float(np.linalg.norm(prev.attractor - p.attractor)) + math.sqrt(
                    max(v, 0.0) / prev.lam_min)
                v = p.lam_max * reach * reach
            c = p.lam_min * (1.0 - 1e-9) * p.radius * p.radius
            n = 0.0
            if v > c:
                ln = math.log(v / c)
                n = ln / (p.rate * self.dt)
                if p.rho < 1.0:
                    n = max(n, ln / -math.log(p.rho))
            total += n + lag + 1
            prev = p
        return math.ceil(self.factor * total) + self.slack

    def budget(self, window: int) -> int:
        """A step budget that decides reachability for any run whose perturbations end by
        step ``window`` (the worst-case deadline from any mode, from anywhere in the box)."""
        worst = max((self.deadline_steps(m) for m in self.params), default=self.slack)
        return int(window) + worst

    # ------------------------------------------------------------------ checks
    def readings(self, traces: Sequence[Trace]) -> list[list[frozenset[str]]]:
        """The task's readings along each trace's read states (batched over traces: the runs
        are padded to one length with their last state, which leaves earlier readings
        unchanged since the sensor model is causal)."""
        if not traces:
            return []
        T = max(len(tr.read_states) for tr in traces)
        n = traces[0].read_states.shape[1]
        X = np.empty((len(traces), T, n))
        for i, tr in enumerate(traces):
            k = len(tr.read_states)
            X[i, :k] = tr.read_states
            X[i, k:] = tr.read_states[-1]
        R = self.task.sensors(X)  # (B, T, m)
        weights = 1 << np.arange(R.shape[2], dtype=np.int64)
        codes = (R.astype(np.int64) * weights).sum(axis=2)
        table = {c: frozenset(nm for j, nm in enumerate(self._names) if (c >> j) & 1)
                 for c in np.unique(codes).tolist()}
        return [[table[c] for c in codes[i, :len(tr.read_states)].tolist()]
                for i, tr in enumerate(traces)]

    def check_many(self, traces: Sequence[Trace]) -> list[Verdict]:
        """:meth:`check` for many traces (readings computed in one batched call)."""
        return [self._check(tr, rd) for tr, rd in zip(traces, self.readings(traces),
                                                       strict=True)]

    def check(self, trace: Trace) -> Verdict:
        """The four checks on one trace (module docstring)."""
        return self.check_many([trace])[0]

    def _check(self, tr: Trace, readings: list[frozenset[str]]) -> Verdict:

        aut = self.automaton
        viol: list[Violation] = []
        T = tr.steps
        assumptions_ok = True
        modes: list[str] = []
        states: list[int] = []
        try:
            s = aut.initial_state(readings[0])
            states.append(s)
            modes.append(aut.states[s].mode)
            for t in range(1, T + 1):
                s, m = aut.next_mode(s, readings[t])
                states.append(s)
                modes.append(m)
        except AssumptionViolation:
            assumptions_ok = False
        end = len(modes) - 1  # last step the oracle's run covers
        # (3) the trace is a run of the automaton
        for t in range(end + 1):
            if tr.modes[t] != modes[t]:
                viol.append(Violation(ViolationKind.AUTOMATON, t,
                                      f"step {t}: the policy ran mode {tr.modes[t]!r}, the "
                                      f"automaton picks {modes[t]!r} for reading "
                                      f"{sorted(readings[t])}"))
                break
        lag = int(getattr(self.task, "lag", 0))
        pushes = sorted(tr.pushes)
        push_set = set(pushes)
        last_push = pushes[-1] if pushes else 0
        cuts_by_mode: dict[str, list[CutRecord]] = {}
        for c in tr.cuts:
            cuts_by_mode.setdefault(c.mode, []).append(c)
        X = tr.read_states
        # (1) invariance
        failures = 0
        answered_steps: list[int] = []
        for t in range(1, end + 1):
            a, b = modes[t - 1], modes[t]
            if a == b:
                continue
            if any(t - lag - 1 <= p <= t for p in pushes):
                continue
            if b in self.planned.get(a, frozenset()):
                continue
            failures += 1
            crossed = [c for c in cuts_by_mode.get(a, ()) if c.step < t
                       and c.side(X[t - 1:t])[0] <= _EPS and c.side(X[t:t + 1])[0] > _EPS]
            if crossed:
                viol.append(Violation(ViolationKind.REPEATED_EXIT, t,
                                      f"step {t}: unprovoked exit {a} -> {b} across the cut "
                                      f"learned at step {crossed[0].step}: the same exit "
                                      "repeated once its cut existed"))
            answered = any(c.step == t and c.mode == a for c in tr.cuts)
            if answered:
                answered_steps.append(t)
            elif not crossed:
                viol.append(Violation(ViolationKind.INVARIANCE, t,
                                      f"step {t}: unprovoked exit {a} -> {b} (not planned, no "
                                      "perturbation) and no cut learned for it"))
        for kind in (ViolationKind.INVARIANCE, ViolationKind.REPEATED_EXIT):
            same = [v for v in viol if v.kind is kind]
            if len(same) > 1:  # the first, with the count
                viol = [v for v in viol if v.kind is not kind]
                viol.append(Violation(kind, same[0].step,
                                      f"{same[0].message} (and {len(same) - 1} more)"))
        # (4) no looping after the last disturbance (a perturbation, or an exit answered
        # with a cut: learning is progress, Thm. 2); the cuts learned after the last
        # perturbation must stop too
        cycles = 0
        t0 = min(max([last_push, *answered_steps]), end)
        visited = {modes[t0]} if modes else set()
        loop_step = None
        for t in range(t0 + 1, end + 1):
            if modes[t] != modes[t - 1]:
                if modes[t] in visited:
                    cycles += 1
                    if cycles > self.max_cycles and loop_step is None:
                        loop_step = t
                visited.add(modes[t])
        if loop_step is not None:
            seq = _runs(modes[t0:])
            viol.append(Violation(ViolationKind.LOOPING, loop_step,
                                  f"after step {t0} (the last perturbation or learned cut) "
                                  f"the modes cycle {cycles} times (bound {self.max_cycles}):"
                                  f" {seq[:40]}{'...' if len(seq) > 40 else ''}"))
        learned = [t for t in answered_steps if t > last_push]
        if len(learned) > self.max_cuts:
            viol.append(Violation(ViolationKind.LOOPING, learned[self.max_cuts],
                                  cut_bound_message(learned=len(learned), last_push=last_push,
                                                    bound=self.max_cuts,
                                                    modes=len(self.automaton.modes))))
        # (2) reachability after the last disturbance
        goal_step = next((t for t in range(end + 1) if modes[t] in self.goals
                          and self.goal_inputs <= readings[t]), None)
        ref = max([last_push, *answered_steps]) if modes else 0
        ref = min(ref, end)
        deadline = None
        conclusive = False
        slack_frac = 1.0
        if modes:
            if goal_step is not None and goal_step <= ref:
                conclusive = True
            else:
                n = self.deadline_steps(modes[ref], X[ref])
                deadline = ref + n
                if goal_step is not None:
                    conclusive = True
                    if goal_step > deadline:
                        viol.append(Violation(ViolationKind.REACHABILITY, deadline,
                                              f"goal reached at step {goal_step}, after the "
                                              f"certified deadline {deadline} ({n} steps from "
                                              f"step {ref})"))
                    slack_frac = (deadline - goal_step) / max(n, 1)
                elif assumptions_ok and T >= deadline:
                    conclusive = True
                    viol.append(Violation(ViolationKind.REACHABILITY, deadline,
                                          f"no goal mode by the certified deadline step "
                                          f"{deadline} ({n} steps after the last disturbance "
                                          f"at step {ref})"))
                    slack_frac = (deadline - T) / max(n, 1)
        # margins and coverage
        size = float(np.max(np.asarray(self.task.hi) - np.asarray(self.task.lo)))
        cut_margin = math.inf
        touched = 0
        idx = np.arange(len(modes))
        for c in tr.cuts:
            inside = np.array([modes[t] == c.mode for t in range(len(modes))], dtype=bool)
            inside &= idx > c.step
            if push_set:
                inside &= ~np.isin(idx, list(push_set))
            if not inside.any():
                continue
            side = c.side(X[:len(modes)][inside])
            cut_margin = min(cut_margin, float(-side.max()))
            if float(np.abs(side).min()) <= self.touch_tol:
                touched += 1
        loop_term = (self.max_cycles - cycles) / (self.max_cycles + 1)
        robustness = min(slack_frac, loop_term, cut_margin / size, 1.0)
        if viol:
            robustness = min(robustness, -1.0 / (1.0 + len(viol))) if robustness >= 0 \
                else robustness
        edges = sorted({(states[t - 1], states[t]) for t in range(1, len(states))
                        if states[t - 1] != states[t]})
        mode_edges = sorted({(modes[t - 1], modes[t]) for t in range(1, len(modes))
                             if modes[t - 1] != modes[t]})
        perturbed = sorted({tr.modes[p - 1] for p in pushes if 1 <= p <= T})
        rank = {k: i for i, k in enumerate(PRIORITY)}
        diagnosis = ""
        if any(v.kind is ViolationKind.LOOPING for v in viol) or not conclusive \
                or not assumptions_ok:
            diagnosis = self.diagnose(tr, modes, readings, t0=min(max([last_push, 0]), end),
                                      assumptions_ok=assumptions_ok)
            viol = [Violation(v.kind, v.step, f"{v.message}. {diagnosis}")
                    if v.kind is ViolationKind.LOOPING and diagnosis else v for v in viol]
        viol.sort(key=lambda v: (rank[v.kind], v.step))
        return Verdict(violations=tuple(viol), reached=goal_step is not None,
                       goal_step=goal_step, deadline_step=deadline, conclusive=conclusive,
                       assumptions_ok=assumptions_ok, cycles=cycles, failures=failures,
                       robustness=float(robustness), edges=tuple(edges),
                       mode_edges=tuple(mode_edges), modes_perturbed=tuple(perturbed),
                       cut_faces=len(tr.cuts), cut_faces_touched=touched,
                       oracle_modes=_runs(modes), diagnosis=diagnosis,
                       beyond_workspace=self._beyond(tr.states))

    def _beyond(self, X: FloatArray) -> int:
        inside = getattr(self.task, "in_workspace", None)
        if inside is None:
            return 0
        return int(np.count_nonzero(~np.asarray(inside(X), dtype=bool)))

    # ------------------------------------------------------------------ diagnosis
    def diagnose(self, tr: Trace, modes: Sequence[str], readings: Sequence[frozenset[str]],
                 *, t0: int, assumptions_ok: bool) -> str:
        """Why a run loops, stays undecided or leaves the assumptions, in one sentence.

        Classes: an **assumption** the task breaks (a reading the spec's assumptions rule
        out); a **composition gap** (the mode that keeps being left was entered where the
        previous mode's flow handed it off, and its DS leaves from there); **invariance** (it
        was entered at the start or by a push); **reachability** (no unprovoked exit: the
        run rests in a mode, its DS at an attractor where the next reading never comes). The
        region it leaves through is the true region of the states before and after the exit.
        """
        X = tr.read_states
        names = tuple(getattr(self.task, "region_names", ()))

        def region(t: int) -> str:
            if not names:
                return "?"
            return str(names[int(self.task.region_index(X[t:t + 1])[0])])

        def at(t: int) -> str:
            return "[" + ", ".join(f"{v:.3g}" for v in X[t].tolist()) + "]"

        end = len(modes) - 1
        if not assumptions_ok:
            t = end + 1 if end + 1 < len(readings) else end
            prev = modes[end] if modes else "?"
            return (f"Diagnosis: an assumption the task breaks: at step {t} the reading "
                    f"{sorted(readings[t])} (region {region(min(t, len(X) - 1))}) is one the "
                    f"spec's assumptions rule out from mode {prev} (a task/spec mismatch: "
                    "tli task check --spec finds such pairs)")
        pushes = set(tr.pushes)
        lag = int(getattr(self.task, "lag", 0))
        exits: dict[tuple[str, str], list[int]] = {}
        for t in range(max(t0, 1), end + 1):
            a, b = modes[t - 1], modes[t]
            if a == b or b in self.planned.get(a, frozenset()):
                continue
            if any(t - lag - 1 <= p <= t for p in pushes):
                continue
            exits.setdefault((a, b), []).append(t)
        if exits:
            (a, b), steps = max(exits.items(), key=lambda kv: (len(kv[1]), kv[1][-1]))
            t = steps[-1]
            e = t - 1
            while e > 0 and modes[e - 1] == a:
                e -= 1
            if e == 0:
                how, cls = "at the start", "invariance"
            elif any(e - lag - 1 <= p <= e for p in pushes):
                how, cls = "by a push", "invariance"
            elif a in self.planned.get(modes[e - 1], frozenset()):
                how = f"where mode {modes[e - 1]}'s flow handed it off"
                cls = ("composition gap: the previous mode's flow enters it where its DS "
                       "leaves (tli learn's offline hand-off step closes it where the regions "
                       "are known: docs/explanation/handoff)")
            else:
                how, cls = f"from mode {modes[e - 1]}", "invariance"
            return (f"Diagnosis: mode {a} leaves into {b} {len(steps)} time(s) without a push, "
                    f"last at step {t}, from region {region(t - 1)} at {at(t - 1)} into region "
                    f"{region(t)}; it was entered at step {e} at {at(e)} {how}: {cls}")
        m = modes[end] if modes else "?"
        p = self.params.get(m)
        if p is not None:
            d = float(np.linalg.norm(X[end] - p.attractor))
            return (f"Diagnosis: reachability: the run stays in mode {m} (region "
                    f"{region(end)}) and ends {d:.3g} from its DS's attractor "
                    f"{np.round(p.attractor, 4).tolist()} with no unprovoked exit: the next "
                    "reading does not come where the DS rests")
        return f"Diagnosis: the run stays in mode {m} (region {region(end)})"


def _runs(modes: Sequence[str]) -> str:

    return mode_sequence(modes)


def _sampled_rate(P: FloatArray, A: FloatArray, dt: float) -> float:
    """``max_k lambda_max(P^{-1} (I + dt A_k)^T P (I + dt A_k))`` (module docstring)."""
    import scipy.linalg as sla

    n = P.shape[0]
    worst = 0.0
    for Ak in (A if A.ndim == 3 else A[None]):
        M = np.eye(n) + dt * Ak
        w = sla.eigh(M.T @ P @ M, P, eigvals_only=True)
        worst = max(worst, float(np.max(w)))
    return worst * (1.0 + 1e-9)


def cut_bound_message(*, learned: int, last_push: int, bound: int, modes: int) -> str:
    """The looping violation's message for too many cuts after the last perturbation: it says
    how the bound counts (by default 3 x the number of modes, in total over all modes).

    Parameters
    ----------
    learned : int
        Cuts learned after the last perturbation.
    last_push : int
        The step of the last perturbation.
    bound : int
        The oracle's ``max_cuts``.
    modes : int
        Modes of the task automaton.

    Returns
    -------
    str
    """
    how = (f"3 x {modes} modes, in total over all modes" if bound == 3 * modes
           else "max_cuts, in total over all modes")
    return (f"{learned} cuts learned after the last perturbation (step {last_push}; bound "
            f"{bound} = {how}): the failures do not stop")
