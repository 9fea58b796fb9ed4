"""Named defaults shared across the toolkit, in one place.

Control period
    :data:`DEFAULT_DT` -- the one default control period: of a task file without ``dt``, and
    the period a certificate proves and the learner's sampled-data constraint imposes when no
    task names one: 1/100 s. A certificate at ``dt`` covers every faster loop (a 1 kHz torque
    loop included); the rule that settles the period, and its proof, are in
    :mod:`tli_verify.project.period`.

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

DEFAULT_DT = Fraction(1, 100)
"""The default control period (s), exact."""
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
