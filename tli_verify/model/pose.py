"""Cuts and modulation on the end-effector pose (issue 35; paper Sec. 5.2 and Thm. 1 on
``R^3 x S^3``).

A pose DS is two certified DS (:class:`PoseDS`): the position LPV-DS ``x_dot = f(x)`` on ``R^3``
with its ``P``, and the orientation DS (:class:`~tli_verify.ds.quaternion.QuaternionDS`), an
LPV-DS ``xi_dot = g(xi)`` in the tangent coordinates ``xi = log_{q*}(q)`` at ``q*`` with its own
``P``. ``log_{q*}`` is a diffeomorphism from the orientations less than a half turn from ``q*``
onto the open ball ``||xi|| < pi``, so a set of orientations is a set of tangent vectors and
back: an orientation cut is a plane in the chart, ``w . (xi - p) <= 0``.

**Invariance failures become cuts in each part.** A failure in position (the tool leaves the
mode's region) is the triple ``(x^0, x^{T_f-1}, x^{T_f})`` of appendix E.3; a failure in
orientation (the tool tilts out of the mode's allowed orientations) is the same triple of
orientations, mapped to the chart, and its cut is the same QCQP there
(:func:`tli_verify.boundary.cuts.solve_cut` with attractor ``0``): :meth:`PoseDS.cut_position`,
:meth:`PoseDS.cut_orientation`. Where the allowed orientations are a cone around an axis (the
tool's axis ``a`` within ``theta`` of a world axis ``u``), :func:`cone_cut` gives the plane
that supports the cone's image in the chart at a boundary orientation.

**Modulation keeps both.** Each part is modulated by its own cuts with its own ``P``
(:func:`tli_verify.boundary.modulation.modulated`, the corner guard and the control period
included), so Thm. 1 holds in each part: from inside its cuts no Euler step at the control
period crosses one, and ``V_x = (x - x*)^T P_x (x - x*)`` and ``V_q = xi^T P_q xi`` do not
decrease slower than nominal. The parts are not coupled (the two DS are learned separately, as
in SE(3) LPV-DS), so ``V = V_x + V_q`` is a Lyapunov function of the pose and the modulated
pose DS converges to ``(x*, q*)`` without leaving the cuts
(``tests/property/test_pose_modulation.py``). The controller integrates ``xi`` and maps back
with ``exp_{q*}``: the orientation it commands is always in the chart.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from tli_verify.boundary.cuts import Cut, InvarianceFailure, solve_cut
from tli_verify.boundary.modulation import ModulatedPolicy, check_control_period, modulated
from tli_verify.ds.lpvds import LPVDS
from tli_verify.ds.quaternion import QuaternionDS
from tli_verify.errors import ModelError
from tli_verify.rotations import quat_exp, quat_log, tilt

__all__ = ["PoseDS", "cone_cut", "tilt"]

FloatArray = npt.NDArray[np.float64]


def cone_cut(q_boundary: npt.ArrayLike, q_star: npt.ArrayLike, tool_axis: npt.ArrayLike,
             world_axis: npt.ArrayLike, *, step: float = 1e-6) -> Cut:
    """The plane in the chart at ``q*`` that supports the cone of allowed orientations at a
    boundary orientation: ``grad_xi tilt(exp(xi))`` at ``xi_b = log(q_b)`` as the normal, through
    ``xi_b`` (the tangent plane of the cone's image; the cone's image is not convex in
    general, so the plane keeps the part of it around ``xi_b``, which
    :class:`PoseDS` requires to hold ``0``).

    Parameters
    ----------
    q_boundary : array_like, shape (4,)
        An orientation on the cone's boundary (or the last allowed one before a tilt out).
    q_star : array_like, shape (4,)
    tool_axis, world_axis : array_like, shape (3,)
    step : float
        Central-difference step of the gradient (rad).

    Raises
    ------
    ModelError
        The gradient vanishes (the tool axis is along or against the world axis).
    """
    xi = quat_log(np.asarray(q_boundary, dtype=np.float64), q_star)
    E = np.eye(3) * step
    up = tilt(quat_exp(xi + E, q_star), tool_axis, world_axis)
    down = tilt(quat_exp(xi - E, q_star), tool_axis, world_axis)
    grad = (up - down) / (2 * step)
    norm = float(np.linalg.norm(grad))
    if not math.isfinite(norm) or norm < 1e-9:
        raise ModelError("cone cut: the tilt has no gradient here (tool axis along the world "
                         "axis)")
    return Cut(normal=grad / norm, point=xi)


@dataclass(frozen=True, eq=False)
class PoseDS:
    """A certified pose DS with cuts in position and in orientation (module docstring).

    Attributes
    ----------
    position : LPVDS
        On ``R^3`` (its ``P`` and attractor ``x*``).
    orientation : QuaternionDS
        In the tangent coordinates at ``q*``.
    position_cuts, orientation_cuts : tuple of Cut
        Planes in ``R^3`` and in the chart (``xi``), the mode on the side ``w . (. - p) <= 0``.
    dt : float or None
        Control period of the Euler steps the velocities are for (Thm. 1 at ``dt``).
    """

    position: LPVDS
    orientation: QuaternionDS
    position_cuts: tuple[Cut, ...] = ()
    orientation_cuts: tuple[Cut, ...] = ()
    dt: float | None = None
    _pos: ModulatedPolicy = field(init=False, repr=False)
    _ori: ModulatedPolicy = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.position.dim != 3:
            raise ModelError(f"a pose DS has a 3-D position DS, got {self.position.dim}-D")
        check_control_period(self.dt)
        object.__setattr__(self, "_pos", modulated(self.position, self.position_cuts,
                                                   self.position.attractor, dt=self.dt))
        object.__setattr__(self, "_ori", modulated(self.orientation.tangent,
                                                   self.orientation_cuts, np.zeros(3),
                                                   dt=self.dt))

    def velocity(self, X: npt.ArrayLike, Q: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Modulated velocities: ``x_dot`` (N, 3) and the tangent velocity ``xi_dot`` (N, 3)."""
        Xa = np.asarray(X, dtype=np.float64).reshape(-1, 3)
        xi = self.orientation.tangent_coordinates(np.asarray(Q, dtype=np.float64).reshape(-1, 4))
        return self._pos.velocity(Xa), self._ori.velocity(xi.reshape(-1, 3))

    def step(self, X: npt.ArrayLike, Q: npt.ArrayLike, dt: float
             ) -> tuple[FloatArray, FloatArray]:
        """One controller step: ``x + dt x_dot``, ``exp_{q*}(xi + dt xi_dot)``."""
        Xa = np.asarray(X, dtype=np.float64).reshape(-1, 3)
        xi = self.orientation.tangent_coordinates(
            np.asarray(Q, dtype=np.float64).reshape(-1, 4)).reshape(-1, 3)
        v = self._pos.velocity(Xa)
        w = self._ori.velocity(xi)
        return Xa + dt * v, np.asarray(quat_exp(xi + dt * w, self.orientation.attractor))

    def cut_position(self, failure: InvarianceFailure, *,
                     keep_inside: npt.ArrayLike | None = None) -> PoseDS:
        """The pose DS with the cut of a position failure (appendix E.3) added."""
        cut = solve_cut(failure, self.position.attractor, previous=self.position_cuts,
                        keep_inside=keep_inside)
        return PoseDS(self.position, self.orientation, (*self.position_cuts, cut),
                      self.orientation_cuts, self.dt)

    def cut_orientation(self, entry: npt.ArrayLike, last_inside: npt.ArrayLike,
                        outside: npt.ArrayLike, *, keep_inside: Sequence[npt.ArrayLike] = ()
                        ) -> PoseDS:
        """The pose DS with the cut of an orientation failure: the triple of orientations
        mapped to the chart, the same QCQP there (attractor ``0``)."""
        q_star = self.orientation.attractor
        chart = [quat_log(np.asarray(q, dtype=np.float64), q_star)
                 for q in (entry, last_inside, outside)]
        keep = (np.array([quat_log(np.asarray(q, dtype=np.float64), q_star)
                          for q in keep_inside]) if len(keep_inside) else None)
        cut = solve_cut(InvarianceFailure(*chart), np.zeros(3),
                        previous=self.orientation_cuts, keep_inside=keep)
        return self.with_orientation_cut(cut)

    def with_orientation_cut(self, cut: Cut) -> PoseDS:
        """The pose DS with one more orientation cut (e.g. :func:`cone_cut`).

        Raises
        ------
        ModelError
            The cut leaves ``q*`` (``xi = 0``) outside.
        """
        return PoseDS(self.position, self.orientation, self.position_cuts,
                      (*self.orientation_cuts, cut), self.dt)
