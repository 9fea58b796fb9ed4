"""A certified policy under test: its files resolved by the project rules, ready to simulate.

:func:`project` is the entry point of :mod:`tli_verify.testing`: it finds the task, spec, model
and certificate by the one project resolver (:func:`tli_verify.tasks.project.resolve`, the rules
every ``tli`` command follows) and holds what a run needs (a
:class:`~tli_verify.verify.config.SimSpec`, as ``tli verify`` builds it).
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tli_verify.project import locate
from tli_verify.tasks.project import project_root

if TYPE_CHECKING:  # pragma: no cover - types only (the imports below are lazy)
    from tli_verify.tasks.project import Resolved
    from tli_verify.tasks.task import Task
    from tli_verify.verify.config import CampaignConfig, SimSpec
    from tli_verify.verify.simulate import Loaded

__all__ = ["DEFAULTS", "Defaults", "Project", "default_project", "default_root", "project"]

PathLike = str | os.PathLike[str]


@dataclass(slots=True)
class Defaults:
    """Process-wide defaults the pytest plugin sets from its options (``--tli-project``,
    ``--tli-case-dir``); None: the working directory, and the project's ``tests/regressions/``
    (else a temporary directory)."""

    project: Path | None = None
    case_dir: Path | None = None


DEFAULTS = Defaults()
"""The defaults :func:`project` and :func:`~tli_verify.testing.assert_satisfies` use."""


@dataclass(frozen=True, slots=True, eq=False)
class Project:
    """A certified policy under test (build it with :func:`project`).

    Attributes
    ----------
    root : Path
        The project folder (absolute): the parent of its ``models/``, ``specs/``, ``tasks/``.
    resolved : Resolved
        The files and the task, by the project rules.
    config : CampaignConfig
        The campaign settings with the task's defaults filled in (window, max_pushes, lag,
        start or random starts), as ``tli verify`` would run them.
    sim : SimSpec
        What a run needs (absolute paths and the SHA-256 that bind the files).
    case_dir : Path or None
        Where failing cases are saved (None: :attr:`regression_dir`'s default).
    """

    root: Path
    resolved: Resolved
    config: CampaignConfig
    sim: SimSpec
    case_dir: Path | None = None

    # ------------------------------------------------------------------ views
    @property
    def task(self) -> Task:
        """The task the policy runs on."""
        return self.resolved.task

    @property
    def name(self) -> str:
        """The task's name."""
        return str(self.resolved.task.name)

    @property
    def modulation(self) -> bool:
        """Cuts are learned online (LTL-DS); False: the no-modulation ablation."""
        return bool(self.sim.modulation)

    @property
    def window(self) -> int:
        """Perturbations happen in steps ``1..window`` (the task's default)."""
        return int(self.sim.window)

    @property
    def max_pushes(self) -> int:
        """At most this many perturbations per case (the task's default)."""
        return int(self.config.max_pushes or 0)

    @property
    def start(self) -> tuple[float, ...] | None:
        """The fixed start of the cases (the task's first nominal start), None: random
        starts."""
        return None if self.config.random_starts else self.config.start

    @property
    def loaded(self) -> Loaded:
        """The loaded setup (task, automaton, model, policy, oracle; cached per process)."""
        from tli_verify.verify.simulate import load

        return load(self.sim)

    @property
    def regression_dir(self) -> Path:
        """Where :func:`~tli_verify.testing.assert_satisfies` saves a failing case: the
        project's :attr:`case_dir`, else the plugin's ``--tli-case-dir``, else
        ``ROOT/tests/regressions/`` when that folder exists, else a temporary directory (one
        per process)."""
        if self.case_dir is not None:
            return self.case_dir
        if DEFAULTS.case_dir is not None:
            return DEFAULTS.case_dir
        mine = self.root / "tests" / "regressions"
        if mine.is_dir():
            return mine
        return _tmp_case_dir()

    # ------------------------------------------------------------------ variants
    def with_modulation(self, modulation: bool) -> Project:
        """The same files, with modulation on (LTL-DS) or off (the ablation)."""
        return replace(self, config=replace(self.config, modulation=bool(modulation)),
                       sim=replace(self.sim, modulation=bool(modulation)))

    def __repr__(self) -> str:
        return (f"Project({self.name!r}, model={_rel(self.sim.model, self.root)!r}, "
                f"modulation={self.modulation})")

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:
        """The short repr in hypothesis's reports too (its printer would list every field of
        a dataclass: the task, the files, the settings)."""
        printer.text(repr(self))


# ---------------------------------------------------------------------------------------------
def project(path: PathLike | None = None, *, task: PathLike | None = None,
            spec: PathLike | None = None, model: PathLike | None = None,
            certificate: PathLike | None = None, modulation: bool = True,
            lag: int | None = None, max_cycles: int | None = None,
            case_dir: PathLike | None = None) -> Project:
    """Resolve a certified policy's files by the project rules and load it.

    Parameters
    ----------
    path : path-like, optional
        A model file (``*.json``), a spec or task file (``*.toml``), or a directory: the project
        folder that holds it or its nearest ancestor with a ``models/``, ``specs/`` or
        ``tasks/`` folder (so ``project(__file__)`` works from ``PROJECT/tests/``); in a
        project folder, its one model (``models/*.model.json``), else its one spec. Default:
        :func:`default_root` (the plugin's ``--tli-project``, else the pytest rootdir, else
        the working directory).
    task, spec, model, certificate : path-like, optional
        Override a file, as ``--task``, ``--spec``, ``--model``, ``--certificate`` do (a task
        may also be a name: the project's ``tasks/NAME.toml``, a bundled task, an entry point).
    modulation : bool, optional
        Learn cuts online (LTL-DS, default); False: the no-modulation ablation.
    lag : int, optional
        Override the task's sensor lag.
    max_cycles : int, optional
        The oracle's loop bound (default: the number of modes).
    case_dir : path-like, optional
        Where failing cases are saved (default: :attr:`Project.regression_dir`).

    Returns
    -------
    Project

    Raises
    ------
    TaskError, CampaignError
        Nothing to start from, missing files, files that do not fit the task (one line naming
        the file), exactly as the ``tli`` commands refuse them.
    CertificateError
        The certificate does not cover the model.

    Examples
    --------
    >>> drawer = project("path/to/drawer-project")              # doctest: +SKIP
    >>> drawer = project(spec="specs/drawer.toml", modulation=False)  # doctest: +SKIP
    """
    from tli_verify.verify.config import CampaignConfig, resolve_config, sim_spec
    from tli_verify.verify.simulate import load

    files: dict[str, str | None] = {
        "task": _fs(task), "spec": _fs(spec), "model": _fs(model),
        "certificate": _fs(certificate)}
    root: Path | None = None
    if path is not None or not any(files.values()):
        where = Path(os.path.abspath(path if path is not None else default_root()))
        kind, found, root = locate(where, given_spec_or_model=bool(files.get("model")
                                                                    or files.get("spec")))
        if kind is not None and files.get(kind) is None:
            files[kind] = str(found)
    cfg = CampaignConfig(task=files["task"], spec=files["spec"], model=files["model"],
                         certificate=files["certificate"], modulation=bool(modulation),
                         lag=lag, max_cycles=max_cycles)
    resolved, filled = resolve_config(cfg)
    sim = _absolute(sim_spec(filled))
    if root is None:

        root = Path(os.path.abspath(project_root(sim.model)))
    out = Project(root=root, resolved=resolved, config=filled, sim=sim,
                  case_dir=None if case_dir is None else Path(os.path.abspath(case_dir)))
    load(out.sim)  # the automaton, the policy (its certificate checked), the oracle: now
    return out


def default_root() -> Path:
    """Where :func:`project` without arguments looks: the plugin's ``--tli-project`` (ini
    ``tli_project``), else the rootdir of the running pytest session, else the working
    directory."""
    if DEFAULTS.project is not None:
        return DEFAULTS.project
    plugin = sys.modules.get("tli_verify.testing.plugin")
    roots = getattr(plugin, "ROOTS", None)
    if roots:
        return Path(roots[-1])
    return Path.cwd()


def default_project() -> Project:
    """The project of :func:`default_root` (the ``tli_project`` fixture's, and the one
    :func:`~tli_verify.testing.cases` draws for without a project), resolved and loaded once
    per process and folder.

    Returns
    -------
    Project

    Raises
    ------
    TaskError, CampaignError
        As :func:`project`.
    """
    key = os.path.abspath(default_root())
    hit = _DEFAULT.get(key)
    if hit is None:
        hit = project(key)
        _DEFAULT[key] = hit
    return hit


_DEFAULT: dict[str, Project] = {}
_TMP: list[Path] = []


def _tmp_case_dir() -> Path:
    """One temporary directory per process for failing cases of a project without
    ``tests/regressions/``."""
    if not _TMP:
        import tempfile

        _TMP.append(Path(tempfile.mkdtemp(prefix="tli-verify-cases-")))
    return _TMP[0]


def _fs(p: PathLike | None) -> str | None:
    return None if p is None else os.fspath(p)


def _rel(path: str, root: Path) -> str:
    try:
        return str(Path(path).relative_to(root))
    except ValueError:
        return str(path)


def _absolute(sim: SimSpec) -> SimSpec:
    """The spec with absolute file paths (a test that changes directory keeps it working)."""
    task = sim.task
    if os.path.isfile(task):
        task = os.path.abspath(task)
    return replace(sim, task=task, spec=os.path.abspath(sim.spec),
                   model=os.path.abspath(sim.model),
                   certificate=os.path.abspath(sim.certificate))
