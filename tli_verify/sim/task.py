"""The Franka scooping task's sensor model: computed by the MuJoCo scene, not by regions.

``sim/franka/tasks/franka-scoop.toml`` names it through the entry point ``franka-scoop`` of
group ``tli_verify.tasks`` (:mod:`tli_verify.tasks.registry`), so the task is data like any
other -- state space, spec, goal -- while its sensors ``r, s, t`` come from the physics
(:mod:`tli_verify.sim.sensors`, read by the trial loop :mod:`tli_verify.sim.loop`). A kinematic
closed loop (``tli run``, ``tli verify``) cannot compute them from states alone: reading them
there is refused with a message saying where they come from.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TaskError

__all__ = ["PhysicsSensors", "physics_sensors"]

BoolArray = npt.NDArray[np.bool_]
FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class PhysicsSensors:
    """The sensor model of a physics task: ``r, s, t`` (contact, soup on the spoon, soup at
    the target), computed by the MuJoCo scene during a trial (``tli sim franka``)."""

    sensor_names: tuple[str, ...] = ("r", "s", "t")
    latent_names: tuple[str, ...] = ()
    cell_based: bool = False
    physics: bool = True
    """Its campaigns are physical ones (``tli evidence`` runs MuJoCo trials)."""

    def initial_latent(self, batch: int) -> BoolArray:
        """No latent state, shape (batch, 0)."""
        return np.zeros((batch, 0), dtype=bool)

    def read(self, x_prev: FloatArray, x: FloatArray, latent: BoolArray
             ) -> tuple[BoolArray, BoolArray]:
        """Refused: these sensors come from the physics, not from the state."""
        raise TaskError("task franka-scoop: its sensors (r, s, t) are computed by the MuJoCo "
                        "scene from contacts and beads, not from the DS state: run it with "
                        "tli sim franka (its campaigns: tli sim franka --trials N --evidence)")


def physics_sensors(*, dim: int, partition: Any) -> PhysicsSensors:
    """The entry point ``franka-scoop``: the physics task's sensor model (any ``dim``)."""
    return PhysicsSensors()
