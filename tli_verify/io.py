"""File helpers shared by every stage: bounded input reads, output checks, atomic writes.

Inputs
    :func:`read_text` is the one reader of every input file (spec, demonstration, model,
    certificate). It reads regular files only (never a device, FIFO or socket, which may never
    end), at most :data:`~tli_verify.limits.MAX_INPUT_BYTES`, accepts a UTF-8 byte-order mark,
    and refuses brackets nested deeper than :data:`~tli_verify.limits.MAX_NESTING`, so the JSON
    and TOML parsers never recurse out of the stack.
Outputs
    :func:`check_output_file` / :func:`check_output_dir` refuse, before any work, an output
    that is a directory (or a file), lies under a regular file, cannot be written, or resolves
    (symlinks, ``./``, hard links) to one of the command's input files. Results are written
    atomically (temporary file in the same directory, fsync, rename), so a crash never leaves a
    half-written certificate, model or automaton (``docs/design.md``, "Files"); every failure is
    an :class:`~tli_verify.errors.OutputError` (exit 2), never a raw ``OSError``.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import stat
import tempfile
from collections.abc import Callable, Iterable, Sequence
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

from tli_verify.arguments import check_path
from tli_verify.errors import OutputError, TliError, missing
from tli_verify.limits import MAX_INPUT_BYTES, MAX_NESTING
from tli_verify.snapshot import current as _snapshot
from tli_verify.snapshot import remember as _remember

__all__ = [
    "BUNDLED_FOLDERS",
    "MAX_INPUT_BYTES",
    "MAX_NESTING",
    "atomic_write_bytes",
    "atomic_write_text",
    "bundled_dir",
    "bundled_root",
    "canonical_json",
    "check_nesting",
    "check_output_dir",
    "check_output_file",
    "field_path",
    "parse_json",
    "read_json",
    "read_text",
    "sha256_file",
    "validate_schema",
]

PathLike = str | os.PathLike[str]
_PLAIN_KEY = re.compile(r"^[A-Za-z0-9_]+$")


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _why(exc: OSError) -> str:
    return exc.strerror or type(exc).__name__

# --------------------------------------------------------------------------------------------
# Outputs
# --------------------------------------------------------------------------------------------


def check_path_arg(path: Any, *, what: str, error: type[TliError] = OutputError) -> Path:
    """``path`` as a :class:`Path`, refused unless it is a ``str`` or ``os.PathLike`` whose
    every component fits ``MAX_NAME_BYTES``.

    Raises
    ------
    error
        Also a :class:`TypeError` for a path of another type (``None``, an int), a
        :class:`ValueError` for a component longer than ``MAX_NAME_BYTES`` or a NUL byte.
    """
    return check_path(path, f"the {what} path", error=error)


def _existing_ancestor(p: Path) -> Path:
    """The nearest ancestor of ``p`` (absolute) that exists (``lstat``), or ``p`` itself."""
    cur = p
    while not os.path.lexists(cur) and cur != cur.parent:
        cur = cur.parent
    return cur


def same_file(a: PathLike, b: PathLike) -> bool:
    """Whether two paths name the same file: the same resolved path, or the same inode (a hard
    link); False when either cannot be resolved or does not exist."""
    try:
        if Path(a).resolve() == Path(b).resolve():
            return True
        return os.path.exists(a) and os.path.exists(b) and os.path.samefile(a, b)
    except (OSError, RuntimeError):  # RuntimeError: a symlink loop
        return False


def _check_dotdot(p: Path, shown: str, what: str) -> None:
    """Refuse ``..`` after a directory that does not exist yet (``out/new/../x``): creating the
    missing directories would change what the path names."""
    cur = Path(p.anchor) if p.is_absolute() else Path(".")
    for part in p.parts[1:] if p.is_absolute() else p.parts:
        if part == ".." and not cur.is_dir():
            raise OutputError(f"{shown}: '..' after {cur}, which is not an existing directory; "
                              f"give the {what} path without it")
        cur = cur / part


def _check_writable_dir(directory: Path, shown: str, what: str) -> None:
    """Refuse ``directory`` (the nearest existing ancestor of an output) unless we can write in it.

    A probe file is created and removed: ``os.access`` is wrong for root and on read-only
    file systems.
    """
    if not directory.is_dir():
        raise OutputError(f"{shown}: cannot write the {what}: {directory} is not a directory "
                          "(a path under a regular file)")
    try:
        fd, probe = tempfile.mkstemp(prefix=".tli-probe.", dir=directory)
    except OSError as exc:
        raise OutputError(f"{shown}: cannot write the {what}: directory {directory} is not "
                          f"writable ({_why(exc)})") from None
    os.close(fd)
    Path(probe).unlink(missing_ok=True)


def check_output_file(path: PathLike, *, inputs: Iterable[PathLike] = (),
                      what: str = "output file") -> Path:
    """Refuse an output file path that cannot, or must not, be written; before any work.

    Parameters
    ----------
    path : path-like
        Where the command will write a file (missing parent directories are created later).
    inputs : iterable of path-like, optional
        The command's input files: writing over one of them would lose it.
    what : str, optional
        What the output is, for messages ("model file", "certificate", ...).

    Returns
    -------
    Path
        ``path`` as a Path.

    Raises
    ------
    OutputError
        (exit 2) An empty path; an existing directory, device, FIFO or socket; a path under a
        regular file; a directory we cannot write in; or a path that resolves (symlinks,
        ``./``, ``..``, hard links) to one of ``inputs``.
    """
    if isinstance(path, str) and path == "":
        raise OutputError(f"empty path given for the {what}")
    p = check_path_arg(path, what=what)
    shown = str(path)
    _check_dotdot(p, shown, what)
    for src in inputs:
        if same_file(p, Path(src)):
            raise OutputError(f"{shown}: the {what} would overwrite the input file {src}; "
                              "choose another output path")
    if p.is_dir() or p.name in ("", ".", ".."):
        raise OutputError(f"{shown}: is a directory, expected a path for the {what}")
    if os.path.lexists(p):
        mode = os.stat(p).st_mode if p.exists() else os.lstat(p).st_mode
        if not stat.S_ISREG(mode) and not stat.S_ISLNK(mode):
            raise OutputError(f"{shown}: exists and is not a regular file (a device, FIFO or "
                              f"socket); refusing to replace it with the {what}")
    _check_writable_dir(_existing_ancestor(p.absolute().parent), shown, what)
    return p


def check_plan(*, inputs: Iterable[PathLike | None],
               outputs: Iterable[tuple[PathLike | None, str]]) -> None:
    """The read/write rule of every command and every public function that writes: refuse,
    before any work, an output that cannot be written, that is one of the command's
    inputs (named, defaulted or implied), or that is another of its outputs.

    Parameters
    ----------
    inputs : iterable of path-like or None
        Every file the command reads (None entries are skipped).
    outputs : iterable of (path-like or None, str)
        Every file it writes -- sidecars and files inside ``--out`` included -- with what it is.

    Raises
    ------
    OutputError
        (exit 2) Naming the output and what is wrong with it.
    """
    read = [Path(p) for p in inputs if p is not None]
    written: list[tuple[Path, str]] = []
    for path, what in outputs:
        if path is None:
            continue
        p = Path(path)
        check_output_file(p, inputs=read, what=what)
        for other, other_what in written:
            if os.path.abspath(other) == os.path.abspath(p) or (
                    p.exists() and other.exists() and os.path.samefile(p, other)):
                raise OutputError(f"{p}: the {what} and the {other_what} would be the same "
                                  "file; choose other output paths")
        written.append((p, what))


def check_output_dir(path: PathLike, *, what: str = "output directory") -> Path:
    """Refuse an output directory that cannot be created or written; before any work.

    Parameters
    ----------
    path : path-like
        Directory the command writes its results into (created if missing).
    what : str, optional
        For messages.

    Returns
    -------
    Path

    Raises
    ------
    OutputError
        (exit 2) An empty path; an existing file; a path under a regular file; a directory we
        cannot write in.
    """
    if isinstance(path, str) and path == "":
        raise OutputError(f"empty path given for the {what}")
    p = check_path_arg(path, what=what)
    _check_dotdot(p, str(path), what)
    if os.path.lexists(p) and not p.is_dir():
        raise OutputError(f"{p}: exists and is not a directory, expected the {what}")
    _check_writable_dir(_existing_ancestor(p.absolute()), str(path), what)
    return p


def atomic_write_bytes(path: PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temp file + rename).

    The file gets the permissions a plain ``open(path, "w")`` would give it (``0o666`` minus the
    umask), not the private ``0o600`` of the temporary file: certificates and reports are meant
    to be read by others.

    Raises
    ------
    OutputError
        (exit 2) The path is a directory or a device, lies under a regular file, or cannot be
        written; nothing is left behind and an existing file at ``path`` is untouched.
    """
    target = Path(path)
    if str(path) == "":
        raise OutputError("empty output path")
    if target.is_dir() or target.name in ("", ".", ".."):
        raise OutputError(f"{target}: is a directory, cannot write a file there")
    if target.exists() and not target.is_file():
        raise OutputError(f"{target}: exists and is not a regular file; refusing to replace it")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise OutputError(f"{target}: cannot write: {_why(exc)} ({exc.filename or target.parent})"
                          ) from None
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise OutputError(f"{target}: cannot write: {_why(exc)}") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    _remember(target, data)  # a snapshot in force sees what was written


