"""The search for the paper's Fig. 7 on the scoop task, and the record of the case it finds.

Fig. 7: without modulation the system loops ``a -> b -> a -> b ...`` (mode b's DS leaves the soup
back into white, a's DS brings the spoon back, again and again) until its step budget runs out
(:func:`is_fig7_loop`); LTL-DS reaches ``d`` after the one cut that the first ``b -> a`` failure
produces (:func:`is_fig7_rescue`). :func:`find_loop` searches seeded episodes for such a case,
:func:`fig7_search` runs it on the shipped model (perturbations of the nominal run from
:data:`NOMINAL_START`, then random starts), and :func:`fig7_record` makes its result JSON-ready,
with the ``tli run`` arguments that replay it.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 7.2, Fig. 7.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.defaults import Stream
from tli_verify.defaults import rng as default_rng
from tli_verify.experiments.scoop_task import scoop_setup
from tli_verify.runtime.episodes import (
    mode_runs,
    mode_string,
    random_perturbations,
    random_start,
    run_variant,
    run_variant_batch,
)
from tli_verify.runtime.events import CutAdded, InvarianceFailure, event_to_json
from tli_verify.runtime.loop import EpisodeResult
from tli_verify.runtime.setup import Setup
from tli_verify.tasks.task import Task

__all__ = [
    "FIG7_MIN_ROUNDS",
    "NOMINAL_START",
    "b_to_a_failures",
    "fig7_record",
    "fig7_search",
    "find_loop",
    "is_fig7_loop",
    "is_fig7_rescue",
]

FloatArray = npt.NDArray[np.float64]

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


def _rounded_perturbations(rng: np.random.Generator, count: int, task: Task, *,
                           last: int) -> dict[int, FloatArray]:
    table = random_perturbations(rng, count, task, last=last)
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
    rng = default_rng(seed, Stream.FIG7)
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


def fig7_search(seed: int, tries: int, steps: int, lag: int = 0) -> dict[str, Any]:
    """The Fig. 7 search on the shipped model (:func:`find_loop`), in two stages.

    1. Perturbations of the nominal run: from :data:`NOMINAL_START`, ``tries`` seeded single
       random perturbations (:func:`~tli_verify.runtime.episodes.random_perturbations` within
       the nominal run's steps, displacements rounded to 0.01 so the case replays from the
       command line).
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


def fig7_record(search: Mapping[str, Any]) -> dict[str, Any]:
    """The JSON-ready Fig. 7 field of ``tli experiment scoop`` (from :func:`fig7_search`).

    ``found`` false: only the text. Otherwise the case (seed, stage, try, start,
    perturbations, the ``tli run`` replay arguments) and both episodes: the unmodulated one
    (mode sequence and run-length trace, ``b -> a`` failures, budget exhausted) and LTL-DS's
    (trace, its invariance failure and the cut it added).
    """
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
