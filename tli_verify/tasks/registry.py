"""The one registry of tasks: bundled task files, a project's ``tasks/`` and entry points.

``find_task(REF)`` resolves a task reference, as every command's ``--task`` does:

1. ``REF`` names a file (it exists, or ends in ``.toml``): that task file;
2. else ``REF`` is a name: ``tasks/REF.toml`` of the project given (the folder a spec or
   model lives in), then the bundled ``tasks/REF.toml`` (the paper's tasks), then the entry
   point ``REF`` of group ``tli_verify.tasks`` (a Python package's task);
3. else an error listing the names known.

Entry points (group ``tli_verify.tasks`` in a distribution's metadata) serve two purposes, by
what their object is:

* a :class:`~tli_verify.tasks.task.Task`, or a callable of no arguments returning one: a task
  of that name;
* a callable ``(*, dim, partition) -> SensorModel``: a Python sensor model a task file names
  with ``sensor_model = "NAME"`` (sensors physics computes).

Worker processes find an entry point by its name in the installed metadata, so a user's
plug-in needs no wrapper script. Evidence binds an entry point by its distribution's name and
version and the SHA-256 of the source file of its module (:func:`entry_point_source`).
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

from tli_verify.arguments import check_path
from tli_verify.errors import TaskError, TliError
from tli_verify.io import bundled_dir
from tli_verify.tasks.formula import is_name
from tli_verify.tasks.plugins import (
    ENTRY_POINT_GROUP,
    _entry_points,
    entry_point,
    entry_point_source,
)
from tli_verify.tasks.task import Task, TaskSource
from tli_verify.tasks.taskfile import load_task

__all__ = ["ENTRY_POINT_GROUP", "bundled_tasks", "entry_point", "entry_point_source",
           "find_task", "task_names"]


def _bundled_dir() -> Path | None:

    try:
        return bundled_dir("tasks")
    except TliError:
        return None


def bundled_tasks() -> dict[str, Path]:
    """The bundled task files by name (``tasks/*.toml`` shipped with tli-verify)."""
    d = _bundled_dir()
    if d is None:
        return {}
    return {p.stem: p for p in sorted(d.glob("*.toml"))}


def task_names(project: str | os.PathLike[str] | None = None) -> list[str]:
    """Every task name ``find_task`` knows: the project's, the bundled ones, entry points."""
    names: set[str] = set(bundled_tasks()) | set(_entry_points())
    if project is not None:
        names |= {p.stem for p in (Path(project) / "tasks").glob("*.toml")}
    return sorted(names)


@lru_cache(maxsize=64)
def _load_file(path: str, mtime_ns: int, size: int) -> Task:
    return load_task(path)


def _from_file(path: Path) -> Task:
    try:
        st = path.stat()
    except OSError:
        return load_task(path)  # the reader says what is wrong
    return _load_file(str(path), st.st_mtime_ns, st.st_size)


def find_task(ref: str | os.PathLike[str], *, project: str | os.PathLike[str] | None = None
              ) -> Task:
    """Resolve a task reference (module docstring).

    Parameters
    ----------
    ref : str or path-like
        A task file, or a task name.
    project : path-like, optional
        A project folder whose ``tasks/`` is searched first.

    Returns
    -------
    Task

    Raises
    ------
    TaskError
        (exit 2) An unknown name (the message lists the known ones), a file that does not
        load, an entry point that is not a task.
    """
    check_path(ref, "task", error=TaskError)
    text = os.fspath(ref)
    p = Path(text)
    if p.suffix == ".toml" or p.exists() or os.sep in text or "/" in text:
        if not p.is_file():
            raise TaskError(f"{p}: no such task file")
        return _from_file(p)

    if not is_name(text.replace("-", "_")):
        raise TaskError(f"--task {text!r}: neither a task file nor a task name")
    if project is not None:
        local = Path(project) / "tasks" / f"{text}.toml"
        if local.is_file():
            return _from_file(local)
    bundled = bundled_tasks().get(text)
    if bundled is not None:
        return _from_file(bundled)
    if text in _entry_points():
        obj = entry_point(text)
        task = obj if isinstance(obj, Task) else None
        if task is None and callable(obj):
            try:
                task = obj()
            except TliError:
                raise
            except TypeError:
                task = None
            except KeyboardInterrupt:
                raise
            except BaseException as exc:  # SystemExit too: a plug-in never ends the process
                raise TaskError(f"entry point {text!r}: building the task failed "
                                f"({type(exc).__name__}: {exc})") from None
        if not isinstance(task, Task):
            raise TaskError(f"entry point {text!r} is not a task (it may be a sensor model: "
                            "name it from a task file's sensor_model)")
        from dataclasses import replace

        if task.source.kind == "code":
            task = replace(task, source=TaskSource("entry-point", entry_point=text,
                                                   **entry_point_source(text)))
        return task
    raise TaskError(f"unknown task {text!r} (tasks: "
                    f"{', '.join(task_names(project)) or 'none'}; or give a task file)")
