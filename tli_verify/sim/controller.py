"""Cartesian impedance (operational-space) pose control of the Panda, with null-space posture
control, tracking a target integrated from the LTL-DS velocity (paper Sec. 7.2).

The DS state (the paper's Fig. 11 uses y, z, pitch; here the full pose)
    ``z = (x, y, z, rx, ry, rz)``, shape (6,): the world position (m) of the controlled site
    (the ladle's tray, or by default Franka's ``tcp`` frame) and the rotation vector ``v``
    (rad) of its orientation in the chart at the nominal orientation ``R0``::

        R(v) = R0 Exp(v),        v = Log(R0^T R),        |v| < pi

    the chart of pose tasks (:mod:`tli_verify.tasks.orientation`, ``q = q_ref (x) Exp(v)``:
    ``v`` in the tool's own frame at ``R0``). ``R0`` defaults to :data:`R0_DOWN` (tool z axis
    pointing down, tool x along world +y, tool y along world +x: the ``tcp`` frame at the
    Menagerie home posture). The velocity map: ``omega = R0 J_l(v) vdot`` (world frame;
    :func:`~tli_verify.rotations.left_jacobian`). :meth:`DSStateMap.ds_state`,
    :meth:`DSStateMap.target_pose_from_ds_state` and :meth:`DSStateMap.twist_from_ds_velocity`
    implement it.

The control law (Khatib's operational-space formulation, Cartesian impedance)
    With the site Jacobian ``J`` (6 x 7: linear rows from ``mj_jacSite``, then angular), the 7x7
    *arm block* ``M`` of the joint-space mass matrix (the same numbers ``mj_fullM`` gives;
    beads or other free bodies never enter it) and ``Lambda = (J M^-1 J^T)^-1``::

        F   = Lambda [Kp e - Kd (J qdot - v_d)]                  (6,)  e = (p_d - p, log(R_d R^T))
        tau = J^T F + (I - J^T Jbar^T) M [Kn (q_n - q) - Dn qdot] + qfrc_bias     (7,)

    with ``Jbar = M^-1 J^T Lambda`` (dynamically consistent null-space projector) and the bias
    ``qfrc_bias = C(q, qdot) qdot + g(q)`` (gravity and Coriolis compensation). Per task-space
    axis this makes the error a unit-mass spring-damper ``e'' + Kd e' + Kp e = 0``: with the
    default gains (:class:`Gains`) ``Kp = 400 /s^2``, ``Kd = 40 /s`` (critically damped, natural
    frequency 20 rad/s) for position and orientation alike, and ``Kn = 25 /s^2``, ``Dn = 10 /s``
    for the posture. Torques are saturated at the Panda's limits (87/87/87/87/12/12/12 N m);
    every call reports the tracking error and how many joints saturated.

Sampled-data check (python-control)
    The controller is evaluated once per control period ``T`` and held (zero-order hold) over
    the ``mj_step`` substeps. :func:`sampled_data_spectral_radius` discretises the per-axis
    closed loop (double integrator under a PD law held over ``T``) with ``control.c2d`` and
    returns the spectral radius of the sampled closed loop; below 1 means stable. With the
    default gains it is 0.965 at ``T = 2 ms`` (control at every step), 0.854 at ``T = 10 ms``
    (5 substeps), exactly 1 at ``T = 50 ms`` and above 1 beyond (1.56 at 60 ms): the loop has a
    5x margin on the control period at 10 ms. This is the linearised, decoupled model (exact when
    ``Lambda``, ``J`` and the bias are exact); contacts and saturation are not in it.
    :func:`closed_loop_spectral_radius` checks the simulated loop itself (the period map of the
    arm's 14-D state, differentiated at rest at the home posture): 0.997 at 2 ms, 0.985 at
    10 ms, 0.971 at 20 ms, 0.942 at 40 ms, 1.03 at 50 ms and 1.58 at 60 ms (the model: 1.56):
    it loses stability where the decoupled model says; its slowest mode (0.997 at 2 ms, a time
    constant of about 0.7 s) is the null-space posture loop, not the task-space impedance.

Fast path
    All buffers are allocated once (:class:`ImpedanceController`). A call makes one
    ``mj_jacSite`` and three quaternion calls, reads ``M`` from ``data.M`` through a precomputed
    index (:func:`arm_mass_index`), and does two Cholesky solves (LAPACK ``dposv``: ``M^-1 J^T``,
    then ``Lambda`` applied to the impedance and posture terms at once), no explicit inverse and
    no Python loop over joints. The views of ``MjData``'s arrays it reads (arm velocities,
    bias, passive forces, site pose, ``M``, the motors' ``ctrl``) are made once per ``MjData``
    (each attribute access of ``MjData`` builds a new array object). The torque loop's entry
    :meth:`ImpedanceController.compute_fast` (what :class:`~tli_verify.sim.demos.PandaRig` calls
    every physics step) takes the target as floats and returns a list; the elementwise work on
    the 6- and 7-vectors (errors, damping, the external-torque filter, the posture term, the
    limit guard's :meth:`~tli_verify.sim.franka_limits.LimitGuard.apply_lists`) runs on Python
    floats, written out component by component (a comprehension's frame and ``zip`` cost more
    than the arithmetic on 7 numbers), which round every operation as numpy's elementwise
    operations do, in the same order; the matrix products stay numpy's (BLAS: their rounding is
    the library's), written into preallocated ``out=`` buffers of the layout numpy would
    allocate; the norms of the task wrench are BLAS's whenever they could reach their caps. The
    external wrench's column of the second solve is filled and solved when
    :attr:`ImpedanceController.external_wrench` is read (once per control period in the loop),
    not at every physics step. The torques are bit-identical to the plain numpy formulation
    (``tests/unit/test_panda_torque_loop_exact.py``, exact on every branch). About 17 us per
    call in a tight loop (22 us before the per-component rewrite), 25-40 us inside the scene's
    closed loop (caches cold after each ``mj_step``; shared cores).

Tracking a DS (the loop)
    Each control period ``T``: ``zdot = f(z_t)`` from the policy (evaluated at the target: the
    sampled-data system a certificate at period ``T`` covers; or at the measured state
    :meth:`ImpedanceController.ds_state`); ``z_t = integrate_ds_target(z_t,
    zdot, T[, z_actual, leash])``; ``pos, quat = target_pose_from_ds_state(z_t)``;
    ``step(data, pos, quat, twist_from_ds_velocity(zdot, z_t), substeps)``. Measured bound
    (``tests/unit/test_sim_controller.py``): for a DS with speed <= 0.25 m/s and pitch rate <=
    0.8 rad/s, the site stays within 1 cm (measured 5-6 mm) and 0.03 rad of pitch (measured
    0.013-0.019 rad) of the integrated target, at ``T`` = 2 ms and 10 ms, without saturating.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray
from scipy.linalg import lapack

from tli_verify.errors import ModelError, SolverError
from tli_verify.rotations import left_jacobian
from tli_verify.sim.franka_limits import CartesianImpedance, LimitGuard
from tli_verify.sim.robot import HOME_QPOS, TORQUE_LIMITS, Panda

__all__ = [
    "R0_DOWN",
    "DSStateMap",
    "Gains",
    "ImpedanceController",
    "TrackingStats",
    "arm_mass_index",
    "closed_loop_spectral_radius",
    "integrate_ds_target",
    "quat_to_mat",
    "sampled_data_spectral_radius",
]

FloatArray = NDArray[np.float64]
_Prev = tuple[float, FloatArray, list[float], list[float], list[float], list[float]]
"""The last call's time, arm mass block, joint velocities, bias, torques and passive forces."""

