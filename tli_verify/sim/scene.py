"""The soup-scooping scene in MuJoCo (paper Sec. 7.2, Fig. 1).

A table, a soup bowl with 30 beads (radius 8 mm, 2 g), a target bowl, and a ladle: a round tray
whose rim is open over the front 110 degrees (a closed front lip of 3 mm or more scooped nothing).
The MJCF is generated from Python with :class:`mujoco.MjSpec`, so the same ladle can hang under a
mocap body (phase 1, :func:`build_mocap_scene`) or be attached to the Panda hand
(:func:`add_ladle` on the hand body, :func:`add_scene` for the rest).

World frame: z up, the table top at ``z = 0``, the Panda base (when present) at the origin. The
task moves in the y-z plane: the soup bowl at ``SOUP_CENTER`` (y < 0), the target bowl at
``TARGET_CENTER`` (y > 0), both at x = 0.5 m.

Ladle frame (site ``ladle_tray``): origin at the centre of the tray floor's top face, local +x the
open front (the scooping direction), local +z the tray normal. At pitch 0 the front faces world -y
(towards the soup, away from the target); a positive pitch (a rotation about world +x) tips the
front down -- scooping at small positive pitch, pouring at large positive pitch.

Contact settings measured to scoop: ``condim`` 6, elliptic cones, ``impratio`` 10, a
2 ms step, ``implicitfast``, ``solimp`` 0.95 0.99 0.001.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt

from tli_verify.defaults import Stream
from tli_verify.defaults import rng as default_rng
from tli_verify.errors import TliError
from tli_verify.rotations import quat_exp
from tli_verify.sim.physics_options import DEFAULT_PHYSICS, SOLVERS, PhysicsOptions

__all__ = [
    "BEAD_MASS",
    "BEAD_RADIUS",
    "DEFAULT_PHYSICS",
    "FT_FORCE",
    "FT_SITE",
    "FT_TORQUE",
    "N_BEADS",
    "SOLVERS",
    "SOUP_CENTER",
    "TARGET_CENTER",
    "TRAY_REFERENCE",
    "Bowl",
    "PhysicsOptions",
    "SceneIds",
    "add_ladle",
    "add_scene",
    "add_stand",
    "add_wrist_ft",
    "build_mocap_scene",
    "ladle_quat",
    "reset_beads",
    "scene_ids",
    "set_contact_options",
    "tray_quat",
]

FloatArray = npt.NDArray[np.float64]

N_BEADS = 30
BEAD_RADIUS = 0.008
BEAD_MASS = 0.002
SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
TABLE_SIZE = (0.3, 0.5, 0.025)
"""Half-sizes (m) of the table's top, the one that collides (the bowls and beads rest on it)."""
TABLE_POS = (0.55, 0.0, -0.025)
"""Centre of the table's top: it spans x 0.25-0.85 m, y -0.5-0.5 m, its top face at z = 0."""
TABLE_RGBA = (0.55, 0.4, 0.3, 1.0)
TABLE_HEIGHT = 0.75
"""Height (m) of the table top over the floor (drawn only: :func:`add_stand`)."""
VISUAL_GROUP = 2
"""Geom group of the drawn-only parts (the Menagerie Panda's visual meshes are in it too)."""
FRICTION = (1.0, 0.005, 0.0001)

SOUP_CENTER = np.array([0.5, -0.2, 0.0])
TARGET_CENTER = np.array([0.5, 0.2, 0.0])

