"""Modulation (paper eq. 7): vectorised closed form vs. literal E D E^-1, invariants, errors."""

from __future__ import annotations

import numpy as np
import pytest

from tli_verify.boundary.cuts import Cut
from tli_verify.boundary.modulation import (
    Modulator,
    gamma,
    modulate,
    modulate_reference,
    modulated,
    modulation_matrix,
)
from tli_verify.errors import ModelError


def _random_setup(n: int, rng: np.random.Generator, *, m: int = 5, degenerate: bool = True):
    x_star = rng.standard_normal(n)
    cuts = []
    for i in range(m):
        w = rng.standard_normal(n)
        w /= np.linalg.norm(w)
        h = 0.0 if (degenerate and i % 2 == 0) else rng.uniform(0.3, 2.0)
        t = rng.standard_normal(n)
        t -= (t @ w) * w
        cuts.append(Cut(normal=w, point=x_star + h * w + t))
    L = rng.standard_normal((n, n))
    P = L @ L.T + 0.5 * np.eye(n)
    return x_star, cuts, P


def _inside_near_faces(x_star: np.ndarray, cuts: list[Cut], rng: np.random.Generator,
                       count: int) -> np.ndarray:
    """States inside the cuts, a third of them next to a face, a third next to two (corners)."""
    n = x_star.size
    W = np.array([c.normal for c in cuts])
    b = np.array([c.normal @ c.point for c in cuts])
    out: list[np.ndarray] = []
    while len(out) < count:
        x = x_star + 2.0 * rng.standard_normal(n)
        k = int(rng.integers(0, 3))
        if k:
            rows = rng.choice(len(cuts), size=k, replace=False)
            A = W[rows]
            # onto those planes, then inwards by distinct tiny amounts: no exact ties of the
            # closest cut, where eq. 7 may legitimately pick either cut
            x = x - np.linalg.pinv(A) @ (A @ x - b[rows] + rng.uniform(1e-9, 1e-7, k))
        if np.all(W @ x <= b + 1e-12):
            out.append(x)
    return np.array(out)


@pytest.mark.parametrize("n", [2, 3, 4])
@pytest.mark.parametrize("degenerate", [False, True])
def test_vectorised_matches_literal_eq5(n: int, degenerate: bool) -> None:
    rng = np.random.default_rng(n + 10 * degenerate)
    x_star, cuts, P = _random_setup(n, rng, degenerate=degenerate)
    X = x_star + 2.0 * rng.standard_normal((600, n))
    F = rng.standard_normal((600, n))
    fast = Modulator.build(cuts, x_star, lyapunov=P).eq5(X, F)
    slow = modulate_reference(X, F, cuts, x_star, lyapunov=P, guard=False)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-9 * (1 + np.abs(slow).max()))
    assert np.any(np.any(fast != F, axis=1)), "the sample must exercise modulation"


@pytest.mark.parametrize("n", [2, 3, 4])
@pytest.mark.parametrize("certified", [False, True])
@pytest.mark.parametrize("dt", [None, 0.05])
def test_guard_matches_kkt_enumeration(n: int, certified: bool, dt: float | None) -> None:
    """The vectorised guard (NNLS) equals the per-point reference (KKT active sets)."""
    rng = np.random.default_rng(100 + n)
    x_star, cuts, P = _random_setup(n, rng, m=6)
    X = _inside_near_faces(x_star, cuts, rng, 300)
    X = np.vstack([X, x_star + 2.0 * rng.standard_normal((300, n))])
    # random velocities do not vanish at x* as a DS does: keep away from it
    X = X[np.linalg.norm(X - x_star, axis=1) > 1e-3]
    F = 3.0 * rng.standard_normal(X.shape)
    lyap = P if certified else None
    mod = Modulator.build(cuts, x_star, lyapunov=lyap)
    fast = mod(X, F, dt=dt)
    slow = modulate_reference(X, F, cuts, x_star, lyapunov=lyap, dt=dt)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-9 * (1 + np.abs(slow).max()))
    guarded = np.any(np.abs(fast - mod.eq5(X, F)) > 1e-12, axis=1)
    assert guarded.sum() >= 5, "the sample must exercise the guard"