_dposv = lapack.dposv  # Cholesky solve of a symmetric positive-definite system
#: Added to the diagonal of Lambda^-1 (1/kg, kg^-1 m^-2): damped least squares near singularities.
_LAMBDA_DAMPING = 1e-6

#: Largest task force (N) and torque (N m) the impedance law asks at the controlled site
#: (:class:`~tli_verify.sim.franka_limits.CartesianImpedance` mode).
TASK_FORCE_LIMIT = 35.0
TASK_TORQUE_LIMIT = 6.0
# Squared norms below these are inside the limits whatever BLAS rounds (ImpedanceController.
# _impedance_force): a sum of three squares is within a relative 3.4e-16 of the exact one.
_FORCE_SQ_SAFE = TASK_FORCE_LIMIT * TASK_FORCE_LIMIT * (1.0 - 1e-9)
_TORQUE_SQ_SAFE = TASK_TORQUE_LIMIT * TASK_TORQUE_LIMIT * (1.0 - 1e-9)


def _cap3(x: float, y: float, z: float, limit: float) -> tuple[float, float, float]:
    """``(x, y, z)`` scaled to norm ``limit`` when its norm (numpy's: ``sqrt`` of the BLAS
    ``ddot``, as the plain law computes it) exceeds it; else unchanged."""
    v = np.array((x, y, z))
    n = math.sqrt(float(v @ v))
    if n > limit:
        s = limit / n
        return x * s, y * s, z * s
    return x, y, z


#: Nominal orientation at pitch 0: tool z down, tool x along world +y, tool y along world +x.
R0_DOWN: FloatArray = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def quat_to_mat(quat: FloatArray) -> FloatArray:
    """Unit quaternion ``(w, x, y, z)`` (MuJoCo order), shape (4,), to a rotation matrix (3, 3)."""
    out = np.empty(9)
    mujoco.mju_quat2Mat(out, np.asarray(quat, dtype=np.float64))
    return out.reshape(3, 3)


