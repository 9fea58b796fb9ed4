"""Exact signed distances of boxes, polytopes, balls and ellipsoids (tli_verify.tasks.geometry).

Every distance is checked against something computed another way: a closed form in rotated
coordinates, brute force over sampled directions or sampled surface points (which bound the
true distance from one side), cvxpy with Clarabel, or independent local minimisation.
"""

from __future__ import annotations

import cvxpy as cp
import numpy as np
import numpy.typing as npt
import pytest
from scipy.optimize import minimize, minimize_scalar
from scipy.spatial import ConvexHull

from tli_verify.tasks import geometry as geo

FloatArray = npt.NDArray[np.float64]
DIMS = [2, 3, 4, 5, 6]


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------


def _rotation(rng: np.random.Generator, n: int) -> FloatArray:
    Q, R = np.linalg.qr(rng.normal(size=(n, n)))
    return np.asarray(Q * np.sign(np.diag(R)), dtype=np.float64)


def _unit(rng: np.random.Generator, k: int, n: int) -> FloatArray:
    U = rng.normal(size=(k, n))
    return np.asarray(U / np.linalg.norm(U, axis=1, keepdims=True), dtype=np.float64)


class RotatedBox:
    """``{c + R u : |u_i| <= h_i}`` written as ``A x <= b`` with unnormalised, redundant rows."""

    def __init__(self, rng: np.random.Generator, n: int) -> None:
        self.n = n
        self.R = _rotation(rng, n)
        self.h = rng.uniform(0.5, 3.0, size=n)
        self.c = rng.uniform(-2.0, 2.0, size=n)
        rows = np.vstack([self.R.T, -self.R.T])
        offs = np.concatenate([self.h + self.R.T @ self.c, self.h - self.R.T @ self.c])
        scale = rng.uniform(0.2, 5.0, size=2 * n)
        # Redundant rows: a loosened copy of a face and the (loose) sum of two opposite faces.
        red_a = np.vstack([rows[0] * 2.0, rows[0] + rows[1]])
        red_b = np.array([2.0 * offs[0] + 0.3, offs[0] + offs[1] + 0.1])
        self.A = np.vstack([rows * scale[:, None], red_a])
        self.b = np.concatenate([offs * scale, red_b])

    def local(self, X: FloatArray) -> FloatArray:
        return np.asarray((X - self.c) @ self.R, dtype=np.float64)

    def exact(self, X: FloatArray) -> FloatArray:
        """Closed-form signed distance in the box's own coordinates."""
        return geo.box_signed_distance(-self.h, self.h, self.local(X))

    def sample_inside(self, rng: np.random.Generator, k: int) -> FloatArray:
        return np.asarray(self.c + rng.uniform(-0.95, 0.95, (k, self.n)) * self.h @ self.R.T)

    def sample_surface(self, rng: np.random.Generator, k: int) -> FloatArray:
        U = rng.uniform(-1.0, 1.0, (k, self.n))
        axis = rng.integers(0, self.n, size=k)
        U[np.arange(k), axis] = rng.choice([-1.0, 1.0], size=k)
        return np.asarray(self.c + (U * self.h) @ self.R.T)


class Hull:
    """The convex hull of random points, ``A x <= b`` from qhull's facet equations."""

    def __init__(self, rng: np.random.Generator, n: int) -> None:
        self.n = n
        pts = rng.normal(size=(n + 8, n)) * rng.uniform(0.5, 2.0, size=n) + rng.normal(size=n)
        hull = ConvexHull(pts)
        self.V = pts[hull.vertices]
        self.simplices = pts[hull.simplices]  # (facets, n, n)
        scale = rng.uniform(0.5, 3.0, size=len(hull.equations))
        self.A = hull.equations[:, :-1] * scale[:, None]
        self.b = -hull.equations[:, -1] * scale

    def sample_inside(self, rng: np.random.Generator, k: int) -> FloatArray:
        W = rng.dirichlet(np.ones(len(self.V)), size=k)
        return np.asarray(W @ self.V)

    def sample_surface(self, rng: np.random.Generator, k: int) -> FloatArray:
        f = rng.integers(0, len(self.simplices), size=k)
        W = rng.dirichlet(np.ones(self.n), size=k)
        return np.asarray(np.einsum("kj,kjn->kn", W, self.simplices[f]))


