"""How a task reads its sensors: the :class:`SensorModel` protocol, sensor formulas and
latches (:class:`FormulaSensors`), and a plug-in's guard (:class:`PluginSensors`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from tli_verify.errors import TaskError
from tli_verify.tasks import formula as fml
from tli_verify.tasks.values import (
    BoolArray,
    FloatArray,
    Partition,
)

__all__ = [
    "FormulaSensors",
    "Latch",
    "PluginSensors",
    "SensorModel",
]


@runtime_checkable
class SensorModel(Protocol):
    """What computes a task's sensor readings (the spec's inputs) from its states.

    ``read`` is one step, vectorised over a batch of episodes: ``(x_prev, x, latent) ->
    (reading, latent)`` with ``x_prev`` and ``x`` of shape (B, n) (``x_prev`` is ``x`` at
    the first step), ``latent`` (B, L) bool, ``reading`` (B, m) bool in :attr:`sensor_names`
    order. ``cell_based`` says whether the reading depends on the states only through the
    partition cells and layers they lie in (then the closed loop may memoize readings). A
    sensor model may also have ``physics = True``: its readings come from a simulator, and its
    campaigns are physical ones (``tli evidence``).
    """

    @property
    def sensor_names(self) -> tuple[str, ...]: ...

    @property
    def latent_names(self) -> tuple[str, ...]: ...

    @property
    def cell_based(self) -> bool: ...

    def initial_latent(self, batch: int) -> BoolArray: ...

    def read(self, x_prev: FloatArray, x: FloatArray, latent: BoolArray
             ) -> tuple[BoolArray, BoolArray]: ...


def _raised(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    if len(text) > 200:
        text = text[:197] + "..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


class PluginSensors:
    """A plug-in's sensor model behind a guard: whatever the plug-in raises -- ``SystemExit``
    included -- or returns in the wrong shape is a :class:`~tli_verify.errors.TaskError` naming
    the plug-in and the task file (exit 2, or a blocked gate), never the end of the process or
    an internal error. Other attributes (``physics``) are the plug-in's own.

    Parameters
    ----------
    model : SensorModel
        What the entry point built.
    name : str
        The entry point's name.
    where : str
        The task file that names it.
    """

    __slots__ = ("_model", "_name", "_where", "cell_based", "latent_names", "sensor_names")

    def __init__(self, model: Any, *, name: str, where: str) -> None:
        self._model = model
        self._name = name
        self._where = where
        self.sensor_names = self._names("sensor_names")
        self.latent_names = self._names("latent_names")
        self.cell_based = bool(self._call("cell_based", lambda: bool(model.cell_based)))

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("_"):
            raise AttributeError(attr)
        return getattr(self._model, attr)

    def __getstate__(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__slots__}

    def __setstate__(self, state: dict[str, Any]) -> None:
        for k, v in state.items():
            object.__setattr__(self, k, v)

    def _fail(self, what: str) -> TaskError:
        return TaskError(f"{self._where}: sensor_model {self._name!r}: {what}")

    def _call(self, what: str, fn: Callable[[], Any]) -> Any:
        try:
            return fn()
        except KeyboardInterrupt:
            raise
        except BaseException as exc:  # SystemExit and GeneratorExit too
            raise self._fail(f"{what} raised {_raised(exc)}") from None

    def _names(self, attr: str) -> tuple[str, ...]:
        names = self._call(attr, lambda: tuple(getattr(self._model, attr)))
        if not all(isinstance(n, str) and n for n in names):
            raise self._fail(f"{attr} must be non-empty strings, got {list(names)!r}")
        if len(set(names)) != len(names):
            raise self._fail(f"{attr} names a sensor twice: {list(names)!r}")
        return tuple(names)

    def _bools(self, value: Any, what: str, shape: tuple[int, int]) -> BoolArray:
        try:
            arr = np.asarray(value)
        except Exception as exc:
            raise self._fail(f"{what} is not an array ({_raised(exc)})") from None
        if arr.shape != shape:
            raise self._fail(f"{what} has shape {arr.shape}, expected {shape} (batch, "
                             "one column per name)")
        if arr.dtype != bool:
            if arr.dtype.kind not in "biu" or not np.isin(arr, (0, 1)).all():
                raise self._fail(f"{what} must be booleans, got dtype {arr.dtype}")
            arr = arr.astype(bool)
        return arr

    def initial_latent(self, batch: int) -> BoolArray:
        """The plug-in's initial latent state, checked: shape (batch, L) bool."""
        value = self._call("initial_latent()", lambda: self._model.initial_latent(batch))
        return self._bools(value, "initial_latent()", (batch, len(self.latent_names)))

    def read(self, x_prev: FloatArray, x: FloatArray, latent: BoolArray
             ) -> tuple[BoolArray, BoolArray]:
        """One step of the plug-in, checked: a (reading (B, m), latent (B, L)) pair."""
        out = self._call("read()", lambda: self._model.read(x_prev, x, latent))
        if not isinstance(out, tuple | list) or len(out) != 2:
            raise self._fail(f"read() returned {type(out).__name__}, expected a (reading, "
                             "latent) pair")
        batch = int(np.shape(x)[0])
        reading = self._bools(out[0], "read()'s reading", (batch, len(self.sensor_names)))
        lat = self._bools(out[1], "read()'s latent", (batch, len(self.latent_names)))
        return reading, lat