TRAY_RADIUS = 0.035
TRAY_HALF_THICKNESS = 0.001
RIM_HEIGHT = 0.015
RIM_HALF_WIDTH = 0.002
OPEN_FRONT_DEG = 110.0
FRONT_LIP = 0.006
"""Height (m) of a low lip across the open front: beads get over it when the tray is pushed
into the pile, and it keeps them from rolling off the front while the tray is levelled
(with the beads gathered in the bowl's middle, a closed lip of 3 mm scooped nothing; against
the wall they are squeezed over 6 mm, and the first bead gets on only once the tray presses
into the pile)."""
HANDLE_LENGTH = 0.16
LADLE_MASS = 0.12
CARRIER_MASS = 1.0
CARRIER_INERTIA = 0.01
FT_SITE = "ladle_ft"
"""The wrist force/torque sensor's site, at the ladle's mount (:func:`add_wrist_ft`)."""
FT_FORCE = "ladle_force"
"""Name of the MuJoCo force sensor on :data:`FT_SITE` (3 numbers, N, site frame)."""
FT_TORQUE = "ladle_torque"
"""Name of the MuJoCo torque sensor on :data:`FT_SITE` (3 numbers, Nm, site frame)."""


@dataclass(frozen=True, slots=True)
class Bowl:
    """A round bowl on the table.

    Attributes
    ----------
    name : str
    center : ndarray, shape (3,)
        Centre of the bowl's base on the table top.
    radius : float
        Inner radius (m).
    floor : float
        Height of the inner floor's top face above the table (m).
    height : float
        Height of the rim's top above the table (m).
    """

    name: str
    center: FloatArray
    radius: float
    floor: float
    height: float

    def inside(self, p: FloatArray, *, above: float = 0.0) -> npt.NDArray[np.bool_]:
        """Points inside the bowl's volume, extended ``above`` metres over the rim.

        Parameters
        ----------
        p : ndarray, shape (..., 3)
        above : float, optional

        Returns
        -------
        ndarray of bool, shape (...)
        """
        d = np.hypot(p[..., 0] - self.center[0], p[..., 1] - self.center[1])
        z = p[..., 2] - self.center[2]
        return (d < self.radius) & (z > self.floor - 1e-3) & (z < self.height + above)

    def contains(self, x: float, y: float, z: float, *, above: float = 0.0) -> bool:
        """:meth:`inside` for one point ``(x, y, z)`` given as floats: the same answer, bit for
        bit, without numpy's per-call cost on scalars.

        The horizontal distance is compared squared, in floats, when it is clearly inside or
        outside (a relative margin of 1e-9, far beyond the roundings of the squares and of
        ``hypot``); only within that margin of the rim is it ``np.hypot``'s, as in
        :meth:`inside`.
        """
        cx, cy, cz = self.center.tolist()
        h = z - cz
        if not (h > self.floor - 1e-3 and h < self.height + above):
            return False
        dx, dy = x - cx, y - cy
        sq = dx * dx + dy * dy
        r2 = self.radius * self.radius
        if sq < r2 * (1.0 - 1e-9):
            return True
        if sq > r2 * (1.0 + 1e-9):
            return False
        return bool(np.hypot(dx, dy) < self.radius)


SOUP_BOWL = Bowl("soup", SOUP_CENTER, radius=0.11, floor=0.008, height=0.045)
SOUP_FLAT = 0.035
"""Radius of the soup bowl's flat bottom; its floor rises outside it at ``SOUP_SLOPE``."""
SOUP_SLOPE = 0.2
"""Slope (rad) of the soup bowl's conical floor ring: the beads gather in the pit."""
SOUP_PIT = np.array([0.0, -0.06])
"""Offset (m, in x and y) of the flat pit from the soup bowl's centre: towards the far side
(-y), the end of the scoop's sweep, so the beads always lie ahead of the ladle and against
the bowl's wall."""
TARGET_BOWL = Bowl("target", TARGET_CENTER, radius=0.08, floor=0.008, height=0.04)


def set_contact_options(spec: mujoco.MjSpec, physics: PhysicsOptions = DEFAULT_PHYSICS) -> None:
    """The measured contact settings (module doc) on ``spec``'s options, with ``physics``."""
    spec.option.timestep = 0.002
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = float(physics.impratio)
    spec.option.tolerance = 1e-6  # solver: 9 % faster steps than 1e-8, scooping unchanged
    if physics.solver == "cg":
        spec.option.solver = mujoco.mjtSolver.mjSOL_CG
    if physics.sleep:
        spec.option.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SLEEP)
        spec.option.sleep_tolerance = float(physics.sleep_tolerance)