def _ray_radius(A: FloatArray, b: FloatArray, x: FloatArray, U: FloatArray) -> float:
    """Brute force: the largest r with ``x + r u`` inside for every sampled direction ``u``
    (an upper bound on the exact inner radius)."""
    slack = b - A @ x
    rate = U @ A.T  # (K, m)
    with np.errstate(divide="ignore"):
        t = np.where(rate > 0, slack / rate, np.inf)
    return float(t.min())


def _cvx_projection(A: FloatArray, b: FloatArray) -> tuple[cp.Problem, cp.Parameter, cp.Variable]:
    y = cp.Variable(A.shape[1])
    p = cp.Parameter(A.shape[1])
    prob = cp.Problem(cp.Minimize(cp.sum_squares(y - p)), [A @ y <= b])
    return prob, p, y


def _inside(A: FloatArray, b: FloatArray, Y: FloatArray) -> npt.NDArray[np.bool_]:
    return np.asarray(np.all(Y @ A.T <= b, axis=1))


# --------------------------------------------------------------------------------------------
# 1. polytopes
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n", DIMS)
def test_rotated_box_polytope_matches_closed_form(n: int) -> None:
    """A rotated box given as unnormalised, redundant rows: inside and outside distances equal
    the closed form in the box's own coordinates to 1e-12."""
    rng = np.random.default_rng(100 + n)
    for _ in range(3):
        box = RotatedBox(rng, n)
        inner = box.sample_inside(rng, 40)
        outer = box.c + _unit(rng, 40, n) * rng.uniform(1.01, 4.0, (40, 1)) * np.linalg.norm(box.h)
        X = np.vstack([inner, outer, box.sample_surface(rng, 5)])
        sd = geo.polytope_signed_distance(box.A, box.b, X)
        np.testing.assert_allclose(sd, box.exact(X), rtol=1e-12, atol=1e-12)
        assert np.all(sd[:40] < 0) and np.all(sd[40:80] > 0)
        np.testing.assert_allclose(sd[80:], 0.0, atol=1e-12)


@pytest.mark.parametrize("n", DIMS)
@pytest.mark.parametrize("kind", ["box", "hull"])
def test_polytope_inside_radius_brute_force(n: int, kind: str) -> None:
    """-sd is at most the sampled-direction radius, the ball of 0.999 (-sd) is inside and the
    point at 1.001 (-sd) towards the nearest face is outside."""
    rng = np.random.default_rng(200 + n + (50 if kind == "hull" else 0))
    shape = RotatedBox(rng, n) if kind == "box" else Hull(rng, n)
    X = shape.sample_inside(rng, 12)
    sd = geo.polytope_signed_distance(shape.A, shape.b, X)
    assert np.all(sd < 0)
    U = _unit(rng, 12_000, n)
    norms = np.linalg.norm(shape.A, axis=1)
    for x, d in zip(X, sd, strict=True):
        r = -d
        bf = _ray_radius(shape.A, shape.b, x, U)
        assert r <= bf * (1 + 1e-12)
        if n == 2:  # dense directions: the brute force is tight in the plane
            assert bf <= r * (1 + 1e-4)
        assert _inside(shape.A, shape.b, x + 0.999 * r * U[:2000]).all()
        face = int(np.argmin((shape.b - shape.A @ x) / norms))
        normal = shape.A[face] / norms[face]
        assert not _inside(shape.A, shape.b, (x + 1.001 * r * normal)[None, :])[0]
        on_face = shape.A[face] @ (x + r * normal) - shape.b[face]
        assert abs(on_face) <= 1e-12 * (norms[face] + abs(shape.b[face]))


