"""Field readers shared by the task-file parsers: finite numbers and vectors, named errors."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TaskError
from tli_verify.limits import MAX_ABS_VALUE

__all__ = ["number", "vector"]

FloatArray = npt.NDArray[np.float64]


def number(raw: Any, where: str, *, lo: float = -math.inf, hi: float = math.inf,
           integer: bool = False) -> float:
    """A finite number in ``[lo, hi]`` from a TOML value (bool refused)."""
    ok = isinstance(raw, int) if integer else isinstance(raw, int | float)
    if not ok or isinstance(raw, bool) or not _finite(raw) or not lo <= raw <= hi:
        kind = "an integer" if integer else "a finite number"
        raise TaskError(f"{where}: expected {kind} in [{lo:g}, {hi:g}], got {raw!r}")
    return float(raw)


def vector(raw: Any, dim: int, where: str, *, bound: float = MAX_ABS_VALUE) -> FloatArray:
    """``dim`` finite numbers from a TOML list, each ``|v| <= bound`` (default
    ``MAX_ABS_VALUE``: states, workspace bounds and starts share the demonstrations' range)."""
    if not isinstance(raw, list) or len(raw) != dim or not all(
            isinstance(v, int | float) and not isinstance(v, bool) and _finite(v)
            for v in raw):
        raise TaskError(f"{where}: expected a list of {dim} finite numbers")
    out = np.array(raw, dtype=np.float64)
    worst = float(np.abs(out).max()) if out.size else 0.0
    if worst > bound:
        raise TaskError(f"{where}: {worst:g} is outside the declared range |v| <= {bound:g} "
                        "(MAX_ABS_VALUE)")
    return out


def _finite(v: int | float) -> bool:
    """Whether a TOML number is a finite double (an int too large for one is not)."""
    try:
        return math.isfinite(v)
    except OverflowError:
        return False
