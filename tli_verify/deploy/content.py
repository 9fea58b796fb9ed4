"""The artifact's content: what a project's model exports to (``tli export``).

One derivation, used by the exporter (:mod:`tli_verify.deploy.export`, which writes it) and by
the gate (:func:`tli_verify.deploy.gate.artifact_item`, which re-derives it to compare a
deployed artifact's numbers with the model and evidence it names). The format is described in
:mod:`tli_verify.deploy.export` and ``docs/howto/deploy-to-robot.md``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tli_verify._version import __version__
from tli_verify.boundary.modulation import (
    BOUNDARY_TOL,
    DEFAULT_BARRIER_RATE,
    DEGENERATE_TOL,
    GUARD_TOL,
)
from tli_verify.deploy.artifact import FORMAT, MAX_C_BITS, SCHEMA_VERSION
from tli_verify.errors import ExportError, TliError, bad_input
from tli_verify.io import read_json
from tli_verify.logic.automaton import plan_progress
from tli_verify.project import Session
from tli_verify.runtime.coverage import plan_states
from tli_verify.runtime.stall import STALL_PARAMETERS, StallRule, lyapunov_level, reentry_route
from tli_verify.tasks.project import check_goal

__all__ = ["DEFAULT_MAX_ONLINE_CUTS", "MAX_ONLINE_CUTS", "artifact_of", "build_artifact",
           "tested_stall_rule"]

DEFAULT_MAX_ONLINE_CUTS = 16
"""Cuts the C evaluator can add per DS at run time (fixed storage; one more is refused)."""
MAX_ONLINE_CUTS = 63
"""Most online cut slots per DS (the C evaluator holds at most 64 cuts per DS, offline ones
included: ``TLI_MAX_CUTS``)."""


def _floats(a: Any) -> list[Any]:
    return np.asarray(a, dtype=np.float64).tolist()


def build_artifact(setup: Any, *, goal_modes: Sequence[str], goal_inputs: Sequence[str],
                   sources: dict[str, Any], max_online_cuts: int = DEFAULT_MAX_ONLINE_CUTS,
                   stall: StallRule | None = None) -> dict[str, Any]:
    """The artifact's content (without ``content_sha256``) of a loaded run setup.

    Parameters
    ----------
    setup : tli_verify.runtime.setup.Setup
        Task, automaton, model and certificate (:attr:`tli_verify.loaded.LoadedProject.setup`).
    goal_modes, goal_inputs : sequence of str
        The goal the executive runs to.
    sources : dict
        ``{"spec"|"model"|"certificate"|"task"|"evidence": {"file", "sha256"} or None}``.
    max_online_cuts : int, optional
        Fixed storage per DS for cuts added at run time.
    stall : StallRule, optional
        The executive's stall rule (:mod:`tli_verify.runtime.stall`) the artifact runs: its
        parameters, each DS's level ``lambda_min(P) r^2`` and each mode's re-entry DS
        (:func:`~tli_verify.runtime.stall.reentry_route`). None: no stall rule.

    Returns
    -------
    dict
        JSON-ready (schema ``policy.schema.json``).

    Raises
    ------
    ExportError
        More than :data:`MAX_C_BITS` sensors or modes (exit 2).
    """
    aut, model = setup.automaton, setup.model
    plans = plan_states(aut, model, tuple(goal_modes), str(model.path))
    progress = plan_progress(plans.values())
    modes = list(dict.fromkeys([*aut.modes, *(s.mode for s in aut.states)]))
    if len(aut.inputs) > MAX_C_BITS or len(modes) > MAX_C_BITS:
        raise ExportError(f"{model.path}: {len(aut.inputs)} sensors and {len(modes)} modes; the "
                          f"C evaluator takes at most {MAX_C_BITS} of each")
    keys = list(model.modes)
    ds = []
    for k in keys:
        mm = model.modes[k]
        lp = mm.ds
        center, rows = lp.mixture.quadratic_form()
        ds.append({
            "key": k, "mode": mm.mode, "next_mode": mm.next_mode,
            "attractor": _floats(lp.attractor), "P": _floats(lp.P),
            "priors": _floats(lp.priors), "means": _floats(lp.means), "covs": _floats(lp.covs),
            "gmm": {"center": list(center), "quadratic": [list(r[: len(r) - lp.dim])
                                                          for r, _ in rows],
                    "linear": [list(r[len(r) - lp.dim:]) for r, _ in rows],
                    "constant": [c for _, c in rows]},
            "A": _floats(lp.A), "b": _floats(-np.einsum("kij,j->ki", lp.A, lp.attractor)),
            "cuts": [{"normal": _floats(c.normal), "point": _floats(c.point)} for c in mm.cuts],
        })
    states = []
    for s in aut.states:
        st = plans[s.id]
        states.append({"id": s.id, "mode": s.mode, "inputs": list(s.inputs), "goal": s.goal,
                       "ds": st.key, "planned": st.next_mode})
    return {
        "format": FORMAT, "schema_version": SCHEMA_VERSION,
        "name": Path(str(model.path)).name.removesuffix(".json").removesuffix(".model"),
        "tool": {"name": "tli-verify", "version": __version__},
        "state_names": list(model.state_names), "dim": model.dim,
        "dt": float(setup.task.dt),
        "readings": {"source": "inputs", "inputs": list(aut.inputs),
                     "note": "one bit per sensor, in this order, computed by the robot's "
                     "perception as the task file (sources.task) defines them"},
        "automaton": {
            "name": aut.name, "inputs": list(aut.inputs), "free_inputs": list(aut.free_inputs),
            "modes": modes, "states": states, "initial": list(aut.initial),
            "edges": [{"from": t.source, "to": t.target, "on": list(t.sensors),
                       "off": list(t.off)} for t in aut.transitions],
            "progress": {m: sorted(progress.get(m, ())) for m in modes},
            "goal_modes": list(goal_modes), "goal_inputs": list(goal_inputs),
        },
        "ds": ds,
        "modulation": {"barrier_rate": DEFAULT_BARRIER_RATE, "degenerate_tol": DEGENERATE_TOL,
                       "boundary_tol": BOUNDARY_TOL, "guard_tol": GUARD_TOL,
                       "max_online_cuts": int(max_online_cuts)},
        "stall": None if stall is None else dict(
            stall.to_dict(),
            levels=[lyapunov_level(model.modes[k].ds.P, stall.radius) for k in keys],
            reentry=[None if (r := reentry_route(aut, model, m)) is None else r[1]
                     for m in modes]),
        "sources": sources,
    }


def artifact_of(session: Session, *, sources: dict[str, Any],
                max_online_cuts: int) -> dict[str, Any]:
    """The artifact content (no ``content_sha256``) a project's model exports to: its setup
    and goal, the stall rule its current evidence ran (:func:`tested_stall_rule`). The one
    derivation :func:`export_policy` writes and the gate re-derives to compare a deployed
    artifact's numbers with (:func:`tli_verify.deploy.gate.artifact_item`).

    Raises
    ------
    TliError
        The project does not load (exit 2).
    """
    resolved = session.files
    setup = session.setup
    goal_modes = check_goal(setup.automaton, resolved.goal, where=str(resolved.spec))
    return build_artifact(setup, goal_modes=goal_modes, goal_inputs=resolved.goal.sensors,
                          sources=sources, max_online_cuts=max_online_cuts,
                          stall=tested_stall_rule(Path(resolved.evidence)))


def tested_stall_rule(evidence: Path) -> StallRule | None:
    """The stall rule the campaign evidence ran (a physical campaign's ``physics.stall_rule``),
    which the artifact must run too: the evidence binds what it tested. None: no evidence, a
    kinematic campaign (its executive runs no stall rule) or ``--no-stall-rule``.

    Raises
    ------
    ExportError
        The recorded rule is not a valid :class:`~tli_verify.runtime.stall.StallRule` (exit 2).
    """
    if not evidence.is_file():
        return None
    data = read_json(evidence, what="campaign evidence", error=ExportError)
    physics = data.get("physics") if isinstance(data, dict) else None
    rule = physics.get("stall_rule") if isinstance(physics, dict) else None
    if rule is None:
        return None
    try:
        return StallRule(**{k: float(rule[k]) for k in STALL_PARAMETERS})
    except (KeyError, TypeError, ValueError, TliError) as exc:
        raise bad_input(ExportError, f"{evidence}: physics.stall_rule: {exc}") from None