@pytest.mark.parametrize("n", DIMS)
@pytest.mark.parametrize("kind", ["box", "hull"])
def test_polytope_outside_distance_brute_force_and_cvxpy(n: int, kind: str) -> None:
    """Outside: sd <= the minimum over sampled boundary points, the projection is feasible and
    at distance sd, and Clarabel's projection agrees to 1e-6."""
    rng = np.random.default_rng(300 + n + (50 if kind == "hull" else 0))
    shape = RotatedBox(rng, n) if kind == "box" else Hull(rng, n)
    centre = shape.sample_inside(rng, 1)[0]
    X = centre + _unit(rng, 40, n) * rng.uniform(0.3, 6.0, size=(40, 1))
    X = X[~_inside(shape.A, shape.b, X)][:8]
    assert len(X) == 8
    sd = geo.polytope_signed_distance(shape.A, shape.b, X)
    assert np.all(sd > 0)
    S = shape.sample_surface(rng, 40_000)
    prob, p, y = _cvx_projection(shape.A, shape.b)
    _, _, An, bn = geo._polytope(shape.A, shape.b)
    for x, d in zip(X, sd, strict=True):
        bf = float(np.linalg.norm(S - x, axis=1).min())
        assert d <= bf + 1e-12
        if n == 2:
            assert bf <= d + 1e-3
        proj, dist = geo._polytope_projection(An, bn, x)
        assert dist == d
        assert np.all(shape.A @ proj <= shape.b + 1e-9 * np.linalg.norm(shape.A, axis=1))
        assert np.linalg.norm(x - proj) == pytest.approx(d, rel=1e-14)
        p.value = x
        prob.solve(solver=cp.CLARABEL)
        assert prob.status == cp.OPTIMAL
        assert float(np.linalg.norm(np.asarray(y.value) - x)) == pytest.approx(d, abs=1e-6)


def test_polytope_unbounded_and_degenerate_rows() -> None:
    """An unbounded wedge with a zero row (ignored), a duplicated row and a narrow apex."""
    eps = 1e-3
    A = np.array([[-eps, 1.0], [-eps, -1.0], [0.0, 0.0], [-2 * eps, 2.0]])
    b = np.array([0.0, 0.0, 1.0, 0.0])  # the wedge |x2| <= eps x1, apex at the origin
    X = np.array([[-1.0, 0.0], [-3.0, 4.0], [10.0, 0.0], [10.0, 1.0]])
    sd = geo.polytope_signed_distance(A, b, X)
    assert sd[0] == pytest.approx(1.0, rel=1e-12)
    assert sd[1] == pytest.approx(5.0, rel=1e-12)
    assert sd[2] == pytest.approx(-10 * eps / np.hypot(eps, 1.0), rel=1e-12)
    # (10, 1) is outside above the upper face x2 = eps x1: distance to that line.
    assert sd[3] == pytest.approx((1.0 - 10 * eps) / np.hypot(eps, 1.0), rel=1e-12)
    # No constraints at all: R^n, every state infinitely deep inside.
    assert np.all(geo.polytope_signed_distance(np.zeros((1, 2)), [0.0], X) == -np.inf)


def test_polytope_sign_agrees_with_membership() -> None:
    """sd < 0 only for states with A x <= b, sd > 0 only for states outside, including states
    on and within rounding of the faces."""
    rng = np.random.default_rng(7)
    box = RotatedBox(rng, 3)
    S = box.sample_surface(rng, 200)
    X = np.vstack([S, S + 1e-15 * rng.normal(size=S.shape), box.sample_inside(rng, 50)])
    sd = geo.polytope_signed_distance(box.A, box.b, X)
    inside = _inside(box.A, box.b, X)
    assert not np.any((sd < 0) & ~inside)
    assert not np.any((sd > 0) & inside)
    assert np.all(np.abs(sd[:400]) <= 1e-13)


# --------------------------------------------------------------------------------------------
# The projection is never returned unverified
# --------------------------------------------------------------------------------------------


def _square() -> tuple[FloatArray, FloatArray]:
    return (np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]),
            np.array([1.0, 1.0, 1.0, 1.0]))


def test_projection_falls_back_when_nnls_fails(monkeypatch: pytest.MonkeyPatch) -> None:
    A, b = _square()
    monkeypatch.setattr(geo, "_ldp_candidate", lambda An, bn, x: None)
    sd = geo.polytope_signed_distance(A, b, [[3.0, 4.0], [0.0, 2.5]])
    np.testing.assert_allclose(sd, [np.hypot(2.0, 3.0), 1.5], rtol=1e-12)


