"""Bisimulation campaigns: generated perturbation sequences against the oracle (paper Sec. 4.4).

:func:`run_campaign` does, for a :class:`CampaignConfig`:

1. **draw** -- the driver draws ``examples`` cases (start + perturbation sequence,
   :func:`tli_verify.verify.strategies.cases`) with hypothesis, deterministically from the seed,
   in chunks of ``batch_size`` on a thread (:func:`draw_chunks`, :func:`draw_cases`:
   ``hypothesis.find`` with ``random=Random(chunk seed)``, a condition that never holds, and no
   example database; hypothesis generates in one process) while the workers simulate;
2. **simulate** -- the cases travel in batches (``batch_size`` runs,
   :func:`simulate_batch`: one vectorised :func:`~tli_verify.runtime.loop.run_episodes`
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
exceeded (:class:`~.simulate.LoopWatchdog`).

A counterexample is saved as a JSON case (:func:`case_document`): task, the files and their
SHA-256, start, perturbation sequence, seed, expected violation; :func:`replay_case` replays it
deterministically (``tli replay``).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.arguments import check_type
from tli_verify.errors import CampaignError
from tli_verify.verify.backends import block_signals_in_this_thread, make_backend
from tli_verify.verify.cases import bound_files, case_document
from tli_verify.verify.config import CampaignConfig, resolve_config, sim_spec
from tli_verify.verify.draws import chunk_seed, config_strategy, draw_chunks
from tli_verify.verify.oracle import (
    PRIORITY,
    ViolationKind,
)
from tli_verify.verify.shrinking import shrink, targeted_search
from tli_verify.verify.simulate import RunOutcome, load, simulate_batch
from tli_verify.verify.strategies import (
    Case,
)

__all__ = [
    "CampaignResult",
    "run_campaign",
]

FloatArray = npt.NDArray[np.float64]


# ------------------------------------------------------------------------------ config


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

    def cuts_by_mode(self) -> dict[str, dict[str, float]]:
        """Cuts learned online per mode: ``{mode: {"total", "runs", "max_per_run"}}`` (runs
        that learned at least one cut of the mode; the most one run learned)."""
        out: dict[str, dict[str, float]] = {}
        for o in self.outcomes:
            for mode, n in o.cuts_by_mode:
                e = out.setdefault(mode, {"total": 0, "runs": 0, "max_per_run": 0})
                e["total"] += n
                e["runs"] += 1
                e["max_per_run"] = max(e["max_per_run"], n)
        return dict(sorted(out.items()))

    def to_dict(self) -> dict[str, Any]:
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
            "cuts_by_mode": self.cuts_by_mode(),
            "runs_beyond_workspace": sum(1 for o in self.outcomes
                                         if o.verdict.beyond_workspace),
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


# ------------------------------------------------------------------------------ simulation


# ------------------------------------------------------------------------------ drawing


# ------------------------------------------------------------------------------ cases


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
    check_type(config, "config", CampaignConfig, "a CampaignConfig", error=CampaignError)
    t0 = time.perf_counter()
    events: list[str] = []

    def emit(text: str) -> None:
        events.append(text)
        if on_event is not None:
            on_event(text)

    _, config = resolve_config(config)  # the task's defaults filled in (recorded as run)
    spec = sim_spec(config)
    ld = load(spec)
    strategy = config_strategy(config, ld)
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
        block_signals_in_this_thread()  # Ctrl-C and SIGTERM are the main thread's
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
        found, v, shrink_steps = targeted_search(spec, strategy, config.seed,
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
        files=bound_files(spec), task_name=ld.task.name)
