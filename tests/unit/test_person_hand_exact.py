"""A person's hand (:meth:`~tli_verify.sim.perturbations.PersonHand.wrench`) gives *bit-identical*
wrenches to its plain numpy formulation.

The wrench is computed every physics step while a hand acts, so it is written for speed (the
norms without ``np.linalg.norm``'s Python wrapper -- the same ``ddot`` and square root --, the
spring-dampers per component on floats, the rotation's log from a list); the trials' outcomes
bind the evidence, so nothing may change by one bit. The reference here is the hand as first
written (``np.linalg.norm``, ``np.trace``, array arithmetic), driven through the same sequences
of poses and velocities: pushes and tilts, the force and torque caps, the release, rotations
near pi (the log's symmetric branch) and at rest. No MuJoCo needed.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tli_verify.sim.perturbations import HAND_RELEASE, PersonHand, Perturbation


def _hat(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _exp(w: np.ndarray) -> np.ndarray:
    theta = float(np.linalg.norm(w))
    if theta < 1e-12:
        return np.eye(3) + _hat(w)
    k = _hat(w / theta)
    return np.eye(3) + math.sin(theta) * k + (1.0 - math.cos(theta)) * (k @ k)


def _log(r: np.ndarray) -> np.ndarray:
    cos = min(1.0, max(-1.0, (float(np.trace(r)) - 1.0) / 2.0))
    theta = math.acos(cos)
    vee = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / 2.0
    if theta < 1e-6:
        return vee
    if math.pi - theta > 1e-4:
        return theta / math.sin(theta) * vee
    b = (r + np.eye(3)) / 2.0
    i = int(np.argmax(np.diag(b)))
    u = b[:, i] / math.sqrt(max(float(b[i, i]), 1e-12))
    if float(u @ vee) < 0:
        u = -u
    return theta * u / float(np.linalg.norm(u))


def _clip_norm(v: np.ndarray, limit: float) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v * (limit / n) if n > limit else v


class _PlainHand:
    """:class:`PersonHand`'s wrench as first written (the grab taken from ``hand``)."""

    def __init__(self, hand: PersonHand) -> None:
        self.hand = hand
        self.max_force = self.max_torque = 0.0

    def wrench(self, t: float, p: np.ndarray, r: np.ndarray, vel: np.ndarray,
               omega: np.ndarray) -> np.ndarray:
        h = self.hand
        if not h.start <= t < h.end:
            return np.zeros(6)
        p0, r0, motion = h._p0, h._r0, np.array(h.perturbation.motion)
        assert p0 is not None and r0 is not None
        s = h.progress(t)
        if h.perturbation.kind == "push":
            p_target, r_target = p0 + s * motion, r0
        else:
            p_target, r_target = p0, _exp(s * motion) @ r0
        force = _clip_norm(h.k * (p_target - p) - h.c * vel, h.f_max)
        torque = _clip_norm(h.k_r * _log(r_target @ r.T) - h.c_r * omega, h.tau_max)
        fade = min(1.0, max(0.0, (h.end - t) / HAND_RELEASE))
        force, torque = fade * force, fade * torque
        self.max_force = max(self.max_force, float(np.linalg.norm(force)))
        self.max_torque = max(self.max_torque, float(np.linalg.norm(torque)))
        return np.concatenate([force, torque])


def _rotation(w: np.ndarray) -> np.ndarray:
    return _exp(w)


@pytest.mark.parametrize("kind", ["push", "tilt"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_wrench_equals_the_plain_formulation_bit_for_bit(kind: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    if kind == "push":
        pert = Perturbation("push", 0.5, 1.0, displacement=(0.2, -0.1, 0.05))
    else:
        pert = Perturbation("tilt", 0.5, 1.0, rotation=(1.1, 0.3, -0.2))
    hand = PersonHand(pert)
    plain = _PlainHand(hand)
    p0 = rng.normal(scale=0.3, size=3)
    r0 = _rotation(rng.normal(size=3))
    capped = {"force": 0, "torque": 0, "pi": 0, "rest": 0, "faded": 0}
    for i in range(600):
        t = 0.45 + i * 0.002
        # the carrier wanders around the grab; now and then far (caps), turned by about pi
        # (the log's symmetric branch) or exactly at the grab pose (the log's small branch)
        far = 10.0 if i % 7 == 0 else 1.0
        p = p0 + far * rng.normal(scale=0.02, size=3)
        if i % 11 == 0:
            axis = rng.normal(size=3)
            r = _rotation((math.pi - 10.0 ** -rng.uniform(4.5, 9)) * axis / np.linalg.norm(axis)
                          ) @ r0
            capped["pi"] += 1
        elif i % 13 == 0:
            p, r = p0.copy(), r0.copy()
            capped["rest"] += 1
        else:
            r = _rotation(far * rng.normal(scale=0.1, size=3)) @ r0
        vel, omega = rng.normal(scale=0.3, size=3), rng.normal(scale=far * 0.5, size=3)
        if i == 30 and not hand.grabbed:
            hand.grab(p0, r0)
        got = hand.wrench(t, p, r.ravel(), vel, omega)
        want = plain.wrench(t, p, r, vel, omega)
        assert np.array_equal(got, want), (i, got - want)
        assert hand.max_force == plain.max_force and hand.max_torque == plain.max_torque
        if hand.active(t):
            capped["force"] += bool(np.isclose(np.linalg.norm(want[:3]), hand.f_max))
            capped["torque"] += bool(np.isclose(np.linalg.norm(want[3:]), hand.tau_max))
            capped["faded"] += hand.end - t < HAND_RELEASE
    assert all(v > 0 for v in capped.values()), capped