def test_guard_is_the_projection_cvxpy() -> None:
    """Where the guard acts, its answer is the P-metric projection of eq. 7 on C(x): an
    independent solver (cvxpy with Clarabel) finds the same point."""
    import cvxpy as cp

    rng = np.random.default_rng(5)
    x_star, cuts, P = _random_setup(3, rng, m=6)
    X = _inside_near_faces(x_star, cuts, rng, 200)
    F = 3.0 * rng.standard_normal(X.shape)
    mod = Modulator.build(cuts, x_star, lyapunov=P)
    out, ref = mod(X, F, dt=0.05), mod.eq5(X, F)
    bound, grad, v_bound, _, _ = mod.admissible(X, F, dt=0.05)
    idx = np.flatnonzero(np.any(np.abs(out - ref) > 1e-12, axis=1))[:8]
    assert idx.size >= 3
    L = np.linalg.cholesky(P)
    for i in idx.tolist():
        v = cp.Variable(3)
        prob = cp.Problem(cp.Minimize(cp.sum_squares(L.T @ (v - ref[i]))),
                          [mod.W @ v <= bound[i], grad[i] @ v <= v_bound[i]])
        prob.solve(solver=cp.CLARABEL)
        assert prob.status == "optimal"
        ours = float(np.sum((L.T @ (out[i] - ref[i])) ** 2))
        assert np.all(mod.W @ out[i] <= bound[i] + 1e-9)
        assert grad[i] @ out[i] <= v_bound[i] + 1e-9 * (1 + abs(v_bound[i]))
        # feasible and no worse than Clarabel: the QP is strictly convex, so this is its optimum
        assert ours <= prob.value * (1 + 1e-7) + 1e-9
        assert np.linalg.norm(out[i] - v.value) <= 1e-3 * (1 + np.abs(v.value).max())


def test_eq5_eigenstructure() -> None:
    """M has eigenvalue 1 - Gamma along r = (x - x*)/|x - x*| and 1 along the cut's tangent."""
    x_star = np.array([0.0, 0.0])
    cut = Cut(normal=[1.0, 0.0], point=[2.0, 0.0])
    x = np.array([1.5, 0.5])
    E, M, g, a = modulation_matrix(x, [cut], x_star)
    assert a == 0 and g == pytest.approx(0.75)
    r = x / np.linalg.norm(x)
    np.testing.assert_allclose(E[:, 0], r)
    np.testing.assert_allclose(M @ r, (1 - g) * r, atol=1e-12)
    np.testing.assert_allclose(M @ np.array([0.0, 1.0]), [0.0, 1.0], atol=1e-12)


def test_gamma_values() -> None:
    x_star = np.zeros(2)
    cuts = [Cut([1.0, 0.0], [2.0, 0.0]), Cut([0.0, 1.0], [0.0, 1.0])]
    X = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 0.5], [3.0, 0.0], [-5.0, -5.0]])
    np.testing.assert_allclose(gamma(X, cuts, x_star), [0.0, 1.0, 0.5, 1.5, 0.0])
    deg = [Cut([0.0, 1.0], [5.0, 0.0])]  # the plane y = 0 holds x*
    G = gamma(np.array([[1.0, 0.0], [1.0, -1.0], [0.0, -1.0], [1.0, 1.0]]), deg, x_star)
    np.testing.assert_allclose(G, [1.0, 0.5, 0.0, 1.5])
    assert Modulator.build(deg, x_star).degenerate.tolist() == [True]


def test_invariance_and_lyapunov_pointwise() -> None:
    """On a cut's plane the normal component vanishes; dV/dt never increases."""
    rng = np.random.default_rng(7)
    for n in (2, 3, 4):
        x_star, cuts, P = _random_setup(n, rng)
        mod = Modulator.build(cuts, x_star, lyapunov=P)
        for i, c in enumerate(cuts):
            t = rng.standard_normal((400, n))
            t -= np.outer(t @ c.normal, c.normal)
            X = c.point + t
            G = mod._gammas(X - x_star)[0]
            others = np.delete(G, i, axis=1)
            face = np.all(others < 1 - 1e-6, axis=1)
            if not face.any():
                continue
            X = X[face]
            F = rng.standard_normal(X.shape)
            out = mod(X, F)
            assert np.all(out @ c.normal <= 1e-9 * (1 + np.linalg.norm(F, axis=1)))
        X = x_star + 2 * rng.standard_normal((1000, n))
        F = rng.standard_normal((1000, n))
        D = X - x_star
        dv_nom = np.einsum("ni,ij,nj->n", D, P, F)
        dv_mod = np.einsum("ni,ij,nj->n", D, P, mod(X, F))
        assert np.all(dv_mod <= dv_nom + 1e-9 * (1 + np.abs(dv_nom)))


