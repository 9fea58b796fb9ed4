"""The one project resolver: from a task, a spec or a model to every file a command needs.

A *project* is a folder laid out like this repository (``tli init DIR`` writes one)::

    PROJECT/
      tasks/NAME.toml               the task: state space, regions, sensors, goal, starts
      specs/SPEC.toml               the GR(1) spec; ``task = "NAME"`` names its task
      demos/*.csv                   demonstrations (``tli demos TASK`` writes scripted ones)
      models/MODEL.model.json       learned models; each names its spec
      certificates/MODEL.cert.json        the model's certificate (``tli certify``)
      certificates/MODEL.campaign.json    its campaign evidence (``tli verify --evidence``)

The rules (:func:`resolve`), applied by ``certify``, ``run``, ``verify``, ``replay``, ``gate``,
``evidence``, ``experiment`` and ``sim`` alike:

* **model -> certificate and evidence** (:func:`model_files`): a model at
  ``ROOT/models/SUB/M.model.json`` has ``ROOT/certificates/SUB/M.cert.json`` and
  ``ROOT/certificates/SUB/M.campaign.json``; a model outside any ``models/`` folder has them
  next to it (``DIR/M.cert.json``, ``DIR/M.campaign.json``);
* **model -> spec**: the spec the model file names (its certificate binds that one);
* **spec -> model**: ``ROOT/models/S.model.json`` for ``ROOT/specs/S.toml``;
* **spec -> task**: the spec's ``task`` key -- a task file relative to the spec, or a name
  looked up in ``ROOT/tasks/``, then the bundled tasks, then entry points
  (:func:`tli_verify.tasks.registry.find_task`);
* **task -> spec**: the task's ``spec`` key (relative to the task file);
* **goal**: the spec's ``[goal]``, else the task's ``[goal]``, else the automaton's sink modes.

A ``--task`` given with a spec that names another task runs on the given one (the evidence
records which; the gate accepts only evidence made on the task the spec names).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tli_verify.errors import TaskError, TliError
from tli_verify.logic.spec import load_spec
from tli_verify.model.serialize import load_model
from tli_verify.tasks.registry import find_task
from tli_verify.tasks.task import Goal, Task

if TYPE_CHECKING:
    from tli_verify.logic.automaton import TaskAutomaton
    from tli_verify.logic.spec import GR1Spec

__all__ = [
    "CERTIFICATE_SUFFIX",
    "EVIDENCE_SUFFIX",
    "MODEL_SUFFIX",
    "ModelFiles",
    "Resolved",
    "check_fit",
    "check_goal",
    "goal_of",
    "model_files",
    "model_stem",
    "pose_blocks",
    "project_root",
    "resolve",
    "spec_task",
]

MODEL_SUFFIX = ".model.json"
CERTIFICATE_SUFFIX = ".cert.json"
EVIDENCE_SUFFIX = ".campaign.json"
FOLDERS = ("tasks", "specs", "demos", "models", "certificates")
"""The folders of a project."""


def model_stem(model: str | os.PathLike[str]) -> str:
    """``scoop`` for ``models/scoop.model.json`` (also ``scoop.json``)."""
    return Path(model).name.removesuffix(".json").removesuffix(".model")


def project_root(path: str | os.PathLike[str]) -> Path:
    """The project folder of a file: the parent of the nearest ancestor folder named
    ``tasks``, ``specs``, ``demos``, ``models`` or ``certificates``; else the file's folder."""
    p = Path(os.path.abspath(path))
    for parent in p.parents:
        if parent.name in FOLDERS:
            return _shown(parent.parent)
    return _shown(p.parent)


def _shown(p: Path) -> Path:
    """Relative to the working directory when under it (messages read ``models/x``)."""
    try:
        return p.relative_to(Path.cwd())
    except ValueError:
        return p


@dataclass(frozen=True, slots=True)
class ModelFiles:
    """Where a model's certificate and campaign evidence live (the one rule).

    Attributes
    ----------
    root : Path
        The model's project folder.
    certificate : Path
    evidence : Path
    """

    root: Path
    certificate: Path
    evidence: Path


