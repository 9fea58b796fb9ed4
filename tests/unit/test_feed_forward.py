"""The Franka loop's velocity feed-forward at the workspace's bounds (tli_verify.sim.target)."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from tli_verify.sim.target import feed_forward

LO = np.array([4.3, -3.35, -0.39, -1.0])
HI = np.array([5.7, 2.63, 2.62, 1.8])

finite = st.floats(-3.0, 3.0, allow_nan=False)
state = st.lists(st.floats(-5.0, 8.0, allow_nan=False), min_size=4, max_size=4)


@given(state, st.lists(finite, min_size=4, max_size=4))
def test_nothing_is_fed_into_a_bound_the_target_rests_at(z: list[float], v: list[float]) -> None:
    target = np.clip(np.array(z), LO, HI)
    vel = np.array(v)
    out = feed_forward(target, vel, LO, HI)
    for i in range(4):
        if (target[i] >= HI[i] and vel[i] > 0) or (target[i] <= LO[i] and vel[i] < 0):
            assert out[i] == 0.0
        else:
            assert out[i] == vel[i]  # elsewhere the DS's velocity, unchanged


def test_inside_the_workspace_it_is_the_ds_velocity() -> None:
    v = np.array([0.5, 2.0, -1.0, 0.3])
    assert np.array_equal(feed_forward((LO + HI) / 2, v, LO, HI), v)
    at_edge = HI.copy()
    at_edge[0] = 5.0
    assert np.array_equal(feed_forward(at_edge, v, LO, HI), np.array([0.5, 0.0, -1.0, 0.0]))
