"""Small file helpers shared by every stage: atomic writes and canonical JSON.

Results are written atomically (temporary file in the same directory, fsync, rename), so a
crash never leaves a half-written certificate, model or automaton (``DESIGN.md``, "Files").
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any

__all__ = ["atomic_write_bytes", "atomic_write_text", "canonical_json", "read_text", "sha256_file"]

MAX_INPUT_BYTES = 4 * 1024 * 1024
"""Largest input file (spec, model, certificate) accepted; larger files are bad input."""


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temp file + rename).

    The file gets the permissions a plain ``open(path, "w")`` would give it (``0o666`` minus the
    umask), not the private ``0o600`` of the temporary file: certificates and reports are meant
    to be read by others.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    atomic_write_bytes(path, text.encode("utf-8"))


def canonical_json(obj: Any) -> str:
    """Deterministic JSON: sorted keys, two-space indent, trailing newline."""
    return json.dumps(obj, indent=2, sort_keys=True, allow_nan=False) + "\n"


def sha256_file(path: str | os.PathLike[str]) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 16), b""):
            digest.update(block)
    return digest.hexdigest()


def read_text(path: str | os.PathLike[str], *, what: str, error: type[Exception]) -> str:
    """Read a UTF-8 text input file, turning every failure into ``error`` naming the file.

    Parameters
    ----------
    path : path-like
        File to read.
    what : str
        What the file is ("spec", "model", ...), used in messages.
    error : type
        Exception class (a :class:`tli_verify.errors.TliError`) to raise.
    """
    p = Path(path)
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise error(f"{p}: cannot read {what} file: {exc.strerror or exc}") from None
    if p.is_dir():
        raise error(f"{p}: is a directory, expected a {what} file")
    if size > MAX_INPUT_BYTES:
        raise error(f"{p}: {what} file is {size} bytes, larger than the limit of "
                    f"{MAX_INPUT_BYTES} bytes")
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise error(f"{p}: cannot read {what} file: {exc.strerror or exc}") from None
    if b"\x00" in raw:
        raise error(f"{p}: not a text file (contains NUL bytes)")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{p}: not UTF-8 text (byte {exc.start})") from None