def _contact(geom: mujoco.MjsGeom) -> mujoco.MjsGeom:
    geom.condim = 6
    geom.solimp = list(SOLIMP)
    geom.friction = list(FRICTION)
    return geom


def _bowl(world: mujoco.MjsBody, bowl: Bowl, rgba: tuple[float, ...], segments: int = 28,
          *, flat: float | None = None, slope: float = 0.0,
          pit: tuple[float, float] = (0.0, 0.0)) -> None:
    body = world.add_body(name=f"{bowl.name}_bowl", pos=bowl.center.tolist())
    wall = 0.006
    _contact(body.add_geom(name=f"{bowl.name}_floor", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                           size=[bowl.radius + wall, bowl.floor / 2, 0],
                           pos=[0, 0, bowl.floor / 2], rgba=list(rgba)))
    r = bowl.radius + wall / 2
    half_len = r * math.tan(math.pi / segments) + 1e-3
    for k in range(segments):
        a = 2 * math.pi * k / segments
        _contact(body.add_geom(
            name=f"{bowl.name}_wall{k}", type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[wall / 2, half_len, bowl.height / 2],
            pos=[r * math.cos(a), r * math.sin(a), bowl.height / 2],
            quat=[math.cos(a / 2), 0, 0, math.sin(a / 2)], rgba=list(rgba)))
    if flat is None:
        return
    # a conical funnel from the flat pit up to the wall, of tilted tiles; the pit is offset by
    # ``pit`` from the bowl's centre, so each tile runs from the pit's edge to the wall
    half_t = 0.003
    qy = np.array([math.cos(-slope / 2), 0.0, math.sin(-slope / 2), 0.0])
    c = np.asarray(pit, dtype=np.float64)
    for k in range(segments):
        a = 2 * math.pi * k / segments
        u = np.array([math.cos(a), math.sin(a)])
        cu = float(c @ u)
        reach = -cu + math.sqrt(cu * cu - float(c @ c) + bowl.radius ** 2)  # pit -> wall
        run = reach - flat
        rise = run * math.tan(slope)
        half_w = reach * math.tan(math.pi / segments) + 1e-3
        rm = (flat + reach) / 2 + half_t * math.sin(slope)
        zm = bowl.floor + rise / 2 - half_t * math.cos(slope)
        qz = np.array([math.cos(a / 2), 0.0, 0.0, math.sin(a / 2)])
        q = np.empty(4)
        mujoco.mju_mulQuat(q, qz, qy)
        _contact(body.add_geom(
            name=f"{bowl.name}_slope{k}", type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[run / 2 / math.cos(slope) + 1e-3, half_w, half_t],
            pos=[c[0] + rm * math.cos(a), c[1] + rm * math.sin(a), zm], quat=q.tolist(),
            rgba=list(rgba)))


def soup_floor(y: float, x: float | None = None) -> float:
    """World height of the soup bowl's floor at ``(x, y)`` (default ``x`` the bowl's centre
    line): flat in the pit, rising at ``SOUP_SLOPE`` outside it (m)."""
    px = float(SOUP_CENTER[0] + SOUP_PIT[0]) if x is None else x
    d = math.hypot(px - float(SOUP_CENTER[0] + SOUP_PIT[0]),
                   y - float(SOUP_CENTER[1] + SOUP_PIT[1]))
    return float(SOUP_CENTER[2] + SOUP_BOWL.floor + max(0.0, d - SOUP_FLAT)
                 * math.tan(SOUP_SLOPE))


