"""Case files: a counterexample saved as JSON, read back, checked and replayed (``tli replay``).

:func:`case_document` records the task, the files and their SHA-256, the start, the
perturbation sequence, the seed and the expected violation (``case.schema.json``);
:func:`read_case` re-checks all of it against the files on disk; :func:`replay_case` replays it
deterministically.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from tli_verify.errors import CampaignError, TaskError, TliError
from tli_verify.io import bundled_root, read_json, validate_schema
from tli_verify.limits import MAX_CAMPAIGN_STEPS, MAX_INPUT_BYTES, MAX_PUSHES
from tli_verify.tasks.project import resolve
from tli_verify.tasks.registry import find_task
from tli_verify.verify.config import SimSpec, task_ref
from tli_verify.verify.oracle import (
    Verdict,
    ViolationKind,
)
from tli_verify.verify.simulate import check_case
from tli_verify.verify.strategies import (
    Case,
    case_from_json,
    case_to_json,
)

__all__ = [
    "CASE_KIND",
    "CASE_VERSION",
    "case_document",
    "read_case",
    "replay_case",
]


CASE_KIND = "tli-verify/bisimulation-case"


CASE_VERSION = 2
"""Version 2 binds the task (``files.task``); version 1 named a bundled world (``world``)."""


def _shown_path(path: str) -> str:
    """A file's path relative to the repository root when under it, else absolute."""
    try:
        root = Path(os.path.realpath(bundled_root()))
    except TliError:
        root = None
    real = Path(os.path.realpath(path))
    return str(real.relative_to(root)) if root is not None and real.is_relative_to(root) \
        else str(real)


def bound_files(spec: SimSpec) -> dict[str, dict[str, str]]:
    """The files of a run (paths relative to the repository root when under it) and the task
    (a file, or an entry point by name), each with the SHA-256 that binds it."""
    out: dict[str, dict[str, str]] = {}
    for name, path, h in zip(("spec", "model", "certificate"),
                             (spec.spec, spec.model, spec.certificate), spec.hashes,
                             strict=True):
        out[name] = {"path": _shown_path(path), "sha256": h}
    if os.path.isfile(spec.task):
        out["task"] = {"path": _shown_path(spec.task), "sha256": spec.task_sha256}
    else:
        out["task"] = {"entry_point": spec.task, "sha256": spec.task_sha256}
    return out


_MAX_MESSAGE = 4000
"""Longest oracle message a case keeps (``expected.messages``, informational)."""


def case_document(spec: SimSpec, case: Case, verdict: Verdict, *, seed: int,
                  index: int | None = None, shrunk: bool = False,
                  kind: ViolationKind | None = None) -> dict[str, Any]:
    """The JSON case file of a counterexample (``tli replay`` reads it; schema
    ``tli_verify/schemas/case.schema.json``); the expected violation is ``kind`` (the one the
    shrinker kept), default the verdict's primary one.

    Raises
    ------
    ValueError
        The verdict has no violation (a case documents one).
    """
    primary = kind if kind is not None and kind in verdict.kinds else verdict.primary
    if primary is None:
        raise ValueError("case_document: the verdict violates nothing: not a counterexample")
    return {
        "kind": CASE_KIND,
        "version": CASE_VERSION,
        "lag": int(spec.lag),
        "modulation": bool(spec.modulation),
        "max_cycles": None if spec.max_cycles is None else int(spec.max_cycles),
        "window": int(spec.window),
        "files": bound_files(spec),
        "seed": int(seed),
        "index": None if index is None else int(index),
        "shrunk": bool(shrunk),
        **case_to_json(case),
        "expected": {"violation": primary.value,
                     "violations": sorted(k.value for k in verdict.kinds),
                     "messages": [v.message[:_MAX_MESSAGE] for v in verdict.violations][:5],
                     "oracle_modes": verdict.oracle_modes[:200]},
    }


def _located(case_path: Path, fp: Path) -> Path:
    """A file a case names: absolute, else relative to the case file's directory, else to the
    repository root (the bundled files' parent)."""
    if fp.is_absolute():
        return fp

    candidates = [case_path.parent / fp]
    with contextlib.suppress(TliError):
        candidates.append(bundled_root() / fp)
    return next((c for c in candidates if c.is_file()), candidates[0])


