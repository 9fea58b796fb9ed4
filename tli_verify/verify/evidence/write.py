"""Writing campaign evidence (``tli verify --evidence``, ``tli evidence``,
:func:`write_campaign_evidence`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tli_verify.errors import EvidenceError, TliError
from tli_verify.io import (
    atomic_write_text,
    canonical_json,
    check_output_file,
)

if TYPE_CHECKING:
    from tli_verify.verify.campaign import CampaignResult
    from tli_verify.verify.config import CampaignConfig
from tli_verify._version import __version__
from tli_verify.errors import OutputError
from tli_verify.io import bundled_root, read_json, validate_schema
from tli_verify.verify.evidence.common import (
    _BadInput,
    _file_entry,
    evidence_digest,
    evidence_path_for,
    task_block,
)
from tli_verify.verify.evidence.rules import (
    CAMPAIGN_SEMANTICS,
    EVIDENCE_KIND,
    EVIDENCE_SCHEMA_VERSION,
)
from tli_verify.verify.evidence.settings import (
    _settings,
)

__all__ = [
    "build_evidence",
    "weaker_than_recorded",
    "write_campaign_evidence",
    "write_evidence",
]


def build_evidence(*, evidence_path: str | os.PathLike[str], world: str,
                   task: Mapping[str, Any],
                   spec: str | os.PathLike[str], model: str | os.PathLike[str],
                   certificate: str | os.PathLike[str], seed: int, examples: int, runs: int,
                   violations: Mapping[str, int], modulation: bool, partial: bool = False,
                   backend: str | None = None, workers: int | None = None,
                   counterexample: Mapping[str, Any] | None = None,
                   inconclusive: int | None = None,
                   settings: Mapping[str, Any] | None = None,
                   expected: Mapping[str, str] | None = None,
                   physics: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The evidence document of one finished campaign (with its digest).

    Parameters
    ----------
    evidence_path : path-like
        Where it will be written (its paths are relative to that directory).
    world : str
        The task's name, or a physical campaign's kind (a :class:`PhysicalWorld`'s name).
    task : mapping
        The task the campaign ran on (:func:`task_block`).
    spec, model, certificate : path-like
        The files the campaign ran; hashed now (SHA-256 of their bytes).
    seed : int
        The campaign's seed, in ``[0, 2**32)``.
    examples : int
        Perturbation sequences drawn (>= 1).
    runs : int
        Simulations run.
    violations : mapping str -> int
        Violations found, by kind (``{}`` or all zero when none).
    modulation : bool
        Whether the policy ran with modulation (paper eq. 7).
    partial : bool, optional
        The campaign was interrupted.
    backend : str, optional
        ``"process"``, ``"dask"``, ... (informational).
    workers : int, optional
        Worker count (informational).
    counterexample : mapping, optional
        The shrunk counterexample, when one was found.
    inconclusive : int, optional
        Runs whose reachability the oracle could not decide (informational).
    settings : mapping, optional
        The campaign's other parameters (``max_pushes``, ``window``, ``levels``, ``lag``, ...;
        JSON values): ``tli gate --rerun`` runs with them again.
    expected : mapping str -> str, optional
        ``spec``/``model``/``certificate`` -> the SHA-256 the campaign ran the file at: a file
        that changed since is refused.
    physics : mapping, optional
        A physical campaign's block (world a :class:`PhysicalWorld`): ``robot``, ``variant``,
        ``duration``, ``pushes``, ``tilts``, ``trials``, ``successes``, ... (schema
        ``physics``).

    Returns
    -------
    dict
        Valid against ``campaign.schema.json``.

    Raises
    ------
    EvidenceError
        (exit 2) A file is missing or changed since the campaign ran it, or a field is out of
        range (the schema names it).
    """
    base = Path(evidence_path).parent
    by_kind = {str(k): int(v) for k, v in violations.items()}
    doc: dict[str, Any] = {
        "schema_version": EVIDENCE_SCHEMA_VERSION,
        "kind": EVIDENCE_KIND,
        "tool": {"name": "tli-verify", "version": __version__},
        "campaign_semantics": CAMPAIGN_SEMANTICS,
        "world": str(world),
        "task": dict(task),
        "spec": _file_entry(Path(spec), base, "spec"),
        "model": _file_entry(Path(model), base, "model"),
        "certificate": _file_entry(Path(certificate), base, "certificate"),
        "campaign": {
            "seed": int(seed), "examples": int(examples), "runs": int(runs),
            "modulation": bool(modulation), "partial": bool(partial),
            "backend": backend, "workers": None if workers is None else int(workers),
            "failure_probability_bound_95": 3.0 / int(examples) if int(examples) > 0 else 3.0,
        },
        "violations": {"total": sum(by_kind.values()), "by_kind": by_kind},
        "counterexample": None if counterexample is None else dict(counterexample),
    }
    if inconclusive is not None:
        doc["campaign"]["inconclusive"] = int(inconclusive)
    if settings is not None:
        doc["campaign"]["settings"] = {str(k): v for k, v in settings.items()}
    if physics is not None:
        doc["physics"] = dict(physics)
    for key, sha in (expected or {}).items():
        if doc[key]["sha256"] != sha:
            raise _BadInput(f"{evidence_path}: the {key} file {doc[key]['path']} changed "
                            f"since the campaign ran it (SHA-256 {sha[:12]}... then, "
                            f"{doc[key]['sha256'][:12]}... now): re-run the campaign")
    doc["digest"] = evidence_digest(doc)
    validate_schema(doc, "campaign.schema.json", where=str(evidence_path), error=_BadInput)
    return doc


