"""The public Python API: the pipeline with objects as well as paths.

The command line works on files; these functions take the same files *or* the objects the
library returns, so a pipeline runs from Python without writing anything until the user asks::

    import tli_verify as tli

    spec = tli.load_spec("specs/drawer.toml")
    demos = tli.find_task("tasks/drawer.toml").demonstrate(seed=0)      # in memory
    model = tli.learn(demos, spec=spec)                                  # a Model
    cert = tli.certify(model)                                            # a Certificate
    assert cert.ok
    policy = tli.make_policy(spec, model, cert)                          # certified executive
    episode = tli.run(policy, task="tasks/drawer.toml", start=[-0.6, 0, 0])

A certificate binds the exact bytes of a model *file* (paper eq. 5 is re-checked exactly on
what is deployed): :func:`certify` of a model that was never saved writes it, with its spec
path, into a private temporary folder the :class:`Certificate` keeps alive; :meth:`Certificate.
save` writes the pair where you want it (re-issued for the saved model's bytes).

Every function that writes keeps the command line's read/write rule
(:func:`tli_verify.io.check_plan`, ``docs/reference/limits.md``): before any work it refuses
an output that is one of the files it reads -- named (a demonstration, a model), or implied
(the spec a model names, the task that spec names, the certificate and evidence the project
layout puts next to a model) -- or another of its outputs, with an
:class:`~tli_verify.errors.OutputError` (an ``InputError``, so a ``ValueError``). Arguments are
checked at the boundary: a wrong type is an ``InputError`` that is also a ``TypeError``, a
value out of range one that is a ``ValueError``; each names the parameter.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022: eq. 3 (the GR(1) spec), eq. 5 (the Lyapunov
conditions a certificate proves), eq. 6 (the executive), Sec. 4.4 (campaigns).
"""

from __future__ import annotations

import functools
import os
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy.typing as npt

from tli_verify.arguments import (
    check_choice,
    check_int,
    check_path,
    check_type,
)
from tli_verify.demos import Demonstration, demo_to_csv
from tli_verify.errors import (
    CertificateError,
    DemoError,
    ModelError,
    SpecError,
    TaskError,
    bad_argument,
    bad_input,
    bad_type,
)
from tli_verify.io import atomic_write_text, canonical_json, check_plan
from tli_verify.limits import MAX_SEED
from tli_verify.loaded import LoadedProject, run_policy
from tli_verify.logic.automaton import TaskAutomaton
from tli_verify.logic.spec import GR1Spec, load_spec
from tli_verify.model.learn import learn_model
from tli_verify.model.serialize import IN_MEMORY, load_model, model_to_dict, relocate_model
from tli_verify.model.serialize import save_model as _save
from tli_verify.model.types import Model
from tli_verify.project import control_period
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.handoff import context_for_spec, learn_handoffs
from tli_verify.runtime.setup import VARIANTS, check_goal
from tli_verify.snapshot import active, current
from tli_verify.tasks.project import (
    model_files,
    pose_blocks,
    resolve,
    spec_inputs,
    spec_state_names,
    spec_task,
)
from tli_verify.tasks.registry import find_task
from tli_verify.tasks.task import Task

if TYPE_CHECKING:
    from tli_verify.certification.certificate import CertCheck
    from tli_verify.ds.lpvds import Clustering, LyapunovKind
    from tli_verify.runtime.loop import EpisodeResult

__all__ = ["Certificate", "certify", "learn", "make_policy", "run", "save_model"]

PathLike = str | os.PathLike[str]
F = TypeVar("F", bound=Callable[..., object])


def _in_snapshot(fn: F) -> F:
    """Run a public function inside a snapshot (:mod:`tli_verify.snapshot`): each file it
    reads is read once, and hashed and parsed from the same bytes."""
    @functools.wraps(fn)
    def inner(*args: object, **kwargs: object) -> object:
        with active():
            return fn(*args, **kwargs)

    return inner  # type: ignore[return-value]


def _spec_path(spec: Any) -> Path | None:
    if spec is None:
        return None
    if isinstance(spec, str | os.PathLike):
        return check_path(spec, "spec", error=SpecError)

    if not isinstance(spec, GR1Spec):
        raise bad_type(SpecError, f"spec: expected a path or a GR1Spec, got "
                       f"{type(spec).__name__}")
    path = getattr(spec, "path", None)
    if path is None:
        raise bad_input(SpecError, "spec: a GR1Spec loaded from a file is needed (the model "
                        "and its certificate bind the spec file); use load_spec(path)")
    return Path(path)