def model_files(model: str | os.PathLike[str]) -> ModelFiles:
    """The certificate and evidence paths of a model (module docstring).

    Parameters
    ----------
    model : path-like

    Returns
    -------
    ModelFiles
    """
    mpath = Path(model)
    stem = model_stem(mpath)
    absolute = Path(os.path.abspath(mpath))
    for parent in absolute.parents:
        if parent.name == "models":
            sub = absolute.parent.relative_to(parent)
            root = _shown(parent.parent)
            base = root / "certificates" / sub
            return ModelFiles(root=root, certificate=base / (stem + CERTIFICATE_SUFFIX),
                              evidence=base / (stem + EVIDENCE_SUFFIX))
    return ModelFiles(root=mpath.parent, certificate=mpath.parent / (stem + CERTIFICATE_SUFFIX),
                      evidence=mpath.parent / (stem + EVIDENCE_SUFFIX))


@dataclass(frozen=True, slots=True, eq=False)
class Resolved:
    """Every file of one closed-loop run, and the task it runs on.

    Attributes
    ----------
    task : Task
    spec : Path
    model : Path
    certificate : Path
    evidence : Path
        Where the model's campaign evidence lives (it may not exist yet).
    goal : Goal
        The spec's, else the task's goal.
    spec_task : Task or None
        The task the spec names (None if it names none); the gate binds evidence to it.
    """

    task: Task
    spec: Path
    model: Path
    certificate: Path
    evidence: Path
    goal: Goal
    spec_task: Task | None

    @property
    def inputs(self) -> tuple[Path, ...]:
        """Every file a run reads: the spec, the model, the certificate, the task file."""
        out = [self.spec, self.model, self.certificate]
        if self.task.source.path is not None:
            out.append(Path(self.task.source.path))
        return tuple(out)


def spec_task(spec: Any, spec_path: str | os.PathLike[str]) -> Task | None:
    """The task a loaded spec names (its ``task`` key), or None.

    Raises
    ------
    TaskError
        (exit 2) The named task cannot be found or does not load.
    """
    ref = getattr(spec, "task", None)
    if ref is None:
        return None
    if ref.endswith(".toml") or "/" in ref:
        return find_task(Path(spec_path).parent / ref)
    try:
        return find_task(ref, project=project_root(spec_path))
    except TaskError as exc:
        raise TaskError(f"{spec_path}: task = {ref!r}: {exc}") from None


def pose_blocks(spec_path: str | os.PathLike[str] | None) -> tuple[tuple[int, ...], ...]:
    """The coupling the learner (:func:`tli_verify.api.learn`, ``tli learn``) keeps out of a
    pose task's ``A_k``: the orientation coordinates as one group (``((3, 4, 5),)`` for
    ``orientation.start = 3``), or none without a spec, when the spec names no task or when
    its task has no orientation.

    Why decoupled. An LPV-DS fits ``xdot = sum_k gamma_k(x) A_k (x - x*)`` by least squares.
    Along a demonstration the orientation often barely moves within a mode while the position
    sweeps: ``rx - rx*`` is then nearly a constant offset, and a free ``A_k`` uses it as a
    bias for the position's velocity. On the Franka scoop's pour that made the position's
    velocity depend on the roll by 3.3 dm/s per rad: a 0.1 rad roll at the pour's entry sent
    the tray 1.2 dm past the target bowl, and in a widened workspace the pour left its mode 41
    times. With the orientation apart in each ``A_k`` (the anchor's SE(3) LPV-DS learns
    position and orientation as two systems) it left it never, and the held-out trials went
    from 8/10 to 10/10 (``docs/howto/franka.md``, "The pose DS", measures this against roll and
    yaw apart only, ``--blocks 3,5``).
    The mixing weights ``gamma_k`` still see the whole pose, ``P`` stays full, and the
    certificate is the same statement: each ``A_k`` with the one ``P``.
    """
    if spec_path is None:
        return ()
    task = spec_task(load_spec(spec_path), spec_path)
    chart = None if task is None else task.orientation
    return () if chart is None else (tuple(range(chart.start, chart.start + 3)),)


def spec_state_names(spec_path: str | os.PathLike[str] | None) -> tuple[str, ...] | None:
    """The state coordinates' names of the task a spec names (``[state] names``), or None
    without a spec or when the spec names no task: what a model learned for that spec calls
    its coordinates (:func:`tli_verify.model.learn.learn_model`)."""
    if spec_path is None:
        return None
    task = spec_task(load_spec(spec_path), spec_path)
    return None if task is None else tuple(task.state_names)


