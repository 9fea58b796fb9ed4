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
from collections.abc import Callable
from pathlib import Path

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


def int_range(lo: int, hi: int | None = None) -> Callable[[str], int]:
    """An argparse ``type``: an integer in ``[lo, hi]`` (``hi`` None: no upper bound).

    A bad value is an ``ArgumentTypeError``, which the CLI turns into one ``error:`` line
    naming the option, exit 2.
    """

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if hi is not None and not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"must be between {lo} and {hi}, got {value}")
        if value < lo:
            raise argparse.ArgumentTypeError(f"must be >= {lo}, got {value}")
        return value

    return parse


def positive_float(text: str) -> float:
    """An argparse ``type``: a finite number > 0 (``inf``, ``nan`` and 0 refused, naming why)."""
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return value


def float_range(lo: float, hi: float, unit: str = "", *, zero: bool = False
                ) -> Callable[[str], float]:
    """An argparse ``type``: a finite number in ``[lo, hi]`` (``zero``: exactly 0 too), its
    unit named in the message. Every float option has such physical bounds
    (:doc:`/reference/limits`), so a subnormal period or an overflowing margin is refused
    before any work.
    """
    import math

    units = f" {unit}" if unit else ""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
        if zero and value == 0:
            return 0.0
        if not lo <= value <= hi:
            either = "0 or " if zero else ""
            raise argparse.ArgumentTypeError(f"must be {either}between {lo:g} and {hi:g}"
                                             f"{units}, got {text!r}")
        return value

    parse.bounds = (lo, hi, zero)  # type: ignore[attr-defined]
    return parse


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
