"""Checking campaign evidence (the gate): it binds the current files, records a campaign that meets
the rules, and its digest matches.
"""

from __future__ import annotations

import os
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tli_verify.errors import EvidenceError, TliError
from tli_verify.io import (
    same_file,
    sha256_file,
)

if TYPE_CHECKING:
    pass
from tli_verify._version import DISTRIBUTION
from tli_verify.io import read_json, validate_schema
from tli_verify.limits import MAX_WORKERS
from tli_verify.logic.spec import load_spec
from tli_verify.verify.evidence.common import (
    evidence_digest,
    task_block,
)
from tli_verify.verify.evidence.rules import (
    BACKENDS,
    CAMPAIGN_SEMANTICS,
    EVIDENCE_KIND,
    EVIDENCE_SCHEMA_VERSION,
    MIN_EVIDENCE_EXAMPLES,
    MIN_MAX_PUSHES,
    MIN_WINDOW,
    PhysicalWorld,
)
from tli_verify.verify.evidence.settings import (
    _CORE,
    settings_for_config,
)

__all__ = [
    "EvidenceCheck",
    "check_evidence",
    "deployed_task_block",
]

"""Version of the evidence file format (``campaign.schema.json``). 3: ``campaign_semantics``
recorded and required (2 compared the tool version instead; 1 bound no task)."""
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
"""Fewest examples (perturbation sequences) a campaign needs to count as evidence in the gate.

With ``N`` examples and no violation, the failure probability per perturbed run is below
``3 / N`` at 95% confidence (the rule of three): 500 examples bound it by 0.6%. A scoop
campaign of 1,000 runs takes about 20 s on 2 cores, so the bundled
evidence (1,000 examples, ``tli evidence``) costs seconds per model."""


"""Shortest perturbation window a kinematic campaign must have drawn from (control steps; 1 s
at 10 ms): pushes confined to the first steps test almost nothing of the mode boundaries."""
"""Fewest perturbations per case a kinematic campaign must have allowed: with one push at most,
no case tests a recovery that is itself perturbed (paper Asm. 2: finitely many, not one)."""


"""Config fields recorded elsewhere in the evidence, or where (not what) the campaign ran."""


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
    if not isinstance(got, Mapping):
        return False
    ignore = {"version"} if want.get("distribution") == DISTRIBUTION else set()
    keys = (set(got) | set(want)) - ignore
    return all(got.get(k) == want.get(k) for k in keys)


def _check_files(doc: Mapping[str, Any], shown: str, mpath: Path, named: Mapping[str, Path],
                 seen: Mapping[str, Path], passed: list[str]) -> list[str]:
    """The three hashes; the spec is the model's; the certificate covers the model. ``named``:
    the files resolved as the OS opens them; ``seen``: as the evidence names them (messages)."""
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


"""The ``--backend`` choices of ``tli verify``, ``tli evidence`` and ``tli sim franka``."""


def _check_run_settings(camp: Mapping[str, Any], shown: str) -> list[str]:
    """How the campaign ran (``campaign.backend``, ``campaign.workers``; kinematic and physical
    alike), validated with the command line's choices and range, like every other recorded
    setting: the schema alone admits any short string and up to 100,000 workers."""
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