def add_scene(spec: mujoco.MjSpec) -> None:
    """Add the table, both bowls and the 30 beads to ``spec``'s world body.

    The beads start on a grid above the soup bowl; :func:`reset_beads` drops and settles them.
    """
    world = spec.worldbody
    _contact(world.add_geom(name="table", type=mujoco.mjtGeom.mjGEOM_BOX,
                            size=list(TABLE_SIZE), pos=list(TABLE_POS), rgba=list(TABLE_RGBA)))
    _bowl(world, SOUP_BOWL, (0.85, 0.85, 0.9, 1), flat=SOUP_FLAT, slope=SOUP_SLOPE,
          pit=(float(SOUP_PIT[0]), float(SOUP_PIT[1])))
    _bowl(world, TARGET_BOWL, (0.3, 0.6, 0.3, 1))
    for i in range(N_BEADS):
        body = world.add_body(name=f"bead{i}", pos=_bead_grid(i).tolist())
        body.add_freejoint(name=f"bead{i}_free")
        _contact(body.add_geom(name=f"bead{i}", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                               size=[BEAD_RADIUS, 0, 0], mass=BEAD_MASS,
                               rgba=[0.95, 0.6, 0.1, 1]))


def add_stand(spec: mujoco.MjSpec) -> None:
    """Draw what the Panda stands on: the table's top extended under the base, its legs, the
    floor, and a sky (the pictures and videos of :mod:`tli_verify.sim.render`).

    Nothing added here takes part in the physics: each geom has ``contype = conaffinity = 0``
    (no contact can involve it) and sits in the world body (no mass or inertia), in the visual
    group :data:`VISUAL_GROUP`; the lights and textures only change pictures. The table that
    collides stays :func:`add_scene`'s (x from 0.25 m): the extension covers x from -0.25 m to
    0.25 m, under the arm's base at the origin, whose bottom face (``link0``) rests on the top at
    ``z = 0``. A trial with the stand is bit-identical to one without it
    (``tests/integration/test_sim_render.py``).
    """
    world = spec.worldbody

    def drawn(name: str, kind: mujoco.mjtGeom, size: list[float], pos: list[float],
              **kw: object) -> mujoco.MjsGeom:
        geom: mujoco.MjsGeom = world.add_geom(name=name, type=kind, size=size, pos=pos, **kw)
        geom.contype = geom.conaffinity = 0
        geom.group = VISUAL_GROUP
        return geom

    box = mujoco.mjtGeom.mjGEOM_BOX
    sx, sy, sz = TABLE_SIZE
    x0, x1 = -0.25, TABLE_POS[0] - sx  # the extension, up to where the colliding top begins
    drawn("table_stand", box, [(x1 - x0) / 2, sy, sz], [(x0 + x1) / 2, 0.0, TABLE_POS[2]],
          rgba=list(TABLE_RGBA))
    leg = 0.03
    legs_h = (TABLE_HEIGHT - 2 * sz) / 2
    far = TABLE_POS[0] + sx
    for k, (x, y) in enumerate([(x0, -sy), (x0, sy), (far, -sy), (far, sy)]):
        drawn(f"table_leg{k}", box, [leg, leg, legs_h],
              [x - math.copysign(leg, x - 0.3), y - math.copysign(leg, y), -2 * sz - legs_h],
              rgba=[0.4, 0.28, 0.2, 1])
    spec.add_texture(name="stand_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=[0.55, 0.7, 0.85],
                     rgb2=[0.05, 0.07, 0.1], width=256, height=256)
    spec.add_texture(name="stand_floor", type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, rgb1=[0.32, 0.34, 0.36],
                     rgb2=[0.26, 0.28, 0.3], width=256, height=256)
    floor = spec.add_material(name="stand_floor", texrepeat=[6, 6])
    floor.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "stand_floor"
    drawn("floor", mujoco.mjtGeom.mjGEOM_PLANE, [3.0, 3.0, 0.05],
          [0.3, 0.0, -TABLE_HEIGHT], material="stand_floor")


