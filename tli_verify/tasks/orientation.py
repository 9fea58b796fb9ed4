"""Pose tasks: orientation coordinates in the state, and regions on the orientation (cones).

A task's state may hold the tool's orientation next to its position. The task declares where::

    [state]
    names = ["x", "y", "z", "rx", "ry", "rz"]
    lower = [-0.5, -0.5, 0.0, -1.2, -1.2, -1.2]
    upper = [0.5, 0.5, 0.8, 1.2, 1.2, 1.2]
    orientation = { start = 3, reference = [1, 0, 0, 0] }   # scalar-first unit quaternion

Coordinates ``start .. start + 2`` are then the rotation vector ``v`` (radians) of the
orientation in the chart at the reference ``q_ref`` (:mod:`tli_verify.rotations`)::

    q(v) = q_ref (x) (cos(|v|/2), sin(|v|/2) v/|v|),    v = log_{q_ref}(q),

the rotation that turns the reference orientation into the state's, in the reference's frame.
The workspace box must lie inside the chart's ball ``|v| < pi`` (every corner), where the map is
one to one with a smooth inverse: every state of the workspace is one orientation, and a
measured orientation maps back to one state.

Why the learner, the certificate and the runtime carry over unchanged
    The LPV-DS of a mode, its Lyapunov function ``V = (x - x*)^T P (x - x*)`` and the exact
    certificate (paper eq. 5, Sec. 4.2, App. B) are statements about the state's coordinates;
    the orientation is the smooth function ``q(v)`` of them, so when ``v`` converges to ``v*``
    the orientation converges to ``q(v*)``, and a flow that stays in a sub-level set of ``V``
    inside the workspace stays inside the chart. This is the anchor's tangent-space
    construction (SE(3) LPV-DS: orientation by an LPV-DS in the tangent space) with one chart
    per task, at the task's reference, instead of one per attractor: the modes' attractors
    differ, the coordinates of the task do not. Position and orientation are learned as one
    DS on the whole state, with one ``P`` and mixing weights on the whole pose, and every
    ``A_k`` block-diagonal: position and orientation decoupled (as the anchor's two systems),
    unless ``tli learn --blocks`` says otherwise (:func:`tli_verify.tasks.project.pose_blocks`
    says why);
    certified as one system.

A cone on the orientation
    ``cone = { axis = [0, 0, 1], toward = [0, 0, 1], within = 20 }``: the states whose tool axis
    ``a`` (in the tool's frame), turned by ``q(v)``, lies within ``theta`` degrees of the world
    direction ``w`` -- "the tool tilted less than 20 degrees from vertical". Its membership is
    exact: ``tilt(v) = angle(R(q(v)) a, w) <= theta``. Its signed distance is the bound
    ``tilt(v) - theta``, of the true sign and never larger in size than the Euclidean distance
    of the state to the cone's boundary: ``tilt`` is 1-Lipschitz in ``v`` (the exponential map
    of SO(3) with its bi-invariant metric does not expand distances within ``|v| < 2 pi``, its
    curvature being positive (Rauch); the reference is an isometry; turning a unit vector by a
    rotation of angle ``phi`` moves it by at most ``phi``), and the other coordinates do not
    enter. A ball of that radius around a state therefore meets no boundary of the cone -- the
    one property the oracle's certified deadline needs of a signed distance
    (:meth:`tli_verify.tasks.task.Task.clearance`). ``tests/property/test_pose_task.py``
    checks the Lipschitz bound on random pairs.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation", CoRL 2022, Sec. 3 (modes as sets of
states sharing a sensor reading). Sun, Figueroa, "SE(3) Linear Parameter Varying Dynamical
Systems for Globally Asymptotically Stable End-Effector Control", IROS 2024.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TaskError
from tli_verify.limits import MAX_ABS_VALUE
from tli_verify.rotations import quat_exp, quat_log, rotate
from tli_verify.tasks.regions import Primitive

__all__ = ["MIN_WITHIN", "UNIT_TOLERANCE", "Cone", "OrientationChart", "parse_cone",
           "parse_orientation"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

UNIT_TOLERANCE = 1e-6
"""How far the norm of a declared reference quaternion may be from 1 (it is normalised)."""

MIN_WITHIN = 0.01
"""Narrowest cone, degrees (and ``180 - MIN_WITHIN`` the widest): far above the resolution of
``arccos`` near 1 and -1 (about 1e-6 degrees), so the computed tilt is on the right side of
``within`` wherever it is more than that resolution away from it."""


@dataclass(frozen=True, slots=True)
class OrientationChart:
    """Where a pose task keeps its orientation, and the chart's reference (module docstring).

    Attributes
    ----------
    start : int
        The first of the three orientation coordinates of the state.
    reference : tuple of float
        ``q_ref``, a unit quaternion ``(w, x, y, z)``.
    """

    start: int
    reference: tuple[float, float, float, float]

    @property
    def columns(self) -> slice:
        """The state's orientation coordinates."""
        return slice(self.start, self.start + 3)

    def quaternions(self, X: npt.ArrayLike) -> FloatArray:
        """The orientation of each state.

        Parameters
        ----------
        X : array_like, shape (N, n)

        Returns
        -------
        ndarray, shape (N, 4)
            Unit quaternions, scalar-first, in the hemisphere of the reference.
        """
        Xa = np.atleast_2d(np.asarray(X, dtype=np.float64))
        return np.atleast_2d(quat_exp(Xa[:, self.columns], self.reference))

    def coordinates(self, Q: npt.ArrayLike) -> FloatArray:
        """The orientation coordinates of unit quaternions (either sign of each).

        Parameters
        ----------
        Q : array_like, shape (N, 4)

        Returns
        -------
        ndarray, shape (N, 3)
        """
        return np.atleast_2d(quat_log(np.atleast_2d(np.asarray(Q, dtype=np.float64)),
                                      self.reference))

    def to_dict(self) -> dict[str, Any]:
        """The ``[state] orientation`` table."""
        return {"start": self.start, "reference": list(self.reference)}


