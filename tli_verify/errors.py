"""The one exception hierarchy of tli-verify.

Every error a user can cause is a :class:`TliError`, in one of two families:

* **bad input** -- :class:`InputError` and its subclasses, which are also :class:`ValueError`
  (a missing input file is also :class:`FileNotFoundError`, see :func:`missing`): a file,
  field or argument that cannot be used;
* **a check said no** -- :class:`CheckFailed` and its subclasses: the input was well formed,
  and the answer is negative (unrealizable spec, certificate that does not re-check, gate
  that blocks).

The library only raises; what a family means to a shell (exit code 2 or 1, ``docs/design.md``
"Exit codes") is decided by the CLI (:func:`tli_verify.cli.exit_code`). Nothing else in the
package prints errors or warnings.
"""

from __future__ import annotations

import errno

__all__ = [
    "MAX_MESSAGE_CHARS",
    "AssetError",
    "CampaignError",
    "CertificateError",
    "CheckFailed",
    "DemoError",
    "EvidenceError",
    "ExportError",
    "GateError",
    "InputError",
    "ModelError",
    "OutputError",
    "SolverError",
    "SpecError",
    "TaskError",
    "TliError",
    "UnrealizableError",
    "WorkerLost",
    "bad_argument",
    "bad_input",
    "bad_type",
    "missing",
    "one_line",
]


MAX_MESSAGE_CHARS = 1000
"""Longest error message (:class:`~tli_verify.errors.TliError`), hence ``error:`` line, in
characters: a longer one keeps its start (the file, line and field) and its end (the reason)
and says how many characters of the middle were cut. Messages quote names and formulas from
their input, which may be megabytes long."""


class TliError(Exception):
    """Base class of every error raised on purpose by tli-verify.

    Parameters
    ----------
    message : str
        One line that names the file, line or field at fault (whitespace runs are folded, so
        the message stays one line; beyond :data:`MAX_MESSAGE_CHARS` its
        middle is cut, so a formula or name quoted from a multi-megabyte input never makes a
        multi-megabyte line, and the file named at its start and the reason at its end stay).
    """

    def __init__(self, message: str) -> None:
        super().__init__(one_line(str(message)))

    __str__ = BaseException.__str__  # not OSError's "[Errno 2] ..." for :func:`missing`