def test_projection_falls_back_to_trust_constr(monkeypatch: pytest.MonkeyPatch) -> None:
    A, b = _square()
    monkeypatch.setattr(geo, "_ldp_candidate", lambda An, bn, x: None)
    monkeypatch.setattr(geo, "_slsqp_candidate", lambda An, bn, x: None)
    sd = geo.polytope_signed_distance(A, b, [[3.0, 4.0], [0.0, 2.5]])
    np.testing.assert_allclose(sd, [np.hypot(2.0, 3.0), 1.5], rtol=1e-12)


def test_wrong_candidates_are_rejected(monkeypatch: pytest.MonkeyPatch) -> None:
    """Feasible but non-optimal points (a far vertex) fail the KKT check: ValueError, never a
    number."""
    A, b = _square()
    far = lambda An, bn, x: np.array([-1.0, -1.0])  # noqa: E731
    for name in ("_ldp_candidate", "_slsqp_candidate", "_trust_constr_candidate"):
        monkeypatch.setattr(geo, name, far)
    monkeypatch.setattr(geo, "_polished", lambda An, bn, x, y0: [])
    with pytest.raises(ValueError, match="KKT"):
        geo.polytope_signed_distance(A, b, [[3.0, 4.0]])
    # Inside states need no solver and still work.
    assert geo.polytope_signed_distance(A, b, [[0.5, 0.0]])[0] == pytest.approx(-0.5)


def test_kkt_check_rejects_a_non_projection() -> None:
    A, b = _square()
    x = np.array([3.0, 4.0])
    assert geo._kkt_ok(A, b, x, np.array([1.0, 1.0]))
    assert not geo._kkt_ok(A, b, x, np.array([1.0, 0.9]))  # feasible, not stationary
    assert not geo._kkt_ok(A, b, x, np.array([1.2, 1.0]))  # infeasible


