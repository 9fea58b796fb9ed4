"""The color-tracing world of the paper's third robot experiment (appendix "Color Tracing").

The end-effector moves through (while staying within) the (Y)ellow, (B)lue, (G)reen, (O)range
and (P)ink tiles and eventually reaches (R)ed; a perturbation into the (D)ark background makes
the task automaton replan (``specs/color-tracing-a/b/c.toml``: re-enter at yellow, at blue, or
tile-dependent). The paper gives no coordinates; ours (workspace ``[0, 12] x [0, 6]``) make every
sensor change the specs' assumptions allow a shared boundary and no other:

* Y ``[0, 2)``, B ``[2, 4)``, G ``[4, 6)``, O ``[6, 8)`` in ``x1``, each over the band
  ``2 <= x2 <= 4``: a row of tiles, each touching the next and the dark background;
* P ``8 <= x1 < 10`` and R ``x1 >= 10``, both over the full height: P touches O, R and the
  dark background; R touches only P (the assumptions allow no dark -> red change, and red is
  absorbing);
* dark: the rest (``x1 < 8`` off the band).

Sensors ``cy, cb, cg, co, cp, cr`` are the tile memberships (all false in the dark); no latent
state. One scripted demonstration (as in the paper) runs from yellow along the row to red.
The assumptions also rule out moving back to the previous tile (``B -> Y`` and so on) although
the tiles share a boundary: the nominal task only moves forward; under a perturbation the
executive reports such a change as an assumption violation.

The dark modes ``d1``-``d4``. The paper demonstrates only the tiles ("the system learns a DS for
each of the colored mode"), so with that demonstration alone the dark modes have no data
(paper Asm. 3) and no DS may honestly run there: ``tli learn --spec specs/color-tracing-*.toml``
on ``demos/color-tracing_1.csv`` alone refuses it, naming ``d1``. The dark modes are entered only
by perturbations (the environment), and their specs say where each one re-enters: yellow,
blue or pink (``d1 -> X(dark | Y)`` and so on). We therefore *add* recovery demonstrations
(2-7, not in the paper): from the dark above or below the row (pink: above only), along the row
while still dark, into the re-entry tile, and on to red. Learned without a spec they give one DS per
demonstrated sensor transition (dark -> Y, dark -> B, dark -> P among them), bound to the dark
modes of each spec by :func:`tli_verify.rebind.rebind_model` (``scripts/make_models.py``). The
dark region is not convex (Asm. 1 fails: it wraps around the row), so a recovery DS is not
guaranteed to enter its tile first from every dark state; where it touches another tile first,
the executive reports the change as an assumption violation and resynchronizes (it never runs
an uncertified DS, and never cuts on such a change).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from tests.support.legacy_worlds.base import BoolArray, FloatArray, IntArray, WorldBase
from tli_verify.demos import Demonstration

__all__ = ["ColorTracingWorld"]

BAND = (2.0, 4.0)
"""The row of Y, B, G, O tiles: ``2 <= x2 <= 4``."""

RECOVERY_TARGETS = ("Y", "B", "P")
"""The tiles the specs' dark modes re-enter at (``d1``..``d4`` of color-tracing-a/b/c)."""