def atomic_write_text(path: PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`atomic_write_bytes`)."""
    atomic_write_bytes(path, text.encode("utf-8"))


def canonical_json(obj: Any) -> str:
    """Deterministic JSON: sorted keys, two-space indent, trailing newline."""
    return json.dumps(obj, indent=2, sort_keys=True, allow_nan=False) + "\n"


def sha256_file(path: PathLike) -> str:
    """Hex SHA-256 of a file's bytes.

    Inside a snapshot (:mod:`tli_verify.snapshot`) the hash is of the bytes the snapshot
    keeps for the file -- the very bytes a parser of the same session uses; a regular file
    within the input limit not yet kept is read once and kept.
    """
    snap = _snapshot()
    if snap is not None:
        kept = snap.kept(path)
        if kept is not None:
            return kept.sha256
        try:
            st = os.stat(path)
        except OSError:
            st = None
        if st is not None and stat.S_ISREG(st.st_mode) and st.st_size <= MAX_INPUT_BYTES:
            with open(path, "rb") as handle:
                data = handle.read(MAX_INPUT_BYTES + 1)
            if len(data) <= MAX_INPUT_BYTES:
                return snap.keep(path, data).sha256
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 16), b""):
            digest.update(block)
    return digest.hexdigest()


# --------------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------------

# A string (JSON/TOML basic "..." with escapes, TOML literal '...', on one line), a comment
# (# to the end of the line, TOML and CSV) or a bracket. Brackets inside strings and comments
# do not nest anything.
_TOKENS = re.compile(r'"(?:[^"\\\n]|\\.)*"|\'[^\'\n]*\'|#[^\n]*|[\[\]{}]')


def check_nesting(text: str, *, where: str, error: type[TliError],
                  limit: int = MAX_NESTING) -> None:
    """Refuse ``[``/``{`` brackets nested deeper than ``limit`` outside strings and comments.

    Python's JSON and TOML parsers recurse once per level and die with ``RecursionError`` near
    1000 levels; this check runs first, in linear time.

    Raises
    ------
    error
        ``"<where>: line L, column C: brackets nested deeper than <limit> (limit MAX_NESTING)"``.
    """
    depth = 0
    for m in _TOKENS.finditer(text):
        tok = m.group()
        if tok in "[{":
            depth += 1
            if depth > limit:
                line = text.count("\n", 0, m.start()) + 1
                col = m.start() - (text.rfind("\n", 0, m.start()) + 1) + 1
                raise error(f"{where}: line {line}, column {col}: brackets nested deeper than "
                            f"{limit} levels (limit MAX_NESTING)")
        elif tok in "]}":
            depth = max(depth - 1, 0)


def parse_toml(text: str, *, where: str, error: type[TliError],
               nested: Callable[[], str] | None = None) -> dict[str, Any]:
    """Parse TOML text, turning every failure into one ``error`` naming the file: the one
    place "read TOML and map its errors" lives (specs, labels, tasks).

    Parameters
    ----------
    text : str
        The TOML text.
    where : str
        The file as shown in messages (``path`` or ``path:line``).
    error : type
        Exception class (a :class:`tli_verify.errors.TliError`) to raise.
    nested : callable, optional
        Makes the whole message for nesting beyond the parser's recursion limit (a reader
        that can find the line and knows its own limit says so); default: the file and
        "arrays or tables nested too deeply".

    Returns
    -------
    dict
        The parsed document.
    """
    import tomllib

    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{where}: invalid TOML: {exc}") from None
    except RecursionError:  # tomllib reads nested arrays recursively
        message = nested() if nested is not None else f"{where}: arrays or tables nested too deeply"
        raise error(message) from None
    except ValueError as exc:  # an integer of more than 4300 digits
        raise error(f"{where}: invalid TOML: {exc}") from None


def read_text(path: PathLike, *, what: str, error: type[TliError]) -> str:
    """Read a UTF-8 text input file, turning every failure into ``error`` naming the file.

    Only regular files are read, at most ``MAX_INPUT_BYTES``; a UTF-8 byte-order mark (as
    spreadsheets write) is dropped; brackets may nest at most ``MAX_NESTING`` deep.

    Parameters
    ----------
    path : path-like
        File to read.
    what : str
        What the file is ("spec", "model", ...), used in messages.
    error : type
        Exception class (a :class:`tli_verify.errors.TliError`) to raise.

    Returns
    -------
    str
        The text, without a leading byte-order mark.
    """
    raw = read_bytes(path, what=what, error=error)
    return _decode(raw, Path(path), what=what, error=error)


def read_bytes(path: PathLike, *, what: str, error: type[TliError]) -> bytes:
    """Read an input file's bytes (:func:`read_text`'s rules, no decoding): inside a snapshot
    (:mod:`tli_verify.snapshot`) the bytes the session keeps for it -- the ones its hash and
    its parse saw -- read once."""
    if isinstance(path, str) and path == "":
        raise error(f"empty path given for the {what} file")
    p = check_path_arg(path, what=f"{what} file", error=error)
    snap = _snapshot()
    kept = snap.kept(p) if snap is not None else None
    if kept is not None:  # read once in this session: the same bytes again
        return kept.data
    try:
        st = p.stat()
    except FileNotFoundError as exc:
        raise missing(error, f"{p}: cannot read {what} file: {_why(exc)}", p) from None
    except OSError as exc:
        raise error(f"{p}: cannot read {what} file: {_why(exc)}") from None
    if stat.S_ISDIR(st.st_mode):
        raise error(f"{p}: is a directory, expected a {what} file")
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{p}: not a regular file (a device, FIFO or socket), expected a {what} "
                    "file")
    if st.st_size > MAX_INPUT_BYTES:
        raise error(f"{p}: {what} file is {st.st_size} bytes, larger than the limit of "
                    f"{MAX_INPUT_BYTES} bytes (MAX_INPUT_BYTES)")
    try:
        with open(p, "rb") as handle:
            raw = handle.read(MAX_INPUT_BYTES + 1)
    except OSError as exc:
        raise error(f"{p}: cannot read {what} file: {_why(exc)}") from None
    if len(raw) > MAX_INPUT_BYTES:  # the file grew, or its size is not what stat said
        raise error(f"{p}: {what} file is larger than the limit of {MAX_INPUT_BYTES} bytes "
                    "(MAX_INPUT_BYTES)")
    if snap is not None:
        snap.keep(p, raw)
    return raw


def _decode(raw: bytes, p: Path, *, what: str, error: type[TliError]) -> str:
    """The text of an input file's bytes (:func:`read_text`'s checks after the read)."""
    if b"\x00" in raw:
        raise error(f"{p}: not a text file (contains NUL bytes)")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{p}: not UTF-8 text (byte {exc.start})") from None
    text = text.removeprefix("\ufeff")
    check_nesting(text, where=str(p), error=error)
    return text

# --------------------------------------------------------------------------------------------
# Bundled files
# --------------------------------------------------------------------------------------------


BUNDLED_FOLDERS = ("tasks", "specs", "demos", "models", "certificates", "sim")
"""The top-level folders of the bundled project (``sim`` holds ``franka/`` and
``PROVENANCE.md``; its ``assets/``, fetched at run time, is never packaged)."""


def _bundled_root_abs() -> Path:
    """The bundled project's root, absolute and resolved (see :func:`bundled_root`)."""
    package = resources.files("tli_verify")
    if not isinstance(package, os.PathLike):  # e.g. a zipped install: no real files
        raise TliError(f"tli-verify is installed as {package!r}, not as files on disk: the "
                       "bundled project needs an unpacked installation (pip install)")
    here = Path(os.fspath(package)).resolve()
    packaged = here / "data"
    if packaged.is_dir():  # an installed wheel: package data
        return packaged
    source_tree = here.parent
    if (source_tree / "pyproject.toml").is_file():  # a checkout or an editable install
        return source_tree
    raise TliError(f"the bundled project is missing (looked for {packaged}, and for a source "
                   f"tree at {source_tree}): the tli-verify installation is incomplete; "
                   "reinstall it (a wheel ships the bundled project under tli_verify/data/, "
                   "a checkout has it at its top)")


