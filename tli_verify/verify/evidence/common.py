"""What writing and checking evidence share: its digest, where a model's evidence lives, the task
block (the task's file, its bytes' and its content's SHA-256).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tli_verify.errors import EvidenceError, TaskError, TliError, missing
from tli_verify.io import (
    canonical_json,
    parse_toml,
    read_text,
    sha256_file,
)

if TYPE_CHECKING:
    pass

__all__ = [
    "evidence_digest",
    "evidence_path_for",
    "model_stem",
    "task_block",
    "task_content_sha256",
]


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

    try:  # the session's bytes of the file: the ones its hash and its parse saw
        data = parse_toml(read_text(path, what="task", error=TaskError), where=str(path),
                          error=TaskError)
        # sorted keys, one spelling per number (inf and nan too), dates as ISO text
        text = json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=False,
                          allow_nan=True, default=str)
    except (TliError, TypeError, ValueError):
        return None
    return hashlib.sha256(text.encode("utf-8")).hexdigest()
