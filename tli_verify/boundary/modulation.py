"""DS modulation by cutting planes (paper Sec. 5.2, eq. 7, Thm. 1 and its proof in appendix A).

Notation: attractor ``x*``, cuts ``i = 1..m`` with unit outward normal ``w_i`` through ``p_i``,
offset ``h_i = w_i . (p_i - x*)`` (``h_i > 0``: ``x*`` strictly inside; ``h_i = 0``: the plane
holds ``x*``, a *degenerate* cut; ``h_i < 0`` is rejected), nominal velocity ``f = f(x)``.

Regular cuts (``h_i > 0``), exactly paper eq. 7 with reference point ``x^r = x*``::

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

Degenerate cuts (``h_i = 0``, the plane holds ``x*``). The cut QCQP (appendix E.3) minimises the
plane's distance to ``x*``, so its optimum is often exactly such a plane. Eq. 7 cannot handle
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
*unchanged*. On a single cut's face Thm. 1's conclusions hold; at corners see the guard below.
A cut counts as degenerate when ``|h_i| <= 1e-9 max(1, ||p_i - x*||)``.

At ``x = x*`` the reference direction is undefined and ``M = I`` (for a DS, ``f(x*) = 0``).

Corner guard (our extension; it makes Thm. 1 hold for *every* cut set). Eq. 7 handles one cut
at a time: the closest. Where two planes meet it can push the state out through the other one
-- for regular cuts only by an ``O(dt)`` Euler overshoot, but where a cut through ``x*`` meets
another cut the exact flow slides into the corner and out (hypothesis found such a case, kept
in ``tests/unit/test_modulation.py``). So :meth:`Modulator.__call__` keeps eq. 7's velocity
``g = M f`` only if it lies in the admissible set, and otherwise replaces it by its projection in
the ``P`` metric (the least change of ``g``)::

    C(x) = { v :  w_i . v <= rho_i(x) max(b_i(x), 0)   for every cut i that applies at x,
                  grad V(x) . v <= grad V(x) . f(x)            (only with a Lyapunov P) }
    v(x) = g                              if g in C(x)
         = argmin_{v in C(x)} (v - g)^T P (v - g)     otherwise (a small QP, exact: NNLS)

with ``b_i(x) = w_i . (p_i - x)`` the distance to plane ``i``. Cut ``i`` *applies* where the
state is on its inner side or within a rounding band beyond it, ``b_i >= -1e-9 (1 + ||x - x*||
+ h_i)``; in the band its bound is 0. The barrier rate is ``rho_i = max(min(max(kappa, r_i),
100 kappa), t)``: ``kappa`` a floor (``barrier_rate``, 10/s by default), ``r_i`` the rate eq. 7
itself uses for that cut (``(w_i . f)^+ / h_i``, or ``sigma (w_i . f)^+ / (q V)`` for a cut
through ``x*``, so eq. 7 satisfies the row of its closest cut; capped to keep rates bounded) and
``t = (-grad V . f)^+ / V`` (0 at ``x*``). Then:

- ``C(x)`` is never empty: ``v = -t (x - x*)`` satisfies every row (for ``w_i . (x - x*) >= 0``
  the left side is <= 0; otherwise ``t |w_i . (x - x*)| <= rho_i b_i`` because ``b_i >= |w_i .
  (x - x*)|`` and ``t <= rho_i``; and ``grad V . v = -t V <= grad V . f``). The QP answer is
  re-checked against every row; should it fail, this witness is used.
- (a) Let ``x(t)`` be an absolutely continuous solution of ``x' = v(x)`` with ``b_i(x(0)) >=
  0``. While ``b_i > 0`` its row gives ``b_i' >= -rho_i b_i`` with ``rho_i`` bounded (LPV-DS:
  ``t`` is bounded by the largest contraction rate), so ``b_i`` cannot reach 0 in finite time;
  and on the band ``b_i <= 0`` the row gives ``b_i' >= 0``. So ``b_i`` never becomes negative:
  no trajectory crosses a cut it starts on the inner side of -- in particular none leaves the
  region bounded by all cuts -- and at a face or corner no velocity points out through any of
  its planes. (Existence of solutions of this discontinuous field is not claimed; the sampled-
  data version below needs none.)
- (b) ``dV/dt`` at every state is at most that of ``f`` at the same state (last row); for a
  certified LPV-DS, ``dV/dt <= -lambda V`` with its certified rate ``lambda``, so (c) every
  trajectory still converges to ``x*`` at least at that exponential rate.
- Sampled data: with the control period ``dt`` (``__call__(..., dt=)``) every rate is ``1/dt``
  -- the rows say "no step past a plane": ``b_i(x + dt v) = b_i(x) - dt w_i . v >= 0`` up to
  rounding, and a state in the band cannot move further out -- and the last row is relaxed to
  ``grad V . v <= max(grad V . f, -V/dt)`` (the witness then has ``t = min(t, 1/dt)``). Eq. 7's
  radial coefficient ``w_a . f / h_a`` is also capped at ``1/dt``: near a cut with a tiny
  offset ``h_a`` it is huge, and one step of it would carry the state far past ``x*``. So no
  explicit Euler step crosses a cut. This is what a control loop (and the single-mode study)
  uses; ``V`` itself may still grow over one step if ``dt`` is too long for ``f``, as for any
  Euler discretisation.

Where eq. 7's answer is admissible the guard changes nothing: with ``dt``, wherever the next
step stays inside every cut that applies; in continuous time, wherever the outward speed towards
each plane but the closest is below ``kappa`` times the distance to it (a braking distance, not
only at corners). A vectorised screen finds the states that may need the projection.

References
----------
.. [1] Wang et al., "Temporal Logic Imitation", CoRL 2022: Sec. 5.2, eq. 7, Thm. 1, appendix A.
.. [2] Khansari-Zadeh, Billard, "A dynamical system approach to realtime obstacle avoidance",
   Autonomous Robots 2012; Huber, Billard, Slotine, "Avoidance of convex and concave obstacles
   with convergence ensured through contraction", RA-L 2019.
.. [3] Ames et al., "Control barrier functions: theory and applications", ECC 2019 (the rows
   of ``C(x)`` are exponential barrier conditions); Lawson, Hanson, *Solving Least Squares
   Problems*, 1974, ch. 23 (least-distance programming by NNLS).
"""