def _shown_path(p: Path) -> Path:
    """Relative to the working directory when under it, else absolute."""
    try:
        return p.relative_to(Path.cwd().resolve())
    except (ValueError, OSError):
        return p


def package_file(*parts: str) -> Path:
    """A file shipped inside the package (``package_file("deploy", "c", "tli_policy.c")``),
    found through :func:`importlib.resources.files`, so it is found in a checkout and in an
    installed wheel alike; the one place besides :func:`bundled_root` that locates package
    files."""
    return Path(str(resources.files("tli_verify").joinpath(*parts)))


def bundled_root() -> Path:
    """The root of the bundled project (the folder holding its ``tasks/``, ``specs/``,
    ``demos/``, ``models/``, ``certificates/`` and ``sim/``), wherever ``tli`` runs from.

    The one resolver of bundled files (:func:`bundled_dir` is a folder of it). The bundled
    project is package data: a built wheel ships it under ``tli_verify/data/`` (``setup.py``
    copies it there), found through :func:`importlib.resources.files`. A checkout or an
    editable install has no ``data/``: the project is the source tree itself (the folder with
    ``pyproject.toml`` next to the ``tli_verify`` package, the tree the CI gate checks).
    Looked up relative to the package, never to the working directory, so ``tli demo``
    behaves the same from anywhere.

    Returns
    -------
    Path
        A real path (wheels are installed unpacked), relative to the working directory when it
        lies under it (so messages read ``specs/scoop.toml`` in a checkout; ``.`` at its top),
        absolute otherwise.

    Raises
    ------
    TliError
        (exit 2) Neither place exists (a broken installation), saying where it looked.
    """
    return _shown_path(_bundled_root_abs())


