"""Named defaults shared across the toolkit, in one place.

Control period
    :data:`DEFAULT_DT` -- the control period a certificate proves, and the learner's
    sampled-data constraint imposes, when the task names none: 1/1000 s, a Franka's 1 kHz
    torque loop. A task's own ``dt`` (its file) always wins (``tli certify``, ``tli learn``).

Random streams
    Everything random takes a seed; one seed feeds several independent streams, each drawn
    from ``numpy.random.default_rng([seed, tag])`` with the tag of :class:`Stream` (values
    fixed: changing one changes every seeded result that uses it). :func:`rng` builds them.
"""

from __future__ import annotations

from enum import IntEnum
from fractions import Fraction
from typing import Any

__all__ = ["DEFAULT_DT", "DEFAULT_DT_FLOAT", "Stream", "rng"]

DEFAULT_DT = Fraction(1, 1000)
"""Default certified control period (s), exact."""
DEFAULT_DT_FLOAT = float(DEFAULT_DT)
"""The same, as the float the learner and the runtime use."""


class Stream(IntEnum):
    """Tags of the independent random streams of one seed (``default_rng([seed, tag])``)."""

    START = 3
    """A random start whose reading is an initial one of the spec (``tli run``, the API)."""
    FIG7 = 7
    """The Fig. 7 looping search's perturbations."""
    PUSHES = 11
    """``tli run --pushes N``: the random pushes of one run."""
    SCENE = 13
    """The MuJoCo scene's bead layout."""
    SIM_DEMOS = 17
    """The Franka demonstrations' waypoint jitter."""
    PERTURBATIONS = 19
    """The Franka trials' perturbations (:func:`tli_verify.sim.perturbations.draw`)."""
    SENSORS = 20
    """The simulated Franka sensors' noise, bias and calibration offsets
    (:mod:`tli_verify.sim.franka_sensors`)."""


def rng(seed: int, stream: Stream) -> Any:
    """The random generator of one stream of a seed.

    Parameters
    ----------
    seed : int
    stream : Stream

    Returns
    -------
    numpy.random.Generator
        ``numpy.random.default_rng([seed, int(stream)])``.
    """
    import numpy as np

    return np.random.default_rng([int(seed), int(stream)])
