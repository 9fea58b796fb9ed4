"""The deployable policy artifact (``tli export``): one self-describing file per certified policy.

A robot's controller runs in C or C++ on a real-time thread, without numpy; this module writes
what such a controller needs to run *the* policy the gate let through (paper eq. 6): the task
automaton ``Omega_phi`` (states, initial states, edges as cubes over the sensor bits, the planner's
choice per state), per DS the position GMM (priors, means, covariances and the precomputed
quadratic form of ``log pi_k N(x | mu_k, Sigma_k)``), ``A_k``, ``b_k = -A_k x*``, ``x*``, ``P``,
the cuts and the modulation constants (eq. 7 and the corner guard,
:mod:`tli_verify.boundary.modulation`), the control period, and the SHA-256 of the spec, model,
certificate, task and campaign evidence it was made from.

Two renderings of the same content are written side by side:

* ``NAME.tli.json`` -- the artifact (:data:`FORMAT`, schema ``tli_verify/schemas/
  policy.schema.json``), for people and tools;
* ``NAME.tli.txt`` -- the same numbers as a flat, line-based token stream (:func:`render_text`)
  that the dependency-free C evaluator (``tli_verify/deploy/c/tli_policy.c``) loads without a
  JSON parser.

Both carry one hash: ``content_sha256`` is the SHA-256 of the text form's body (every line
before its closing ``sha256`` line), and the text form is a pure function of the JSON content
(:func:`render_text`), so :func:`check_artifact` re-derives it from the JSON and the C loader
re-hashes the text; an edit to either file is refused.

Readings are inputs: the controller supplies one bit per sensor, in the artifact's ``inputs``
order, computed by the robot's perception as the task file (SHA-256 recorded) defines them.

Export is refused (:class:`~tli_verify.errors.GateError`, exit 1, one line) for a model the
deployment gate would block: :func:`export_policy` runs :func:`~tli_verify.deploy.gate.run_gate`
on the model's project and refuses on its first blocker.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Sequence
from dataclasses import dataclass
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
from tli_verify.deploy.artifact import (
    FORMAT,
    MAX_C_BITS,
    SCHEMA_VERSION,
    TEXT_MAGIC,
    check_artifact,
    content_hash,
    render_text,
    text_path_for,
)
from tli_verify.errors import ExportError, GateError, TliError, bad_input
from tli_verify.io import atomic_write_text, canonical_json, check_plan, sha256_file
from tli_verify.logic.automaton import plan_progress
from tli_verify.project import open_project
from tli_verify.runtime.coverage import plan_states
from tli_verify.tasks.project import check_goal, model_files

__all__ = ["FORMAT", "MAX_C_BITS", "SCHEMA_VERSION", "TEXT_MAGIC", "Exported", "build_artifact",
           "check_artifact", "content_hash", "export_policy", "render_text", "text_path_for",
           "write_artifact"]

DEFAULT_MAX_ONLINE_CUTS = 16
"""Cuts the C evaluator can add per DS at run time (fixed storage; one more is refused)."""
MAX_ONLINE_CUTS = 63
"""Most online cut slots per DS (the C evaluator holds at most 64 cuts per DS, offline ones
included: ``TLI_MAX_CUTS``)."""


@dataclass(frozen=True, slots=True)
class Exported:
    """What :func:`export_policy` wrote.

    Attributes
    ----------
    json_path, text_path : Path
    content_sha256 : str
    artifact : dict
    """

    json_path: Path
    text_path: Path
    content_sha256: str
    artifact: dict[str, Any]


def _hash_or_none(path: Path | None) -> dict[str, str] | None:

    if path is None or not path.is_file():
        return None
    return {"file": path.name, "sha256": sha256_file(path)}


def _floats(a: Any) -> list[Any]:
    return np.asarray(a, dtype=np.float64).tolist()


def build_artifact(setup: Any, *, goal_modes: Sequence[str], goal_inputs: Sequence[str],
                   sources: dict[str, Any], max_online_cuts: int = DEFAULT_MAX_ONLINE_CUTS
                   ) -> dict[str, Any]:
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
        "sources": sources,
    }


def export_policy(model: str | os.PathLike[str], out: str | os.PathLike[str], *,
                  rerun: int | None = None, max_online_cuts: int = DEFAULT_MAX_ONLINE_CUTS,
                  ) -> Exported:
    """Gate a model's project, then write its artifact (JSON and text form).

    Parameters
    ----------
    model : path-like
        A model file under a project's ``models/`` (its spec, task, certificate and evidence
        are found and read once by the project session, :func:`tli_verify.project.open_project`).
    out : path-like
        The JSON artifact to write; the text form goes to :func:`text_path_for`.
    rerun : int, optional
        Examples of the gate's re-run campaign (default: the gate's; 0 skips it, Python only).
    max_online_cuts : int, optional
        Cuts the C evaluator may add per DS at run time.

    Returns
    -------
    Exported

    Raises
    ------
    GateError
        The gate blocks the model's project (exit 1), naming the first blocker.
    ExportError, OutputError, TaskError, ModelError, SpecError
        Bad input (exit 2).
    """
    from tli_verify.deploy.gate import run_gate

    if isinstance(max_online_cuts, bool) or not isinstance(max_online_cuts, int) or \
            not 0 <= max_online_cuts <= MAX_ONLINE_CUTS:
        raise bad_input(ExportError, "max_online_cuts must be an integer in "
                        f"0..{MAX_ONLINE_CUTS}, got {max_online_cuts!r}")
    session = open_project(model=model)
    resolved = session.files
    out_json = Path(out)
    out_text = text_path_for(out_json)
    check_plan(inputs=[*resolved.inputs, resolved.evidence],
               outputs=[(out_json, "policy artifact"), (out_text, "policy artifact text form")])
    root = model_files(resolved.model).root
    report = run_gate(root, rerun=rerun)
    mine = Path(os.path.abspath(resolved.model))
    if not report.ok:
        first = report.blockers[0]
        raise GateError(f"{resolved.model}: refused: the gate blocks its project {root}: "
                        f"{first.path}: {first.message}")
    if not any(i.kind == "model" and Path(os.path.abspath(root / i.path)) == mine
               for i in report.items):
        raise bad_input(GateError, f"{resolved.model}: refused: not a model the gate checked "
                        f"under {root}/models/")
    setup = session.setup
    goal_modes = check_goal(setup.automaton, resolved.goal, where=str(resolved.spec))
    try:  # the executive's own checks: certificate coverage, control period, plan per state
        session.policy("LTL-DS")
    except TliError as exc:
        raise GateError(f"{resolved.model}: refused: {exc}") from None
    task_file = Path(resolved.task.source.path) if resolved.task.source.path else None
    sources = {"spec": _hash_or_none(Path(resolved.spec)),
               "model": _hash_or_none(Path(resolved.model)),
               "certificate": _hash_or_none(Path(resolved.certificate)),
               "task": _hash_or_none(task_file),
               "evidence": _hash_or_none(Path(resolved.evidence))}
    art = build_artifact(setup, goal_modes=goal_modes, goal_inputs=resolved.goal.sensors,
                         sources=sources, max_online_cuts=max_online_cuts)
    return write_artifact(art, out_json)


def write_artifact(art: dict[str, Any], out: str | os.PathLike[str]) -> Exported:
    """Hash an artifact's content and write it (JSON) and its text form, atomically.

    The caller checked the paths (:func:`tli_verify.io.check_plan`); ``art`` is the content of
    :func:`build_artifact` (its ``content_sha256`` is set here).
    """
    out_json = Path(out)
    out_text = text_path_for(out_json)
    art = {k: v for k, v in art.items() if k != "content_sha256"}
    body = render_text(art)
    digest = hashlib.sha256(body.encode("utf-8")).hexdigest()
    art["content_sha256"] = digest
    atomic_write_text(out_text, body + f"sha256 {digest}\n")
    atomic_write_text(out_json, canonical_json(art))
    return Exported(json_path=out_json, text_path=out_text, content_sha256=digest, artifact=art)
