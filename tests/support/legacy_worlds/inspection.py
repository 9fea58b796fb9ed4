"""The inspection-line world of the paper's second robot experiment (appendix "Inspection").

The robot brings a cube to the inspection entry, slides it along the inspection track and
releases it at the release station; the task repeats forever (``specs/inspection.toml``: mode
``a`` "go to the inspection entry" while ``!line``, mode ``b`` "follow the line and release"
while ``line``). The paper gives no coordinates; ours (workspace ``[0, 10] x [0, 6]``):

* **track**: ``3 <= x1 < 8`` and ``2.5 <= x2 <= 3.5`` (the inspection line, entered at its left
  end);
* **release**: ``8 <= x1 <= 9`` and ``2.5 <= x2 <= 3.5`` (the release station, the track's
  right end);
* **off**: the rest.

Sensors and latent state ``holding`` (the gripper holds a cube; true at the start):

* ``line`` = holding and on the track or the release station (the camera sees the cube on
  the line);
* ``rel`` = holding, at the release station, and on the line at the previous step: the cube
  is released (``holding`` becomes false);
* a new cube is grasped as soon as the robot is off the line (the paper's pre-defined grasping
  motion, region (a), not modelled).

So ``rel -> line``, ``rel -> X !line`` (the cube is gone) and ``!line -> X !rel`` (release needs
the cube on the line one step before) hold under any motion: the spec's assumptions.
Two scripted demonstrations (as in the paper), each one inspection: from the lower left to the
entry, along the track, release, lift off the line. Readings ``a -> b -> a``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from tests.support.legacy_worlds.base import BoolArray, FloatArray, IntArray, WorldBase
from tli_verify.demos import Demonstration

__all__ = ["InspectionWorld"]


@dataclass(frozen=True, slots=True)
class InspectionWorld(WorldBase):
    """The inspection-line world (module docstring).

    Attributes
    ----------
    lag : int
        Sensor lag in steps (default 0).
    duration : float
        Seconds per demonstration.
    dt : float
        Sampling period (s).
    """

    duration: float = 10.0
    dt: float = 0.05

    name: ClassVar[str] = "inspection"
    specs: ClassVar[tuple[str, ...]] = ("inspection.toml",)
    sensor_names: ClassVar[tuple[str, ...]] = ("line", "rel")
    latent_names: ClassVar[tuple[str, ...]] = ("holding",)
    region_names: ClassVar[tuple[str, ...]] = ("off", "track", "release")
    region_colors: ClassVar[tuple[str, ...]] = ("#3a3a3a", "#cfcfcf", "#7aa6f7")
    lo: ClassVar[tuple[float, ...]] = (0.0, 0.0)
    hi: ClassVar[tuple[float, ...]] = (10.0, 6.0)

    def region_index(self, X: npt.ArrayLike) -> IntArray:
        """0 off, 1 track, 2 release, shape (N,)."""
        Xa = np.asarray(X, dtype=np.float64)
        x1, x2 = Xa[..., 0], Xa[..., 1]
        band = (x2 >= 2.5) & (x2 <= 3.5)
        idx = np.zeros(x1.shape, dtype=np.int64)
        idx[band & (x1 >= 3.0) & (x1 < 8.0)] = 1
        idx[band & (x1 >= 8.0) & (x1 <= 9.0)] = 2
        return idx

    def initial_latent(self, batch: int) -> BoolArray:
        """Holding a cube at the start, shape (batch, 1)."""
        return np.ones((batch, 1), dtype=bool)

    def read(self, x_prev: FloatArray, x: FloatArray, latent: BoolArray
             ) -> tuple[BoolArray, BoolArray]:
        """``(line, rel)`` and the latent ``holding`` (module docstring)."""
        now = self.region_index(x)
        before = self.region_index(x_prev)
        holding = latent[:, 0] | (now == 0)
        line = holding & (now > 0)
        rel = line & (now == 2) & (before > 0)
        return np.stack([line, rel], axis=1), np.asarray(holding & ~rel)[:, None]

    def demonstrate(self, seed: int, n_demos: int | None = None) -> list[Demonstration]:
        """Inspections (default 2): to the entry, along the track, release, lift (seeded)."""
        rng = np.random.default_rng(seed)
        out = []
        for i in range(2 if n_demos is None else int(n_demos)):
            start = np.array([1.0, 1.0]) + rng.uniform(-0.6, 0.6, size=2)
            j = 0.08 * rng.normal(size=(3, 2))
            waypoints = np.vstack([
                start,
                np.array([2.6, 2.2]) + j[0],   # below the entry
                np.array([3.6, 3.0]) + j[1],   # on the line at the entry
                np.array([8.5, 3.0]) + j[2],   # the release station
                np.array([8.6, 5.0]),          # lifted off the line
            ])
            out.append(self._demo(str(i + 1), waypoints, self.duration, self.dt))
        return out
