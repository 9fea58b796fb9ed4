"""Campaign evidence: ``certificates/<name>.campaign.json``, required by ``tli gate``.

A deployed model needs, besides its Lyapunov certificate, evidence that a bisimulation campaign
(``tli verify``: generated perturbation sequences against invariance and reachability, paper
Sec. 4.4, Thm. 2, Asm. 2) ran on *its exact files* and found nothing. The evidence file (schema
``tli_verify/schemas/campaign.schema.json``) binds, by SHA-256 of their exact bytes (the
certificate's convention, :mod:`tli_verify.certification.certificate`):

* the spec, the model and the certificate (paths relative to the evidence file's directory);
* the task the campaign ran on (``task``): a task file by its SHA-256, an entry point by its
  distribution, version and the SHA-256 of its module's source. The gate recomputes it for the
  task the deployed spec names (:func:`tli_verify.tasks.project.resolve`) and blocks on any
  difference: another task's evidence, an edited region, a renamed task;
* the seed, the number of examples (perturbation sequences) and of runs (simulations), whether
  modulation was on (it must be: that is the deployed policy) and whether the campaign was
  interrupted (``partial``: then it is not evidence);
* the violations found, by kind (``total`` must be 0 to deploy) and the counterexample (null);
* what the campaign means, :data:`CAMPAIGN_SEMANTICS` (``campaign_semantics``: the gate requires
  this tool's), and the tool version (``tool``: information only, never compared, so a release
  that changes nothing a campaign means keeps the evidence valid); and ``digest``, the SHA-256
  of the canonical JSON of everything else.

Nothing in it is trusted: :func:`check_evidence` re-reads it (bounded, regular files only, never
a symlink), recomputes the digest and the three hashes, requires the spec to be the one the
model names and the certificate to cover the model, and requires ``violations.total == 0``,
no counterexample, modulation on, a complete campaign and at least
:data:`MIN_EVIDENCE_EXAMPLES` examples. ``tli gate --rerun N`` additionally re-runs a short
campaign with the evidence's seed (:mod:`tli_verify.deploy.gate`).

Write evidence with :func:`write_evidence` (``tli verify ... --evidence``, or
``tli evidence DIR`` for every model of a project).

Physical campaigns
-----------------------------
The Franka policy (``sim/franka``) runs in MuJoCo, not in a 2-D world: its evidence has the world
``"franka-physics"`` (a :class:`PhysicalWorld`, whose checks live in
:mod:`tli_verify.sim.physics_checks`) and a ``physics`` block (robot, variant, duration,
pushes and tilts per trial, trials, successes, the MuJoCo version, per-trial outcomes), written
by ``tli sim franka --evidence`` or ``tli evidence sim/franka``
(:func:`tli_verify.sim.physics_evidence.write_physics_evidence`).
Each example is one perturbed physical
trial (seconds each), so the minimum is
:data:`~tli_verify.sim.physics_checks.MIN_PHYSICS_TRIALS` (the paper's 30 trials), and
the gate also requires every trial to have delivered soup, the deployed variant (``LTL-DS``) and
both perturbation levels (pushes and tilts). ``tli gate --rerun N`` re-runs ``N`` physical
trials with the recorded settings.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tli_verify.errors import EvidenceError, TliError, missing
from tli_verify.io import (
    atomic_write_text,
    canonical_json,
    check_output_file,
    same_file,
    sha256_file,
)

if TYPE_CHECKING:
    from tli_verify.verify.campaign import CampaignResult
    from tli_verify.verify.config import CampaignConfig

__all__ = [
    "CAMPAIGN_SEMANTICS",
    "EVIDENCE_KIND",
    "EVIDENCE_SCHEMA_VERSION",
    "EVIDENCE_SUFFIX",
    "MIN_EVIDENCE_EXAMPLES",
    "MIN_MAX_PUSHES",
    "MIN_WINDOW",
    "EvidenceCheck",
    "PhysicalWorld",
    "build_evidence",
    "check_evidence",
    "evidence_digest",
    "evidence_path_for",
    "model_stem",
    "settings_for_config",
    "settings_problems",
    "task_content_sha256",
    "weaker_than_recorded",
    "write_campaign_evidence",
    "write_evidence",
]

EVIDENCE_SCHEMA_VERSION = 3
"""Version of the evidence file format (``campaign.schema.json``). 3: ``campaign_semantics``
recorded and required (2 compared the tool version instead; 1 bound no task)."""
CAMPAIGN_SEMANTICS = 3
"""What a campaign's verdict means; evidence recorded under another value does not count.

Evidence records it (``campaign_semantics``) and ``tli gate`` requires this tool's value, so
evidence stays valid across releases of tli-verify that change nothing a campaign means
(the tool version is recorded as information only), and is refused, asking for a new
campaign, after one that does.