def write_evidence(path: str | os.PathLike[str], **fields: Any) -> dict[str, Any]:
    """Build (:func:`build_evidence`) and write an evidence file atomically (canonical JSON).

    Parameters
    ----------
    path : path-like
        ``certificates/<name>.campaign.json`` (see :func:`evidence_path_for`).
    **fields
        The keyword arguments of :func:`build_evidence` but ``evidence_path``.

    Returns
    -------
    dict
        The document written.

    Raises
    ------
    OutputError
        (exit 2) The path cannot be written or is one of the campaign's input files.
    EvidenceError
        (exit 2) See :func:`build_evidence`.
    """
    inputs = [fields[k] for k in ("spec", "model", "certificate") if fields.get(k) is not None]
    check_output_file(path, inputs=inputs, what="campaign evidence")
    doc = build_evidence(evidence_path=path, **fields)
    atomic_write_text(path, canonical_json(doc))
    return doc


def write_campaign_evidence(config: CampaignConfig, result: CampaignResult, *,
                            path: str | os.PathLike[str] | None = None
                            ) -> tuple[Path, dict[str, Any]]:
    """Write the evidence of a finished campaign (``tli verify ... --evidence [PATH]``).

    Parameters
    ----------
    config : tli_verify.verify.config.CampaignConfig
        The config given to :func:`~tli_verify.verify.campaign.run_campaign`. What is recorded
        is the campaign the result says ran (``result.config``: the task's defaults filled in,
        e.g. its perturbation ``window`` and ``max_pushes``), so evidence written from Python
        with a config's defaults is the evidence ``tli verify --evidence`` writes; a config
        whose seed, examples or modulation differ from the result's is refused.
    result : tli_verify.verify.campaign.CampaignResult
        Its ``config``, ``runs``, ``violations`` (kind -> count), ``counterexample``,
        ``partial``, ``inconclusive`` and ``files`` (the spec, model and certificate the
        campaign ran, with the SHA-256 it ran them at).
    path : path-like, optional
        Where to write it (default: :func:`evidence_path_for` the model, under the model's
        project: ``models/NAME.model.json`` -> ``certificates/NAME.campaign.json``).

    Returns
    -------
    (Path, dict)
        ``path``: the evidence file written; ``record``: the document written to it (the
        JSON object of ``campaign.schema.json``: ``campaign`` with ``seed``, ``examples``,
        ``runs`` and ``settings``, ``violations``, the bound files' SHA-256, ``digest``).
        Evidence of a violating or partial campaign is written too, as an honest record (the
        gate refuses it), but a partial campaign never replaces a file that exists.

    Raises
    ------
    EvidenceError
        (exit 2) A file changed since the campaign hashed it, or is missing; or ``config`` is
        not the campaign ``result`` ran.
    OutputError
        (exit 2) The path cannot be written, or the campaign is partial and a file is there.
    """
    config = _campaign_config(config, result)
    files = _campaign_files(config, result)
    model = files["model"][0]
    target = Path(path) if path is not None else evidence_path_for(model)
    task = _campaign_task(result)
    if getattr(result, "partial", False) and os.path.lexists(target):

        raise OutputError(f"{target}: an interrupted (partial) campaign never replaces the "
                          "evidence there; rerun the campaign to the end")
    counterexample = getattr(result, "counterexample", None)
    if counterexample is not None and not isinstance(counterexample, Mapping):
        to_dict = getattr(counterexample, "to_dict", None)
        counterexample = to_dict() if callable(to_dict) else {"repr": repr(counterexample)}
    backend = getattr(config, "backend", None)
    inconclusive = getattr(result, "inconclusive", None)
    doc = write_evidence(
        target, world=str(task.name), task=task_block(task, target.parent),
        spec=files["spec"][0], model=model,
        certificate=files["certificate"][0], seed=int(config.seed),
        examples=int(config.examples), runs=int(result.runs),
        violations=_counts(result.violations), modulation=bool(config.modulation),
        partial=bool(getattr(result, "partial", False)),
        backend=None if backend is None else str(backend),
        workers=getattr(config, "workers", None), counterexample=counterexample,
        inconclusive=None if inconclusive is None else int(inconclusive),
        settings=_settings(config), expected={k: h for k, (_, h) in files.items() if h is not None})
    return target, doc


