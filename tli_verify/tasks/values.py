"""A task's values: goal, starts, perturbation bounds, source, named regions, partition;
the task file's limits and keys (the format: :mod:`tli_verify.tasks.taskfile`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.tasks.regions import Region

__all__ = [
    "DEFAULT_COLORS",
    "MAX_LAG",
    "MAX_LATCHES",
    "MAX_REGIONS",
    "MAX_SENSORS",
    "MAX_TASK_DIM",
    "TASK_KEYS",
    "BoolArray",
    "FloatArray",
    "Goal",
    "IntArray",
    "NamedRegion",
    "Partition",
    "PerturbationBounds",
    "Starts",
    "TaskSource",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]

MAX_TASK_DIM = 32
"""Largest state dimension of a task (the learner's limit, :data:`tli_verify.limits`)."""
MAX_REGIONS = 64
"""Most regions (cells and layers) of one task."""
MAX_LATCHES = 32
"""Most latches of one task."""
MAX_SENSORS = 64
"""Most sensors of one task."""
MAX_LAG = 100_000
"""Largest sensor lag (control steps)."""
TASK_KEYS = ("name", "description", "lag", "dt", "background", "background_color", "spec",
             "sensor_model", "state", "regions", "latches", "sensors", "goal", "starts",
             "perturbations", "demonstrator")
"""The top-level keys of a task file."""
DEFAULT_COLORS = ("#f7e27a", "#f4b6c8", "#9ed99b", "#7aa6f7", "#f7b36b", "#c9a0dc",
                  "#e2574c", "#8dd3c7", "#bebada", "#fdb462")


@dataclass(frozen=True, slots=True)
class Goal:
    """What completes an episode.

    Attributes
    ----------
    modes : tuple of str or None
        Goal modes of the spec (None: the automaton's sink modes).
    sensors : tuple of str
        Sensors that must also read true in a goal mode (a cyclic task's "done").
    """

    modes: tuple[str, ...] | None = None
    sensors: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """``{"modes": [...] or "sinks", "sensors": [...]}``."""
        return {"modes": "sinks" if self.modes is None else list(self.modes),
                "sensors": list(self.sensors)}


@dataclass(frozen=True, slots=True)
class Starts:
    """Where episodes start.

    Attributes
    ----------
    nominal : tuple of tuple of float
        Documented start states (the first is the default start of a campaign).
    region : str or None
        The region random starts are drawn in (None: the whole workspace); only states whose
        first reading the spec's initial assumption allows are used.
    random : bool
        Campaigns draw random starts by default (``[starts] random = true``), though the task
        keeps nominal starts (for ``tli run`` and ``--start``-less tools); without nominal
        starts campaigns draw random starts anyway.
    """

    nominal: tuple[tuple[float, ...], ...] = ()
    region: str | None = None
    random: bool = False


@dataclass(frozen=True, slots=True)
class PerturbationBounds:
    """Perturbation defaults of the task's campaigns (paper Asm. 2).

    Attributes
    ----------
    max_magnitude : float or None
        Largest displacement (None: the workspace's largest side, the paper's "up to the
        dimension of the entire workspace").
    window : int
        Perturbations happen in control steps ``1..window``.
    max_pushes : int
        At most this many per episode.
    """

    max_magnitude: float | None = None
    window: int = 700
    max_pushes: int = 3


@dataclass(frozen=True, slots=True)
class TaskSource:
    """Where a task came from, for the evidence that binds it (``tli gate``).

    Attributes
    ----------
    kind : str
        ``"file"`` (a task file), ``"entry-point"`` (Python, group ``tli_verify.tasks``) or
        ``"code"`` (built in memory, e.g. the single-mode study's random modes; not bindable).
    path : str or None
        The task file.
    sha256 : str or None
        SHA-256 of the task file's bytes.
    entry_point : str or None
        The entry point's name (a ``sensor_model``, or the task itself).
    distribution, version : str or None
        The distribution that provides the entry point, and its version.
    source_sha256 : str or None
        SHA-256 of the source file of the entry point's module.
    """

    kind: str
    path: str | None = None
    sha256: str | None = None
    entry_point: str | None = None
    distribution: str | None = None
    version: str | None = None
    source_sha256: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """The evidence's ``task`` block (paths as given)."""
        out: dict[str, Any] = {"kind": self.kind}
        if self.path is not None:
            out["path"] = self.path
        if self.sha256 is not None:
            out["sha256"] = self.sha256
        if self.entry_point is not None:
            out["entry_point"] = {"name": self.entry_point, "distribution": self.distribution,
                                  "version": self.version,
                                  "source_sha256": self.source_sha256}
        return out


@dataclass(frozen=True, slots=True, eq=False)
class NamedRegion:
    """A region of a task, with its name and picture colour.

    Attributes
    ----------
    name : str
    region : Region
    color : str
    layer : bool
        A layer is read by formulas but is not a cell of the partition.
    """

    name: str
    region: Region
    color: str
    layer: bool = False


@dataclass(frozen=True, slots=True, eq=False)
class Partition:
    """The true regions of a task: a state lies in the first listed region holding it, else
    in the background; layers are read separately.

    Attributes
    ----------
    cells : tuple of NamedRegion
        In priority order.
    background : str
    background_color : str
    layers : tuple of NamedRegion
    """

    cells: tuple[NamedRegion, ...]
    background: str
    background_color: str
    layers: tuple[NamedRegion, ...] = ()

    @property
    def names(self) -> tuple[str, ...]:
        """Cell names in index order, the background last."""
        return (*(c.name for c in self.cells), self.background)

    def index(self, X: npt.ArrayLike) -> IntArray:
        """Cell index of each state, shape (N,) (``len(cells)``: the background)."""
        Xa = np.asarray(X, dtype=np.float64)
        shape = Xa.shape[:-1]
        flat = Xa.reshape(-1, Xa.shape[-1])
        idx = np.full(len(flat), len(self.cells), dtype=np.int64)
        for k in range(len(self.cells) - 1, -1, -1):
            idx[self.cells[k].region.contains(flat)] = k
        return idx.reshape(shape)

    def one(self, x: Sequence[float]) -> int:
        """:meth:`index` of one state, in plain Python."""
        for k, c in enumerate(self.cells):
            if c.region.contains_one(x):
                return k
        return len(self.cells)

    def membership(self, X: FloatArray, names: frozenset[str]) -> dict[str, BoolArray]:
        """``name -> (N,) bool`` for the cells and layers in ``names``."""
        out: dict[str, BoolArray] = {}
        cell_names = self.names
        wanted = [n for n in cell_names if n in names]
        if wanted:
            idx = self.index(X)
            for n in wanted:
                out[n] = np.asarray(idx == cell_names.index(n))
        for layer in self.layers:
            if layer.name in names:
                out[layer.name] = layer.region.contains(X)
        return out
