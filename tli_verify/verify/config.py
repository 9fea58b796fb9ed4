"""A campaign's configuration and the files it binds (paper Sec. 4.4).

* :class:`CampaignConfig` -- what ``tli verify`` runs (validated on construction);
* :func:`resolve_config` -- its files by the project rules, the task's defaults filled in
  (:func:`fill_config`);
* :class:`SimSpec` and :func:`sim_spec` -- what a worker needs to find and re-check them: the
  files' paths and SHA-256, and how to find the task again (:func:`task_ref`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from tli_verify.errors import CampaignError
from tli_verify.io import sha256_file
from tli_verify.limits import MAX_BATCH_SIZE, MAX_CAMPAIGN_STEPS, MAX_EXAMPLES, MAX_PUSHES, MAX_SEED
from tli_verify.tasks.project import resolve
from tli_verify.tasks.task import Task
from tli_verify.verify.strategies import (
    LEVELS,
)

__all__ = [
    "CampaignConfig",
    "SimSpec",
    "fill_config",
    "resolve_config",
    "sim_spec",
    "task_ref",
]


@dataclass(frozen=True, slots=True)
class CampaignConfig:
    """A campaign (``tli verify``).

    Attributes
    ----------
    task : str or None
        A task name or task file (:func:`tli_verify.tasks.registry.find_task`): its sensor
        model, true regions, starts and perturbation bounds (default: the task the spec names).
    spec, model, certificate : str or None
        Files, resolved by the project rules (:func:`tli_verify.tasks.project.resolve`).
    examples : int
        Cases drawn and simulated.
    seed : int
    modulation : bool
        Learn cuts online (LTL-DS); False: the no-modulation ablation.
    workers : int or None
        Worker processes (default: the CPU count).
    backend : str
        ``"process"``, ``"serial"`` or ``"dask"``.
    scheduler : str or None
        Dask scheduler address (``--backend dask``).
    batch_size : int
        Runs per batch (one task).
    max_pushes : int or None
        Perturbations per case, at most (default: the task's ``perturbations.max_pushes``).
    window : int or None
        Perturbations happen in steps ``1..window`` (default: the task's).
    levels : tuple of str
        Perturbation levels (:data:`~tli_verify.verify.strategies.LEVELS`).
    start : tuple of float or None
        Fixed start (default: the task's first nominal start).
    random_starts : bool or None
        Draw starts too (in the regions whose first reading the spec allows); default: when
        the task has no nominal start, or its ``[starts] random = true``.
    lag : int or None
        Sensor lag (steps; default: the task's).
    max_cycles : int or None
        Loop bound of the oracle (default: the number of modes).
    shrink : bool
        Shrink the first counterexample.
    target_examples : int
        Extra driver-side targeted examples when nothing was found (0: none).
    """

    task: str | None = None
    spec: str | None = None
    model: str | None = None
    certificate: str | None = None
    examples: int = 200
    seed: int = 0
    modulation: bool = True
    workers: int | None = None
    backend: str = "process"
    scheduler: str | None = None
    batch_size: int = 100
    max_pushes: int | None = None
    window: int | None = None
    levels: tuple[str, ...] = LEVELS
    start: tuple[float, ...] | None = None
    random_starts: bool | None = None
    lag: int | None = None
    max_cycles: int | None = None
    shrink: bool = True
    target_examples: int = 0

    def __post_init__(self) -> None:
        """Every field's type and range, as the CLI options check them (recorded settings of
        evidence are re-run through here, so a forged one is refused, never run).

        Raises
        ------
        CampaignError
            (exit 2) Naming the field.
        """

        def whole(name: str, lo: int, hi: int, *, optional: bool = False) -> None:
            v = getattr(self, name)
            if v is None and optional:
                return
            if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
                raise CampaignError(f"{name}: expected an integer in [{lo}, {hi}], got {v!r}")

        whole("examples", 1, MAX_EXAMPLES)
        whole("seed", 0, MAX_SEED)
        whole("batch_size", 1, MAX_BATCH_SIZE)
        whole("workers", 1, 256, optional=True)
        whole("window", 1, MAX_CAMPAIGN_STEPS, optional=True)
        whole("lag", 0, MAX_CAMPAIGN_STEPS, optional=True)
        whole("max_pushes", 0, MAX_PUSHES, optional=True)
        whole("max_cycles", 0, MAX_CAMPAIGN_STEPS, optional=True)
        whole("target_examples", 0, MAX_EXAMPLES)
        for name in ("modulation", "shrink"):
            if not isinstance(getattr(self, name), bool):
                raise CampaignError(f"{name}: expected true or false, got "
                                    f"{getattr(self, name)!r}")
        if self.random_starts is not None and not isinstance(self.random_starts, bool):
            raise CampaignError(f"random_starts: expected true or false, got "
                                f"{self.random_starts!r}")
        if self.backend not in ("process", "serial", "dask"):
            raise CampaignError(f"backend: one of process, serial, dask, got {self.backend!r}")
        if not isinstance(self.levels, tuple) or not self.levels or any(
                lv not in LEVELS for lv in self.levels) or len(set(self.levels)) != \
                len(self.levels):
            raise CampaignError(f"levels: a non-empty subset of {', '.join(LEVELS)}, got "
                                f"{self.levels!r}")
        if self.start is not None and (not isinstance(self.start, tuple) or not all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                for v in self.start)):
            raise CampaignError(f"start: expected finite numbers, got {self.start!r}")
        for name in ("task", "spec", "model", "certificate", "scheduler"):
            v = getattr(self, name)
            if v is not None and not isinstance(v, str):
                raise CampaignError(f"{name}: expected a path or name, got {v!r}")


@dataclass(frozen=True, slots=True)
class SimSpec:
    """What a worker needs to rebuild the setup (files by path and SHA-256; picklable).

    ``task`` is the task file's path, or the name of an entry-point task (a worker finds it in
    the installed metadata); ``task_sha256`` is what binds it (the file's SHA-256, or the
    entry point's source SHA-256).
    """

    task: str
    task_sha256: str
    lag: int
    spec: str
    model: str
    certificate: str
    hashes: tuple[str, str, str]
    modulation: bool
    max_cycles: int | None
    window: int


def task_ref(task: Any) -> tuple[str, str]:
    """How a worker finds a task again, and what binds it: ``(task file path, its SHA-256)``,
    or ``(entry point name, its source SHA-256)``.

    Raises
    ------
    CampaignError
        (exit 2) A task built in memory (it cannot be bound or found by a worker).
    """
    src = task.source
    if src.kind == "file" and src.path is not None and src.sha256 is not None:
        return src.path, src.sha256
    if src.kind == "entry-point" and src.entry_point is not None and src.source_sha256:
        return src.entry_point, src.source_sha256
    raise CampaignError(f"task {task.name!r} was built in memory: campaigns need a task file "
                        "or an entry-point task")


def resolve_config(cfg: CampaignConfig) -> tuple[Any, CampaignConfig]:
    """The config's files by the project rules, and the config with the task's defaults
    filled in (:func:`fill_config`).

    Raises
    ------
    TaskError, CampaignError
        (exit 2) Missing files, a model or spec that does not fit the task, a start outside
        the workspace or of the wrong dimension.
    """
    resolved = resolve(task=cfg.task, spec=cfg.spec, model=cfg.model,
                       certificate=cfg.certificate, lag=cfg.lag)
    return resolved, fill_config(cfg, resolved.task)


def fill_config(cfg: CampaignConfig, task: Task) -> CampaignConfig:
    """The config with its task's defaults filled in: window, max_pushes, lag, and the start
    or random starts (a task without a nominal start draws random starts).

    Parameters
    ----------
    cfg : CampaignConfig
    task : Task
        The task the config's files resolved to (its lag already overridden by ``cfg.lag``).

    Raises
    ------
    CampaignError
        (exit 2) A start outside the workspace or of the wrong dimension, or no start at all.
    """
    start = cfg.start
    random_starts = cfg.random_starts
    if random_starts is None:
        random_starts = start is None and (not task.starts.nominal or task.starts.random)
    if not random_starts and start is None:
        if not task.starts.nominal:
            raise CampaignError(f"task {task.name!r} has no nominal start ([starts] nominal): "
                                "pass a start or use random starts")
        start = task.starts.nominal[0]
    if start is not None:
        if len(start) != task.dim:
            raise CampaignError(f"start: expected {task.dim} coordinates (task "
                                f"{task.name!r}), got {len(start)}")
        if not bool(task.in_workspace(np.asarray(start, dtype=np.float64)[None])[0]):
            raise CampaignError(f"start {list(start)}: outside the workspace of task "
                                f"{task.name!r}")
    return replace(cfg, window=task.perturbations.window if cfg.window is None else cfg.window,
                   max_pushes=(task.perturbations.max_pushes if cfg.max_pushes is None
                               else cfg.max_pushes),
                   lag=task.lag, random_starts=bool(random_starts),
                   start=None if random_starts else tuple(float(v) for v in start or ()))


def sim_spec(cfg: CampaignConfig) -> SimSpec:
    """Resolve the files of a config (its task defaults filled in) and hash them.

    Raises
    ------
    CampaignError, TaskError
        (exit 2) Unknown task, missing files, files that do not fit.
    """
    resolved, filled = resolve_config(cfg)
    ref, sha = task_ref(resolved.task)
    assert filled.window is not None
    assert filled.lag is not None
    return SimSpec(task=ref, task_sha256=sha, lag=filled.lag, spec=str(resolved.spec),
                   model=str(resolved.model), certificate=str(resolved.certificate),
                   hashes=(sha256_file(resolved.spec), sha256_file(resolved.model),
                           sha256_file(resolved.certificate)),
                   modulation=cfg.modulation, max_cycles=cfg.max_cycles, window=filled.window)