@dataclass(frozen=True, slots=True)
class DSStateMap:
    """The map between the robot and the 6-D DS state ``(x, y, z, rx, ry, rz)`` (module
    docstring: position, and the rotation vector in the chart at ``r0``).

    Attributes
    ----------
    site : int
        Site id of the controlled point (its position is the DS position).
    r0 : ndarray, shape (3, 3)
        The chart's reference orientation (default :data:`R0_DOWN`).
    """

    site: int
    r0: FloatArray = field(default_factory=lambda: R0_DOWN.copy())
    _q0: tuple[float, float, float, float] = field(init=False, repr=False, compare=False)
    _q0_conj: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        r0 = np.asarray(self.r0, dtype=np.float64)
        if r0.shape != (3, 3) or not np.allclose(r0 @ r0.T, np.eye(3), atol=1e-9) \
                or np.linalg.det(r0) < 0:
            raise ModelError("DSStateMap: field 'r0' is not a 3x3 rotation matrix")
        q0 = np.empty(4)
        mujoco.mju_mat2Quat(q0, r0.ravel())
        object.__setattr__(self, "_q0", tuple(float(v) for v in q0))
        object.__setattr__(self, "_q0_conj", q0 * np.array([1.0, -1.0, -1.0, -1.0]))

    @property
    def reference(self) -> tuple[float, float, float, float]:
        """The chart's reference as a unit quaternion ``(w, x, y, z)`` (a task's
        ``[state] orientation.reference``)."""
        return self._q0

    def ds_state(self, data: Any) -> FloatArray:
        """The DS state ``(x, y, z, rx, ry, rz)`` of the site, shape (6,), as of the last
        kinematics: ``v = Log(r0^T R)``, the rotation angle ``|v|`` in ``[0, pi]``."""
        q, e, v = np.empty(4), np.empty(4), np.empty(3)
        mujoco.mju_mat2Quat(q, data.site_xmat[self.site])
        mujoco.mju_mulQuat(e, self._q0_conj, q)
        mujoco.mju_quat2Vel(v, e, 1.0)  # the shorter way: angle in [0, pi]
        x, y, z = data.site_xpos[self.site].tolist()
        rx, ry, rz = v.tolist()
        return np.array((x, y, z, rx, ry, rz))

    def target_pose_from_ds_state(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Target site pose for a DS state ``z`` (shape (6,)).

        Returns
        -------
        pos : ndarray, shape (3,)
            ``z[:3]`` (m, world frame).
        quat : ndarray, shape (4,)
            Unit quaternion ``(w, x, y, z)`` of ``r0 Exp(z[3:])``.
        """
        za = np.asarray(z, dtype=np.float64).reshape(6)
        quat = np.empty(4)
        self.target_quat_into(float(za[3]), float(za[4]), float(za[5]), quat)
        return za[:3].copy(), quat

    def target_quat_into(self, rx: float, ry: float, rz: float, out: FloatArray) -> None:
        """The quaternion ``q0 (x) Exp(v)`` of :meth:`target_pose_from_ds_state` at the
        rotation vector ``v = (rx, ry, rz)`` (rad), written to ``out`` (shape (4,)) on floats
        (the torque loop calls it every physics step)."""
        t = math.sqrt(rx * rx + ry * ry + rz * rz)
        c = math.cos(0.5 * t)
        k = math.sin(0.5 * t) / t if t > 1e-8 else 0.5 - t * t / 48.0
        b, cc, d = rx * k, ry * k, rz * k
        w0, x0, y0, z0 = self._q0
        out[0] = w0 * c - x0 * b - y0 * cc - z0 * d
        out[1] = w0 * b + x0 * c + y0 * d - z0 * cc
        out[2] = w0 * cc - x0 * d + y0 * c + z0 * b
        out[3] = w0 * d + x0 * cc - y0 * b + z0 * c

    def twist_from_ds_velocity(self, zdot: FloatArray, z: FloatArray) -> FloatArray:
        """Site twist ``(v, omega)`` (m/s, rad/s; world frame), shape (6,), for a DS velocity
        ``zdot`` (shape (6,)) at the DS state ``z`` (shape (6,)): ``v = zdot[:3]``,
        ``omega = r0 J_l(z[3:]) zdot[3:]``."""
        zd = np.asarray(zdot, dtype=np.float64).reshape(6)
        za = np.asarray(z, dtype=np.float64).reshape(6)
        omega = np.asarray(self.r0, dtype=np.float64) @ (left_jacobian(za[3:]) @ zd[3:])
        return np.concatenate((zd[:3], omega))


def integrate_ds_target(z_target: FloatArray, zdot: FloatArray, dt: float,
                        z_actual: FloatArray | None = None,
                        leash: FloatArray | None = None) -> FloatArray:
    """One Euler step of the target along the DS velocity, kept on a leash of the actual state.

    ``z_new = z_target + dt * zdot``, then, if ``z_actual`` and ``leash`` are given, clipped to
    ``z_actual +- leash`` per coordinate: under a push the target waits for the robot instead of
    running away, so the DS (evaluated at the actual state) re-plans from where the robot is.

    Parameters
    ----------
    z_target : ndarray, shape (n,)
        Current target DS state.
    zdot : ndarray, shape (n,)
        DS velocity (m/s, rad/s).
    dt : float
        Control period (s).
    z_actual : ndarray, shape (n,), optional
        Measured DS state.
    leash : ndarray, shape (n,), optional
        Largest target-actual gap per coordinate (m, rad).

    Returns
    -------
    ndarray, shape (n,)
    """
    z_new = np.asarray(z_target, dtype=np.float64) + dt * np.asarray(zdot, dtype=np.float64)
    if z_actual is not None and leash is not None:
        z_new = np.clip(z_new, z_actual - leash, z_actual + leash)
    return z_new


@dataclass(frozen=True, slots=True)
class Gains:
    """Impedance gains, per unit task-space mass (the force is ``Lambda`` times them).

    Attributes
    ----------
    kp_pos, kd_pos : float
        Position stiffness (1/s^2) and damping (1/s).
    kp_rot, kd_rot : float
        Orientation stiffness (1/s^2) and damping (1/s).
    kn, dn : float
        Null-space posture stiffness (1/s^2) and damping (1/s), joint space, mass-weighted.
    """

    kp_pos: float = 400.0
    kd_pos: float = 40.0
    kp_rot: float = 400.0
    kd_rot: float = 40.0
    kn: float = 25.0
    dn: float = 10.0


@dataclass(frozen=True, slots=True)
class TrackingStats:
    """Tracking and saturation over the calls since the last reset.

    Attributes
    ----------
    calls : int
        Controller calls.
    saturated_calls : int
        Calls where at least one joint torque hit its limit.
    saturation_fraction : float
        ``saturated_calls / calls`` (0 without calls).
    max_pos_error : float
        Largest position error seen (m).
    max_rot_error : float
        Largest orientation error seen (rad).
    last_pos_error, last_rot_error : float
        Errors at the last call (m, rad).
    """

    calls: int
    saturated_calls: int
    saturation_fraction: float
    max_pos_error: float
    max_rot_error: float
    last_pos_error: float
    last_rot_error: float


@dataclass(frozen=True, slots=True, eq=False)
class _DataViews:
    """Views into one ``MjData`` (:meth:`ImpedanceController._bind`); None: not a slice.

    Attributes
    ----------
    data : MjData
    mass : ndarray, shape (nM,)
        ``data.M``.
    qvel, bias, passive, qpos, ctrl : ndarray, shape (7,), or None
        The arm's entries of ``qvel``, ``qfrc_bias``, ``qfrc_passive``, ``qpos`` and ``ctrl``.
    site_xpos : ndarray, shape (3,)
    site_xmat : ndarray, shape (9,)
    """

    data: Any
    mass: FloatArray
    qvel: FloatArray | None
    bias: FloatArray | None
    passive: FloatArray | None
    qpos: FloatArray | None
    ctrl: FloatArray | None
    site_xpos: FloatArray
    site_xmat: FloatArray


def arm_mass_index(model: Any, dof_adr: NDArray[np.intp]) -> NDArray[np.intp]:
    """Indices into ``data.M`` (MuJoCo's sparse lower-triangular CSR mass matrix) of the 7x7 arm
    block, so that ``data.M[idx]`` is the dense block ``mj_fullM`` would give, shape (7, 7).

    Raises
    ------
    ModelError
        A needed entry is not stored (the arm dofs are not one kinematic chain).
    """
    n = len(dof_adr)
    idx = np.empty((n, n), dtype=np.intp)
    for a, r in enumerate(dof_adr):
        for b, c in enumerate(dof_adr):
            row, col = (r, c) if c <= r else (c, r)
            start = int(model.M_rowadr[row])
            cols = model.M_colind[start:start + int(model.M_rownnz[row])]
            hit = np.flatnonzero(cols == col)
            if hit.size != 1:
                raise ModelError(f"model: mass-matrix entry ({row}, {col}) of the arm is not "
                                 "stored; the arm joints are not one kinematic chain")
            idx[a, b] = start + int(hit[0])
    return idx


class ImpedanceController:
    """Cartesian impedance pose controller with null-space posture control (module docstring).

    Parameters
    ----------
    panda : Panda
        The indexed model (arm alone or a scene containing it).
    site : int, optional
        The controlled site (default the ``tcp`` site).
    gains : Gains, optional
    posture : ndarray, shape (7,), optional
        Null-space posture ``q_n`` (rad; default :data:`~tli_verify.sim.robot.HOME_QPOS`).
    r0 : ndarray, shape (3, 3), optional
        Nominal orientation of the DS state map (default :data:`R0_DOWN`).
    impedance : CartesianImpedance, optional
        The Franka's Cartesian impedance law ``F = K e - D (J qdot - v_d)`` in N/m and Nm/rad
        (:class:`~tli_verify.sim.franka_limits.CartesianImpedance`) instead of the
        per-unit-mass ``gains`` (which then set only the posture loop).
    guard : LimitGuard, optional
        Enforces the robot's torque, torque-rate and velocity limits on every command, with the
        reflex stop (:class:`~tli_verify.sim.franka_limits.LimitGuard`); default: the torques
        are only clipped at :data:`~tli_verify.sim.robot.TORQUE_LIMITS`.
    ext_time_constant : float, optional
        Low-pass time constant (s) of the external wrench estimate (:attr:`external_wrench`).

    Attributes
    ----------
    map : DSStateMap
        The 4-D DS state map of the controlled site.
    posture : ndarray, shape (7,)
        The null-space posture (may be overwritten in place, e.g. with an IK solution).
    pos_error, rot_error : float
        Position (m) and orientation (rad) error at the last call.
    calls, saturated_calls : int
        Counters since :meth:`reset_stats` (see :meth:`stats`).

    Notes
    -----
    The gains are read at construction. The data passed to :meth:`compute` must have positions,
    velocities, ``M`` and ``qfrc_bias`` at the current state: call it after ``mj_step1`` (then
    set the torques and ``mj_step2``), or after ``mj_forward``. :meth:`step` does that for
    ``substeps`` physics steps per call.
    """

    __slots__ = ("_acc", "_act", "_contig", "_dn", "_dof", "_ext_stale", "_ext_tau",
                 "_ext_tau_l", "_fy", "_idx_m", "_jac", "_jac6", "_jacp", "_jacr", "_jtf", "_k6",
                 "_kd6", "_kd6_list", "_kn", "_kp6", "_kp6_list", "_lam_diag", "_lam_inv",
                 "_last_tau", "_limits", "_mv", "_n_sat", "_prev", "_pvec", "_q_idx", "_qerr",
                 "_quat", "_rhs", "_rhs_ext", "_rhs_post", "_tau0", "_twist", "_two_zeta",
                 "_views", "_x", "_y", "calls", "ext_time_constant", "gains", "guard",
                 "impedance", "map", "max_pos_error", "max_rot_error", "model", "panda",
                 "pos_error", "posture", "rot_error", "saturated_calls", "site")

    def __init__(self, panda: Panda, site: int | None = None, gains: Gains | None = None,
                 posture: FloatArray | None = None, r0: FloatArray | None = None, *,
                 impedance: CartesianImpedance | None = None, guard: LimitGuard | None = None,
                 ext_time_constant: float = 0.02) -> None:
        self.panda = panda
        self.model = panda.model
        self.site = panda.tcp_site if site is None else int(site)
        self.gains = Gains() if gains is None else gains
        self.posture = np.array(HOME_QPOS if posture is None else posture, dtype=np.float64)
        self.map = DSStateMap(self.site, R0_DOWN.copy() if r0 is None else np.array(r0))
        nv = self.model.nv
        self._jac6 = np.zeros((6, nv))  # rows 0-2 linear, 3-5 angular (C-contiguous blocks)
        self._dof = panda.dof_adr
        d0 = int(self._dof[0])
        self._contig = bool(np.array_equal(self._dof, np.arange(d0, d0 + 7)))
        self._q_idx = panda.qpos_adr
        self._idx_m = arm_mass_index(self.model, self._dof)
        self._qerr = np.zeros(4)
        self._quat = np.zeros(4)
        # impedance, posture, external wrench, I (Lambda); Fortran order (LAPACK's), so that
        # the products fill columns 1 and 2 in place
        self._rhs = np.zeros((6, 3 + 6), order="F")
        self._rhs[:, 3:] = np.eye(6)
        self._rhs_post, self._rhs_ext = self._rhs[:, 1], self._rhs[:, 2]
        # out= buffers of the products (the layout numpy would give a new result)
        self._lam_inv = np.zeros((6, 6))
        self._lam_diag = self._lam_inv.reshape(-1)[::7]  # a view of its diagonal
        self._twist = np.zeros(6)
        self._acc, self._mv, self._pvec = np.zeros(7), np.zeros(7), np.zeros(7)
        self._tau0, self._jtf, self._fy = np.zeros(7), np.zeros(7), np.zeros(6)
        self._last_tau = np.zeros(7)
        g = self.gains
        self._kp6 = np.array([g.kp_pos] * 3 + [g.kp_rot] * 3)
        self._kd6 = np.array([g.kd_pos] * 3 + [g.kd_rot] * 3)
        self._kp6_list = self._kp6.tolist()
        self._kd6_list = self._kd6.tolist()
        self._kn, self._dn = float(g.kn), float(g.dn)
        self._limits = TORQUE_LIMITS.tolist()
        self._jacp, self._jacr = self._jac6[:3], self._jac6[3:]  # views: mj_jacSite fills them
        self._jac = self._jac6[:, d0:d0 + 7]  # the arm columns (a view) when contiguous
        self._views: _DataViews | None = None
        a0 = int(panda.act_ids[0])
        self._act: Any = (slice(a0, a0 + 7) if np.array_equal(panda.act_ids, np.arange(a0, a0 + 7))
                          else panda.act_ids)
        self._n_sat = 0
        self.impedance = impedance
        self._k6 = impedance.stiffness().tolist() if impedance is not None else None
        self._two_zeta = 2.0 * impedance.damping_ratio if impedance is not None else 0.0
        self.guard = guard
        self.ext_time_constant = float(ext_time_constant)
        self._y = np.zeros((6, 3))  # the last solve's right-hand sides: column 2 is the wrench
        self._x = np.zeros((7, 6))  # the last call's M^-1 J^T
        self._ext_stale = False  # whether column 2 of _y is to be solved (external_wrench)
        self._ext_tau = np.zeros(7)
        self._ext_tau_l = [0.0] * 7  # its values, as floats
        self._prev: _Prev | None = None
        self.reset_stats()

    # ----------------------------------------------------------------------------------------
    def reset_stats(self) -> None:
        """Zero the call, saturation and error counters."""
        self.calls = 0
        self.saturated_calls = 0
        self.max_pos_error = 0.0
        self.max_rot_error = 0.0
        self.pos_error = 0.0
        self.rot_error = 0.0

    def stats(self) -> TrackingStats:
        """Tracking error and saturation since the last :meth:`reset_stats`."""
        return TrackingStats(
            calls=self.calls, saturated_calls=self.saturated_calls,
            saturation_fraction=self.saturated_calls / self.calls if self.calls else 0.0,
            max_pos_error=self.max_pos_error, max_rot_error=self.max_rot_error,
            last_pos_error=self.pos_error, last_rot_error=self.rot_error)

    @property
    def last_saturated(self) -> int:
        """Joints saturated at the last call."""
        return self._n_sat

    @property
    def external_wrench(self) -> FloatArray:
        """The estimated external wrench at the site ``(F, tau)`` (N, N m; world), shape (6,).

        What the robot could compute (the Panda reports ``O_F_ext_hat_K`` from its joint torque
        sensors and its model): the joint torques the rigid-body model does not explain,
        ``tau_ext = M (qdot_k+1 - qdot_k) / dt + C qdot + g - tau - tau_passive`` (the
        commanded torques, the model's friction and damping), low-pass filtered with time
        constant :attr:`ext_time_constant`, mapped to the site with the dynamically consistent
        inverse ``Jbar^T = Lambda J M^-1``. Contacts (beads, bowls) count as external, as on
        the robot. No simulator state beyond the arm's joints and its model is read.

        Computed on access (once per call of :meth:`compute_fast`; the loop reads it once per
        control period): column 2 of the last call's solve, redone with that call's ``Lambda^-1``
        and right-hand sides and the filtered torque put in column 2 -- a triangular solve
        treats each column alone, so this is the column the call's own solve would have given,
        bit for bit, and the torque loop skips the product ``X^T tau_ext`` at every step.
        """
        if self._ext_stale:
            np.matmul(self._x.T, self._ext_tau, out=self._rhs_ext)
            _, y, info = _dposv(self._lam_inv, self._rhs)
            if info != 0:  # pragma: no cover - the call's own solve succeeded on it
                raise SolverError(f"model: task-space inertia singular at the site (info {info})")
            self._y = y
            self._ext_stale = False
        return self._y[:, 2].copy()

    def _estimate_external(self, time: float, qd: list[float]) -> None:
        """Update the filtered joint-space external torque from the last call's step
        (:attr:`external_wrench`; ``qd`` the arm's joint velocities now)."""
        prev = self._prev
        if prev is None:
            return
        t_prev, m_prev, qd_prev, b_prev, tau_prev, p_prev = prev
        dt = time - t_prev
        if dt <= 0.0:
            return
        # raw = M0 (qd - qd0) / dt + b0 - tau0 - p0; ext += alpha (raw - ext): elementwise in
        # floats, joint by joint (the roundings of numpy's elementwise operations), the
        # product with numpy
        a0, a1, a2, a3, a4, a5, a6 = qd
        c0, c1, c2, c3, c4, c5, c6 = qd_prev
        acc = self._acc
        acc[:] = ((a0 - c0) / dt, (a1 - c1) / dt, (a2 - c2) / dt, (a3 - c3) / dt,
                  (a4 - c4) / dt, (a5 - c5) / dt, (a6 - c6) / dt)
        m0, m1, m2, m3, m4, m5, m6 = np.matmul(m_prev, acc, out=self._mv).tolist()
        b0, b1, b2, b3, b4, b5, b6 = b_prev
        t0, t1, t2, t3, t4, t5, t6 = tau_prev
        p0, p1, p2, p3, p4, p5, p6 = p_prev
        e0, e1, e2, e3, e4, e5, e6 = self._ext_tau_l
        alpha = dt / (self.ext_time_constant + dt)
        ext = [e0 + alpha * (m0 + b0 - t0 - p0 - e0), e1 + alpha * (m1 + b1 - t1 - p1 - e1),
               e2 + alpha * (m2 + b2 - t2 - p2 - e2), e3 + alpha * (m3 + b3 - t3 - p3 - e3),
               e4 + alpha * (m4 + b4 - t4 - p4 - e4), e5 + alpha * (m5 + b5 - t5 - p5 - e5),
               e6 + alpha * (m6 + b6 - t6 - p6 - e6)]
        self._ext_tau_l = ext
        self._ext_tau[:] = ext

    def ds_state(self, data: Any) -> FloatArray:
        """The DS state ``(x, y, z, rx, ry, rz)`` of the controlled site, shape (6,)."""
        return self.map.ds_state(data)

    def target_pose_from_ds_state(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Target ``(pos (3,), quat (4,))`` for the DS state ``z`` (shape (6,))."""
        return self.map.target_pose_from_ds_state(z)

    def arm_mass(self, data: Any) -> FloatArray:
        """The 7x7 arm block of the joint-space mass matrix (kg m^2), from ``data.M``."""
        return np.asarray(data.M[self._idx_m], dtype=np.float64)

    # ----------------------------------------------------------------------------------------
    def compute(self, data: Any, pos_d: FloatArray, quat_d: FloatArray,
                twist_d: FloatArray | None = None) -> FloatArray:
        """Joint torques tracking the target pose, saturated; also written to the motors.

        Parameters
        ----------
        data : MjData
            At the current state (after ``mj_step1`` or ``mj_forward``).
        pos_d : ndarray, shape (3,)
            Target site position (m, world).
        quat_d : ndarray, shape (4,)
            Target site orientation, unit quaternion ``(w, x, y, z)``.
        twist_d : ndarray, shape (6,), optional
            Target twist ``(v, w)`` (m/s, rad/s; world) used as damping feed-forward.

        Returns
        -------
        ndarray, shape (7,)
            The saturated torques (N m).
        """
        px, py, pz = np.asarray(pos_d, dtype=np.float64).tolist()
        tw = None if twist_d is None else np.asarray(twist_d, dtype=np.float64).tolist()
        return np.array(self.compute_fast(data, px, py, pz,
                                          np.asarray(quat_d, dtype=np.float64), tw))

    def compute_fast(self, data: Any, px: float, py: float, pz: float, quat_d: FloatArray,
                     twist_d: list[float] | None = None) -> list[float]:
        """:meth:`compute` without the conversions (the torque loop's entry): the target
        position as floats, ``quat_d`` a float64 array of shape (4,), ``twist_d`` a list of
        6 floats or None. Returns the torques sent, as a list of 7 floats.

        Elementwise arithmetic runs on Python floats (the same IEEE roundings as numpy's
        elementwise operations, in the same order), written out per component (a
        comprehension's frame and ``zip`` cost more than the arithmetic on 6- and 7-vectors);
        every matrix product and solve is the numpy / LAPACK call of the plain formulation, on
        operands of the same layout (a preallocated ``out=`` buffer has the layout of the array
        numpy would allocate), so the torques are bit-identical to it
        (``tests/unit/test_panda_torque_loop_exact.py``).
        """
        v = self._views if self._views is not None and self._views.data is data \
            else self._bind(data)
        mujoco.mj_jacSite(self.model, data, self._jacp, self._jacr, self.site)
        jac = self._jac if self._contig else self._jac6[:, self._dof]
        qd = v.qvel if v.qvel is not None else data.qvel[self._dof]
        mass = v.mass[self._idx_m]                      # the 7x7 arm block of data.M
        # X = M^-1 J^T (Cholesky solve); Lambda^-1 = J X (+ a tiny damping near singularities).
        _, x, info = _dposv(mass, jac.T)
        if info != 0:
            raise SolverError(f"model: the arm mass matrix is not positive definite (info {info})")
        lam_inv = np.matmul(jac, x, out=self._lam_inv)
        self._lam_diag += _LAMBDA_DAMPING               # a view of lam_inv's diagonal
        # Pose error: position, and the rotation vector of R_d R^T (world frame).
        sx, sy, sz = v.site_xpos.tolist()
        ex, ey, ez = px - sx, py - sy, pz - sz
        qerr = self._qerr
        site_quat = self._quat
        mujoco.mju_mat2Quat(site_quat, v.site_xmat)
        mujoco.mju_negQuat(site_quat, site_quat)
        mujoco.mju_mulQuat(qerr, quat_d, site_quat)     # q_d * conj(q): world-frame error
        w, a, b, c = qerr.tolist()
        if w < 0.0:
            w, a, b, c = -w, -a, -b, -c
        vnorm = math.sqrt(a * a + b * b + c * c)
        angle = 2.0 * math.atan2(vnorm, w)
        k = angle / vnorm if vnorm > 1e-12 else 0.0
        err = (ex, ey, ez, a * k, b * k, c * k)
        # J qdot - v_d: the measured site twist less the target's
        twist = np.matmul(jac, qd, out=self._twist).tolist()   # (6,)
        if twist_d is None:
            vel = twist
        else:
            w0, w1, w2, w3, w4, w5 = twist
            d0, d1, d2, d3, d4, d5 = twist_d
            vel = [w0 - d0, w1 - d1, w2 - d2, w3 - d3, w4 - d4, w5 - d5]
        bias = (v.bias if v.bias is not None else data.qfrc_bias[self._dof]).tolist()
        qdl = qd.tolist()
        time = float(data.time)
        self._estimate_external(time, qdl)
        rhs = self._rhs                                 # Fortran order: contiguous columns
        if self._k6 is None:
            kp, kd = self._kp6_list, self._kd6_list
            rhs[:, 0] = [kp[i] * err[i] - kd[i] * vel[i] for i in range(6)]
        # Posture torque (mass-weighted), projected with I - J^T Jbar^T, Jbar = M^-1 J^T Lambda:
        # J^T Jbar^T tau0 = J^T Lambda X^T tau0. One solve gives F = Lambda acc and that term,
        # and Lambda X^T tau_ext = Jbar^T tau_ext, the external wrench at the site; in the
        # Franka impedance law also Lambda itself (its diagonal sets the damping).
        q0, q1, q2, q3, q4, q5, q6 = (v.qpos if v.qpos is not None
                                      else data.qpos[self._q_idx]).tolist()
        n0, n1, n2, n3, n4, n5, n6 = self.posture.tolist()
        v0, v1, v2, v3, v4, v5, v6 = qdl
        kn, dn = self._kn, self._dn
        self._pvec[:] = (kn * (n0 - q0) - dn * v0, kn * (n1 - q1) - dn * v1,
                         kn * (n2 - q2) - dn * v2, kn * (n3 - q3) - dn * v3,
                         kn * (n4 - q4) - dn * v4, kn * (n5 - q5) - dn * v5,
                         kn * (n6 - q6) - dn * v6)
        tau0 = np.matmul(mass, self._pvec, out=self._tau0)
        xt = x.T
        np.matmul(xt, tau0, out=self._rhs_post)         # a view of rhs's column 1
        # column 2 (the external wrench) is filled and solved on access (external_wrench)
        _, y, info = _dposv(lam_inv, rhs)
        if info != 0:
            raise SolverError(f"model: task-space inertia singular at the site (info {info})")
        self._y, self._x, self._ext_stale = y, x, True
        if self._k6 is not None:
            ys = y.ravel(order="F").tolist()            # column by column (Fortran order)
            f0, f1, f2, f3, f4, f5 = self._impedance_force(
                err, vel, (ys[18], ys[25], ys[32], ys[39], ys[46], ys[53]))  # Lambda's diagonal
            g0, g1, g2, g3, g4, g5 = ys[6:12]           # column 1
            fy = self._fy
            fy[:] = (f0 - g0, f1 - g1, f2 - g2, f3 - g3, f4 - g4, f5 - g5)
        else:
            fy = y[:, 0] - y[:, 1]
        j0, j1, j2, j3, j4, j5, j6 = np.matmul(jac.T, fy, out=self._jtf).tolist()
        s0, s1, s2, s3, s4, s5, s6 = tau0.tolist()
        b0, b1, b2, b3, b4, b5, b6 = bias
        t = [j0 + s0 + b0, j1 + s1 + b1, j2 + s2 + b2, j3 + s3 + b3, j4 + s4 + b4,
             j5 + s5 + b5, j6 + s6 + b6]
        l0, l1, l2, l3, l4, l5, l6 = self._limits
        n_sat = (abs(t[0]) > l0) + (abs(t[1]) > l1) + (abs(t[2]) > l2) + (abs(t[3]) > l3) + \
            (abs(t[4]) > l4) + (abs(t[5]) > l5) + (abs(t[6]) > l6)
        if self.guard is not None:
            out = self.guard.apply_lists(t, qdl, mass, twist)
        elif n_sat:
            out = [min(max(tj, -lj), lj) for tj, lj in zip(t, self._limits, strict=True)]
        else:
            out = t
        self._prev = (time, mass, qdl, bias, out,
                      (v.passive if v.passive is not None
                       else data.qfrc_passive[self._dof]).tolist())
        if v.ctrl is not None:
            v.ctrl[:] = out
        else:
            data.ctrl[self._act] = out
        # Bookkeeping.
        pe = math.sqrt(ex * ex + ey * ey + ez * ez)
        self._n_sat = n_sat
        self.pos_error = pe
        self.rot_error = angle
        self.calls += 1
        if n_sat:
            self.saturated_calls += 1
        if pe > self.max_pos_error:
            self.max_pos_error = pe
        if angle > self.max_rot_error:
            self.max_rot_error = angle
        return out

    def _impedance_force(self, err: tuple[float, ...], vel: list[float],
                         lam_diag: tuple[float, ...]) -> tuple[float, ...]:
        """The Franka law's task wrench ``K e - 2 zeta sqrt(K |Lambda_jj|) vel``, within
        :data:`TASK_FORCE_LIMIT` and :data:`TASK_TORQUE_LIMIT` (floats; module doc).

        The norm of a part is numpy's (``sqrt(f @ f)``: BLAS ``ddot``) whenever it could exceed
        its limit; a sum of three squares in floats is within a relative 4e-16 of it, so below
        ``limit^2 (1 - 1e-9)`` the part is inside its limit whatever ``ddot`` rounds to, and is
        left alone without the call."""
        tz, k6 = self._two_zeta, self._k6
        assert k6 is not None
        k0, k1, k2, k3, k4, k5 = k6
        e0, e1, e2, e3, e4, e5 = err
        v0, v1, v2, v3, v4, v5 = vel
        l0, l1, l2, l3, l4, l5 = lam_diag
        f0 = k0 * e0 - tz * math.sqrt(k0 * abs(l0)) * v0
        f1 = k1 * e1 - tz * math.sqrt(k1 * abs(l1)) * v1
        f2 = k2 * e2 - tz * math.sqrt(k2 * abs(l2)) * v2
        t0 = k3 * e3 - tz * math.sqrt(k3 * abs(l3)) * v3
        t1 = k4 * e4 - tz * math.sqrt(k4 * abs(l4)) * v4
        t2 = k5 * e5 - tz * math.sqrt(k5 * abs(l5)) * v5
        if f0 * f0 + f1 * f1 + f2 * f2 > _FORCE_SQ_SAFE:
            f0, f1, f2 = _cap3(f0, f1, f2, TASK_FORCE_LIMIT)
        if t0 * t0 + t1 * t1 + t2 * t2 > _TORQUE_SQ_SAFE:
            t0, t1, t2 = _cap3(t0, t1, t2, TASK_TORQUE_LIMIT)
        return f0, f1, f2, t0, t1, t2

    def _bind(self, data: Any) -> _DataViews:
        """Views of ``data``'s arrays that :meth:`compute` reads and writes, made once per
        ``data`` (MuJoCo never reallocates them): each attribute access of ``MjData``
        builds a new array object, and slicing it another."""
        d0, a0 = int(self._dof[0]), int(self.panda.qpos_adr[0])
        contig_q = bool(np.array_equal(self._q_idx, np.arange(a0, a0 + 7)))
        act = self._act
        self._views = _DataViews(
            data=data, mass=data.M,
            qvel=data.qvel[d0:d0 + 7] if self._contig else None,
            bias=data.qfrc_bias[d0:d0 + 7] if self._contig else None,
            passive=data.qfrc_passive[d0:d0 + 7] if self._contig else None,
            qpos=data.qpos[a0:a0 + 7] if contig_q else None,
            ctrl=data.ctrl[act] if isinstance(act, slice) else None,
            site_xpos=data.site_xpos[self.site], site_xmat=data.site_xmat[self.site])
        return self._views

    def step(self, data: Any, pos_d: FloatArray, quat_d: FloatArray,
             twist_d: FloatArray | None = None, substeps: int = 1,
             control_every: int | None = None) -> FloatArray:
        """One control period of ``substeps`` physics steps towards a held target.

        The torques are computed (``mj_step1``, :meth:`compute`, ``mj_step2``) on the first
        physics step and again every ``control_every`` steps, and held (zero-order hold) in
        between with plain ``mj_step``. The default ``control_every = substeps`` computes them
        once per period (the loop :func:`sampled_data_spectral_radius` analyses);
        ``control_every = 1`` is a torque loop at the physics rate (500 Hz) under a slower
        target, as on the real robot (1 kHz torque loop, slower DS).

        Returns
        -------
        ndarray, shape (7,)
            The last torques applied (N m).
        """
        m = self.model
        every = substeps if control_every is None else max(1, int(control_every))
        tau = self._last_tau
        for k in range(substeps):
            if k % every == 0:
                mujoco.mj_step1(m, data)
                tau = self.compute(data, pos_d, quat_d, twist_d)
                mujoco.mj_step2(m, data)
            else:
                mujoco.mj_step(m, data)
        self._last_tau = tau
        return tau


def sampled_data_spectral_radius(kp: float, kd: float, period: float) -> float:
    """Spectral radius of the sampled closed loop of one task-space axis (python-control).

    The decoupled axis is a unit double integrator ``e'' = u``; the PD law ``u = -kp e - kd e'``
    is computed at the samples and held over ``period`` (zero-order hold, as the controller is
    between ``mj_step`` substeps). The plant is discretised with ``control.c2d(..., 'zoh')``.

    Parameters
    ----------
    kp : float
        Stiffness (1/s^2).
    kd : float
        Damping (1/s).
    period : float
        Control period (s).

    Returns
    -------
    float
        Largest eigenvalue modulus of ``Ad - Bd K``; below 1 means the sampled loop is stable.
    """
    import control

    plant = control.ss([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0]], np.eye(2), np.zeros((2, 1)))
    disc = control.c2d(plant, period, method="zoh")
    k = np.array([[kp, kd]])
    closed = np.asarray(disc.A) - np.asarray(disc.B) @ k
    return float(np.max(np.abs(np.linalg.eigvals(closed))))


def closed_loop_spectral_radius(panda: Panda, substeps: int, *, gains: Gains | None = None,
                                qpos: FloatArray | None = None, settle: int = 200,
                                eps: float = 1e-6) -> float:
    """Spectral radius of the *simulated* sampled-data closed loop, linearised at rest.

    The map of one control period (``substeps`` physics steps, torques computed once and held:
    :meth:`ImpedanceController.step`) acting on the arm state ``(q, qdot)`` (shape (14,)) is
    differentiated by central differences at an equilibrium (target = the site's pose at
    ``qpos``, posture = ``qpos``, reached by ``settle`` 1-step periods). Unlike
    :func:`sampled_data_spectral_radius` (one decoupled axis), this includes the coupled
    rigid-body dynamics, the null-space posture loop, joint damping and armature, and MuJoCo's
    integrator. For the arm alone (no contacts).

    Parameters
    ----------
    panda : Panda
    substeps : int
        Physics steps per control period.
    gains : Gains, optional
    qpos : ndarray, shape (7,), optional
        Posture of the equilibrium (default :data:`~tli_verify.sim.robot.HOME_QPOS`).
    settle : int, optional
    eps : float, optional
        Finite-difference step (rad, rad/s).

    Returns
    -------
    float
        Largest eigenvalue modulus of the period map's Jacobian (shape (14, 14)); below 1:
        locally asymptotically stable.
    """
    q0 = np.array(HOME_QPOS if qpos is None else qpos, dtype=np.float64)
    ctl = ImpedanceController(panda, gains=gains, posture=q0)
    data = panda.new_data(q0)
    pos, quat = ctl.target_pose_from_ds_state(ctl.ds_state(data))
    qa, va = panda.qpos_adr, panda.dof_adr

    def period(x: FloatArray, n: int) -> FloatArray:
        data.qpos[qa] = x[:7]
        data.qvel[va] = x[7:]
        data.qacc_warmstart[:] = 0.0
        ctl.step(data, pos, quat, substeps=n)
        return np.concatenate((data.qpos[qa], data.qvel[va]))

    x0 = np.concatenate((q0, np.zeros(7)))
    for _ in range(settle):
        x0 = period(x0, 1)
    jac = np.empty((14, 14))
    for i in range(14):
        dx = np.zeros(14)
        dx[i] = eps
        jac[:, i] = (period(x0 + dx, substeps) - period(x0 - dx, substeps)) / (2.0 * eps)
    return float(np.max(np.abs(np.linalg.eigvals(jac))))