def _spec_inputs(spec: Path | None) -> list[Path]:

    return spec_inputs(spec)


@_in_snapshot
def learn(demos: Sequence[PathLike | Demonstration], *, spec: PathLike | GR1Spec | None = None,
          seed: int = 0, out: PathLike | None = None, handoff: bool = True,
          handoff_samples: int = 1000, eps: float = 1e-3, rate: float | None = None,
          rate_budget: float | None = 0.03, control_dt: float | Fraction | None = None,
          clustering: Clustering = "pc-gmm", lyapunov: LyapunovKind = "p-qlf",
          blocks: Sequence[Sequence[int]] | None = None) -> Model:
    """Learn a certified-stable LPV-DS per mode from demonstrations (``tli learn``).

    Parameters
    ----------
    demos : sequence of path-like or Demonstration
        CSV files, or :class:`~tli_verify.demos.Demonstration` objects (e.g. a task's
        :meth:`~tli_verify.tasks.task.Task.demonstrate`).
    spec : path-like or GR1Spec, optional
        The spec whose ``[modes]`` labels segment the demonstrations (paper Sec. 3).
    seed : int, optional
    out : path-like, optional
        Also save the model there (atomically).
    handoff : bool, optional
        Where the spec's task declares its regions, find every mode's exits offline, cut them
        and record the hand-off claims in the model (``tli learn``'s default;
        :func:`tli_verify.runtime.handoff.learn_handoffs`, docs/explanation/handoff).
    handoff_samples : int, optional
        States drawn per DS in each round of that step.
    eps, rate, rate_budget, clustering, lyapunov : optional
        As :func:`tli_verify.model.learn.learn_model` (``tli learn --eps --rate --rate-budget
        --baseline``).
    control_dt : float or Fraction, optional
        The period of the sampled-data constraint (default: the spec's task's, else
        :data:`~tli_verify.defaults.DEFAULT_DT`: :func:`tli_verify.project.control_period`).
    blocks : sequence of sequence of int, optional
        Groups of coordinates every ``A_k`` keeps decoupled (``tli learn --blocks``; see
        :func:`tli_verify.ds.lpvds.learn_lpvds`); ``[]``: every entry free. Default (None):
        for a pose task (the spec's task declares ``[state] orientation``) its orientation
        coordinates, position and orientation decoupled
        (:func:`tli_verify.tasks.project.pose_blocks` says why); else none.

    Returns
    -------
    Model
    """
    if isinstance(demos, str | bytes | os.PathLike) or not isinstance(demos, Sequence):
        raise bad_type(DemoError, f"demos: expected a sequence of demonstration files or "
                       f"Demonstration objects, got {type(demos).__name__}")
    if not demos:
        raise bad_input(DemoError, "demos: no demonstrations given")
    given: list[Demonstration | Path] = [
        d if isinstance(d, Demonstration) else check_path(d, f"demos[{i}]", error=DemoError)
        for i, d in enumerate(demos)]
    spec_path = _spec_path(spec)
    seed = check_int(seed, "seed", 0, MAX_SEED)
    if out is not None:  # the read/write rule, before any work
        out = check_path(out, "out", error=ModelError)
        check_plan(inputs=[*(d for d in given if isinstance(d, Path)),
                           *_spec_inputs(spec_path)], outputs=[(out, "model")])
    with tempfile.TemporaryDirectory(prefix="tli-learn-") as tmp:
        paths: list[Path] = []
        for i, d in enumerate(given):
            if isinstance(d, Demonstration):
                p = Path(tmp) / f"demo_{i + 1}.csv"
                atomic_write_text(p, demo_to_csv(d))
                paths.append(p)
            else:
                paths.append(d)
        target = Path(out) if out is not None else Path(tmp) / "model.json"
        dt = float(control_period(control_dt, spec_path))
        groups = pose_blocks(spec_path) if blocks is None else _blocks(blocks)
        model = learn_model(paths, out_path=target, spec_path=spec_path, seed=seed, eps=eps,
                            rate=rate, rate_budget=rate_budget, control_dt=dt,
                            clustering=clustering, lyapunov=lyapunov, blocks=groups,
                            state_names=spec_state_names(spec_path))
        if handoff and spec_path is not None:

            ctx = context_for_spec(spec_path)
            if ctx is not None:
                model = learn_handoffs(ctx.task, ctx.automaton, model, dt=dt,
                                       goal_modes=ctx.goal_modes, samples=handoff_samples,
                                       seed=seed).model
        if out is not None:
            save_model(model, out)

            return load_model(out)
        return _in_memory(model, paths, Path(tmp), spec_path)


