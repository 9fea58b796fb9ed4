"""The soup-scooping world of the paper (Fig. 2, Sec. 7.2, appendix F), in the authors' geometry.

Workspace ``[-8, 8]^2``; ``x1`` (horizontal) is the spoon's orientation, ``x2`` (vertical) its
distance to the soup. True regions (hidden from the learner), a partition of the workspace:

* **pink** (soup on the spoon): ``2 <= x1 <= 6`` and ``-8 <= x2 <= 6``; it overrides yellow;
* **green** (at the target): ``2 <= x1 <= 6`` and ``6 < x2 <= 8``;
* **yellow** (contact with the soup): ``x2 <= -4`` outside the pink column;
* **white**: the rest.

Sensors (the inputs of ``specs/scoop.toml``): ``r`` (contact), ``s`` (soup on the spoon),
``t`` (soup at the target). "Soup on the spoon" is *latent*: the spoon picks soup up only by
moving from contact (yellow) straight into pink, i.e. by scooping; reaching pink any other way
(from white, or by a perturbation) gives an empty spoon, which reads like white. Soup is lost
(spilled) whenever the spoon leaves pink and green: a perturbation from pink to white reads
``c -> a``, from pink to yellow ``c -> b``. Soup carried into green is delivered, and the task
stays done (``t`` latches; the spec's assumption ``G(t -> X t)``). One step of the model, on the
(lagged) previous state ``x'``, state ``x`` and latent ``(soup, delivered)``::

    soup'      = (soup & x in pink|green) | (x in pink & x' in yellow)
    delivered' = delivered | (soup' & x in green)
    reading    = (0, 0, 1)                    if delivered'
                 (x in yellow, soup' & x in pink, 0)   otherwise

so the readings are exactly the labels of modes a (``!r!s!t``: white, or pink/green with an
empty spoon), b (``r``: yellow), c (``s``: pink with soup), d (``t``: done), and every sensor
change the world can produce -- even under arbitrary jumps of the state -- is one the spec's
assumptions allow: ``a -> a|b``, ``b -> a|b|c``, ``c -> a|b|c|d``, ``d -> d``.

The scripted demonstrator moves the spoon from white (upper left) down into the soup (yellow),
scoops -- an arc: down to the bottom of the soup, back up steeply to just under the surface,
levelling off sideways into pink -- and lifts through pink into the green target, timed with a
minimum-jerk profile: readings ``a -> b -> c -> d``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from tests.support.legacy_worlds.base import BoolArray, FloatArray, IntArray, WorldBase
from tli_verify.demos import Demonstration

__all__ = ["MODE_REGION", "SCOOP_WAYPOINTS", "ScoopWorld"]

X1_COLUMN = (2.0, 6.0)
"""The pink/green column ``2 <= x1 <= 6``."""
CONTACT_X2 = -4.0
"""Yellow (contact) is ``x2 <= -4`` (outside the column)."""
TARGET_X2 = 6.0
"""Green is ``x2 > 6`` in the column; pink is ``x2 <= 6``."""
TARGET_CENTER = np.array([4.0, 7.0])
"""Where the demonstrations end (the middle of green)."""

SCOOP_WAYPOINTS: tuple[tuple[tuple[float, float], float], ...] = (
    ((-3.0, -1.5), 1.0),    # above the soup (a: reaching)
    ((-2.3, -5.2), 0.4),    # in contact (yellow; b: scooping starts)
    ((-0.5, -6.9), 0.3),    # the bottom of the scoop
    ((0.8, -6.0), 0.2),     # coming back up ...
    ((1.2, -4.5), 0.1),     # ... steeply, to just under the surface
    ((2.3, -4.25), 0.1),    # levelling off sideways into pink: scooped (c: transporting)
    ((3.6, -3.0), 0.2),     # lifting
    ((4.0, 1.5), 0.5),      # up through pink
)
"""The scripted demonstrator's waypoints between the start and :data:`TARGET_CENTER`:
``(point, jitter)``; each point moves by ``jitter * N(0, 0.25^2 I)`` per demonstration."""

MODE_REGION = {"a": "white", "b": "yellow", "c": "pink", "d": "green"}
"""The region each mode of ``specs/scoop.toml`` runs in (nominally)."""


@dataclass(frozen=True, slots=True)
class ScoopWorld(WorldBase):
    """The paper's 2-D soup-scooping world (module docstring).

    Attributes
    ----------
    lag : int
        Sensor lag in steps (default 0).
    duration : float
        Seconds per demonstration.
    dt : float
        Sampling period of the demonstrations (s).
    """

    duration: float = 12.0
    dt: float = 0.05

    name: ClassVar[str] = "scoop"
    specs: ClassVar[tuple[str, ...]] = ("scoop.toml",)
    sensor_names: ClassVar[tuple[str, ...]] = ("r", "s", "t")
    latent_names: ClassVar[tuple[str, ...]] = ("soup", "delivered")
    region_names: ClassVar[tuple[str, ...]] = ("white", "yellow", "pink", "green")
    region_colors: ClassVar[tuple[str, ...]] = ("#ffffff", "#f7e27a", "#f4b6c8", "#9ed99b")
    lo: ClassVar[tuple[float, ...]] = (-8.0, -8.0)
    hi: ClassVar[tuple[float, ...]] = (8.0, 8.0)

    def region_index(self, X: npt.ArrayLike) -> IntArray:
        """0 white, 1 yellow, 2 pink, 3 green, shape (N,) (module docstring)."""
        Xa = np.asarray(X, dtype=np.float64)
        x1, x2 = Xa[..., 0], Xa[..., 1]
        column = (x1 >= X1_COLUMN[0]) & (x1 <= X1_COLUMN[1])
        idx = np.zeros(x1.shape, dtype=np.int64)
        idx[~column & (x2 <= CONTACT_X2)] = 1
        idx[column & (x2 <= TARGET_X2)] = 2
        idx[column & (x2 > TARGET_X2)] = 3
        return idx

    def region_one(self, x: Sequence[float]) -> int:
        """:meth:`region_index` of one state ``(x1, x2)``: the same comparisons, in Python."""
        x1, x2 = float(x[0]), float(x[1])
        if X1_COLUMN[0] <= x1 <= X1_COLUMN[1]:
            return 2 if x2 <= TARGET_X2 else (3 if x2 > TARGET_X2 else 0)
        return 1 if x2 <= CONTACT_X2 else 0

    def read(self, x_prev: FloatArray, x: FloatArray, latent: BoolArray
             ) -> tuple[BoolArray, BoolArray]:
        """One sensor step: ``(r, s, t)`` and the latent ``(soup, delivered)`` (module doc)."""
        now = self.region_index(x)
        before = self.region_index(x_prev)
        pink, green = now == 2, now == 3
        soup = (latent[:, 0] & (pink | green)) | (pink & (before == 1))
        delivered = latent[:, 1] | (soup & green)
        r = (now == 1) & ~delivered
        s = soup & pink & ~delivered
        reading = np.stack([r, s, delivered], axis=1)
        return reading, np.stack([soup, delivered], axis=1)

    def demonstrate(self, seed: int, n_demos: int | None = None) -> list[Demonstration]:
        """Scripted scooping demonstrations (default 3), readings ``a -> b -> c -> d``.

        Waypoints (jittered with the seed; :data:`SCOOP_WAYPOINTS`): a start in the upper-left
        white region, down into the soup (yellow), a scooping arc -- dip to the bottom of the
        soup, come back up steeply to just under its surface and level off sideways into the
        pink column (the soup is on the spoon) -- then up through pink to the middle of green.
        The arc is what makes Fig. 7's looping possible: the scooping DS (mode ``b``) learned
        from it rises near the top of yellow, so from states just under the surface left of
        pink it leaves the soup back into white (an invariance failure, ``b -> a``), and the
        reaching DS (``a``) brings the spoon straight back (:mod:`tli_verify.experiments.scoop`,
        :func:`~tli_verify.experiments.fig7.fig7_search`).
        """
        rng = np.random.default_rng(seed)
        out = []
        for i in range(3 if n_demos is None else int(n_demos)):
            start = np.array([-5.0, 4.5]) + rng.uniform(-1.5, 1.5, size=2)
            j = rng.normal(scale=0.25, size=(len(SCOOP_WAYPOINTS), 2))
            waypoints = np.vstack([start]
                                  + [np.array(p) + s * j[k]
                                     for k, (p, s) in enumerate(SCOOP_WAYPOINTS)]
                                  + [TARGET_CENTER])
            out.append(self._demo(str(i + 1), waypoints, self.duration, self.dt))
        return out
