"""Subcommand groups of the ``tli`` CLI; each module exposes ``register(subparsers)``.

Path conventions every command follows (checked once, before the handler runs, by
:func:`tli_verify.cli.check_paths`): an argument named ``output`` is the output file
(``-o/--output``), one named ``out`` is the output directory (``--out``); every other
:class:`~pathlib.Path` argument is an input file. Outputs that cannot be written, or that would
overwrite an input, are refused with exit 2 before any work. Output arguments use
:func:`output_path` as their type so an empty string is refused too.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from tli_verify.arguments import float_range as float_range  # the one set of validators
from tli_verify.arguments import int_range as int_range
from tli_verify.arguments import positive_float as positive_float
from tli_verify.errors import CheckFailed, TliError
from tli_verify.io import check_plan as check_plan  # the library's read/write rule


def output_path(text: str) -> Path:
    """``argparse`` type of ``-o``/``--out``: a non-empty path (``Path("")`` would be ``.``)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("empty path")
    return Path(text)


class _DefaultPath:
    """The ``const`` of an optional-argument output (``--evidence [PATH]``): given bare, the
    command's default path. A sentinel, not ``""``: an empty PATH typed by the user is refused
    by :func:`output_path` instead of silently meaning the default."""

    def __repr__(self) -> str:
        return "<default path>"


DEFAULT_PATH = _DefaultPath()


def chosen_path(value: object) -> Path | None:
    """The path the user chose for an ``nargs="?"`` output, or None for :data:`DEFAULT_PATH`."""
    return None if value is DEFAULT_PATH or value is None else Path(str(value))


PROJECT_FOLDERS = ("tasks", "specs", "models", "certificates")
"""The folders of a project the gate reads: a report must not land in one (a JSON report in
``certificates/`` would be read as a certificate, in ``models/`` as a model)."""


def check_report_dir(out: Path | str | None) -> None:
    """Refuse a report directory (``--out``) that is, or lies directly in, one of a project's
    :data:`PROJECT_FOLDERS`.

    Raises
    ------
    OutputError
        (exit 2) Naming the folder.
    """
    import os

    from tli_verify.errors import OutputError

    if out is None:
        return
    p = Path(os.path.abspath(out))
    for part in (p.name, p.parent.name):
        if part in PROJECT_FOLDERS:
            raise OutputError(f"{out}: a report directory inside a project's {part}/ folder: "
                              f"tli gate reads every file there as a {part[:-1]} file; "
                              "choose another --out")


def exit_code(exc: TliError) -> int:
    """The exit code of an error (``docs/design.md``, "Exit codes").

    2 for bad input (a :class:`ValueError` or :class:`OSError`, or any error that is not a
    verdict), 1 when a check said no (:class:`~tli_verify.errors.CheckFailed`).

    Parameters
    ----------
    exc : TliError

    Returns
    -------
    int
    """
    if isinstance(exc, ValueError | OSError) or not isinstance(exc, CheckFailed):
        return 2
    return 1
