"""The LTL-DS executive (paper eq. 6, Sec. 5, Fig. 3(b) and Fig. 7).

``x' = sum_i delta_{Omega_phi(alpha), sigma_i} M_i(x) f_i(x)``: the task automaton ``Omega_phi``
picks the mode from the sensor reading ``alpha``; the mode's certified DS ``f_i``, modulated by
the cuts learned for the mode's region (``M_i``, eq. 7), moves the state.

:class:`LTLDSPolicy` is the controller: ``reset(x0, sensors)`` once, then ``step(x, sensors)``
every control period returns the velocity to apply. Per step it

1. advances the automaton on the reading (Mealy step, :meth:`TaskAutomaton.next_mode`);
2. **assumption monitor**: a reading the environment assumptions rule out is reported
   (:class:`~.events.AssumptionViolationEvent`), never ignored; the executive resynchronizes to
   an automaton state entered with that reading (same strategy memory first) and holds (zero
   velocity) while none exists -- it never crashes on a reading;
3. **replanning**: a mode other than the planned next one is followed (receding horizon,
   :class:`~.events.Replan`);
4. **invariance failures**: such an exit that no perturbation caused, into a mode that is not
   planned progress either (a later mode of the plan,
   :func:`~tli_verify.logic.automaton.plan_progress`), (the caller reports
   perturbations: ``step(..., perturbed=True)`` or :meth:`LTLDSPolicy.notify_perturbation`) is
   an invariance failure of the mode left (an exit across a reading the assumptions rule out
   is reported as an assumption violation and cuts nothing). The executive records
   ``(x^0, x^{T_f-1}, x^{T_f})`` -- the mode-entry state, the last in-mode state, the failure
   state -- and solves the cut QCQP (appendix E.3), constrained by the mode's earlier cut points
   and every entry state recorded in the mode, so earlier failures stay separated. It applies
   the cut at once: a new model (:meth:`tli_verify.model.types.Model.add_cut`), whose DS of that
   mode all share the cut;
5. runs ``model.velocity(x, mode, next_mode=planned, dt=dt)``: the per-transition DS towards the
   planned next mode where the model has one. The plan is the toolkit's one planner,
   :meth:`TaskAutomaton.planned_keys`, which the deployment gate checks coverage with too;
6. **growing the spec** (``learn_transitions=True``, paper appendix F): a reading the
   assumptions rule out that shows another *known* mode (paper Asm. 3) is a transition the
   spec lacks. It is added to ``phi_t^s`` (:func:`tli_verify.logic.infer.regrow`: the observed
   sensor change joins the assumptions, the change is marked as regressing), the spec is
   re-synthesized and re-checked (realizable, well-separated), the grown automaton must give
   every state a DS of the certified model (the same coverage check as at construction), and
   the run carries on from the matching state (:func:`~tli_verify.logic.infer.resume_state`)
   with a :class:`~.events.TransitionLearned` event; otherwise the old spec is kept, a
   :class:`~.events.TransitionRefused` event says why and the reading is handled as an
   assumption violation. The certified model and its certificate are untouched: they still
   bind the spec the model names; the grown spec (:attr:`LTLDSPolicy.spec_toml`) is a new file
   (:mod:`tli_verify.runtime.growth`).

It refuses (:class:`~tli_verify.errors.CertificateError`) a model its certificate does not
cover, exactly as the gate does (:func:`tli_verify.runtime.coverage.check_coverage`: cuts
learned online are covered, modulation keeps the certified ``V`` decreasing, Thm. 1), and a
control period longer than the certified one.

The closed loop around it is :mod:`tli_verify.runtime.loop`.
"""

from __future__ import annotations