def parse_orientation(raw: object, lo: FloatArray, hi: FloatArray, where: str
                      ) -> OrientationChart:
    """The ``[state] orientation`` table of a task file, checked against the workspace box.

    Parameters
    ----------
    raw : object
        The table (``start``, ``reference``).
    lo, hi : ndarray, shape (n,)
        The workspace box.
    where : str
        ``file: state.orientation`` for messages.

    Raises
    ------
    TaskError
        (exit 2) Naming the field: not a table, unknown keys, a start that leaves fewer than
        three coordinates, a reference that is not four finite numbers of norm 1, a workspace
        box not inside the chart's ball ``|v| < pi``.
    """
    if not isinstance(raw, dict):
        raise TaskError(f"{where}: expected a table {{ start = K, reference = [w, x, y, z] }}")
    unknown = sorted(set(raw) - {"start", "reference"})
    if unknown:
        raise TaskError(f"{where}.{unknown[0]}: unknown key (start, reference)")
    n = int(lo.size)
    if n < 3:
        raise TaskError(f"{where}: the state has {n} coordinate(s); an orientation needs 3")
    start = raw.get("start", n - 3)
    if isinstance(start, bool) or not isinstance(start, int) or not 0 <= start <= n - 3:
        raise TaskError(f"{where}.start: expected a whole number from 0 to {n - 3} (three "
                        f"coordinates of the {n})")
    ref_raw = raw.get("reference", [1.0, 0.0, 0.0, 0.0])
    if (not isinstance(ref_raw, list) or len(ref_raw) != 4
            or not all(isinstance(v, int | float) and not isinstance(v, bool)
                       and abs(float(v)) <= MAX_ABS_VALUE for v in ref_raw)):
        raise TaskError(f"{where}.reference: expected four numbers [w, x, y, z] of size at "
                        f"most {MAX_ABS_VALUE:g} (a unit quaternion, scalar first)")
    ref = np.array([float(v) for v in ref_raw])
    norm = float(np.linalg.norm(ref))
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        raise TaskError(f"{where}.reference: norm {norm:.9g}, not a unit quaternion (within "
                        f"{UNIT_TOLERANCE:g})")
    ref = ref / norm
    cols = slice(start, start + 3)
    corner = np.maximum(np.abs(lo[cols]), np.abs(hi[cols]))
    reach = float(np.linalg.norm(corner))
    if reach >= math.pi:
        raise TaskError(f"{where}: the workspace box reaches |v| = {reach:.4g} rad in the "
                        "orientation coordinates; it must lie inside the chart's ball |v| < pi "
                        "(center the box on the orientations of the task with reference)")
    return OrientationChart(start=start, reference=(float(ref[0]), float(ref[1]),
                                                    float(ref[2]), float(ref[3])))


