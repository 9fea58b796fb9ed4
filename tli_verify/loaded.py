"""A project's files, found once, read once, loaded once: :class:`LoadedProject`.

:func:`load_project` is the one entry from "a folder, a task, a spec or a model" to the loaded
objects every layer above runs on. It applies the project resolver's rules
(:func:`tli_verify.tasks.project.resolve`: model -> spec -> task -> certificate, evidence,
goal), reads each file once inside a snapshot (:mod:`tli_verify.snapshot`: hashes and parsers
see the same bytes) and returns a frozen :class:`LoadedProject`; the spec's automaton is
synthesized once, on first use, and its goal checked reachable. Its methods
(:meth:`LoadedProject.policy`, :meth:`LoadedProject.run`,
:meth:`LoadedProject.check_certificate`) run inside the same snapshot.

This is the session's core, low enough in the layers for the campaign workers
(:func:`tli_verify.verify.simulate.load`) and the Franka loop
(:func:`tli_verify.sim.franka_project.load_policy`) to load through it;
:class:`tli_verify.project.Session` adds the campaigns (kinematic and physical) on top.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Self

import numpy as np
import numpy.typing as npt

from tli_verify.arguments import check_int, check_vector
from tli_verify.defaults import Stream, rng
from tli_verify.errors import TaskError, TliError, bad_input, bad_type
from tli_verify.io import parse_toml, read_text
from tli_verify.limits import MAX_CAMPAIGN_STEPS, MAX_SEED
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import load_spec
from tli_verify.model.serialize import load_model
from tli_verify.runtime.coverage import check_coverage
from tli_verify.runtime.episodes import pusher, random_start
from tli_verify.runtime.loop import run_episode
from tli_verify.runtime.setup import Setup, make_policy
from tli_verify.runtime.task_sensors import TaskSensors
from tli_verify.snapshot import Snapshot, current
from tli_verify.tasks.project import check_goal, project_root, resolve

if TYPE_CHECKING:
    from tli_verify.certification.certificate import CertCheck
    from tli_verify.logic.automaton import TaskAutomaton
    from tli_verify.logic.spec import GR1Spec
    from tli_verify.model.types import Model
    from tli_verify.runtime.executive import LTLDSPolicy
    from tli_verify.runtime.loop import EpisodeResult
    from tli_verify.tasks.project import Resolved
    from tli_verify.tasks.task import Goal, Task

__all__ = ["LoadedProject", "load_project", "locate", "run_policy"]

PathLike = str | os.PathLike[str]


@dataclass(frozen=True, eq=False)
class LoadedProject:
    """A project's files, loaded once and settled (:func:`load_project`); its attributes are
    documented on the public subclass, :class:`tli_verify.project.Session`.
    """

    files: Resolved
    spec: GR1Spec
    model: Model
    snapshot: Snapshot

    @cached_property
    def automaton(self) -> TaskAutomaton:
        """The task automaton synthesized from ``spec`` (paper eq. 3, Sec. 4.1), once, on first
        use (a command checks its outputs before this work); its goal checked reachable.

        Raises
        ------
        TaskError
            (exit 2) The goal is not reachable in the automaton.
        """
        automaton = synthesize(self.spec)
        check_goal(automaton, self.files.goal, where=str(self.files.spec))
        return automaton

    @property
    def task(self) -> Task:
        """The task the session runs on (its sensors, regions, workspace, starts)."""
        return self.files.task

    @property
    def goal(self) -> Goal:
        """The spec's goal, else the task's (settled once)."""
        return self.files.goal

    @property
    def setup(self) -> Setup:
        """What a closed-loop episode runs (:class:`~tli_verify.runtime.setup.Setup`)."""
        return self.setup_with(self.automaton)

    def setup_with(self, automaton: TaskAutomaton) -> Setup:
        """:attr:`setup` with another automaton of the same task (one the caller synthesized
        or grew; the session's own is then never synthesized)."""
        return Setup(task=self.task, automaton=automaton, model=self.model,
                     certificate=str(self.files.certificate), goal=self.goal,
                     spec=str(self.files.spec))

    @property
    def control_period(self) -> Fraction:
        """The period the certificate proves and the policy runs at (the certificate's own).

        Raises
        ------
        CertificateError
            (exit 1) The certificate does not cover the model.
        """
        return self.check_certificate_covers()

    def check_certificate_covers(self) -> Fraction:
        """Refuse a certificate that does not cover the model; return its control period."""
        with self.snapshot.use():
            return check_coverage(self.model, self.files.certificate)

    def check_certificate(self) -> CertCheck:
        """Re-check the certificate exactly (paper eq. 5), as ``tli check-cert`` does."""
        from tli_verify.certification.certificate import check_certificate

        with self.snapshot.use():
            return check_certificate(self.files.certificate)

    def policy(self, variant: str = "LTL-DS", *,
               automaton: TaskAutomaton | None = None) -> LTLDSPolicy:
        """The executive of one variant (paper eq. 6; ``LTL-DS``, ``no-modulation``,
        ``no-replan``), certified: it refuses a certificate that does not cover the model.

        Parameters
        ----------
        variant : str, optional
        automaton : TaskAutomaton, optional
            Run another automaton of the same task (``tli run --learn-transitions``).
        """
        setup = self.setup if automaton is None else self.setup_with(automaton)
        with self.snapshot.use():
            return make_policy(setup, variant)

    def run(self, *, start: npt.ArrayLike | None = None,
            perturbations: Mapping[int, npt.ArrayLike] | None = None, steps: int = 3000,
            seed: int = 0, variant: str = "LTL-DS") -> EpisodeResult:
        """One closed-loop episode of a variant on the session's task (``tli run``;
        :func:`run_policy`)."""
        policy = self.policy(variant)
        with self.snapshot.use():
            return run_policy(policy, self.task, start=start, perturbations=perturbations,
                              steps=steps, seed=seed)

    @classmethod
    def open(cls, path: PathLike | None = None, *, task: PathLike | Task | None = None,
             spec: PathLike | None = None, model: PathLike | None = None,
             certificate: PathLike | None = None, lag: int | None = None) -> Self:
        """:func:`load_project` (``cls``'s instance: :class:`tli_verify.project.Session`
        opens with the same rule)."""
        snap = current() or Snapshot()  # inside a command's snapshot: the same bytes (they nest)
        with snap.use():
            if path is not None:
                kind, p, _ = locate(Path(os.path.abspath(path)),
                                    given_spec_or_model=spec is not None or model is not None)
                if kind == "model" and model is None:
                    model = p
                elif kind == "spec" and spec is None:
                    spec = p
                elif kind == "task" and task is None:
                    task = p
            files = resolve(task=task, spec=spec, model=model, certificate=certificate, lag=lag)
            return cls(files=files, spec=load_spec(files.spec),
                       model=load_model(files.model), snapshot=snap)


def run_policy(policy: LTLDSPolicy, task: Task, *, start: npt.ArrayLike | None = None,
               perturbations: Mapping[int, npt.ArrayLike] | None = None, steps: int = 3000,
               seed: int = 0) -> EpisodeResult:
    """One closed-loop episode of a policy on a task (``tli run``, :meth:`LoadedProject.run`,
    :func:`tli_verify.run`), its arguments checked at the boundary.

    Parameters
    ----------
    policy : LTLDSPolicy
        Forked: the caller's executive is left as it was.
    task : Task
    start : array_like, shape (n,), optional
        Default: the task's first nominal start, else a seeded random state (in the task's
        start region) whose reading is an initial one of the spec -- the rule ``tli run``
        follows.
    perturbations : mapping of int to array_like, optional
        ``{step: displacement}``, steps in ``[0, steps)``, displacements of shape (n,).
    steps : int, optional
    seed : int, optional
        Seed of the random start.

    Returns
    -------
    EpisodeResult

    Raises
    ------
    InputError
        (a TaskError; also a ValueError or TypeError) Naming the argument.
    """
    steps = check_int(steps, "steps", 1, MAX_CAMPAIGN_STEPS, error=TaskError)
    seed = check_int(seed, "seed", 0, MAX_SEED, error=TaskError)
    if start is not None:
        x0 = check_vector(start, "start", task.dim, error=TaskError)
        if not bool(task.in_workspace(x0[None])[0]):
            raise bad_input(TaskError, f"start: {x0.tolist()} lies outside the workspace of "
                            f"task {task.name!r}")
    elif task.starts.nominal:
        x0 = np.array(task.starts.nominal[0], dtype=np.float64)
    else:
        x0 = random_start(task, policy.automaton, rng(seed, Stream.START))
    if perturbations is not None and not isinstance(perturbations, Mapping):
        raise bad_type(TaskError, f"perturbations: expected a mapping step -> displacement, "
                       f"got {type(perturbations).__name__}")
    table = {}
    for step, d in (perturbations or {}).items():
        t = check_int(step, "perturbations (a step)", 0, steps - 1, error=TaskError)
        table[t] = check_vector(d, f"perturbations[{t}]", task.dim, error=TaskError)
    return run_episode(policy.fork(), TaskSensors(task), x0, steps=steps,
                       perturb=pusher(task, table))


def load_project(path: PathLike | None = None, *, task: PathLike | Task | None = None,
                 spec: PathLike | None = None, model: PathLike | None = None,
                 certificate: PathLike | None = None, lag: int | None = None
                 ) -> LoadedProject:
    """Load a project: the rule, the parameters and the errors of
    :func:`tli_verify.project.open_project` (the public entry, documented there), without the
    campaigns.

    Returns
    -------
    LoadedProject
    """
    return LoadedProject.open(path, task=task, spec=spec, model=model,
                              certificate=certificate, lag=lag)


_MARKERS = ("models", "specs", "tasks")
"""Folders that make a directory a project (``tli init`` writes them)."""


def locate(where: Path, *, given_spec_or_model: bool = False
           ) -> tuple[str | None, Path, Path]:
    """What one path names: ``(kind, file, project root)``.

    ``kind`` is ``"model"`` (a ``*.json`` file), ``"task"`` (a ``*.toml`` with a ``[state]``
    table), ``"spec"`` (another ``*.toml``), or None (a project folder whose spec or model is
    given otherwise). A folder -- the project that holds it or its nearest ancestor with a
    ``models/``, ``specs/`` or ``tasks/`` folder -- names its one model, else its one spec.

    Raises
    ------
    TaskError
        (exit 2) No such path; not in a project; several models, or no model and not exactly
        one spec.
    """
    if where.is_file() and where.suffix == ".json":
        return "model", where, Path(os.path.abspath(project_root(where)))
    if where.is_file() and where.suffix == ".toml":
        return _toml_kind(where), where, Path(os.path.abspath(project_root(where)))
    if not where.exists():
        raise TaskError(f"{where}: no such project folder or file")
    start = where if where.is_dir() else where.parent
    root = next((d for d in (start, *start.parents)
                 if any((d / m).is_dir() for m in _MARKERS)), None)
    if root is None:
        raise TaskError(f"{where}: not in a project (no models/, specs/ or tasks/ folder here "
                        "or above it): pass a model, spec or task")
    if given_spec_or_model:
        return None, root, root
    models = sorted((root / "models").glob("*.model.json"))
    if len(models) == 1:
        return "model", models[0], root
    if len(models) > 1:
        raise TaskError(f"{root}: {len(models)} models in models/ "
                        f"({', '.join(m.name for m in models[:6])}"
                        f"{', ...' if len(models) > 6 else ''}): pass model=")
    specs = sorted((root / "specs").glob("*.toml"))
    if len(specs) == 1:
        return "spec", specs[0], root
    raise TaskError(f"{root}: no model in models/ and {len(specs)} specs in specs/: pass "
                    "model= or spec= (learn and certify a model first: tli learn, tli certify)")


def _toml_kind(path: Path) -> str:
    """``"task"`` for a task file (a ``[state]`` table), else ``"spec"``."""
    try:
        doc = parse_toml(read_text(path, what="spec or task", error=TaskError),
                         where=str(path), error=TaskError)
    except TliError:
        return "spec"  # the spec reader says what is wrong
    return "task" if "state" in doc else "spec"