def _check_case_fields(doc: dict[str, Any], p: Path) -> None:
    """What the schema does not say of a case (after it validated): integers written as floats
    (``700.0``), the limits, one way to name the task per version, and an expected violation
    the run showed.

    Raises
    ------
    CampaignError
        (exit 2) Naming the case file, the field and the limit.
    """
    pushes = doc["perturbations"]
    ints: list[tuple[str, Any, bool]] = [  # (field, value, bounded by MAX_CAMPAIGN_STEPS)
        ("version", doc["version"], False), ("lag", doc["lag"], True),
        ("window", doc["window"], True), ("max_cycles", doc["max_cycles"], True),
        ("seed", doc["seed"], False), ("index", doc["index"], False),
        *((f"perturbations[{i}].step", push["step"], True) for i, push in enumerate(pushes))]
    for name, value, bounded in ints:
        if value is None:
            continue
        if not isinstance(value, int):  # the schema's integers include 700.0
            raise CampaignError(f"{p}: {name}: expected an integer, got {value!r}")
        if bounded and value > MAX_CAMPAIGN_STEPS:
            raise CampaignError(f"{p}: {name}: {value} is above MAX_CAMPAIGN_STEPS "
                                f"({MAX_CAMPAIGN_STEPS} steps)")
    if len(pushes) > MAX_PUSHES:
        raise CampaignError(f"{p}: perturbations: {len(pushes)} perturbations, more than "
                            f"MAX_PUSHES ({MAX_PUSHES})")
    task = doc["files"].get("task")
    if doc["version"] == 1 and task is not None:
        raise CampaignError(f"{p}: files.task: a version 1 case names its task by world; "
                            "files.task is for version 2")
    if doc["version"] == 2:  # the schema requires files.task
        if "world" in doc:
            raise CampaignError(f"{p}: world: a version 2 case binds its task by files.task; "
                                "world is for version 1")
        if ("path" in task) == ("entry_point" in task):
            raise CampaignError(f"{p}: files.task: expected a task path or an entry_point "
                                "(one of the two)")
    expected = doc["expected"]
    if expected["violation"] not in expected["violations"]:
        raise CampaignError(f"{p}: expected.violation: {expected['violation']!r} is not one of "
                            f"expected.violations ({', '.join(expected['violations'])})")


def _hash_input(fp: Path, p: Path, field_: str) -> str:
    """SHA-256 of a file a case names, read like any input: at most ``MAX_INPUT_BYTES``.

    Raises
    ------
    CampaignError
        (exit 2) Unreadable or larger than the limit (``/proc/kcore`` would never end).
    """
    import hashlib

    try:
        with open(fp, "rb") as handle:
            data = handle.read(MAX_INPUT_BYTES + 1)
    except OSError as exc:
        raise CampaignError(f"{p}: {field_}: {fp}: cannot read ({exc.strerror or exc})"
                            ) from None
    if len(data) > MAX_INPUT_BYTES:
        raise CampaignError(f"{p}: {field_}: {fp}: larger than the limit of {MAX_INPUT_BYTES} "
                            "bytes (MAX_INPUT_BYTES)")
    return hashlib.sha256(data).hexdigest()


def _case_task(doc: dict[str, Any], p: Path) -> tuple[Any, str]:
    """The task a (validated) case names, and the field that names it.

    Raises
    ------
    CampaignError
        (exit 2) A missing task file, an unknown task or one that does not load.
    """
    if doc["version"] == 1:  # a bundled world by name
        field_, ref = "world", doc["world"]
    else:
        entry = doc["files"]["task"]
        if "path" in entry:
            field_ = "files.task.path"
            ref = _located(p, Path(entry["path"]))
            if not ref.is_file():
                raise CampaignError(f"{p}: {field_}: {ref}: no such task file")
        else:
            field_, ref = "files.task.entry_point", entry["entry_point"]
    try:
        return find_task(ref), field_
    except TliError as exc:
        raise CampaignError(f"{p}: {field_}: {exc}") from None