@dataclass(frozen=True, slots=True, eq=False)
class Cone(Primitive):
    """The states whose tool axis, turned by their orientation, lies within ``within`` of a
    world direction (module docstring).

    Attributes
    ----------
    dim : int
        The state's dimension.
    chart : OrientationChart
    axis, toward : ndarray, shape (3,)
        The tool's axis (tool frame) and the world direction, unit.
    within : float
        The largest tilt, radians, in ``(0, pi)``.
    """

    dim: int
    chart: OrientationChart
    axis: FloatArray
    toward: FloatArray
    within: float

    _frame: tuple[FloatArray, FloatArray, FloatArray, float] = field(init=False, repr=False)
    """``(a, w', a x w', a . w')`` with ``w' = R(q_ref)^T toward``: the direction in the
    reference's frame, so that ``cos tilt = (R(Exp v) a) . w'``."""

    def __post_init__(self) -> None:
        for name in ("axis", "toward"):  # read-only copies, as every region's arrays
            v = np.array(getattr(self, name), dtype=np.float64)
            v.setflags(write=False)
            object.__setattr__(self, name, v)
        w = tilt_direction(np.array(self.chart.reference), self.toward)
        a = self.axis
        object.__setattr__(self, "_frame", (a, w, np.cross(a, w), float(a @ w)))

    def cos_tilt(self, V: FloatArray) -> FloatArray:
        """``cos`` of the tilt for orientation coordinates ``V`` (shape (N, 3)), by Rodrigues'
        formula ``R(Exp v) a = a cos t + (k x a) sin t + k (k . a)(1 - cos t)``, ``v = t k``,
        without forming quaternions (the closed loop reads the cone every control step)."""
        a, w, u, aw = self._frame
        with np.errstate(invalid="ignore", over="ignore"):  # a non-finite state: NaN, outside
            t2 = np.einsum("ij,ij->i", V, V)
            t = np.sqrt(t2)
            small = t < 1e-4
            ts = np.where(small, 1.0, t)
            sinc = np.where(small, 1.0 - t2 / 6.0, np.sin(ts) / ts)  # sin t / t
            versc = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(ts)) / (ts * ts))
            c = np.cos(t) * aw + sinc * (V @ u) + versc * (V @ a) * (V @ w)
        return np.asarray(np.clip(c, -1.0, 1.0))

    def tilt(self, X: npt.ArrayLike) -> FloatArray:
        """The angle between the turned tool axis and ``toward``, radians, shape (N,)."""
        Xa = np.atleast_2d(np.asarray(X, dtype=np.float64))
        if Xa.ndim != 2 or Xa.shape[1] != self.dim:
            raise TaskError(f"states must be (N, {self.dim}), got shape {np.shape(X)}")
        return np.asarray(np.arccos(self.cos_tilt(Xa[:, self.chart.columns])))

    def contains(self, X: npt.ArrayLike) -> BoolArray:
        """Membership of each state, shape (N,)."""
        return np.asarray(self.tilt(X) <= self.within)  # NaN (a non-finite state): outside

    def contains_one(self, x: Sequence[float]) -> bool:
        """Membership of one state, in plain Python (Rodrigues' formula, as
        :meth:`cos_tilt`)."""
        s = self.chart.start
        v0, v1, v2 = float(x[s]), float(x[s + 1]), float(x[s + 2])
        a, w, u, aw = self._frame
        t2 = v0 * v0 + v1 * v1 + v2 * v2
        if not math.isfinite(t2):  # no orientation: outside, as contains says
            return False
        t = math.sqrt(t2)
        if t < 1e-4:
            sinc, versc = 1.0 - t2 / 6.0, 0.5 - t2 / 24.0
        else:
            sinc, versc = math.sin(t) / t, (1.0 - math.cos(t)) / t2
        va = v0 * a[0] + v1 * a[1] + v2 * a[2]
        vw = v0 * w[0] + v1 * w[1] + v2 * w[2]
        vu = v0 * u[0] + v1 * u[1] + v2 * u[2]
        c = math.cos(t) * aw + sinc * vu + versc * va * vw
        return math.acos(min(1.0, max(-1.0, c))) <= self.within

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        """Unbounded: the cone constrains the orientation only, and every orientation
        coordinate reaches the whole chart."""
        return np.full(self.dim, -np.inf), np.full(self.dim, np.inf)

    def leaves(self) -> tuple[Primitive, ...]:
        """The cone itself."""
        return (self,)

    def signed_distance(self, X: npt.ArrayLike) -> FloatArray:
        """``tilt - within``: the sign of the true signed distance, never larger in size
        (a lower bound on the distance to the boundary; module docstring)."""
        return np.asarray(self.tilt(X) - self.within)

    def to_dict(self) -> dict[str, Any]:
        """The ``cone`` table (``within`` in degrees)."""
        return {"cone": {"axis": self.axis.tolist(), "toward": self.toward.tolist(),
                         "within": math.degrees(self.within)}}


