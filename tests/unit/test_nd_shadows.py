"""Shadows of a 4-D task's regions are exact where the shape allows (issue 32, part 6): a 4-D
ball's shadow is a circle, an ellipsoid's the ellipse of its marginal, a box's a rectangle, a
polytope's the polygon of its projected vertices; only unions/differences (and cells an earlier
region overlaps) are sampled. The task is a file a user writes."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from tli_verify.viz import regions as vr

TASK = """
name = "four"
dt = 0.01
background = "free"

[state]
names = ["a", "b", "c", "d"]
lower = [-2.0, -2.0, -2.0, -2.0]
upper = [2.0, 2.0, 2.0, 2.0]

[regions.ball]
ball = { center = [1.0, 1.0, 0.0, 0.0], radius = 0.6 }

[regions.egg]
ellipsoid = { center = [-1.0, 1.0, 0.5, -0.5], matrix = [
    [4.0, 1.0, 0.0, 0.5], [1.0, 3.0, 0.5, 0.0], [0.0, 0.5, 2.0, 0.3], [0.5, 0.0, 0.3, 5.0]] }

[regions.slab]
box = { lower = [-1.5, -1.9, -1.0, -1.5], upper = [-0.5, -0.6, 1.5, 0.0] }

[regions.gem]
polytope = { A = %(A)s, b = %(b)s }

[regions.ring]
difference = [
    { box = { lower = [0.5, -1.9, -1.9, -1.9], upper = [1.9, -0.2, 1.9, 1.9] } },
    { ball = { center = [1.2, -1.0, 0.0, 0.0], radius = 0.4 } }]

[sensors]
s = "ball"
"""

# a rotated 4-D cube around (1, -1, 0, 0)... placed away from the ring: centre (0, 0, 0, 1.2)
_Q, _ = np.linalg.qr(np.random.default_rng(7).normal(size=(4, 4)))
_CENTER = np.array([0.0, 0.0, 0.0, 1.2])
_HALF = 0.35
A = np.vstack([_Q.T, -_Q.T])
B = np.concatenate([_HALF + _Q.T @ _CENTER, _HALF - _Q.T @ _CENTER])


def _vertices() -> np.ndarray:
    return np.array([_CENTER + _Q @ (np.array(s) * _HALF)
                     for s in itertools.product((-1, 1), repeat=4)])


@pytest.fixture(scope="module")
def task(tmp_path_factory: pytest.TempPathFactory):
    import tli_verify as tli

    path = tmp_path_factory.mktemp("four") / "four.toml"
    path.write_text(TASK % {"A": np.round(A, 12).tolist(), "b": np.round(B, 12).tolist()})
    return tli.load_task(path)


def _area(P: np.ndarray) -> float:
    x, y = P[:, 0], P[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


PAIRS = list(itertools.combinations(range(4), 2))


def test_which_regions_are_exact(task) -> None:
    shapes = dict(zip(task.region_names, vr.exact_shapes(task), strict=False))
    assert {k for k, v in shapes.items() if v is not None} == {"ball", "egg", "slab", "gem"}
    assert shapes["ring"] is None  # a difference: sampled


@pytest.mark.parametrize(("i", "j"), PAIRS)
def test_a_ball_s_shadow_is_a_circle(task, i: int, j: int) -> None:
    shape = vr.exact_shapes(task)[task.region_names.index("ball")]
    P = vr.exact_shadow(shape, i, j, task.lo, task.hi)
    c = np.array([[1.0, 1.0, 0.0, 0.0][i], [1.0, 1.0, 0.0, 0.0][j]])
    assert np.allclose(np.linalg.norm(P - c, axis=1), 0.6, atol=1e-12)


@pytest.mark.parametrize(("i", "j"), PAIRS)
def test_an_ellipsoid_s_shadow_is_the_marginal_ellipse(task, i: int, j: int) -> None:
    shape = vr.exact_shapes(task)[task.region_names.index("egg")]
    P = vr.exact_shadow(shape, i, j, task.lo, task.hi)
    S = np.linalg.inv(np.asarray(shape.matrix))
    S2 = S[np.ix_([i, j], [i, j])]
    # the support function of the ellipse is the ellipsoid's: max over the 4-D shape of d.x
    for t in np.linspace(0, 2 * math.pi, 13):
        d = np.array([math.cos(t), math.sin(t)])
        assert float(np.max(P @ d)) == pytest.approx(
            float(d @ np.asarray(shape.center)[[i, j]] + math.sqrt(d @ S2 @ d)), abs=2e-3)
    assert _area(P) == pytest.approx(math.pi * math.sqrt(np.linalg.det(S2)), rel=1e-3)


@pytest.mark.parametrize(("i", "j"), PAIRS)
def test_a_polytope_s_shadow_is_its_projected_hull(task, i: int, j: int) -> None:
    from scipy.spatial import ConvexHull

    shape = vr.exact_shapes(task)[task.region_names.index("gem")]
    P = vr.exact_shadow(shape, i, j, task.lo, task.hi)
    V = _vertices()[:, [i, j]]
    assert _area(P) == pytest.approx(ConvexHull(V).volume, rel=1e-9)


@pytest.mark.parametrize(("i", "j"), PAIRS)
def test_every_sample_lies_in_the_exact_shadow(task, i: int, j: int) -> None:
    """Soundness against the sampler: the region's own samples project inside its shadow."""
    from matplotlib.path import Path as MplPath

    shapes = vr.exact_shapes(task)
    for s in vr.region_shadows(task, samples=2000):
        shape = shapes[s.index] if s.index < len(shapes) else None
        if shape is None or s.points is None:
            continue
        poly = MplPath(vr.exact_shadow(shape, i, j, task.lo, task.hi))
        assert poly.contains_points(s.points[:, [i, j]], radius=1e-3).all(), s.name


def test_the_picture_says_which_shadows_are_exact(task, tmp_path: Path) -> None:
    bg = vr._background(task, samples=1500)
    labels = [h.get_label() for h in bg.legend_handles()]
    assert "regions: shadows (projections; 4 exact, 2 sampled)" in labels  # + background
    pic = vr.plot_task(task, tmp_path / "four.png", samples=1500)
    assert pic.path.is_file() if hasattr(pic, "path") else (tmp_path / "four.png").is_file()