Bump rule: increment it (and re-run ``tli evidence .`` and ``tli evidence sim/franka``) in the
change that alters what a campaign of given files, seed and settings establishes:

* the oracle: what counts as a violation (invariance, reachability, looping), its kinds, its
  tolerances or the simulation it judges (the executive, the sensor debouncing, the cuts, the
  modulation, the integration of a kinematic world; the physical trial's success criterion);
* the strategies' encoding: how a seed and the settings become perturbation sequences
  (:mod:`tli_verify.verify.strategies`, :mod:`tli_verify.sim.perturbations`), so that the same
  recorded seed would draw other cases, or the settings mean other bounds;
* the deadline computation: the number of steps (or seconds) a run gets to reach the goal
  before it counts as a failure.

Do not bump it for refactors, speed-ups, messages, new commands or a release by itself; a
change of the evidence *file format* bumps :data:`EVIDENCE_SCHEMA_VERSION` instead.
History: 1 (tli-verify 0.1.0) is the first recorded value; 2: the Franka trials run on the
Panda within its limits, with person-like perturbations drawn uniformly, ``perturbed`` from the
estimated external wrench, and the ``limits`` oracle kind; 3: the physical oracle's
``invariance`` kind (an invariance failure not answered with a cut fails the trial, as in the
2-D oracle)."""
EVIDENCE_KIND = "tli-verify/campaign-evidence"
EVIDENCE_SUFFIX = ".campaign.json"
MIN_EVIDENCE_EXAMPLES = 500
"""Fewest examples (perturbation sequences) a campaign needs to count as evidence in the gate.

With ``N`` examples and no violation, the failure probability per perturbed run is below
``3 / N`` at 95% confidence (the rule of three): 500 examples bound it by 0.6%. A scoop
campaign of 1,000 runs takes about 20 s on 2 cores, so the bundled
evidence (1,000 examples, ``tli evidence``) costs seconds per model."""


MIN_WINDOW = 100
"""Shortest perturbation window a kinematic campaign must have drawn from (control steps; 1 s
at 10 ms): pushes confined to the first steps test almost nothing of the mode boundaries."""
MIN_MAX_PUSHES = 2
"""Fewest perturbations per case a kinematic campaign must have allowed: with one push at most,
no case tests a recovery that is itself perturbed (paper Asm. 2: finitely many, not one)."""


@dataclass(frozen=True, slots=True)
class PhysicalWorld:
    """A kind of physical campaign the evidence check accepts; its checks live with its
    simulator (the MuJoCo Franka's: :data:`tli_verify.sim.physics_checks.FRANKA_PHYSICS`).

    Attributes
    ----------
    name : str
        The evidence's ``world`` (e.g. ``"franka-physics"``).
    min_trials : int
        Fewest decided trials that count as evidence.
    check : callable
        ``check(doc, shown, passed) -> problems`` on the evidence document (its ``physics``
        block present), appending what passed to ``passed``.
    """

    name: str
    min_trials: int
    check: Callable[[Mapping[str, Any], str, list[str]], list[str]]


class _BadInput(EvidenceError, ValueError):
    """Evidence that cannot be built from what was given (bad input, not a verdict)."""


def evidence_digest(doc: Mapping[str, Any]) -> str:
    """SHA-256 of the canonical JSON of an evidence document without its ``digest`` field."""
    body = {k: v for k, v in doc.items() if k != "digest"}
    return hashlib.sha256(canonical_json(body).encode("utf-8")).hexdigest()


def model_stem(model_path: str | os.PathLike[str]) -> str:
    """``scoop`` for ``models/scoop.model.json`` (:func:`tli_verify.tasks.project.model_stem`)."""
    from tli_verify.tasks.project import model_stem as stem

    return stem(model_path)


def evidence_path_for(model_path: str | os.PathLike[str]) -> Path:
    """Where a model's campaign evidence lives: the project rule
    (:func:`tli_verify.tasks.project.model_files`): ``ROOT/models/SUB/NAME.model.json`` ->
    ``ROOT/certificates/SUB/NAME.campaign.json``; a model outside any ``models/`` folder ->
    ``NAME.campaign.json`` next to it.

    Parameters
    ----------
    model_path : path-like

    Returns
    -------
    Path
    """
    from tli_verify.tasks.project import model_files

    return model_files(model_path).evidence


def _relpath(target: Path, base_dir: Path) -> str:
    return Path(os.path.relpath(target.resolve(), base_dir.resolve())).as_posix()


def _file_entry(path: Path, base: Path, what: str) -> dict[str, str]:
    if not path.is_file():
        raise missing(EvidenceError, f"{path}: {what} file not found", path)
    return {"path": _relpath(path, base), "sha256": sha256_file(path)}


def task_block(task: Any, base: str | os.PathLike[str]) -> dict[str, Any]:
    """The evidence's ``task`` block of a task (paths relative to ``base``).

    Raises
    ------
    EvidenceError
        (exit 2) A task built in memory (nothing binds it).
    """
    src = task.source
    if src.kind == "file" and src.path is not None and src.sha256 is not None:
        out: dict[str, Any] = {"name": task.name, "kind": "file",
                               "path": _relpath(Path(src.path), Path(base)),
                               "sha256": src.sha256}
        content = task_content_sha256(src.path)
        if content is not None:
            out["content_sha256"] = content
    elif src.kind == "entry-point" and src.source_sha256 is not None:
        out = {"name": task.name, "kind": "entry-point", "sha256": src.source_sha256}
    else:
        raise _BadInput(f"task {task.name!r} was built in memory: evidence needs a task "
                        "file or an entry-point task")
    if src.entry_point is not None and src.source_sha256 is not None:
        out["entry_point"] = {"name": src.entry_point, "distribution": src.distribution,
                              "version": src.version, "source_sha256": src.source_sha256}
    return out


def task_content_sha256(path: str | os.PathLike[str]) -> str | None:
    """SHA-256 of a task file's content: the parsed TOML as canonical JSON (comments, blank
    lines, key order and number spelling do not count). None if it does not parse.

    Evidence records it next to the file's SHA-256, so the gate tells an edit of comments or
    formatting (same content: accepted, and said) from a change of the task (blocked).
    """
    import hashlib
    import json
    import tomllib

    try:
        with open(path, "rb") as fh:
            data = tomllib.loads(fh.read().decode("utf-8-sig"))
        # sorted keys, one spelling per number (inf and nan too), dates as ISO text
        text = json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=False,
                          allow_nan=True, default=str)
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, TypeError, ValueError,
            RecursionError):
        return None
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


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
    from tli_verify._version import __version__
    from tli_verify.io import validate_schema

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
        from tli_verify.errors import OutputError

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
    from tli_verify.io import read_json

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


_CORE = frozenset({"task", "spec", "model", "certificate", "examples", "seed", "modulation",
                   "workers", "backend", "scheduler"})
"""Config fields recorded elsewhere in the evidence, or where (not what) the campaign ran."""


def _settings(config: Any) -> dict[str, Any]:
    """The config's other fields with JSON values (tuples as lists), for a faithful re-run."""
    import dataclasses

    if not dataclasses.is_dataclass(config):
        return {}
    out: dict[str, Any] = {}
    for f in dataclasses.fields(config):
        if f.name in _CORE:
            continue
        value = getattr(config, f.name)
        if isinstance(value, tuple):
            value = list(value)
        if value is None or isinstance(value, bool | int | float | str) or (
                isinstance(value, list)
                and all(isinstance(v, bool | int | float | str) for v in value)):
            out[f.name] = value
    return out


def settings_for_config(settings: Mapping[str, Any], config_type: Any) -> dict[str, Any]:
    """Recorded settings as keyword arguments of ``config_type`` (lists back to tuples; fields
    it does not have are dropped)."""
    import dataclasses

    names = {f.name for f in dataclasses.fields(config_type)} - _CORE
    return {k: tuple(v) if isinstance(v, list) else v for k, v in settings.items()
            if k in names}


def settings_problems(settings: Mapping[str, Any], task: Any) -> list[str]:
    """What in a kinematic campaign's recorded settings no ``tli verify`` or ``tli evidence``
    command line could have produced on ``task`` (an edited evidence file): the gate refuses
    such evidence whatever its digest says.

    The CLI records: ``start`` the task's first nominal start (or none, with random starts),
    ``levels`` all of them, ``max_cycles`` none, ``lag`` the task's, and every number within
    the options' ranges; no other keys.

    Parameters
    ----------
    settings : mapping
        ``campaign.settings`` of the evidence.
    task : Task
        The task the evidence binds.

    Returns
    -------
    list of str
        One line per problem (empty: the settings are ones the CLI writes).
    """
    from tli_verify.limits import MAX_BATCH_SIZE, MAX_CAMPAIGN_STEPS, MAX_EXAMPLES, MAX_PUSHES
    from tli_verify.verify.strategies import LEVELS

    out: list[str] = []
    known = {"batch_size", "lag", "levels", "max_cycles", "max_pushes", "random_starts",
             "shrink", "start", "target_examples", "window"}
    extra = sorted(set(settings) - known)
    if extra:
        out.append(f"campaign.settings.{extra[0]}: not a setting tli verify records")

    def whole(name: str, lo: int, hi: int) -> None:
        if name not in settings:  # absent: the option's default
            return
        v = settings[name]
        if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
            out.append(f"campaign.settings.{name}: {v!r} is not an integer in [{lo}, {hi}] "
                       "(what the tli verify option takes)")

    whole("batch_size", 1, MAX_BATCH_SIZE)
    whole("window", 1, MAX_CAMPAIGN_STEPS)
    whole("max_pushes", 0, MAX_PUSHES)
    whole("target_examples", 0, MAX_EXAMPLES)
    whole("lag", 0, MAX_CAMPAIGN_STEPS)
    for name in ("shrink", "random_starts"):
        if name in settings and not isinstance(settings[name], bool):
            out.append(f"campaign.settings.{name}: {settings[name]!r} is not true or false")
    if "levels" in settings and (not isinstance(settings["levels"], list | tuple)
                                 or list(settings["levels"]) != list(LEVELS)):
        out.append(f"campaign.settings.levels: {settings['levels']!r}; tli verify always "
                   f"draws every level ({', '.join(LEVELS)})")
    if settings.get("max_cycles") is not None:
        out.append(f"campaign.settings.max_cycles: {settings['max_cycles']!r}; tli verify "
                   "records none (the oracle's default)")
    lag = settings.get("lag")
    if isinstance(lag, int) and not isinstance(lag, bool) and lag != task.lag:
        out.append(f"campaign.settings.lag: {lag}, but task {task.name!r} has lag {task.lag}")
    start = settings.get("start")
    if start is not None:
        nominal = [[float(v) for v in s] for s in task.starts.nominal]
        try:
            recorded = [float(v) for v in start]
        except (TypeError, ValueError, OverflowError):
            recorded = None
        if settings.get("random_starts") is True:
            out.append("campaign.settings.start: a fixed start with random starts")
        elif not nominal or recorded != nominal[0]:
            first = nominal[0] if nominal else "none"
            out.append(f"campaign.settings.start: {start!r} is not the task's first nominal "
                       f"start ({first}), the only fixed start tli verify records")
    return out


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
                from tli_verify.io import bundled_root

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
            from tli_verify.io import bundled_root

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


# --------------------------------------------------------------------------------------------
# Checking
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class EvidenceCheck:
    """Result of re-checking one evidence file.

    Attributes
    ----------
    path : str
        The evidence file.
    problems : tuple of str
        Everything that differs or fails; empty iff the evidence is valid.
    passed : tuple of str
        What was verified.
    world : str or None
    seed : int or None
    examples : int or None
    runs : int or None
        The campaign's, when the file could be read.
    model_path, spec_path, certificate_path : str or None
        The files it binds (resolved), when the file could be read.
    settings : tuple of (str, object)
        The campaign's other recorded parameters (``campaign.settings``).
    digest : str or None
        The evidence's recorded digest (the gate derives its re-run seeds from it).
    physics : tuple of (str, object)
        A physical campaign's settings (``physics``: robot, variant, duration, pushes,
        tilts, retry, sensors, and ``evaluator`` when the trials ran an exported artifact in
        the C evaluator); empty for a 2-D world.
    """

    path: str
    problems: tuple[str, ...] = ()
    passed: tuple[str, ...] = field(default=())
    world: str | None = None
    seed: int | None = None
    examples: int | None = None
    runs: int | None = None
    model_path: str | None = None
    spec_path: str | None = None
    certificate_path: str | None = None
    settings: tuple[tuple[str, Any], ...] = ()
    physics: tuple[tuple[str, Any], ...] = ()
    digest: str | None = None

    @property
    def ok(self) -> bool:
        """True iff nothing failed."""
        return not self.problems




def _short(sha: str) -> str:
    return f"{sha[:12]}..."


def check_evidence(path: str | os.PathLike[str], *,
                   model_path: str | os.PathLike[str] | None = None,
                   valid_certificates: Collection[str | os.PathLike[str]] | None = None,
                   min_examples: int | None = None,
                   physical: Sequence[PhysicalWorld] = ()) -> EvidenceCheck:
    """Re-check campaign evidence against the files it binds.

    Parameters
    ----------
    path : path-like
        The evidence file (must be a regular file, not a symlink).
    model_path : path-like, optional
        The deployed model it must bind (default: the one it names).
    valid_certificates : collection of path-like, optional
        The certificates known to re-check for this model (the gate's); the evidence's
        certificate must be one of them. Default: only the certificate's hash and the model
        hash it records are compared (``tli check-cert`` re-checks the certificate itself).
    min_examples : int, optional
        Fewest examples accepted (default :data:`MIN_EVIDENCE_EXAMPLES`; for a physical
        campaign its world's ``min_trials``).
    physical : sequence of PhysicalWorld, optional
        The physical campaigns accepted, with their checks (``tli gate``: the MuJoCo Franka's).
        Evidence of a physical world not given here is refused.

    Returns
    -------
    EvidenceCheck
        Every problem found (not just the first); never raises for a bad file.
    """
    from tli_verify.io import read_json, validate_schema

    epath = Path(path)
    shown = str(epath)
    if epath.is_symlink():
        return EvidenceCheck(shown, (f"{shown}: a symlink: refused, never followed (campaign "
                                     "evidence must be a regular file in certificates/)",))
    if not epath.exists():
        return EvidenceCheck(shown, (f"{shown}: no such campaign evidence file",))
    try:
        doc = read_json(epath, what="campaign evidence", error=EvidenceError)
        old = doc.get("schema_version") if isinstance(doc, Mapping) else None
        if (type(old) is int and 1 <= old < EVIDENCE_SCHEMA_VERSION
                and doc.get("kind") == EVIDENCE_KIND):  # an earlier format, not a forgery
            return EvidenceCheck(shown, (
                f"{shown}: evidence schema {old}, written by an earlier tli-verify that "
                f"recorded no campaign semantics (this tool's are {CAMPAIGN_SEMANTICS}, "
                f"schema {EVIDENCE_SCHEMA_VERSION}): re-run the campaign (tli evidence DIR, "
                "or tli verify ... --evidence)",))
        validate_schema(doc, "campaign.schema.json", where=shown, error=EvidenceError)
    except EvidenceError as exc:
        return EvidenceCheck(shown, (f"malformed campaign evidence: {exc}",))
    except RecursionError:
        return EvidenceCheck(shown, (f"malformed campaign evidence: {shown}: nested too deeply",))
    problems: list[str] = []
    passed: list[str] = []
    if evidence_digest(doc) != doc["digest"]:
        problems.append(f"{shown}: digest does not match the content: the evidence was edited "
                        "after the campaign wrote it")
    else:
        passed.append("digest matches the content")
    worlds = {w.name: w for w in physical}
    problems += _check_tool_and_world(doc, shown, passed, worlds)
    base = epath.parent
    named = {k: Path(os.path.realpath(base / doc[k]["path"]))
             for k in ("model", "spec", "certificate")}
    mpath = Path(model_path) if model_path is not None else named["model"]
    if model_path is not None and not same_file(named["model"], mpath):
        problems.append(f"{shown}: model.path {doc['model']['path']!r} ({named['model']}) is "
                        f"not the deployed model {mpath}: the evidence binds another model")
    seen = {k: Path(os.path.normpath(base / doc[k]["path"])) for k in ("spec", "certificate")}
    problems += _check_files(doc, shown, mpath, named, seen, passed)
    if mpath.is_file():
        problems += _check_task(doc, shown, mpath, base, passed, worlds)
    if valid_certificates is not None and named["certificate"].is_file() and not any(
            same_file(named["certificate"], Path(c)) for c in valid_certificates):
        problems.append(f"{shown}: certificate {doc['certificate']['path']!r} is not a valid "
                        f"certificate of {mpath}")
    if min_examples is None:
        world = worlds.get(doc["world"])
        min_examples = MIN_EVIDENCE_EXAMPLES if world is None else world.min_trials
    problems += _check_campaign(doc, shown, min_examples, passed, worlds)
    problems += _check_physics(doc, shown, passed, worlds)
    camp = doc["campaign"]
    keep = ("robot", "variant", "duration", "pushes", "tilts", "retry", "sensors", "evaluator")
    return EvidenceCheck(shown, tuple(problems), tuple(passed), world=doc["world"],
                         seed=int(camp["seed"]), examples=int(camp["examples"]),
                         runs=int(camp["runs"]), model_path=str(mpath),
                         spec_path=str(named["spec"]),
                         certificate_path=str(named["certificate"]),
                         settings=tuple(sorted(camp.get("settings", {}).items())),
                         physics=tuple(sorted((k, v) for k, v in doc.get("physics", {}).items()
                                              if k in keep)),
                         digest=str(doc["digest"]))


def _check_tool_and_world(doc: Mapping[str, Any], shown: str, passed: list[str],
                          worlds: Mapping[str, PhysicalWorld]) -> list[str]:
    """The campaign semantics are this tool's (:data:`CAMPAIGN_SEMANTICS`; the tool version
    is not compared) and the world agrees with the task and the physics block."""
    out: list[str] = []
    semantics = doc["campaign_semantics"]
    version = doc["tool"]["version"]
    if semantics != CAMPAIGN_SEMANTICS:
        out.append(f"{shown}: campaign semantics {semantics} (written by tli-verify {version}), "
                   f"this tool's are {CAMPAIGN_SEMANTICS}: the oracle, the perturbation "
                   "strategies or the deadlines changed what a campaign means; re-run the "
                   "campaign with this version")
    else:
        passed.append(f"campaign semantics {semantics} are this tool's (written by tli-verify "
                      f"{version})")
    physical = doc["world"] in worlds
    if physical != (doc.get("physics") is not None):
        out.append(f"{shown}: world {doc['world']!r} and the physics block disagree (a "
                   "physical campaign has world franka-physics and a physics block; a "
                   "kinematic one neither)")
    elif not physical and doc["world"] != doc["task"]["name"]:
        out.append(f"{shown}: world {doc['world']!r} is not the name of the task the campaign "
                   f"ran on ({doc['task']['name']!r}): the evidence was edited")
    return out


def deployed_task_block(model_path: str | os.PathLike[str], base: Path) -> dict[str, Any]:
    """The ``task`` block evidence for a deployed model must carry: the task its spec names,
    as the project resolver finds it (:func:`tli_verify.tasks.project.resolve`).

    Raises
    ------
    TliError
        The spec names no task, or the task does not load or fit.
    """
    from tli_verify.logic.spec import load_spec
    from tli_verify.model.serialize import load_model
    from tli_verify.tasks.project import spec_task

    spec = load_model(model_path).spec_path
    if spec is None:
        raise EvidenceError(f"{model_path}: the model names no spec, so it has no task")
    task = spec_task(load_spec(spec), spec)
    if task is None:
        raise EvidenceError(f"{spec}: the spec names no task (task = \"NAME\"), so no "
                            "evidence can be bound to the deployed task")
    return task_block(task, base)


def _physics_task(model_path: Path) -> bool:
    """Whether the deployed spec's task computes its sensors in a simulator."""
    from tli_verify.logic.spec import load_spec
    from tli_verify.model.serialize import load_model
    from tli_verify.tasks.project import spec_task

    spec = load_model(model_path).spec_path
    task = None if spec is None else spec_task(load_spec(spec), spec)
    return bool(getattr(getattr(task, "sensor_model", None), "physics", False))


def _check_task(doc: Mapping[str, Any], shown: str, mpath: Path, base: Path,
                passed: list[str], worlds: Mapping[str, PhysicalWorld]) -> list[str]:
    """The evidence's task is the deployed spec's task, byte for byte (or source for source)."""
    try:
        want = deployed_task_block(mpath, base)
    except TliError as exc:
        return [f"{shown}: the deployed task cannot be resolved: {exc}"]
    got = doc["task"]
    physical = doc["world"] in worlds
    if physical != _physics_task(mpath):
        return [f"{shown}: a {'physical' if physical else 'kinematic'} campaign, but the "
                f"deployed task {want['name']!r} is "
                f"{'kinematic' if physical else 'physical (its sensors come from a simulator)'}"
                ": the kind of evidence must match the model"]
    same_content = (got.get("kind") == want["kind"] == "file"
                    and got.get("content_sha256") is not None
                    and got.get("content_sha256") == want.get("content_sha256"))
    if (got.get("kind") != want["kind"] or got.get("sha256") != want["sha256"]) and \
            not same_content:
        where = want.get("path") or want.get("entry_point", {}).get("name")
        why = "another task, or the task changed after the campaign"
        if got.get("kind") == want["kind"] == "file" and got.get("name") == want["name"] \
                and got.get("path") == want.get("path"):
            why = ("its content changed since the campaign (not only comments or formatting)"
                   if got.get("content_sha256") else
                   "its bytes changed since the campaign; this evidence records no content "
                   "hash, so an edit of comments alone cannot be told apart: re-run the "
                   "campaign (tli evidence)")
        return [f"{shown}: the campaign ran on task {got.get('name')!r} "
                f"({got.get('path') or got.get('entry_point', {}).get('name')}, SHA-256 "
                f"{_short(str(got.get('sha256')))}), but the deployed spec's task is "
                f"{want['name']!r} ({where}, SHA-256 {_short(want['sha256'])}): {why}"]
    if "entry_point" in want and not _same_entry_point(got.get("entry_point"),
                                                       want["entry_point"]):
        return [f"{shown}: the task's entry point {want['entry_point']['name']!r} differs "
                "from the one the campaign ran (distribution, version or source)"]
    if got.get("sha256") != want["sha256"]:
        passed.append(f"task {want['name']!r} is the deployed spec's; only its comments or "
                      "formatting changed since the campaign (its content SHA-256 matches)")
    else:
        passed.append(f"task {want['name']!r} is the deployed spec's and matches its SHA-256")
    return []


def _same_entry_point(got: Any, want: Mapping[str, Any]) -> bool:
    """The entry point the campaign ran is the deployed one: same name, distribution, source
    and version. The version of tli-verify's own entry points is not compared (it is the tool
    version: :data:`CAMPAIGN_SEMANTICS` binds what tli-verify's code means); a third-party
    distribution's version is (its module's dependencies may have changed)."""
    from tli_verify._version import DISTRIBUTION

    if not isinstance(got, Mapping):
        return False
    ignore = {"version"} if want.get("distribution") == DISTRIBUTION else set()
    keys = (set(got) | set(want)) - ignore
    return all(got.get(k) == want.get(k) for k in keys)


def _check_files(doc: Mapping[str, Any], shown: str, mpath: Path, named: Mapping[str, Path],
                 seen: Mapping[str, Path], passed: list[str]) -> list[str]:
    """The three hashes; the spec is the model's; the certificate covers the model. ``named``:
    the files resolved as the OS opens them; ``seen``: as the evidence names them (messages)."""
    from tli_verify.io import read_json
    from tli_verify.model.serialize import load_model

    out: list[str] = []
    if not mpath.is_file():
        return [f"{shown}: model file {mpath} not found"]
    model_sha = sha256_file(mpath)
    if model_sha != doc["model"]["sha256"]:
        out.append(f"{mpath}: SHA-256 {_short(model_sha)} differs from the evidence's "
                   f"{_short(doc['model']['sha256'])}: the campaign ran another model (or the "
                   "model changed after it)")
    else:
        passed.append(f"model {mpath} matches its SHA-256")
    try:
        model = load_model(mpath)
    except TliError as exc:
        return [*out, f"model does not load: {exc}"]
    spec = named["spec"]
    if model.spec_path is None:
        out.append(f"{mpath} names no spec, the evidence binds {doc['spec']['path']!r}")
    elif not same_file(spec, model.spec_path):
        out.append(f"{shown}: spec.path {doc['spec']['path']!r} ({spec}) is not the spec the "
                   f"model names ({model.spec_path}): the campaign ran another spec")
    elif not spec.is_file():
        out.append(f"{shown}: spec file {seen['spec']} not found")
    elif (sha := sha256_file(spec)) != doc["spec"]["sha256"]:
        out.append(f"{seen['spec']}: SHA-256 {_short(sha)} differs from the evidence's "
                   f"{_short(doc['spec']['sha256'])}: the spec changed after the campaign")
    else:
        passed.append(f"spec {seen['spec']} is the model's and matches its SHA-256")
    cert = named["certificate"]
    if not cert.is_file():
        out.append(f"{shown}: certificate file {seen['certificate']} not found")
        return out
    sha = sha256_file(cert)
    if sha != doc["certificate"]["sha256"]:
        out.append(f"{seen['certificate']}: SHA-256 {_short(sha)} differs from the evidence's "
                   f"{_short(doc['certificate']['sha256'])}: the certificate changed after the "
                   "campaign")
        return out
    try:
        cert_doc = read_json(cert, what="certificate", error=EvidenceError)
        cert_model = str(cert_doc["model"]["sha256"])
    except (EvidenceError, KeyError, TypeError):
        return [*out, f"{shown}: certificate {seen['certificate']} is not a readable "
                "certificate"]
    if cert_model != model_sha:
        out.append(f"{shown}: certificate {doc['certificate']['path']!r} covers model "
                   f"{_short(cert_model)}, not {mpath} ({_short(model_sha)})")
    else:
        passed.append(f"certificate {seen['certificate']} matches its SHA-256 and covers the "
                      "model")
    return out


def _check_campaign(doc: Mapping[str, Any], shown: str, min_examples: int,
                    passed: list[str], worlds: Mapping[str, PhysicalWorld]) -> list[str]:
    out: list[str] = []
    camp, viol = doc["campaign"], doc["violations"]
    by_kind = {k: int(v) for k, v in viol["by_kind"].items()}
    total = int(viol["total"])
    if total != sum(by_kind.values()):
        out.append(f"{shown}: violations.total {total} is not the sum of violations.by_kind "
                   f"({sum(by_kind.values())})")
    found = max(total, sum(by_kind.values()))
    if found:
        kinds = ", ".join(f"{k}: {v}" for k, v in sorted(by_kind.items()) if v) or "-"
        if doc["world"] in worlds:
            out.append(f"{shown}: physical trials failed the oracle (trials per kind: {kinds}): "
                       "not evidence for deployment (the counterexample says how to reproduce "
                       "the first)")
        else:
            out.append(f"{shown}: the campaign found {found} violation(s) ({kinds}): not "
                       "evidence for deployment (tli replay the counterexample, fix the model)")
    elif doc["counterexample"] is not None:
        out.append(f"{shown}: records a counterexample: not evidence for deployment")
    if camp["partial"]:
        out.append(f"{shown}: the campaign was interrupted (partial): not evidence")
    if not camp["modulation"]:
        out.append(f"{shown}: the campaign ran without modulation, the deployed policy runs "
                   "with it: not evidence for it")
    examples, runs = int(camp["examples"]), int(camp["runs"])
    physical = doc["world"] in worlds
    inconclusive = camp.get("inconclusive")
    if not physical and inconclusive is None:
        out.append(f"{shown}: campaign.inconclusive is missing: the gate counts only runs "
                   "whose reachability was decided")
    decided = examples - (int(inconclusive) if inconclusive is not None else 0)
    if decided < min_examples:
        const = "MIN_PHYSICS_TRIALS" if physical else "MIN_EVIDENCE_EXAMPLES"  # their names
        what = (f"{examples} example(s)" if decided == examples else
                f"{decided} decided example(s) ({examples} drawn, {inconclusive} with "
                "reachability undecided)")
        out.append(f"{shown}: {what}, fewer than the minimum {min_examples} ({const})")
    if not physical:
        settings = camp.get("settings") or {}
        out += _check_settings(camp, settings, shown)
        window, pushes = settings.get("window"), settings.get("max_pushes")
        if not isinstance(window, int) or isinstance(window, bool) or window < MIN_WINDOW:
            out.append(f"{shown}: perturbation window {window!r}: campaigns must draw pushes "
                       f"over at least {MIN_WINDOW} steps (MIN_WINDOW) to count")
        if not isinstance(pushes, int) or isinstance(pushes, bool) or pushes < MIN_MAX_PUSHES:
            out.append(f"{shown}: max_pushes {pushes!r}: campaigns must allow at least "
                       f"{MIN_MAX_PUSHES} perturbations per case (MIN_MAX_PUSHES) to count")
    if runs < examples:
        out.append(f"{shown}: {runs} run(s) for {examples} examples: every example is at "
                   "least one run")
    out += _check_run_settings(camp, shown)
    if not out:
        passed.append(f"{examples} examples ({runs} runs, {decided} decided, seed "
                      f"{camp['seed']}), modulation on, 0 violations")
    return out



BACKENDS = ("process", "dask", "serial")
"""The ``--backend`` choices of ``tli verify``, ``tli evidence`` and ``tli sim franka``."""
def _check_run_settings(camp: Mapping[str, Any], shown: str) -> list[str]:
    """How the campaign ran (``campaign.backend``, ``campaign.workers``; kinematic and physical
    alike), validated with the command line's choices and range, like every other recorded
    setting: the schema alone admits any short string and up to 100,000 workers."""
    from tli_verify.limits import MAX_WORKERS

    out = []
    backend, workers = camp.get("backend"), camp.get("workers")
    if backend is not None and backend not in BACKENDS:
        out.append(f"{shown}: campaign.backend {backend!r}: not one of {', '.join(BACKENDS)} "
                   "(what --backend takes)")
    if workers is not None and not (isinstance(workers, int) and not isinstance(workers, bool)
                                    and 1 <= workers <= MAX_WORKERS):
        out.append(f"{shown}: campaign.workers {workers!r}: not an integer in [1, "
                   f"{MAX_WORKERS}] (what --workers takes)")
    return out


def _check_settings(camp: Mapping[str, Any], settings: Mapping[str, Any], shown: str
                    ) -> list[str]:
    """Every recorded campaign setting (and the seed, examples and modulation), validated as
    the command-line options are (:class:`~tli_verify.verify.config.CampaignConfig`), whether
    or not the gate re-runs it: a forged ``target_examples = 1e9`` or ``2.5`` is refused."""
    import dataclasses

    from tli_verify.verify.config import CampaignConfig

    known = {f.name for f in dataclasses.fields(CampaignConfig)} - _CORE
    unknown = sorted(set(settings) - known)
    if unknown:
        return [f"{shown}: campaign.settings.{unknown[0]}: not a campaign setting (known: "
                f"{', '.join(sorted(known))})"]
    try:
        CampaignConfig(examples=camp["examples"], seed=camp["seed"],
                       modulation=camp["modulation"],
                       **settings_for_config(settings, CampaignConfig))
    except (TliError, TypeError, ValueError) as exc:
        return [f"{shown}: campaign.settings: {exc} (recorded settings are validated with the "
                "command line's limits)"]
    return []


def _check_physics(doc: Mapping[str, Any], shown: str, passed: list[str],
                   worlds: Mapping[str, PhysicalWorld]) -> list[str]:
    """A physics block is present exactly for a physical world; the world's own checks
    (:attr:`PhysicalWorld.check`) judge it."""
    phys = doc.get("physics")
    world = worlds.get(doc["world"])
    if world is None:
        if phys is not None:
            return [f"{shown}: a physics block for world {doc['world']!r}, which is not a "
                    "physical campaign"]
        return []
    if phys is None:
        return [f"{shown}: world {doc['world']!r} is a physical campaign but the evidence has "
                "no physics block"]
    return world.check(doc, shown, passed)