def tilt_direction(reference: FloatArray, toward: FloatArray) -> FloatArray:
    """``R(q_ref)^T toward``: a world direction in the reference orientation's frame."""
    conj = reference * np.array([1.0, -1.0, -1.0, -1.0])
    return np.asarray(rotate(conj[None], np.asarray(toward, dtype=np.float64))[0])


def _unit3(raw: object, where: str) -> FloatArray:
    if (not isinstance(raw, list) or len(raw) != 3
            or not all(isinstance(v, int | float) and not isinstance(v, bool)
                       and abs(float(v)) <= MAX_ABS_VALUE for v in raw)):
        raise TaskError(f"{where}: expected three numbers of size at most {MAX_ABS_VALUE:g} "
                        "(a direction)")
    v = np.array([float(t) for t in raw])
    norm = float(np.linalg.norm(v))
    if norm < 1e-9:
        raise TaskError(f"{where}: the zero vector is no direction")
    out = v / norm
    out.setflags(write=False)
    return out


def parse_cone(raw: object, *, dim: int, chart: OrientationChart | None, where: str) -> Cone:
    """A ``cone = { axis, toward, within }`` shape table.

    Raises
    ------
    TaskError
        (exit 2) The task has no orientation coordinates; unknown or missing keys; a direction
        that is not three finite numbers or is zero; ``within`` not in ``(0, 180)`` degrees.
    """
    if chart is None:
        raise TaskError(f"{where}: a cone is a region on the orientation: the task's [state] "
                        "needs orientation = { start = K, reference = [w, x, y, z] }")
    if not isinstance(raw, dict):
        raise TaskError(f"{where}: expected a table {{ axis = [..], toward = [..], within = "
                        "DEGREES }")
    unknown = sorted(set(raw) - {"axis", "toward", "within"})
    if unknown:
        raise TaskError(f"{where}.{unknown[0]}: unknown key (axis, toward, within)")
    for key in ("axis", "toward", "within"):
        if key not in raw:
            raise TaskError(f"{where}.{key}: missing")
    within = raw["within"]
    if (isinstance(within, bool) or not isinstance(within, int | float)
            or not MIN_WITHIN <= float(within) <= 180.0 - MIN_WITHIN):
        raise TaskError(f"{where}.within: expected degrees from {MIN_WITHIN:g} to "
                        f"{180.0 - MIN_WITHIN:g}, got {within!r}")
    return Cone(dim=dim, chart=chart, axis=_unit3(raw["axis"], f"{where}.axis"),
                toward=_unit3(raw["toward"], f"{where}.toward"),
                within=math.radians(float(within)))
