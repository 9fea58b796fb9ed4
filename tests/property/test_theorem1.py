"""Theorem 1 of the paper (Key Contribution 1) as hypothesis property tests.

Theorem 1 (paper Sec. 6, proof in appendix A). A nonlinear DS ``f(x) = sum_k gamma_k(x) A_k
(x - x*)`` with ``P = P^T > 0`` and ``A_k^T P + P A_k < 0`` for all k, modulated by cutting planes
as in Sec. 5.2 (eq. 7) with the reference point ``x^r = x*``, never penetrates the cuts and is
globally asymptotically stable at ``x*``.

The paper proves it for one cut with ``x*`` strictly inside. Our modulation is eq. 7 plus the
corner guard of :mod:`tli_verify.boundary.modulation` (the ``P``-metric projection of eq. 7's
velocity on the admissible set ``C(x)``), for which the theorem holds for *any* cut set that
keeps ``x*`` inside or on every plane, corners and cuts through ``x*`` included, in continuous
time and for explicit Euler with the control period passed to the guard. Checked over generated
certified LPV-DS (dimension 2-4, random ``P``, 1-3 components) and 1-4 random cuts, each
independently strictly off ``x*`` or through it:

(a) no integrated trajectory that starts inside the cuts ever crosses a cut (every Euler step
    ``x + dt v`` stays inside), more generally no trajectory crosses a cut it starts on the
    inner side of, and at every boundary point -- faces and corners where two planes meet --
    the modulated velocity does not point out through any plane it lies on;
(b) ``dV/dt`` of the modulated DS is at most that of the nominal DS at every sampled state;
(c) every trajectory reaches ``x*``: ``V(x(T)) <= V(x(0)) exp(-lambda T)`` with the rate
    ``lambda = 2 min_k lambda_min(Q_k) / lambda_max(P)`` that (b) guarantees, and
    ``V(x(T)) <= 1e-4 V(x(0))``.

Paper eq. 7 alone fails (a) where a cut through ``x*`` meets another cut (hypothesis found the
case kept in ``tests/unit/test_modulation.py::test_mixed_corner_eq5_leaves_guard_stays``); the
guard is what these tests exercise there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from tli_verify.boundary.cuts import Cut
from tli_verify.boundary.modulation import Modulator
from tli_verify.ds.lpvds import LPVDS


@dataclass(frozen=True)
class System:
    ds: LPVDS
    cuts: list[Cut]
    modulator: Modulator
    rate: float  # guaranteed exponential decay rate of V

    def velocity(self, X: np.ndarray) -> np.ndarray:
        return self.modulator(X, self.ds.velocity(X))


def _unit(v: np.ndarray, fallback: int) -> np.ndarray:
    nv = np.linalg.norm(v)
    if nv < 1e-3:
        v = np.zeros_like(v)
        v[fallback % v.size] = 1.0
        return v
    return v / nv


def _mat(n: int, lo: float, hi: float) -> st.SearchStrategy[np.ndarray]:
    return hnp.arrays(np.float64, (n, n), elements=st.floats(lo, hi, width=64))


def _vec(n: int, lo: float, hi: float) -> st.SearchStrategy[np.ndarray]:
    return hnp.arrays(np.float64, (n,), elements=st.floats(lo, hi, width=64))


@st.composite
def systems(draw: st.DrawFn) -> System:
    """A certified LPV-DS with 1-4 cuts, each strictly off x* or through it."""
    n = draw(st.integers(2, 4), label="n")
    K = draw(st.integers(1, 3), label="K")
    L = draw(_mat(n, -0.5, 0.5), label="L")
    P = L @ L.T + 0.5 * np.eye(n)
    P /= np.max(np.linalg.eigvalsh(P))
    x_star = draw(_vec(n, -2.0, 2.0), label="x_star")
    A, Q = [], []
    for k in range(K):
        S = draw(_mat(n, -1.0, 1.0), label=f"S{k}")
        R = draw(_mat(n, -0.5, 0.5), label=f"R{k}")
        Qk = R @ R.T + 0.3 * np.eye(n)
        A.append(np.linalg.solve(P, (S - S.T) - Qk))  # A^T P + P A = -2 Q_k < 0
        Q.append(Qk)
    means = np.array([x_star + draw(_vec(n, -2.0, 2.0), label=f"mu{k}") for k in range(K)])
    covs = []
    for k in range(K):
        C = draw(_mat(n, -0.7, 0.7), label=f"C{k}")
        covs.append(C @ C.T + 0.3 * np.eye(n))
    priors = np.array([draw(st.floats(0.2, 1.0), label=f"pi{k}") for k in range(K)])
    ds = LPVDS(attractor=x_star, priors=priors / priors.sum(), means=means,
               covs=np.array(covs), A=np.array(A), P=P)
    m = draw(st.integers(1, 4), label="m")
    cuts = []
    for i in range(m):
        w = _unit(draw(_vec(n, -1.0, 1.0), label=f"w{i}"), i)
        degenerate = draw(st.booleans(), label=f"degenerate{i}")
        h = 0.0 if degenerate else draw(st.floats(0.3, 2.0), label=f"h{i}")
        t = draw(_vec(n, -2.0, 2.0), label=f"t{i}")
        t = t - (t @ w) * w
        cuts.append(Cut(normal=w, point=x_star + h * w + t))
    rate = 2.0 * min(float(np.min(np.linalg.eigvalsh(q))) for q in Q)  # lambda_max(P) = 1
    return System(ds=ds, cuts=cuts, modulator=Modulator.build(cuts, x_star, lyapunov=P),
                  rate=rate)


def _starts(sys_: System, directions: np.ndarray) -> np.ndarray:
    """Points inside the cuts along rays from x*, some close to the boundary."""
    x_star = sys_.ds.attractor
    W = np.array([c.normal for c in sys_.cuts])
    h = sys_.modulator.h
    out = []
    for u in directions:
        u = _unit(u, 0)
        wu = W @ u
        if np.any(wu[sys_.modulator.degenerate] > -0.05):
            continue  # this ray runs along or out through a cut that holds x*
        hit = wu > 1e-9
        t_max = float(np.min(h[hit] / wu[hit])) if hit.any() else 3.0
        for frac in (0.5, 0.97, 0.9995):
            out.append(x_star + frac * min(t_max, 3.0) * u)
    X = np.array(out).reshape(-1, x_star.size)
    return X[sys_.modulator.gamma(X) < 1.0 - 1e-12]


@settings(max_examples=60)
@given(sys_=systems(), data=st.data())
def test_boundary_velocity_never_points_outward(sys_: System, data: st.DataObject) -> None:
    """(a), pointwise: on every face and every corner of two planes, ``w_i . v <= 0`` for each
    plane ``i`` the state lies on."""
    n = sys_.ds.dim
    m = len(sys_.cuts)
    W = sys_.modulator.W
    offs = np.array([c.normal @ c.point for c in sys_.cuts])
    groups = [(i,) for i in range(m)] + [(i, j) for i in range(m) for j in range(i + 1, m)]
    for grp in groups:
        T = data.draw(hnp.arrays(np.float64, (12, n), elements=st.floats(-3, 3, width=64)),
                      label=f"points{grp}")
        A = W[list(grp)]
        if np.linalg.cond(A) > 1e6:  # (nearly) parallel planes: their corner is at infinity
            continue
        X = sys_.ds.attractor + T
        X = X - (X @ A.T - offs[list(grp)]) @ np.linalg.pinv(A).T  # onto the planes
        others = np.delete(np.arange(m), grp)
        keep = np.all(X @ W[others].T < offs[others] - 1e-6, axis=1)
        keep &= np.all(np.abs(X @ A.T - offs[list(grp)]) <= 1e-9 * (1 + np.abs(X).max()), axis=1)
        keep &= np.linalg.norm(X - sys_.ds.attractor, axis=1) > 1e-6
        if not keep.any():
            continue
        X = X[keep]
        F = sys_.ds.velocity(X)
        for dt in (None, 0.01):
            Vel = sys_.modulator(X, F, dt=dt)
            tol = 1e-9 * (1.0 + np.linalg.norm(F, axis=1))[:, None]
            assert np.all(Vel @ A.T <= tol), f"velocity points out through cuts {grp}"


@settings(max_examples=60)
@given(sys_=systems(), data=st.data())
def test_lyapunov_decreases_at_least_as_fast(sys_: System, data: st.DataObject) -> None:
    """(b): dV/dt(M f) <= dV/dt(f) < 0 at sampled states inside, on and outside the cuts."""
    n = sys_.ds.dim
    X = sys_.ds.attractor + data.draw(
        hnp.arrays(np.float64, (40, n), elements=st.floats(-4, 4, width=64)), label="X")
    X = np.vstack([X, _starts(sys_, X - sys_.ds.attractor)])
    D = X - sys_.ds.attractor
    F = sys_.ds.velocity(X)
    dv_nom = 2 * np.einsum("ni,ij,nj->n", D, sys_.ds.P, F)
    dv_mod = 2 * np.einsum("ni,ij,nj->n", D, sys_.ds.P, sys_.velocity(X))
    tol = 1e-9 * (1.0 + np.abs(dv_nom))
    assert np.all(dv_mod <= dv_nom + tol)
    nz = np.linalg.norm(D, axis=1) > 1e-9
    assert np.all(dv_mod[nz] < 0.0)


def _euler(sys_: System, X: np.ndarray, dt: float, horizon: float
           ) -> tuple[np.ndarray, np.ndarray]:
    """Explicit Euler with the guard told the step: the lowest distance to each plane seen
    after its first non-negative value (N, m), and V along the way (steps, N)."""
    offs = np.array([c.normal @ c.point for c in sys_.cuts])
    W = sys_.modulator.W
    B = offs - X @ W.T
    seen = B >= 0.0
    worst = np.where(seen, B, np.inf)
    Vs = [sys_.ds.lyapunov(X)]
    for _ in range(int(np.ceil(horizon / dt))):
        X = X + dt * sys_.modulator(X, sys_.ds.velocity(X), dt=dt)
        B = offs - X @ W.T
        worst = np.where(seen, np.minimum(worst, B), worst)
        seen |= B >= 0.0
        worst = np.where(seen & np.isinf(worst), B, worst)
        Vs.append(sys_.ds.lyapunov(X))
    return worst, np.array(Vs)


def _mixed_corner() -> System:
    """The 3D case hypothesis found where eq. 7 alone leaves (a cut through x* next to a
    regular cut; ``tests/unit/test_modulation.py``), as an explicit example."""
    A = np.array([[-0.3, 0.0, -1.0], [0.0, -0.3, -1.0], [1.0, 1.0, -0.3]])
    ds = LPVDS(attractor=np.zeros(3), priors=np.array([1.0]), means=np.zeros((1, 3)),
               covs=np.eye(3)[None], A=A[None], P=np.eye(3))
    cuts = [Cut(np.array([1.0, 0.0, 0.0]), np.array([0.5, 0.0, 0.0])),
            Cut(np.array([0.0, 1.0, 0.0]), np.zeros(3))]
    return System(ds=ds, cuts=cuts, modulator=Modulator.build(cuts, np.zeros(3),
                                                              lyapunov=np.eye(3)), rate=0.6)


@settings(max_examples=30)
@given(sys_=systems(), dirs=st.integers(2, 5).flatmap(
    lambda k: hnp.arrays(np.float64, (k, 4), elements=st.floats(-1, 1, width=64))))
@example(sys_=_mixed_corner(), dirs=np.array([[-1.0, -1.0, -1.0, 0.0], [-1.0, -0.2, 0.5, 0.0]]))
def test_trajectories_stay_inside_and_converge(sys_: System, dirs: np.ndarray) -> None:
    """(a) along trajectories and (c): no Euler step leaves the cuts, and V decays to x*.

    Fixed-step explicit Euler, ``dt = 0.01 / max(1, max_k ||A_k||)``, with the step passed to
    the guard (which then caps its barrier rates at ``1 / dt``: ``b_i(x + dt v) >= (1 - dt
    rho_i) b_i(x) >= 0`` for every plane). Starts along rays from x*, some a hair from a face.
    """
    n = sys_.ds.dim
    X0 = _starts(sys_, dirs[:, :n])
    if X0.shape[0] == 0:
        return
    assert np.all(sys_.modulator.gamma(X0) < 1.0)
    dt = 0.01 / max(1.0, max(float(np.linalg.norm(a, 2)) for a in sys_.ds.A))
    horizon = 1.1 * float(np.log(1e4) / sys_.rate)
    worst, V = _euler(sys_, X0.copy(), dt, horizon)
    scale = 1e-12 * (1.0 + np.abs(np.array([c.normal @ c.point for c in sys_.cuts])))
    assert np.all(worst >= -scale), f"a trajectory crossed a cut (by {-np.min(worst):.3g})"
    t = dt * np.arange(V.shape[0])[:, None]
    rate = sys_.rate * (1.0 - 0.02)  # allowance for the Euler discretisation
    assert np.all(V <= 1.01 * V[0] * np.exp(-rate * t) + 1e-12), (
        "V decays slower than Theorem 1 guarantees")
    assert np.all(V[-1] <= 1e-4 * V[0] + 1e-12), "a trajectory did not reach x*"


@settings(max_examples=30)
@given(sys_=systems(), data=st.data())
def test_a_satisfied_cut_stays_satisfied(sys_: System, data: st.DataObject) -> None:
    """(a), beyond the theorem: from any start -- also outside some cuts -- a trajectory never
    crosses a cut it is on the inner side of (each half-space is invariant by itself)."""
    n = sys_.ds.dim
    X0 = sys_.ds.attractor + data.draw(
        hnp.arrays(np.float64, (6, n), elements=st.floats(-3, 3, width=64)), label="X0")
    dt = 0.01 / max(1.0, max(float(np.linalg.norm(a, 2)) for a in sys_.ds.A))
    horizon = min(1.1 * float(np.log(1e4) / sys_.rate), 40.0)
    worst, _ = _euler(sys_, X0, dt, horizon)
    finite = np.isfinite(worst)
    scale = 1e-12 * (1.0 + np.abs(np.array([c.normal @ c.point for c in sys_.cuts])))
    assert np.all(worst[finite] >= -np.broadcast_to(scale, worst.shape)[finite]), (
        "a trajectory crossed a cut it had been inside of")
