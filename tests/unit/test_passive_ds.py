"""The passive-DS law (tli_verify.sim.passive) on the arm alone: it tracks the DS velocity at
the measured state (position and turn rate: the DS's rates of the rotation vector), damps to
rest without one, holds the orientation its servo is given, keeps its energy tank in bounds,
and refuses gains outside the Franka's documented ranges."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import pytest

from tests.support.sim import require_panda
from tli_verify.errors import InputError

pytestmark = pytest.mark.sim


@pytest.fixture(scope="module")
def panda() -> Any:
    return require_panda()


def _law(panda: Any, **gains: float) -> tuple[Any, Any]:
    from tli_verify.sim.controller import DSStateMap
    from tli_verify.sim.passive import PassiveDSController, PassiveGains
    from tli_verify.sim.robot import HOME_QPOS

    data = panda.new_data(np.array(HOME_QPOS))
    law = PassiveDSController(panda, panda.tcp_site, DSStateMap(panda.tcp_site),
                              gains=PassiveGains(**gains))
    return law, data


def _run(panda: Any, law: Any, data: Any, steps: int, *,
         angular: bool = False) -> list[np.ndarray]:
    """``steps`` physics steps of the law; the site's linear velocity after each (world; with
    ``angular``, the twist ``(v, omega)``)."""
    jacp, jacr = np.zeros((3, panda.model.nv)), np.zeros((3, panda.model.nv))
    out = []
    for _ in range(steps):
        mujoco.mj_step1(panda.model, data)
        law.compute(data)
        mujoco.mj_step2(panda.model, data)
        mujoco.mj_jacSite(panda.model, data, jacp, jacr, panda.tcp_site)
        out.append(np.concatenate((jacp @ data.qvel, jacr @ data.qvel)) if angular
                   else jacp @ data.qvel)
    return out


def test_the_site_moves_at_the_ds_velocity(panda: Any) -> None:
    """A constant DS velocity of 10 cm/s along y (no tank limit in 0.5 s): after the arm's
    transient (its task inertia over the damping: a few ms) the site moves at it, within
    1 cm/s, and the energy it put in came from the tank, which stayed in its bounds."""
    law, data = _law(panda)
    f = np.array([0.0, 0.1, 0.0, 0.0, 0.0, 0.0])
    law.set_velocity(f)
    vel = _run(panda, law, data, 250)
    late = np.array(vel[150:])
    assert np.max(np.abs(late - f[:3]), axis=0).max() < 0.01, late[-1]
    assert 0.0 < law.tank_low <= law.tank <= law.gains.tank_max
    assert law.withheld == 0


def test_without_a_ds_velocity_the_arm_comes_to_rest(panda: Any) -> None:
    """f = 0 is pure damping: a site moving at 20 cm/s is brought to rest (passive), and the
    tank only gains (the damping's dissipation)."""
    law, data = _law(panda)
    law.set_velocity(np.array([0.0, 0.2, 0.0, 0.0, 0.0, 0.0]))
    _run(panda, law, data, 150)
    start = law.tank
    law.set_velocity(np.zeros(6))
    vel = _run(panda, law, data, 250)
    assert np.linalg.norm(vel[0]) > 0.15 and np.linalg.norm(vel[-1]) < 0.01
    assert law.tank >= start


def test_an_empty_tank_withholds_the_ds_part(panda: Any) -> None:
    """A tank 10 mJ above its floor: the DS part is switched off (counted) whenever it would
    inject energy the tank does not hold, so the tank never runs dry (passivity), and the
    arm, which can spend only what the damping gives back, falls short of the DS velocity."""
    law, data = _law(panda, tank_start=0.06, tank_min=0.05, tank_max=0.06)
    law.set_velocity(np.array([0.0, 0.1, 0.0, 0.0, 0.0, 0.0]))
    vel = _run(panda, law, data, 200)
    assert law.withheld > 0
    assert 0.0 < law.tank_low and law.tank <= 0.06
    full, dfull = _law(panda)
    full.set_velocity(np.array([0.0, 0.1, 0.0, 0.0, 0.0, 0.0]))
    ref = _run(panda, full, dfull, 200)
    assert abs(vel[-1][1]) < abs(ref[-1][1]) - 0.01, (vel[-1], ref[-1])


def test_the_site_turns_at_the_ds_turn_rate(panda: Any) -> None:
    """A constant pitch rate of 0.3 rad/s (``ry``, no servo): the site turns about world x
    (the default chart's pitch axis) at the DS's turn rate ``r0 J_l(v) f_rot``, within
    0.07 rad/s (measured: 0.05, the joints' own damping, 1 Nms/rad each, which the law does not
    compensate, against its 6 Nms/rad), about no other axis, and stays where it is."""
    law, data = _law(panda)
    f = np.array([0.0, 0.0, 0.0, 0.0, 0.3, 0.0])
    law.set_velocity(f)
    start = law.map.ds_state(data)
    late = np.array(_run(panda, law, data, 250, angular=True)[150:])
    w_f = law.map.twist_from_ds_velocity(f, law.map.ds_state(data))[3:]
    np.testing.assert_allclose(w_f, [0.3, 0.0, 0.0], atol=2e-3)  # about world x
    assert np.abs(late[:, 3:] - w_f).max() < 0.07, late[-1]
    assert np.abs(late[:, :3]).max() < 0.01  # the site stays
    turned = law.map.ds_state(data) - start
    assert 0.1 < turned[4] < 0.15 and np.abs(turned[[3, 5]]).max() < 0.02, turned
    assert law.withheld == 0


def test_the_servo_holds_the_orientation_it_is_given(panda: Any) -> None:
    """With no DS velocity and the servo at a rotation vector turning all three axes, the site
    turns there (within 2 mrad on each after 1 s) and comes to rest."""
    law, data = _law(panda)
    servo = np.array([0.1, 0.2, -0.15])
    law.set_velocity(np.zeros(6), servo)
    start = law.map.ds_state(data)
    vel = _run(panda, law, data, 500, angular=True)
    z = law.map.ds_state(data)
    assert np.abs(start[3:] - servo).min() > 0.09  # it did start away
    np.testing.assert_allclose(z[3:], servo, atol=2e-3)
    assert np.linalg.norm(vel[-1]) < 0.01
    law.set_velocity(np.zeros(6))  # no servo: no spring pulls it anywhere
    _run(panda, law, data, 250)
    np.testing.assert_allclose(law.map.ds_state(data)[3:], z[3:], atol=2e-3)


@pytest.mark.parametrize("field", ["lambda1", "lambda2", "d_rot", "k_rot"])
def test_gains_outside_the_documented_ranges_are_refused(field: str) -> None:
    from tli_verify.sim.passive import PassiveGains

    with pytest.raises(InputError, match=field):
        PassiveGains(**{field: 1e4})
    with pytest.raises(InputError, match="tank"):
        PassiveGains(tank_min=2.0, tank_start=1.0)
