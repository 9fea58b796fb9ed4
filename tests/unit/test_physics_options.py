"""The scene's solver settings (tli_verify.sim.scene.PhysicsOptions): the default is the
measured setting every trial and piece of evidence uses; the others change only what they say."""

from __future__ import annotations

import math

import pytest

from tli_verify.errors import TliError

mujoco = pytest.importorskip("mujoco")

from tli_verify.sim.scene import (  # noqa: E402
    DEFAULT_PHYSICS,
    PhysicsOptions,
    build_mocap_scene,
)

pytestmark = pytest.mark.sim

SLEEP = int(mujoco.mjtEnableBit.mjENBL_SLEEP)


def test_the_default_is_the_measured_setting() -> None:
    opt = build_mocap_scene().opt
    assert opt.solver == mujoco.mjtSolver.mjSOL_NEWTON
    assert opt.impratio == 10.0 and opt.tolerance == 1e-6 and opt.timestep == 0.002
    assert opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert opt.enableflags & SLEEP and opt.sleep_tolerance == pytest.approx(0.01)
    assert DEFAULT_PHYSICS == PhysicsOptions()


def test_each_setting_changes_only_its_option() -> None:
    base = build_mocap_scene().opt
    opt = build_mocap_scene(PhysicsOptions(sleep_tolerance=0.02)).opt
    assert opt.enableflags & SLEEP and opt.sleep_tolerance == pytest.approx(0.02)
    assert opt.solver == base.solver and opt.impratio == base.impratio
    opt = build_mocap_scene(PhysicsOptions(sleep=False)).opt
    assert not opt.enableflags & SLEEP
    assert opt.solver == base.solver and opt.impratio == base.impratio
    opt = build_mocap_scene(PhysicsOptions(solver="cg")).opt
    assert opt.solver == mujoco.mjtSolver.mjSOL_CG and opt.enableflags & SLEEP
    opt = build_mocap_scene(PhysicsOptions(impratio=1.0)).opt
    assert opt.impratio == 1.0 and opt.solver == base.solver


@pytest.mark.parametrize("kwargs", [
    {"solver": "pgs"}, {"impratio": 0.5}, {"impratio": math.nan}, {"impratio": math.inf},
    {"sleep_tolerance": 0.0}, {"sleep_tolerance": math.nan},
])
def test_bad_settings_are_refused(kwargs: dict[str, object]) -> None:
    with pytest.raises(TliError, match="physics: "):
        PhysicsOptions(**kwargs)  # type: ignore[arg-type]