from __future__ import annotations

import itertools
import math
import numbers
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from tli_verify.boundary.cuts import Cut
from tli_verify.errors import ModelError, SolverError

__all__ = [
    "ModulatedPolicy",
    "Modulator",
    "StatePolicy",
    "check_control_period",
    "gamma",
    "modulate",
    "modulate_reference",
    "modulated",
    "modulation_matrix",
]

FloatArray = npt.NDArray[np.float64]

DEFAULT_BARRIER_RATE = 10.0
"""Least barrier rate ``kappa`` (1/s) of the continuous-time corner guard (module docstring)."""

DEGENERATE_TOL = 1e-9
"""Relative tolerance below which ``h_i = w_i . (p_i - x*)`` counts as 0 (a degenerate cut)."""

BOUNDARY_TOL = 1e-9
"""States with ``Gamma <= 1 + BOUNDARY_TOL`` count as inside (rounding on the plane)."""

RATE_CAP = 100.0
"""Continuous time: the barrier rates eq. 7 asks for are capped at ``RATE_CAP * kappa`` (a bounded
rate is what the invariance argument needs; it matters only for cuts through ``x*`` next to
``x*`` with a policy that does not vanish there, e.g. BC)."""

GUARD_TOL = 1e-12
"""Relative slack before the corner guard treats an eq. 7 velocity as inadmissible."""


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
    certified: bool = False
    metric: FloatArray | None = None
    barrier_rate: float = DEFAULT_BARRIER_RATE

    @classmethod
    def build(
        cls,
        cuts: Sequence[Cut],
        attractor: npt.ArrayLike,
        *,
        lyapunov: npt.ArrayLike | None = None,
        barrier_rate: float = DEFAULT_BARRIER_RATE,
    ) -> Modulator:
        """Validate the cuts against ``x*`` and precompute.

        Parameters
        ----------
        cuts : sequence of Cut
        attractor : array_like, shape (n,)
        lyapunov : array_like, shape (n, n), optional
            ``P`` of ``V(x) = (x-x*)^T P (x-x*)``; symmetric positive definite. Identity if
            omitted. Degenerate cuts use it, and when it is given the corner guard also keeps
            ``dV/dt`` at most that of the nominal flow (Thm. 1 (b)).
        barrier_rate : float, optional
            The least barrier rate ``kappa`` of the continuous-time corner guard, in 1/s (see
            the module docstring; with a control period ``dt`` the rate is ``1/dt``). Larger
            values leave more of eq. 7 untouched and let the flow approach a face faster; any
            positive value keeps Thm. 1.

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
        if (isinstance(barrier_rate, bool) or not isinstance(barrier_rate, numbers.Real)
                or not (np.isfinite(barrier_rate) and barrier_rate > 0)):
            raise ModelError(f"barrier_rate must be a positive number, got {barrier_rate!r}")
        cuts = list(cuts)
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
        metric = np.asarray(np.linalg.inv(np.linalg.cholesky(P)).T, dtype=np.float64)
        for arr in (x_star, W, h, degenerate, P, PinvW, q, metric):
            arr.setflags(write=False)
        return cls(attractor=x_star, W=W, h=h, degenerate=degenerate, P=P, PinvW=PinvW, q=q,
                   certified=lyapunov is not None, metric=metric,
                   barrier_rate=float(barrier_rate))

    @property
    def dim(self) -> int:
        """State dimension ``n``."""
        return int(self.attractor.size)

    def _check(self, X: npt.ArrayLike, name: str) -> FloatArray:
        Xa = np.asarray(X, dtype=np.float64)
        if Xa.ndim != 2 or Xa.shape[1] != self.dim:
            raise ModelError(f"{name} must have shape (N, {self.dim}), got {Xa.shape}")
        if not np.isfinite(Xa).all():
            raise ModelError(f"{name} has a NaN or infinite entry")
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

    def eq5(self, X: npt.ArrayLike, F: npt.ArrayLike) -> FloatArray:
        """Paper eq. 7 alone, ``M(x) f(x)`` by the closest cut, vectorised over N.

        This is the modulation the paper defines (and :func:`modulate_reference` builds
        literally); :meth:`__call__` adds the corner guard on top of it.

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
        return self._eq5(*self._pair(X, F))[0]

    def _pair(self, X: npt.ArrayLike, F: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        Xa = self._check(X, "X")
        Fa = self._check(F, "F")
        if Fa.shape[0] != Xa.shape[0]:
            raise ModelError(f"X has {Xa.shape[0]} rows but F has {Fa.shape[0]}")
        return Xa, Fa

    def _eq5(self, Xa: FloatArray, Fa: FloatArray, dt: float | None = None
             ) -> tuple[FloatArray, FloatArray | None, FloatArray | None]:
        """Eq. 7 on checked arrays: ``(M f, X - x*, S = (X - x*) W^T)`` (None, None: no cuts).

        With a control period ``dt`` the radial coefficient ``w_a . f / h_a`` is capped at
        ``1 / dt``: one step of the correction never carries the state past ``x*`` (it would
        near a cut with a tiny offset ``h_a``, where eq. 7's correction is ``|f| |x - x*| / h_a``).
        """
        m = self.W.shape[0]
        if m == 0 or Xa.shape[0] == 0:
            return Fa.copy(), None, None
        D = Xa - self.attractor
        G, S, V = self._gammas(D)
        rows = np.arange(Xa.shape[0])
        a = np.argmax(G, axis=1)
        g = G[rows, a]
        wf = np.einsum("ni,ni->n", self.W[a], Fa)
        active = (g > 0.0) & (g <= 1.0 + BOUNDARY_TOL) & (wf > 0.0)
        cap = np.inf if dt is None else 1.0 / dt
        if V is None:
            coef = np.where(active, np.minimum(wf / self.h[a], cap), 0.0)
            return Fa - coef[:, None] * D, D, S
        deg_a = self.degenerate[a]
        reg_act = active & ~deg_a
        deg_act = active & deg_a
        with np.errstate(divide="ignore", invalid="ignore"):
            coef = np.where(reg_act, np.minimum(wf / np.where(deg_a, 1.0, self.h[a]), cap),
                            0.0)
            out = Fa - coef[:, None] * D
            cq = np.where(deg_act, wf / self.q[a], 0.0)
            radial = np.where(deg_act, -S[rows, a] / np.where(V > 0.0, V, 1.0), 0.0)
        out -= cq[:, None] * self.PinvW[a] + (cq * radial)[:, None] * D
        return out, D, S

    def __call__(self, X: npt.ArrayLike, F: npt.ArrayLike, *,
                 dt: float | None = None) -> FloatArray:
        """Modulated velocities: eq. 7 (:meth:`eq5`) with the corner guard, vectorised over N.

        Parameters
        ----------
        X, F : array_like, shape (N, n)
            States and the nominal velocities ``f(x)`` there, as for :meth:`eq5`.
        dt : float, optional
            Control period of a sampled-data loop that holds the velocity for ``dt`` (explicit
            Euler). With it every barrier rate is ``1 / dt``, so that no step ``x + dt v``
            crosses a cut either. Omit for the continuous-time field.

        Returns
        -------
        ndarray, shape (N, n)
            A velocity in the admissible set ``C(x)`` (module docstring): eq. 7's where that
            is admissible (inside the cuts), ``f(x)`` where no cut applies.
        """
        check_control_period(dt)
        Xa, Fa = self._pair(X, F)
        out, D, S = self._eq5(Xa, Fa, dt)
        if D is None or S is None:
            return out
        # Screen (cheap, conservative): a row can only be violated where w_i . v exceeds
        # kappa b_i (continuous time, rho_i >= kappa) or b_i / dt (sampled data). The Lyapunov
        # row needs no screen: eq. 7 never raises dV/dt (Thm. 1 (b)).
        B = self.h - S
        rate = self.barrier_rate if dt is None else 1.0 / dt
        near = out @ self.W.T > rate * np.maximum(B, 0.0)
        if near.any():
            cand = np.flatnonzero((near & self._applies(D, B)).any(axis=1))
            if cand.size:
                out[cand] = self._guard(Xa[cand], Fa[cand], out[cand], dt)
        return out

    def _applies(self, D: FloatArray, B: FloatArray) -> npt.NDArray[np.bool_]:
        """Which rows apply: states on the inner side of each plane, or within the rounding
        band ``b_i >= -1e-9 (1 + ||x - x*|| + h_i)`` beyond it, (N, m). In the band the row's
        bound is 0, so the state cannot drift further out (module docstring)."""
        nd = np.sqrt(np.einsum("ni,ni->n", D, D))
        return B >= -BOUNDARY_TOL * (1.0 + nd[:, None] + self.h[None, :])

    def admissible(self, X: npt.ArrayLike, F: npt.ArrayLike, *, dt: float | None = None
                   ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray,
                              npt.NDArray[np.bool_]]:
        """The linear constraints ``C(x)`` of the corner guard at each state.

        Parameters
        ----------
        X, F : array_like, shape (N, n)
            States and nominal velocities.
        dt : float, optional
            Control period (see :meth:`__call__`).

        Returns
        -------
        bound : ndarray, shape (N, m)
            ``rho_i(x) b_i(x)``: the largest admissible ``w_i . v``.
        grad : ndarray, shape (N, n)
            ``P (x - x*)`` (``dV/dt = 2 grad . v``).
        v_bound : ndarray, shape (N,)
            The largest admissible ``grad . v`` (``+inf`` without a Lyapunov matrix).
        witness : ndarray, shape (N, n)
            A velocity that satisfies every constraint, ``-t (x - x*)``.
        inside : ndarray of bool, shape (N, m)
            Whether each state is on the inner side of (or on) each cut, and not at ``x*``:
            the constraints that apply. ``bound`` is ``+inf`` where they do not.
        """
        Xa, Fa = self._pair(X, F)
        D = Xa - self.attractor
        S = D @ self.W.T
        B = self.h - S  # distance to each plane, >= 0 inside
        inside = self._applies(D, B)
        B = np.maximum(B, 0.0)
        V = np.einsum("ni,ij,nj->n", D, self.P, D)
        Vs = np.where(V > 0.0, V, 1.0)  # at x*: sigma = 0 and grad V = 0, rates stay finite
        out_rate = np.maximum(Fa @ self.W.T, 0.0)
        hs = np.where(self.degenerate, 1.0, self.h)
        rate = np.where(self.degenerate,
                        np.maximum(-S, 0.0) * out_rate / (self.q * Vs[:, None]),
                        out_rate / hs)
        rho = np.clip(rate, self.barrier_rate, RATE_CAP * self.barrier_rate)
        grad = D @ self.P
        if self.certified:
            v_bound = np.einsum("ni,ni->n", grad, Fa)
            t = np.where(V > 0.0, np.maximum(-v_bound / Vs, 0.0), 0.0)
            rho = np.maximum(rho, t[:, None])
        else:
            v_bound = np.full(Xa.shape[0], np.inf)
            t = np.zeros(Xa.shape[0])
        if dt is not None:  # sampled data: the rows say "no step past a plane"
            rho = np.full_like(rho, 1.0 / dt)
            t = np.minimum(t, 1.0 / dt)
            if self.certified:
                v_bound = np.maximum(v_bound, -V / dt)
        return np.where(inside, rho * B, np.inf), grad, v_bound, -t[:, None] * D, inside

    def _violations(self, V: FloatArray, ref: FloatArray, bound: FloatArray,
                    inside: npt.NDArray[np.bool_], grad: FloatArray, v_bound: FloatArray
                    ) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
        """Rows of C(x) that velocities ``V`` (N, n) break beyond rounding: barrier (N, m)
        and Lyapunov (N,). ``ref`` is what ``V`` was computed from (sets the rounding scale)."""
        mag = np.abs(V) + np.abs(ref)
        barrier = inside & (V @ self.W.T > bound + GUARD_TOL * (
            np.abs(np.where(inside, bound, 0.0)) + mag @ np.abs(self.W).T))
        if not self.certified:
            return barrier, np.zeros(V.shape[0], dtype=bool)
        lyap = np.einsum("ni,ni->n", grad, V) > v_bound + GUARD_TOL * (
            np.abs(v_bound) + np.einsum("ni,ni->n", np.abs(grad), mag))
        return barrier, lyap

    def _most_broken(self, V: FloatArray, barrier: npt.NDArray[np.bool_],
                     lyap: npt.NDArray[np.bool_], bound: FloatArray, grad: FloatArray,
                     v_bound: FloatArray) -> npt.NDArray[np.intp]:
        """Index of the row each velocity breaks by the largest distance (``m``: Lyapunov)."""
        exc = np.where(barrier, V @ self.W.T - bound, -np.inf)
        gn = np.linalg.norm(grad, axis=1)
        lv = np.where(lyap & (gn > 0), (np.einsum("ni,ni->n", grad, V) - v_bound)
                      / np.where(gn > 0, gn, 1.0), -np.inf)
        return np.asarray(np.argmax(np.c_[exc, lv], axis=1), dtype=np.intp)

    def _kkt(self, G: FloatArray, A: FloatArray, c: FloatArray, S: npt.NDArray[np.intp]
             ) -> FloatArray:
        """Projections of ``G`` (N, n) in the ``P`` metric with the rows ``S`` (N, s) of
        ``A`` (N, k, n) ``<= c`` (N, k) active: ``v = G - P^-1 A_S^T lam``, ``lam = (A_S P^-1
        A_S^T)^-1 (A_S G - c_S)``; rows with a negative multiplier (not a KKT point) or
        dependent active rows get NaN."""
        AS = np.take_along_axis(A, S[:, :, None], axis=1)  # (N, s, n)
        cS = np.take_along_axis(c, S, axis=1)
        PinvAS = np.linalg.solve(self.P, AS.transpose(0, 2, 1))  # (N, n, s)
        K = AS @ PinvAS
        rhs = np.einsum("nsi,ni->ns", AS, G) - cS
        diag = np.prod(np.abs(np.diagonal(K, axis1=1, axis2=2)), axis=1)
        singular = ~(np.abs(np.linalg.det(K)) > 1e-10 * diag)  # dependent rows (or NaN)
        K[singular] = np.eye(S.shape[1])
        lam = np.linalg.solve(K, rhs[:, :, None])[:, :, 0]
        cand = G - np.einsum("nis,ns->ni", PinvAS, lam)
        cand[np.any(lam < -1e-12 * (1.0 + np.abs(lam)), axis=1) | singular] = np.nan
        return np.asarray(cand, dtype=np.float64)

    def _guard(self, X: FloatArray, F: FloatArray, out: FloatArray,
               dt: float | None) -> FloatArray:
        """Replace each inadmissible eq. 7 velocity by its ``P``-metric projection on C(x).

        First a vectorised primal active-set pass: with the rows ``S`` active, the projection
        has the closed form of :meth:`_kkt`; starting from the most broken row, the row the
        candidate breaks most is added, up to ``n`` rows. A candidate with non-negative
        multipliers that satisfies every row is a KKT point of the (convex) QP, hence *the*
        projection. States that do not settle this way (a negative multiplier, dependent rows)
        go through the exact least-distance program one at a time.
        """
        bound, grad, v_bound, witness, inside = self.admissible(X, F, dt=dt)
        G = out
        barrier, lyap = self._violations(G, G, bound, inside, grad, v_bound)
        todo = barrier.any(axis=1) | lyap
        # a vectorised primal active-set pass: start from the most broken row, add the row
        # the candidate breaks most, up to n rows; what does not settle goes to NNLS below
        rows = np.flatnonzero(todo)
        # (for one or two states the per-state least-distance program below is faster)
        for size in range(1, self.dim + 1 if rows.size > 2 else 1):
            if size == 1:
                # rows of C(x) as one array: the m barrier rows, then the Lyapunov row (m)
                A_all = np.concatenate([np.broadcast_to(self.W, (G.shape[0], *self.W.shape)),
                                        grad[:, None, :]], axis=1)
                c_all = np.concatenate([np.where(inside, bound, 0.0), v_bound[:, None]],
                                       axis=1)
                S = self._most_broken(G[rows], barrier[rows], lyap[rows], bound[rows],
                                      grad[rows], v_bound[rows])[:, None]
            cand = self._kkt(G[rows], A_all[rows], c_all[rows], S)
            b2, l2 = self._violations(cand, G[rows], bound[rows], inside[rows], grad[rows],
                                      v_bound[rows])
            finite = np.all(np.isfinite(cand), axis=1)
            ok = finite & ~(b2.any(axis=1) | l2)
            G[rows[ok]] = cand[ok]
            todo[rows[ok]] = False
            grow = finite & ~ok
            if size == self.dim or not grow.any():
                break
            nxt = self._most_broken(cand[grow], b2[grow], l2[grow], bound[rows[grow]],
                                    grad[rows[grow]], v_bound[rows[grow]])
            rows, S = rows[grow], np.c_[S[grow], nxt]
        metric = (self.metric if self.metric is not None
                  else np.linalg.inv(np.linalg.cholesky(self.P)).T)
        for i in np.flatnonzero(todo).tolist():
            on = inside[i]
            if self.certified:
                A = np.vstack([self.W[on], grad[i][None, :]])
                c = np.append(bound[i, on], v_bound[i])
            else:
                A, c = self.W[on], bound[i, on]
            g = G[i]  # breaks a row (``todo``: same test and tolerance as ``_admits``)
            v = _project_polyhedron(g, A, c, metric)
            G[i] = v if v is not None and _admits(A, c, v, g) else witness[i]
        return G


def _admits(A: FloatArray, c: FloatArray, v: FloatArray, g: FloatArray) -> bool:
    """``A v <= c`` up to rounding: ``GUARD_TOL`` relative to the terms involved (``v`` was
    computed from ``g``)."""
    tol = GUARD_TOL * (np.abs(c) + np.abs(A) @ (np.abs(v) + np.abs(g)))
    return bool(np.all(A @ v <= c + tol))


def check_control_period(dt: float | None) -> None:
    """Raise :class:`ModelError` unless ``dt`` is None or a positive finite number."""
    if dt is None or (type(dt) is float and 0.0 < dt < math.inf):  # the fast path (per step)
        return
    if (isinstance(dt, bool) or not isinstance(dt, numbers.Real)
                           or not (np.isfinite(dt) and dt > 0)):
        raise ModelError(f"dt must be a positive number, got {dt!r}")


def _project_polyhedron(g: FloatArray, A: FloatArray, c: FloatArray,
                        metric: FloatArray) -> FloatArray | None:
    """``argmin ||v - g||_P  s.t.  A v <= c``, exactly, by least-distance programming.

    With ``P = L L^T`` and ``metric = L^-T``, ``v = g + L^-T z`` turns the problem into the
    least-distance program ``min ||z||  s.t.  G z >= e`` with ``G = -A L^-T``, ``e = A g - c``,
    which Lawson & Hanson (*Solving Least Squares Problems*, 1974, ch. 23) reduce to one
    non-negative least squares problem ``min ||[G^T; e^T] y - e_{n+1}||, y >= 0`` (a finite
    active-set method, :func:`scipy.optimize.nnls`): with the residual ``r``, ``z = -r[:n] /
    r[n]``. Returns None if the polyhedron is empty (``r = 0``).

    Parameters
    ----------
    g : ndarray, shape (n,)
    A : ndarray, shape (k, n)
    c : ndarray, shape (k,)
    metric : ndarray, shape (n, n)
        ``L^-T``.

    Returns
    -------
    ndarray, shape (n,) or None
    """
    from scipy.optimize import nnls

    n = g.size
    AM = A @ metric
    e = A @ g - c
    # The residual's last entry is 1 / (1 + ||z||^2): scale the rows to unit norm and the
    # problem so that ||z|| = O(1) (both leave the answer unchanged), or it underflows.
    norms = np.linalg.norm(AM, axis=1)
    keep = norms > 0.0
    if np.any(e[~keep] > 0.0):
        return None  # a row 0 . v <= c_j < 0: empty
    AM, e = AM[keep] / norms[keep, None], e[keep] / norms[keep]
    scale = float(np.max(np.abs(e), initial=0.0))
    if scale == 0.0:
        return g.copy()
    E = np.vstack([-AM.T, (e / scale)[None, :]])
    rhs = np.zeros(n + 1)
    rhs[n] = 1.0
    y, _ = nnls(E, rhs)
    r = E @ y - rhs
    if not abs(r[n]) > 1e-12:
        return None
    return np.asarray(g + metric @ (-scale * r[:n] / r[n]), dtype=np.float64)


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
    dt: float | None = None,
) -> FloatArray:
    """Modulate nominal velocities by the cuts (paper eq. 7 and the corner guard), vectorised.

    Parameters
    ----------
    X : array_like, shape (N, n)
        States, any ``n >= 2``.
    F : array_like, shape (N, n)
        Nominal velocities ``f(X)`` (of an LPV-DS, a BC network, ...).
    cuts : sequence of Cut
        The mode's cuts; each must keep ``x*`` inside or on its plane.
    attractor : array_like, shape (n,)
        ``x*``, the reference point ``x^r`` of eq. 7.
    lyapunov : array_like, shape (n, n), optional
        The DS's ``P``: degenerate cuts (through ``x*``) use it, and the guard then keeps
        ``dV/dt`` at most that of ``f``. Identity (and no ``V`` constraint) if omitted.
    dt : float, optional
        Control period of a sampled-data (explicit Euler) loop, see :meth:`Modulator.__call__`.

    Returns
    -------
    ndarray, shape (N, n)
        ``M(x) f(x)`` (guarded) where modulation applies, ``f(x)`` elsewhere.

    Raises
    ------
    ModelError
        On shape mismatch or a cut that leaves ``x*`` outside.

    References
    ----------
    Paper Sec. 5.2, eq. 7; Thm. 1 (appendix A).
    """
    return Modulator.build(cuts, attractor, lyapunov=lyapunov)(X, F, dt=dt)


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
    """Literal eq. 7 at one state: ``E``, ``M = E D E^-1``, ``Gamma`` and the closest cut.

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
    dt: float | None = None,
    guard: bool = True,
    barrier_rate: float = DEFAULT_BARRIER_RATE,
) -> FloatArray:
    """Straightforward per-point modulation, for checking :func:`modulate`.

    Eq. 7 literally (build ``E`` and ``D``, invert, multiply) and, unless ``guard=False``, the
    corner guard written out constraint by constraint and solved by enumerating the KKT active
    sets (an independent route to the projection :class:`Modulator` computes by NNLS). Same
    contract as :func:`modulate`; a Python loop over points. The oracle of the tests and the
    baseline of ``benchmarks/bench_modulation.py``.
    """
    Xa = np.asarray(X, dtype=np.float64)
    Fa = np.asarray(F, dtype=np.float64)
    out = Fa.copy()
    if not cuts:
        return out
    x_star = np.asarray(attractor, dtype=np.float64)
    P = np.eye(x_star.size) if lyapunov is None else np.asarray(lyapunov, dtype=np.float64)
    for i in range(Xa.shape[0]):
        if guard:
            out[i] = _guard_reference(Xa[i], Fa[i], _eq5_reference(Xa[i], Fa[i], cuts, x_star,
                                                                   lyapunov, dt),
                                      cuts, x_star, P, certified=lyapunov is not None, dt=dt,
                                      kappa=barrier_rate)
        else:
            out[i] = _eq5_reference(Xa[i], Fa[i], cuts, x_star, lyapunov, dt)
    return out


def _eq5_reference(x: FloatArray, f: FloatArray, cuts: Sequence[Cut], x_star: FloatArray,
                   lyapunov: npt.ArrayLike | None, dt: float | None) -> FloatArray:
    """Eq. 7 at one state, literally (``f`` itself at ``x*``, outside, or for inward flow)."""
    if np.array_equal(x, x_star):
        return f.copy()
    E, M, g, a = modulation_matrix(x, cuts, x_star, lyapunov=lyapunov)
    coef = np.linalg.solve(E, f)[0]
    out = f.copy()
    if 0.0 < g <= 1.0 + BOUNDARY_TOL and coef >= 0.0:
        out = M @ f
        d = x - x_star
        h = float(cuts[a].normal @ (cuts[a].point - x_star))
        radial = g * coef / float(np.linalg.norm(d))  # M f = f - radial (x - x*)
        if (dt is not None and radial > 1.0 / dt
                and h > DEGENERATE_TOL * max(1.0, float(np.linalg.norm(cuts[a].point
                                                                      - x_star)))):
            out = f - d / dt  # the sampled-data cap of eq. 7's correction
    return out


def _guard_reference(x: FloatArray, f: FloatArray, v: FloatArray, cuts: Sequence[Cut],
                     x_star: FloatArray, P: FloatArray, *, certified: bool,
                     dt: float | None, kappa: float) -> FloatArray:
    """The corner guard at one state, written out (see the module docstring)."""
    d = x - x_star
    V = float(d @ P @ d)
    rows: list[FloatArray] = []
    bounds: list[float] = []
    t = max(-float(d @ P @ f) / V, 0.0) if certified and V > 0 else 0.0
    for c in cuts:
        w = np.asarray(c.normal)
        h = float(w @ (c.point - x_star))
        b = float(w @ (c.point - x))
        if b < -BOUNDARY_TOL * (1.0 + float(np.linalg.norm(d)) + max(h, 0.0)):
            continue  # x is beyond this cut: no constraint from it
        outward = max(float(w @ f), 0.0)
        if abs(h) <= DEGENERATE_TOL * max(1.0, float(np.linalg.norm(c.point - x_star))):
            q = float(w @ np.linalg.solve(P, w))
            rate = max(-float(w @ d), 0.0) * outward / (q * V) if V > 0 else 0.0
        else:
            rate = outward / h
        rate = min(max(rate, kappa), RATE_CAP * kappa)
        rho = max(rate, t) if dt is None else 1.0 / dt
        rows.append(w)
        bounds.append(rho * max(b, 0.0))
    if certified:
        rows.append(P @ d)
        bounds.append(max(float(d @ P @ f), -V / dt) if dt is not None else float(d @ P @ f))
    if not rows:
        return v
    A, c_ = np.array(rows).reshape(len(rows), x.size), np.array(bounds)
    if np.all(A @ v <= c_ + GUARD_TOL * (np.abs(c_) + np.abs(A) @ np.abs(v))):
        return v
    best: FloatArray | None = None
    Pinv = np.linalg.inv(P)
    for size in range(1, min(len(rows), x.size) + 1):
        for S in itertools.combinations(range(len(rows)), size):
            AS = A[list(S)]
            K = AS @ Pinv @ AS.T
            if np.linalg.cond(K) > 1e12:
                continue
            lam = np.linalg.solve(K, AS @ v - c_[list(S)])
            cand = v - Pinv @ AS.T @ lam
            if np.all(lam >= -1e-12) and np.all(A @ cand <= c_ + 1e-9 * (1.0 + np.abs(c_))):
                if best is None or ((cand - v) @ P @ (cand - v)
                                    < (best - v) @ P @ (best - v)):
                    best = cand
    if best is None:
        raise SolverError("corner guard: no KKT point found (reference enumeration)")
    return best


@dataclass(frozen=True, slots=True, eq=False)
class ModulatedPolicy:
    """``x -> M(x) f(x)`` around any state-based policy (paper Sec. 5.2, last paragraph).

    Attributes
    ----------
    policy : callable
        Nominal ``f``: maps states (N, n) to velocities (N, n).
    modulator : Modulator
    dt : float or None
        Control period of the loop that applies the velocities (explicit Euler), or None for
        the continuous-time field (see :meth:`Modulator.__call__`).
    """

    policy: Callable[[FloatArray], FloatArray]
    modulator: Modulator
    dt: float | None = None

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
        return self.modulator(Xa, self.policy(Xa), dt=self.dt)

    def __call__(self, X: npt.ArrayLike) -> FloatArray:
        """Same as :meth:`velocity`."""
        return self.velocity(X)


def modulated(
    policy: StatePolicy | Callable[[FloatArray], FloatArray],
    cuts: Sequence[Cut],
    attractor: npt.ArrayLike,
    *,
    lyapunov: npt.ArrayLike | None = None,
    dt: float | None = None,
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
    dt : float, optional
        Control period of the loop that will apply the velocities (explicit Euler); with it
        no step ``x + dt v`` from inside the cuts crosses one.

    Returns
    -------
    ModulatedPolicy
    """
    check_control_period(dt)
    if isinstance(policy, StatePolicy):
        fn: Callable[[FloatArray], FloatArray] = policy.velocity
        if lyapunov is None and getattr(policy, "P", None) is not None:
            lyapunov = policy.P  # type: ignore[attr-defined]
    elif callable(policy):
        fn = policy
    else:
        raise ModelError("policy must be callable or have a velocity(X) method")
    return ModulatedPolicy(policy=fn, modulator=Modulator.build(cuts, attractor,
                                                                 lyapunov=lyapunov), dt=dt)
