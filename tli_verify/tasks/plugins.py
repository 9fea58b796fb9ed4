"""Entry points of group ``tli_verify.tasks``: Python tasks and sensor models, by name.

A distribution declares them in its metadata (``[project.entry-points."tli_verify.tasks"]``);
every process -- a campaign's workers included -- finds them by name, so a user's plug-in needs
no wrapper script. Evidence binds one by its distribution's name and version and the SHA-256 of
the source file of its module (:func:`entry_point_source`).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

from tli_verify.errors import TaskError

__all__ = ["ENTRY_POINT_GROUP", "entry_point", "entry_point_names", "entry_point_source"]

ENTRY_POINT_GROUP = "tli_verify.tasks"


def _entry_points() -> dict[str, Any]:
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def entry_point_names() -> list[str]:
    """The names of the installed entry points of group ``tli_verify.tasks``."""
    return sorted(_entry_points())


def entry_point(name: str) -> Any:
    """The object of entry point ``name`` of group ``tli_verify.tasks``.

    Raises
    ------
    TaskError
        (exit 2) No such entry point, or it fails to load.
    """
    ep = _entry_points().get(name)
    if ep is None:
        raise TaskError(f"no entry point {name!r} in group {ENTRY_POINT_GROUP!r} (installed: "
                        f"{', '.join(sorted(_entry_points())) or 'none'})")
    try:
        return ep.load()
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # SystemExit too: a plug-in never ends the process
        raise TaskError(f"entry point {name!r} ({ep.value}) does not load: "
                        f"{type(exc).__name__}: {exc}") from None


def entry_point_source(name: str) -> dict[str, str | None]:
    """What binds an entry point: ``distribution``, ``version`` and ``source_sha256`` (of the
    source file of the module it names)."""
    import importlib.util

    ep = _entry_points().get(name)
    if ep is None:
        raise TaskError(f"no entry point {name!r} in group {ENTRY_POINT_GROUP!r}")
    dist = getattr(ep, "dist", None)
    module = ep.value.split(":", 1)[0].strip()
    sha: str | None = None
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        spec = None
    origin = getattr(spec, "origin", None)
    if origin and os.path.isfile(origin):
        sha = hashlib.sha256(Path(origin).read_bytes()).hexdigest()
    if sha is None:
        raise TaskError(f"entry point {name!r}: the source of module {module!r} cannot be "
                        "found, so evidence could not bind it")
    return {"distribution": None if dist is None else dist.metadata["Name"],
            "version": None if dist is None else dist.version, "source_sha256": sha}