def one_line(message: str) -> str:
    """``message`` with its whitespace runs folded to one space and, when longer than
    :data:`MAX_MESSAGE_CHARS`, its middle replaced by a note of how many
    characters were cut (the start, which names the file, and the end, which says why, stay)."""
    text = " ".join(message.split())
    if len(text) <= MAX_MESSAGE_CHARS:
        return text
    keep = MAX_MESSAGE_CHARS - 40
    head, tail = text[:keep * 2 // 3], text[len(text) - keep // 3:]
    return f"{head} ... [{len(text) - len(head) - len(tail):,} characters cut] ... {tail}"


class InputError(TliError, ValueError):
    """Bad input: a file, field or argument that cannot be used (also a :class:`ValueError`)."""


class CheckFailed(TliError):
    """A check said no: the input is well formed and the answer is negative."""


class SpecError(InputError):
    """A task specification (TOML, LTL formula) is malformed or outside GR(1)."""


class TaskError(InputError):
    """A task file (state space, regions, sensors, goal, starts) is malformed, or a model, spec
    or evidence does not fit the task it runs on."""


class UnrealizableError(CheckFailed):
    """A strategy was requested from a GR(1) game the system cannot win."""


class DemoError(InputError):
    """A demonstration file is malformed or inconsistent with the spec."""


class ModelError(InputError):
    """A model file (per-mode LPV-DS and cuts) is malformed."""


class OutputError(InputError):
    """An output path cannot be written: a directory, under a regular file, not writable, or one
    of the command's own input files (which it would overwrite)."""


class SolverError(CheckFailed):
    """A numerical solver failed or returned a status other than optimal."""


class CertificateError(CheckFailed):
    """A certificate is malformed, or does not re-check exactly."""


class EvidenceError(CheckFailed):
    """Campaign evidence (``certificates/<name>.campaign.json``) is malformed, or does not bind
    the deployed files."""


class GateError(CheckFailed):
    """The deployment gate blocks: something is uncertified or tampered with."""


class ExportError(InputError):
    """A policy artifact (``tli export``) cannot be built or does not check: malformed, edited
    (its ``content_sha256`` is not the hash of its content), or beyond the C evaluator's
    limits."""


class AssetError(InputError):
    """A simulator asset (the MuJoCo Panda model files) cannot be fetched, fails its pinned
    sha256, or is missing: run ``python -m tli_verify.sim.assets fetch``."""


class WorkerLost(CheckFailed):
    """A worker running a batch of a campaign died more often than the retries allow."""


class CampaignError(InputError):
    """A campaign's configuration, case file or backend is unusable (exit 2)."""


_VARIANTS: dict[tuple[type, ...], type[TliError]] = {}


def _variant(cls: type[TliError], *builtins: type[Exception]) -> type[TliError]:
    """``cls`` that is also each of ``builtins`` (one class per combination, so ``except``
    clauses and pickling see a stable type)."""
    key = (cls, *builtins)
    found = _VARIANTS.get(key)
    if found is not None:
        return found
    extra = tuple(b for b in builtins if not issubclass(cls, b))
    for b in extra:  # e.g. TliError and InputError: the variant is InputError's
        if issubclass(b, cls):
            return _VARIANTS.setdefault(key, _variant(b, *(x for x in builtins if x is not b)))
    made: type[TliError] = cls if not extra else type(cls.__name__, (cls, *extra), {
        "__module__": cls.__module__, "__qualname__": cls.__qualname__, "__doc__": cls.__doc__,
        "__reduce__": _reduce, "_tli_variant": (cls, builtins)})
    return _VARIANTS.setdefault(key, made)


def _reduce(self: BaseException) -> tuple[object, ...]:
    cls, builtins = type(self)._tli_variant  # type: ignore[attr-defined]
    return (_rebuild, (cls, builtins, self.args[0] if self.args else ""))


def _rebuild(cls: type[TliError], builtins: tuple[type[Exception], ...],
             message: str) -> TliError:
    return _variant(cls, *builtins)(message)


def bad_input(cls: type[TliError], message: str) -> TliError:
    """An error of ``cls`` that is bad input (a :class:`ValueError`), e.g. a malformed
    certificate: a :class:`CertificateError` that is not the verdict "does not re-check".

    Parameters
    ----------
    cls : type
        A :class:`TliError` subclass.
    message : str

    Returns
    -------
    TliError
        An instance of ``cls`` and of :class:`ValueError`.
    """
    return _variant(cls, ValueError)(message)


def bad_type(cls: type[TliError], message: str) -> TliError:
    """An error of ``cls`` for an argument of the wrong type: also a :class:`TypeError` (and
    a :class:`ValueError`, as all bad input is), e.g. ``load_spec(None)``.

    Parameters
    ----------
    cls : type
        A :class:`TliError` subclass.
    message : str

    Returns
    -------
    TliError
        An instance of ``cls``, :class:`InputError` (a :class:`ValueError`) and
        :class:`TypeError`.
    """
    return _variant(cls, InputError, TypeError)(message)


def bad_argument(cls: type[TliError], message: str, *, builtin: type[Exception] = ValueError
                 ) -> TliError:
    """An error of ``cls`` for a bad argument of a public function: also an
    :class:`InputError` (whatever family ``cls`` is in: a bad argument of ``certify`` is a
    :class:`CertificateError` that is bad input, not the verdict) and ``builtin``
    (:class:`ValueError` for a value, :class:`TypeError` for a type).

    Returns
    -------
    TliError
    """
    return _variant(cls, InputError, builtin)(message)


def missing(cls: type[TliError], message: str, path: object) -> TliError:
    """An error of ``cls`` for an input file that does not exist (also a
    :class:`FileNotFoundError` with ``errno`` ENOENT and ``filename`` set).

    Parameters
    ----------
    cls : type
        A :class:`TliError` subclass (``SpecError`` for a spec file, ...).
    message : str
    path : path-like

    Returns
    -------
    TliError
        An instance of ``cls``, :class:`ValueError` and :class:`FileNotFoundError`.
    """
    exc = _variant(cls, ValueError, FileNotFoundError)(message)
    exc.errno = errno.ENOENT  # type: ignore[attr-defined]
    exc.strerror = "No such file or directory"  # type: ignore[attr-defined]
    exc.filename = str(path)  # type: ignore[attr-defined]
    return exc
