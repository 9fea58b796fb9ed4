"""The LPV-DS motion policy of one mode and its learning pipeline (paper Sec. 4.3, eqs. 4-5).

``f(x) = sum_k gamma_k(x) A_k (x - x*)`` with ``gamma_k`` the posterior of a position GMM
(:class:`tli_verify.ds.gmm.GMM`). Writing ``b_k = -A_k x*`` (paper eq. 5) makes ``x*`` an exact
equilibrium. With ``P = P^T > 0`` and ``A_k^T P + P A_k < 0`` for all k,
``V(x) = (x-x*)^T P (x-x*)`` proves global asymptotic stability.

Learning (:func:`learn_lpvds`) follows ds-opt (Figueroa & Billard, CoRL 2018):

1. mixing: physically-consistent Bayesian non-parametric GMM (:func:`~tli_verify.ds.gmm.fit_pcgmm`),
   or, as the baseline, EM with K by BIC (:func:`~tli_verify.ds.gmm.fit_em_bic`);
2. ``P``: the convex P-QLF program (:func:`~tli_verify.ds.lyapunov.estimate_p`), or ``P = I``
   for the baseline;
3. ``A_k``: Lyapunov-constrained least squares (:func:`~tli_verify.ds.lyapunov.fit_a`).

Default constraint of step 3: a *certified decay rate* and a *sampled-data* margin.
With only the margin ``A_k^T P + P A_k <= -eps I`` (eps = 1e-3, ds-opt's choice), learned models
sit on the stability boundary: ``V`` decays at ~5e-4 /s away from the data, and the per-step
decrease of a 1 kHz controller failed for 8 of the 21 bundled scoop components. The default
(:func:`~tli_verify.ds.lyapunov.fit_a` with ``rate`` and ``dt``) is now
``A_k^T P + P A_k <= -(eps I + rate P)`` with ``rate = 0.25 x`` the data's own rate
(:func:`~tli_verify.ds.lyapunov.data_rate`, ``mean |xdot| / mean |x - x*|``), so ``V`` decays at
least like ``exp(-rate t)``, and the per-step decrease at ``dt = 1 ms``,
``(I + dt A_k)^T P (I + dt A_k) < P`` with margin at least ``dt rate / 2`` (hence at every
shorter period too). ``rate=0`` gives back the old program exactly.

Rate choice per DS (``rate_budget``, the default of :func:`tli_verify.model.learn.learn_model` and
``tli learn``): a fixed factor spends accuracy unevenly (on LASA, 0.25x costs +9% RMSE on one
shape and +1% on another), so :func:`~tli_verify.ds.lyapunov.choose_rate` fits at rate 0 first
and then certifies the largest rate of a half-octave grid (up to the data's own rate) whose fit's
training velocity RMSE stays within ``1 + rate_budget`` of the rate-0 fit's (default
:data:`~tli_verify.ds.lyapunov.RATE_BUDGET` = 3%). Without ``rate_budget`` (and without ``rate``)
:func:`learn_lpvds` keeps the fixed factor :data:`~tli_verify.ds.lyapunov.RATE_FACTOR`.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from operator import mul
from typing import Literal

import numpy as np
import numpy.typing as npt

from tli_verify.defaults import DEFAULT_DT_FLOAT
from tli_verify.ds.gmm import GMM, fit_em_bic, fit_pcgmm
from tli_verify.ds.lyapunov import (
    RATE_FACTOR,
    SOLVER,
    block_structure,
    choose_rate,
    data_rate,
    estimate_p,
    fit_a,
)
from tli_verify.errors import ModelError

__all__ = ["LPVDS", "Clustering", "FitInfo", "LyapunovKind", "learn_lpvds"]

FloatArray = npt.NDArray[np.float64]
Clustering = Literal["pc-gmm", "em-bic"]
"""Mixing model: the PC-GMM method or the EM+BIC baseline."""
LyapunovKind = Literal["p-qlf", "identity"]
"""``P`` learned by the convex P-QLF program, or fixed to the identity (baseline)."""


@dataclass(frozen=True, slots=True, eq=False)
class LPVDS:
    """A linear parameter-varying dynamical system (paper eq. 4).

    Attributes
    ----------
    attractor : ndarray, shape (n,)
        ``x*``.
    priors : ndarray, shape (K,)
        GMM weights ``pi_k``.
    means : ndarray, shape (K, n)
        GMM means ``mu_k``.
    covs : ndarray, shape (K, n, n)
        GMM covariances ``Sigma_k``.
    A : ndarray, shape (K, n, n)
        Linear systems ``A_k``.
    P : ndarray, shape (n, n)
        Lyapunov matrix of ``V(x) = (x - x*)^T P (x - x*)``.
    """

    attractor: FloatArray
    priors: FloatArray
    means: FloatArray
    covs: FloatArray
    A: FloatArray
    P: FloatArray
    _mix: GMM = field(init=False, repr=False)
    _a_stack: FloatArray = field(init=False, repr=False)
    _one: tuple[tuple[float, ...], tuple[tuple[float, ...], ...]] = field(init=False,
                                                                          repr=False)

    def __post_init__(self) -> None:
        mix = GMM(priors=self.priors, means=self.means, covs=self.covs)
        k, n = mix.n_components, mix.dim
        attractor = np.array(self.attractor, dtype=np.float64)
        A = np.array(self.A, dtype=np.float64)
        P = np.array(self.P, dtype=np.float64)
        if attractor.shape != (n,):
            raise ModelError(f"attractor must have shape ({n},), got {attractor.shape}")
        if A.shape != (k, n, n):
            raise ModelError(f"A must have shape ({k}, {n}, {n}), got {A.shape}")
        if P.shape != (n, n):
            raise ModelError(f"P must have shape ({n}, {n}), got {P.shape}")
        if not (np.all(np.isfinite(attractor)) and np.all(np.isfinite(A))
                and np.all(np.isfinite(P))):
            raise ModelError("LPV-DS parameters must be finite")
        for name, value in (("attractor", attractor), ("A", A), ("P", P)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        for name in ("priors", "means", "covs"):
            object.__setattr__(self, name, getattr(mix, name))
        object.__setattr__(self, "_mix", mix)
        a_stack = np.ascontiguousarray(np.transpose(A, (0, 2, 1)).reshape(k * n, n))
        a_stack.setflags(write=False)
        object.__setattr__(self, "_a_stack", a_stack)  # rows k*n + j: (A_k)[:, j]
        # single-state path (velocity of one state): x* and the columns of a_stack as floats
        object.__setattr__(self, "_one", (tuple(attractor.tolist()),
                                          tuple(tuple(c) for c in a_stack.T.tolist())))

    @property
    def dim(self) -> int:
        """State dimension n."""
        return int(self.attractor.size)

    @property
    def mixture(self) -> GMM:
        """The position GMM of ``gamma_k`` (paper eq. 4)."""
        return self._mix

    @property
    def n_components(self) -> int:
        """Number of linear systems K."""
        return int(self.priors.size)

    def _states(self, X: npt.ArrayLike) -> tuple[FloatArray, bool]:
        Xa = np.asarray(X, dtype=np.float64)
        single = Xa.ndim == 1
        if single:
            Xa = Xa[None, :]
        if Xa.ndim != 2 or Xa.shape[1] != self.dim:
            raise ModelError(f"states must have shape (N, {self.dim}) or ({self.dim},), "
                             f"got {np.shape(X)}")
        return Xa, single

    def gamma(self, X: npt.ArrayLike) -> FloatArray:
        """Mixing weights ``gamma_k(x)``.

        Parameters
        ----------
        X : array_like, shape (N, n)

        Returns
        -------
        ndarray, shape (N, K)
        """
        Xa, _ = self._states(X)
        return self._mix.posterior(Xa)

    def velocity(self, X: npt.ArrayLike) -> FloatArray:
        """Evaluate ``f(x) = sum_k gamma_k(x) A_k (x - x*)`` (paper eq. 4), vectorised.

        Parameters
        ----------
        X : array_like, shape (N, n) or (n,)

        Returns
        -------
        ndarray, shape (N, n) or (n,)
            Same leading shape as ``X``.
        """
        if isinstance(X, np.ndarray) and X.shape == (len(self._one[0]),) \
                and X.dtype == np.float64:
            return self._velocity_one(X.tolist())
        Xa, single = self._states(X)
        Z = Xa - self.attractor
        gamma = self._mix.posterior(Xa)  # (N, K)
        # sum_k gamma_k A_k z = [gamma_k z_j]_(k, j) @ [A_k^T stacked]: one matrix product.
        G = (gamma[:, :, None] * Z[:, None, :]).reshape(Z.shape[0], -1)  # (N, K n)
        F = G @ self._a_stack
        return F[0] if single else F

    def _velocity_one(self, x: list[float]) -> FloatArray:
        """:meth:`velocity` of one state in plain Python: ``G @ a_stack`` with
        ``G = [gamma_k z_i]`` (the same products; only the summation order differs)."""
        xs, cols = self._one
        z = [xi - ai for xi, ai in zip(x, xs, strict=True)]
        g = [gk * zi for gk in self._mix.posterior_one(x) for zi in z]  # (K n,)
        return np.array([sum(map(mul, g, col)) for col in cols])

    def lyapunov(self, X: npt.ArrayLike) -> FloatArray:
        """``V(x) = (x - x*)^T P (x - x*)``.

        Parameters
        ----------
        X : array_like, shape (N, n) or (n,)

        Returns
        -------
        ndarray, shape (N,) or ()
        """
        Xa, single = self._states(X)
        Z = Xa - self.attractor
        V = np.einsum("ni,ij,nj->n", Z, self.P, Z)
        return V[0] if single else V


@dataclass(frozen=True, slots=True)
class FitInfo:
    """How an LPV-DS was learned (stored in the model file's ``fit`` field).

    Attributes
    ----------
    clustering : str
        ``"pc-gmm"`` (method) or ``"em-bic"`` (baseline).
    lyapunov : str
        ``"p-qlf"`` (P learned) or ``"identity"`` (P = I).
    n_components : int
        K.
    eps : float
        LMI margin of the A-fit.
    rate : float
        Decay rate imposed by the A-fit (``A_k^T P + P A_k <= -rate P``); 0 for none.
    control_dt : float or None
        Control period of the sampled-data constraint (None: continuous-time only).
    seed : int
        Seed of the clustering.
    solver : str
        Solver of the SDPs.
    status : str
        Status of the last SDP (always ``"optimal"``).
    seconds : float
        Total learning time.
    n_samples : int
        Number of training samples.
    rate_budget : float or None
        Accuracy budget of the rate choice (None: the rate was given or the fixed factor).
    reference_rmse : float or None
        With a budget: training velocity RMSE of the rate-0 fit.
    rate_rmse : float or None
        With a budget: training velocity RMSE of the fit at ``rate``.
    data_rate : float or None
        With a budget: :func:`~tli_verify.ds.lyapunov.data_rate` of the data (the grid's top).
    rate_within_budget : bool or None
        With a budget: False when even the grid's smallest rate costs more than the budget
        (that rate is kept; see :class:`~tli_verify.ds.lyapunov.RateChoice`).
    blocks : tuple of tuple of int
        Groups of coordinates the ``A_k`` keep decoupled (empty: every entry free;
        :func:`~tli_verify.ds.lyapunov.block_structure`).
    """

    clustering: str
    lyapunov: str
    n_components: int
    eps: float
    rate: float
    control_dt: float | None
    seed: int
    solver: str
    status: str
    seconds: float
    n_samples: int
    rate_budget: float | None = None
    reference_rmse: float | None = None
    rate_rmse: float | None = None
    data_rate: float | None = None
    rate_within_budget: bool | None = None
    blocks: tuple[tuple[int, ...], ...] = ()


def learn_lpvds(
    X: npt.ArrayLike,
    dX: npt.ArrayLike,
    attractor: npt.ArrayLike,
    *,
    seed: int = 0,
    eps: float = 1e-3,
    rate: float | None = None,
    rate_budget: float | None = None,
    control_dt: float | None = DEFAULT_DT_FLOAT,
    clustering: Clustering = "pc-gmm",
    lyapunov: LyapunovKind = "p-qlf",
    max_components: int = 12,
    blocks: Sequence[Sequence[int]] = (),
) -> tuple[LPVDS, FitInfo]:
    """Learn a Lyapunov-stable LPV-DS from position/velocity samples (paper Sec. 4.3).

    Parameters
    ----------
    X : array_like, shape (N, n)
        Positions.
    dX : array_like, shape (N, n)
        Velocities.
    attractor : array_like, shape (n,)
        ``x*`` (:mod:`tli_verify.segmentation`: inside the next mode's region).
    seed : int, optional
        Seed of the clustering; same seed, same model.
    eps : float, optional
        Margin of ``A_k^T P + P A_k <= -eps I``.
    rate : float, optional
        Decay rate of ``V`` to impose, ``A_k^T P + P A_k <= -(eps I + rate P)`` (1/time);
        given, it is forced (``rate_budget`` is ignored). Default (None): chosen under
        ``rate_budget``, or without one ``RATE_FACTOR * data_rate(X, dX, attractor)``
        (:mod:`tli_verify.ds.lyapunov`). ``0``: the plain ``eps`` margin, without the
        sampled-data constraint (the earlier margin-only learner).
    rate_budget : float, optional
        With ``rate`` None: choose the rate by :func:`~tli_verify.ds.lyapunov.choose_rate`,
        the largest grid rate whose fit's training velocity RMSE is within
        ``1 + rate_budget`` of the rate-0 fit's (e.g. ``RATE_BUDGET = 0.03``; needs
        ``eps > 0``). The choice is recorded in :class:`FitInfo`. None (default here): the
        fixed factor.
    control_dt : float, optional
        With ``rate > 0``: impose the sampled-data form at this control period
        (:func:`~tli_verify.ds.lyapunov.fit_a`), which also certifies every shorter period.
        None: continuous time only.
    clustering : {"pc-gmm", "em-bic"}, optional
        Mixing model: the Bayesian non-parametric physically-consistent GMM, or the EM+BIC baseline.
    lyapunov : {"p-qlf", "identity"}, optional
        Learn ``P`` (convex P-QLF) or fix ``P = I`` (baseline).
    max_components : int, optional
        Upper bound on K.
    blocks : sequence of sequence of int, optional
        Groups of coordinates whose dynamics the ``A_k`` keep decoupled: entry ``(r, c)`` is 0
        unless ``r`` and ``c`` lie in the same group (the coordinates in no group form one
        more); e.g. ``[[3, 4, 5]]`` for a pose state's orientation. The mixing weights still
        see the whole state, and the certificate (each ``A_k`` with the one ``P``) is
        unchanged. Default: every entry free.

    Returns
    -------
    ds : LPVDS
    info : FitInfo

    Raises
    ------
    SolverError
        When an SDP does not reach status ``optimal``.
    ModelError
        When the data cannot define a mixture (too few samples, NaN).
    """
    from threadpoolctl import threadpool_limits

    start = time.perf_counter()
    # small matrices: multi-threaded BLAS and OpenMP (k-means) only add contention: 20x
    # slower on a busy machine (k-means init 0.3 s with 2 OpenMP threads, 0.01 s with one)
    with threadpool_limits(limits=1):
        ds, fit = _learn(X, dX, attractor, seed=seed, eps=eps, rate=rate,
                         rate_budget=rate_budget, control_dt=control_dt,
                         clustering=clustering, lyapunov=lyapunov,
                         max_components=max_components, blocks=blocks)
    return ds, dataclasses.replace(fit, seconds=time.perf_counter() - start)


def _learn(X: npt.ArrayLike, dX: npt.ArrayLike, attractor: npt.ArrayLike, *, seed: int,
           eps: float, rate: float | None, rate_budget: float | None,
           control_dt: float | None, clustering: str, lyapunov: str,
           max_components: int, blocks: Sequence[Sequence[int]] = ()
           ) -> tuple[LPVDS, FitInfo]:

    start = time.perf_counter()
    Xa = np.asarray(X, dtype=np.float64)
    dXa = np.asarray(dX, dtype=np.float64)
    xs = np.asarray(attractor, dtype=np.float64)
    if Xa.ndim != 2 or dXa.shape != Xa.shape or xs.shape != (Xa.shape[1],):
        raise ModelError(f"learning data shapes do not match: X {Xa.shape}, dX {dXa.shape}, "
                         f"attractor {xs.shape}")
    groups = tuple(tuple(int(c) for c in g) for g in blocks)
    structure = block_structure(Xa.shape[1], groups) if groups else None
    chooser = rate_budget if rate is None else None  # a given rate is forced
    if chooser is not None and not (np.isfinite(chooser) and chooser >= 0.0):
        raise ModelError(f"rate budget must be finite and >= 0, got {chooser}")
    if chooser is not None and not eps > 0.0:
        raise ModelError(f"the rate choice needs eps > 0 (its rate-0 reference fit), got {eps}")
    if clustering == "pc-gmm":
        mix = fit_pcgmm(Xa, dXa, seed=seed, max_components=max_components)
    elif clustering == "em-bic":
        mix = fit_em_bic(Xa, seed=seed, max_components=max_components)
    else:
        raise ModelError(f"unknown clustering {clustering!r}")
    if lyapunov == "p-qlf":
        P, _ = estimate_p(Xa, dXa, xs)
    elif lyapunov == "identity":
        P = np.eye(Xa.shape[1])
    else:
        raise ModelError(f"unknown Lyapunov option {lyapunov!r}")
    gamma = mix.posterior(Xa)
    budget: float | None = None  # the rate choice's record (FitInfo), with a budget only
    reference: float | None = None
    error: float | None = None
    own: float | None = None
    within: bool | None = None
    if chooser is not None:
        choice = choose_rate(Xa, dXa, gamma, xs, P, eps=eps, dt=control_dt, budget=chooser,
                             structure=structure)
        lam, A, info = choice.rate, choice.A, choice.info
        dt = control_dt if lam > 0.0 else None  # rate 0 only when the data do not move
        budget, reference, error = choice.budget, choice.reference_rmse, choice.rmse
        own, within = choice.data_rate, choice.within_budget
    else:
        lam = RATE_FACTOR * data_rate(Xa, dXa, xs) if rate is None else float(rate)
        if not (np.isfinite(lam) and lam >= 0.0):
            raise ModelError(f"decay rate must be finite and >= 0, got {lam}")
        dt = control_dt if lam > 0.0 else None
        A, info = fit_a(Xa, dXa, gamma, xs, P, eps=eps, rate=lam, dt=dt, structure=structure)
    ds = LPVDS(attractor=xs, priors=mix.priors, means=mix.means, covs=mix.covs, A=A, P=P)
    fit = FitInfo(clustering=clustering, lyapunov=lyapunov, n_components=mix.n_components,
                  eps=float(eps), rate=lam, control_dt=None if dt is None else float(dt),
                  seed=int(seed), solver=SOLVER, status=info.status,
                  seconds=time.perf_counter() - start, n_samples=int(Xa.shape[0]),
                  rate_budget=budget, reference_rmse=reference, rate_rmse=error, data_rate=own,
                  rate_within_budget=within, blocks=groups)
    return ds, fit