def read_case(path: str | os.PathLike[str]) -> tuple[dict[str, Any], SimSpec, Case]:
    """Read a case file; the files it names are resolved relative to it when not absolute (else
    to the repository root).

    The file is read with :func:`tli_verify.io.read_json` (bounded; NaN, Infinity and numbers
    that overflow refused) and checked against ``case.schema.json`` before its meaning: the
    limits (``MAX_CAMPAIGN_STEPS``, ``MAX_PUSHES``), the files, the task and their fit
    (:func:`tli_verify.tasks.project.resolve`: the model's dimension, the spec's inputs are the
    task's sensors), the start in the task's workspace, every vector of the task's dimension,
    every target a region of the task.

    Raises
    ------
    CampaignError
        (exit 2) Unreadable, malformed, or naming missing files or files that do not fit; one
        line naming the case file and the field.
    """
    p = Path(path)
    if not p.is_file():
        raise CampaignError(f"{p}: no such case file")
    doc = read_json(p, what="case", error=CampaignError)
    validate_schema(doc, "case.schema.json", where=str(p), error=CampaignError)
    _check_case_fields(doc, p)
    paths: list[str] = []
    for name in ("spec", "model", "certificate"):
        fp = _located(p, Path(doc["files"][name]["path"]))
        if not fp.is_file():
            raise CampaignError(f"{p}: files.{name}.path: {fp}: no such file")
        paths.append(str(fp))
    task, task_field = _case_task(doc, p)
    try:  # the files load and fit the task (dimension, sensors = the spec's inputs, goal)
        resolve(task=task, spec=paths[0], model=paths[1], certificate=paths[2])
    except TaskError as exc:  # a misfit (the message names the file and the task)
        raise CampaignError(f"{p}: files and {task_field} do not fit: {exc}") from None
    except TliError as exc:  # a spec or model that does not load (the message names it)
        raise CampaignError(f"{p}: {exc}") from None
    hashes = [_hash_input(Path(fp), p, f"files.{name}.path")
              for name, fp in zip(("spec", "model", "certificate"), paths, strict=True)]
    task_path, task_sha = task_ref(task)
    lag, mc, window = doc["lag"], doc["max_cycles"], doc["window"]
    try:
        case = case_from_json(doc, dim=task.dim, where=str(p))
    except TliError as exc:
        raise CampaignError(str(exc)) from None
    if not bool(task.in_workspace(np.asarray(case.start)[None])[0]):
        raise CampaignError(f"{p}: start {list(case.start)}: outside the workspace of task "
                            f"{task.name!r}")
    for i, push in enumerate(case.pushes):
        if push.target is not None and push.target not in task.region_names:
            raise CampaignError(f"{p}: perturbations[{i}].target: unknown region "
                                f"{push.target!r} of task {task.name!r} (regions: "
                                f"{', '.join(task.region_names)})")
    spec = SimSpec(task=task_path, task_sha256=task_sha, lag=lag, spec=paths[0],
                   model=paths[1], certificate=paths[2],
                   hashes=(hashes[0], hashes[1], hashes[2]),
                   modulation=doc["modulation"], max_cycles=mc,
                   window=max(window, case.last_step))
    return doc, spec, case


def replay_case(path: str | os.PathLike[str], *, modulation: bool | None = None
                ) -> tuple[dict[str, Any], Verdict, bool, list[str]]:
    """Replay a saved case deterministically.

    Parameters
    ----------
    path : path-like
    modulation : bool, optional
        Override the case's setting (e.g. check that LTL-DS fixes a no-modulation case).

    Returns
    -------
    (doc, Verdict, bool, list of str)
        The case document, the verdict now, whether the expected violation reproduced, and
        notes (files whose SHA-256 changed since the case was saved).

    Raises
    ------
    CampaignError
        (exit 2) A bad case file (:func:`read_case`), before anything is simulated.
    """
    doc, spec, case = read_case(path)
    files = doc["files"]
    notes = [f"{name}: {spec_path} changed since the case was saved (SHA-256 differs)"
             for name, spec_path, h in
             zip(("spec", "model", "certificate"), (spec.spec, spec.model, spec.certificate),
                 spec.hashes, strict=True) if files[name]["sha256"] != h]
    if "task" in files and files["task"]["sha256"] != spec.task_sha256:
        notes.append(f"task: {spec.task} changed since the case was saved (SHA-256 differs)")
    if modulation is not None:
        spec = replace(spec, modulation=modulation)
    want = ViolationKind(doc["expected"]["violation"])  # validated: a kind
    verdict = check_case(spec, case)
    return doc, verdict, want in verdict.kinds, notes
