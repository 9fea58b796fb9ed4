"""The Panda's stand (drawn only) and the camera that frames the arm (no OpenGL needed).

The stand (:func:`tli_verify.sim.scene.add_stand`) must not change a trial: its geoms collide
with nothing, and a rig built with it is bit-identical to one built without. The camera
(:data:`tli_verify.sim.render.PANDA_VIEW`) must show the base standing on the table, the whole
arm, both bowls and the ladle: their points are projected through MuJoCo's free camera
(``mjv_updateScene`` runs without a rendering context).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mujoco")

import mujoco

from tli_verify.sim import demos, render, scene
from tli_verify.sim.demos import PandaRig

pytestmark = pytest.mark.sim

STAND = ("table_stand", "table_leg0", "table_leg1", "table_leg2", "table_leg3", "floor")


@pytest.fixture(scope="module")
def rig() -> PandaRig:
    from tests.support.sim import require_panda

    require_panda()
    return PandaRig(0)


def _geom(model: mujoco.MjModel, name: str) -> int:
    g = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name))
    assert g >= 0, name
    return g


def test_the_stand_collides_with_nothing_and_holds_the_base(rig: PandaRig) -> None:
    m = rig.model
    for name in STAND:
        g = _geom(m, name)
        assert m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0, name
        assert m.geom_bodyid[g] == 0 and m.geom_group[g] == scene.VISUAL_GROUP, name
    # the base (link0, at the origin) stands on the stand's top face, inside its footprint
    base = int(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, render.BASE_BODY))
    assert np.allclose(rig.data.xpos[base], 0.0)
    g = _geom(m, "table_stand")
    lo = m.geom_pos[g] - m.geom_size[g]
    hi = m.geom_pos[g] + m.geom_size[g]
    assert hi[2] == pytest.approx(0.0) and lo[0] < -0.1 and lo[1] < -0.1 and hi[1] > 0.1
    table = _geom(m, "table")
    assert hi[0] == pytest.approx(m.geom_pos[table][0] - m.geom_size[table][0])  # flush


def test_a_rig_with_the_stand_is_bit_identical_to_one_without(
        rig: PandaRig, monkeypatch: pytest.MonkeyPatch) -> None:
    """The rig's construction moves the arm for 1 s and settles the beads for 0.6 s: every
    contact of the scene is made on the way."""
    monkeypatch.setattr(demos, "add_stand", lambda spec: None)  # where the rig calls it
    bare = PandaRig(0)
    assert bare.model.ngeom == rig.model.ngeom - len(STAND)
    for field in ("qpos", "qvel", "qacc", "act", "qfrc_applied", "xfrc_applied"):
        assert np.array_equal(getattr(bare.data, field), getattr(rig.data, field)), field
    assert bare.data.ncon == rig.data.ncon and bare.data.time == rig.data.time


def _project(model: mujoco.MjModel, data: mujoco.MjData, view: render.View,
             points: np.ndarray, size: tuple[int, int] = (360, 480)) -> np.ndarray:
    """Image coordinates (u right, v down, both 0..1) of world points seen from ``view``."""
    cam = mujoco.MjvCamera()
    cam.lookat[:] = view.lookat
    cam.distance, cam.azimuth, cam.elevation = view.distance, view.azimuth, view.elevation
    opt = mujoco.MjvOption()
    scn = mujoco.MjvScene(model, maxgeom=2000)
    mujoco.mjv_updateScene(model, data, opt, None, cam, mujoco.mjtCatBit.mjCAT_ALL, scn)
    gl = scn.camera[0]
    fwd = np.array(gl.forward)
    up = np.array(gl.up)
    right = np.cross(fwd, up)
    rel = points - np.array(gl.pos)
    z = rel @ fwd
    assert np.all(z > 0), "a point behind the camera"
    half_h = math.tan(math.radians(float(model.vis.global_.fovy)) / 2)
    half_w = half_h * size[1] / size[0]
    u = 0.5 + (rel @ right) / z / (2 * half_w)
    v = 0.5 - (rel @ up) / z / (2 * half_h)
    return np.stack([u, v], axis=1)


def test_the_panda_view_frames_the_arm_the_base_and_both_bowls(rig: PandaRig) -> None:
    m, d = rig.model, rig.data
    assert render.view_for(m) is render.PANDA_VIEW
    bodies = [int(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n))
              for n in (render.BASE_BODY, *(f"link{k}" for k in range(1, 8)), "hand", "ladle")]
    assert min(bodies) >= 0
    pts = [d.xpos[b] for b in bodies]
    for bowl in (scene.SOUP_BOWL, scene.TARGET_BOWL):
        for dy in (-bowl.radius, bowl.radius):
            pts.append(bowl.center + np.array([0.0, dy, bowl.height]))
    # where the arm's links go in a nominal trial (their origins reach y = 0.40 m over the
    # target bowl and z = 0.66 m; the meshes 0.1 m beyond)
    pts += [np.array([0.55, 0.45, 0.75]), np.array([0.0, 0.0, 0.8])]
    uv = _project(m, d, render.PANDA_VIEW, np.array(pts))
    margin = 0.03
    assert np.all((uv > margin) & (uv < 1 - margin)), uv
    # the soup bowl on the left, the target bowl on the right
    soup, target = uv[len(bodies)], uv[len(bodies) + 2]
    assert soup[0] < target[0]


def test_the_free_tool_keeps_its_close_up() -> None:
    model = scene.build_mocap_scene()
    assert render.view_for(model) is render.TOOL_VIEW