@dataclass(frozen=True, slots=True, eq=False)
class Latch:
    """A history variable: ``value = set | (prev(value) & !reset)``, ``initial`` at the start.

    Attributes
    ----------
    name : str
    initial : bool
    set, reset : Formula
    """

    name: str
    initial: bool
    set: fml.Formula
    reset: fml.Formula


@dataclass(frozen=True, slots=True, eq=False)
class FormulaSensors:
    """The sensor model of a task file: formulas over regions and latches (module docstring).

    Attributes
    ----------
    partition : Partition
    formulas : tuple of (str, Formula)
        Sensor name -> formula, in column order.
    latches : tuple of Latch
    """

    partition: Partition
    formulas: tuple[tuple[str, fml.Formula], ...]
    latches: tuple[Latch, ...] = ()
    cell_based: bool = True
    _now: frozenset[str] = field(default=frozenset(), repr=False)
    _prev: frozenset[str] = field(default=frozenset(), repr=False)

    def __post_init__(self) -> None:
        regions = set(self.partition.names) | {la.name for la in self.partition.layers}
        now: set[str] = set()
        prev: set[str] = set()
        every = [f for _, f in self.formulas]
        for la in self.latches:
            every += [la.set, la.reset]
        for f in every:
            now |= f.now & regions
            prev |= f.prev & regions
        object.__setattr__(self, "_now", frozenset(now))
        object.__setattr__(self, "_prev", frozenset(prev))

    @property
    def sensor_names(self) -> tuple[str, ...]:
        """The sensors, in column order."""
        return tuple(n for n, _ in self.formulas)

    @property
    def latent_names(self) -> tuple[str, ...]:
        """The latches, in column order."""
        return tuple(la.name for la in self.latches)

    def initial_latent(self, batch: int) -> BoolArray:
        """Every latch's initial value, shape (batch, L)."""
        return np.tile(np.array([la.initial for la in self.latches], dtype=bool), (batch, 1))

    def read(self, x_prev: FloatArray, x: FloatArray, latent: BoolArray
             ) -> tuple[BoolArray, BoolArray]:
        """One sensor step (:class:`SensorModel`)."""
        B = len(x)
        now: dict[str, BoolArray] = dict(self.partition.membership(x, self._now))
        prev: dict[str, BoolArray] = dict(self.partition.membership(x_prev, self._prev))
        for j, la in enumerate(self.latches):
            prev[la.name] = latent[:, j]
        for la in self.latches:
            now[la.name] = la.set.evaluate(now, prev, B) | (
                prev[la.name] & ~la.reset.evaluate(now, prev, B))
        reading = np.zeros((B, len(self.formulas)), dtype=bool)
        for i, (_, f) in enumerate(self.formulas):
            reading[:, i] = f.evaluate(now, prev, B)
        new = np.zeros((B, len(self.latches)), dtype=bool)
        for j, la in enumerate(self.latches):
            new[:, j] = now[la.name]
        return reading, new