def weaker_than_recorded(path: str | os.PathLike[str], config: Any) -> str | None:
    """Why a campaign of ``config`` (its task defaults filled in:
    :func:`~tli_verify.verify.config.resolve_config`) would be weaker than the passing
    evidence at ``path``, or None (no such file, or it records a violation, an interrupted
    campaign, or nothing stronger). ``tli evidence`` and ``tli verify --evidence`` refuse to
    replace stronger evidence without ``--force``.

    Stronger: more examples; random starts where the new campaign starts at a nominal state;
    a longer perturbation window; more pushes per case; more perturbation levels.
    """
    try:
        doc = read_json(Path(path), what="campaign evidence", error=EvidenceError)
        camp, viol = doc["campaign"], doc["violations"]
        if int(viol["total"]) or camp["partial"] or not camp["modulation"]:
            return None
        old = camp.get("settings") or {}
        why = []
        if int(config.examples) < int(camp["examples"]):
            why.append(f"{camp['examples']} examples, this one {config.examples}")
        if old.get("random_starts") is True and not config.random_starts:
            why.append("random starts, this one a nominal start")
        for key, what in (("window", "perturbation window"), ("max_pushes", "pushes per case")):
            was, now = old.get(key), getattr(config, key, None)
            if isinstance(was, int) and isinstance(now, int) and now < was:
                why.append(f"{what} {was}, this one {now}")
        levels = old.get("levels")
        if isinstance(levels, list) and not set(levels) <= set(config.levels):
            why.append(f"levels {', '.join(map(str, levels))}, this one "
                       f"{', '.join(config.levels)}")
    except (TliError, OSError, KeyError, TypeError, ValueError, AttributeError):
        return None
    return "; ".join(why) or None


def _campaign_config(config: Any, result: Any) -> Any:
    """The config the campaign ran (``result.config``, its task defaults filled in), checked
    against the one given (the same seed, examples and modulation)."""
    used = getattr(result, "config", None)
    if used is None or config is None:
        return used if config is None else config
    for name in ("seed", "examples", "modulation"):
        given, ran = getattr(config, name, None), getattr(used, name, None)
        if given != ran:
            raise _BadInput(f"config.{name} is {given!r}, the campaign ran with {ran!r}: pass "
                            "the config the result came from (result.config)")
    return used


def _campaign_files(config: Any, result: Any) -> dict[str, tuple[Path, str | None]]:
    """name -> (path, SHA-256 the campaign ran it at) from ``result.files`` (paths relative to
    the repository root or absolute), else from the config."""
    files = getattr(result, "files", None) or {}
    out: dict[str, tuple[Path, str | None]] = {}
    for name in ("spec", "model", "certificate"):
        entry = files.get(name)
        if isinstance(entry, Mapping) and entry.get("path"):
            p = Path(str(entry["path"]))
            if not p.is_absolute():

                p = Path(os.path.realpath(bundled_root())) / p
            out[name] = (p, str(entry.get("sha256") or "") or None)
        elif getattr(config, name, None):
            out[name] = (Path(getattr(config, name)), None)
        else:
            raise _BadInput(f"campaign evidence needs the campaign's {name} file; neither "
                            "the result nor the config names it")
    return out


def _campaign_task(result: Any) -> Any:
    """The task a campaign ran on (``result.files["task"]``), checked against the SHA-256 it
    ran at."""
    from tli_verify.tasks.registry import find_task

    entry = (getattr(result, "files", None) or {}).get("task")
    if not isinstance(entry, Mapping):
        raise _BadInput("campaign evidence needs the campaign's task; the result names "
                        "none")
    if entry.get("path"):
        p = Path(str(entry["path"]))
        if not p.is_absolute():

            p = Path(os.path.realpath(bundled_root())) / p
        task = find_task(p)
        sha = task.source.sha256
    else:
        task = find_task(str(entry["entry_point"]))
        sha = task.source.source_sha256
    if sha != entry.get("sha256"):
        raise _BadInput(f"{task.where}: the task changed since the campaign ran it "
                        "(SHA-256 differs): re-run the campaign")
    return task


def _counts(violations: Any) -> dict[str, int]:
    """``{kind: count}`` from a mapping whose keys may be enum members."""
    out: dict[str, int] = {}
    for k, v in dict(violations).items():
        name = getattr(k, "value", k)
        out[str(name)] = out.get(str(name), 0) + int(v)
    return out

