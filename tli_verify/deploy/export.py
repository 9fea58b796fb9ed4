"""The deployable policy artifact (``tli export``): one self-describing file per certified policy.

A robot's controller runs in C or C++ on a real-time thread, without numpy; this module writes
what such a controller needs to run *the* policy the gate let through (paper eq. 6): the task
automaton ``Omega_phi`` (states, initial states, edges as cubes over the sensor bits, the planner's
choice per state), per DS the position GMM (priors, means, covariances and the precomputed
quadratic form of ``log pi_k N(x | mu_k, Sigma_k)``), ``A_k``, ``b_k = -A_k x*``, ``x*``, ``P``,
the cuts and the modulation constants (eq. 7 and the corner guard,
:mod:`tli_verify.boundary.modulation`), the stall rule the campaign evidence ran
(:mod:`tli_verify.runtime.stall`: its parameters, each DS's level and each mode's re-entry DS),
the control period, and the SHA-256 of the spec, model, certificate, task and campaign evidence
it was made from. The content is derived in :mod:`tli_verify.deploy.content`.

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

import dataclasses
import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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
from tli_verify.deploy.cloop import CEvaluator, compile_evaluator
from tli_verify.deploy.content import (
    DEFAULT_MAX_ONLINE_CUTS,
    MAX_ONLINE_CUTS,
    artifact_of,
    build_artifact,
    tested_stall_rule,
)
from tli_verify.errors import ExportError, GateError, TliError, bad_input
from tli_verify.io import atomic_write_text, canonical_json, check_plan, sha256_file
from tli_verify.project import open_project
from tli_verify.tasks.project import model_files

__all__ = ["DEFAULT_MAX_ONLINE_CUTS", "FORMAT", "MAX_C_BITS", "MAX_ONLINE_CUTS", "SCHEMA_VERSION",
           "TEXT_MAGIC", "Exported", "artifact_of", "build_artifact", "c_load_check",
           "check_artifact",
           "content_hash", "export_policy", "render_text", "tested_stall_rule", "text_path_for",
           "write_artifact"]


@dataclass(frozen=True, slots=True)
class Exported:
    """What :func:`export_policy` wrote.

    Attributes
    ----------
    json_path, text_path : Path
    content_sha256 : str
    artifact : dict
    c_loaded : bool
        The C evaluator, built with the system compiler, loaded the text form before it was
        written (False: no C compiler here, so not checked).
    """

    json_path: Path
    text_path: Path
    content_sha256: str
    artifact: dict[str, Any]
    c_loaded: bool = False


def _hash_or_none(path: Path | None) -> dict[str, str] | None:

    if path is None or not path.is_file():
        return None
    return {"file": path.name, "sha256": sha256_file(path)}


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
    art = artifact_of(session, sources=sources, max_online_cuts=max_online_cuts)
    loaded = c_load_check(art, where=str(resolved.model))
    return dataclasses.replace(write_artifact(art, out_json), c_loaded=loaded)


def c_load_check(art: dict[str, Any], *, where: str) -> bool:
    """Load an artifact's text form in the C evaluator before it is written: what the robot's
    controller will load must load (its own checks: sizes, SPD ``P``, cuts, stall levels and
    re-entry DS). True when loaded; False when this machine has no C compiler (not checked).

    Raises
    ------
    ExportError
        The C loader refuses it, or the evaluator does not build with the compiler found
        (exit 2), with the message.
    """
    import shutil
    import tempfile

    body = render_text({k: v for k, v in art.items() if k != "content_sha256"})
    digest = hashlib.sha256(body.encode("utf-8")).hexdigest()
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        return False  # no compiler: not checked (a failing build, with one, is an error)
    with tempfile.TemporaryDirectory(prefix="tli-export-c-") as tmp:
        lib = compile_evaluator(tmp)
        text = Path(tmp) / "artifact.tli.txt"
        text.write_text(body + f"sha256 {digest}\n", encoding="utf-8")
        try:
            CEvaluator(lib, text)
        except ExportError as exc:
            raise ExportError(f"{where}: refused: the C evaluator would not load its artifact: "
                              f"{str(exc).split(': ', 1)[-1]}") from None
    return True


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
