"""The target pose of the Franka loop: the DS velocity integrated, capped, leashed and bounded.

Per control period (:mod:`tli_verify.sim.loop`) the DS velocity is capped per axis
(:data:`SPEED_CAP`), integrated to the target pose ``z* <- z* + dt v``, the target kept on a
leash of the measured state (:data:`LEASH`) and inside the workspace (:func:`workspace`: the
demonstrations' box widened by :data:`MARGIN`); the velocity fed forward to the arm drops the
components that push into a bound the target rests at (:func:`feed_forward`).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TliError
from tli_verify.sim.franka_project import bundled_demos

__all__ = ["LEASH", "MARGIN", "SPEED_CAP", "clip_floats", "feed_forward", "feed_forward_floats",
           "inside_cuts",
           "workspace"]

FloatArray = npt.NDArray[np.float64]

LEASH = np.array([0.3, 0.3, 0.3, 0.15, 0.15, 0.15])
"""Per-axis distance (dm, dm, dm, rad x 3) the target may lead the measured pose (x, y, z,
rx, ry, rz: :mod:`tli_verify.sim.demos`; a 4-D DS takes its columns): held back,
the arm pulls with at most stiffness x leash (60 N and 7.5 N m on the Panda at 2,000 N/m and
50 Nm/rad: within the wrist's 12 N m)."""


SPEED_CAP = np.array([2.0, 2.0, 2.0, 2.0, 2.0, 2.0])
"""Per-axis speed limit of the DS velocity (dm/s, rad/s), direction kept."""


MARGIN = np.array([0.5, 0.5, 0.5, 0.3, 0.3, 0.3])
"""How far (dm, dm, dm, rad x 3) the target may leave the demonstrations' bounding box: the
workspace limits of the hand (the DS extrapolates poorly far from its data: after a spilling
tilt it turned the ladle over and drifted 1.5 dm sideways)."""


def workspace(margin: npt.ArrayLike = MARGIN) -> tuple[FloatArray, FloatArray]:
    """Bounds of the target pose: the bundled demonstrations' box widened by ``margin``.

    Parameters
    ----------
    margin : array_like, shape (6,), optional
        Per axis of the pose (dm, dm, dm, rad x 3), >= 0; default :data:`MARGIN`.

    Returns
    -------
    lo, hi : ndarray, shape (6,)
    """
    m = np.asarray(margin, dtype=np.float64)
    if m.shape != (6,) or not bool(np.all(np.isfinite(m) & (m >= 0))):
        raise TliError(f"workspace margin must be 6 finite numbers >= 0 (x, y, z, rx, ry, rz), "
                       f"got {margin!r}")
    box_lo, box_hi = _demo_box()
    return box_lo - m, box_hi + m


@functools.lru_cache(maxsize=1)
def _demo_box() -> tuple[FloatArray, FloatArray]:
    """The bundled demonstrations' bounding box (read once per process: every trial needs it)."""
    x = np.vstack([d.x for d in bundled_demos()])
    lo, hi = x.min(axis=0), x.max(axis=0)
    lo.setflags(write=False)
    hi.setflags(write=False)
    return lo, hi


def feed_forward(target: FloatArray, v: FloatArray, lo: FloatArray,
                 hi: FloatArray) -> FloatArray:
    """The velocity fed forward to the arm with the new target: the DS's ``v`` without the
    components that push into a workspace bound the target rests at.

    The arm is not driven on past a target the workspace holds at rest (fed the DS's velocity
    there, the tray went 1.7 cm beyond a target at the workspace's edge, across the target
    bowl's rim, and the pour left its mode on the loop's account, not the DS's).

    Parameters
    ----------
    target : ndarray, shape (n,)
        The new target, already clipped to ``[lo, hi]``.
    v : ndarray, shape (n,)
        The DS velocity it was integrated with (dm/s, rad/s).
    lo, hi : ndarray, shape (n,)
        The workspace (:func:`workspace`).

    Returns
    -------
    ndarray, shape (n,)
    """
    return np.array(feed_forward_floats(np.asarray(target, dtype=np.float64).tolist(),
                                  np.asarray(v, dtype=np.float64).tolist(),
                                  np.asarray(lo, dtype=np.float64).tolist(),
                                  np.asarray(hi, dtype=np.float64).tolist()))


def feed_forward_floats(target: list[float], v: list[float], lo: list[float],
                  hi: list[float]) -> list[float]:
    """:func:`feed_forward` on lists of floats (the loop's; the same comparisons)."""
    return [0.0 if (t >= h and a > 0.0) or (t <= low and a < 0.0) else a
            for t, a, low, h in zip(target, v, lo, hi, strict=True)]


def inside_cuts(target: FloatArray, cuts: tuple[Any, ...], anchor: FloatArray | None = None,
                passes: int = 4) -> FloatArray:
    """The target moved into the running mode's cut set (appendix E.3 half-spaces
    ``n . (x - p) <= 0``): projected onto each violated half-space in turn (``passes``
    rounds; alternating projections onto convex sets converge to a point of their
    intersection, slowly where planes are nearly parallel), then, if some cut is still
    violated and ``anchor`` (the measured state) satisfies them all, pulled along the segment
    to ``anchor`` to the first point inside every cut (exact: each half-space holds an
    interval of the segment that contains ``anchor``).

    Under the *measured* law the DS and its modulation act on the robot's measured state, but
    the impedance law pulls the arm towards the integrated target, which leads it by up to the
    leash: a target beyond a cut drags the robot out of the mode however the DS is modulated
    (measured: the pour's exits crossed cuts learned from earlier exits, 12 times in a trial).
    With the target kept inside too, the pull points into the cut set.

    Parameters
    ----------
    target : ndarray, shape (n,)
    cuts : tuple of Cut
        With ``normal`` and ``point``, shape (n,) each.
    anchor : ndarray, shape (n,), optional
        A state inside the cut set, if known.
    passes : int, optional

    Returns
    -------
    ndarray, shape (n,)
        ``target`` itself when no cut is violated.
    """
    if not cuts:
        return target
    x = target
    for _ in range(passes):
        moved = False
        for c in cuts:
            n = c.normal
            g = float(n @ (x - c.point))
            if g > 0.0:
                x = x - (g / float(n @ n)) * n
                moved = True
        if not moved:
            return x
    if anchor is None:
        return x
    gaps = [(float(c.normal @ (x - c.point)), float(c.normal @ (anchor - c.point)))
            for c in cuts]
    if max(g for g, _ in gaps) <= 0.0 or max(a for _, a in gaps) > 0.0:
        return x
    # g(s) = (1 - s) g_anchor + s g_x along anchor + s (x - anchor): <= 0 for s <= s_c
    s = min(a / (a - g) for g, a in gaps if g > 0.0)
    return anchor + s * (x - anchor)


def clip_floats(x: list[float], lo: list[float], hi: list[float]) -> list[float]:
    """``np.clip(x, lo, hi)`` of arrays, on floats, by numpy's rule: ``max(a, low)`` is ``a``
    when ``a > low`` or ``a`` is NaN, else ``low``; then ``min(., h)`` alike with ``<``
    (signed zeros and NaNs come out as numpy's; tested against it)."""
    out = []
    for a, low, h in zip(x, lo, hi, strict=True):
        a = a if a > low or a != a else low
        out.append(a if a < h or a != a else h)
    return out