@dataclass(frozen=True, slots=True)
class ColorTracingWorld(WorldBase):
    """The color-tracing world (module docstring).

    Attributes
    ----------
    lag : int
        Sensor lag in steps (default 0).
    duration : float
        Seconds per demonstration.
    dt : float
        Sampling period (s).
    """

    duration: float = 12.0
    dt: float = 0.05

    name: ClassVar[str] = "color-tracing"
    specs: ClassVar[tuple[str, ...]] = ("color-tracing-a.toml", "color-tracing-b.toml",
                                        "color-tracing-c.toml")
    sensor_names: ClassVar[tuple[str, ...]] = ("cy", "cb", "cg", "co", "cp", "cr")
    region_names: ClassVar[tuple[str, ...]] = ("dark", "Y", "B", "G", "O", "P", "R")
    region_colors: ClassVar[tuple[str, ...]] = ("#3a3a3a", "#f7e27a", "#7aa6f7", "#9ed99b",
                                                "#f7b36b", "#f4b6c8", "#e2574c")
    lo: ClassVar[tuple[float, ...]] = (0.0, 0.0)
    hi: ClassVar[tuple[float, ...]] = (12.0, 6.0)

    def region_index(self, X: npt.ArrayLike) -> IntArray:
        """0 dark, 1 Y, 2 B, 3 G, 4 O, 5 P, 6 R, shape (N,)."""
        Xa = np.asarray(X, dtype=np.float64)
        x1, x2 = Xa[..., 0], Xa[..., 1]
        band = (x2 >= BAND[0]) & (x2 <= BAND[1])
        tile = np.clip(np.floor(x1 / 2.0), 0, 3).astype(np.int64) + 1  # Y B G O by x1
        idx = np.where(band & (x1 < 8.0), tile, 0)
        idx = np.where((x1 >= 8.0) & (x1 < 10.0), 5, idx)
        return np.asarray(np.where(x1 >= 10.0, 6, idx), dtype=np.int64)

    def read(self, x_prev: FloatArray, x: FloatArray, latent: BoolArray
             ) -> tuple[BoolArray, BoolArray]:
        """One-hot tile membership ``(cy, cb, cg, co, cp, cr)`` (all false in the dark)."""
        idx = self.region_index(x)
        return np.stack([idx == k for k in range(1, 7)], axis=1), latent

    def demonstrate(self, seed: int, n_demos: int | None = None) -> list[Demonstration]:
        """The tile demonstration, then recovery demonstrations out of the dark (default 7).

        Demonstration 1 (as in the paper) runs from yellow along the tiles to red. Demonstrations
        2-7 are *recoveries*, scripted, not in the paper (module docstring): each starts in the
        dark background, above or below the row of tiles, moves along the row (staying dark)
        to the re-entry tile of the specs' dark modes -- yellow, blue or pink -- enters it,
        and goes on along the tiles to red. Order: yellow from above, yellow from below, blue
        from above, blue from below, pink from above (twice, at two heights; seeded jitter).

        Pink is entered from above only: the DS of a sensor transition heads for the mean entry
        point of its segments (Lemma 2, :mod:`tli_verify.segmentation`), and entries from above
        and below would average to the height of the row of tiles, so the learned dark -> pink
        DS would cross the row (measured: 8 of 300 dark starts entered pink first, against
        171 of 300 with the entries from above).
        """
        rng = np.random.default_rng(seed)
        out = []
        total = 7 if n_demos is None else int(n_demos)
        for i in range(min(total, 1)):
            xs = np.array([0.8, 3.0, 5.0, 7.0, 9.0, 11.0])
            ys = 3.0 + rng.uniform(-0.35, 0.35, size=xs.size)
            xs = xs + np.concatenate([rng.uniform(-0.3, 0.3, size=1), np.zeros(4),
                                      rng.uniform(-0.3, 0.3, size=1)])
            out.append(self._demo(str(i + 1), np.column_stack([xs, ys]), self.duration,
                                  self.dt))
        for i in range(1, total):
            target = RECOVERY_TARGETS[((i - 1) // 2) % len(RECOVERY_TARGETS)]
            above = (i - 1) % 2 == 0
            where = "above" if above or target == "P" else "below"
            out.append(self._recovery(f"{i + 1} (recovery into {target}, from {where})",
                                      target, above, rng))
        return out

    def _recovery(self, label: str, target: str, above: bool, rng: np.random.Generator
                  ) -> Demonstration:
        """One recovery: a dark start, along the row to the target tile, in, on to red."""
        tile_x = {"Y": 1.0, "B": 3.0, "P": 9.0}[target]
        if target == "P":  # both from above (see demonstrate), at two heights
            side = 4.6 if above else 5.3
        else:
            side = 4.8 if above else 1.2
        y0 = side + rng.uniform(-0.15, 0.15)
        x0 = rng.uniform(4.5, 7.0) if target != "P" else rng.uniform(2.0, 5.0)
        mid = (0.5 * (x0 + tile_x), y0)
        if target == "P":  # pink spans the full height: straight across into it
            waypoints = [(x0, y0), mid, (tile_x, y0), (11.0, 3.0)]
        else:
            waypoints = [(x0, y0), mid, (tile_x, y0), (tile_x, 3.0)]
            waypoints += [(x, 3.0) for x in (5.0, 7.0, 9.0, 11.0) if x > tile_x + 1.0]
        W = np.array(waypoints) + np.vstack([np.zeros((1, 2)),
                                             rng.uniform(-0.15, 0.15, size=(len(waypoints) - 1,
                                                                             2))])
        return self._demo(label, W, self.duration, self.dt)