def _bead_grid(i: int) -> FloatArray:
    """Start positions: layers of a 4x4 grid inside the soup bowl (before settling)."""
    layer, k = divmod(i, 12)
    ring = [(-1.5, -0.5), (-1.5, 0.5), (-0.5, -1.5), (-0.5, -0.5), (-0.5, 0.5), (-0.5, 1.5),
            (0.5, -1.5), (0.5, -0.5), (0.5, 0.5), (0.5, 1.5), (1.5, -0.5), (1.5, 0.5)][k]
    step = 2.6 * BEAD_RADIUS
    return SOUP_CENTER + np.array([SOUP_PIT[0] + ring[0] * step, SOUP_PIT[1] + ring[1] * step,
                                   SOUP_BOWL.floor + BEAD_RADIUS * (1.2 + 2.4 * layer)])


def add_ladle(body: mujoco.MjsBody, *, pos: tuple[float, float, float] = (0.0, 0.0, 0.0),
              quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
              ) -> mujoco.MjsBody:
    """Attach the ladle under ``body`` (a mocap body, a free body, or the Panda hand).

    Parameters
    ----------
    body : mujoco.MjsBody
    pos, quat : tuple, optional
        Pose of the ladle frame (module doc) in ``body``'s frame.

    Returns
    -------
    mujoco.MjsBody
        The ladle body (``ladle``), rigidly fixed to ``body``; its site ``ladle_tray`` is the
        tray frame.
    """
    # The ladle is built in a spec of its own and attached under ``body``: MuJoCo sensors
    # live in a spec, and a body does not reach the spec it belongs to (PandaRig passes only
    # the hand); attaching brings the wrist F/T sensors along (:func:`add_wrist_ft`).
    part = mujoco.MjSpec()
    ladle = part.worldbody.add_body(name="ladle", pos=list(pos), quat=list(quat))
    rgba = [0.6, 0.6, 0.65, 1]
    _contact(ladle.add_geom(name="ladle_floor", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                            size=[TRAY_RADIUS, TRAY_HALF_THICKNESS, 0],
                            pos=[0, 0, -TRAY_HALF_THICKNESS], rgba=rgba,
                            mass=LADLE_MASS * 0.4))
    half_open = math.radians(OPEN_FRONT_DEG) / 2
    n = 14
    span = 2 * math.pi - 2 * half_open
    r = TRAY_RADIUS + RIM_HALF_WIDTH
    half_len = r * math.sin(span / n / 2) + 1e-3
    for k in range(n):
        a = half_open + span * (k + 0.5) / n
        _contact(ladle.add_geom(
            name=f"ladle_rim{k}", type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[RIM_HALF_WIDTH, half_len, RIM_HEIGHT / 2],
            pos=[r * math.cos(a), r * math.sin(a), RIM_HEIGHT / 2],
            quat=[math.cos(a / 2), 0, 0, math.sin(a / 2)], rgba=rgba,
            mass=LADLE_MASS * 0.2 / n))
    # the handle: from the back of the rim, rising at 60 degrees
    back = TRAY_RADIUS + 2 * RIM_HALF_WIDTH
    c, sn = math.cos(math.pi / 3), math.sin(math.pi / 3)
    _contact(ladle.add_geom(
        name="ladle_handle", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
        fromto=[-back, 0, RIM_HEIGHT, -back - HANDLE_LENGTH * c, 0,
                RIM_HEIGHT + HANDLE_LENGTH * sn],
        size=[0.006, 0, 0], rgba=rgba, mass=LADLE_MASS * 0.4))
    if FRONT_LIP > 0:  # a low lip across the open front
        m = 6
        half_len_f = r * math.sin(2 * half_open / m / 2) + 1e-3
        for k in range(m):
            a = -half_open + 2 * half_open * (k + 0.5) / m
            _contact(ladle.add_geom(
                name=f"ladle_lip{k}", type=mujoco.mjtGeom.mjGEOM_BOX,
                size=[RIM_HALF_WIDTH, half_len_f, FRONT_LIP / 2],
                pos=[r * math.cos(a), r * math.sin(a), FRONT_LIP / 2],
                quat=[math.cos(a / 2), 0, 0, math.sin(a / 2)], rgba=rgba, mass=1e-3))
    ladle.add_site(name="ladle_tray", pos=[0, 0, 0], size=[0.004, 0, 0], rgba=[1, 0, 0, 1])
    grip = (-back - HANDLE_LENGTH * c, 0.0, RIM_HEIGHT + HANDLE_LENGTH * sn)
    ladle.add_site(name="ladle_grip", pos=list(grip), size=[0.004, 0, 0], rgba=[0, 0, 1, 1])
    add_wrist_ft(part, ladle, pos=grip)
    # attached with the prefix "ladle" (MuJoCo warns at compile time on an empty one), so
    # each name loses it here and gets it back: the compiled names stay "ladle_floor", ...
    stem = "ladle"
    for element in (*part.geoms, *part.sites):
        element.name = element.name.removeprefix(stem)
    for sensor in part.sensors:
        sensor.name = sensor.name.removeprefix(stem)
        sensor.objname = sensor.objname.removeprefix(stem)
    ladle.name = ""  # an unnamed body is not prefixed: named once attached
    attached: mujoco.MjsBody = body.add_frame().attach_body(ladle, stem, "")
    attached.name = stem
    return attached