# --------------------------------------------------------------------------------------------
# polytope bounds
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [2, 4, 6])
def test_polytope_bounds(n: int) -> None:
    rng = np.random.default_rng(400 + n)
    box = RotatedBox(rng, n)
    lo, hi = geo.polytope_bounds(box.A, box.b)
    half = np.abs(box.R) @ box.h
    np.testing.assert_allclose(lo, box.c - half, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(hi, box.c + half, rtol=1e-12, atol=1e-12)
    hull = Hull(rng, n)
    lo, hi = geo.polytope_bounds(hull.A, hull.b)
    np.testing.assert_allclose(lo, hull.V.min(axis=0), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(hi, hull.V.max(axis=0), rtol=1e-9, atol=1e-9)


def test_polytope_bounds_unbounded_and_empty() -> None:
    lo, hi = geo.polytope_bounds([[0.0, 1.0], [1.0, 1.0]], [-4.0, 2.0])
    assert lo.tolist() == [-np.inf, -np.inf] and hi.tolist() == [np.inf, -4.0]
    lo, hi = geo.polytope_bounds(np.zeros((0, 3)), np.zeros(0))
    assert np.all(lo == -np.inf) and np.all(hi == np.inf)
    with pytest.raises(ValueError, match="empty"):
        geo.polytope_bounds([[1.0], [-1.0]], [-1.0, -1.0])
    with pytest.raises(ValueError, match="empty"):
        geo.polytope_signed_distance([[1.0], [-1.0]], [-1.0, -1.0], [[0.0]])


# --------------------------------------------------------------------------------------------
# 2. ellipsoids and balls
# --------------------------------------------------------------------------------------------


def _random_ellipsoid(rng: np.random.Generator, n: int) -> tuple[FloatArray, FloatArray,
                                                                  FloatArray, FloatArray]:
    """Centre, M, rotation R and semi-axes a (ratio exactly 20 between the extremes)."""
    a = np.exp(rng.uniform(np.log(0.25), np.log(5.0), size=n))
    a[0], a[-1] = 0.25, 5.0
    a = rng.permutation(a)
    R = _rotation(rng, n)
    M = R @ np.diag(1.0 / a**2) @ R.T
    return rng.uniform(-3.0, 3.0, size=n), 0.5 * (M + M.T), R, a


def _surface_2d(c: FloatArray, R: FloatArray, a: FloatArray, theta: FloatArray) -> FloatArray:
    return np.asarray(c + (np.column_stack([np.cos(theta), np.sin(theta)]) * a) @ R.T)


def _ellipse_gap(t: float, c: FloatArray, R: FloatArray, a: FloatArray, x: FloatArray) -> float:
    return float(np.linalg.norm(_surface_2d(c, R, a, np.array([t]))[0] - x))


def _refined_distance(c: FloatArray, R: FloatArray, a: FloatArray, x: FloatArray,
                      starts: FloatArray) -> float:
    """Independent local minimisation of |c + R (a * u/|u|) - x| from sampled directions."""
    def f(u: FloatArray) -> tuple[float, FloatArray]:
        nu = np.linalg.norm(u)
        w = u / nu
        gap = c + R @ (a * w) - x
        dw = 2.0 * a * (R.T @ gap)
        return float(gap @ gap), (dw - w * (w @ dw)) / nu
    best = np.inf
    for u0 in starts:
        res = minimize(f, u0, jac=True, method="BFGS", options={"gtol": 1e-14, "maxiter": 2000})
        best = min(best, float(res.fun))
    return float(np.sqrt(best))


def test_ellipse_2d_dense_parametrisation() -> None:
    """2-D: 200 000 surface angles, refined by bounded scalar minimisation, agree to 1e-12."""
    rng = np.random.default_rng(500)
    theta = np.linspace(0.0, 2 * np.pi, 200_000, endpoint=False)
    for _ in range(3):
        c, M, R, a = _random_ellipsoid(rng, 2)
        X = c + rng.uniform(-1.2, 1.2, size=(16, 2)) * a @ R.T
        sd = geo.ellipsoid_signed_distance(c, M, X)
        S = _surface_2d(c, R, a, theta)
        g = np.einsum("ij,jk,ik->i", X - c, M, X - c)
        assert np.all((sd < 0) == (g < 1))
        for x, d in zip(X, sd, strict=True):
            dd = np.linalg.norm(S - x, axis=1)
            k = int(np.argmin(dd))
            assert abs(d) <= dd[k] + 1e-12
            step = theta[1] - theta[0]
            res = minimize_scalar(_ellipse_gap, args=(c, R, a, x),
                                  bounds=(theta[k] - step, theta[k] + step), method="bounded",
                                  options={"xatol": 1e-13})
            assert abs(d) == pytest.approx(min(float(res.fun), dd[k]), rel=1e-11, abs=1e-12)


@pytest.mark.parametrize("n", DIMS)
def test_ellipsoid_brute_force_and_cvxpy(n: int) -> None:
    """Inside and outside states: |sd| <= the minimum over sampled surface points (an upper
    bound), equals independent BFGS refinement from the best samples to 1e-9, and outside
    equals Clarabel's projection onto the ellipsoid to 1e-6."""
    rng = np.random.default_rng(600 + n)
    c, M, R, a = _random_ellipsoid(rng, n)
    X = c + _unit(rng, 8, n) * rng.uniform(0.05, 1.6, size=(8, 1)) * a.max() @ R.T
    X = np.vstack([X, c + (rng.uniform(-0.9, 0.9, size=(4, n)) * a / np.sqrt(n)) @ R.T])
    sd = geo.ellipsoid_signed_distance(c, M, X)
    g = np.einsum("ij,jk,ik->i", X - c, M, X - c)
    assert np.all((sd < 0) == (g < 1)) and np.all((sd > 0) == (g > 1))
    Umany = rng.normal(size=(40_000, n))
    S = c + (a * Umany / np.linalg.norm(Umany, axis=1, keepdims=True)) @ R.T
    y = cp.Variable(n)
    p = cp.Parameter(n)
    L = np.diag(1.0 / a) @ R.T  # |L (y - c)| <= 1 is the ellipsoid
    prob = cp.Problem(cp.Minimize(cp.sum_squares(y - p)), [cp.norm(L @ (y - c)) <= 1])
    for x, d in zip(X, sd, strict=True):
        dd = np.linalg.norm(S - x, axis=1)
        assert abs(d) <= dd.min() + 1e-12
        starts = Umany[np.argsort(dd)[:4]]
        ref = _refined_distance(c, R, a, x, starts)
        assert abs(d) == pytest.approx(ref, rel=1e-9, abs=1e-10)
        if d > 0:
            p.value = x
            prob.solve(solver=cp.CLARABEL)
            assert prob.status == cp.OPTIMAL
            assert float(np.linalg.norm(np.asarray(y.value) - x)) == pytest.approx(d, abs=1e-6)


@pytest.mark.parametrize("n", [1, *DIMS])
def test_sphere_equals_ball(n: int) -> None:
    """M = I / r^2 (and a rotated copy with roundoff-split eigenvalues) agrees with the ball
    formula to 1e-12, at the centre, on the surface and inside and out."""
    rng = np.random.default_rng(700 + n)
    r = 1.7
    c = rng.normal(size=n)
    X = np.vstack([c, c + 1e-12, c + _unit(rng, 30, n) * rng.uniform(0, 3, size=(30, 1)),
                   c + r * _unit(rng, 5, n)])
    ball = geo.ball_signed_distance(c, r, X)
    Q = _rotation(rng, n)
    for M in (np.eye(n) / r**2, Q @ (np.eye(n) / r**2) @ Q.T):
        np.testing.assert_allclose(geo.ellipsoid_signed_distance(c, M, X), ball,
                                   rtol=0, atol=1e-12)
    assert ball[0] == -r


@pytest.mark.parametrize("rotated", [False, True])
def test_ellipse_principal_axes_closed_forms(rotated: bool) -> None:
    """On the axes of x^2/a^2 + y^2/b^2 <= 1 (a = 2 > b = 1): the centre (-b), the major axis
    near the centre (root at the pole: -b sqrt(1 - x0^2/(a^2 - b^2))), the major axis beyond
    the evolute's cusp (a - |x0|), the minor axis (b - |y0|) and outside the vertices."""
    a, b = 2.0, 1.0
    R = _rotation(np.random.default_rng(8), 2) if rotated else np.eye(2)
    c = np.array([0.3, -0.7]) if rotated else np.zeros(2)
    M = R @ np.diag([1 / a**2, 1 / b**2]) @ R.T
    cusp = (a * a - b * b) / a
    local = np.array([[0, 0], [0.5, 0], [-1.0, 0], [cusp, 0], [1.6, 0], [-1.9, 0], [0, 0.4],
                      [0, -0.99], [3.0, 0], [0, -2.5]], dtype=np.float64)
    expected = np.array([
        -b, -b * np.sqrt(1 - 0.25 / (a * a - b * b)), -b * np.sqrt(1 - 1.0 / (a * a - b * b)),
        -(a - cusp), -(a - 1.6), -(a - 1.9), -(b - 0.4), -(b - 0.99), 3.0 - a, 2.5 - b])
    sd = geo.ellipsoid_signed_distance(c, M, c + local @ R.T)
    np.testing.assert_allclose(sd, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("n", [3, 5])
def test_ellipsoid_centre_and_axes(n: int) -> None:
    """The centre is at the shortest semi-axis; a point on axis i beyond its vertex is at
    t - a_i; a point on the shortest axis inside is at a_min - t."""
    rng = np.random.default_rng(900 + n)
    c, M, R, a = _random_ellipsoid(rng, n)
    i_min = int(np.argmin(a))
    X = [c]
    expected = [-a.min()]
    for i in range(n):
        X.append(c + 1.5 * a[i] * R[:, i])
        expected.append(0.5 * a[i])
    X.append(c - 0.6 * a[i_min] * R[:, i_min])
    expected.append(-0.4 * a[i_min])
    sd = geo.ellipsoid_signed_distance(c, M, np.array(X))
    np.testing.assert_allclose(sd, expected, rtol=1e-12, atol=1e-12)


def test_ellipsoid_bounds() -> None:
    rng = np.random.default_rng(11)
    for n in (1, 2, 4, 6):
        c, M, R, a = _random_ellipsoid(rng, n)
        lo, hi = geo.ellipsoid_bounds(c, M)
        half = np.sqrt((R * R) @ (a * a))
        np.testing.assert_allclose(lo, c - half, rtol=1e-12)
        np.testing.assert_allclose(hi, c + half, rtol=1e-12)
        U = _unit(rng, 20_000, n)
        S = c + (a * U) @ R.T
        assert np.all(S >= lo - 1e-12) and np.all(S <= hi + 1e-12)


def test_ball_signed_distance() -> None:
    sd = geo.ball_signed_distance([1.0, 1.0], 2.0, [[1.0, 1.0], [4.0, 5.0], [3.0, 1.0]])
    assert sd.tolist() == [-2.0, 3.0, 0.0]
    assert geo.ball_signed_distance([0.0], 0.0, [[0.0], [-2.0]]).tolist() == [0.0, 2.0]


# --------------------------------------------------------------------------------------------
# 3. boxes
# --------------------------------------------------------------------------------------------


def test_box_infinite_sides() -> None:
    inf = np.inf
    # The half-space x2 <= -4.
    sd = geo.box_signed_distance([-inf, -inf], [inf, -4.0], [[0, 0], [7, -4], [3, -10]])
    assert sd.tolist() == [4.0, 0.0, -6.0]
    # A quarter plane x1 >= 1, x2 <= 2: outside the corner the distance is Euclidean.
    sd = geo.box_signed_distance([1.0, -inf], [inf, 2.0], [[-2, 6], [5, 0], [1.5, 1.0]])
    np.testing.assert_allclose(sd, [5.0, -2.0, -0.5], rtol=1e-15)
    # No finite side: R^n.
    assert geo.box_signed_distance([-inf] * 3, [inf] * 3, np.zeros((2, 3))).tolist() == [-inf] * 2
    assert geo.box_signed_distance([0.0], [1.0], np.zeros((0, 1))).shape == (0,)


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_box_equals_polytope(n: int) -> None:
    """A box and the polytope with rows +/- e_i (finite sides only) give the same signed
    distances, inside, outside and on the boundary; their bounds agree."""
    rng = np.random.default_rng(1000 + n)
    lower = rng.uniform(-3, 0, size=n)
    upper = lower + rng.uniform(0.2, 3, size=n)
    lower[0] = -np.inf if n > 1 else lower[0]
    eye = np.eye(n)
    X = rng.uniform(-6, 6, size=(80, n))
    X[:20] = np.clip(X[:20], np.where(np.isinf(lower), -5.0, lower), upper)
    for lo_, hi_ in ((lower, upper), (np.where(np.isinf(lower), -5.0, lower), upper)):
        keep_lo = np.isfinite(lo_)
        A = np.vstack([eye, -eye[keep_lo]])
        b = np.concatenate([hi_, -lo_[keep_lo]])
        box = geo.box_signed_distance(lo_, hi_, X)
        poly = geo.polytope_signed_distance(A, b, X)
        np.testing.assert_allclose(poly, box, rtol=1e-12, atol=1e-12)
        assert np.all(box[:20] <= 0)
        plo, phi = geo.polytope_bounds(A, b)
        np.testing.assert_allclose(plo, lo_, rtol=1e-12)
        np.testing.assert_allclose(phi, hi_, rtol=1e-12)


# --------------------------------------------------------------------------------------------
# 4. the diagonal-face regression
# --------------------------------------------------------------------------------------------


def test_diagonal_face_regression() -> None:
    """The square [-0.9, 0.9]^2 with its corner cut by x1 + x2 <= 1: from the origin every axis
    ray leaves through a side at 0.900, but the cut is at 1/sqrt(2) = 0.707."""
    A = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0], [1.0, 1.0]])
    b = np.array([0.9, 0.9, 0.9, 0.9, 1.0])
    axes = np.vstack([np.eye(2), -np.eye(2)])
    assert _ray_radius(A, b, np.zeros(2), axes) == pytest.approx(0.9)  # the old, wrong answer
    sd = geo.polytope_signed_distance(A, b, [[0.0, 0.0]])
    assert -sd[0] == pytest.approx(1 / np.sqrt(2), rel=1e-15)
    assert not _inside(A, b, np.array([[0.5, 0.5]]) * 1.001)[0]


