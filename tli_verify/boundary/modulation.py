"""DS modulation by cutting planes (paper Sec. 5.2, eq. 5, Thm. 1 and its proof in appendix A).

Notation: attractor ``x*``, cuts ``i = 1..m`` with unit outward normal ``w_i`` through ``p_i``,
offset ``h_i = w_i . (p_i - x*)`` (``h_i > 0``: ``x*`` strictly inside; ``h_i = 0``: the plane
holds ``x*``, a *degenerate* cut; ``h_i < 0`` is rejected), nominal velocity ``f = f(x)``.

Regular cuts (``h_i > 0``), exactly paper eq. 5 with reference point ``x^r = x*``::

    Gamma_i(x) = w_i . (x - x*) / h_i          (0 at x*, 1 on the plane, > 1 beyond it)
    Gamma(x)   = max(0, max_i Gamma_i(x))      (the max with 0 keeps lambda_r <= 1, see below)
    a          = argmax_i Gamma_i(x)            (the "closest" cut: grad Gamma = w_a / h_a)
    E = [r, e_1 .. e_{n-1}],  r = (x - x*) / ||x - x*||,  e_j an orthonormal basis of w_a^perp
    D = diag(1 - Gamma, 1, .., 1),  M = E D E^-1

``M f`` is applied only inside the cuts (``0 < Gamma <= 1``) and only when the flow points
outward, ``[E^-1 f]_1 >= 0``; elsewhere ``M = I`` (paper Sec. 5.2). Because the ``e_j`` are
orthogonal to ``w_a``, ``w_a . f = [E^-1 f]_1 (w_a . r)`` and ``w_a . r = Gamma h_a / ||x-x*||
> 0``, so the test is ``w_a . f >= 0`` and the product collapses to a closed form (used by the
vectorised code; :func:`modulate_reference` builds ``E`` and ``D`` literally, point by point)::

    M f = f - Gamma [E^-1 f]_1 r = f - (w_a . f / h_a) (x - x*)

On the plane (``Gamma = 1``) the normal component ``w_a . M f = (1 - Gamma) w_a . f`` is zero,
and ``dV/dt`` changes by ``-2 (w_a . f / h_a) V(x) <= 0`` (Thm. 1's proof). Outside every cut's
reach (``Gamma_i <= 0`` for all i, i.e. ``x`` behind ``x*``) ``M = I``: this is why ``Gamma`` is
clipped at 0 -- a negative ``Gamma`` would give ``lambda_r > 1`` and amplify an outward flow.

Degenerate cuts (``h_i = 0``, the plane holds ``x*``). The cut QCQP (appendix F) minimises the
plane's distance to ``x*``, so its optimum is often exactly such a plane. Eq. 5 cannot handle
it: ``r`` lies in the plane there, so ``E`` is singular and radial scaling cannot remove a
normal velocity. We keep the structure ``M = E D E^-1`` with ``D = diag(1 - Gamma_i, 1, .., 1)``
and the tangent basis of the cut, and replace the reference direction ``r`` by the direction
that leaves ``V(x) = (x - x*)^T P (x - x*)`` unchanged (``P`` is the DS's Lyapunov matrix,
keyword ``lyapunov``; identity by default, e.g. for BC)::

    sigma    = -w . (x - x*) >= 0 (depth inside),   V = (x - x*)^T P (x - x*),   q = w^T P^-1 w
    v(x)     = P^-1 w + (sigma / V) (x - x*)        (grad V . v = 0,  w . v = q - sigma^2 / V)
    Gamma_i  = 1 - sign(sigma) sigma^2 / (q V)      (1 on the plane, in [0, 1] inside, > 1 out)
    M f      = f - Gamma_i [E^-1 f]_1 v = f - (w . f / q) v        (when 0 < Gamma_i <= 1, w.f >= 0)

By Cauchy-Schwarz in the ``P`` metric ``sigma^2 <= q V``, so ``w . v = q Gamma_i >= 0``. The
normal component is again scaled by ``1 - Gamma_i`` (zero on the plane) and ``dV/dt`` is
*unchanged*, so Thm. 1's conclusions hold (no crossing, V decreases at least as fast, G.A.S.).
A cut counts as degenerate when ``|h_i| <= 1e-9 max(1, ||p_i - x*||)``.

At ``x = x*`` the reference direction is undefined and ``M = I`` (for a DS, ``f(x*) = 0``).

References
----------
.. [1] Wang et al., "Temporal Logic Imitation", CoRL 2022: Sec. 5.2, eq. 5, Thm. 1, appendix A.
.. [2] Khansari-Zadeh, Billard, "A dynamical system approach to realtime obstacle avoidance",
   Autonomous Robots 2012; Huber, Billard, Slotine, "Avoidance of convex and concave obstacles
   with convergence ensured through contraction", RA-L 2019.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from tli_verify.boundary.cuts import Cut
from tli_verify.errors import ModelError

__all__ = [
    "ModulatedPolicy",
    "Modulator",
    "StatePolicy",
    "gamma",
    "modulate",
    "modulate_reference",
    "modulated",
    "modulation_matrix",
]

FloatArray = npt.NDArray[np.float64]

DEGENERATE_TOL = 1e-9
"""Relative tolerance below which ``h_i = w_i . (p_i - x*)`` counts as 0 (a degenerate cut)."""

BOUNDARY_TOL = 1e-9
"""States with ``Gamma <= 1 + BOUNDARY_TOL`` count as inside (rounding on the plane)."""


@runtime_checkable
class StatePolicy(Protocol):
    """Anything with a vectorised ``velocity(X: (N, n)) -> (N, n)`` (LPV-DS, BC, ...)."""

    def velocity(self, X: npt.ArrayLike) -> FloatArray:  # pragma: no cover - protocol
        """Velocities, shape (N, n)."""
        ...


@dataclass(frozen=True, slots=True, eq=False)
class Modulator:
    """Precomputed cut data for fast repeated modulation (see the module docstring).

    Attributes
    ----------
    attractor : ndarray, shape (n,)
    W : ndarray, shape (m, n)
        Cut normals.
    h : ndarray, shape (m,)
        Offsets ``w_i . (p_i - x*)`` (0 for degenerate cuts).
    degenerate : ndarray of bool, shape (m,)
    P : ndarray, shape (n, n)
        Lyapunov matrix used for degenerate cuts.
    PinvW : ndarray, shape (m, n)
        ``P^-1 w_i``.
    q : ndarray, shape (m,)
        ``w_i^T P^-1 w_i``.
    """

    attractor: FloatArray
    W: FloatArray
    h: FloatArray
    degenerate: npt.NDArray[np.bool_]
    P: FloatArray
    PinvW: FloatArray
    q: FloatArray

    @classmethod
    def build(
        cls,
        cuts: Sequence[Cut],
        attractor: npt.ArrayLike,
        *,
        lyapunov: npt.ArrayLike | None = None,
    ) -> Modulator:
        """Validate the cuts against ``x*`` and precompute.

        Parameters
        ----------
        cuts : sequence of Cut
        attractor : array_like, shape (n,)
        lyapunov : array_like, shape (n, n), optional
            ``P`` of ``V(x) = (x-x*)^T P (x-x*)``; symmetric positive definite. Identity if
            omitted. Only degenerate cuts use it.

        Raises
        ------
        ModelError
            On dimension mismatch, a non-SPD ``P``, or a cut that leaves ``x*`` outside.
        """
        x_star = np.array(attractor, dtype=np.float64)
        if x_star.ndim != 1 or x_star.size < 2 or not np.all(np.isfinite(x_star)):
            raise ModelError(f"attractor must be a finite vector of dimension >= 2, "
                             f"got shape {x_star.shape}")
        n = x_star.size
        for i, c in enumerate(cuts):
            if not isinstance(c, Cut):
                raise ModelError(f"cuts[{i}] is not a Cut")
            if c.dim != n:
                raise ModelError(f"cuts[{i}] has dimension {c.dim}, attractor has {n}")
        if lyapunov is None:
            P = np.eye(n)
        else:
            P = np.array(lyapunov, dtype=np.float64)
            if P.shape != (n, n) or not np.all(np.isfinite(P)):
                raise ModelError(f"lyapunov matrix must be a finite ({n}, {n}) array")
            if not np.allclose(P, P.T, rtol=1e-10, atol=1e-12 * float(np.max(np.abs(P)))):
                raise ModelError("lyapunov matrix must be symmetric")
            P = 0.5 * (P + P.T)
            try:
                np.linalg.cholesky(P)
            except np.linalg.LinAlgError:
                raise ModelError("lyapunov matrix must be positive definite") from None
        m = len(cuts)
        W = np.array([c.normal for c in cuts], dtype=np.float64).reshape(m, n)
        pts = np.array([c.point for c in cuts], dtype=np.float64).reshape(m, n)
        h = np.einsum("ij,ij->i", W, pts - x_star)
        scale = np.maximum(1.0, np.linalg.norm(pts - x_star, axis=1))
        degenerate = np.abs(h) <= DEGENERATE_TOL * scale
        bad = (~degenerate) & (h < 0)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise ModelError(
                f"cuts[{i}] leaves the attractor outside (w . (p - x*) = {h[i]:.6g} < 0); "
                "modulation needs x* inside or on every cut (paper Thm. 1)"
            )
        h = np.where(degenerate, 0.0, h)
        PinvW: FloatArray = (np.asarray(np.linalg.solve(P, W.T).T, dtype=np.float64) if m
                             else np.zeros((0, n)))
        q = np.einsum("ij,ij->i", W, PinvW)
        for arr in (x_star, W, h, degenerate, P, PinvW, q):
            arr.setflags(write=False)
        return cls(attractor=x_star, W=W, h=h, degenerate=degenerate, P=P, PinvW=PinvW, q=q)

    @property
    def dim(self) -> int:
        """State dimension ``n``."""
        return int(self.attractor.size)

    def _check(self, X: npt.ArrayLike, name: str) -> FloatArray:
        Xa = np.asarray(X, dtype=np.float64)
        if Xa.ndim != 2 or Xa.shape[1] != self.dim:
            raise ModelError(f"{name} must have shape (N, {self.dim}), got {Xa.shape}")
        return Xa

    def _gammas(self, D: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray | None]:
        """Per-cut ``Gamma_i`` (N, m), ``S = w_i . (x - x*)`` (N, m) and ``V`` (N,) or None."""
        S = D @ self.W.T
        if not self.degenerate.any():
            return S / self.h, S, None
        V = np.einsum("ni,ij,nj->n", D, self.P, D)
        G = np.empty_like(S)
        reg = ~self.degenerate
        G[:, reg] = S[:, reg] / self.h[reg]
        Sd = S[:, self.degenerate]
        with np.errstate(divide="ignore", invalid="ignore"):
            Gd = 1.0 + Sd * np.abs(Sd) / (self.q[self.degenerate] * V[:, None])
        G[:, self.degenerate] = np.where(V[:, None] > 0.0, Gd, 0.0)
        return G, S, V

    def gamma(self, X: npt.ArrayLike) -> FloatArray:
        """``Gamma(x) = max(0, max_i Gamma_i(x))``; <1 inside, 1 on, >1 outside the cuts.

        Parameters
        ----------
        X : array_like, shape (N, n)

        Returns
        -------
        ndarray, shape (N,)
            Zeros when there are no cuts.
        """
        Xa = self._check(X, "X")
        if self.W.shape[0] == 0:
            return np.zeros(Xa.shape[0])
        G, _, _ = self._gammas(Xa - self.attractor)
        return np.maximum(np.max(G, axis=1), 0.0)

    def __call__(self, X: npt.ArrayLike, F: npt.ArrayLike) -> FloatArray:
        """Modulated velocities ``M(x) f(x)``, vectorised over N (see the module docstring).

        Parameters
        ----------
        X : array_like, shape (N, n)
            States.
        F : array_like, shape (N, n)
            Nominal velocities ``f(x)`` at those states.

        Returns
        -------
        ndarray, shape (N, n)
        """
        Xa = self._check(X, "X")
        Fa = self._check(F, "F")
        if Fa.shape[0] != Xa.shape[0]:
            raise ModelError(f"X has {Xa.shape[0]} rows but F has {Fa.shape[0]}")
        m = self.W.shape[0]
        if m == 0 or Xa.shape[0] == 0:
            return Fa.copy()
        D = Xa - self.attractor
        G, S, V = self._gammas(D)
        rows = np.arange(Xa.shape[0])
        a = np.argmax(G, axis=1)
        g = G[rows, a]
        wf = np.einsum("ni,ni->n", self.W[a], Fa)
        active = (g > 0.0) & (g <= 1.0 + BOUNDARY_TOL) & (wf > 0.0)
        if V is None:
            coef = np.where(active, wf / self.h[a], 0.0)
            return Fa - coef[:, None] * D
        deg_a = self.degenerate[a]
        reg_act = active & ~deg_a
        deg_act = active & deg_a
        with np.errstate(divide="ignore", invalid="ignore"):
            coef = np.where(reg_act, wf / np.where(deg_a, 1.0, self.h[a]), 0.0)
            out = Fa - coef[:, None] * D
            cq = np.where(deg_act, wf / self.q[a], 0.0)
            radial = np.where(deg_act, -S[rows, a] / np.where(V > 0.0, V, 1.0), 0.0)
        out -= cq[:, None] * self.PinvW[a] + (cq * radial)[:, None] * D
        return out


def gamma(
    X: npt.ArrayLike,
    cuts: Sequence[Cut],
    attractor: npt.ArrayLike,
    *,
    lyapunov: npt.ArrayLike | None = None,
) -> FloatArray:
    """``Gamma(x)`` of paper Sec. 5.2 for the given cuts (see :meth:`Modulator.gamma`).

    Parameters
    ----------
    X : array_like, shape (N, n)
    cuts : sequence of Cut
    attractor : array_like, shape (n,)
    lyapunov : array_like, shape (n, n), optional

    Returns
    -------
    ndarray, shape (N,)
    """
    return Modulator.build(cuts, attractor, lyapunov=lyapunov).gamma(X)


def modulate(
    X: npt.ArrayLike,
    F: npt.ArrayLike,
    cuts: Sequence[Cut],
    attractor: npt.ArrayLike,
    *,
    lyapunov: npt.ArrayLike | None = None,
) -> FloatArray:
    """Modulate nominal velocities by the cuts (paper eq. 5), vectorised over N.

    Parameters
    ----------
    X : array_like, shape (N, n)
        States, any ``n >= 2``.
    F : array_like, shape (N, n)
        Nominal velocities ``f(X)`` (of an LPV-DS, a BC network, ...).
    cuts : sequence of Cut
        The mode's cuts; each must keep ``x*`` inside or on its plane.
    attractor : array_like, shape (n,)
        ``x*``, the reference point ``x^r`` of eq. 5.
    lyapunov : array_like, shape (n, n), optional
        The DS's ``P``; only degenerate cuts (through ``x*``) use it. Identity if omitted.

    Returns
    -------
    ndarray, shape (N, n)
        ``M(x) f(x)`` where modulation applies, ``f(x)`` elsewhere.

    Raises
    ------
    ModelError
        On shape mismatch or a cut that leaves ``x*`` outside.

    References
    ----------
    Paper Sec. 5.2, eq. 5; Thm. 1 (appendix A).
    """
    return Modulator.build(cuts, attractor, lyapunov=lyapunov)(X, F)


def _tangent_basis(w: FloatArray) -> FloatArray:
    """Orthonormal basis of ``w^perp``, shape (n, n-1)."""
    _, _, vt = np.linalg.svd(w[None, :])
    return np.asarray(vt[1:].T)


def modulation_matrix(
    x: npt.ArrayLike,
    cuts: Sequence[Cut],
    attractor: npt.ArrayLike,
    *,
    lyapunov: npt.ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray, float, int]:
    """Literal eq. 5 at one state: ``E``, ``M = E D E^-1``, ``Gamma`` and the closest cut.

    Parameters
    ----------
    x : array_like, shape (n,)
    cuts : sequence of Cut
        At least one cut.
    attractor : array_like, shape (n,)
    lyapunov : array_like, shape (n, n), optional

    Returns
    -------
    E : ndarray, shape (n, n)
        ``[r, e_1 .. e_{n-1}]`` (``r`` replaced by ``v`` for a degenerate closest cut).
    M : ndarray, shape (n, n)
    Gamma : float
    closest : int
        Index of the cut with the largest ``Gamma_i``.
    """
    mod = Modulator.build(cuts, attractor, lyapunov=lyapunov)
    if mod.W.shape[0] == 0:
        raise ModelError("modulation_matrix needs at least one cut")
    xa = np.array(x, dtype=np.float64)
    d = xa - mod.attractor
    G, S, _ = mod._gammas(d[None, :])
    a = int(np.argmax(G[0]))
    g = max(float(G[0, a]), 0.0)
    w = mod.W[a]
    if mod.degenerate[a]:
        v_val = float(d @ mod.P @ d)
        sigma = -float(S[0, a])
        r = mod.PinvW[a] + (sigma / v_val) * d if v_val > 0 else mod.PinvW[a].copy()
    else:
        nd = float(np.linalg.norm(d))
        r = d / nd if nd > 0 else w.copy()
    E = np.column_stack([r, _tangent_basis(w)])
    Dm = np.diag(np.r_[1.0 - g, np.ones(mod.dim - 1)])
    M = E @ Dm @ np.linalg.inv(E)
    return E, M, g, a


def modulate_reference(
    X: npt.ArrayLike,
    F: npt.ArrayLike,
    cuts: Sequence[Cut],
    attractor: npt.ArrayLike,
    *,
    lyapunov: npt.ArrayLike | None = None,
) -> FloatArray:
    """Straightforward per-point eq. 5 (build ``E``, ``D``, invert, multiply), for checking.

    Same contract as :func:`modulate`; a Python loop over points. Used as the oracle in tests
    and as the baseline of ``benchmarks/bench_modulation.py``.
    """
    Xa = np.asarray(X, dtype=np.float64)
    Fa = np.asarray(F, dtype=np.float64)
    out = Fa.copy()
    if not cuts:
        return out
    x_star = np.asarray(attractor, dtype=np.float64)
    for i in range(Xa.shape[0]):
        if np.array_equal(Xa[i], x_star):
            continue
        E, M, g, _ = modulation_matrix(Xa[i], cuts, x_star, lyapunov=lyapunov)
        if not 0.0 < g <= 1.0 + BOUNDARY_TOL:
            continue
        if np.linalg.solve(E, Fa[i])[0] >= 0.0:
            out[i] = M @ Fa[i]
    return out


@dataclass(frozen=True, slots=True, eq=False)
class ModulatedPolicy:
    """``x -> M(x) f(x)`` around any state-based policy (paper Sec. 5.2, last paragraph).

    Attributes
    ----------
    policy : callable
        Nominal ``f``: maps states (N, n) to velocities (N, n).
    modulator : Modulator
    """

    policy: Callable[[FloatArray], FloatArray]
    modulator: Modulator

    def velocity(self, X: npt.ArrayLike) -> FloatArray:
        """Modulated velocities.

        Parameters
        ----------
        X : array_like, shape (N, n)

        Returns
        -------
        ndarray, shape (N, n)
        """
        Xa = np.asarray(X, dtype=np.float64)
        return self.modulator(Xa, self.policy(Xa))

    def __call__(self, X: npt.ArrayLike) -> FloatArray:
        """Same as :meth:`velocity`."""
        return self.velocity(X)


def modulated(
    policy: StatePolicy | Callable[[FloatArray], FloatArray],
    cuts: Sequence[Cut],
    attractor: npt.ArrayLike,
    *,
    lyapunov: npt.ArrayLike | None = None,
) -> ModulatedPolicy:
    """Wrap a state-based policy so that it never leaves the cuts.

    Parameters
    ----------
    policy : StatePolicy or callable
        An object with ``velocity(X)`` (e.g. :class:`tli_verify.ds.lpvds.LPVDS`,
        :class:`tli_verify.ds.bc.BCPolicy`) or a function ``(N, n) -> (N, n)``.
    cuts : sequence of Cut
    attractor : array_like, shape (n,)
    lyapunov : array_like, shape (n, n), optional
        The policy's Lyapunov matrix if it has one (an LPV-DS's ``P``); Thm. 1 needs it for
        cuts through ``x*``. A policy with an attribute ``P`` supplies it automatically.

    Returns
    -------
    ModulatedPolicy
    """
    if isinstance(policy, StatePolicy):
        fn: Callable[[FloatArray], FloatArray] = policy.velocity
        if lyapunov is None and getattr(policy, "P", None) is not None:
            lyapunov = policy.P  # type: ignore[attr-defined]
    elif callable(policy):
        fn = policy
    else:
        raise ModelError("policy must be callable or have a velocity(X) method")
    return ModulatedPolicy(policy=fn, modulator=Modulator.build(cuts, attractor,
                                                                 lyapunov=lyapunov))
