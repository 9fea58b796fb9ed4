"""Repeated invariance failures: does a run leave a mode again where it already failed?

LTL-DS learns a cut from each invariance failure and modulates the mode's DS so that it never
crosses that cut again (paper Sec. 5.2 and Thm. 2); hence "the system experiences each
invariance failure only once" (paper Sec. 7.2). This module checks that claim on a recorded run,
and measures how an unmodulated run breaks it:

* a failure ``k`` of a mode *repeats* an earlier one ``j < k`` when its failure state
  ``x^{T_f}`` lies beyond the cut learned from failure ``j`` -- the run left the mode across a
  boundary it had already seen;
* a run that learns cuts (LTL-DS) is checked against the cuts it learned
  (:class:`~tli_verify.runtime.events.CutAdded`, in order); a run that does not (the
  no-modulation ablation) is checked against the cuts LTL-DS's rule *would* have learned from
  the same failures (:func:`replay_cuts`: :func:`~tli_verify.runtime.online.online_cut` on
  each failure in turn, the failures' ``x^0`` kept inside -- the executive keeps every entry
  state it recorded, so a replayed cut may differ from a learned one after the first).

A failure counts as repeated wherever it goes (to which mode) and wherever the run was the
period before: the unmodulated pour, for one, is often beyond the replayed cut already before
it leaves.

The bisimulation oracle of the 2-D campaigns (:mod:`tli_verify.verify.oracle`,
``REPEATED_EXIT``) checks a run against its *own* cuts, as the crossing of a cut between the
last in-mode and the failure reading; this module adds the replay, so that a run which learned
no cut can be measured by the same boundaries, and counts an exit as repeated when its failure
state lies beyond an earlier cut wherever the run was the period before (an unmodulated run is
often beyond the replayed cut already before it leaves).

The states are the executive's DS states (what the cuts and the modulation act on), not a
simulator's ground truth. A modulated DS state stays on the inner side of every cut, so an
LTL-DS run has no repeat unless something outside the DS moves its state (a perturbation is
not an invariance failure; a state the executive resynchronised to the measured pose may be).

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022: Sec. 5.2 (cuts from invariance failures), Thm. 2
(the modulated DS never penetrates the cuts), Sec. 7.2 and Fig. 6 (without modulation the
plan loops; with it each invariance failure happens once).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.boundary.cuts import Cut
from tli_verify.boundary.cuts import InvarianceFailure as FailureTriple
from tli_verify.errors import TliError
from tli_verify.runtime.events import CutAdded, InvarianceFailure
from tli_verify.runtime.online import online_cut

__all__ = ["REPEAT_TOL", "FailureCheck", "check_repeats", "replay_cuts"]

FloatArray = npt.NDArray[np.float64]

REPEAT_TOL = 1e-6
"""A failure state counts as beyond a cut when ``w . (x - p) > REPEAT_TOL`` (state units): the
modulated DS slides *on* a cut, so its states there lie on the plane up to rounding."""


@dataclass(frozen=True, slots=True)
class FailureCheck:
    """One invariance failure of the checked mode, against the cuts learned before it.

    Attributes
    ----------
    step : int
        The executive's step of the failure.
    to_mode : str
    repeats : tuple of int
        Indices of the earlier failures whose cut ``x^{T_f}`` lies beyond (empty: a new
        failure).
    cut : Cut or None
        The cut learned (or, replayed, that would have been learned) from this failure; None
        when no plane separates it.
    """

    step: int
    to_mode: str
    repeats: tuple[int, ...]
    cut: Cut | None

    @property
    def repeated(self) -> bool:
        """True iff the failure crosses a cut learned from an earlier one."""
        return bool(self.repeats)


def replay_cuts(model: Any, failures: Sequence[InvarianceFailure], *,
                margin: float = 1e-3) -> list[Cut | None]:
    """The cuts LTL-DS would have learned from ``failures``, in order.

    Each failure is cut by :func:`~tli_verify.runtime.online.online_cut` on the model as the
    earlier replayed cuts left it, with the entry states ``x^0`` of the failures so far kept
    inside (the executive keeps every entry state it recorded; a replay has only these).

    Parameters
    ----------
    model : Model
        The model the run started from (its cuts included).
    failures : sequence of InvarianceFailure
        Failures of one mode, in order (executive events).
    margin : float, optional
        The cut QCQP's separation margin.

    Returns
    -------
    list of Cut or None
        One per failure; None where no separating plane exists.
    """
    out: list[Cut | None] = []
    entries: list[FloatArray] = []
    for f in failures:
        entries.append(np.asarray(f.entry, dtype=np.float64))
        triple = FailureTriple(entry=f.entry, last_inside=f.last_inside, outside=f.outside)
        learned = online_cut(model, f.key, f.mode, triple, entries, margin=margin)
        cut = learned.attempt.cut if learned.attempt is not None else None
        if learned.model is not None and cut is not None:
            model = learned.model
            out.append(cut)
        else:
            out.append(None)
    return out


def check_repeats(events: Sequence[Any], mode: str, *, replay_from: Any = None,
                  margin: float = 1e-3, tol: float = REPEAT_TOL) -> tuple[FailureCheck, ...]:
    """Check each invariance failure of ``mode`` in a run's events against the earlier cuts.

    Parameters
    ----------
    events : sequence
        The executive's events of one run (:mod:`tli_verify.runtime.events`).
    mode : str
    replay_from : Model, optional
        For a run that does not learn cuts (the no-modulation ablation): the model it started
        from; the cuts are replayed on it (:func:`replay_cuts`). None (default): the run's own
        cuts (:class:`~tli_verify.runtime.events.CutAdded` at a failure's step; a failure
        without one -- :class:`~tli_verify.runtime.events.CutFailed` -- has none).
    margin : float, optional
        The cut QCQP's margin for a replay.
    tol : float, optional
        :data:`REPEAT_TOL`.

    Returns
    -------
    tuple of FailureCheck
        One per failure of ``mode``, in order.
    """
    failures = [e for e in events if isinstance(e, InvarianceFailure) and e.mode == mode]
    if replay_from is not None:
        if any(isinstance(e, CutAdded) and e.mode == mode for e in events):
            raise TliError(f"the run learned cuts of mode {mode!r}: check it against its own "
                           "(no replay_from)")
        cuts = replay_cuts(replay_from, failures, margin=margin)
    else:
        added = {e.step: e.cut for e in events if isinstance(e, CutAdded) and e.mode == mode}
        cuts = [added.get(f.step) for f in failures]
    out = []
    for k, (f, cut) in enumerate(zip(failures, cuts, strict=True)):
        x = np.asarray(f.outside, dtype=np.float64)
        repeats = tuple(j for j in range(k) if (c := cuts[j]) is not None
                        and float(c.normal @ (x - c.point)) > tol)
        out.append(FailureCheck(step=f.step, to_mode=f.to_mode, repeats=repeats, cut=cut))
    return tuple(out)