import math
import os
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from tli_verify.boundary.cuts import InvarianceFailure as _Failure
from tli_verify.errors import CertificateError, ModelError, TliError
from tli_verify.logic.automaton import (
    AssumptionViolation,
    PlannedStep,
    TaskAutomaton,
    plan_progress,
)
from tli_verify.logic.infer import spec_to_toml
from tli_verify.logic.spec import parse_spec
from tli_verify.model.types import Model
from tli_verify.runtime.coverage import check_coverage, plan_states
from tli_verify.runtime.events import (
    AssumptionViolationEvent,
    CutAdded,
    CutFailed,
    Event,
    InvarianceFailure,
    ModeChange,
    Perturbation,
    Reentered,
    Replan,
    Stall,
    TransitionLearned,
    TransitionRefused,
)
from tli_verify.runtime.growth import Refusal, learn_transition
from tli_verify.runtime.online import online_cut
from tli_verify.runtime.stall import StallRule, lyapunov_level, lyapunov_value, reentry_route

if TYPE_CHECKING:
    from tli_verify.logic.spec import GR1Spec

__all__ = [
    "MAX_ENTRY_STATES",
    "LTLDSPolicy",
]

FloatArray = npt.NDArray[np.float64]
Sensors = Mapping[str, bool] | Iterable[str]

MAX_ENTRY_STATES = 64
"""Most mode-entry states the executive keeps per mode (kept inside every later cut of the
mode). Beyond it, one of the two closest recorded states (the older) is dropped, so the record
stays bounded over long runs and keeps its spread (see :meth:`LTLDSPolicy._record_entry`)."""


class _EntryRecord(list[FloatArray]):
    """A mode's recorded entry states with their pairwise squared distances.

    A list of the states (shape (n,) each; a plain list to every reader) plus ``d2``, shape
    (m, m): ``d2[i, j] = |x_i - x_j|^2`` for ``i < j``, ``inf`` on and below the diagonal,
    for the first ``m`` states; :meth:`in_sync` says whether they are the list's states but
    the newest (``m = len - 1``), as :meth:`LTLDSPolicy._record_entry` leaves it.
    """

    __slots__ = ("_d2", "_last", "_points")
    _d2: FloatArray
    _last: FloatArray
    _points: FloatArray

    @classmethod
    def of(cls, states: list[FloatArray], d2: FloatArray) -> _EntryRecord:
        """The record of ``states`` (shape (m, n) once stacked) with their distances ``d2``."""
        rec = cls(states)
        rec._d2 = d2
        rec._points = np.array(states)
        rec._last = states[-1]
        return rec

    def in_sync(self) -> bool:
        """One state appended since the distances were computed, nothing else changed."""
        m = self._d2.shape[0]
        return len(self) == m + 1 and self[m - 1] is self._last

    def with_newest(self) -> FloatArray:
        """``d2`` of all the states, shape (m + 1, m + 1): the distances to the newest added
        (the same elementwise squares and summation over the coordinates as for all pairs)."""
        m = self._d2.shape[0]
        out = np.full((m + 1, m + 1), np.inf)
        out[:m, :m] = self._d2
        out[:m, m] = ((self._points - self[m]) ** 2).sum(axis=-1)
        return out


