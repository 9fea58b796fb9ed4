"""The deployment gate (``tli gate [DIR]``): nothing uncertified, unbound or tampered with ships.

The gate re-verifies; it never trusts a stored verdict (``docs/design.md``, "Certificates are
re-checked, never trusted"). Under a project directory ``DIR`` it checks:

1. every spec under ``DIR/specs/`` re-checks with :func:`tli_verify.logic.check.check_spec_file`
   and gets the verdict it declares (``expect``; realizable specs must also be well-separated);
2. every certificate under ``DIR/certificates/`` re-checks exactly
   (:func:`tli_verify.certification.certificate.check_certificate`): digest, model and spec hashes,
   the spec it names is the model's, ``P`` is the model's (the runtime's) ``P``, the cuts, the
   continuous-time, sampled-data and decay-rate conditions; an orientation certificate
   (:mod:`tli_verify.certification.orientation`, recognised by its ``kind``) likewise, with its
   chart region;
3. every model under ``DIR/models/`` -- a *deployed* model -- is bound to its spec and covered:

   * ``certificate``: a valid certificate covers its exact bytes (SHA-256), cuts included;
   * ``spec``: it names a spec, which loads and re-checks realizable (well-separated unless it
     declares otherwise);
   * ``modes``: it has a DS for every mode the spec's task automaton can run, a per-transition
     DS for every mode transition the automaton can take out of a mode whose DS is
     per-transition, in every automaton state of such a mode a DS the runtime can pick (one
     towards a mode that state can move to), and no mode (or next mode) the spec lacks;
   * ``dimension``: its state names are distinct and every DS and cut has their dimension;
   * ``campaign``: campaign evidence ``certificates/<name>.campaign.json``
     (:mod:`tli_verify.verify.evidence`) binds its current spec, model and valid certificate,
     found 0 violations with modulation on, is complete and has at least
     ``MIN_EVIDENCE_EXAMPLES`` examples; a short campaign (``rerun``; default
     ``DEFAULT_RERUN_EXAMPLES``; ``rerun=N``: ``tli gate --rerun N``; ``rerun=0`` from Python
     only) runs again on a seed the gate derives (:func:`rerun_seed`, not the evidence's) and
     must find nothing. Evidence that binds no deployed model blocks too. A physical campaign's
     evidence (world ``franka-physics``, the Franka project ``sim/franka``) needs
     ``MIN_PHYSICS_TRIALS`` perturbed MuJoCo trials that all delivered soup; its ``rerun``
     re-runs ``N`` physical trials with the recorded robot, variant and duration, on a derived seed
     (:func:`tli_verify.sim.campaign.run_physics_campaign`) and every one must pass the
     physics oracle.

A directory with no model to deploy fails closed ("nothing to gate"). Any failure blocks.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tli_verify.arguments import check_int, check_path
from tli_verify.certification.certificate import CertCheck, check_certificate
from tli_verify.certification.orientation import (
    ORIENTATION_CERT_KIND,
    check_orientation_certificate,
)
from tli_verify.deploy.artifact import check_artifact, render_text, text_path_for
from tli_verify.deploy.cloop import CInTheLoop, in_the_loop
from tli_verify.deploy.content import artifact_of
from tli_verify.errors import CertificateError, GateError, ModelError, TliError, bad_input
from tli_verify.io import read_bytes, read_json, same_file, sha256_file
from tli_verify.limits import MAX_EXAMPLES
from tli_verify.logic.check import check_spec_file, synthesize
from tli_verify.model.serialize import load_model
from tli_verify.project.session import open_project
from tli_verify.runtime.handoff import handoff_status
from tli_verify.sim.physics_checks import FRANKA_PHYSICS
from tli_verify.tasks.project import check_goal, goal_of, resolve, spec_task
from tli_verify.verify.config import CampaignConfig
from tli_verify.verify.evidence import (
    EVIDENCE_SUFFIX,
    check_evidence,
    evidence_path_for,
    settings_for_config,
    settings_problems,
)
from tli_verify.verify.evidence.rules import (
    DEFAULT_RERUN_EXAMPLES,
    DEFAULT_RERUN_TRIALS,
    HANDOFF_RETEST,
)

if TYPE_CHECKING:
    from tli_verify.logic.check import SpecCheck

__all__ = ["DEFAULT_RERUN_EXAMPLES", "DEFAULT_RERUN_TRIALS", "CampaignRunner", "GateItem",
           "GateReport", "rerun_campaign", "rerun_physics", "rerun_seed", "rerun_starts",
           "run_gate"]

CampaignRunner = Callable[[Any, Path, int], tuple[bool, str]]
"""``(evidence check, model path, examples) -> (ok, one-line message)``: a re-run."""


def rerun_seed(check: Any, model: Path, count: int) -> int:
    """The seed of the gate's re-run: derived from the evidence's digest and the model's
    SHA-256, so it is not the evidence's seed and evidence cannot be tuned to it; the same files
    give the same seed (a re-run is reproducible), any edit gives another.

    Parameters
    ----------
    check : EvidenceCheck
    model : Path
    count : int
        Examples or trials re-run (seeds ``s .. s + count - 1`` stay below ``2**32``).
    """
    import hashlib

    text = f"tli-verify gate re-run:{check.digest}:{sha256_file(model)}"
    value = int(hashlib.sha256(text.encode("utf-8")).hexdigest()[:16], 16)
    return value % (2**32 - max(int(count), 1))


@dataclass(frozen=True, slots=True)
class GateItem:
    """One check the gate made.

    Attributes
    ----------
    kind : str
        ``"spec"``, ``"certificate"``, ``"model"``, ``"evidence"`` or ``"project"``.
    path : str
        The file (relative to the project).
    ok : bool
    message : str
        What passed, or what blocks.
    check : str
        Which check of that file (``"re-check"``, ``"certificate"``, ``"spec"``, ``"modes"``,
        ``"dimension"``, ``"campaign"``, ``"rerun"``, ``"contents"``).
    """

    kind: str
    path: str
    ok: bool
    message: str
    check: str = "re-check"

    def to_dict(self) -> dict[str, Any]:
        """One ``--json`` record."""
        return {"kind": self.kind, "path": self.path, "check": self.check, "ok": self.ok,
                "message": self.message}


@dataclass(frozen=True, slots=True)
class GateReport:
    """Everything the gate checked.

    Attributes
    ----------
    root : str
    items : tuple of GateItem
    """

    root: str
    items: tuple[GateItem, ...]

    @property
    def ok(self) -> bool:
        """True iff nothing blocks (and something was checked)."""
        return bool(self.items) and all(i.ok for i in self.items)

    @property
    def blockers(self) -> tuple[GateItem, ...]:
        """The failing items."""
        return tuple(i for i in self.items if not i.ok)

    def count(self, kind: str) -> int:
        """Number of distinct files of one kind."""
        return len({i.path for i in self.items if i.kind == kind})


def _files(directory: Path, pattern: str) -> list[Path]:
    """Every entry matching ``pattern`` that is not a directory (regular or not), and every
    symlinked directory (``rglob`` does not descend into them, so they are blocked, never
    silently skipped)."""
    if not directory.is_dir():
        return []
    found = {p for p in directory.rglob(pattern) if not p.is_dir()}
    found |= {p for p in directory.rglob("*") if p.is_symlink() and p.is_dir()}
    return sorted(found)


def _irregular(path: Path, kind: str, shown: str) -> GateItem | None:
    """A blocking item for a device, FIFO, socket or dangling link where a file must be."""
    if path.is_file() and not path.is_symlink():
        return None
    try:
        if path.is_symlink() and path.resolve(strict=True).is_file():
            return None
    except OSError:
        pass
    what = ("a symlinked directory, not followed" if path.is_dir() else
             "a device, FIFO, socket or dangling link")
    return GateItem(kind, shown, False, f"not a regular file ({what}): refused, never read",
                    "load")


def _default_spec_checker() -> Callable[[Path], SpecCheck]:

    return check_spec_file


class _Specs:
    """Spec checks, each file checked once (keyed by resolved path)."""

    def __init__(self, checker: Callable[[Path], SpecCheck] | None) -> None:
        self._checker = checker
        self._done: dict[Path, Any] = {}

    def check(self, path: Path) -> Any:
        """The check result, or the ``TliError`` it raised."""
        key = path.resolve()
        if key not in self._done:
            if self._checker is None:
                self._checker = _default_spec_checker()
            try:
                self._done[key] = self._checker(path)
            except TliError as exc:
                self._done[key] = exc
            except RecursionError:
                self._done[key] = TliError(f"{path}: too deeply nested to check")
        return self._done[key]


def _spec_item(result: Any, shown: str) -> GateItem:
    if isinstance(result, TliError):
        return GateItem("spec", shown, False, f"does not load: {result}")
    realizable = bool(result.realizable)
    expected = bool(result.expected_realizable)
    as_expected = bool(getattr(result, "as_expected", realizable == expected))
    verdict = "realizable" if realizable else "unrealizable"
    if as_expected:
        return GateItem("spec", shown, True, f"{verdict}, as the spec declares")
    if realizable != expected:
        return GateItem("spec", shown, False, f"{verdict}, but the spec declares "
                        f"{'realizable' if expected else 'unrealizable'}")
    return GateItem("spec", shown, False, f"{verdict} but not well-separated: it may be won "
                    "vacuously (declare expect = \"not-well-separated\" if intended)")


def _orientation_item(cert: Path, shown: str) -> GateItem | None:
    """The re-check of an orientation certificate (:mod:`tli_verify.certification.orientation`),
    or None when ``cert`` is not one. Orientation models are not deployed by the gate yet (no
    pose task or campaign); their certificates re-check exactly all the same, and a failing one
    blocks."""
    try:
        doc = read_json(cert, what="certificate", error=CertificateError)
    except (TliError, RecursionError):
        return None  # check_certificate reports it
    if not (isinstance(doc, dict) and doc.get("kind") == ORIENTATION_CERT_KIND):
        return None
    try:
        check = check_orientation_certificate(cert)
    except TliError as exc:
        return GateItem("certificate", shown, False, f"unreadable: {exc}")
    if check.ok:
        return GateItem("certificate", shown, True, "orientation DS re-checked exactly (P, "
                        "continuous, sampled, decay rate, chart region); covers "
                        f"{doc['model']['path']}")
    return GateItem("certificate", shown, False, "; ".join(check.failures))


def _certificate_line(check: CertCheck) -> str:
    rate = f", sampled-data at dt = {check.dt}" if check.dt else ""
    return (f"re-checked exactly ({len(check.passed)} checks: digest, model and spec SHA-256, "
            f"P = the model's P, cuts, Lyapunov conditions{rate})")


def _model_checks(model_path: Path, shown: Callable[[Path], str],
                  certified: dict[Path, list[tuple[Path, CertCheck]]],
                  specs: _Specs) -> list[GateItem]:
    """The per-model binding checks (certificate, spec, modes, dimension)."""
    name = shown(model_path)
    try:
        model = load_model(model_path)
    except TliError as exc:
        return [GateItem("model", name, False, f"does not load: {exc}", "load")]
    except RecursionError:
        return [GateItem("model", name, False, "does not load: too deeply nested", "load")]
    items: list[GateItem] = []
    covering = certified.get(model_path.resolve(), [])
    if covering:
        cert, _ = covering[0]
        items.append(GateItem("model", name, True, f"covered by {shown(cert)}: a valid "
                              "certificate of its exact bytes (SHA-256), cuts included",
                              "certificate"))
    else:
        items.append(GateItem("model", name, False, "no valid certificate covers it (run: tli "
                              f"certify {model_path})", "certificate"))

    items.append(_dimension_item(model, name))
    if model.spec_path is None:
        items.append(GateItem("model", name, False, "names no spec: a deployed model must name "
                              "the spec whose automaton runs it (\"spec\" field)", "spec"))
        return items
    spec_path = model.spec_path  # resolved as the OS opens it
    if not spec_path.is_file():
        items.append(GateItem("model", name, False, f"its spec {spec_path} does not exist",
                              "spec"))
        return items
    result = specs.check(spec_path)
    if isinstance(result, TliError):
        items.append(GateItem("model", name, False, f"its spec {shown(spec_path)} does not "
                              f"load: {result}", "spec"))
        return items
    if not result.realizable:
        items.append(GateItem("model", name, False, f"its spec {shown(spec_path)} is "
                              "unrealizable: no automaton can run it", "spec"))
        return items
    if not result.as_expected:
        items.append(GateItem("model", name, False, f"its spec {shown(spec_path)} does not "
                              "re-check as it declares (not well-separated)", "spec"))
        return items
    items.append(GateItem("model", name, True, f"names {shown(spec_path)}: realizable"
                          f"{', well-separated' if result.well_separated else ''}", "spec"))
    items.append(_modes_item(model, name, result.spec, shown(spec_path)))
    items.append(_task_item(model, name, result.spec, spec_path, shown,
                            [c for _, c in covering]))
    items.append(_handoff_item(model, name, spec_path))
    return items


def _handoff_item(model: Any, name: str, spec_path: Path) -> GateItem:
    """Which hand-off guarantees are proved (re-decided here) and which are tested (re-tested
    on the gate's own draw) (:func:`tli_verify.runtime.handoff.handoff_status`)."""
    import hashlib

    # the model's bytes as the session read them (the ones its certificate check hashed)
    data = read_bytes(str(model.path), what="model", error=ModelError) if model.path else b""
    seed = int.from_bytes(hashlib.sha256(b"tli-gate-handoff:" + data).digest()[:4], "big") \
        if model.path else 0
    try:
        ok, lines = handoff_status(model, spec_path, retest=HANDOFF_RETEST, seed=seed)
    except TliError as exc:
        return GateItem("model", name, False, f"hand-off record does not re-check: {exc}",
                        "handoff")
    return GateItem("model", name, ok, "; ".join(lines), "handoff")


def _task_item(model: Any, name: str, spec: Any, spec_path: Path,
               shown: Callable[[Path], str], checks: list[CertCheck]) -> GateItem:
    """The task the spec names: it loads, fits the model (dimension) and the spec (sensors,
    goal), its goal is reachable, and the model's certificate covers its control period."""
    from fractions import Fraction

    try:
        task = spec_task(spec, spec_path)
    except TliError as exc:
        return GateItem("model", name, False, f"its spec's task does not load: {exc}", "task")
    if task is None:
        return GateItem("model", name, False, f"its spec {shown(spec_path)} names no task "
                        "(task = \"NAME\"): nothing says which task the policy runs in",
                        "task")
    problems = []
    if task.dim != model.dim:
        problems.append(f"task {task.name!r} is {task.dim}-D, the model {model.dim}-D")
    if set(task.sensor_names) != set(spec.inputs):
        problems.append(f"task {task.name!r} has sensors {', '.join(task.sensor_names)}, the "
                        f"spec's inputs are {', '.join(spec.inputs)}")
    goal = goal_of(spec, task)
    try:
        modes = check_goal(synthesize(spec), goal, where=shown(spec_path))
    except TliError as exc:
        problems.append(str(exc))
        modes = ()
    periods = [Fraction(c.dt) for c in checks if c.dt]
    if periods and Fraction(repr(task.dt)) > max(periods):
        problems.append(f"task {task.name!r} runs at dt = {task.dt:g} s, longer than the "
                        f"certified {max(periods)} s: the runtime refuses it")
    if problems:
        return GateItem("model", name, False, "; ".join(problems), "task")
    return GateItem("model", name, True, f"runs in task {task.name!r} ({task.where}): "
                    f"{task.dim}-D, sensors {', '.join(task.sensor_names)}, goal "
                    f"{', '.join(modes)} reachable, dt {task.dt:g} s certified", "task")


def _dimension_item(model: Any, name: str) -> GateItem:
    names = list(model.state_names)
    dupes = sorted({s for s in names if names.count(s) > 1})
    if dupes or not names or any(not s for s in names):
        return GateItem("model", name, False, "state names must be distinct and non-empty; "
                        f"repeated: {', '.join(dupes) or '-'}", "dimension")
    n = len(names)
    for key, mm in model.modes.items():
        if mm.ds.attractor.shape != (n,) or mm.ds.A.shape[1:] != (n, n):
            return GateItem("model", name, False, f"DS {key!r} has dimension "
                            f"{mm.ds.attractor.shape[0]}, the state names give {n}", "dimension")
        for c, cut in enumerate(mm.cuts):
            if cut.dim != n:
                return GateItem("model", name, False, f"DS {key!r} cut {c} has dimension "
                                f"{cut.dim}, the state names give {n}", "dimension")
    return GateItem("model", name, True, f"n = {n} ({', '.join(names)}) in all "
                    f"{len(model.modes)} DS and their cuts", "dimension")


def _modes_item(model: Any, name: str, spec: Any, spec_shown: str) -> GateItem:
    """DS coverage of the task automaton, and no mode the spec lacks."""
    try:
        automaton = synthesize(spec)
    except TliError as exc:
        return GateItem("model", name, False, f"cannot build the automaton of {spec_shown}: "
                        f"{exc}", "modes")
    spec_modes = set(automaton.modes)
    problems: list[str] = []
    plain = {mm.mode for mm in model.modes.values() if mm.key == mm.mode}
    per_transition: dict[str, set[str]] = {}
    for mm in model.modes.values():
        for m in (mm.mode, mm.next_mode):
            if m is not None and m not in spec_modes:
                problems.append(f"DS {mm.key!r} names mode {m!r}, which {spec_shown} lacks")
        if mm.key != mm.mode and mm.next_mode is not None:
            per_transition.setdefault(mm.mode, set()).add(mm.next_mode)
    runnable = sorted({s.mode for s in automaton.states})
    for m in runnable:
        if m not in plain and m not in per_transition:
            problems.append(f"no DS for mode {m!r}, which the automaton can run")
    # state by state, with the runtime's own planner (TaskAutomaton.planned_keys): the DS the
    # executive would run in each state must exist (modes without any DS are reported above)
    ds = {k: (mm.mode, mm.next_mode) for k, mm in model.modes.items()}
    for step in automaton.planned_keys(ds):
        m = step.mode
        if step.key is None and (m in plain or m in per_transition):
            towards = ", ".join(step.moves) or "none: it only stays in the mode"
            problems.append(f"no DS to run in automaton state {step.state} (mode {m!r}): no "
                            f"plain DS {m!r} and no per-transition DS towards the modes it can "
                            f"move to ({towards})")
            break
    for src, dst in automaton.mode_transitions():
        if src != dst and src not in plain and src in per_transition \
                and dst not in per_transition[src]:
            problems.append(f"no per-transition DS {src}->{dst} for a transition the automaton "
                            "can take")
    if problems:
        return GateItem("model", name, False, "; ".join(problems), "modes")
    return GateItem("model", name, True, f"a DS for each of the {len(runnable)} modes the "
                    f"automaton of {spec_shown} can run (and each transition out of "
                    "per-transition modes); no mode the spec lacks", "modes")


def run_gate(root: str | os.PathLike[str] = ".", *,
             spec_checker: Callable[[Path], SpecCheck] | None = None, rerun: int | None = None,
             campaign_runner: CampaignRunner | None = None,
             artifacts: Sequence[str | os.PathLike[str]] = ()) -> GateReport:
    """Run the deployment gate on a project directory.

    Parameters
    ----------
    root : path-like, optional
        Project directory holding ``certificates/``, ``models/`` and ``specs/``.
    spec_checker : callable, optional
        ``path -> result`` with ``.realizable``, ``.expected_realizable``, ``.as_expected``,
        ``.well_separated`` and ``.spec`` (default:
        :func:`tli_verify.logic.check.check_spec_file`).
    rerun : int, optional
        Examples (physical evidence: trials) the gate re-runs per deployed model whose evidence
        checks, on a seed it derives (:func:`rerun_seed`), with the evidence's recorded
        settings (``tli gate --rerun N``); any violation blocks. Default
        :data:`DEFAULT_RERUN_EXAMPLES` / :data:`DEFAULT_RERUN_TRIALS`; 0 skips the re-run
        (the Python API only, for tests of the other checks; the CLI always re-runs).
    campaign_runner : callable, optional
        ``(evidence check, model path, examples) -> (ok, message)`` for ``rerun`` (default:
        :func:`rerun_campaign`, which calls :func:`tli_verify.verify.campaign.run_campaign`).
    artifacts : sequence of path-like, optional
        Exported policies to be deployed (``tli gate --artifact``): each is checked
        (:func:`artifact_item`) against the project and the campaign that tested it, and with
        physical evidence re-run ``rerun`` trials in the C evaluator (:func:`artifact_rerun`).

    Returns
    -------
    GateReport
        Blocked (``ok`` false) when anything fails or there is no model to deploy.

    Raises
    ------
    GateError
        ``root`` is not a directory (exit 2).
    """
    base = check_path(root, "root", error=GateError)
    if rerun is not None:
        rerun = check_int(rerun, "rerun", 0, MAX_EXAMPLES, error=GateError)
    if not base.is_dir():
        raise bad_input(GateError, f"{base}: not a directory")

    def shown(p: Path) -> str:
        for a, b in ((p.absolute(), base.absolute()), (p.resolve(), base.resolve())):
            try:
                return Path(os.path.normpath(a)).relative_to(os.path.normpath(b)).as_posix()
            except ValueError:
                continue
        return str(p)

    specs = _Specs(spec_checker)
    items: list[GateItem] = []
    for spec in _files(base / "specs", "*.toml"):
        bad = _irregular(spec, "spec", shown(spec))
        items.append(bad if bad is not None else _spec_item(specs.check(spec), shown(spec)))
    certified: dict[Path, list[tuple[Path, CertCheck]]] = {}
    for cert in _files(base / "certificates", "*.json"):
        if cert.name.endswith(".campaign.json"):  # EVIDENCE_SUFFIX
            continue  # campaign evidence, checked per model (_campaign_items)
        bad = _irregular(cert, "certificate", shown(cert))
        if bad is not None:
            items.append(bad)
            continue
        orientation = _orientation_item(cert, shown(cert))
        if orientation is not None:
            items.append(orientation)
            continue
        try:
            check = check_certificate(cert)
        except TliError as exc:
            items.append(GateItem("certificate", shown(cert), False, f"unreadable: {exc}"))
            continue
        except RecursionError:
            items.append(GateItem("certificate", shown(cert), False,
                                  "unreadable: too deeply nested"))
            continue
        if check.ok:
            model = Path(check.model_path or "").resolve()
            certified.setdefault(model, []).append((cert, check))
            items.append(GateItem("certificate", shown(cert), True,
                                  f"{_certificate_line(check)}; covers "
                                  f"{shown(model)}"))
        else:
            items.append(GateItem("certificate", shown(cert), False,
                                  "; ".join(check.problems)))
    models = _files(base / "models", "*.json")
    for model in models:
        bad = _irregular(model, "model", shown(model))
        items += [bad] if bad is not None else _model_checks(model, shown, certified, specs)
    items += _campaign_items(base, models, shown, certified, rerun=rerun,
                             runner=campaign_runner)
    items += [artifact_item(Path(a), base, items, shown, rerun=rerun) for a in artifacts]
    if not models:
        items.append(GateItem("project", shown(base), False, "nothing to gate: no model under "
                              f"{shown(base / 'models')}/ to deploy (the gate fails closed)",
                              "contents"))
    return GateReport(root=str(base), items=tuple(items))

# --------------------------------------------------------------------------------------------
# Deployed artifacts
# --------------------------------------------------------------------------------------------


CONTENT_REL_TOL = 1e-9
"""Relative tolerance of the gate's comparison of an artifact's numbers with the ones its model
exports to now: they are re-derived (the GMM's quadratic form, the stall levels), and BLAS
kernels sum in other orders on other CPUs, so the last bits differ between machines."""


def _first_difference(want: object, have: object, where: str) -> str | None:
    """The path of the first place ``have`` is not ``want`` (numbers within
    :data:`CONTENT_REL_TOL` relative; everything else exactly), or None."""
    if isinstance(want, dict):
        if not isinstance(have, dict) or set(have) != set(want):
            return where
        for k, v in want.items():
            found = _first_difference(v, have[k], f"{where}.{k}" if where else str(k))
            if found is not None:
                return found
        return None
    if isinstance(want, list):
        if not isinstance(have, list) or len(have) != len(want):
            return where
        for i, (a, b) in enumerate(zip(want, have, strict=True)):
            found = _first_difference(a, b, f"{where}[{i}]")
            if found is not None:
                return found
        return None
    if isinstance(want, float) and isinstance(have, float | int) and \
            not isinstance(have, bool):
        scale = max(1.0, abs(want), abs(float(have)))
        return None if abs(want - float(have)) <= CONTENT_REL_TOL * scale else where
    return None if (type(want) is type(have) and want == have) else where


def _content_differs(art: dict[str, Any], model: Path) -> str | None:
    """What of a deployed artifact's content is not what its model exports to now
    (:func:`~tli_verify.deploy.content.artifact_of`, with the artifact's own sources and cut
    storage; the stall rule the current evidence ran), or None. A hash binds the file to its
    content, not the content to the model: an artifact edited and re-hashed (a matrix, a
    stall level, an edge) with its ``sources`` left alone is caught here. Numbers compare
    within :data:`CONTENT_REL_TOL`; the exporting ``tool`` version may differ."""
    try:
        want = artifact_of(open_project(model=model), sources=art["sources"],
                           max_online_cuts=int(art["modulation"]["max_online_cuts"]))
    except TliError as exc:
        return f"its model does not export: {exc}"
    want.pop("tool", None)
    have = {k: v for k, v in art.items() if k not in ("tool", "content_sha256")}
    where = _first_difference(want, have, "")
    if where is None:
        return None
    if where.startswith("stall"):
        return (f"its stall rule ({where}) is not the one the current campaign evidence ran "
                "(or its levels and re-entries are not the model's): re-export it")
    return (f"its content ({where}) is not what its model exports to now: the artifact was "
            "edited (and re-hashed) or made from other files; re-export it")


def artifact_item(path: Path, base: Path, items: Sequence[GateItem],
                  shown: Callable[[Path], str], *, rerun: int | None = None) -> GateItem:
    """Check an exported policy (``tli export``) against what the gate passed.

    It binds "the artifact that will be deployed" to "the campaign that tested it": the
    artifact re-checks (schema, its own content hash, its text form -- what the C evaluator
    loads -- the exact rendering of its JSON); its model is one of the project's models, and
    the gate passed every check of it; its spec, certificate and task are the files the model
    resolves to, byte for byte; and its campaign is the current evidence: either the artifact
    was exported with this evidence, or this evidence's trials ran this very artifact in the C
    evaluator (``physics.evaluator``). When that evidence is a physical campaign, the artifact
    itself then drives the robot: ``rerun`` perturbed MuJoCo trials (default
    :data:`DEFAULT_RERUN_TRIALS`; 0 skips them, the Python API only) run through the C
    evaluator, on a seed derived from the artifact's content and the model
    (:func:`artifact_rerun`), and each must pass the physics oracle.

    Returns
    -------
    GateItem
        Kind ``artifact``; blocking on the first mismatch, naming it.
    """
    name = shown(path)

    def block(why: str, check: str) -> GateItem:
        return GateItem("artifact", name, False, why, check)

    bad = _irregular(path, "artifact", name)
    if bad is not None:
        return bad
    try:
        art = check_artifact(path)
    except TliError as exc:
        return block(f"refused: {exc}", "re-check")
    text = text_path_for(path)
    want = render_text({k: v for k, v in art.items() if k != "content_sha256"}) + \
        f"sha256 {art['content_sha256']}\n"
    try:
        have = text.read_text(encoding="utf-8") if text.is_file() else None
    except (OSError, UnicodeDecodeError) as exc:
        return block(f"its text form {shown(text)} is unreadable: {exc}", "re-check")
    if have is None:
        return block(f"no text form {shown(text)} next to it (the file the C evaluator "
                     "loads)", "re-check")
    if have != want:
        return block(f"its text form {shown(text)} is not the rendering of the JSON "
                     "artifact: the file the C evaluator loads was edited", "re-check")
    src = art["sources"]
    model_sha = (src.get("model") or {}).get("sha256")
    models = [m for m in _files(base / "models", "*.json")
              if _irregular(m, "model", shown(m)) is None and sha256_file(m) == model_sha]
    if not models:
        return block(f"its model (SHA-256 {str(model_sha)[:12]}...) is none of the project's "
                     f"models under {shown(base / 'models')}/: not a policy this gate checked",
                     "binding")
    model = models[0]
    blocked = [i for i in items if not i.ok and i.path == shown(model)]
    if blocked:
        return block(f"its model {shown(model)} is blocked: {blocked[0].message}", "binding")
    try:
        files = resolve(model=model)
    except TliError as exc:
        return block(f"its model {shown(model)} does not resolve: {exc}", "binding")
    task_file = Path(files.task.source.path) if files.task.source.path else None
    for what, file in (("spec", files.spec), ("certificate", files.certificate),
                       ("task", task_file)):
        recorded = (src.get(what) or {}).get("sha256")
        actual = sha256_file(file) if file is not None and file.is_file() else None
        if recorded != actual:
            return block(f"its {what} (SHA-256 {str(recorded)[:12]}...) is not the {what} "
                         f"{shown(file) if file else '(none)'} the model resolves to now "
                         f"({str(actual)[:12]}...)", "binding")
    evidence = files.evidence
    if not evidence.is_file():
        return block(f"no campaign evidence {shown(evidence)} for its model", "campaign")
    differs = _content_differs(art, model)
    if differs is not None:
        return block(differs, "content")
    try:
        doc = read_json(evidence, what="campaign evidence", error=GateError)
    except TliError as exc:
        return block(f"its evidence does not load: {exc}", "campaign")
    physics = doc.get("physics") if isinstance(doc, dict) else None
    recorded = (src.get("evidence") or {}).get("sha256")
    ran = ((physics or {}).get("evaluator") or {}).get("artifact_sha256") \
        if isinstance(physics, dict) else None
    bound = None
    if recorded == sha256_file(evidence):
        bound = (f"the policy of {shown(model)} as gated, exported with the current evidence "
                 f"{shown(evidence)}")
    elif ran == art["content_sha256"] and same_file(evidence, files.evidence):
        bound = f"the campaign {shown(evidence)} ran this artifact in the C evaluator"
    if bound is not None:
        head = f"content {art['content_sha256'][:12]}...: {bound}"
        count = DEFAULT_RERUN_TRIALS if rerun is None else int(rerun)
        if not isinstance(physics, dict) or count == 0:
            return GateItem("artifact", name, True, head, "binding")
        ok, what = artifact_rerun(path, model, physics, count)
        return GateItem("artifact", name, ok, f"{head}; {what}", "rerun")
    return block(f"no campaign tested it: it was exported with other evidence than "
                 f"{shown(evidence)}, whose trials did not run it (re-export it, or run the "
                 f"campaign with it: tli sim franka --c-evaluator {name} --evidence)", "campaign")

# --------------------------------------------------------------------------------------------
# Campaign evidence
# --------------------------------------------------------------------------------------------


def _campaign_items(base: Path, models: list[Path], shown: Callable[[Path], str],
                    certified: dict[Path, list[tuple[Path, CertCheck]]], *,
                    rerun: int | None, runner: CampaignRunner | None) -> list[GateItem]:
    """One ``campaign`` line per deployed model (and a ``rerun`` line with ``rerun``), then
    one blocking ``evidence`` line per evidence file that binds no deployed model."""
    items: list[GateItem] = []
    claimed: set[Path] = set()
    for model in models:
        if _irregular(model, "model", shown(model)) is not None:
            continue  # already blocked, never read
        name = shown(model)
        evidence = evidence_path_for(model)
        claimed.add(Path(os.path.normpath(evidence.absolute())))
        if not os.path.lexists(evidence):
            items.append(GateItem("model", name, False, f"no campaign evidence "
                                  f"{shown(evidence)} (run: tli evidence {shown(base)}, or "
                                  f"tli verify --model {name} --evidence)", "campaign"))
            continue
        valid = [c for c, _ in certified.get(model.resolve(), [])]
        check = check_evidence(evidence, model_path=model, valid_certificates=valid,
                               physical=(FRANKA_PHYSICS,))
        if not check.ok:
            problems = "; ".join(_unprefixed(p, check.path) for p in check.problems)
            items.append(GateItem("model", name, False, f"{shown(evidence)}: {problems}",
                                  "campaign"))
            continue
        comments = next((p for p in check.passed if "only its comments" in p), None)
        if check.physics:
            phys = dict(check.physics)
            items.append(GateItem(
                "model", name, True, f"{shown(evidence)}: physical campaign {check.world!r} "
                f"(robot {phys['robot']}, {phys['variant']}, {phys['duration']:g} s budget): "
                f"{check.examples} perturbed trials from seed {check.seed}"
                f"{_partition(phys)} ({phys['pushes']} "
                f"push(es) and {phys['tilts']} tilt(s) each), all delivered soup, 0 "
                "violations; binds its task, spec, model and certificate (SHA-256)"
                + _evaluator_note(phys), "campaign"))
        else:
            forged = _settings_problems(check, model)
            if forged:
                items.append(GateItem("model", name, False, f"{shown(evidence)}: "
                                      f"{'; '.join(forged)}", "campaign"))
                continue
            items.append(GateItem("model", name, True, f"{shown(evidence)}: campaign on task "
                                  f"{check.world!r} with seed {check.seed}: {check.examples} "
                                  f"examples ({check.runs} runs), modulation on, 0 violations; "
                                  "binds its task, spec, model and certificate (SHA-256)"
                                  + (f"; {comments}" if comments else ""), "campaign"))
        count = (DEFAULT_RERUN_TRIALS if check.physics else DEFAULT_RERUN_EXAMPLES) \
            if rerun is None else int(rerun)
        if count > 0:
            ok, message = (runner or rerun_campaign)(check, model, count)
            items.append(GateItem("model", name, ok, message, "rerun"))
    for evidence in _files(base / "certificates", "*" + EVIDENCE_SUFFIX):
        if evidence.name.endswith(EVIDENCE_SUFFIX) and \
                Path(os.path.normpath(evidence.absolute())) not in claimed:
            items.append(GateItem("evidence", shown(evidence), False, "binds no deployed "
                                  "model (the gate looks for models/<name>.model.json next to "
                                  "certificates/<name>.campaign.json)", "campaign"))
    return items


def _evaluator_note(phys: dict[str, Any]) -> str:
    """``; the trials ran artifact <sha> in the C evaluator`` when the evidence says so."""
    ev = phys.get("evaluator")
    if not isinstance(ev, dict):
        return ""
    return (f"; the trials ran the exported artifact {ev.get('artifact_sha256')} in the C "
            f"evaluator ({ev.get('steps')} steps, velocities within "
            f"{float(ev.get('max_rel_diff', 0.0)):.1e} of the runtime's)")


def _unprefixed(problem: str, path: str) -> str:
    """A problem without the evidence path it starts with (the gate's line names it once)."""
    return problem[len(path) + 2:] if problem.startswith(path + ": ") else problem


def _settings_problems(check: Any, model: Path) -> list[str]:
    """Recorded campaign settings no CLI command could have produced on the model's task
    (:func:`tli_verify.verify.evidence.settings_problems`)."""
    try:
        task = resolve(model=model).task
    except TliError as exc:
        return [f"the model's task does not resolve: {exc}"]
    return settings_problems(dict(check.settings), task)


def _partition(phys: dict[str, Any]) -> str:
    """How a physical campaign's trials were split, for the gate's line ("" for one chunk)."""
    chunks = phys.get("chunks") or ()
    return "" if len(chunks) <= 1 else f" in {len(chunks)} chunks of seeds (one executive each)"


def rerun_campaign(check: Any, model: Path, examples: int) -> tuple[bool, str]:
    """The gate's re-run: a short campaign on a seed the gate derives (:func:`rerun_seed`)
    and from starts it chooses itself (:func:`rerun_starts`: drawn in the task's start region,
    and the task's nominal starts; the evidence's recorded start is never used), with the
    evidence's other recorded settings (validated like the CLI's options), modulation on, on
    the deployed files; not shrunk (the line says how to reproduce it), in this process when
    ``N`` fits in one batch.

    Parameters
    ----------
    check : tli_verify.verify.evidence.EvidenceCheck
        A passing evidence check (its world, seed, spec and certificate).
    model : Path
        The deployed model.
    examples : int
        Examples of the short campaign.

    Returns
    -------
    (bool, str)
        Whether it found nothing, and one line saying what it ran and found.
    """
    if check.physics:
        return rerun_physics(check, model, examples)

    settings = settings_for_config(dict(check.settings), CampaignConfig)
    # a verdict, not a counterexample: no shrinking; one batch runs in this process (a pool
    # would only add its start-up)
    settings["shrink"] = False
    settings.pop("target_examples", None)
    # the gate's own starts, never the recorded ones: drawn in the task's start region, and
    # the task's nominal starts (a recorded start is the campaign's claim, not a fact)
    settings.pop("start", None)
    settings.pop("random_starts", None)
    seed = rerun_seed(check, model, examples)
    try:  # the project's files through its session: read once, the bytes the checks hashed
        session = open_project(model=model, spec=check.spec_path,
                               certificate=check.certificate_path)
        nominal = session.task.starts.nominal
        plan = rerun_starts(nominal, examples, seed)
        batch = settings.get("batch_size", 100)
        runs = inconclusive = 0
        found: dict[str, int] = {}
        partial = False
        first_bad = None
        for start, count, part_seed in plan:
            single = isinstance(batch, int) and count <= batch
            config = CampaignConfig(examples=count, seed=part_seed, modulation=True,
                                    backend="serial" if single else "process",
                                    start=start, random_starts=start is None, **settings)
            result = session.campaign(config)
            runs += int(result.runs)
            inconclusive += int(result.inconclusive)
            partial = partial or bool(getattr(result, "partial", False))
            if first_bad is None:
                first_bad = next((o.verdict for o in getattr(result, "outcomes", ())
                                  if not o.verdict.ok), None)
            for k, v in dict(result.violations).items():
                if int(v):
                    key = str(getattr(k, "value", k))
                    found[key] = found.get(key, 0) + int(v)
    except TliError as exc:
        return False, f"the re-run campaign failed: {exc}"
    except TypeError as exc:  # a recorded setting the config does not take
        return False, f"the evidence's recorded settings are malformed: {exc}"
    drawn = sum(c for s, c, _ in plan if s is None)
    starts = (f"{drawn} from starts drawn in the task's start region"
              + (f", {examples - drawn} from its {len(nominal)} nominal start(s)"
                 if examples > drawn else ""))
    what = (f"re-ran {examples} examples on the gate's own seed {seed} and its own starts "
            f"({starts}; task {check.world!r}, {runs} runs, {inconclusive} undecided)")
    if partial:
        return False, f"{what}: interrupted, incomplete"
    if found:
        kinds = ", ".join(f"{k} {v}" for k, v in sorted(found.items()))
        if first_bad is not None:  # the first violating run's own words (its diagnosis)
            kinds += f" (first: {first_bad.diagnosis or first_bad.violations[0].message})"
        first = plan[0]
        how = (f"--seed {first[2]} --examples {first[1]} --random-starts" if first[0] is None
               else f"--seed {first[2]} --examples {first[1]}")
        return False, (f"{what}: violations by kind (a run may count under several): {kinds}; "
                       f"reproduce (first part): tli verify --model {model} {how}")
    if inconclusive == runs:
        return False, f"{what}: no run was decided: the re-run shows nothing"
    return True, f"{what}: 0 violations"


def rerun_starts(nominal: Any, examples: int, seed: int
                 ) -> list[tuple[tuple[float, ...] | None, int, int]]:
    """How the gate's re-run splits its examples among its own starts: half (rounded up) on
    starts drawn in the task's start region, the rest spread over the task's nominal starts
    (all drawn when the task has none); each part on a seed derived from ``seed``.

    Parameters
    ----------
    nominal : sequence of sequence of float
        The task's nominal starts.
    examples : int
    seed : int
        The re-run's seed (:func:`rerun_seed`).

    Returns
    -------
    list of (start or None, count, seed)
        ``None``: random starts.
    """
    fixed = [tuple(float(v) for v in s) for s in nominal]
    on_nominal = examples // 2 if fixed else 0
    plan: list[tuple[tuple[float, ...] | None, int, int]] = [
        (None, examples - on_nominal, seed)]
    for i, start in enumerate(fixed):
        count = on_nominal // len(fixed) + (1 if i < on_nominal % len(fixed) else 0)
        if count:
            plan.append((start, count, (seed + 104_729 * (i + 1)) % (2**32 - count)))
    return [p for p in plan if p[1] > 0]


def artifact_rerun(path: Path, model: Path, physics: dict[str, Any], trials: int
                   ) -> tuple[bool, str]:
    """The deployed artifact drives the robot: ``trials`` perturbed MuJoCo trials with the
    evidence's recorded settings, the C evaluator in the loop
    (:func:`tli_verify.deploy.cloop.in_the_loop`; the Python executive supervises and must
    agree every step), on seeds derived from the artifact's content hash and the model's
    SHA-256 (not the evidence's, not the model re-run's), each judged by the physics oracle.

    Returns
    -------
    (bool, str)
        Passed, and the line's text (the failure and how to reproduce it).
    """
    import hashlib
    import tempfile

    held: list[CInTheLoop] = []
    try:
        art = read_json(path, what="policy artifact", error=GateError)
        text = f"tli-verify gate artifact re-run:{art['content_sha256']}:{sha256_file(model)}"
        seed = int(hashlib.sha256(text.encode("utf-8")).hexdigest()[:16], 16) % (2**32 - trials)
        session = open_project(model=model)
        with tempfile.TemporaryDirectory(prefix="tli-gate-c-") as build:

            def wrap(policy: Any) -> CInTheLoop:
                held.append(in_the_loop(policy, path, build))
                return held[-1]

            result = session.physics_campaign(seed=seed, trials=int(trials),
                                              recorded=dict(physics), wrap=wrap)
    except TliError as exc:
        return False, f"the C evaluator's re-run trials failed: {exc}"
    what = (f"re-ran {trials} physical trial(s) in the C evaluator from seed {seed}: "
            f"{result.successes}/{trials} delivered soup")
    found = {k: v for k, v in result.violations.items() if v}
    if found:
        bad = next(v for v in result.verdicts if not v.ok)
        config = result.config
        flags = f" --robot {config.robot} --duration {config.duration:g}" + \
            ("" if config.retry else " --no-stall-rule")
        return False, (f"{what}; violations: {', '.join(found)}; first: seed {bad.seed}: "
                       f"{bad.messages[0]}; reproduce: tli sim franka --certificates "
                       f"{session.root / 'certificates'} --seed {bad.seed} --trials 1{flags} "
                       f"--c-evaluator {path}")
    loop = held[0]
    return True, (f"{what}, 0 violations ({loop.steps} C steps, velocities within "
                  f"{loop.max_rel_diff:.1e} of the runtime's)")


def rerun_physics(check: Any, model: Path, trials: int) -> tuple[bool, str]:
    """``tli gate --rerun N`` on a physical campaign's evidence: ``N`` perturbed MuJoCo trials
    with the evidence's robot, variant, duration, pushes and tilts on seeds the gate derives
    (not the evidence's seed), on the deployed files
    (the project is the model's ``models/`` parent), each judged by the physics oracle
    (:func:`tli_verify.sim.trial_oracle.check_trial`).

    The re-run compares nothing trial by trial with the evidence: it runs ``N`` new trials on
    seeds the gate derives (:func:`rerun_seed`), in this process with one fresh executive
    (``workers=1``, serial), and every one must pass. However the evidence's trials were
    partitioned (``physics.workers``, ``physics.chunks``: each chunk began with a fresh
    executive too), its first re-run trial starts as every chunk did, with no cuts learned.

    Parameters
    ----------
    check : tli_verify.verify.evidence.EvidenceCheck
        A passing check of ``franka-physics`` evidence (its ``physics`` settings).
    model : Path
        The deployed model (``<project>/models/franka-scoop.model.json``).
    trials : int

    Returns
    -------
    (bool, str)
    """
    seed = rerun_seed(check, model, trials)
    try:  # the project's session runs the trials (the gate imports no physics itself)
        session = open_project(model=model, spec=check.spec_path,
                               certificate=check.certificate_path)
        root = session.root
        result = session.physics_campaign(seed=seed, trials=int(trials),
                                          recorded=dict(check.physics))
    except TliError as exc:
        return False, f"the re-run physical trials failed: {exc}"
    config = result.config
    what = (f"re-ran {trials} physical trial(s) from seed {seed} (robot {config.robot}, "
            f"{config.variant}, {config.duration:g} s): {result.successes}/{trials} delivered "
            "soup")
    found = {k: v for k, v in result.violations.items() if v}
    if found:
        bad = next(v for v in result.verdicts if not v.ok)
        kinds = ", ".join(f"{k} {v}" for k, v in found.items())
        return False, (f"{what}; violations (trials per kind): {kinds}; first: seed {bad.seed}: "
                       f"{bad.messages[0]}; reproduce: tli sim franka --certificates "
                       f"{root / 'certificates'} --seed {bad.seed} --trials 1 --robot "
                       f"{config.robot} --duration {config.duration:g}")
    return True, f"{what}, 0 violations"
