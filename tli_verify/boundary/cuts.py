"""Cutting planes that inner-approximate a mode boundary (paper Sec. 5.2, appendix F).

A cut is a hyperplane through a last in-mode state with a unit normal pointing out of the mode.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["Cut"]


@dataclass(frozen=True, slots=True)
class Cut:
    """One cutting plane ``{x : normal . (x - point) = 0}``; the mode is on the side
    ``normal . (x - point) <= 0``.

    Attributes
    ----------
    normal : ndarray, shape (n,)
        Unit outward normal ``w``.
    point : ndarray, shape (n,)
        A point on the plane (the last in-mode state ``x^{T_f - 1}``).
    """

    normal: npt.NDArray[np.float64]
    point: npt.NDArray[np.float64]