def bundled_dir(name: str) -> Path:
    """A directory of the bundled project (``"specs"``, ``"demos"``, ``"sim"``, ...):
    ``bundled_root() / name`` (:func:`bundled_root`), checked to exist.

    Parameters
    ----------
    name : str
        A top-level folder of the bundled project (:data:`BUNDLED_FOLDERS`): ``"tasks"``,
        ``"specs"``, ``"demos"``, ``"models"``, ``"certificates"`` or ``"sim"``.

    Returns
    -------
    Path
        The directory, relative to the working directory when it lies under it, absolute
        otherwise. ``bundled_dir("models").parent`` is :func:`bundled_root`.

    Raises
    ------
    TliError
        (exit 2) The directory is missing (a broken installation), saying where it looked.
    """
    if name not in BUNDLED_FOLDERS:
        raise ValueError(f"bundled_dir: {name!r} is not a folder of the bundled project "
                         f"({', '.join(BUNDLED_FOLDERS)})")
    found = _bundled_root_abs() / name
    if not found.is_dir():
        raise TliError(f"the bundled {name}/ directory is missing ({found}): the tli-verify "
                       "installation is incomplete; reinstall it (a wheel ships the bundled "
                       "project under tli_verify/data/, a checkout has it at its top)")
    return _shown_path(found)

