"""Certified reachability deadlines from a certificate's decay rate (paper Thm. 1 (c), Lemma 2).

A certificate proves ``A_k^T P + P A_k + lambda P < 0`` for every component, so along the
nominal DS -- and along the modulated DS, whose corner guard keeps
``grad V . M(x) f(x) <= grad V . f(x)`` -- ``dV/dt <= -lambda V`` and

    V(x(t)) <= V(x(0)) exp(-lambda t).

From any start in a box ``[lo, hi]`` the state therefore enters the sublevel set
``{V <= c}`` by

    T = ln(max_{x in box} V(x) / c) / lambda,

and ``max_{x in box} V`` of the convex quadratic ``V`` is attained at a vertex of the box
(enumerated exactly up to 16 dimensions, bounded by ``lambda_max(P) |x - x*|^2`` above). The
sublevel set ``{V <= lambda_min(P) r^2}`` lies inside the ball of radius ``r`` around ``x*``.
The campaigns and the Franka loop use ``T`` as the reachability deadline instead of an
arbitrary horizon.

The bound is continuous-time: a sampled loop at period ``dt`` is certified to decrease ``V`` at
each Euler step of the nominal DS, but not at the rate ``exp(-lambda dt)`` per step, and not for
the modulated step; use ``T`` for a sampled loop only with that caveat.
"""

from __future__ import annotations

import itertools
import math
from fractions import Fraction

import numpy as np
import numpy.typing as npt

__all__ = ["ball_level", "max_v_on_box", "reach_deadline"]


def max_v_on_box(P: npt.ArrayLike, attractor: npt.ArrayLike, lo: npt.ArrayLike,
                 hi: npt.ArrayLike) -> float:
    """``max V(x)`` over the box ``lo <= x <= hi`` (a vertex; a safe upper bound above 16-D).

    Parameters
    ----------
    P : array_like, shape (n, n)
    attractor : array_like, shape (n,)
    lo, hi : array_like, shape (n,)

    Returns
    -------
    float
    """
    Pa = np.asarray(P, dtype=np.float64)
    xs = np.asarray(attractor, dtype=np.float64)
    lo_a, hi_a = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    if np.any(hi_a < lo_a):
        raise ValueError("box: hi must be >= lo in every coordinate")
    n = xs.shape[0]
    if n <= 16:
        corners = np.array(list(itertools.product(*zip(lo_a, hi_a, strict=True)))) - xs
        return float(np.einsum("ni,ij,nj->n", corners, Pa, corners).max())
    far = np.maximum(np.abs(lo_a - xs), np.abs(hi_a - xs))
    return float(np.linalg.eigvalsh(Pa).max() * far @ far)


def ball_level(P: npt.ArrayLike, radius: float) -> float:
    """A level ``c`` with ``{V <= c}`` inside the ball of ``radius`` around ``x*``.

    ``c = lambda_min(P) r^2`` (with a relative safety margin of 1e-9 for the eigenvalue)."""
    lam_min = float(np.linalg.eigvalsh(np.asarray(P, dtype=np.float64)).min())
    return lam_min * (1.0 - 1e-9) * radius * radius


def reach_deadline(P: npt.ArrayLike, attractor: npt.ArrayLike, rate: Fraction | float,
                   lo: npt.ArrayLike, hi: npt.ArrayLike, *, radius: float) -> float:
    """Time by which every start in ``[lo, hi]`` is within ``radius`` of ``x*`` (certified).

    Parameters
    ----------
    P : array_like, shape (n, n)
        The certificate's P.
    attractor : array_like, shape (n,)
    rate : Fraction or float
        The certificate's decay rate ``lambda > 0``.
    lo, hi : array_like, shape (n,)
        The box of starts.
    radius : float
        Radius of the target ball around ``x*``.

    Returns
    -------
    float
        Seconds (0 when the whole box is already inside the target set).

    Raises
    ------
    ValueError
        ``rate <= 0`` or ``radius <= 0``.
    """
    lam = float(rate)
    if not lam > 0:
        raise ValueError(f"rate: {rate} is not positive; no deadline follows")
    if not radius > 0:
        raise ValueError(f"radius: {radius} is not positive")
    v_max = max_v_on_box(P, attractor, lo, hi)
    c = ball_level(P, radius)
    return 0.0 if v_max <= c else math.log(v_max / c) / lam
