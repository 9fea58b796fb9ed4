"""Convex programs for a Lyapunov-stable LPV-DS (paper Sec. 4.3, eqs. 4-5).

Stability of ``f(x) = sum_k gamma_k(x) A_k (x - x*)`` follows from a quadratic Lyapunov function
``V(x) = (x - x*)^T P (x - x*)`` with

    P = P^T > 0,    A_k^T P + P A_k < 0   for every k          (paper eq. 5, "stability")

because ``dV/dt = sum_k gamma_k (x - x*)^T (A_k^T P + P A_k) (x - x*) < 0`` for ``x != x*``.
Learning P *and* A_k jointly is not convex (bilinear). Following ds-opt's P-QLF case
(Figueroa & Billard 2018, Sec. 4.2) we split it into two convex steps, both solved by cvxpy with
the Clarabel interior-point solver:

1. :func:`estimate_p` picks ``P`` from the data alone: the Lyapunov function should decrease along
   the demonstrations, ``(x_i - x*)^T P xdot_i < 0``. The condition is linear in ``P``; we minimise
   the total hinge violation of its normalised form (with a small margin) over
   ``{P : P >= p_min I, trace P = n}`` -- an SDP. (ds-opt solves a non-convex weighted variant
   with fmincon; the hinge version is convex and has the same zero set.)
2. :func:`fit_a` fits the ``A_k`` to the velocities by least squares with ``P`` fixed, under the
   LMIs ``A_k^T P + P A_k <= -eps I`` -- an SDP with K small semidefinite cones.

:func:`choose_rate` picks the decay rate the A-fit imposes: the largest on a grid up to the data's
own rate whose fit stays within an accuracy budget (:data:`RATE_BUDGET`) of the rate-0 fit.

:func:`find_p` solves the remaining direction (``A_k`` fixed, search ``P``); ``tli certify`` uses
it when a model's own ``P`` does not certify.

Any solver status other than ``optimal`` (including ``optimal_inaccurate``) raises
:class:`~tli_verify.errors.SolverError`: it never yields a model or a certificate.

References
----------
.. [1] N. Figueroa and A. Billard, "A Physically-Consistent Bayesian Non-Parametric Mixture Model
   for Dynamical System Learning", CoRL 2018 (ds-opt: P-QLF estimation, Lyapunov-constrained
   LPV-DS optimisation).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import SolverError

__all__ = [
    "RATE_BUDGET",
    "RATE_FACTOR",
    "RATE_GRID",
    "RATE_PAD",
    "SOLVER",
    "RateChoice",
    "SolveInfo",
    "block_structure",
    "choose_rate",
    "data_rate",
    "decay_rate",
    "estimate_p",
    "find_p",
    "fit_a",
    "rate_candidates",
    "sampled_growth",
    "velocity_rmse",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

SOLVER = "CLARABEL"
"""The only solver used for the Lyapunov SDPs (SCS misses the LMI margin)."""


RATE_FACTOR = 0.25
"""Fixed-factor decay rate of ``V``, as a fraction of :func:`data_rate`: the default of
:func:`tli_verify.ds.lpvds.learn_lpvds` without a ``rate_budget``, and the learner's default
before the per-DS choice (:func:`choose_rate`, the default of ``tli learn``).

Chosen on the LASA benchmark (``benchmarks/bench_lasa.py``, method PC-GMM + P-QLF, medians over
26 shapes against the old margin-only learner): factor 0.1 costs nothing measurable (RMSE and
DTWD within 1%) for a 100x larger certified rate; 0.25 costs +5% RMSE and +14% DTWD for 250x;
0.5 costs +17% RMSE and +49% DTWD. A quarter of the data's own rate keeps the certified decay
useful as a reachability deadline (``V`` halves within ``ln 2 / rate``) at a bounded cost."""

RATE_BUDGET = 0.03
"""Default accuracy budget of the per-DS rate choice (:func:`choose_rate`, ``tli learn``).

