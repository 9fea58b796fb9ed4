"""``perturbed`` as the robot can know it: its own estimate of the external wrench.

The Franka loop (:mod:`tli_verify.sim.loop`) tells the executive it is perturbed from the
rig's estimated external wrench (as the Panda's ``O_F_ext_hat_K``), never from the
simulator's list of perturbations: beyond 25 N or 2.5 N m, held 1.5 s (paper Sec. 7.2, the
perturbation signal of the executive).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from tli_verify.errors import InputError

__all__ = ["DETECT_FORCE", "DETECT_TORQUE", "NOTIFY_AFTER", "ContactDetector"]

FloatArray = npt.NDArray[np.float64]

NOTIFY_AFTER = 1.5
"""Seconds after the estimated external wrench falls below the thresholds during which the
executive is still told "perturbed" (:class:`ContactDetector`)."""


DETECT_FORCE = 25.0
"""External force (N) beyond which the robot counts itself perturbed."""


DETECT_TORQUE = 2.5
"""External torque (N m) beyond which the robot counts itself perturbed."""


class ContactDetector:
    """``perturbed`` as the robot can know it: the estimated external wrench beyond a threshold.

    The rig's estimate (:meth:`~tli_verify.sim.demos.PandaRig.external_wrench`: joint torques
    and the arm's model, as the Panda's ``O_F_ext_hat_K``) is compared with
    ``force`` (N) and ``torque`` (N m); the executive is told ``perturbed`` from the first
    period beyond either until ``hold`` seconds after the last (spilled beads take that long to
    leave the tray). Scooping presses the tray into the beads with less than the thresholds, so
    a nominal trial is never "perturbed" (tested).

    Parameters
    ----------
    force : float, optional
    torque : float, optional
    hold : float, optional
    """

    __slots__ = ("_since", "force", "hold", "torque")

    def __init__(self, force: float = DETECT_FORCE, torque: float = DETECT_TORQUE,
                 hold: float = NOTIFY_AFTER) -> None:
        if not (force > 0 and torque > 0 and hold >= 0):
            raise InputError(f"contact detector: need force > 0, torque > 0, hold >= 0; got "
                             f"{force}, {torque}, {hold}")
        self.force, self.torque, self.hold = float(force), float(torque), float(hold)
        self._since = math.inf

    def reset(self) -> None:
        """Forget the last contact (a new trial)."""
        self._since = math.inf

    def update(self, wrench: FloatArray, dt: float) -> bool:
        """Advance one period with the estimated wrench ``(F, tau)`` (shape (6,)); perturbed?

        A part is beyond its threshold when its norm (``np.linalg.norm``) is; the norm is
        computed only when the sum of squares in floats is within a relative 1e-9 of the
        threshold's square (farther, the answer does not depend on the roundings)."""
        w = np.asarray(wrench, dtype=np.float64)
        if _beyond(w, 0, self.force) or _beyond(w, 3, self.torque):
            self._since = 0.0
        else:
            self._since += dt
        return self._since <= self.hold

    def to_dict(self) -> dict[str, float]:
        """The evidence's record."""
        return {"force": self.force, "torque": self.torque, "hold": self.hold}


def _beyond(w: FloatArray, i: int, limit: float) -> bool:
    """``np.linalg.norm(w[i:i + 3]) > limit``, the norm computed only near ``limit``."""
    a, b, c = w[i:i + 3].tolist()
    sq, lim2 = a * a + b * b + c * c, limit * limit
    if sq < lim2 * (1.0 - 1e-9):
        return False
    if sq > lim2 * (1.0 + 1e-9):
        return True
    return float(np.linalg.norm(w[i:i + 3])) > limit
