"""Field readers shared by the task-file parsers: finite numbers and vectors, named errors."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TaskError

__all__ = ["number", "vector"]

FloatArray = npt.NDArray[np.float64]


def number(raw: Any, where: str, *, lo: float = -math.inf, hi: float = math.inf,
           integer: bool = False) -> float:
    """A finite number in ``[lo, hi]`` from a TOML value (bool refused)."""
    ok = isinstance(raw, int) if integer else isinstance(raw, int | float)
    if not ok or isinstance(raw, bool) or not math.isfinite(raw) or not lo <= raw <= hi:
        kind = "an integer" if integer else "a finite number"
        raise TaskError(f"{where}: expected {kind} in [{lo:g}, {hi:g}], got {raw!r}")
    return float(raw)


def vector(raw: Any, dim: int, where: str) -> FloatArray:
    """``dim`` finite numbers from a TOML list."""
    if not isinstance(raw, list) or len(raw) != dim or not all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in raw):
        raise TaskError(f"{where}: expected a list of {dim} finite numbers")
    return np.array(raw, dtype=np.float64)