def _blocks(blocks: object) -> tuple[tuple[int, ...], ...]:
    """``learn``'s ``blocks`` argument, checked for type (the dimension is checked by the
    learner)."""
    if isinstance(blocks, str | bytes) or not isinstance(blocks, Sequence) or not all(
            isinstance(g, Sequence) and not isinstance(g, str | bytes)
            and all(isinstance(c, int) and not isinstance(c, bool) for c in g)
            for g in blocks):
        raise bad_type(ModelError, "blocks: expected a sequence of groups of coordinate "
                       f"indices, e.g. [[3, 5]], got {blocks!r}")
    return tuple(tuple(int(c) for c in g) for g in blocks)


def _in_memory(model: Model, paths: Sequence[Path], tmp: Path, spec_path: Path | None
               ) -> Model:
    """A learned model that has no file: its spec path absolute, and the demonstrations that
    were objects recorded as ``in-memory:demo_<i>`` (their SHA-256 kept), so nothing points
    into the deleted temporary folder."""
    import dataclasses
    import json
    from types import MappingProxyType

    source = json.loads(json.dumps(dict(model.source or {})))
    for i, (demo, p) in enumerate(zip(source.get("demos") or [], paths, strict=True)):
        demo["path"] = (f"{IN_MEMORY}demo_{i + 1}" if p.parent == tmp
                        else str(p.resolve()))
    return dataclasses.replace(
        model, path=None, source=MappingProxyType(source),
        spec=None if spec_path is None else str(spec_path.resolve()))


@_in_snapshot
def save_model(model: Model, path: PathLike) -> Model:
    """Write a model where you want it (relative paths inside rewritten for its folder);
    return the model as loaded from there (its ``path`` set).

    Parameters
    ----------
    model : Model
    path : path-like

    Returns
    -------
    Model
    """
    check_type(model, "model", Model, "a Model (tli_verify.learn, load_model)",
               error=ModelError)
    target = check_path(path, "path", error=ModelError)
    check_plan(inputs=_model_reads(model, IN_MEMORY), outputs=[(target, "model")])
    _save(relocate_model(model, target), target)
    return load_model(target)


def _model_reads(model: Model, in_memory: str) -> list[Path]:
    """What a model object implies, for the read/write rule: its spec and the spec's task,
    the demonstrations it was learned from, and the certificate and evidence next to its
    file (not the file itself: saving a model over its own file rewrites it)."""
    reads = _spec_inputs(model.spec_path)
    base = Path(model.path).parent if model.path else Path(".")
    for demo in (model.source or {}).get("demos") or ():
        p = str(demo.get("path", "")) if hasattr(demo, "get") else ""
        if p and not p.startswith(in_memory):
            reads.append(base / p)
    if model.path is not None:
        files = model_files(model.path)
        reads += [files.certificate, files.evidence]
    return reads


