"""The Franka's limits in the torque loop (:mod:`tli_verify.sim.franka_limits`), the external
wrench estimate the robot computes (:attr:`ImpedanceController.external_wrench`) and the
``perturbed`` detector built on it (:class:`tli_verify.sim.contact.ContactDetector`)."""

from __future__ import annotations

import numpy as np
import pytest

from tli_verify.errors import InputError
from tli_verify.sim.franka_limits import (
    JOINT_VELOCITY_LIMITS,
    TORQUE_RATE_LIMIT,
    CartesianImpedance,
    FrankaLimits,
    LimitGuard,
)
from tli_verify.sim.robot import TORQUE_LIMITS

DT = 0.002
MASS = np.full(7, 0.5)


def test_torques_are_clipped_and_the_ratio_is_the_commanded_ones() -> None:
    guard = LimitGuard(FrankaLimits(), DT)
    tau = guard.apply(np.array([100.0, 0, 0, 0, 30.0, 0, 0]), np.zeros(7), MASS)
    assert np.all(np.abs(tau) <= TORQUE_LIMITS + 1e-12)
    assert tau[0] == pytest.approx(87.0) and tau[4] == pytest.approx(12.0)
    assert guard.ratios()["torque"] == pytest.approx(30.0 / 12.0)
    assert guard.stopped is None


def test_the_torque_rate_is_limited_per_step() -> None:
    guard = LimitGuard(FrankaLimits(), DT)
    guard.apply(np.zeros(7), np.zeros(7), MASS)
    tau = guard.apply(np.full(7, 10.0), np.zeros(7), MASS)
    step = TORQUE_RATE_LIMIT * DT  # 2 N m per 2 ms
    assert tau == pytest.approx(np.full(7, step))
    assert guard.ratios()["torque_rate"] == pytest.approx(10.0 / step)
    for _ in range(10):
        tau = guard.apply(np.full(7, 10.0), np.zeros(7), MASS)
    assert tau == pytest.approx(np.full(7, 10.0))  # reached, never faster than the rate


def test_a_joint_near_its_velocity_limit_is_braked_and_beyond_it_the_reflex_stops() -> None:
    limits = FrankaLimits()
    guard = LimitGuard(limits, DT)
    qd = np.zeros(7)
    qd[3] = 0.95 * JOINT_VELOCITY_LIMITS[3]
    tau = guard.apply(np.zeros(7), qd, MASS)
    assert tau[3] < 0.0 and np.all(tau[[0, 1, 2, 4, 5, 6]] == 0.0)  # against the motion
    assert guard.stopped is None
    qd[3] = 1.01 * JOINT_VELOCITY_LIMITS[3]
    guard.apply(np.zeros(7), qd, MASS)
    assert guard.stopped is not None and "joint 4 velocity" in guard.stopped
    assert guard.ratios()["joint_velocity"] == pytest.approx(1.01)
    guard.reset_ratios()
    assert guard.stopped is None and guard.ratios()["joint_velocity"] == 0.0


def test_an_end_effector_too_fast_stops_the_robot_unless_the_reflex_is_off() -> None:
    twist = np.array([1.8, 0.0, 0.0, 0.0, 0.0, 0.0])
    guard = LimitGuard(FrankaLimits(), DT)
    guard.apply(np.zeros(7), np.zeros(7), MASS, twist)
    assert guard.stopped is not None and "end-effector speed" in guard.stopped
    quiet = LimitGuard(FrankaLimits(reflex=False), DT)
    quiet.apply(np.zeros(7), np.zeros(7), MASS, twist)
    assert quiet.stopped is None and quiet.ratios()["cartesian_speed"] == pytest.approx(1.8 / 1.7)


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"stiffness_pos": 5000.0}, "stiffness_pos"),
    ({"stiffness_pos": 5.0}, "stiffness_pos"),
    ({"stiffness_rot": 400.0}, "stiffness_rot"),
    ({"damping_ratio": 0.0}, "damping_ratio"),
])
def test_an_impedance_outside_the_robots_range_is_refused(kwargs: dict[str, float],
                                                          field: str) -> None:
    with pytest.raises(InputError, match=field):
        CartesianImpedance(**kwargs)


def test_the_contact_detector_holds_and_releases() -> None:
    from tli_verify.sim.contact import ContactDetector

    det = ContactDetector(force=25.0, torque=2.5, hold=0.1)
    quiet, push = np.zeros(6), np.array([30.0, 0, 0, 0, 0, 0])
    assert not det.update(quiet, 0.02)
    assert det.update(push, 0.02)
    flags = [det.update(quiet, 0.02) for _ in range(8)]
    assert flags[:5] == [True] * 5 and not any(flags[6:])  # 0.1 s of hold, then off
    assert det.update(np.array([0, 0, 0, 0, 0, 3.0]), 0.02)  # a torque counts too
    with pytest.raises(InputError, match="contact detector"):
        ContactDetector(force=0.0)


@pytest.mark.sim
def test_the_external_wrench_estimate_sees_a_force_on_the_ladle() -> None:
    """A known 30 N force on the ladle of the Panda at rest: the estimate from the joints and
    the model (no simulator force read) finds it within 15 %, and nothing without it."""
    pytest.importorskip("mujoco")
    from tli_verify.sim.demos import PandaRig

    rig = PandaRig(0)
    rig.command(rig.pose())
    rig.step(100)
    quiet = float(np.linalg.norm(rig.external_wrench()[:3]))
    rig.push[:] = [0.0, 30.0, 0.0, 0.0, 0.0, 0.0]
    rig.step(150)
    est = rig.external_wrench()[:3]
    assert quiet < 5.0
    assert float(np.linalg.norm(est)) == pytest.approx(30.0, rel=0.15)
    assert est[1] > 0.8 * float(np.linalg.norm(est))  # along the push