def spec_inputs(spec: str | os.PathLike[str] | None) -> list[Path]:
    """The files a spec implies: the spec itself and the task file it names (when that task
    is a file). What every writer that reads the spec must not overwrite (the read/write rule,
    :func:`tli_verify.io.check_plan`).

    Parameters
    ----------
    spec : path-like or None

    Returns
    -------
    list of Path
        Empty for None. A spec that does not load, or names a task that does not, implies only
        itself (the error comes from the work that reads it).
    """
    if spec is None:
        return []

    found = [Path(spec)]
    try:
        task = spec_task(load_spec(spec), spec)
    except TliError:
        return found
    if task is not None and task.source.path is not None:
        found.append(Path(task.source.path))
    return found


def model_inputs(model: str | os.PathLike[str] | None, spec: Any = None) -> list[Path]:
    """The files a model file implies: itself, its spec (``spec``, or the one it names), the
    spec's task file, and the certificate and evidence the project layout puts next to it.

    Parameters
    ----------
    model : path-like or None
        A model file (None: only the spec's files).
    spec : path-like, optional
        The model's spec when it is known already (a model that was never saved).

    Returns
    -------
    list of Path
    """
    found: list[Path] = []
    if model is not None:
        found.append(Path(model))
        files = model_files(model)
        found += [files.certificate, files.evidence]
        if spec is None and Path(model).is_file():

            try:
                spec = load_model(model).spec_path
            except TliError:
                spec = None
    return found + spec_inputs(spec)


def resolve(*, task: str | os.PathLike[str] | Task | None = None,
            spec: str | os.PathLike[str] | None = None,
            model: str | os.PathLike[str] | None = None,
            certificate: str | os.PathLike[str] | None = None,
            lag: int | None = None) -> Resolved:
    """Resolve a run's files by the project rules (module docstring).

    Parameters
    ----------
    task : str, path-like or Task, optional
        A task name or file (``--task``), or a loaded task.
    spec, model, certificate : path-like, optional
        Files given on the command line.
    lag : int, optional
        Override the task's sensor lag.

    Returns
    -------
    Resolved

    Raises
    ------
    TaskError
        (exit 2) One line naming what is missing or does not fit: no task, spec or model to
        start from; a spec that is not the one the model names; a missing file; a model whose
        dimension, or a spec whose inputs, differ from the task's (:func:`check_fit`).
    """
    loaded: Task | None = None
    if isinstance(task, Task):
        loaded = task
    elif task is not None:  # a name: the project of the spec or model first, else this folder
        anchor = spec if spec is not None else model
        loaded = find_task(task, project=project_root(anchor) if anchor is not None
                           else Path.cwd())
    spec_path = Path(spec) if spec is not None else None
    model_path = Path(model) if model is not None else None
    if model_path is None and spec_path is None:
        if loaded is None:
            raise TaskError("nothing to run: give --task, --spec or --model")
        spec_path = loaded.spec_path
        if spec_path is None:
            raise TaskError(f"{loaded.where}: the task names no default spec (spec = "
                            "\"...\"): pass --spec or --model")
    model_doc = None
    if model_path is not None:
        if not model_path.is_file():
            raise TaskError(f"{model_path}: no such model file")
        model_doc = load_model(model_path)
        named = model_doc.spec_path
        if named is None and spec_path is None:
            raise TaskError(f"{model_path}: the model names no spec: pass --spec (and learn "
                            "with --spec so the model is bound to it)")
        if named is not None:
            if spec_path is not None and os.path.realpath(spec_path) != os.path.realpath(named):
                raise TaskError(f"--spec {spec_path}: not the spec the model names ({named}); "
                                "its certificate binds that one")
            spec_path = Path(_shown(Path(named)))
    assert spec_path is not None
    if not spec_path.is_file():
        raise TaskError(f"{spec_path}: no such spec file")
    spec_doc = load_spec(spec_path)
    if model_path is None:
        model_path = project_root(spec_path) / "models" / (spec_path.stem + MODEL_SUFFIX)
        if not model_path.is_file():
            raise TaskError(f"{model_path}: no such model file (the model of {spec_path} by "
                            "the project layout; pass --model)")
    named_task = spec_task(spec_doc, spec_path)
    if loaded is None:
        loaded = named_task
    if loaded is None:
        raise TaskError(f"{spec_path}: the spec names no task (add task = \"NAME\"): pass "
                        "--task")
    if lag is not None:
        loaded = loaded.with_lag(lag)
    files = model_files(model_path)
    cert_path = Path(certificate) if certificate is not None else files.certificate
    if not cert_path.is_file():
        raise TaskError(f"{cert_path}: no such certificate file"
                        + ("" if certificate is not None else
                           f" (the certificate of {model_path} by the project layout; run "
                           f"tli certify {model_path}, or pass --certificate)"))
    goal = goal_of(spec_doc, loaded)
    resolved = Resolved(task=loaded, spec=spec_path, model=model_path, certificate=cert_path,
                        evidence=files.evidence, goal=goal, spec_task=named_task)
    check_fit(resolved, spec_doc, model_doc if model_doc is not None else load_model(model_path))
    return resolved