@dataclass(frozen=True, eq=False)
class Certificate:
    """A certificate of a model file: the document, the files it binds, and its exact check.

    Attributes
    ----------
    doc : dict
        The certificate document (JSON: schema ``tli_verify/schemas/certificate.schema.json``).
    path : Path
        The certificate file (a temporary one for an unsaved model, see the module docstring).
    model_path : Path
        The model file it covers.
    """

    doc: dict[str, Any]
    path: Path
    model_path: Path
    _tmp: Path | None = field(default=None, repr=False)

    @property
    def dt(self) -> Fraction:
        """The control period it proves (exact)."""
        return Fraction(str(self.doc["control_period"]["dt"]))

    @property
    def ok(self) -> bool:
        """Whether it re-checks exactly now (:func:`tli_verify.certification.certificate.
        check_certificate`: digest, hashes, P, the Lyapunov and sampled-data conditions)."""
        return bool(self.check().ok)

    def check(self) -> CertCheck:
        """The exact re-check (a :class:`~tli_verify.certification.certificate.CertCheck`)."""
        from tli_verify.certification.certificate import check_certificate

        return check_certificate(self.path)

    def to_dict(self) -> dict[str, Any]:
        """The certificate document."""
        return dict(self.doc)

    def save(self, path: PathLike, *, model: PathLike | None = None) -> Certificate:
        """Write the certificate (and, with ``model``, the model it covers) to files.

        Parameters
        ----------
        path : path-like
            The certificate file.
        model : path-like, optional
            Where to write the model first (an unsaved model must be saved somewhere: the
            certificate binds its file's bytes); default: the model file it covers now.

        Returns
        -------
        Certificate
            Re-issued for the files written.
        """
        target = check_path(path, "path", error=CertificateError)
        mpath = Path(self.model_path)
        current = load_model(mpath)
        reads = [mpath, *_spec_inputs(current.spec_path)]
        if model is not None:
            mpath = check_path(model, "model", error=ModelError)
            check_plan(inputs=reads, outputs=[(mpath, "model"), (target, "certificate")])
            save_model(current, mpath)
        else:
            check_plan(inputs=reads, outputs=[(target, "certificate")])
        return certify(mpath, dt=self.dt, out=target)


@_in_snapshot
def certify(model: Model | PathLike, *, dt: Fraction | str | None = None,
            out: PathLike | None = None) -> Certificate:
    """Prove a model's Lyapunov conditions exactly and issue its certificate (``tli certify``).

    Parameters
    ----------
    model : Model or path-like
        A model object (saved or not) or a model file.
    dt : Fraction or str, optional
        The control period the sampled-data conditions hold at (default: the control period
        of the task the model's spec names, else 1/100 s: :func:`tli_verify.project.
        control_period`).
    out : path-like, optional
        Write the certificate there (default: kept with the model: a temporary file for an
        unsaved model).

    Returns
    -------
    Certificate

    Raises
    ------
    CertificateError
        A DS does not certify with the model's own P (naming the mode and the condition).
    """
    from tli_verify.certification.certificate import issue_certificate, write_certificate

    if not isinstance(model, Model):
        model = check_path(model, "model", error=ModelError)
    if out is not None:
        out = check_path(out, "out", error=CertificateError)
    if dt is not None:
        dt = _check_dt(dt)
    tmp: Path | None = None
    if isinstance(model, Model):
        if model.path is not None and Path(model.path).is_file() and \
                load_model(model.path).modes.keys() == model.modes.keys() and \
                _same_bytes(model, Path(model.path)):
            mpath = Path(model.path)
        else:
            tmp = Path(tempfile.mkdtemp(prefix="tli-certify-"))
            mpath = tmp / "model.json"
            save_model(model, mpath)
    else:
        mpath = Path(model)
    dt = control_period(dt, load_model(mpath).spec_path)
    if out is not None:
        cpath = Path(out)
    elif tmp is not None:
        cpath = tmp / "model.cert.json"
    else:

        cpath = model_files(mpath).certificate
    # the read/write rule, before any work: the certificate is none of the files it binds
    check_plan(inputs=[mpath, *_spec_inputs(load_model(mpath).spec_path)],
               outputs=[(cpath, "certificate")])
    doc = issue_certificate(mpath, cert_path=cpath, dt=dt)
    write_certificate(doc, cpath)
    cert = Certificate(doc=doc, path=cpath, model_path=mpath, _tmp=tmp)
    if tmp is not None:  # the private folder lives as long as the certificate object
        import shutil
        import weakref

        weakref.finalize(cert, shutil.rmtree, tmp, True)
    return cert


def _check_dt(dt: Any) -> Fraction:
    """``dt`` as a positive Fraction (``certify(dt=...)``)."""
    if isinstance(dt, bool) or not isinstance(dt, Fraction | str | int | float):
        raise bad_type(CertificateError, f"dt: expected a Fraction or a decimal string, got "
                       f"{type(dt).__name__}")
    try:
        value = Fraction(repr(dt)) if isinstance(dt, float) else Fraction(dt)
    except (ValueError, ZeroDivisionError, OverflowError):
        raise bad_argument(CertificateError, f"dt: {dt!r} is not a number") from None
    if value <= 0:
        raise bad_argument(CertificateError, f"dt: the control period must be > 0, got {dt!r}")
    return value


