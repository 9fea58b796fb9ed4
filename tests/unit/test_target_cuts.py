"""The measured law's target kept inside the running mode's cut set (sim.target.inside_cuts)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.model.types import Cut
from tli_verify.sim.target import inside_cuts


def _cut(normal: list[float], point: list[float]) -> Cut:
    n = np.array(normal, dtype=np.float64)
    return Cut(normal=n / np.linalg.norm(n), point=np.array(point, dtype=np.float64))


def test_a_target_inside_every_cut_is_left_alone() -> None:
    cuts = (_cut([1, 0, 0, 0], [1, 0, 0, 0]), _cut([0, 1, 0, 0], [0, 2, 0, 0]))
    x = np.array([0.5, 1.0, 3.0, -1.0])
    assert inside_cuts(x, cuts) is x
    assert inside_cuts(x, ()) is x


def test_a_target_beyond_a_cut_is_projected_onto_its_plane() -> None:
    cut = _cut([1, 1, 0, 0], [1, 1, 0, 0])
    x = np.array([3.0, 3.0, 0.5, 0.2])
    y = inside_cuts(x, (cut,))
    assert abs(float(cut.normal @ (y - cut.point))) < 1e-12
    np.testing.assert_allclose(y[2:], x[2:])  # moved along the normal only


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_projected_targets_satisfy_every_cut_through_a_common_point(seed: int) -> None:
    """Cuts through (or beyond) a common inside state, like the cuts of a mode that hold its
    measured state: the projections end inside all of them (alternating projections)."""
    rng = np.random.default_rng(seed)
    inside = rng.normal(size=4)
    cuts = []
    for _ in range(int(rng.integers(1, 5))):
        n = rng.normal(size=4)
        n /= np.linalg.norm(n)
        cuts.append(Cut(normal=n, point=inside + rng.uniform(0.0, 0.5) * n))
    x = inside + rng.normal(scale=3.0, size=4)
    y = inside_cuts(x, tuple(cuts), inside)
    worst = max(float(c.normal @ (y - c.point)) for c in cuts)
    assert worst < 1e-12, worst
    if max(float(c.normal @ (x - c.point)) for c in cuts) <= 0.0:
        assert y is x
