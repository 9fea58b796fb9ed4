"""Paper Lemma 2's premise as a property: every attractor lies strictly inside the next mode.

Generated: a ball ``delta_r`` (convex, paper Asm. 1) in 2-3 dimensions and 1-4 demonstrations
that run in straight lines at a constant sampling step from outside the ball to a point inside
it, where they stop. Sensor ``r`` reads "inside the ball". For every such data set the attractor
of mode ``!r`` (:func:`tli_verify.segmentation.segment_demos`) is strictly inside the ball, for
any ``entry_samples``. (Appendix C's mean last state, the earlier rule, is outside the
ball for every single demonstration: the test fails at once on that rule.)
"""

from __future__ import annotations

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from tli_verify.demos import Demonstration
from tli_verify.segmentation import segment_demos


def _line_demo(start: np.ndarray, stop: np.ndarray, step: float, centre: np.ndarray,
               radius: float, index: int) -> Demonstration:
    length = float(np.linalg.norm(stop - start))
    ks = np.arange(0.0, length, step)
    X = np.vstack([start + np.outer(ks, (stop - start) / length), stop])
    t = np.arange(len(X), dtype=float)
    inside = np.linalg.norm(X - centre, axis=1) <= radius
    return Demonstration(path=f"line{index}.csv", t=t, x=X, dx=np.gradient(X, t, axis=0),
                         sensor_names=("r",), sensors=inside[:, None])


@st.composite
def scenes(draw: st.DrawFn) -> tuple[np.ndarray, float, list[Demonstration], int]:
    n = draw(st.integers(2, 3))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    centre = rng.uniform(-5, 5, size=n)
    radius = float(rng.uniform(0.5, 3.0))
    demos = []
    for i in range(draw(st.integers(1, 4))):
        u = rng.normal(size=n)
        u /= np.linalg.norm(u)
        start = centre + u * (radius + rng.uniform(0.5, 5.0))
        w = rng.normal(size=n)
        stop = centre + w / np.linalg.norm(w) * radius * rng.uniform(0.0, 0.95)
        step = float(rng.uniform(0.05, 0.4))  # at least two samples before the ball
        demos.append(_line_demo(start, stop, step, centre, radius, i))
    return centre, radius, demos, draw(st.integers(1, 6))


@settings(max_examples=60)
@given(scenes())
def test_attractor_strictly_inside_the_next_ball(
        scene: tuple[np.ndarray, float, list[Demonstration], int]) -> None:
    centre, radius, demos, entry = scene
    # the goal mode r needs two samples in all to learn a DS (else a DemoError, rightly)
    assume(sum(int(d.sensors[:, 0].sum()) for d in demos) >= 2)
    data = segment_demos(demos, entry_samples=entry).data["!r"]
    assert data.next_mode == "r"
    assert np.linalg.norm(data.attractor - centre) < radius * (1 - 1e-9)
