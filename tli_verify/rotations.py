"""Unit quaternions and rotations, scalar-first ``q = (w, x, y, z)``: pure numpy.

The one place of the rotation arithmetic: the Hamilton product, the logarithm and exponential of
SO(3) at a reference orientation (the tangent chart), rotation angles, rotating a vector and the
tilt of a tool axis. Used by the orientation DS (:mod:`tli_verify.ds.quaternion`), the pose DS
and its cuts (:mod:`tli_verify.model.pose`) and the orientation coordinates of pose tasks
(:mod:`tli_verify.tasks.orientation`); light on purpose (numpy only), so that reading a task does
not load the learners.

The chart at ``q*`` (the double cover handled): for a unit quaternion ``q``, the error
``e = q*^{-1} (x) q`` is put in the hemisphere ``w >= 0`` and mapped to its rotation vector,
``xi = log_{q*}(q) = theta u`` with ``e = (cos(theta/2), sin(theta/2) u)``, ``0 <= theta <= pi``;
the inverse is ``exp_{q*}(xi) = q* (x) (cos(|xi|/2), sin(|xi|/2) xi/|xi|)``. ``log_{q*}`` is a
bijection from the rotations at angle ``< pi`` from ``q*`` onto the open ball ``|xi| < pi``.

References
----------
Sun, Figueroa, "SE(3) Linear Parameter Varying Dynamical Systems for Globally Asymptotically
Stable End-Effector Control", IROS 2024 (orientation in the tangent space at the attractor).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = [
    "canonical_hemisphere",
    "left_jacobian",
    "quat_exp",
    "quat_log",
    "quat_multiply",
    "rotate",
    "rotation_angle",
    "tilt",
]

FloatArray = npt.NDArray[np.float64]


def quat_multiply(p: npt.ArrayLike, q: npt.ArrayLike) -> FloatArray:
    """Hamilton product ``p (x) q`` (scalar-first), broadcast over leading axes.

    Parameters
    ----------
    p, q : array_like, shape (..., 4)

    Returns
    -------
    ndarray, shape (..., 4)
    """
    a = np.asarray(p, dtype=np.float64)
    b = np.asarray(q, dtype=np.float64)
    w1, x1, y1, z1 = np.moveaxis(a, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=-1)


def _conjugate(q: FloatArray) -> FloatArray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def canonical_hemisphere(Q: npt.ArrayLike, reference: npt.ArrayLike) -> FloatArray:
    """Each quaternion with the sign that puts it in the hemisphere of ``reference``
    (``<q, reference> >= 0``): the same rotations, one representative each.

    Parameters
    ----------
    Q : array_like, shape (N, 4) or (4,)
    reference : array_like, shape (4,)

    Returns
    -------
    ndarray, same shape as ``Q``
    """
    Qa = np.asarray(Q, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    sign = np.where(Qa @ ref < 0.0, -1.0, 1.0)
    return np.asarray(Qa * (sign[..., None] if Qa.ndim > 1 else sign), dtype=np.float64)


def quat_log(Q: npt.ArrayLike, attractor: npt.ArrayLike) -> FloatArray:
    """Tangent coordinates ``xi = log_{q*}(q)``: the rotation vector of ``q*^{-1} (x) q``.

    Parameters
    ----------
    Q : array_like, shape (N, 4) or (4,)
        Unit quaternions (scalar-first); either sign of each gives the same ``xi``.
    attractor : array_like, shape (4,)
        ``q*``, unit.

    Returns
    -------
    ndarray, shape (N, 3) or (3,)
        ``|xi| = theta in [0, pi]``, the rotation angle from ``q*``.
    """
    Qa = np.asarray(Q, dtype=np.float64)
    single = Qa.ndim == 1
    Qa = np.atleast_2d(Qa)
    e = quat_multiply(_conjugate(np.asarray(attractor, dtype=np.float64)), Qa)
    e = e * np.where(e[:, :1] < 0.0, -1.0, 1.0)  # hemisphere of q*: w >= 0
    s = np.linalg.norm(e[:, 1:], axis=1)
    theta = 2.0 * np.arctan2(s, e[:, 0])
    # theta / s -> 2 / w as s -> 0 (w -> 1): the series keeps full precision near q*
    far = s > 1e-8
    ratio = np.where(far, theta / np.where(far, s, 1.0), 2.0 / np.where(far, 1.0, e[:, 0]))
    xi = e[:, 1:] * ratio[:, None]
    return xi[0] if single else xi


def quat_exp(Xi: npt.ArrayLike, attractor: npt.ArrayLike) -> FloatArray:
    """The inverse of :func:`quat_log`: ``q = q* (x) (cos(|xi|/2), sin(|xi|/2) xi/|xi|)``.

    Parameters
    ----------
    Xi : array_like, shape (N, 3) or (3,)
    attractor : array_like, shape (4,)

    Returns
    -------
    ndarray, shape (N, 4) or (4,)
        Unit quaternions in the hemisphere of ``q*`` for ``|xi| < pi``.
    """
    Xa = np.asarray(Xi, dtype=np.float64)
    single = Xa.ndim == 1
    Xa = np.atleast_2d(Xa)
    theta = np.linalg.norm(Xa, axis=1)
    half = 0.5 * theta
    # sin(theta/2)/theta -> 1/2 - theta^2/48 near 0
    sinc = np.where(theta > 1e-8, np.sin(half) / np.where(theta > 1e-8, theta, 1.0),
                    0.5 - theta**2 / 48.0)
    e = np.column_stack([np.cos(half), Xa * sinc[:, None]])
    q = quat_multiply(np.asarray(attractor, dtype=np.float64), e)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q[0] if single else q


def rotation_angle(Q: npt.ArrayLike, attractor: npt.ArrayLike) -> FloatArray:
    """Rotation angle (radians, in ``[0, pi]``) between each ``q`` and ``q*``.

    Parameters
    ----------
    Q : array_like, shape (N, 4) or (4,)
    attractor : array_like, shape (4,)

    Returns
    -------
    ndarray, shape (N,) or ()
    """
    xi = quat_log(Q, attractor)
    return np.asarray(np.linalg.norm(xi, axis=-1))


def rotate(q: FloatArray, v: FloatArray) -> FloatArray:
    """``R(q) v`` for unit scalar-first quaternions ``q`` (shape (N, 4)) and a vector ``v``."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    R = np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1),
    ], axis=1)
    return np.asarray(R @ v, dtype=np.float64)