The learner certifies the largest rate of :data:`RATE_GRID` whose fit's training velocity RMSE
stays within ``1 + RATE_BUDGET`` of the rate-0 fit's (the plain ``eps`` margin, ``--rate 0``).
The fixed factor :data:`RATE_FACTOR` cost up to ~9% RMSE on some LASA shapes and almost nothing
on others; a budget spends the same accuracy everywhere (``benchmarks/bench_lasa.py``)."""

RATE_GRID = tuple(2.0 ** (-j / 2) for j in range(13))
"""Candidate rates of :func:`choose_rate`, as fractions of :func:`data_rate`: half-octave steps
from 1 (the data's own rate) down to 1/64. Each candidate is rounded *down* to 3 significant
digits (the rate the model records) and imposed with the relative pad :data:`RATE_PAD`, so the
4-digit rate the certificate states (:func:`tli_verify.certification.exact.certified_decay_rate`) is
never below the recorded one."""

RATE_PAD = 1e-4
"""Relative pad of the rate :func:`choose_rate` imposes over the rate it records.

The certificate states ``floor_4 digits(lambda* (1 - 1e-5))`` of the fit's best rate
``lambda* >= imposed rate``. A 3-digit recorded rate ``r`` is on that 4-digit grid, so the
stated rate is at least ``r`` iff ``lambda* (1 - 1e-5) >= r``: imposing ``r (1 + RATE_PAD)``
guarantees it whatever ``eps`` (the ``eps I`` margin alone covers it only for
``r <= 1e5 eps / lambda_max(P)``, e.g. not for ``--eps 1e-6``), with room for the solver's
``~1e-9`` constraint tolerance."""


def data_rate(X: npt.ArrayLike, dX: npt.ArrayLike, attractor: npt.ArrayLike) -> float:
    """The demonstrations' own time scale: ``mean_i |xdot_i| / mean_i |x_i - x*|`` (1/time).

    An exponential approach ``x(t) - x* = e^{-r t} z_0`` has exactly ``r`` here; on the LASA
    shapes it is 0.5-1.5 /s (durations 2-8 s). Independent of the length unit, so the same
    factor fits millimetres and metres.

    Parameters
    ----------
    X, dX : array_like, shape (N, n)
    attractor : array_like, shape (n,)

    Returns
    -------
    float
        Positive; 0 when the data do not move or all sit on the attractor.
    """
    Xa, dXa, xs = _as_data(X, dX, attractor)
    dist = float(np.mean(np.linalg.norm(Xa - xs, axis=1))) if Xa.size else 0.0
    speed = float(np.mean(np.linalg.norm(dXa, axis=1))) if dXa.size else 0.0
    return speed / dist if dist > 0.0 and np.isfinite(speed / dist) else 0.0


def decay_rate(P: npt.ArrayLike, A: npt.ArrayLike) -> float:
    """Largest ``lambda`` with ``A_k^T P + P A_k <= -lambda P`` for every k (float).

    ``lambda = min_k min eig(-(A_k^T P + P A_k), P)``, a generalized symmetric eigenvalue
    problem; ``dV/dt <= -lambda V`` along every mixture of the ``A_k``. Floating point: a
    figure for reports and benchmarks, not a certificate (see
    :mod:`tli_verify.certification.exact`).

    Parameters
    ----------
    P : array_like, shape (n, n)
        Symmetric positive definite.
    A : array_like, shape (K, n, n)

    Returns
    -------
    float
        Negative when some ``A_k^T P + P A_k`` is not negative definite.
    """
    from scipy.linalg import eigh

    Pa = np.asarray(P, dtype=np.float64)
    Ps = 0.5 * (Pa + Pa.T)
    out = np.inf
    for a in np.asarray(A, dtype=np.float64):
        Q = -(a.T @ Ps + Ps @ a)
        out = min(out, float(eigh(0.5 * (Q + Q.T), Ps, eigvals_only=True)[0]))
    return float(out)


def sampled_growth(P: npt.ArrayLike, A: npt.ArrayLike, dt: float) -> float:
    """Largest per-step factor ``V(x + dt A_k (x - x*)) / V(x)`` over k and x, minus 1 (float).

    ``max_k max eig((I + dt A_k)^T P (I + dt A_k), P) - 1``: negative iff every
    ``(I + dt A_k)^T P (I + dt A_k) - P`` is negative definite (the sampled-data condition at
    control period ``dt``). Floating point, like :func:`decay_rate`.

    Parameters
    ----------
    P : array_like, shape (n, n)
    A : array_like, shape (K, n, n)
    dt : float
        Control period.

    Returns
    -------
    float
    """
    from scipy.linalg import eigh

    Pa = np.asarray(P, dtype=np.float64)
    Ps = 0.5 * (Pa + Pa.T)
    Aa = np.asarray(A, dtype=np.float64)
    eye = np.eye(Ps.shape[0])
    out = -np.inf
    for a in Aa:
        F = eye + dt * a
        Q = F.T @ Ps @ F
        out = max(out, float(eigh(0.5 * (Q + Q.T), Ps, eigvals_only=True)[-1]) - 1.0)
    return float(out)


@dataclass(frozen=True, slots=True)
class SolveInfo:
    """What a convex solve reported.

    Attributes
    ----------
    problem : str
        Which program ("P-QLF", "A-fit", "P-search").
    solver : str
        Solver name (``"CLARABEL"``).
    status : str
        cvxpy status: ``"optimal"``, or ``"optimal_inaccurate"`` for an A-fit whose
        constraints were re-checked (:func:`fit_a`).
    objective : float
        Optimal value.
    seconds : float
        Wall-clock time of compile + solve.
    """

    problem: str
    solver: str
    status: str
    objective: float
    seconds: float


def _solve(problem: Any, what: str, *, inaccurate_ok: bool = False) -> SolveInfo:
    """Solve with Clarabel; anything but ``optimal`` is a :class:`SolverError`.

    With ``inaccurate_ok``, ``optimal_inaccurate`` is returned too (its status kept in the
    :class:`SolveInfo`): the caller must then re-check the constraints it needs itself.
    """
    import cvxpy as cp

    start = time.perf_counter()
    try:
        with warnings.catch_warnings():  # cvxpy warns on inaccurate solutions: handled here
            warnings.simplefilter("ignore", UserWarning)
            problem.solve(solver=cp.CLARABEL)
    except cp.error.SolverError as exc:
        raise SolverError(f"{what}: solver {SOLVER} failed: {exc}") from None
    status = str(problem.status)
    if status != cp.OPTIMAL and not (inaccurate_ok and status == cp.OPTIMAL_INACCURATE
                                     and problem.value is not None):
        raise SolverError(f"{what}: solver {SOLVER} returned status {status!r}, not 'optimal'; "
                          "no model or certificate is produced")
    return SolveInfo(problem=what, solver=SOLVER, status=status,
                     objective=float(problem.value), seconds=time.perf_counter() - start)


def _as_data(X: npt.ArrayLike, dX: npt.ArrayLike, attractor: npt.ArrayLike
             ) -> tuple[FloatArray, FloatArray, FloatArray]:
    Xa = np.asarray(X, dtype=np.float64)
    dXa = np.asarray(dX, dtype=np.float64)
    xs = np.asarray(attractor, dtype=np.float64)
    if Xa.ndim != 2 or dXa.shape != Xa.shape or xs.shape != (Xa.shape[1],):
        raise SolverError(f"data shapes do not match: X {Xa.shape}, dX {dXa.shape}, "
                          f"attractor {xs.shape}")
    return Xa, dXa, xs


def estimate_p(
    X: npt.ArrayLike,
    dX: npt.ArrayLike,
    attractor: npt.ArrayLike,
    *,
    p_min: float = 0.05,
    margin: float = 0.1,
    shrink: float = 1e-2,
) -> tuple[FloatArray, SolveInfo]:
    """Convex P-QLF: a Lyapunov matrix under which the demonstrations descend.

    Solves ::

        min_P  mean_i max(0, c_i(P) + margin) + shrink * |P - I|_F^2
        s.t.   P >= p_min I,  trace P = n,
        c_i(P) = (x_i - x*)^T P xdot_i / (|x_i - x*| |xdot_i|)

    Parameters
    ----------
    X, dX : array_like, shape (N, n)
        Positions and velocities.
    attractor : array_like, shape (n,)
        ``x*``.
    p_min : float, optional
        Smallest eigenvalue allowed for ``P`` (with ``trace P = n``): bounds its condition number.
    margin : float, optional
        Desired normalised decrease ``-c_i`` on each sample.
    shrink : float, optional
        Pull towards ``P = I`` (breaks ties when many ``P`` explain the data).

    Returns
    -------
    P : ndarray, shape (n, n)
        Symmetric positive definite.
    info : SolveInfo
    """
    import cvxpy as cp

    Xa, dXa, xs = _as_data(X, dX, attractor)
    n = Xa.shape[1]
    Z = Xa - xs
    zn = np.linalg.norm(Z, axis=1)
    vn = np.linalg.norm(dXa, axis=1)
    use = (zn > 1e-9 * max(1.0, float(zn.max(initial=0.0)))) & (vn > 1e-12)
    if not np.any(use):
        return np.eye(n), SolveInfo("P-QLF", "none", "optimal", 0.0, 0.0)
    zh = Z[use] / zn[use, None]
    vh = dXa[use] / vn[use, None]
    # c_i = sum_ab P_ab zh_a vh_b: linear in vec(P)
    G = np.einsum("ia,ib->iab", zh, vh).reshape(-1, n * n)
    P = cp.Variable((n, n), symmetric=True)
    c = G @ cp.reshape(P, (n * n,), order="C")
    objective = cp.sum(cp.pos(c + margin)) / G.shape[0] + shrink * cp.sum_squares(P - np.eye(n))
    problem = cp.Problem(cp.Minimize(objective),
                         [P >> p_min * np.eye(n), cp.trace(P) == n])
    info = _solve(problem, "P-QLF")
    value = np.asarray(P.value, dtype=np.float64)
    return 0.5 * (value + value.T), info


def fit_a(
    X: npt.ArrayLike,
    dX: npt.ArrayLike,
    gamma: npt.ArrayLike,
    attractor: npt.ArrayLike,
    P: npt.ArrayLike,
    *,
    eps: float = 1e-3,
    rate: float = 0.0,
    dt: float | None = None,
    ridge: float = 1e-6,
    structure: npt.ArrayLike | None = None,
) -> tuple[FloatArray, SolveInfo]:
    """Least-squares ``A_k`` under the Lyapunov LMIs for a fixed ``P`` (paper eq. 5).

    Solves ::

        min_{A_1..A_K}  mean_i |xdot_i - sum_k gamma_k(x_i) A_k (x_i - x*)|^2
                        + ridge * sum_k |A_k|_F^2
        s.t.            A_k^T P + P A_k <= -M                       for every k   (dt None)
                        (I + dt A_k)^T P (I + dt A_k) <= P - dt M   for every k   (dt given)
        with            M = eps I + rate P

    ``rate = 0, dt = None`` is the plain margin ``A_k^T P + P A_k <= -eps I`` (the learner's
    earlier margin-only behaviour). With ``rate > 0`` every component contracts ``V`` at rate
    ``rate``: ``dV/dt <= -rate V`` for every mixture (paper eq. 4), so ``V`` decays at least like
    ``exp(-rate t)``. The sampled-data form, divided by ``dt``, is
    ``A_k^T P + P A_k + M + dt A_k^T P A_k <= 0``, imposed as the Schur complement LMI ::

        [[-(A_k^T P + P A_k) - M, sqrt(dt) A_k^T R], [sqrt(dt) R^T A_k, I]] >= 0,  P = R R^T

    (this scaling keeps the program well conditioned at ``dt = 1e-3``). It implies the
    continuous one (``A_k^T P A_k >= 0``); the per-step decrease
    ``V(x + dt f(x)) <= (1 - dt rate) V(x)`` of a controller running at period ``dt`` (by
    convexity of the P-norm it covers every mixture of the ``A_k``); and the same at every
    shorter period (``I + s A_k`` is a convex combination of ``I`` and ``I + dt A_k`` for
    ``0 <= s <= dt``).

    With ``dt`` given, the continuous-time program is solved first; its optimum is kept when it
    already decreases ``V`` per step by at least half the sampled LMI's margin
    (:func:`sampled_growth` ``<= -dt (rate + eps / lambda_max(P)) / 2``), which is the usual
    case (``dt |A_k|^2`` far below ``rate``). Otherwise the program is solved again with the
    sampled-data LMIs in place of the continuous ones.

    The data enter only through the ``K n^2``-dimensional normal equations (Cholesky factor), so
    the program size does not grow with N. The objective is divided by the squared norm of the
    normal equations' right-hand side (same minimiser): without it, data in millimetres drove
    Clarabel to ``optimal_inaccurate`` on the sampled-data LMIs.

    Parameters
    ----------
    X, dX : array_like, shape (N, n)
        Positions and velocities.
    gamma : array_like, shape (N, K)
        Mixing weights ``gamma_k(x_i)``.
    attractor : array_like, shape (n,)
        ``x*``.
    P : array_like, shape (n, n)
        Lyapunov matrix (symmetric positive definite).
    eps : float, optional
        LMI margin (units of 1/time when ``trace P = n``).
    rate : float, optional
        Certified decay rate of ``V`` (1/time); 0 for the plain ``eps`` margin.
    dt : float, optional
        Control period of the sampled-data constraint; None for the continuous-time LMI only.
    ridge : float, optional
        Tikhonov weight relative to the mean squared data scale.
    structure : array_like of bool, shape (n, n), optional
        The entries of every ``A_k`` the fit may use; the others are 0 (e.g. a pose DS's
        blocks: position and orientation decoupled, :func:`block_structure`). Default: all.

    Returns
    -------
    A : ndarray, shape (K, n, n)
    info : SolveInfo
    """
    Xa, dXa, xs = _as_data(X, dX, attractor)
    Ga = np.asarray(gamma, dtype=np.float64)
    Pa = np.asarray(P, dtype=np.float64)
    N, n = Xa.shape
    if Ga.ndim != 2 or Ga.shape[0] != N:
        raise SolverError(f"gamma must have shape ({N}, K), got {Ga.shape}")
    K = Ga.shape[1]
    Z = Xa - xs
    free = _free_entries(structure, n)  # the entries of vec_F(A_k) the fit uses
    # design matrix D[(i,a), (k,b,c)] = gamma_ik z_ib delta_ac; columns follow vec_F(A_k)
    D = np.einsum("ik,ib,ac->iakbc", Ga, Z, np.eye(n)).reshape(N * n, K, n * n)
    D = D[:, :, free].reshape(N * n, K * free.size)
    y = dXa.reshape(N * n)
    H = D.T @ D / N
    g = D.T @ y / N
    lam = ridge * max(float(np.trace(H)) / H.shape[0], 1e-12)
    H[np.diag_indices_from(H)] += lam
    L = np.linalg.cholesky(H)
    rhs = np.linalg.solve(L, g)
    if not (eps >= 0.0 and rate >= 0.0 and eps + rate > 0.0):
        raise SolverError(f"A-fit needs eps >= 0 and rate >= 0, not both 0 (got eps={eps}, "
                          f"rate={rate})")
    if dt is not None and not dt > 0.0:
        raise SolverError(f"A-fit: control period dt must be positive, got {dt}")
    Ps = 0.5 * (Pa + Pa.T)
    margin = eps * np.eye(n) + rate * Ps
    # unit-scale objective (mm or m alike); the floor, far below the velocities any fit must
    # produce (|A_k| >= (eps + rate) / 2 lambda_max(P)), only matters for data that do not
    # move, whose objective was otherwise scaled by up to 1e24 (Clarabel: 'infeasible')
    floor = 1e-3 * (eps + rate) * float(np.sqrt(np.trace(H) / H.shape[0]))
    scale = max(float(np.linalg.norm(rhs)), floor, 1e-12)
    # |L^T theta - rhs|^2 / scale^2 with L L^T = H and L rhs = g
    objective = (2.0 * H / scale**2, -2.0 * g / scale**2, float(rhs @ rhs) / scale**2)
    # continuous LMI of every k: -(P A_k + A_k^T P) - margin >= 0
    basis = _unit_matrices(n)  # (n^2, n, n), index c n + r: E_rc (vec_F order of theta)
    lin = -(np.matmul(Ps, basis) + np.matmul(np.transpose(basis, (0, 2, 1)), Ps))
    values, info = _lmi_least_squares(objective, -margin, lin[free], K, "A-fit", free=free,
                                      n=n)
    if info.status != "optimal":
        _check_margin(Ps, values, margin, None, info)
    if dt is None:
        return values, info
    # per-step decrease the sampled LMI guarantees: V(x + dt f) <= (1 - target) V(x)
    target = dt * (rate + eps / float(np.linalg.eigvalsh(Ps)[-1]))
    if sampled_growth(Ps, values, dt) <= -0.5 * target:
        return values, info  # the continuous optimum already steps down at dt: keep it
    root = np.linalg.cholesky(Ps)  # P = root root^T
    # A^T P + P A + margin + dt A^T P A <= 0, as the Schur complement with unit scale
    # [[-(P A + A^T P) - margin, C^T], [C, I]] >= 0,  C = sqrt(dt) R^T A
    const = np.block([[-margin, np.zeros((n, n))], [np.zeros((n, n)), np.eye(n)]])
    C = np.sqrt(dt) * np.matmul(root.T, basis)
    lin2 = np.zeros((n * n, 2 * n, 2 * n))
    lin2[:, :n, :n] = lin
    lin2[:, n:, :n] = C
    lin2[:, :n, n:] = np.transpose(C, (0, 2, 1))
    values, info = _lmi_least_squares(objective, const, lin2[free], K, "A-fit (sampled)",
                                      free=free, n=n)
    if info.status != "optimal":
        _check_margin(Ps, values, margin, dt, info)
    return values, info


def block_structure(n: int, blocks: Sequence[Sequence[int]]) -> BoolArray:
    """The ``structure`` of :func:`fit_a` that decouples groups of coordinates: entry
    ``(r, c)`` of ``A_k`` is free iff ``r`` and ``c`` lie in the same group (coordinates in no
    group form one more group).

    Parameters
    ----------
    n : int
        State dimension.
    blocks : sequence of sequence of int
        Disjoint groups of coordinates, e.g. ``[[3, 4, 5]]`` for a pose state's orientation.

    Returns
    -------
    ndarray of bool, shape (n, n)
    """
    group = np.full(n, -1)
    for g, cols in enumerate(blocks):
        for c in cols:
            if not 0 <= int(c) < n or group[int(c)] != -1:
                raise SolverError(f"A-fit structure: coordinate {c} is outside 0..{n - 1} or "
                                  "in two groups")
            group[int(c)] = g
    return np.asarray(group[:, None] == group[None, :], dtype=np.bool_)


def _free_entries(structure: npt.ArrayLike | None, n: int) -> npt.NDArray[np.intp]:
    """The indices (``vec_F`` order, ``c n + r``) of the entries of ``A_k`` the fit uses."""
    if structure is None:
        return np.arange(n * n)
    mask = np.asarray(structure, dtype=bool)
    if mask.shape != (n, n) or not bool(np.all(np.diag(mask))):
        raise SolverError(f"A-fit structure must be an ({n}, {n}) boolean mask with a free "
                          "diagonal")
    return np.flatnonzero(mask.T.reshape(-1))


def _unit_matrices(n: int) -> FloatArray:
    """``E_rc`` (1 at (r, c)), stacked in column-major order: index ``c n + r``; shape
    (n^2, n, n)."""
    out = np.zeros((n * n, n, n))
    for c in range(n):
        for r in range(n):
            out[c * n + r, r, c] = 1.0
    return out


def _svec_rows(m: int) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp], FloatArray]:
    """Clarabel's ``PSDTriangleConeT`` vectorisation of an (m, m) symmetric matrix: the upper
    triangle column by column, off-diagonal entries scaled by sqrt(2)."""
    rows = [(i, j) for j in range(m) for i in range(j + 1)]
    i = np.array([r[0] for r in rows], dtype=np.intp)
    j = np.array([r[1] for r in rows], dtype=np.intp)
    return i, j, np.where(i == j, 1.0, np.sqrt(2.0))


def _lmi_least_squares(
    objective: tuple[FloatArray, FloatArray, float],
    const: FloatArray,
    lin: FloatArray,
    K: int,
    what: str,
    *,
    free: npt.NDArray[np.intp] | None = None,
    n: int | None = None,
) -> tuple[FloatArray, SolveInfo]:
    """``min 0.5 theta^T Q theta + q^T theta + c0`` s.t. ``const + sum_m theta_(k, m) lin_m >= 0``
    (semidefinite, one block per k), solved by Clarabel directly.

    The program :func:`fit_a` used to state through cvxpy, built here without cvxpy's
    compilation (70 ms per A-fit at LASA size, 5 A-fits per DS with the rate choice, against
    ~10 ms for the solve). Same solver, same (default) settings; the optimum agrees with the
    cvxpy formulation to the solver's tolerance.

    Parameters
    ----------
    objective : (Q, q, c0)
        ``Q`` shape (K m, K m) symmetric PSD, ``q`` shape (K m,), constant ``c0``;
        ``m = n^2`` entries of each ``A_k`` in column-major order.
    const : ndarray, shape (s, s)
        Constant part of every block's matrix.
    lin : ndarray, shape (m, s, s)
        Coefficient matrix of each free entry of ``A_k`` (the same for every k).
    K : int
        Number of blocks.
    what : str
        Program name for :class:`SolveInfo` and errors.
    free, n : optional
        The free entries' indices in ``vec_F(A_k)`` and the dimension (default: all ``m =
        n^2`` entries); the others are 0.

    Returns
    -------
    A : ndarray, shape (K, n, n)
    info : SolveInfo
        Status ``"optimal"`` (Clarabel ``Solved``) or ``"optimal_inaccurate"``
        (``AlmostSolved``: the caller re-checks the LMIs, :func:`_check_margin`).

    Raises
    ------
    SolverError
        Any other solver status.
    """
    import clarabel
    import scipy.sparse as sp

    start = time.perf_counter()
    Q, q, c0 = objective
    m = lin.shape[0]
    if n is None:
        n = round(np.sqrt(m))
    idx = np.arange(n * n) if free is None else free
    i, j, w = _svec_rows(const.shape[0])
    block = -(lin[:, i, j] * w).T  # (svec, n^2): s = b - A theta
    A_mat = sp.block_diag([sp.csc_matrix(block)] * K, format="csc")
    b = np.tile(const[i, j] * w, K)
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    try:
        solver = clarabel.DefaultSolver(sp.triu(sp.csc_matrix(Q), format="csc"), q, A_mat, b,
                                        [clarabel.PSDTriangleConeT(const.shape[0])] * K,
                                        settings)
        solution = solver.solve()
    except Exception as exc:  # Clarabel's own errors (bad data): no model
        raise SolverError(f"{what}: solver {SOLVER} failed: {exc}") from None
    if solution.status == clarabel.SolverStatus.Solved:
        status = "optimal"
    elif solution.status == clarabel.SolverStatus.AlmostSolved:
        status = "optimal_inaccurate"
    else:
        raise SolverError(f"{what}: solver {SOLVER} returned status {str(solution.status)!r}, "
                          "not 'optimal'; no model or certificate is produced")
    theta = np.asarray(solution.x, dtype=np.float64)
    if not np.all(np.isfinite(theta)):
        raise SolverError(f"{what}: solver {SOLVER} returned a non-finite solution")
    full = np.zeros((K, n * n))
    full[:, idx] = theta.reshape(K, m)
    values = np.stack([full[k].reshape(n, n, order="F") for k in range(K)])
    return values, SolveInfo(problem=what, solver=SOLVER, status=status,
                             objective=float(solution.obj_val) + c0,
                             seconds=time.perf_counter() - start)


def _check_margin(P: FloatArray, A: FloatArray, margin: FloatArray, dt: float | None,
                  info: SolveInfo) -> None:
    """Accept an ``optimal_inaccurate`` A-fit only if its ``A_k`` meet the LMIs in floats.

    Each ``A_k^T P + P A_k + margin`` (plus ``dt A_k^T P A_k`` for the sampled form) must be
    negative semidefinite to ``1e-9`` of its scale. A near-optimal fit that satisfies the
    constraints is as good a DS as the optimal one; whether it is *certified* is decided by
    the exact rational check of ``tli certify``, never by this float test.

    Raises
    ------
    SolverError
        The inaccurate solution violates a constraint.
    """
    for k, a in enumerate(A):
        Q = a.T @ P + P @ a + margin + (0.0 if dt is None else dt * (a.T @ P @ a))
        top = float(np.linalg.eigvalsh(0.5 * (Q + Q.T))[-1])
        if top > 1e-9 * max(1.0, float(np.abs(Q).max())):
            raise SolverError(
                f"{info.problem}: solver {SOLVER} returned status 'optimal_inaccurate' and "
                f"A_{k} violates its Lyapunov LMI by {top:.2g}; no model or certificate is "
                "produced")


def find_p(A: npt.ArrayLike, *, eps: float = 1e-6,
           dt: float | None = None) -> tuple[FloatArray, SolveInfo]:
    """Search a common quadratic Lyapunov matrix for fixed ``A_k``.

    Solves ``min kappa  s.t.  I <= P <= kappa I,  A_k^T P + P A_k <= -eps I`` (every k), and
    with ``dt`` also the sampled-data decrease ``(I + dt A_k)^T P (I + dt A_k) - P <= -dt eps I``
    (linear in ``P`` for fixed ``A_k``).

    Parameters
    ----------
    A : array_like, shape (K, n, n)
    eps : float, optional
        LMI margin.
    dt : float, optional
        Control period of the sampled-data condition.

    Returns
    -------
    P : ndarray, shape (n, n)
    info : SolveInfo

    Raises
    ------
    SolverError
        If the SDP is infeasible (no common quadratic Lyapunov function) or not solved to
        ``optimal``.
    """
    import cvxpy as cp

    Aa = np.asarray(A, dtype=np.float64)
    n = Aa.shape[-1]
    P = cp.Variable((n, n), symmetric=True)
    kappa = cp.Variable()
    eye = np.eye(n)
    constraints = [P >> eye, P << kappa * eye]
    for a in Aa:
        M = P @ a
        constraints.append(M + M.T << -eps * eye)
        if dt is not None:
            B = eye + dt * a
            S = B.T @ P @ B - P
            constraints.append(0.5 * (S + S.T) << -dt * eps * eye)
    info = _solve(cp.Problem(cp.Minimize(kappa), constraints), "P-search")
    value = np.asarray(P.value, dtype=np.float64)
    return 0.5 * (value + value.T), info


def velocity_rmse(X: npt.ArrayLike, dX: npt.ArrayLike, gamma: npt.ArrayLike,
                  attractor: npt.ArrayLike, A: npt.ArrayLike) -> float:
    """Velocity RMSE ``sqrt(mean_i |xdot_i - sum_k gamma_k(x_i) A_k (x_i - x*)|^2)`` (float).

    Parameters
    ----------
    X, dX : array_like, shape (N, n)
    gamma : array_like, shape (N, K)
    attractor : array_like, shape (n,)
    A : array_like, shape (K, n, n)

    Returns
    -------
    float
        In the units of ``dX``; 0 for no samples.
    """
    Xa, dXa, xs = _as_data(X, dX, attractor)
    if not Xa.size:
        return 0.0
    F = np.einsum("ik,kab,ib->ia", np.asarray(gamma, dtype=np.float64),
                  np.asarray(A, dtype=np.float64), Xa - xs)
    return float(np.sqrt(np.mean(np.sum((F - dXa) ** 2, axis=1))))


@dataclass(frozen=True, slots=True)
class RateChoice:
    """The decay rate :func:`choose_rate` picked, and the fit at that rate.

    Attributes
    ----------
    rate : float
        Chosen rate (1/time), 3 significant digits (the fit imposed it padded by
        :data:`RATE_PAD`, so a certificate of the fit states at least this); 0 when the data do
        not move.
    A : ndarray, shape (K, n, n)
        The A-fit at ``rate`` (with the sampled-data constraint when ``dt`` was given).
    info : SolveInfo
        Its solve.
    rmse : float
        Training velocity RMSE of that fit.
    reference_rmse : float
        Training velocity RMSE of the rate-0 fit (plain ``eps`` margin, continuous time).
    budget : float
        The accuracy budget: ``rmse <= (1 + budget) reference_rmse`` (when ``within_budget``).
    data_rate : float
        :func:`data_rate` of the data (the grid's top).
    within_budget : bool
        False only when even the grid's smallest rate costs more than the budget (or its solve
        failed for every candidate but the smallest); the smallest rate is chosen then (the
        learner keeps a positive certified rate).
    tried : tuple of (rate, rmse)
        Every candidate solved, in the order solved (``rmse`` inf for a solver failure).
    """

    rate: float
    A: FloatArray
    info: SolveInfo
    rmse: float
    reference_rmse: float
    budget: float
    data_rate: float
    within_budget: bool
    tried: tuple[tuple[float, float], ...]


def _round_down(x: float, digits: int) -> float:
    """``x > 0`` rounded down to ``digits`` significant decimal digits (exactly, then to the
    nearest float: its exact decimal is what a certificate compares with)."""
    import math
    from fractions import Fraction

    exact = Fraction(x)
    exp10 = math.floor(math.log10(x)) - digits + 1
    if Fraction(10) ** (exp10 + digits) <= exact:  # log10 rounded up across a power of 10
        exp10 += 1
    elif Fraction(10) ** (exp10 + digits - 1) > exact:  # ... or down
        exp10 -= 1
    unit = Fraction(10) ** exp10
    return float(math.floor(exact / unit) * unit)


def rate_candidates(rate: float, grid: tuple[float, ...] = RATE_GRID) -> tuple[float, ...]:
    """The candidate rates of :func:`choose_rate` for data of rate ``rate``, largest first.

    ``grid_j * rate`` rounded down to 3 significant digits, duplicates removed; empty when
    ``rate`` is 0 (data that do not move).

    Parameters
    ----------
    rate : float
        :func:`data_rate` of the data.
    grid : tuple of float, optional
        Fractions of ``rate`` (default :data:`RATE_GRID`).

    Returns
    -------
    tuple of float
    """
    import math

    return tuple(sorted({_round_down(f * rate, 3) for f in grid
                         if f * rate > 0.0 and math.isfinite(f * rate)}, reverse=True))


def choose_rate(
    X: npt.ArrayLike,
    dX: npt.ArrayLike,
    gamma: npt.ArrayLike,
    attractor: npt.ArrayLike,
    P: npt.ArrayLike,
    *,
    eps: float = 1e-3,
    dt: float | None = None,
    budget: float = RATE_BUDGET,
    grid: tuple[float, ...] = RATE_GRID,
    structure: npt.ArrayLike | None = None,
) -> RateChoice:
    """The largest decay rate on a grid whose A-fit stays within an accuracy budget.

    1. Reference: :func:`fit_a` at ``rate = 0`` (the plain ``eps`` margin, continuous time: the
       program of ``--rate 0``), with training velocity RMSE ``e_0`` (:func:`velocity_rmse`).
    2. Candidates (:func:`rate_candidates`): ``r_j = grid_j * data_rate(X, dX, attractor)``,
       rounded down to 3 significant digits, largest first. A candidate is *within budget*
       when the A-fit imposing ``r_j (1 + RATE_PAD)`` (with the sampled-data constraint at
       ``dt``: exactly the fit the learner keeps) has RMSE
       ``e_j <= (1 + budget) e_0 + 1e-6 rms|xdot|`` (the absolute term only keeps an exact fit,
       ``e_0 ~ 0``, or ``budget = 0`` from rejecting a rate the fit does not feel on solver
       noise).
    3. Bisection over the candidate index. Whatever the data, the result is a rate within
       budget whose next larger candidate was solved and is not (or the largest candidate):
       the bisection keeps "``r_lo`` outside, ``r_hi`` within" and stops when they are
       neighbours. It is the *largest* rate within budget when ``e_j`` grows with the rate,
       which holds up to solver accuracy for the continuous-time fits (their feasible sets
       shrink as the rate grows; the ``1e-6`` ridge term is what is minimised besides the
       RMSE) and may fail by a hair where :func:`fit_a` switches between the continuous
       optimum and the sampled-data re-solve (a different program). ``ceil(log2(m + 1))``
       candidate solves for ``m`` candidates (4 for the default grid) besides the reference: 5
       A-fits instead of 1.

    A candidate whose solve fails (:class:`~tli_verify.errors.SolverError`) counts as outside
    the budget. When no candidate is within budget the smallest is chosen (``within_budget``
    False). Deterministic: no randomness, a fixed number of solves for given data.

    Parameters
    ----------
    X, dX, gamma, attractor, P, eps, dt, structure
        As for :func:`fit_a` (every fit of the choice has the same structure).
    budget : float, optional
        Relative RMSE increase allowed over the rate-0 fit (default :data:`RATE_BUDGET`).
    grid : tuple of float, optional
        Candidate rates as fractions of :func:`data_rate` (default :data:`RATE_GRID`; any
        order, sorted here).

    Returns
    -------
    RateChoice

    Raises
    ------
    SolverError
        The reference fit fails, ``eps`` is not positive, the budget is not finite and >= 0,
        or every candidate is outside the budget and the smallest one's fit fails.
    """
    import math

    if not (isinstance(budget, (int, float)) and math.isfinite(budget) and budget >= 0.0):
        raise SolverError(f"rate budget must be a finite number >= 0, got {budget!r}")
    if not eps > 0.0:
        raise SolverError(f"the rate choice needs a positive margin eps for its rate-0 reference "
                          f"fit, got eps={eps}")
    Xa, dXa, xs = _as_data(X, dX, attractor)
    r_data = data_rate(Xa, dXa, xs)
    A_ref, info_ref = fit_a(Xa, dXa, gamma, xs, P, eps=eps, structure=structure)
    e_ref = velocity_rmse(Xa, dXa, gamma, xs, A_ref)
    rms = float(np.sqrt(np.mean(np.sum(dXa**2, axis=1)))) if dXa.size else 0.0
    limit = (1.0 + budget) * e_ref + 1e-6 * rms
    rates = rate_candidates(r_data, grid)
    if not rates:  # the data do not move: nothing to choose, the margin-only fit
        return RateChoice(0.0, A_ref, info_ref, e_ref, e_ref, float(budget), r_data, True, ())
    fits: dict[int, tuple[FloatArray, SolveInfo, float]] = {}
    errors: dict[int, SolverError] = {}
    tried: list[tuple[float, float]] = []

    def within(j: int) -> bool:
        try:
            A, info = fit_a(Xa, dXa, gamma, xs, P, eps=eps, rate=rates[j] * (1.0 + RATE_PAD),
                            dt=dt, structure=structure)
        except SolverError as exc:
            errors[j] = exc
            tried.append((rates[j], math.inf))
            return False
        e = velocity_rmse(Xa, dXa, gamma, xs, A)
        fits[j] = (A, info, e)
        tried.append((rates[j], e))
        return e <= limit

    lo, hi = -1, len(rates)  # invariant: rates[lo] outside (or none), rates[hi] within (or none)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if within(mid):
            hi = mid
        else:
            lo = mid
    ok = hi < len(rates)
    j = hi if ok else len(rates) - 1  # none within: lo ended on the smallest, solved
    if j not in fits:
        raise SolverError(f"rate choice: no candidate rate is within the budget {budget:g} and "
                          f"the smallest, {rates[j]:g}/s, does not solve: {errors[j]}")
    A, info, e = fits[j]
    return RateChoice(rates[j], A, info, e, e_ref, float(budget), r_data, ok, tuple(tried))