def test_unmodulated_cases() -> None:
    x_star = np.zeros(2)
    cuts = [Cut([1.0, 0.0], [1.0, 0.0])]
    X = np.array([[0.5, 0.0], [2.0, 0.0], [0.0, 0.0], [-1.0, 0.0]])
    F = np.array([[-1.0, 0.3], [1.0, 0.0], [1.0, 1.0], [1.0, 0.0]])
    # inward flow, outside the cuts, at x*, behind x* (Gamma clipped at 0)
    np.testing.assert_array_equal(modulate(X, F, cuts, x_star), F)
    np.testing.assert_array_equal(modulate(X, F, [], x_star), F)
    out = modulate(np.array([[0.5, 0.5]]), np.array([[1.0, 0.0]]), cuts, x_star)
    np.testing.assert_allclose(out, [[0.5, -0.5]])  # f - (w.f / h)(x - x*)


def test_degenerate_cut_is_lyapunov_neutral() -> None:
    rng = np.random.default_rng(2)
    x_star = np.array([1.0, -2.0, 0.5])
    w = np.array([0.0, 0.0, 1.0])
    cut = Cut(normal=w, point=x_star + np.array([3.0, 1.0, 0.0]))
    L = rng.standard_normal((3, 3))
    P = L @ L.T + np.eye(3)
    X = x_star + rng.standard_normal((500, 3)) * np.array([1, 1, 0]) - np.array([0, 0, 1]) * \
        rng.uniform(0, 1, size=(500, 1))
    F = rng.standard_normal((500, 3))
    mod = Modulator.build([cut], x_star, lyapunov=P)
    D = X - x_star
    dv_nom = np.einsum("ni,ij,nj->n", D, P, F)
    np.testing.assert_allclose(np.einsum("ni,ij,nj->n", D, P, mod.eq5(X, F)), dv_nom,
                               atol=1e-9)  # eq. 7's correction for a cut through x*
    dv_guarded = np.einsum("ni,ij,nj->n", D, P, mod(X, F))
    assert np.all(dv_guarded <= dv_nom + 1e-9)  # the guard can only slow V down further
    on_plane = X.copy()
    on_plane[:, 2] = x_star[2]
    out = modulate(on_plane, F, [cut], x_star, lyapunov=P)
    assert np.all(out @ w <= 1e-12)


def test_errors() -> None:
    x_star = np.zeros(2)
    with pytest.raises(ModelError, match="leaves the attractor outside"):
        Modulator.build([Cut([1.0, 0.0], [-1.0, 0.0])], x_star)
    with pytest.raises(ModelError, match="positive definite"):
        Modulator.build([], x_star, lyapunov=-np.eye(2))
    with pytest.raises(ModelError, match="symmetric"):
        Modulator.build([], x_star, lyapunov=np.array([[1.0, 1.0], [0.0, 1.0]]))
    with pytest.raises(ModelError, match="dimension"):
        Modulator.build([Cut([1.0, 0.0, 0.0], [1.0, 0.0, 0.0])], x_star)
    with pytest.raises(ModelError, match="shape"):
        modulate(np.zeros((3, 3)), np.zeros((3, 3)), [], x_star)
    with pytest.raises(ModelError, match="rows"):
        modulate(np.zeros((3, 2)), np.zeros((2, 2)), [], x_star)
    with pytest.raises(ModelError):
        modulated(42, [], x_star)  # type: ignore[arg-type]