def tilt(Q: npt.ArrayLike, tool_axis: npt.ArrayLike, world_axis: npt.ArrayLike) -> FloatArray:
    """The angle (rad) between the tool's axis ``R(q) a`` and a world axis ``u``.

    Parameters
    ----------
    Q : array_like, shape (N, 4) or (4,)
        Unit quaternions, scalar-first.
    tool_axis, world_axis : array_like, shape (3,)
        Unit vectors (normalised here).

    Returns
    -------
    ndarray, shape (N,) or ()
    """
    q = np.asarray(Q, dtype=np.float64)
    single = q.ndim == 1
    q = q.reshape(-1, 4)
    a = np.asarray(tool_axis, dtype=np.float64)
    u = np.asarray(world_axis, dtype=np.float64)
    a, u = a / np.linalg.norm(a), u / np.linalg.norm(u)
    c = np.clip(rotate(q, a) @ u, -1.0, 1.0)
    out = np.arccos(c)
    return out[0] if single else out


def left_jacobian(v: npt.ArrayLike) -> FloatArray:
    """The left Jacobian of SO(3) at the rotation vector ``v``: ``omega = J_l(v) vdot``.

    For ``R(t) = R_ref Exp(v(t))`` (the chart of :func:`quat_exp`) the angular velocity in the
    reference's frame is ``J_l(v) vdot`` (in the world frame ``R_ref J_l(v) vdot``), with::

        J_l(v) = I + (1 - cos t) / t^2 [v]x + (t - sin t) / t^3 [v]x^2,    t = |v|

    (series ``1/2 - t^2/24`` and ``1/6 - t^2/120`` below ``t = 1e-4``). It is invertible for
    ``|v| < 2 pi``, and ``J_l(0) = I``.

    Parameters
    ----------
    v : array_like, shape (3,)

    Returns
    -------
    ndarray, shape (3, 3)
    """
    va = np.asarray(v, dtype=np.float64).reshape(3)
    t2 = float(va @ va)
    t = float(np.sqrt(t2))
    if t < 1e-4:
        a, b = 0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0
    else:
        a, b = (1.0 - np.cos(t)) / t2, (t - np.sin(t)) / (t2 * t)
    k = np.array([[0.0, -va[2], va[1]], [va[2], 0.0, -va[0]], [-va[1], va[0], 0.0]])
    return np.asarray(np.eye(3) + a * k + b * (k @ k), dtype=np.float64)
