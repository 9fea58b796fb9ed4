"""Adapt a task (:mod:`tli_verify.tasks`) to the executive's :class:`SensorModel`.

Imports go one way: the runtime consumes tasks; tasks never import the runtime.

A task's sensor model is batched and stateful (:meth:`tli_verify.tasks.task.Task.read`:
``(x_prev, x, latent) -> (reading, latent)``, with a lag of ``L`` steps: the reading at step
``k`` is computed from the state at step ``max(k - L, 0)``). :class:`TaskSensors` keeps one
episode's history and latent state and answers ``read(x)`` once per control step, exactly as
:meth:`~tli_verify.tasks.task.Task.sensors` scans a whole history.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from tli_verify.tasks.task import Task

__all__ = ["TaskSensors"]

FloatArray = npt.NDArray[np.float64]


Key = tuple[int, int, tuple[bool, ...]]
Hit = tuple[dict[str, bool], tuple[bool, ...], frozenset[str]]
"""A memoized reading: name -> value, the latent state after it, the set of true sensors."""


class TaskSensors:
    """One episode's sensor model of a task (the runtime's ``SensorModel`` protocol).

    Parameters
    ----------
    task : Task
        Its ``lag`` is honoured.
    cache : dict, optional
        Reading memo shared between episodes of one task (see Notes); default: its own.
    region_cache : bool, optional
        Memoize ``task.read`` on ``(cells and layers of x_prev, of x, latent)`` (default:
        when the task's sensor model is ``cell_based``).

    Notes
    -----
    ``read(x)`` must be called once per control step, in order (the lag counts calls). The
    latent state (scooping: soup on the spoon) starts at ``task.initial_latent`` on
    :meth:`reset`.

    A task file's sensors (formulas over regions and latches) depend on the states only through
    the partition cell and the layers they lie in (``Task.reading_key_one``) and on the latent
    state, so one reading per ``(key before, key now, latent)`` is exact and saves the batched
    call's overhead on a single state (about 30 of 40 microseconds per step); a Python sensor
    model that is not ``cell_based`` is read every step. A shared ``cache`` must only be
    shared by sensors of the same task.
    """

    __slots__ = ("_cache", "_hist", "_latent", "_one", "_prev", "names", "region_cache",
                 "task")

    def __init__(self, task: Task, *, cache: dict[Key, Hit] | None = None,
                 region_cache: bool | None = None) -> None:
        self.task = task
        self.names = tuple(task.sensor_names)
        if region_cache is None:
            region_cache = bool(getattr(task.sensor_model, "cell_based", False))
        self.region_cache = bool(region_cache)
        self._cache = {} if cache is None else cache
        self._hist: deque[tuple[FloatArray, int]] = deque(maxlen=task.lag + 1)  # (x (n,), region)
        self._latent: tuple[bool, ...] = tuple(task.initial_latent(1)[0].tolist())
        self._prev: tuple[FloatArray, int] | None = None
        self._one: Callable[[list[float]], int] | None = getattr(task, "reading_key_one",
                                                                 None)

    def reset(self, x0: FloatArray) -> None:
        """Start an episode at ``x0`` (history and latent state cleared)."""
        self._hist.clear()
        self._latent = tuple(self.task.initial_latent(1)[0].tolist())
        self._prev = None

    def read(self, x: FloatArray) -> dict[str, bool]:
        """The reading at this step (from the state ``lag`` calls back), name -> value."""
        xa = np.array(x, dtype=np.float64).reshape(-1)  # a copy: callers update x in place
        return dict(self._advance(xa, xa.tolist() if self._one is not None else None)[0])

    def read_set(self, x: FloatArray, point: list[float]) -> frozenset[str]:
        """:meth:`read`, as the set of true sensors, for the batched loop.

        Parameters
        ----------
        x : ndarray, shape (n,)
            The state; kept (not copied) in the lag history, so the caller must not update
            it in place.
        point : list of float, length n
            ``x.tolist()``.

        Returns
        -------
        frozenset of str
        """
        return self._advance(x, point)[2]

    def _advance(self, xa: FloatArray, point: list[float] | None
                 ) -> tuple[dict[str, bool], tuple[bool, ...], frozenset[str]]:
        if not self.region_cache:
            region = -1
        elif self._one is not None and point is not None:
            region = self._one(point)  # the task's scalar cell-and-layers key
        else:
            region = self.task.reading_key_one(xa.tolist())
        self._hist.append((xa, region))
        lagged = self._hist[0]  # maxlen = lag + 1: the state lag steps back (or the first)
        prev = lagged if self._prev is None else self._prev
        self._prev = lagged
        key = (prev[1], lagged[1], self._latent)
        hit = self._cache.get(key) if self.region_cache else None
        if hit is None:
            reading, latent = self.task.read(prev[0][None, :], lagged[0][None, :],
                                              np.array([self._latent], dtype=bool))
            values = {n: bool(v) for n, v in zip(self.names, reading[0].tolist(), strict=True)}
            hit = (values, tuple(bool(v) for v in latent[0].tolist()),
                   frozenset(n for n, v in values.items() if v))
            if self.region_cache:
                self._cache[key] = hit
        self._latent = hit[1]
        return hit

    @property
    def latent(self) -> dict[str, bool]:
        """The latent state after the last reading (name -> value)."""
        return dict(zip(self.task.latent_names, self._latent, strict=True))