class LTLDSPolicy:
    """The LTL-DS executive: task automaton + modulated, certified DS per mode (paper eq. 6).

    Parameters
    ----------
    automaton : TaskAutomaton
        From :func:`tli_verify.logic.check.synthesize`.
    model : Model
        Loaded from its file; a DS for every mode the automaton runs.
    certificate : path-like
        A certificate covering the model file (see :func:`check_coverage`).
    dt : float, optional
        Control period of the loop (default: the certified one; longer is refused).
    goal_modes : sequence of str, optional
        Modes that complete the task (default: the automaton's sink modes, which no
        transition leaves); used to rank the next modes a state can plan.
    learn_cuts : bool, optional
        Add a cut on each invariance failure (paper Sec. 5.2); off: report only.
    cut_margin : float, optional
        Separation margin of the cut QCQP.
    spec : GR1Spec, optional
        The spec ``automaton`` was synthesized from (needed by ``learn_transitions``; its
        inputs and modes must be the automaton's).
    learn_transitions : bool, optional
        Grow the spec online (module docstring, item 6). Default off: a transition the spec
        lacks is reported as an assumption violation only.
    goal_inputs : sequence of str, optional
        Sensors that must also read true for a goal mode to complete the task (a cyclic task
        such as inspection, ``GF(b & rel)``: done at the first ``b & rel``).
    stall : StallRule, optional
        The assumption monitor's stall rule (:mod:`tli_verify.runtime.stall`): a converged DS
        without the next mode's reading is reported and the mode re-entered from its
        predecessor. Default off.

    Raises
    ------
    CertificateError
        The certificate does not cover the model, or ``dt`` exceeds the certified period (1).
    ModelError
        A mode the automaton runs has no DS in the model, or a state has no DS the planner can
        run (2).
    TliError
        ``learn_transitions`` without a matching ``spec`` (2).
    """

    __slots__ = (
        "_entries",
        "_entry",
        "_holding",
        "_inputs",
        "_key",
        "_last",
        "_learned",
        "_mode",
        "_model",
        "_pending",
        "_pending_seen",
        "_plan_cache",
        "_planned",
        "_progress",
        "_reentered_at",
        "_reentry",
        "_refused",
        "_spec_text",
        "_stall_at",
        "_stall_count",
        "_stall_levels",
        "_stall_trend",
        "_state",
        "_steps",
        "automaton",
        "certificate",
        "cut_margin",
        "dt",
        "events",
        "goal_inputs",
        "goal_modes",
        "learn_cuts",
        "learn_transitions",
        "stall_rule",
    )

    def __init__(self, automaton: TaskAutomaton, model: Model,
                 certificate: str | os.PathLike[str], *, dt: float | None = None,
                 goal_modes: Sequence[str] | None = None, learn_cuts: bool = True,
                 cut_margin: float = 1e-3, spec: GR1Spec | None = None,
                 learn_transitions: bool = False, goal_inputs: Sequence[str] = (),
                 stall: StallRule | None = None) -> None:
        cert_dt = check_coverage(model, certificate)
        if dt is None:
            dt = float(cert_dt)
        if not (np.isfinite(dt) and dt > 0):
            raise TliError(f"dt must be a positive number, got {dt!r}")
        if dt > float(cert_dt) * (1.0 + 1e-12):  # the float nearest the certified period is fine
            raise CertificateError(f"{certificate}: refused: control period {dt:g} s is longer "
                                   f"than the certified {cert_dt} s")
        if goal_modes is None:
            goal_modes = automaton.sink_modes()
        self.goal_modes = tuple(goal_modes)
        unknown = sorted(set(goal_inputs) - set(automaton.inputs))
        if unknown:
            raise TliError(f"goal_inputs: {unknown[0]!r} is not a sensor of the automaton "
                           f"({', '.join(automaton.inputs)})")
        self.goal_inputs = frozenset(goal_inputs)
        self._plan_cache: dict[int, PlannedStep] = plan_states(
            automaton, model, self.goal_modes, str(model.path))
        self._progress = plan_progress(self._plan_cache.values())
        self.learn_transitions = bool(learn_transitions)
        self._spec_text: str | None = None
        if spec is not None:

            if tuple(spec.inputs) != tuple(automaton.inputs) or \
                    tuple(spec.mode_names) != tuple(automaton.modes):
                raise TliError(f"{spec.path or spec.name}: not the spec of the automaton "
                               f"{automaton.name!r} (inputs or modes differ)")
            self._spec_text = spec_to_toml(spec)
        elif self.learn_transitions:
            raise TliError("learn_transitions needs the spec the automaton was synthesized "
                           "from (spec=...)")
        if self.learn_transitions and spec is not None and spec.modes is None:
            raise TliError(f"{spec.path or spec.name}: learn_transitions needs a [modes] table "
                           "(which mode a reading shows)")
        self._learned: tuple[tuple[str, str], ...] = ()
        self._refused: frozenset[tuple[str, frozenset[str]]] = frozenset()
        self.automaton = automaton
        self._model = model
        self.certificate = str(certificate)
        self.dt = float(dt)
        self.learn_cuts = bool(learn_cuts)
        self.cut_margin = float(cut_margin)
        self.events: list[Event] = []
        self._state: int | None = None
        self._mode = ""
        self._planned: str | None = None
        self._key = ""
        self._entry: FloatArray | None = None
        self._last: FloatArray | None = None
        self._steps = 0
        self._pending = False
        self._holding = False
        self._entries: dict[str, list[FloatArray]] = {}
        self._inputs = frozenset(automaton.inputs)
        self.stall_rule = stall
        self._stall_levels: dict[str, float] = {}
        self._stall_count = 0
        self._stall_at: tuple[int | None, str] = (None, "")
        self._stall_trend: deque[float] = deque()
        self._pending_seen = False
        self._reentry: tuple[str, str, str, frozenset[str]] | None = None
        self._reentered_at = -1

    def drop_cuts(self) -> None:
        """Run the nominal DS of every mode from now on: the model's cuts -- the ones learned
        offline included -- are not used (the no-modulation ablation, with
        ``learn_cuts=False``; paper Sec. 7.2)."""
        self._model = Model(state_names=self._model.state_names,
                            modes={k: mm.with_cuts(()) for k, mm in self._model.modes.items()},
                            spec=self._model.spec, path=self._model.path,
                            source=self._model.source)

    # ---------------------------------------------------------------- public state
    @property
    def model(self) -> Model:
        """The certified model with the cuts learned so far (read-only: replacing it would
        run a model the certificate check did not see)."""
        return self._model

    @property
    def mode(self) -> str:
        """The mode being run."""
        return self._mode

    @property
    def state(self) -> int | None:
        """The automaton state (None before :meth:`reset`)."""
        return self._state

    @property
    def planned(self) -> str | None:
        """The next mode the automaton plans from the current state (None in a goal mode)."""
        return self._planned

    @property
    def key(self) -> str:
        """The model key of the DS being run."""
        return self._key

    @property
    def steps(self) -> int:
        """Control steps since :meth:`reset`."""
        return self._steps

    @property
    def holding(self) -> bool:
        """No automaton state matches the last reading: the executive holds (zero velocity)."""
        return self._holding

    @property
    def done(self) -> bool:
        """The current mode is a goal mode (with every sensor of ``goal_inputs`` read true)."""
        if self._mode not in self.goal_modes:
            return False
        if not self.goal_inputs:
            return True
        return self._state is not None and \
            self.goal_inputs <= frozenset(self.automaton.states[self._state].inputs)

    @property
    def learned(self) -> tuple[tuple[str, str], ...]:
        """The mode changes added to the spec online, in order (``learn_transitions``)."""
        return self._learned

    @property
    def spec_toml(self) -> str | None:
        """The TOML text of the current spec -- the grown one after a learned transition --
        accepted by ``tli spec check`` (None when built without ``spec``)."""
        return self._spec_text

    @property
    def spec(self) -> GR1Spec | None:
        """The current spec, parsed from :attr:`spec_toml` (None when built without one)."""
        return None if self._spec_text is None else parse_spec(self._spec_text)

    # ---------------------------------------------------------------- planning
    def _plan(self, state: int) -> str | None:
        """The next mode planned from ``state`` (:meth:`TaskAutomaton.planned_keys`)."""
        return self._plan_cache[state].next_mode

    def _enter(self, state: int) -> None:
        step = self._plan_cache[state]
        self._state = state
        self._mode = step.mode
        self._planned = step.next_mode
        self._key = step.key or ""  # every state has a key (plan_states checked)

    def _resync(self, reading: frozenset[str]) -> int | None:
        """An automaton state entered with this reading: same strategy memory first."""
        cands = [s for s in self.automaton.states if frozenset(s.inputs) == reading]
        if not cands:
            return None
        goal = self.automaton.states[self._state].goal if self._state is not None else 0
        return min(cands, key=lambda s: (s.goal != goal, s.id not in self.automaton.initial,
                                         s.id)).id

    # ---------------------------------------------------------------- control
    def _vector(self, x: npt.ArrayLike) -> FloatArray:
        xa = np.array(x, dtype=np.float64).reshape(-1)  # a copy: callers update x in place
        if xa.size != self.model.dim or not (math.isfinite(xa.sum()) or np.isfinite(xa).all()):
            raise ModelError(f"state must be a finite vector of dimension {self.model.dim}, "
                             f"got shape {np.shape(x)}")
        return xa

    def _read(self, sensors: Sensors) -> frozenset[str]:
        """The set of true sensors (unknown names raise :class:`SpecError`, exit 2)."""
        if isinstance(sensors, dict) and sensors.keys() <= self._inputs:
            return frozenset([k for k, v in sensors.items() if v])
        return self.automaton._reading(sensors)

    def reset(self, x0: npt.ArrayLike, sensors: Sensors) -> None:
        """Start an episode at ``x0`` with the first reading (learned cuts are kept).

        A reading the initial assumptions rule out is reported and resynchronized like any
        other (:class:`~.events.AssumptionViolationEvent`).
        """
        x = self._vector(x0)
        self.events = []
        self._steps = 0
        self._pending = False
        self._holding = False
        self._state = None
        self._reentry = None
        self._reentered_at = -1
        self._stall_count = 0
        self._stall_at = (None, "")
        self._stall_trend = deque()
        self._pending_seen = False
        reading = self._read(sensors)
        try:
            sid = self.automaton.initial_state(reading)
        except AssumptionViolation as exc:
            sid_or_none = self._resync(reading)
            self.events.append(AssumptionViolationEvent(0, -1, tuple(sorted(reading)), str(exc),
                                                        sid_or_none))
            if sid_or_none is None:
                self._holding = True
                sid = self.automaton.initial[0]
            else:
                sid = sid_or_none
        self._enter(sid)
        self._entry = x
        self._last = x
        self._record_entry(self._mode, x)

    def fork(self) -> LTLDSPolicy:
        """A copy for another episode: same automaton, model (and its learned cuts) and
        certificate check, its own episode state, events and recorded entry states. Forks of
        one policy share the model object, so :func:`run_episodes` batches their DS."""
        new = object.__new__(type(self))  # a subclass (the no-replan ablation) stays one
        for cls in type(self).__mro__:
            for name in getattr(cls, "__slots__", ()):
                if hasattr(self, name):
                    setattr(new, name, getattr(self, name))
        new.events = list(self.events)
        new._entries = {k: list(v) for k, v in self._entries.items()}
        new._plan_cache = dict(self._plan_cache)
        return new

    def _record_entry(self, mode: str, x: FloatArray) -> None:
        """Record a mode-entry state (kept inside the mode's later cuts), bounded.

        At most :data:`MAX_ENTRY_STATES` per mode: past it, the older of the two closest
        recorded states goes (a near-duplicate constraint), so long runs stay bounded in memory
        and in the cut QCQP's size while isolated entry states -- the ones a cut could
        otherwise exclude -- are kept.

        The squared distances between the kept states are carried along
        (:class:`_EntryRecord`), so a full record costs one new row of distances per entry,
        not all pairs again (a perturbed stretch enters a mode every control period); the
        same numbers, so the same state goes as when they were all recomputed.
        """
        kept = self._entries.setdefault(mode, [])
        kept.append(x)
        if len(kept) <= MAX_ENTRY_STATES:
            return
        if isinstance(kept, _EntryRecord) and kept.in_sync():
            d2 = kept.with_newest()
        else:  # first time full, or a copy made elsewhere (forks copy the lists)
            P = np.array(kept)
            d2 = ((P[:, None, :] - P[None, :, :]) ** 2).sum(axis=-1)
            d2[np.tril_indices(len(kept))] = np.inf
        i, _ = np.unravel_index(int(np.argmin(d2)), d2.shape)  # i < j: i is the older one
        del kept[int(i)]
        self._entries[mode] = _EntryRecord.of(kept, np.delete(np.delete(d2, i, 0), i, 1))

    def notify_perturbation(self) -> None:
        """The next reading follows a perturbation: a mode exit then is not a failure."""
        self._pending = True

    def decide(self, x: npt.ArrayLike, sensors: Sensors, *, perturbed: bool = False) -> str:
        """Advance the automaton, the monitor and the cuts on a reading; return the DS key to
        run (``""`` while holding). :meth:`step` is this plus the velocity."""
        if self._state is None:
            raise TliError("call reset(x0, sensors) before step()")
        return self._decide(self._vector(x), self._read(sensors), perturbed)

    def _decide(self, xv: FloatArray, reading: frozenset[str], perturbed: bool) -> str:
        """:meth:`decide` on a checked state (finite, shape (n,), not updated in place later:
        it may be recorded) and a checked reading (the set of true inputs)."""
        assert self._state is not None  # reset() ran (decide checks)
        self._steps += 1
        t = self._steps
        perturbed = perturbed or self._pending
        self._pending = False
        self._pending_seen = perturbed
        if perturbed:
            self.events.append(Perturbation(t, self._mode))
        cause = "perturbation" if perturbed else "invariance failure"
        if self._reentry is not None:  # the stall rule's re-entry (runtime.stall)
            mode, via, via_key, reading0 = self._reentry
            converged = self._converged(via_key, xv)
            self._last = xv
            free = frozenset(self.automaton.free_inputs)  # never recorded in a state's inputs
            if reading - free == reading0 and not converged:
                return via_key  # a perturbation does not end it: the DS of via rides it out
            # back to the stalled mode (its automaton state was kept); a changed reading (or
            # a perturbation reported in this period) is the next period's step, from there
            self._reentry = None
            self._pending = perturbed
            assert self._state is not None
            self._enter(self._state)
            self.events.append(Reentered(t, mode, via, converged))
            self.events.append(ModeChange(t, via, mode, self._state, True))
            self._entry = xv
            self._reentered_at = t  # no stall test in this period (:meth:`monitor`)
            return self._key
        was_holding = self._holding
        if was_holding and not perturbed:
            cause = "assumption violation"
        try:
            new_state, new_mode = self.automaton.next_mode(self._state, reading)
            self._holding = False
        except AssumptionViolation as exc:
            grown = self._grow(t, reading, perturbed) if self.learn_transitions else None
            if grown is not None:
                new_state, new_mode = grown, self.automaton.states[grown].mode
                self._holding = False
                return self._advance(t, xv, new_state, new_mode, perturbed, cause)
            sid = self._resync(reading)
            self.events.append(AssumptionViolationEvent(t, self._state, tuple(sorted(reading)),
                                                        str(exc), sid))
            if sid is None:
                self._holding = True
                return ""
            self._holding = False
            new_state, new_mode = sid, self.automaton.states[sid].mode
            if not perturbed:
                cause = "assumption violation"
        return self._advance(t, xv, new_state, new_mode, perturbed, cause)

    def _advance(self, t: int, xv: FloatArray, new_state: int, new_mode: str, perturbed: bool,
                 cause: str) -> str:
        """Enter ``new_state`` (mode change, replan, invariance failure and its cut)."""
        old_mode, planned = self._mode, self._planned
        if new_mode != old_mode:
            expected = new_mode == planned
            # a cut only for a policy-made exit: not after a perturbation, and not across a
            # reading the assumptions rule out (a sensor glitch or an unreported push; its
            # "last in-mode state" may not be one)
            # nor for a move to a later mode of the plan (planned progress: the offline
            # hand-off step's rule too, plan_progress)
            progress = new_mode in self._progress.get(old_mode, frozenset())
            if not expected and not progress and cause == "invariance failure" and \
                    self._last is not None and self._entry is not None:
                self._failure(t, old_mode, new_mode, xv)
            self._enter(new_state)
            if not expected:
                self.events.append(Replan(t, old_mode, new_mode, planned, self._planned, cause))
            self.events.append(ModeChange(t, old_mode, new_mode, new_state, expected))
            self._entry = xv
            self._record_entry(new_mode, xv)
        else:
            if new_state != self._state:
                self._enter(new_state)
            if perturbed:
                self._entry = xv
                self._record_entry(new_mode, xv)
        self._last = xv
        return self._key

    def step(self, x: npt.ArrayLike, sensors: Sensors, *, perturbed: bool = False
             ) -> FloatArray:
        """One control step: the velocity to apply at ``x`` given the reading there.

        Parameters
        ----------
        x : array_like, shape (n,)
            The current state.
        sensors : mapping of str to bool, or iterable of str
            The reading at ``x``.
        perturbed : bool, optional
            A perturbation moved the state since the last step.

        Returns
        -------
        ndarray, shape (n,)
            ``M_i(x) f_i(x)`` of the mode's DS (zero while holding).
        """
        key = self.monitor(self.decide(x, sensors, perturbed=perturbed))
        if not key or self._last is None:
            return np.zeros(self.model.dim)
        return self.model.modes[key].velocity(self._last, dt=self.dt)

    def monitor(self, key: str) -> str:
        """The assumption monitor's stall test (:mod:`~.stall`) after :meth:`decide` returned
        ``key``: the DS key to run (the re-entry's when the stall rule fires; ``key`` itself
        without a rule, while holding or during a re-entry). :meth:`step` is ``decide``, this,
        and the velocity; a supervisor beside another executive (the exported C evaluator,
        :mod:`tli_verify.deploy.cloop`) calls the two in the same order."""
        if not key or self._last is None or self.stall_rule is None or \
                self._reentry is not None or self._reentered_at == self._steps:
            # a period that ended a re-entry is the return's: were the test run in it (with a
            # dwell of one step), a re-entry ended by a new reading would fire again before
            # the automaton saw that reading, and loop for as long as V stays low
            return key
        return self._monitor_stall(key, self._last)

    # ---------------------------------------------------------------- the stall rule
    def _level(self, key: str) -> float:
        """``lambda_min(P) r^2`` of DS ``key`` (:func:`~.stall.lyapunov_level`), cached."""
        level = self._stall_levels.get(key)
        if level is None:
            assert self.stall_rule is not None
            level = lyapunov_level(self.model.modes[key].ds.P, self.stall_rule.radius)
            self._stall_levels[key] = level
        return level

    def _converged(self, key: str, x: FloatArray) -> bool:
        """The certified ``V`` of DS ``key`` at ``x`` is below the stall rule's level."""
        ds = self.model.modes[key].ds
        return lyapunov_value(ds.attractor, ds.P, x) < self._level(key)

    def _monitor_stall(self, key: str, x: FloatArray) -> str:
        """The assumption monitor's stall test after a step (:mod:`~.stall`); the DS key to
        run (the predecessor's when the rule fires)."""
        rule = self.stall_rule
        assert rule is not None
        if self.done or self._holding or self._mode in self.goal_modes:
            self._stall_count = 0
            return key
        if self._stall_at != (self._state, key) or self._pending_seen:
            self._stall_at, self._stall_count = (self._state, key), 0
            self._stall_trend.clear()
        ds = self.model.modes[key].ds
        value = lyapunov_value(ds.attractor, ds.P, x)
        trend = self._stall_trend
        trend.append(value)
        dwell, window = rule.periods(self.dt)
        if len(trend) > window:
            trend.popleft()
        blocked = len(trend) == window and value > (1.0 - rule.progress) * trend[0]
        self._stall_count = self._stall_count + 1 if value < self._level(key) else 0
        if self._stall_count < dwell and not blocked:
            return key
        self._stall_count = 0
        trend.clear()
        pred = reentry_route(self.automaton, self.model, self._mode)
        if pred is None:
            return key
        via, via_key = pred
        t, mode = self._steps, self._mode
        assert self._state is not None
        reading = frozenset(self.automaton.states[self._state].inputs)
        self.events.append(Stall(t, mode, key, value, via, via_key))
        self.events.append(ModeChange(t, mode, via, self._state, False))
        self._reentry = (mode, via, via_key, reading)
        self._mode, self._key, self._planned = via, via_key, mode
        self._entry = x
        return via_key

    def velocity(self, x: npt.ArrayLike) -> FloatArray:
        """The current DS's velocity at ``x`` without advancing (zero while holding)."""
        if self._holding or not self._key:
            return np.zeros(self.model.dim)
        return self.model.modes[self._key].velocity(self._vector(x), dt=self.dt)

    # ---------------------------------------------------------------- growing the spec
    def _grow(self, t: int, reading: frozenset[str], perturbed: bool) -> int | None:
        """Learn the transition a reading the assumptions rule out shows
        (:func:`~tli_verify.runtime.growth.learn_transition`); the state of the grown automaton
        to carry on from, or None (refused, or nothing to learn: the caller resynchronizes)."""
        spec = self.spec
        if spec is None or self._state is None:  # pragma: no cover - checked in __init__
            return None
        from_mode = self._mode
        if (from_mode, reading) in self._refused:
            return None
        out = learn_transition(spec, self.automaton, self._state, from_mode, reading,
                               self.model, self.goal_modes)
        if isinstance(out, Refusal):
            self._refused = self._refused | {(from_mode, reading)}
            if out.reason is not None:
                self.events.append(TransitionRefused(t, from_mode, out.to_mode,
                                                     tuple(sorted(reading)), out.reason))
            return None
        self.automaton = out.automaton
        self._plan_cache = out.plans
        self._progress = plan_progress(self._plan_cache.values())
        self._spec_text = spec_to_toml(out.spec)
        self._learned = (*self._learned, (from_mode, out.to_mode))
        self._refused = frozenset()  # the spec changed: earlier refusals may not hold now
        mode_edges = sum(1 for a, b in out.automaton.mode_transitions() if a != b)
        self.events.append(TransitionLearned(
            t, from_mode, out.to_mode, tuple(sorted(reading)), out.state,
            len(out.automaton.states), len(out.automaton.transitions), mode_edges, perturbed))
        return out.state

    # ---------------------------------------------------------------- online cuts
    def _failure(self, t: int, mode: str, to_mode: str, x_out: FloatArray) -> None:
        """Report an invariance failure and learn its cut (:func:`~.online.online_cut`)."""
        if self._entry is None or self._last is None:  # pragma: no cover - set by reset
            return
        key = self._key
        self.events.append(InvarianceFailure(t, mode, key, to_mode, self._entry.copy(),
                                             self._last.copy(), x_out.copy()))
        if not self.learn_cuts:
            return
        try:
            failure = _Failure(entry=self._entry, last_inside=self._last, outside=x_out)
        except ModelError as exc:
            self.events.append(CutFailed(t, mode, str(exc)))
            return
        out = online_cut(self.model, key, mode, failure, self._entries.get(mode, []),
                         margin=self.cut_margin)
        if out.model is None or out.attempt is None or out.attempt.cut is None:
            self.events.append(CutFailed(t, mode, str(out.error)))
            return
        self._model = out.model
        self.events.append(CutAdded(t, mode, self.model.keys_of(mode), out.attempt.cut,
                                    len(self.model.region_cuts(mode)), out.attempt.fallback,
                                    out.attempt.shift))

