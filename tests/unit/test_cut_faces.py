"""Cuts in n-D pictures are shadows, like the regions (issue 32, part 6): the shadow of a cut's
face -- the part of its plane that bounds the mode's region -- is exact
(:func:`tli_verify.viz.regions.cut_face_shadow`). Checked on 4-D cut sets: every point of the
face projects inside the polygon, and the points fill it; a face whose normal lies in the plane
projects to a segment; a face removed by another cut, or covering the panel, is not drawn."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from tli_verify.viz.regions import cut_face_shadow

LO, HI = np.zeros(4), np.ones(4)
PAIRS = list(itertools.combinations(range(4), 2))


def _cuts(seed: int, count: int = 6) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` random unit normals through points around the centre (the mode's region, the
    inner side ``w . (x - p) <= 0``, holds the centre)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        w = rng.normal(size=4)
        w /= np.linalg.norm(w)
        out.append((w, 0.5 + w * rng.uniform(0.15, 0.4)))
    return out


def _face_points(cuts: list[tuple[np.ndarray, np.ndarray]], k: int, seed: int) -> np.ndarray:
    """Points of cut k's face: box samples moved onto its plane, kept where the box and the
    other cuts hold them."""
    w, p = cuts[k]
    X = np.random.default_rng([seed, k]).uniform(LO, HI, size=(40000, 4))
    X = X - np.outer((X - p) @ w, w)
    keep = np.all((X >= LO) & (X <= HI), axis=1)
    for q, (v, r) in enumerate(cuts):
        if q != k:
            keep &= (X - r) @ v <= 0.0
    return X[keep]


def _inside(poly: np.ndarray, pts: np.ndarray, tol: float) -> np.ndarray:
    """Points inside a counter-clockwise convex polygon (within ``tol``)."""
    ok = np.ones(len(pts), dtype=bool)
    for a, b in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        e = b - a
        ok &= e[0] * (pts[:, 1] - a[1]) - e[1] * (pts[:, 0] - a[0]) >= -tol * np.hypot(*e)
    return ok


@pytest.mark.parametrize("seed", range(4))
def test_a_face_s_points_project_inside_its_shadow_and_fill_it(seed: int) -> None:
    cuts = _cuts(seed)
    checked = 0
    for k, (i, j) in itertools.product(range(len(cuts)), PAIRS):
        others = [c for q, c in enumerate(cuts) if q != k]
        poly = cut_face_shadow(*cuts[k], i, j, LO, HI, others)
        F = _face_points(cuts, k, seed)
        if poly is None:  # empty, or covering the whole panel
            assert len(F) < 50 or ConvexHull(F[:, [i, j]]).volume > 0.95
            continue
        assert poly.shape[1] == 2 and len(poly) >= 2
        if len(F) < 200 or len(poly) == 2:
            continue
        assert _inside(poly, F[:, [i, j]], 1e-9).all()
        hull = ConvexHull(F[:, [i, j]]).volume
        area = ConvexHull(poly).volume
        assert 0.85 * area <= hull <= area * (1 + 1e-9)
        checked += 1
    assert checked >= 10


def test_a_box_s_faces_are_segments_or_its_rectangle() -> None:
    lower, upper = np.array([0.45, 0.45, 0.45, 0.4]), np.array([0.55, 0.55, 0.55, 0.6])
    cuts = []
    for k in range(4):
        e = np.eye(4)[k]
        cuts += [(e, upper * e), (-e, lower * e)]
    for (k, (w, p)), (i, j) in itertools.product(enumerate(cuts), PAIRS):
        poly = cut_face_shadow(w, p, i, j, LO, HI, [c for q, c in enumerate(cuts) if q != k])
        assert poly is not None
        axis = k // 2
        got = np.sort(poly, axis=0)
        if axis in (i, j):  # the normal lies in the plane: a side of the rectangle
            assert len(poly) == 2
            u = 0 if axis == i else 1
            assert np.allclose(poly[:, u], p[axis])
        else:  # the face spans the plane's two coordinates: the whole rectangle
            assert len(poly) == 4
            assert np.allclose(got[[0, -1]], [[lower[i], lower[j]], [upper[i], upper[j]]])


def test_faces_not_drawn() -> None:
    e0 = np.eye(4)[0]
    # another cut keeps the mode on x1 <= 0.3: the face x1 = 0.6 bounds nothing
    assert cut_face_shadow(e0, 0.6 * e0, 0, 1, LO, HI, [(e0, 0.3 * e0)]) is None
    # the face x1 = 0.6 of the workspace covers every (x2, x3)
    assert cut_face_shadow(e0, 0.6 * e0, 1, 2, LO, HI) is None
