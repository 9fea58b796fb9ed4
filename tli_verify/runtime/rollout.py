"""The rollout engine: explicit-Euler episodes of a state-based policy, batched over starts.

One engine runs the single-mode study (paper Sec. 7.1, appendix E), the batched episodes of the
campaigns and the benchmarks: ``x_{t+1} = x_t + dt * cap(v(x_t))`` with the velocity capped at a
speed limit (keeping its direction), stopped per start when the goal is reached or the state
leaves the region (an *invariance failure*, paper Sec. 5.2). Every step evaluates the policy
once on all active starts (numpy over the batch), so a policy that is vectorised -- an LPV-DS,
a modulated DS, a BC network -- costs one call per step, not one per start.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from tli_verify.boundary.cuts import InvarianceFailure
from tli_verify.errors import TliError

__all__ = [
    "EulerProtocol",
    "Policy",
    "Region",
    "Rollouts",
    "cap_speed",
    "failures",
    "rollout",
    "rollout_protocol",
]

FloatArray = npt.NDArray[np.float64]
Policy = Callable[[FloatArray], FloatArray]
"""A state-based policy: states (N, n) -> velocities (N, n)."""
Region = Callable[[FloatArray], npt.NDArray[np.bool_]]
"""A mode sensor: states (N, n) -> inside (N,)."""


@dataclass(frozen=True, slots=True)
class EulerProtocol:
    """How an episode is integrated (the protocol of the authors' MATLAB code by default).

    Attributes
    ----------
    dt : float
        Euler step, also the control period the modulation is told (0.01).
    steps : int
        Step budget (1000).
    speed_cap : float
        Speed limit; a faster velocity is rescaled, keeping its direction (20).
    goal_tolerance : float
        Goal radius (0.4).
    """

    dt: float = 0.01
    steps: int = 1000
    speed_cap: float = 20.0
    goal_tolerance: float = 0.4

    def validate(self) -> None:
        """Raise :class:`~tli_verify.errors.TliError` (exit code 2) on a bad parameter."""
        if not (np.isfinite(self.dt) and self.dt > 0) or self.steps < 1:
            raise TliError("dt must be positive and steps >= 1")
        if not (self.speed_cap > 0 and self.goal_tolerance > 0):
            raise TliError("speed cap and goal tolerance must be positive")


def cap_speed(V: FloatArray, speed_cap: float) -> FloatArray:
    """Rescale, in place, the rows of ``V`` (N, n) faster than ``speed_cap``; returns ``V``."""
    speed = np.linalg.norm(V, axis=1)
    over = speed > speed_cap
    if np.any(over):
        V[over] *= (speed_cap / speed[over])[:, None]
    return V


@dataclass(frozen=True, slots=True, eq=False)
class Rollouts:
    """Vectorised rollouts from N starts.

    Attributes
    ----------
    reached : ndarray of bool, shape (N,)
        Reached the goal before leaving the mode (= success).
    left : ndarray of bool, shape (N,)
        Left the mode before reaching the goal (an invariance failure).
    exit_step : ndarray of int, shape (N,)
        Step of the first state outside the mode, -1 if none.
    entry, last_inside, outside : ndarray, shape (N, n)
        ``x^0``, ``x^{T_f-1}``, ``x^{T_f}`` (the last two NaN where the mode was not left).
    paths : ndarray, shape (steps + 1, N, n), optional
        States, frozen after a rollout ends; only when recorded.
    """

    reached: npt.NDArray[np.bool_]
    left: npt.NDArray[np.bool_]
    exit_step: npt.NDArray[np.int64]
    entry: FloatArray
    last_inside: FloatArray
    outside: FloatArray
    paths: FloatArray | None = None

    @property
    def success(self) -> npt.NDArray[np.bool_]:
        """Reached the goal and never left the mode."""
        return self.reached

    @property
    def reachability_failures(self) -> npt.NDArray[np.bool_]:
        """Stayed in the mode but did not reach the goal within the horizon."""
        return ~self.reached & ~self.left

    @property
    def invariance_failures(self) -> npt.NDArray[np.intp]:
        """Indices of the starts that left the mode after at least one step (cuttable)."""
        return np.flatnonzero(self.left & (self.exit_step > 0))


def failures(res: Rollouts, rows: npt.ArrayLike | None = None) -> list[InvarianceFailure]:
    """The invariance failures ``(x^0, x^{T_f-1}, x^{T_f})`` of a batch (paper Sec. 5.2).

    Parameters
    ----------
    res : Rollouts
    rows : array_like of int, optional
        Which starts (default: every start that left the mode after at least one step; a start
        outside the mode has no last in-mode state).

    Returns
    -------
    list of InvarianceFailure
    """
    idx = res.invariance_failures if rows is None else np.asarray(rows, dtype=np.intp)
    return [InvarianceFailure(entry=res.entry[j], last_inside=res.last_inside[j],
                              outside=res.outside[j]) for j in idx.tolist()]


def rollout(
    policy: Policy,
    starts: npt.ArrayLike,
    contains: Region,
    attractor: npt.ArrayLike,
    *,
    dt: float = 0.01,
    steps: int = 1000,
    speed_cap: float = 20.0,
    goal_tolerance: float = 0.4,
    record: bool = False,
) -> Rollouts:
    """Euler rollouts of a state-based policy, vectorised over the starts.

    Parameters
    ----------
    policy : callable
        Velocities for states, (M, n) -> (M, n).
    starts : array_like, shape (N, n)
        Start states (inside the mode).
    contains : callable
        The mode sensor, (M, n) -> bool (M,).
    attractor : array_like, shape (n,)
        Goal.
    dt, steps, speed_cap, goal_tolerance : float, int, float, float
        Integration protocol (:class:`EulerProtocol`); the speed cap rescales a velocity,
        keeping its direction.
    record : bool, optional
        Keep the paths (for figures).

    Returns
    -------
    Rollouts
    """
    X = np.array(starts, dtype=np.float64)
    goal = np.asarray(attractor, dtype=np.float64)
    N, n = X.shape
    reached = np.linalg.norm(X - goal, axis=1) <= goal_tolerance
    left = ~contains(X)
    exit_step = np.where(left, 0, -1).astype(np.int64)
    last_inside = np.full((N, n), np.nan)
    outside = np.where(left[:, None], X, np.nan)
    reached &= ~left
    active = ~(reached | left)
    paths = np.empty((steps + 1, N, n)) if record else None
    if paths is not None:
        paths[0] = X
    for t in range(1, steps + 1):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            if paths is not None:
                paths[t:] = X
            break
        x = X[idx]
        v = cap_speed(policy(x), speed_cap)
        x_new = x + dt * v
        inside = contains(x_new)
        out_now = ~inside
        if np.any(out_now):
            j = idx[out_now]
            left[j] = True
            exit_step[j] = t
            last_inside[j] = x[out_now]
            outside[j] = x_new[out_now]
        goal_now = inside & (np.linalg.norm(x_new - goal, axis=1) <= goal_tolerance)
        reached[idx[goal_now]] = True
        X[idx[inside]] = x_new[inside]
        active[idx[out_now | goal_now]] = False
        if paths is not None:
            paths[t] = X
            paths[t, idx[out_now]] = x_new[out_now]
    if paths is not None:
        # keep the exit point visible: states after an exit stay at the failure state
        for row in np.flatnonzero(left & (exit_step > 0)).tolist():
            paths[int(exit_step[row]):, row] = outside[row]
    return Rollouts(reached=reached, left=left, exit_step=exit_step,
                    entry=np.array(starts, dtype=np.float64), last_inside=last_inside,
                    outside=outside, paths=paths)


def rollout_protocol(
    policy: Policy, starts: npt.ArrayLike, contains: Region, attractor: npt.ArrayLike,
    protocol: EulerProtocol, *, record: bool = False,
) -> Rollouts:
    """:func:`rollout` with the integration parameters of ``protocol``."""
    return rollout(policy, starts, contains, attractor, dt=protocol.dt, steps=protocol.steps,
                   speed_cap=protocol.speed_cap, goal_tolerance=protocol.goal_tolerance,
                   record=record)