def check_goal(automaton: TaskAutomaton, goal: Goal, *, where: str) -> tuple[str, ...]:
    """The goal modes, checked: every mode the automaton can run reaches one of them.

    Returns
    -------
    tuple of str
        The goal modes (the sink modes when the goal names none).

    Raises
    ------
    TaskError
        (exit 2) A goal mode the automaton never runs, a goal with no mode (no sink and none
        named), or a mode from which the mode graph cannot reach the goal.
    """
    run = sorted({s.mode for s in automaton.states})
    modes = tuple(automaton.sink_modes()) if goal.modes is None else tuple(goal.modes)
    if not modes:
        raise TaskError(f"{where}: the automaton {automaton.name!r} has no sink mode, so an "
                        "episode never ends: name the goal ([goal] modes = [...] in the spec "
                        "or the task)")
    absent = [m for m in modes if m not in run]
    if absent:
        raise TaskError(f"{where}: goal mode {absent[0]!r} is never run by the automaton "
                        f"{automaton.name!r} (it runs {', '.join(run)})")
    dist = automaton.mode_distances(list(modes))
    stuck = [m for m in run if m not in dist]
    if stuck:
        raise TaskError(f"{where}: the automaton {automaton.name!r} cannot reach the goal "
                        f"({', '.join(modes)}) from mode {stuck[0]!r}: no path in its mode "
                        "graph, so no episode from there can succeed")
    return modes


def goal_of(spec: GR1Spec, task: Task) -> Goal:
    """The goal rule: the spec's ``[goal]``, else the task's ``[goal]`` (else, later, the
    automaton's sink modes: :func:`check_goal`)."""
    if spec.goal_modes is not None or spec.goal_sensors:
        return Goal(spec.goal_modes, spec.goal_sensors)
    return task.goal


def check_fit(resolved: Resolved, spec: Any, model: Any) -> None:
    """Refuse a model, spec or goal that does not fit the task (before any work).

    Raises
    ------
    TaskError
        (exit 2) The model's dimension differs from the task's; the spec's inputs are not the
        task's sensors; a goal mode is not a mode of the spec or a goal sensor not an input.
    """
    task = resolved.task
    if model.dim != task.dim:
        raise TaskError(f"{resolved.model}: a {model.dim}-D model, but task {task.name!r} "
                        f"({task.where}) has a {task.dim}-D state")
    if set(spec.inputs) != set(task.sensor_names):
        missing = sorted(set(spec.inputs) - set(task.sensor_names))
        extra = sorted(set(task.sensor_names) - set(spec.inputs))
        what = (f"the task has no sensor {missing[0]!r}" if missing
                else f"the task's sensor {extra[0]!r} is not an input of the spec")
        raise TaskError(f"{resolved.spec}: its inputs ({', '.join(spec.inputs)}) are not the "
                        f"sensors of task {task.name!r} ({', '.join(task.sensor_names)}): "
                        f"{what}")
    modes = set(spec.mode_names)
    if resolved.goal.modes is not None:
        bad = [m for m in resolved.goal.modes if m not in modes]
        if bad:
            raise TaskError(f"{task.where}: goal.modes: {bad[0]!r} is not a mode of "
                            f"{resolved.spec} ({', '.join(spec.mode_names)})")
