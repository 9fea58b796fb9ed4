"""One read per file per session: the bytes a command checks are the bytes it uses.

A command (or a :class:`tli_verify.project.Session`) runs inside a *snapshot*. Within it,
the first read of a file keeps its bytes; every later read of the same file (the same real
path) -- to parse it, to hash it for a certificate's binding, to parse it again deeper down --
gets those same bytes, and an object parsed from them (a model, a spec, a task) is parsed once
and shared (the objects are frozen). Two consequences:

* **one open, one parse**: ``tli run`` on a project opens its model and its spec once each
  (before: the model 8 times, the spec 4; ``tests/integration/test_project_session.py``
  counts them with an audit hook);
* **no gap between check and use**: a certificate's SHA-256 is computed over the very bytes
  the runtime then parses, so a file swapped mid-command cannot pass the check with one
  content and run with another.

A write through :func:`tli_verify.io.atomic_write_bytes` replaces the entry with the bytes
written (a command that learns, then certifies what it learned, sees its own output). Outside
a snapshot every read goes to the file system, as before. Snapshots nest: an inner
:func:`active` inside an outer one reuses it.

Only regular files up to the input limit are kept; everything else streams as before.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import TypeVar

__all__ = ["Snapshot", "active", "current", "forget", "remember"]

T = TypeVar("T")


def _key(path: str | os.PathLike[str]) -> str:
    return os.path.realpath(os.fspath(path))


@dataclass(frozen=True, slots=True)
class Kept:
    """A file's bytes as first read in a snapshot, and their SHA-256 (hex)."""

    data: bytes
    sha256: str


@dataclass(eq=False)
class Snapshot:
    """The files one session has read (by real path) and the objects parsed from them.

    Attributes
    ----------
    files : dict
        Real path -> :class:`Kept`.
    parsed : dict
        ``(kind, real path)`` -> the object parsed from that file's kept bytes.
    opens : int
        How many files this snapshot read from the file system (each at most once).
    """

    files: dict[str, Kept] = field(default_factory=dict)
    parsed: dict[tuple[str, str], object] = field(default_factory=dict)
    opens: int = 0

    def kept(self, path: str | os.PathLike[str]) -> Kept | None:
        """The bytes kept for ``path``, or None if this snapshot has not read it."""
        return self.files.get(_key(path))

    def keep(self, path: str | os.PathLike[str], data: bytes, *, read: bool = True) -> Kept:
        """Keep ``data`` as the content of ``path`` (``read``: it came from the disk)."""
        key = _key(path)
        kept = Kept(data, hashlib.sha256(data).hexdigest())
        self.files[key] = kept
        for k in [k for k in self.parsed if k[1] == key]:
            del self.parsed[k]
        if read:
            self.opens += 1
        return kept

    def parse(self, kind: str, path: str | os.PathLike[str], make: Callable[[], T]) -> T:
        """The object of ``kind`` parsed from ``path``: made once, then shared."""
        key = (kind, _key(path))
        if key not in self.parsed:
            self.parsed[key] = make()
        return self.parsed[key]  # type: ignore[return-value]

    @contextmanager
    def use(self) -> Iterator[Snapshot]:
        """Make this snapshot the current one for the ``with`` block."""
        token = _CURRENT.set(self)
        try:
            yield self
        finally:
            _CURRENT.reset(token)


_CURRENT: ContextVar[Snapshot | None] = ContextVar("tli_verify_snapshot", default=None)


def current() -> Snapshot | None:
    """The snapshot in force, if any."""
    return _CURRENT.get()


@contextmanager
def active() -> Iterator[Snapshot]:
    """Run the block inside a snapshot: the current one if any, else a new one."""
    snap = _CURRENT.get()
    if snap is not None:
        yield snap
        return
    with Snapshot().use() as snap:
        yield snap


def remember(path: str | os.PathLike[str], data: bytes) -> None:
    """A file was just written with ``data``: the current snapshot (if any) keeps them."""
    snap = _CURRENT.get()
    if snap is not None:
        snap.keep(path, data, read=False)


def forget(path: str | os.PathLike[str]) -> None:
    """A file changed by other means (removed, written by a tool): drop what was kept."""
    snap = _CURRENT.get()
    if snap is not None:
        key = _key(path)
        snap.files.pop(key, None)
        for k in [k for k in snap.parsed if k[1] == key]:
            del snap.parsed[k]
