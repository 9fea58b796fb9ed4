"""The Franka loop's per-period arithmetic on floats equals numpy's bit for bit
(tli_verify.sim.loop: the leash and workspace clips, the feed-forward; the trials' outcomes bind
the evidence, so a faster loop must not change one bit of the targets it sends)."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from tli_verify.sim.loop import _clip, _feed_forward, feed_forward

# values that tie with the bounds, signed zeros and NaNs included: numpy's clip rule decides
special = st.sampled_from([0.0, -0.0, 1.0, -1.0, 0.5, np.nan, np.inf, -np.inf])
value = st.one_of(st.floats(-10.0, 10.0), special)
vec = st.lists(value, min_size=4, max_size=4)


def _bits(a: np.ndarray) -> bytes:
    return np.asarray(a, dtype=np.float64).tobytes()


@given(vec, vec, vec)
def test_clip_is_numpys_clip_bit_for_bit(x: list[float], lo: list[float], hi: list[float]
                                         ) -> None:
    want = np.clip(np.array(x), np.array(lo), np.array(hi))
    assert _bits(np.array(_clip(x, lo, hi))) == _bits(want)


@given(vec, vec, vec, vec)
def test_feed_forward_floats_is_the_numpy_rule(target: list[float], v: list[float],
                                               lo: list[float], hi: list[float]) -> None:
    t, vv, lo_a, hi_a = map(np.array, (target, v, lo, hi))
    into = ((t >= hi_a) & (vv > 0)) | ((t <= lo_a) & (vv < 0))
    want = np.where(into, 0.0, vv)
    assert _bits(np.array(_feed_forward(target, v, lo, hi))) == _bits(want)
    assert _bits(feed_forward(t, vv, lo_a, hi_a)) == _bits(want)


def test_the_loops_leash_clip_on_a_signed_zero() -> None:
    # np.clip with array bounds returns the bound on a tie: -0.0 against a bound of 0.0 is 0.0
    assert _bits(np.array(_clip([-0.0, 0.0], [0.0, -0.0], [1.0, 1.0]))) == \
        _bits(np.clip(np.array([-0.0, 0.0]), np.array([0.0, -0.0]), np.array([1.0, 1.0])))