# --------------------------------------------------------------------------------------------
# JSON inputs: one reader, one schema validator (models, certificates, evidence, tasks)
# --------------------------------------------------------------------------------------------


def field_path(parts: Sequence[str | int]) -> str:
    """Format a JSON location like ``modes.a.components[2].cov`` (odd keys in ``["..."]``)."""
    out = ""
    for part in parts:
        if isinstance(part, int):
            out += f"[{part}]"
        elif _PLAIN_KEY.match(part):
            out += f".{part}" if out else part
        else:
            out += f"[{json.dumps(part)}]"
    return out or "(top level)"


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not allowed (numbers must be finite)")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):  # e.g. 1e400, which Python reads as inf
        raise ValueError(f"number {text} overflows a double (numbers must be finite)")
    return value


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object, refusing a repeated key (``json`` keeps the last one silently, so an
    inserted ``"total": 0`` before ``"total": 7`` would be read as 7 while a digest over the
    parsed document still matched)."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"duplicate key {key!r} in an object")
        out[key] = value
    return out


def _float_int(text: str) -> int:
    value = int(text)
    if abs(value) > _FLOAT_MAX:
        raise ValueError(f"integer {text[:20]}... is too large for a double (numbers must be "
                         "finite)")
    return value


_FLOAT_MAX = int(float.fromhex("0x1.fffffffffffffp+1023"))