def add_wrist_ft(spec: mujoco.MjSpec, ladle: mujoco.MjsBody, *,
                 pos: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
    """A wrist force/torque sensor at the ladle's mount: site ``ladle_ft`` and two sensors.

    The site sits at ``pos`` in the ladle frame (where the handle meets the hand: the grip,
    at Franka's ``tcp`` on the Panda), its axes those of the ladle frame. MuJoCo's ``force``
    (:data:`FT_FORCE`) and ``torque`` (:data:`FT_TORQUE`) sensors on it read the interaction
    wrench between the ladle's subtree and its parent body (the Panda hand, or the mocap rig's
    carrier), in the site frame, the torque about the site's origin: the wrench the parent
    exerts on the ladle (the ladle exerts its opposite on the parent, as a wrist F/T between
    flange and tool measures it). At rest that is ``R^T (0, 0, m g)`` for a ladle of mass
    ``m`` (``R`` the site's orientation), plus whatever rests on or pushes the ladle (beads on
    the tray, the bowl's floor, the pile). Noise-free and without latency:
    :mod:`tli_verify.sim.franka_sensors` models the real sensor. Sensors do not change the
    dynamics (they only make ``mj_step`` compute ``mj_rnePostConstraint``).

    Parameters
    ----------
    spec : mujoco.MjSpec
        The spec holding ``ladle``.
    ladle : mujoco.MjsBody
        The ladle body (:func:`add_ladle`).
    pos : tuple of float, shape (3,), optional
        Position of the mount in the ladle frame (m).
    """
    ladle.add_site(name=FT_SITE, pos=list(pos), size=[0.006, 0, 0], rgba=[1, 1, 0, 1])
    spec.add_sensor(name=FT_FORCE, type=mujoco.mjtSensor.mjSENS_FORCE,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname=FT_SITE)
    spec.add_sensor(name=FT_TORQUE, type=mujoco.mjtSensor.mjSENS_TORQUE,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname=FT_SITE)


def ladle_quat(pitch: float) -> FloatArray:
    """World orientation (w, x, y, z) of the ladle frame at ``pitch`` (module doc).

    ``R = Rx(pitch) Rz(-pi/2)``: the open front along world -y at pitch 0, tipped down by a
    positive pitch.

    Parameters
    ----------
    pitch : float
        Radians.

    Returns
    -------
    ndarray, shape (4,)
    """
    qz = np.array([math.cos(-math.pi / 4), 0.0, 0.0, math.sin(-math.pi / 4)])
    qx = np.array([math.cos(pitch / 2), math.sin(pitch / 2), 0.0, 0.0])
    out = np.empty(4)
    mujoco.mju_mulQuat(out, qx, qz)
    return out


TRAY_REFERENCE: tuple[float, float, float, float] = tuple(  # type: ignore[assignment]
    float(v) for v in ladle_quat(0.0))
"""The orientation chart's reference: the ladle frame at pitch 0, ``(w, x, y, z)``. A tray
pose's rotation vector ``v`` turns it: ``q = TRAY_REFERENCE (x) Exp(v)`` (the chart of pose
tasks, :mod:`tli_verify.tasks.orientation`). A pure pitch ``p`` is ``v = (0, p, 0)``: the
world x axis is the ladle frame's y axis at pitch 0. ``rx`` turns the tray about its front
axis (a roll, world -y at pitch 0), ``rz`` about its normal (a yaw)."""


def tray_quat(rotvec: npt.ArrayLike) -> FloatArray:
    """World orientation ``(w, x, y, z)`` of the tray at the rotation vector ``rotvec``
    (shape (3,), rad) in the chart at :data:`TRAY_REFERENCE`."""
    return np.asarray(quat_exp(np.asarray(rotvec, dtype=np.float64).reshape(3),
                               TRAY_REFERENCE), dtype=np.float64)


def build_mocap_scene(physics: PhysicsOptions = DEFAULT_PHYSICS) -> mujoco.MjModel:
    """The phase-1 scene: the ladle on a free "hand" body, and a mocap marker of its target.

    The free body ``ladle_carrier`` (1 kg, like the Panda hand; gravity compensated) carries
    the ladle; :class:`tli_verify.sim.demos.MocapRig` drives it to the pose of the mocap body
    ``ladle_target`` with a Cartesian impedance law (a spring-damper wrench in
    ``xfrc_applied``), so perturbation wrenches push and tilt it as they would a hand under
    impedance control. The marker does not collide.

    Parameters
    ----------
    physics : PhysicsOptions, optional
        Solver settings (default: the measured ones).

    Returns
    -------
    mujoco.MjModel
    """
    spec = mujoco.MjSpec()
    spec.modelname = "soup_scooping_mocap"
    set_contact_options(spec, physics)
    add_scene(spec)
    start = SOUP_CENTER + np.array([0.0, 0.25, 0.2])
    q = ladle_quat(0.0)
    marker = spec.worldbody.add_body(name="ladle_target", mocap=True, pos=start.tolist(),
                                     quat=q.tolist())
    marker.add_site(name="target_marker", size=[0.005, 0, 0], rgba=[0, 1, 0, 0.5])
    carrier = spec.worldbody.add_body(name="ladle_carrier", pos=start.tolist(), quat=q.tolist())
    carrier.add_freejoint(name="ladle_free")
    carrier.mass = CARRIER_MASS
    carrier.inertia = [CARRIER_INERTIA] * 3
    carrier.explicitinertial = True
    carrier.gravcomp = 1.0  # as the arm's gravity compensation would
    add_ladle(carrier).gravcomp = 1.0
    spec.worldbody.add_light(pos=[0.5, 0.0, 1.5], dir=[0, 0, -1])
    spec.worldbody.add_camera(name="side", pos=[1.3, 0.0, 0.45],
                              xyaxes=[0, 1, 0, -0.3, 0, 0.95])
    try:
        return spec.compile()
    except ValueError as exc:  # pragma: no cover - a bug in this module
        raise TliError(f"sim scene: MuJoCo refused the generated MJCF: {exc}") from exc


@dataclass(frozen=True, slots=True, eq=False)
class SceneIds:
    """Ids of the scene's parts in a compiled model (what the sensors read).

    Attributes
    ----------
    bead_bodies : ndarray of int, shape (30,)
    bead_geoms : ndarray of int, shape (30,)
    bead_qpos : ndarray of int, shape (30,)
        Address of each bead's free joint in ``qpos`` (7 numbers each).
    bead_dof : ndarray of int, shape (30,)
        Address of each bead's free joint in ``qvel`` (6 numbers each).
    ladle_body : int
    ladle_geoms : frozenset of int
        The tray floor and rim (what a bead rests on).
    tray_site : int
    """

    bead_bodies: npt.NDArray[np.int64]
    bead_geoms: npt.NDArray[np.int64]
    bead_qpos: npt.NDArray[np.int64]
    bead_dof: npt.NDArray[np.int64]
    ladle_body: int
    ladle_geoms: frozenset[int]
    tray_site: int


def scene_ids(model: mujoco.MjModel) -> SceneIds:
    """Look up the scene's ids in ``model`` (built with :func:`add_scene` + :func:`add_ladle`)."""
    def need(kind: mujoco.mjtObj, name: str) -> int:
        i = int(mujoco.mj_name2id(model, kind, name))
        if i < 0:
            raise TliError(f"sim scene: the model has no {name!r} "
                           "(build it with tli_verify.sim.scene)")
        return i

    bodies = np.array([need(mujoco.mjtObj.mjOBJ_BODY, f"bead{i}") for i in range(N_BEADS)])
    geoms = np.array([need(mujoco.mjtObj.mjOBJ_GEOM, f"bead{i}") for i in range(N_BEADS)])
    joints = [need(mujoco.mjtObj.mjOBJ_JOINT, f"bead{i}_free") for i in range(N_BEADS)]
    ladle = need(mujoco.mjtObj.mjOBJ_BODY, "ladle")
    tray = {need(mujoco.mjtObj.mjOBJ_GEOM, "ladle_floor")}
    k = 0
    while (g := int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"ladle_rim{k}"))) >= 0:
        tray.add(g)
        k += 1
    return SceneIds(bead_bodies=bodies.astype(np.int64), bead_geoms=geoms.astype(np.int64),
                    bead_qpos=np.array([model.jnt_qposadr[j] for j in joints], dtype=np.int64),
                    bead_dof=np.array([model.jnt_dofadr[j] for j in joints], dtype=np.int64),
                    ladle_body=ladle, ladle_geoms=frozenset(tray),
                    tray_site=need(mujoco.mjtObj.mjOBJ_SITE, "ladle_tray"))


