"""Retrying a mode that stalls at its attractor: the scoop that gathered nothing.

LTL-DS guarantees that each mode's certified DS reaches its attractor, and the demonstrations
put that attractor where the next mode's sensor turns on (paper Asm. 3 and the bisimulation
conditions, Sec. 4.4). In the physical scene the attractor of mode ``b`` ("scoop") is a pose in
the pile of beads, and *reaching* it does not always put a bead on the spoon: a push, or a
pile that moved, leaves the ladle resting beside the beads with ``s`` off. Nothing then leaves
the mode -- no invariance failure to cut, no reading to replan on -- and the environment
assumption ``GF(!b | s)`` ("while scooping, soup eventually gets on the spoon") is not met
by the scene. The paper's robot retries: "LTL replans the scooping DS until the robot enters
the transferring mode successfully" (appendix, Robot Experiment 1).

:class:`StallRetry` makes that retry explicit, outside the certified executive. When the ladle
has stayed put in the active (non-goal) mode -- every component of the measured state within a
span of ``rest_span`` over the last ``stall_after`` seconds (at the attractor, or wedged
against the beads or the floor where the DS still pulls) -- the loop runs the certified DS of
the mode that leads into it (for ``b``: ``a``, whose attractor is where ``b`` is entered) back
to that attractor, then hands control back to the executive, which runs ``b`` again from there:
the approach the demonstrations show. The executive is *not* told ``perturbed`` during a
retreat: a mode change the retreat causes is judged like any other (by the executive, and by
the oracle, which skips no check). Every retry is counted in the trial's result and in the
evidence, and ``--no-retry`` switches it off. Not in the paper's algorithm: a loop-level
recovery for an environment assumption the physics breaks, reported as such.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["StallRetry"]

FloatArray = npt.NDArray[np.float64]


class StallRetry:
    """Detect a stalled mode and drive the retreat into it (module doc).

    Parameters
    ----------
    model : Model
        The executive's model (``policy.model``: the DS with their learned cuts).
    dt : float
        Control period (s).
    stall_after : float, optional
        Seconds at rest in a non-goal mode before a retry.
    rest_span : float, optional
        Per-axis range (DS units: dm, rad) of the measured state over ``stall_after`` within
        which the ladle has stayed put.
    arrive : float, optional
        Per-axis distance (DS units) to the retreat attractor that ends a retry.
    max_retry : float, optional
        Longest retreat (s).

    Attributes
    ----------
    retries : int
        Retries started so far.
    active : bool
        Whether a retreat is running.
    """

    def __init__(self, model: Any, dt: float, *, stall_after: float = 1.5,
                 rest_span: float = 0.25, arrive: float = 0.05,
                 max_retry: float = 4.0) -> None:
        self.model = model
        self.dt = float(dt)
        self.stall_after = float(stall_after)
        self.rest_span = float(rest_span)
        self.arrive = float(arrive)
        self.max_retry = float(max_retry)
        self.retries = 0
        self.active = False
        self._mode: str | None = None
        self._retreat_key: str | None = None
        self._elapsed = 0.0
        self._window: deque[FloatArray] = deque(maxlen=max(1, round(stall_after / dt)))

    def _into(self, mode: str) -> str | None:
        """Key of the DS whose transition leads into ``mode`` (``"a"`` for ``b``), if one."""
        keys = sorted(k for k, mm in self.model.modes.items()
                      if mm.next_mode == mode and mm.mode != mode)
        return keys[0] if keys else None

    def update(self, mode: str, done: bool, ref: npt.ArrayLike, measured: npt.ArrayLike
               ) -> FloatArray | None:
        """Advance one control period; the retreat velocity to use instead of ``v``, if any.

        Parameters
        ----------
        mode : str
            The executive's mode after its step.
        done : bool
            Whether it is a goal mode (never retried).
        ref : array_like, shape (n,)
            The DS state the executive was evaluated at.
        measured : array_like, shape (n,)
            The measured DS state this period.

        Returns
        -------
        ndarray, shape (n,), or None
            The retreat DS's velocity at ``ref`` while retrying, else None.
        """
        x = np.asarray(ref, dtype=np.float64)
        if mode != self._mode:  # a new mode: whatever caused it, start over
            self._mode, self.active = mode, False
            self._window.clear()
        if self.active:
            assert self._retreat_key is not None
            mm = self.model.modes[self._retreat_key]
            self._elapsed += self.dt
            if float(np.max(np.abs(x - mm.ds.attractor))) < self.arrive or \
                    self._elapsed >= self.max_retry:
                self.active = False  # back at the entry: run the mode again
                self._window.clear()
                return None
            return np.asarray(mm.velocity(x, dt=self.dt), dtype=np.float64)
        if done:
            self._window.clear()
            return None
        self._window.append(np.array(measured, dtype=np.float64))
        if len(self._window) == self._window.maxlen:
            span = np.ptp(np.asarray(self._window), axis=0)
            if float(np.max(span)) < self.rest_span:
                key = self._into(mode)
                self._window.clear()
                if key is None:
                    return None
                self.retries += 1
                self.active, self._retreat_key, self._elapsed = True, key, 0.0
                mm = self.model.modes[key]
                return np.asarray(mm.velocity(x, dt=self.dt), dtype=np.float64)
        return None