class _LinearDS:
    def __init__(self, A: np.ndarray, x_star: np.ndarray, P: np.ndarray) -> None:
        self.A, self.x_star, self.P = A, x_star, P

    def velocity(self, X: np.ndarray) -> np.ndarray:
        return (np.asarray(X) - self.x_star) @ self.A.T


def test_modulated_wrapper_uses_policy_lyapunov() -> None:
    x_star = np.zeros(2)
    P = np.array([[2.0, 0.3], [0.3, 1.0]])
    ds = _LinearDS(np.array([[-1.0, 2.0], [-2.0, -1.0]]), x_star, P)
    cuts = [Cut([0.0, 1.0], [3.0, 0.0])]  # degenerate: uses P
    pol = modulated(ds, cuts, x_star)
    np.testing.assert_array_equal(pol.modulator.P, P)
    X = np.array([[1.0, -0.1], [2.0, -1.0]])
    np.testing.assert_allclose(pol(X), modulate(X, ds.velocity(X), cuts, x_star, lyapunov=P))
    fn = modulated(ds.velocity, cuts, x_star)  # a plain function: identity P
    np.testing.assert_array_equal(fn.modulator.P, np.eye(2))


def test_mixed_corner_eq5_leaves_guard_stays() -> None:
    """A cut through x* next to a regular cut: eq. 7 alone leaves, the guarded field does not.

    Minimal case found by hypothesis (tests/property/test_theorem1.py): P = I, x* = 0, cuts
    x <= 0.5 and y <= 0 (the latter holds x*). On each face eq. 7's velocity is tangent, but the
    field switches between the radial and the V-neutral correction across Gamma_x = Gamma_y and
    slides along that surface into the corner and out of the cuts. The corner guard keeps every
    Euler step inside (Thm. 1 for any cut set, docs/boundary.md) and the state still converges.
    """
    A = np.array([[-0.3, 0.0, -1.0], [0.0, -0.3, -1.0], [1.0, 1.0, -0.3]])
    x_star = np.zeros(3)
    cuts = [Cut([1.0, 0.0, 0.0], [0.5, 0.0, 0.0]), Cut([0.0, 1.0, 0.0], [0.0, 0.0, 0.0])]
    mod = Modulator.build(cuts, x_star, lyapunov=np.eye(3))
    X0 = np.array([[-1.0, -1.0, -1.0]]) * 2.999 / np.sqrt(3.0)
    assert mod.gamma(X0)[0] < 1.0
    dt = 2e-4
    X, worst = X0.copy(), 0.0
    for _ in range(20_000):
        X = X + dt * mod.eq5(X, X @ A.T)
        worst = max(worst, float(mod.gamma(X)[0]))
        if worst > 1.0 + 1e-3:
            break
    assert worst > 1.0 + 1e-3  # paper eq. 7 alone leaves the cuts here
    for step in (2e-4, 1e-2):
        X, worst = X0.copy(), 0.0
        for _ in range(round(8.0 / step)):
            X = X + step * mod(X, X @ A.T, dt=step)
            worst = max(worst, float(mod.gamma(X)[0]))
        assert worst <= 1.0 + 1e-12, f"dt={step}: the guarded field left the cuts"
        assert np.linalg.norm(X) < 0.05 * np.linalg.norm(X0)


def test_guard_is_scale_invariant() -> None:
    """Scaling P leaves the P-metric projection unchanged, and large velocities are projected
    as accurately as small ones (the least-distance program is scaled before NNLS)."""
    cuts = [Cut([1.0, 0.0], [1.0, 0.0]), Cut([0.0, 1.0], [0.0, 1.0])]
    P = np.array([[2.0, 0.5], [0.5, 1.0]])
    x = np.array([[0.95, 0.9]])
    for speed in (1.0, 1e3, 1e6):
        f = speed * np.array([[1.0, 2.0]])
        ref = modulate_reference(x, f, cuts, np.zeros(2), lyapunov=P)
        for scale in (1e-4, 1.0, 1e4):
            out = Modulator.build(cuts, np.zeros(2), lyapunov=scale * P)(x, f)
            np.testing.assert_allclose(out, ref, rtol=1e-9, atol=1e-9 * speed)
            assert np.abs(out - f).max() > 0.1 * speed  # the guard did act