# --------------------------------------------------------------------------------------------
# 5. validation
# --------------------------------------------------------------------------------------------


NAN = float("nan")
BAD_CALLS = [
    ("X", lambda: geo.box_signed_distance([0, 0], [1, 1], [[0, 0, 0]])),
    ("X", lambda: geo.box_signed_distance([0, 0], [1, 1], [0, 0])),
    ("X", lambda: geo.box_signed_distance([0, 0], [1, 1], [[NAN, 0]])),
    ("X", lambda: geo.box_signed_distance([0, 0], [1, 1], [[np.inf, 0]])),
    ("upper", lambda: geo.box_signed_distance([0, 0], [1, 1, 1], [[0, 0]])),
    ("lower", lambda: geo.box_signed_distance([NAN, 0], [1, 1], [[0, 0]])),
    ("lower", lambda: geo.box_signed_distance([2, 0], [1, 1], [[0, 0]])),
    ("empty", lambda: geo.box_signed_distance([np.inf], [np.inf], [[0]])),
    ("lower", lambda: geo.box_signed_distance([], [], np.zeros((1, 0)))),
    ("b", lambda: geo.polytope_signed_distance([[1, 0]], [1, 2], [[0, 0]])),
    ("A", lambda: geo.polytope_signed_distance([1, 0], [1], [[0, 0]])),
    ("A", lambda: geo.polytope_signed_distance([[NAN, 0]], [1], [[0, 0]])),
    ("b", lambda: geo.polytope_signed_distance([[1, 0]], [np.inf], [[0, 0]])),
    ("X", lambda: geo.polytope_signed_distance([[1, 0]], [1], [[0, 0, 0]])),
    ("X", lambda: geo.polytope_signed_distance([[1, 0]], [1], [[0, NAN]])),
    ("empty", lambda: geo.polytope_signed_distance([[0, 0]], [-1], [[0, 0]])),
    ("A", lambda: geo.polytope_bounds([[[1.0]]], [1])),
    ("radius", lambda: geo.ball_signed_distance([0, 0], -1.0, [[0, 0]])),
    ("radius", lambda: geo.ball_signed_distance([0, 0], NAN, [[0, 0]])),
    ("radius", lambda: geo.ball_signed_distance([0, 0], [1.0, 2.0], [[0, 0]])),
    ("center", lambda: geo.ball_signed_distance([0, NAN], 1.0, [[0, 0]])),
    ("X", lambda: geo.ball_signed_distance([0, 0], 1.0, [[0, 0, 1]])),
    ("M", lambda: geo.ellipsoid_signed_distance([0, 0], np.eye(3), [[0, 0]])),
    ("M", lambda: geo.ellipsoid_signed_distance([0, 0], [[1, 0.5], [0, 1]], [[0, 0]])),
    ("M", lambda: geo.ellipsoid_signed_distance([0, 0], [[1, 0], [0, -1]], [[0, 0]])),
    ("M", lambda: geo.ellipsoid_signed_distance([0, 0], [[1, 0], [0, 0]], [[0, 0]])),
    ("M", lambda: geo.ellipsoid_signed_distance([0, 0], [[1, 0], [0, NAN]], [[0, 0]])),
    ("X", lambda: geo.ellipsoid_signed_distance([0, 0], np.eye(2), [[NAN, 0]])),
    ("center", lambda: geo.ellipsoid_bounds([[0, 0]], np.eye(2))),
    ("M", lambda: geo.ellipsoid_bounds([0, 0], [[1, 2], [2, 1]])),
]


@pytest.mark.parametrize(("word", "call"), BAD_CALLS)
def test_validation_errors(word: str, call: object) -> None:
    assert callable(call)
    with pytest.raises(ValueError, match=word) as info:
        call()
    assert "\n" not in str(info.value)