def check_numbers(data: Any, *, where: str, error: type[TliError]) -> None:
    """Refuse an integer that does not fit a double anywhere in parsed TOML or JSON data
    (``lag = 1`` followed by 400 zeros): every reader turns numbers into floats, where such an
    integer would be an ``OverflowError``, not an error naming the field.

    Raises
    ------
    error
        ``"<where>: <field>: integer ... is too large for a double"``.
    """
    stack: list[tuple[tuple[str | int, ...], Any]] = [((), data)]
    while stack:
        at, value = stack.pop()
        if isinstance(value, dict):
            stack.extend(((*at, str(k)), v) for k, v in value.items())
        elif isinstance(value, list):
            stack.extend(((*at, i), v) for i, v in enumerate(value))
        elif isinstance(value, int) and not isinstance(value, bool) and \
                abs(value) > _FLOAT_MAX:
            digits = len(str(abs(value))) if value.bit_length() < 14_000 else "many"
            raise error(f"{where}: {field_path(at) or 'value'}: an integer of {digits} digits "
                        "is too large for a double (numbers must be finite)")


def parse_json(text: str) -> Any:
    """``json.loads`` as every reader of tli-verify does: no NaN or Infinity, no number that
    overflows a double, no duplicate key.

    Raises
    ------
    ValueError, json.JSONDecodeError
    """
    return json.loads(text, parse_constant=_reject_constant, parse_float=_finite_float,
                      parse_int=_float_int, object_pairs_hook=_unique_keys)


def read_json(path: str | os.PathLike[str], *, what: str, error: type[TliError]) -> Any:
    """Read a JSON file; errors name the file, line and column.

    NaN, Infinity, numbers that overflow a double (``1e400``) and duplicate keys are rejected
    (:func:`parse_json`); so are files larger than ``MAX_INPUT_BYTES``, non-regular files and
    brackets nested deeper than ``MAX_NESTING`` (:func:`tli_verify.io.read_text`).
    """
    text = read_text(path, what=what, error=error)
    try:
        return parse_json(text)
    except json.JSONDecodeError as exc:
        raise error(f"{path}: line {exc.lineno}, column {exc.colno}: invalid JSON: "
                    f"{exc.msg}") from None
    except ValueError as exc:
        raise error(f"{path}: invalid JSON: {exc}") from None
    except RecursionError:  # not reached after read_text's nesting check; kept as a backstop
        raise error(f"{path}: invalid JSON: nested too deeply") from None


@cache
def _validator(name: str) -> Any:
    import jsonschema

    schema = json.loads(resources.files("tli_verify").joinpath("schemas", name).read_text("utf-8"))
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    return cls(schema)


def validate_schema(data: Any, schema: str, *, where: str, error: type[TliError]) -> None:
    """Validate ``data`` against ``tli_verify/schemas/<schema>``.

    Raises
    ------
    error
        ``"<where>: <field path>: <what is wrong>"`` for the most relevant violation.
    """
    from jsonschema.exceptions import best_match

    errors = sorted(_validator(schema).iter_errors(data),
                    key=lambda e: [str(p) for p in e.absolute_path])
    if errors:
        worst = best_match(errors)
        message = worst.message if len(worst.message) <= 160 else worst.message[:157] + "..."
        raise error(f"{where}: {field_path(list(worst.absolute_path))}: {message}")