def reset_beads(model: mujoco.MjModel, data: mujoco.MjData, ids: SceneIds, *,
                seed: int = 0, settle: float = 0.6,
                step: Callable[[], None] | None = None, in_bowl: int = N_BEADS) -> None:
    """Put the beads on their grid with a seeded jitter and let them settle in the bowl.

    Parameters
    ----------
    model, data : MuJoCo model and data
        Only the beads are reset; the rest evolves under ``step`` while they settle.
    ids : SceneIds
    seed : int, optional
    settle : float, optional
        Seconds of simulation to let the beads fall and come to rest.
    step : callable, optional
        One physics step (the caller's controller + ``mj_step``); default plain ``mj_step``.
    in_bowl : int, optional
        How many beads go into the soup bowl; the others rest in a row on the far edge of the
        table (x = 0.8 m), out of the task (a bowl already scooped from: the demonstrations).
    """
    if not 1 <= in_bowl <= N_BEADS:
        raise TliError(f"in_bowl must be between 1 and {N_BEADS}, got {in_bowl}")
    rng = default_rng(seed, Stream.SCENE)
    for i in range(N_BEADS):
        a = int(ids.bead_qpos[i])
        jitter = rng.uniform(-0.2, 0.2, size=2) * BEAD_RADIUS
        data.qpos[a:a + 3] = _bead_grid(i) + np.array([jitter[0], jitter[1], 0.0]) \
            if i < in_bowl else (0.8, -0.45 + 2.5 * BEAD_RADIUS * i, BEAD_RADIUS)
        data.qpos[a + 3:a + 7] = (1.0, 0.0, 0.0, 0.0)
        d = int(ids.bead_dof[i])
        data.qvel[d:d + 6] = 0.0
    mujoco.mj_forward(model, data)
    for _ in range(round(settle / model.opt.timestep)):
        if step is None:
            mujoco.mj_step(model, data)
        else:
            step()