def test_sampled_data_fast_flow_never_crosses() -> None:
    """One cut, a fast outward flow and long steps: every Euler step lands on or inside."""
    mod = Modulator.build([Cut([1.0, 0.0], [1.0, 0.0])], np.zeros(2))
    X = np.c_[np.linspace(-1.0, 0.99, 2000), np.zeros(2000)]
    F = np.tile([1e3, 1e2], (2000, 1))
    for _ in range(5):
        X = X + 0.01 * mod(X, F, dt=0.01)
        assert np.all(X[:, 0] <= 1.0 + 1e-12)


def test_policy_through_x_star_with_a_cut_through_x_star() -> None:
    """A policy that does not vanish at x* (BC-like, f = (0, 1)) crosses x* on the plane of a
    cut through x*: it must not leave, in continuous time nor with a control period."""
    mod = Modulator.build([Cut([0.0, 1.0], [3.0, 0.0])], np.zeros(2))
    for dt, steps in ((None, 20_000), (0.01, 200)):
        x = np.array([[0.0, -1.0]])
        step = 1e-4 if dt is None else dt
        for _ in range(steps):
            x = x + step * mod(x, np.array([[0.0, 1.0]]), dt=dt)
            assert x[0, 1] <= 1e-12, f"dt={dt}: left through the cut at {x}"


def test_sampled_data_caps_eq5_near_tiny_offsets() -> None:
    """A cut a hair off x* makes eq. 7's correction |f| |x - x*| / h; with dt it is capped, so
    one step cannot fling the state far past x*."""
    A = np.array([[-1.0, -1.0], [1.0, -1.0]])
    for h in (1e-6, 1e-3):
        mod = Modulator.build([Cut([0.0, 1.0], [0.0, h])], np.zeros(2), lyapunov=np.eye(2))
        x = np.array([[1.0, h / 2]])
        x1 = x + 0.01 * mod(x, x @ A.T, dt=0.01)
        assert np.linalg.norm(x1) <= np.linalg.norm(x) * 1.01
        assert x1[0, 1] <= h + 1e-15


def test_dt_validation() -> None:
    mod = Modulator.build([Cut([1.0, 0.0], [1.0, 0.0])], np.zeros(2))
    X, F = np.array([[0.5, 0.0]]), np.array([[1.0, 0.0]])
    np.testing.assert_allclose(mod(X, F, dt=np.float32(0.01)), mod(X, F, dt=0.01))
    for bad in (0.0, -1.0, float("nan"), True, "0.1"):
        with pytest.raises(ModelError, match="dt"):
            mod(X, F, dt=bad)  # type: ignore[arg-type]


@pytest.mark.parametrize("kappa", [0.5, 200.0])
def test_barrier_rate_matches_reference(kappa: float) -> None:
    rng = np.random.default_rng(11)
    x_star, cuts, P = _random_setup(3, rng, m=5)
    X = _inside_near_faces(x_star, cuts, rng, 300)
    X = X[np.linalg.norm(X - x_star, axis=1) > 1e-3]
    F = 3.0 * rng.standard_normal(X.shape)
    mod = Modulator.build(cuts, x_star, lyapunov=P, barrier_rate=kappa)
    fast = mod(X, F)
    slow = modulate_reference(X, F, cuts, x_star, lyapunov=P, barrier_rate=kappa)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-9 * (1 + np.abs(slow).max()))
    assert np.any(np.abs(fast - mod.eq5(X, F)) > 1e-9)


def test_bad_inputs_are_model_errors() -> None:
    cut = Cut([1.0, 0.0], [1.0, 0.0])
    mod = Modulator.build(iter([cut]), np.zeros(2))  # any iterable of cuts
    with pytest.raises(ModelError, match="X has a NaN"):
        mod(np.array([[np.nan, 0.0]]), np.zeros((1, 2)))
    with pytest.raises(ModelError, match="F has a NaN"):
        mod(np.zeros((1, 2)), np.array([[np.inf, 1.0]]))
    for bad in ("1", True, 0.0, -2.0, float("inf")):
        with pytest.raises(ModelError, match="barrier_rate"):
            Modulator.build([cut], np.zeros(2), barrier_rate=bad)  # type: ignore[arg-type]
