"""Cut learning from invariance failures (paper Sec. 5.2 and appendix E.3), shared by the
single-mode study's batch loop and the executive's online cuts.

A cut for a failure ``(x^0, x^{T_f-1}, x^{T_f})`` is the plane through the last in-mode state
that separates the failure state and keeps ``x*``, the earlier cut points and the given states
inside (:func:`tli_verify.boundary.cuts.solve_cut`). When no plane keeps every given state
inside, :func:`cut_for_failure` falls back to the failure's own ``x^0`` (appendix E.3 as written).

When even appendix E.3's QCQP has no solution -- the run dipped below the chord from ``x^0`` to
``x*`` and left the mode above it, so every plane through ``x^{T_f-1}`` that keeps ``x^0`` and
``x*`` inside also keeps ``x^{T_f}`` inside -- the plane is moved along the exit step: it passes
through ``x^{T_f-1} + s (x^{T_f} - x^{T_f-1})`` for the smallest ``s`` in :data:`SHIFTS` that
admits a separating plane, with ``x^{T_f-1}`` itself kept inside. This extends appendix E.3 (found
by the bisimulation campaigns: without it the failure got no cut and could repeat).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.boundary.cuts import Cut, InvarianceFailure, inside_cuts, solve_cut
from tli_verify.boundary.modulation import modulated
from tli_verify.errors import ModelError, SolverError, TliError
from tli_verify.runtime.rollout import EulerProtocol, Policy, Region, Rollouts, rollout_protocol

__all__ = ["SHIFTS", "CutAttempt", "CutLearning", "OnlineCut", "cut_for_failure", "learn_cuts",
           "online_cut"]

FloatArray = npt.NDArray[np.float64]

#: Fractions of the exit step ``x^{T_f} - x^{T_f-1}`` tried, in order, for the plane's point
#: when no plane through ``x^{T_f-1}`` separates the failure (module docstring).
SHIFTS: tuple[float, ...] = (0.25, 0.5, 0.75, 0.9)


@dataclass(frozen=True, slots=True)
class CutAttempt:
    """The outcome of :func:`cut_for_failure`.

    Attributes
    ----------
    cut : Cut or None
        None when no separating plane exists.
    fallback : bool
        Solved keeping only the failure's own ``x^0`` (and ``x*``, earlier cut points) inside.
    shift : float
        0 for a plane through ``x^{T_f-1}`` (appendix E.3); else the fraction of the exit step
        the plane was moved by (:data:`SHIFTS`), ``x^{T_f-1}`` kept inside.
    """

    cut: Cut | None
    fallback: bool = False
    shift: float = 0.0


def cut_for_failure(
    failure: InvarianceFailure,
    attractor: npt.ArrayLike,
    *,
    previous: Sequence[Cut] = (),
    keep_inside: npt.ArrayLike | None = None,
    margin: float = 1e-3,
) -> CutAttempt:
    """Solve the cut QCQP for one failure, falling back to appendix E.3's constraints.

    Parameters
    ----------
    failure : InvarianceFailure
    attractor : array_like, shape (n,)
        ``x*`` of the DS the cut modulates.
    previous : sequence of Cut
        Earlier cuts of the mode (their points stay inside).
    keep_inside : array_like, shape (k, n), optional
        More states to keep inside (e.g. every observed entry state, earlier failures' ``x^0``).
    margin : float

    Returns
    -------
    CutAttempt
    """
    try:
        return CutAttempt(solve_cut(failure, attractor, previous=previous,
                                    keep_inside=keep_inside, margin=margin))
    except SolverError:
        if keep_inside is None:
            return CutAttempt(None)
    last = np.asarray(failure.last_inside, dtype=np.float64)
    x_star = np.asarray(attractor, dtype=np.float64).reshape(-1)
    # x* strictly inside (Model.add_cut's rule): a small box around it, as the executive keeps
    delta = 1e-3 * max(1e-6, float(np.linalg.norm(last - x_star)))
    box = x_star + delta * np.vstack([np.eye(x_star.size), -np.eye(x_star.size)])
    try:  # some kept state lies beyond the exit: keep only this failure's x^0
        return CutAttempt(solve_cut(failure, attractor, previous=previous, keep_inside=box,
                                    margin=margin), fallback=True)
    except SolverError:
        pass
    step = np.asarray(failure.outside, dtype=np.float64) - last
    for s in SHIFTS:  # no plane through x^{T_f-1}: move it along the exit step
        moved = InvarianceFailure(entry=failure.entry, last_inside=last + s * step,
                                  outside=failure.outside)
        try:
            cut = solve_cut(moved, attractor, previous=previous,
                            keep_inside=np.vstack([last[None, :], box]),
                            margin=margin)
        except SolverError:
            continue
        return CutAttempt(cut, fallback=True, shift=s)
    return CutAttempt(None)


@dataclass(frozen=True, slots=True, eq=False)
class CutLearning:
    """Outcome of iterative cut learning for one policy and start set.

    Attributes
    ----------
    cuts : list of Cut
    curve : list of float
        Success rate with 0, 1, ..., len(cuts) cuts.
    failures : list of tuple
        The invariance failures ``(x^0, x^{T_f-1}, x^{T_f})`` the cuts were built from.
    final : Rollouts
        Rollouts with all cuts.
    unsolved : int
        Failures for which no separating cut existed (skipped).
    fallback : int
        Cuts solved with only the failure's own ``x^0`` kept inside, because no plane kept
        every entry state inside (``cut_constraints="entries"`` only).
    converged : bool
        No rollout left the mode with the final cuts.
    """

    cuts: list[Cut]
    curve: list[float]
    failures: list[tuple[FloatArray, FloatArray, FloatArray]]
    final: Rollouts
    unsolved: int
    fallback: int
    converged: bool


def learn_cuts(
    base: Policy,
    starts: FloatArray,
    contains: Region,
    attractor: FloatArray,
    rng: np.random.Generator,
    *,
    protocol: EulerProtocol,
    max_cuts: int = 20,
    cut_margin: float = 1e-3,
    cut_constraints: str = "entries",
    lyapunov: FloatArray | None = None,
    record: bool = False,
) -> CutLearning:
    """Add cuts from sampled invariance failures one at a time (paper appendix E.1).

    Roll out all starts with the modulated policy, pick one failure at random (those whose
    last in-mode state is inside the cuts first: a cut only changes the flow inside the cuts,
    paper Fig. 4), solve its cut, add it, repeat until no start leaves or ``max_cuts``.

    Parameters
    ----------
    base : callable
        Nominal policy, (N, n) -> (N, n).
    starts : ndarray, shape (N, n)
    contains : callable
        Mode sensor.
    attractor : ndarray, shape (n,)
    rng : numpy.random.Generator
        Picks which failure to cut next.
    protocol : EulerProtocol
        Integration; the modulation is told its ``dt``.
    max_cuts : int, optional
    cut_margin : float, optional
    cut_constraints : {"entries", "paper"}, optional
        ``"entries"`` keeps every start inside each cut, ``"paper"`` only the failure's ``x^0``.
    lyapunov : ndarray, shape (n, n), optional
        The DS's ``P`` (None for BC).
    record : bool, optional
        Record paths of the final rollouts.

    Returns
    -------
    CutLearning
    """
    if cut_constraints not in ("entries", "paper"):
        raise TliError(f"cut constraints must be 'entries' or 'paper', got {cut_constraints!r}")
    cuts: list[Cut] = []
    curve: list[float] = []
    used: list[tuple[FloatArray, FloatArray, FloatArray]] = []
    unsolved = 0
    fallback = 0
    keep = starts if cut_constraints == "entries" else None
    while True:
        pol = modulated(base, cuts, attractor, lyapunov=lyapunov, dt=protocol.dt)
        res = rollout_protocol(pol.velocity, starts, contains, attractor, protocol,
                               record=record)
        curve.append(float(res.success.mean()))
        fails = res.invariance_failures
        if fails.size == 0 or len(cuts) >= max_cuts:
            return CutLearning(cuts=cuts, curve=curve, failures=used, final=res,
                               unsolved=unsolved, fallback=fallback,
                               converged=fails.size == 0)
        new = None
        order = rng.permutation(fails)
        fixable = inside_cuts(res.last_inside[order], cuts)
        order = np.concatenate([order[fixable], order[~fixable]])
        for j in order:
            failure = InvarianceFailure(entry=res.entry[j], last_inside=res.last_inside[j],
                                        outside=res.outside[j])
            attempt = cut_for_failure(failure, attractor, previous=cuts, keep_inside=keep,
                                      margin=cut_margin)
            if attempt.cut is None:
                unsolved += 1
                continue
            new = attempt.cut
            fallback += int(attempt.fallback)
            used.append((res.entry[j].copy(), res.last_inside[j].copy(), res.outside[j].copy()))
            break
        if new is None:
            return CutLearning(cuts=cuts, curve=curve, failures=used, final=res,
                               unsolved=unsolved, fallback=fallback, converged=False)
        cuts.append(new)


@dataclass(frozen=True, slots=True, eq=False)
class OnlineCut:
    """The cut the executive learned for one invariance failure, or why none.

    Attributes
    ----------
    model : Model or None
        The model with the cut (:meth:`~tli_verify.model.types.Model.add_cut`: every DS of the mode
        shares it); None when no cut was added.
    attempt : CutAttempt or None
        The QCQP's answer (None when the failure itself was degenerate).
    error : str or None
        Why no cut was added (None when one was).
    """

    model: Any
    attempt: CutAttempt | None
    error: str | None


def online_cut(model: Any, key: str, mode: str, failure: InvarianceFailure,
               entries: Sequence[npt.ArrayLike], *, margin: float) -> OnlineCut:
    """Cut a mode's region after an invariance failure seen online (paper Sec. 5.2).

    Kept inside: every entry state recorded in the mode (earlier failures' ``x^0`` among
    them), the other DS' attractors of the mode, and a small box around ``x*`` (so ``x*`` is
    strictly inside); constrained by the mode's earlier cuts (:func:`cut_for_failure`).

    Parameters
    ----------
    model : Model
        The model being run.
    key : str
        The model key of the DS that failed.
    mode : str
        Its mode (the region cut).
    failure : InvarianceFailure
        ``(x^0, x^{T_f-1}, x^{T_f})``.
    entries : sequence of array_like, each shape (n,)
        The mode-entry states recorded in the mode.
    margin : float
        Separation margin of the cut QCQP.

    Returns
    -------
    OnlineCut
    """
    mm = model.modes[key]
    x_star = mm.ds.attractor
    last = np.asarray(failure.last_inside, dtype=np.float64)
    delta = 1e-3 * max(1e-6, float(np.linalg.norm(last - x_star)))
    box = x_star + delta * np.vstack([np.eye(x_star.size), -np.eye(x_star.size)])
    others = [model.modes[k].ds.attractor for k in model.keys_of(mode) if k != key]
    keep = np.vstack([*entries, *others, box])
    attempt = cut_for_failure(failure, x_star, previous=model.region_cuts(mode),
                              keep_inside=keep, margin=margin)
    if attempt.cut is None:
        return OnlineCut(None, attempt, "no plane through the last in-mode state separates "
                         "the failure state")
    try:
        return OnlineCut(model.add_cut(key, attempt.cut), attempt, None)
    except ModelError as exc:
        return OnlineCut(None, attempt, str(exc))
