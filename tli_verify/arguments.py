"""Argument checks at the public API's boundary: one line naming the parameter.

Every public function checks its arguments before any work and raises an
:class:`~tli_verify.errors.InputError` that is also the builtin it means -- a
:class:`TypeError` for an argument of the wrong type (``None`` where a path is needed, a
string where numbers are), a :class:`ValueError` for one of the right type outside its range
(``seed=-1``, ``steps=-1``, a NaN, a vector of the wrong dimension) -- never an
``AttributeError`` or a numpy error from deep inside.
"""

from __future__ import annotations

import argparse
import math
import numbers
import os
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from tli_verify.errors import InputError, TliError, bad_argument, bad_type
from tli_verify.limits import MAX_NAME_BYTES

__all__ = ["check_choice", "check_float", "check_int", "check_path", "check_type",
           "check_vector", "float_range", "int_range", "positive_float"]


def check_path(value: Any, name: str, *, error: type[TliError] = InputError) -> Path:
    """``value`` as a :class:`~pathlib.Path`: a non-empty ``str`` or ``os.PathLike``.

    Raises
    ------
    InputError
        Also a :class:`TypeError` (another type: ``None``, an int, bytes) or a
        :class:`ValueError` (an empty path, a NUL byte, a component longer than
        ``MAX_NAME_BYTES``).
    """
    if isinstance(value, bool) or not isinstance(value, str | os.PathLike):
        raise bad_type(error, f"{name}: expected a path (str or os.PathLike), got "
                       f"{type(value).__name__}")
    text = os.fspath(value)
    if not isinstance(text, str):
        raise bad_type(error, f"{name}: expected a text path, got {type(text).__name__}")
    if text == "":
        raise bad_argument(error, f"{name}: an empty path")
    if "\0" in text:
        raise bad_argument(error, f"{name}: a path with a NUL byte")
    for part in Path(text).parts:
        try:
            size = len(os.fsencode(part))
        except UnicodeError:
            raise bad_argument(error, f"{name}: cannot be encoded for the file system") from None
        if size > MAX_NAME_BYTES:
            raise bad_argument(error, f"{name}: {_short(text)} has a component of {size} bytes, "
                            f"longer than {MAX_NAME_BYTES} (MAX_NAME_BYTES)")
    return Path(text)


def check_int(value: Any, name: str, lo: int | None = None, hi: int | None = None, *,
              error: type[TliError] = InputError) -> int:
    """``value`` as an int in ``[lo, hi]`` (bools are not ints here).

    Raises
    ------
    InputError
        Also a :class:`TypeError` (not an integer) or :class:`ValueError` (out of range).
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise bad_type(error, f"{name}: expected an integer, got {type(value).__name__} "
                       f"{_short(value)}")
    v = int(value)
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        span = f"[{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}]"
        raise bad_argument(error, f"{name}: {v} is outside {span}")
    return v


def check_float(value: Any, name: str, *, lo: float | None = None, hi: float | None = None,
                error: type[TliError] = InputError) -> float:
    """``value`` as a finite float in ``[lo, hi]``.

    Raises
    ------
    InputError
        Also a :class:`TypeError` (not a real number) or :class:`ValueError` (NaN, infinite,
        out of range).
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise bad_type(error, f"{name}: expected a number, got {type(value).__name__} "
                       f"{_short(value)}")
    try:
        v = float(value)
    except OverflowError:
        raise bad_argument(error, f"{name}: {_short(value)} is too large for a float") from None
    if not math.isfinite(v):
        raise bad_argument(error, f"{name}: expected a finite number, got {v}")
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise bad_argument(error, f"{name}: {v:g} is outside [{lo}, {hi}]")
    return v


def check_vector(value: Any, name: str, dim: int | None = None, *,
                 error: type[TliError] = InputError) -> Any:
    """``value`` as a finite float array of shape ``(dim,)``.

    Returns
    -------
    numpy.ndarray, shape (dim,)

    Raises
    ------
    InputError
        Also a :class:`TypeError` (not numbers: a string, None) or :class:`ValueError` (a NaN
        or infinity, another shape).
    """
    import numpy as np

    if value is None or isinstance(value, str | bytes | dict):
        raise bad_type(error, f"{name}: expected a sequence of numbers, got "
                       f"{type(value).__name__} {_short(value)}")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise bad_type(error, f"{name}: expected a sequence of numbers, got "
                       f"{_short(value)}") from None
    want = "(n,)" if dim is None else f"({dim},)"
    if arr.ndim != 1 or (dim is not None and arr.shape[0] != dim):
        raise bad_argument(error, f"{name}: expected shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise bad_argument(error, f"{name}: expected finite numbers, got {_short(value)}")
    return arr


def check_choice(value: Any, name: str, choices: Iterable[str], *,
                 error: type[TliError] = InputError) -> str:
    """``value`` as one of ``choices``.

    Raises
    ------
    InputError
        Also a :class:`ValueError` naming the choices (a :class:`TypeError` for a non-string).
    """
    options = tuple(choices)
    if not isinstance(value, str):
        raise bad_type(error, f"{name}: expected one of {', '.join(options)}, got "
                       f"{type(value).__name__}")
    if value not in options:
        raise bad_argument(error, f"{name}: expected one of {', '.join(options)}, got {value!r}")
    return value


def check_type(value: Any, name: str, expected: type | tuple[type, ...], what: str, *,
               error: type[TliError] = InputError) -> Any:
    """``value`` if it is an instance of ``expected``.

    Raises
    ------
    InputError
        Also a :class:`TypeError` naming ``what`` was expected.
    """
    if not isinstance(value, expected):
        raise bad_type(error, f"{name}: expected {what}, got {type(value).__name__}")
    return value


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


# ------------------------------------------------------------------ command-line validators
# argparse ``type`` functions (the CLI's and the pytest plugin's options): a bad value is an
# ``ArgumentTypeError``, which the CLI turns into one ``error:`` line naming the option.

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


def _finite_number(text: str) -> float:
    """A command-line number: finite (``inf`` and ``nan`` refused), else an argparse error
    naming why."""
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """An argparse ``type``: a finite number > 0 (``inf``, ``nan`` and 0 refused, naming why)."""
    value = _finite_number(text)
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
    units = f" {unit}" if unit else ""

    def parse(text: str) -> float:
        value = _finite_number(text)
        if zero and value == 0:
            return 0.0
        if not lo <= value <= hi:
            either = "0 or " if zero else ""
            raise argparse.ArgumentTypeError(f"must be {either}between {lo:g} and {hi:g}"
                                             f"{units}, got {text!r}")
        return value

    parse.bounds = (lo, hi, zero)  # type: ignore[attr-defined]
    return parse
