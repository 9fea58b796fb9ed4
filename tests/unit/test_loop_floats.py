"""The Franka loop's per-period arithmetic on floats equals numpy's bit for bit
(tli_verify.sim.target: the leash and workspace clips, the feed-forward; the trials' outcomes bind
the evidence, so a faster loop must not change one bit of the targets it sends)."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from tli_verify.sim.target import clip_floats, feed_forward, feed_forward_floats

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
    assert _bits(np.array(clip_floats(x, lo, hi))) == _bits(want)


@given(vec, vec, vec, vec)
def test_feed_forward_floats_is_the_numpy_rule(target: list[float], v: list[float],
                                               lo: list[float], hi: list[float]) -> None:
    t, vv, lo_a, hi_a = map(np.array, (target, v, lo, hi))
    into = ((t >= hi_a) & (vv > 0)) | ((t <= lo_a) & (vv < 0))
    want = np.where(into, 0.0, vv)
    assert _bits(np.array(feed_forward_floats(target, v, lo, hi))) == _bits(want)
    assert _bits(feed_forward(t, vv, lo_a, hi_a)) == _bits(want)


def test_the_loops_leash_clip_on_a_signed_zero() -> None:
    # np.clip with array bounds returns the bound on a tie: -0.0 against a bound of 0.0 is 0.0
    assert _bits(np.array(clip_floats([-0.0, 0.0], [0.0, -0.0], [1.0, 1.0]))) == \
        _bits(np.clip(np.array([-0.0, 0.0]), np.array([0.0, -0.0]), np.array([1.0, 1.0])))


# points near a bowl's rim and its floor and height, where the answer is decided in the last bits
near = st.floats(-1e-12, 1e-12)


@given(st.sampled_from(["soup", "target"]), st.floats(0.0, 2 * np.pi), st.floats(0.5, 1.5),
       near, st.floats(-0.02, 0.3), st.sampled_from([0.0, 0.02, 0.25]))
def test_bowl_contains_is_inside_for_one_point(which: str, angle: float, scale: float,
                                               eps: float, height: float, above: float) -> None:
    from tli_verify.sim.scene import SOUP_BOWL, TARGET_BOWL

    bowl = SOUP_BOWL if which == "soup" else TARGET_BOWL
    cx, cy, cz = bowl.center.tolist()
    rho = bowl.radius * (scale if scale < 0.9 or scale > 1.1 else 1.0) * (1.0 + eps)
    p = np.array([cx + rho * np.cos(angle), cy + rho * np.sin(angle), cz + height])
    want = bool(bowl.inside(p, above=above))
    assert bowl.contains(*p.tolist(), above=above) is want
    # on the floor and height bounds themselves
    for zz in (bowl.floor - 1e-3, bowl.height + above):
        q = np.array([p[0], p[1], cz + zz])
        assert bowl.contains(*q.tolist(), above=above) is bool(bowl.inside(q, above=above))


def test_bowl_contains_at_the_rim_in_the_last_bit() -> None:
    from tli_verify.sim.scene import TARGET_BOWL

    cx, cy, cz = TARGET_BOWL.center.tolist()
    r = TARGET_BOWL.radius
    z = cz + 0.02
    xs = [cx + r]  # and the 4 floats on either side of it, where np.hypot decides
    for _ in range(4):
        xs = [float(np.nextafter(xs[0], -np.inf)), *xs, float(np.nextafter(xs[-1], np.inf))]
    for x in xs:
        p = np.array([x, cy, z])
        assert TARGET_BOWL.contains(*p.tolist()) is bool(TARGET_BOWL.inside(p))


@given(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3), near,
       st.sampled_from([25.0, 2.5]), st.sampled_from([0, 3]), special)
def test_detector_threshold_is_the_norms(direction: list[float], eps: float, limit: float,
                                         i: int, other: float) -> None:
    from tli_verify.sim.contact import _beyond

    d = np.array(direction)
    n = float(np.linalg.norm(d))
    part = d / n * limit * (1.0 + eps) if n > 1e-6 else d * limit
    w = np.full(6, other)
    w[i:i + 3] = part
    assert _beyond(w, i, limit) is (float(np.linalg.norm(w[i:i + 3])) > limit)
    assert _beyond(w, 3 - i, limit) is (float(np.linalg.norm(w[3 - i:6 - i])) > limit)
