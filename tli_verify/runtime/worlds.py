"""Adapt a task world (:mod:`tli_verify.worlds`) to the executive's :class:`SensorModel`.

Imports go one way: the runtime consumes worlds (this module imports
:mod:`tli_verify.worlds.base` for the protocol only); worlds never import the runtime.

A world's sensor model is batched and stateful (:meth:`tli_verify.worlds.base.WorldBase.read`:
``(x_prev, x, latent) -> (reading, latent)``, with a lag of ``L`` steps: the reading at step
``k`` is computed from the state at step ``max(k - L, 0)``). :class:`WorldSensors` keeps one
episode's history and latent state and answers ``read(x)`` once per control step, exactly as
:meth:`~tli_verify.worlds.base.WorldBase.sensors` scans a whole history.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import numpy.typing as npt

from tli_verify.worlds.base import World

__all__ = ["WorldSensors"]

FloatArray = npt.NDArray[np.float64]


class WorldSensors:
    """One episode's sensor model of a world (the runtime's ``SensorModel`` protocol).

    Parameters
    ----------
    world : World
        E.g. :class:`tli_verify.worlds.ScoopWorld`; its ``lag`` is honoured.

    Notes
    -----
    ``read(x)`` must be called once per control step, in order (the lag counts calls). The
    latent state (scooping: soup on the spoon) starts at ``world.initial_latent`` on
    :meth:`reset`.
    """

    __slots__ = ("_hist", "_latent", "_prev", "names", "world")

    def __init__(self, world: World) -> None:
        self.world = world
        self.names = tuple(world.sensor_names)
        self._hist: deque[FloatArray] = deque(maxlen=world.lag + 1)
        self._latent = world.initial_latent(1)
        self._prev: FloatArray | None = None

    def reset(self, x0: FloatArray) -> None:
        """Start an episode at ``x0`` (history and latent state cleared)."""
        self._hist.clear()
        self._latent = self.world.initial_latent(1)
        self._prev = None

    def read(self, x: FloatArray) -> dict[str, bool]:
        """The reading at this step (from the state ``lag`` calls back), name -> value."""
        xa = np.array(x, dtype=np.float64).reshape(1, -1)  # a copy: callers update x in place
        self._hist.append(xa)
        lagged = self._hist[0]  # maxlen = lag + 1: the state lag steps back (or the first)
        prev = lagged if self._prev is None else self._prev
        reading, self._latent = self.world.read(prev, lagged, self._latent)
        self._prev = lagged
        return {n: bool(v) for n, v in zip(self.names, reading[0].tolist(), strict=True)}

    @property
    def latent(self) -> dict[str, bool]:
        """The latent world state after the last reading (name -> value)."""
        return {n: bool(v) for n, v in
                zip(self.world.latent_names, self._latent[0].tolist(), strict=True)}