def _same_bytes(model: Any, path: Path) -> bool:
    """Whether the model object is the file's content (cuts learned in memory make it not)."""
    return canonical_json(model_to_dict(relocate_model(model, path))) == \
        path.read_text(encoding="utf-8")


@_in_snapshot
def make_policy(spec: PathLike | GR1Spec | TaskAutomaton, model: Model | PathLike,
                certificate: Certificate | PathLike, *, task: Task | PathLike | None = None,
                variant: str = "LTL-DS") -> LTLDSPolicy:
    """The certified LTL-DS executive (paper eq. 6) of a spec, model and certificate.

    Parameters
    ----------
    spec : path-like, GR1Spec or TaskAutomaton
        The spec (its automaton is synthesized) or the automaton itself.
    model : Model or path-like
    certificate : Certificate or path-like
        It must cover the model exactly (the executive refuses one that does not).
    task : Task, path-like or str, optional
        Its goal and control period (default: the task the spec names).
    variant : str, optional
        ``"LTL-DS"``, ``"no-modulation"`` or ``"no-replan"`` (the paper's ablations).

    Returns
    -------
    LTLDSPolicy

    Raises
    ------
    CertificateError
        The certificate does not cover the model (also a ValueError when the model was never
        saved).
    """
    variant = check_choice(variant, "variant", VARIANTS)
    cpath = certificate.path if isinstance(certificate, Certificate) else check_path(
        certificate, "certificate", error=CertificateError)
    if not isinstance(model, Model):
        model = check_path(model, "model", error=ModelError)
    if not isinstance(spec, TaskAutomaton | str | os.PathLike):

        check_type(spec, "spec", GR1Spec, "a path, a GR1Spec or a TaskAutomaton",
                   error=SpecError)
    if isinstance(model, Model):
        if model.path is None and isinstance(certificate, Certificate):
            model = load_model(certificate.model_path)
        elif model.path is None:
            raise bad_input(CertificateError, "the model was never saved: certify(model) "
                            "first (a certificate binds a model file)")
    else:
        model = load_model(model)
    spec_file = model.spec_path
    if spec_file is None:
        raise bad_input(ModelError, "the model names no spec: learn it with spec=...")
    snap = current()
    assert snap is not None  # @_in_snapshot
    project = LoadedProject(
        files=resolve(task=task, spec=spec_file, model=model.path, certificate=cpath),
        spec=spec if isinstance(spec, GR1Spec) else load_spec(spec_file), model=model,
        snapshot=snap)
    if not isinstance(spec, TaskAutomaton):
        return project.policy(variant)  # synthesized, its goal checked reachable
    check_goal(spec, project.goal, where=str(spec_file))
    return project.policy(variant, automaton=spec)


@_in_snapshot
def run(policy: LTLDSPolicy, *, task: Task | PathLike | None = None,
        start: npt.ArrayLike | None = None,
        perturbations: Mapping[int, npt.ArrayLike] | None = None, steps: int = 3000,
        seed: int = 0) -> EpisodeResult:
    """One closed-loop episode of a policy on its task (``tli run``).

    Parameters
    ----------
    policy : LTLDSPolicy
        From :func:`make_policy`.
    task : Task, path-like or str, optional
        Default: the task of the policy's spec.
    start : array_like, shape (n,), optional
        Default: the task's first nominal start, else a seeded random state whose reading is
        an initial one of the spec (as ``tli run``).
    perturbations : mapping of int to array_like, optional
        ``{step: displacement}`` (each shape (n,)).
    steps : int, optional
    seed : int, optional

    Returns
    -------
    EpisodeResult
    """
    check_type(policy, "policy", LTLDSPolicy, "an LTLDSPolicy (make_policy)", error=TaskError)
    found: Task | None
    if isinstance(task, Task):
        found = task
    elif task is not None:
        if not isinstance(task, str | os.PathLike):
            raise bad_type(TaskError, f"task: expected a Task, a task name or a task file, "
                           f"got {type(task).__name__}")
        found = find_task(task)
    else:

        spec = policy.model.spec_path
        found = spec_task(load_spec(spec), spec) if spec is not None else None
        if found is None:
            raise bad_input(TaskError, "run: the policy's spec names no task: pass task=...")
    return run_policy(policy, found, start=start, perturbations=perturbations, steps=steps,
                      seed=seed)
