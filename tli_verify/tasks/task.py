"""A task as data: state space, regions, sensors, goal, starts, perturbations, demonstrator.

A task file (TOML, schema ``tli_verify/schemas/task.schema.json``) declares everything the
closed loop, the campaigns and the pictures need about a user's task, in any dimension ``n``;
the spec (``specs/*.toml``) says what to do, the task says what the world is. The paper's four
worlds ship as task files (``tasks/scoop.toml``, ``cooking.toml``, ``color-tracing.toml``,
``inspection.toml``). The format::

    name = "drawer"
    description = "approach the handle, pull the drawer open, retract"
    lag = 0                       # sensor lag in control steps
    dt = 0.01                     # control period (s); a certificate must cover it
    background = "free"           # the region of every state no listed region contains
    spec = "../specs/drawer.toml" # optional: the default spec of `tli run --task drawer`

    [state]
    names = ["x", "y", "z"]       # n = 3 (default names x0, x1, ...)
    lower = [-1.0, -1.0, 0.0]     # the workspace box
    upper = [1.0, 1.0, 1.0]

    [regions.handle]              # listed in priority order: a state is in the FIRST listed
    box = { lower = [0.4, -0.1, 0.3], upper = [0.6, 0.1, 0.5] }   # region holding it
    color = "#f7e27a"
    [regions.zone]
    ball = { center = [0, 0, 0.5], radius = 0.3 }
    layer = true                  # a layer: read by formulas, not a cell of the partition

    [latches.pulled]              # history: value = set | (prev(value) & !reset)
    initial = false
    set = "handle & prev(handle)"
    reset = "false"

    [sensors]                     # the spec's inputs: formulas over regions and latches
    h = "handle"
    p = "pulled & !handle"

    [goal]                        # what completes an episode (default: the automaton's
    modes = ["c"]                 # sink modes); sensors that must also read true
    sensors = []

    [starts]
    nominal = [[-0.5, 0.0, 0.5]]  # the default start of `tli verify`
    region = "free"               # random starts are drawn here (default: the workspace)

    [perturbations]               # the defaults of `tli verify`
    max_magnitude = 2.0           # default: the workspace's largest side
    window = 700
    max_pushes = 3

    [demonstrator]                # optional: `tli demos TASK` (tli_verify.tasks.demonstrator)
    count = 3
    duration = 8.0
    dt = 0.05
    sigma = 0.02
    [[demonstrator.scripts]]
    start = [-0.5, 0.0, 0.5]
    start_jitter = 0.05
    waypoints = [[0.5, 0.0, 0.4], [0.5, 0.0, 0.8]]
    jitter = [1.0, 0.0]

Sensor and latch formulas (:mod:`tli_verify.tasks.formula`) read a region name as "the state
lies in that cell of the partition" (or in that layer), ``prev(NAME)`` one step before (the
current state at the first step), a latch name as the latch's value: in a latch's own
``set``/``reset`` only latches declared before it may be read without ``prev``. Latches update
in order, then the sensors are read. A reading at control step ``k`` is computed from the state
``lag`` steps back.

A task may compute its sensors in Python instead (``sensor_model = "NAME"``: an entry point of
group ``tli_verify.tasks``, :mod:`tli_verify.tasks.registry`), for sensors physics computes.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation", CoRL 2022: Sec. 3 (modes as sets
of states sharing a sensor reading, sigma = L(alpha)), Sec. 7 and the appendices (the worlds),
Asm. 2 (finitely many perturbations).
"""

from __future__ import annotations

import hashlib
import os
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from tli_verify.defaults import DEFAULT_DT_FLOAT
from tli_verify.demos import Demonstration
from tli_verify.errors import TaskError, TliError, bad_type
from tli_verify.tasks import formula as fml
from tli_verify.tasks.demonstrator import Demonstrator, parse_demonstrator
from tli_verify.tasks.fields import number, vector
from tli_verify.tasks.regions import Primitive, Region, parse_region

__all__ = [
    "MAX_TASK_DIM",
    "TASK_KEYS",
    "FormulaSensors",
    "Goal",
    "Latch",
    "NamedRegion",
    "Partition",
    "PerturbationBounds",
    "SensorModel",
    "Starts",
    "Task",
    "TaskSource",
    "load_task",
    "number",
    "parse_task",
    "vector",
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


# ------------------------------------------------------------------------------ values
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


# ------------------------------------------------------------------------------ the task
@dataclass(frozen=True, slots=True, eq=False)
class Task:
    """A task: everything the closed loop, the campaigns and the pictures need about the world.

    It is the world of the runtime, the campaigns and the oracle: the members below are what
    they use (true regions, a vectorised sensor model with a lag, the workspace box).

    Attributes
    ----------
    name : str
    description : str
    state_names : tuple of str
        Display names of the ``n`` coordinates.
    lo, hi : tuple of float
        The workspace box.
    partition : Partition
        The true regions (hidden from the learner).
    sensor_model : SensorModel
    lag : int
        Sensor lag in control steps.
    dt : float
        Control period (s).
    goal : Goal
    starts : Starts
    perturbations : PerturbationBounds
    demonstrator : Demonstrator or None
    source : TaskSource
    spec : str or None
        The default spec (a path; relative paths are relative to the task file).
    """

    name: str
    description: str
    state_names: tuple[str, ...]
    lo: tuple[float, ...]
    hi: tuple[float, ...]
    partition: Partition
    sensor_model: SensorModel
    lag: int = 0
    dt: float = DEFAULT_DT_FLOAT
    goal: Goal = field(default_factory=Goal)
    starts: Starts = field(default_factory=Starts)
    perturbations: PerturbationBounds = field(default_factory=PerturbationBounds)
    demonstrator: Demonstrator | None = None
    source: TaskSource = field(default_factory=lambda: TaskSource("code"))
    spec: str | None = None

    # ------------------------------------------------------------------ shape
    @property
    def dim(self) -> int:
        """State dimension n."""
        return len(self.lo)

    @property
    def where(self) -> str:
        """The task file (or ``task NAME``) for messages."""
        return self.source.path or f"task {self.name!r}"

    @property
    def sensor_names(self) -> tuple[str, ...]:
        """The spec inputs the task reads, in column order."""
        return tuple(self.sensor_model.sensor_names)

    @property
    def latent_names(self) -> tuple[str, ...]:
        """The latent (history) variables, in column order."""
        return tuple(self.sensor_model.latent_names)

    @property
    def region_names(self) -> tuple[str, ...]:
        """The true regions in index order (:meth:`region_index`), the background last."""
        return self.partition.names

    @property
    def region_colors(self) -> tuple[str, ...]:
        """Picture colours of :attr:`region_names`."""
        return (*(c.color for c in self.partition.cells), self.partition.background_color)

    @property
    def size(self) -> float:
        """The workspace's largest side (the paper's perturbation magnitude bound)."""
        return float(np.max(np.asarray(self.hi) - np.asarray(self.lo)))

    @property
    def spec_path(self) -> Path | None:
        """The default spec, resolved against the task file's folder."""
        if self.spec is None:
            return None
        p = Path(self.spec)
        if not p.is_absolute() and self.source.path is not None:
            p = Path(self.source.path).parent / p
        return p

    def with_lag(self, lag: int) -> Task:
        """The same task with another sensor lag."""
        if not isinstance(lag, int) or isinstance(lag, bool) or not 0 <= lag <= MAX_LAG:
            raise TaskError(f"{self.where}: sensor lag must be an integer in [0, {MAX_LAG}], "
                            f"got {lag!r}")
        return self if lag == self.lag else replace(self, lag=lag)

    # ------------------------------------------------------------------ regions
    def region_index(self, X: npt.ArrayLike) -> IntArray:
        """Index into :attr:`region_names` of the true region of each state, shape (N,)."""
        return self.partition.index(self._states(X))

    def region_one(self, x: Sequence[float]) -> int:
        """:meth:`region_index` of one state (a list of floats), in plain Python."""
        return self.partition.one(x)

    def reading_key_one(self, x: Sequence[float]) -> int:
        """A key of what the sensors see of one state: its cell and its layers (bits)."""
        key = self.partition.one(x)
        shift = len(self.partition.cells) + 1
        for i, layer in enumerate(self.partition.layers):
            if layer.region.contains_one(x):
                key += shift << i
        return key

    def true_mode(self, X: npt.ArrayLike) -> npt.NDArray[np.str_]:
        """Name of the true region of each state, shape (N,)."""
        return np.asarray(self.region_names, dtype=np.str_)[self.region_index(X)]

    def region_masks(self, X: npt.ArrayLike) -> dict[str, BoolArray]:
        """Membership of every true region, ``{name: (N,) bool}`` (a partition)."""
        idx = self.region_index(X)
        return {name: np.asarray(idx == i) for i, name in enumerate(self.region_names)}

    def in_region(self, name: str, X: npt.ArrayLike) -> BoolArray:
        """Membership of one true region (or layer), shape (N,)."""
        if name in self.region_names:
            return np.asarray(self.region_index(X) == self.region_names.index(name))
        for layer in self.partition.layers:
            if layer.name == name:
                return layer.region.contains(self._states(X))
        raise TaskError(f"{self.where}: no region {name!r} (regions: "
                        f"{', '.join(self.region_names)})")

    def in_workspace(self, X: npt.ArrayLike) -> BoolArray:
        """Whether each state lies in the workspace box, shape (N,)."""
        Xa = np.asarray(X, dtype=np.float64)
        return np.asarray(np.all((Xa >= np.array(self.lo)) & (Xa <= np.array(self.hi)),
                                 axis=-1))

    def _region_box(self, name: str) -> tuple[FloatArray, FloatArray]:
        lo, hi = np.array(self.lo), np.array(self.hi)
        for nr in (*self.partition.cells, *self.partition.layers):
            if nr.name == name:
                rlo, rhi = nr.region.bounds()
                return np.maximum(lo, rlo), np.minimum(hi, rhi)
        return lo, hi

    def sample_region(self, name: str, count: int, rng: np.random.Generator) -> FloatArray:
        """``count`` uniform random states of a true region (or layer), shape (count, n), by
        rejection: from the workspace box, or, for a region whose bounding box fills less than
        1/64 of it, from that box within the workspace (both are uniform in the region; the
        first is the former worlds' stream of draws, which seeded anchors rely on).

        Raises
        ------
        TaskError
            Unknown region, or one too small to hit (about 1e-4 of its box) or outside the
            workspace.
        """
        if name not in self.region_names and all(la.name != name
                                                 for la in self.partition.layers):
            raise TaskError(f"{self.where}: no region {name!r} (regions: "
                            f"{', '.join(self.region_names)})")
        lo, hi = np.array(self.lo), np.array(self.hi)
        blo, bhi = self._region_box(name)
        if not np.all(blo <= bhi):
            raise TaskError(f"{self.where}: region {name!r} lies outside the workspace")
        small = float(np.prod(bhi - blo)) < float(np.prod(hi - lo)) / 64.0
        if small:
            lo, hi = blo, bhi
        out: list[FloatArray] = []
        got = 0
        for _ in range(200):
            X = rng.uniform(lo, hi, size=(max(4 * count, 64), lo.size))
            ok = X[self.in_region(name, X)]
            out.append(ok)
            got += len(ok)
            if got >= count:
                return np.concatenate(out)[:count]
        raise TaskError(f"{self.where}: cannot sample {count} states of region {name!r} "
                        "(too small within the workspace)")

    def clearance(self, x: npt.ArrayLike) -> float:
        """Radius of a ball around ``x`` inside its true region (and its layers), exact for a
        region that is one convex shape, a guaranteed lower bound otherwise.

        The ball meets no boundary of a shape that decides membership of ``x``'s cell (the
        cells listed before it, its own, every one for the background) or of a layer: so every
        state in it lies in the same cell and layers, and the sensors' region terms read the
        same there (the oracle's certified-deadline target, paper Lemma 2). Capped at the
        workspace's largest side.

        Parameters
        ----------
        x : array_like, shape (n,)

        Returns
        -------
        float
        """
        xa = self._states(x, "x", finite=True).reshape(1, -1)
        k = int(self.partition.index(xa)[0])
        cells = self.partition.cells[:k + 1]
        leaves: list[Primitive] = []
        for nr in (*cells, *self.partition.layers):
            leaves += [leaf for leaf in nr.region.leaves() if all(leaf is not q for q in leaves)]
        best = self.size
        for leaf in leaves:
            best = min(best, abs(float(leaf.signed_distance(xa)[0])))
        return best

    # ------------------------------------------------------------------ sensors
    def initial_latent(self, batch: int) -> BoolArray:
        """The latent state at the start of an episode, shape (batch, L)."""
        return np.asarray(self.sensor_model.initial_latent(batch), dtype=bool)

    def read(self, x_prev: FloatArray, x: FloatArray, latent: BoolArray
             ) -> tuple[BoolArray, BoolArray]:
        """One step of the sensor model (:class:`SensorModel`), vectorised over a batch."""
        return self.sensor_model.read(x_prev, x, latent)

    def sensors(self, X: npt.ArrayLike, latent: npt.ArrayLike | None = None) -> BoolArray:
        """Sensor readings along a state history, with the task's lag.

        Parameters
        ----------
        X : array_like, shape (T, n) or (B, T, n)
        latent : array_like of bool, shape (L,) or (B, L), optional
            Latent state before the first reading (default :meth:`initial_latent`).

        Returns
        -------
        ndarray of bool, shape (T, m) or (B, T, m)
        """
        readings, _ = self.sensors_and_latent(X, latent)
        return readings

    def sensors_and_latent(self, X: npt.ArrayLike, latent: npt.ArrayLike | None = None
                           ) -> tuple[BoolArray, BoolArray]:
        """:meth:`sensors` plus the latent state after every reading.

        Returns
        -------
        readings : ndarray of bool, shape (T, m) or (B, T, m)
        latents : ndarray of bool, shape (T, L) or (B, T, L)
        """
        try:
            Xa = np.asarray(X, dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            raise bad_type(TaskError, f"{self.where}: X: expected states (numbers), got "
                           f"{type(X).__name__}") from None
        single = Xa.ndim == 2
        if single:
            Xa = Xa[None]
        if Xa.ndim != 3 or Xa.shape[1] < 1 or Xa.shape[2] != self.dim:
            raise TaskError(f"{self.where}: states must be (T, {self.dim}) or "
                            f"(B, T, {self.dim}), got {np.shape(X)}")
        if not np.isfinite(Xa).all():
            raise TaskError(f"{self.where}: X: NaN or infinite coordinates")
        B, T, _ = Xa.shape
        L = len(self.latent_names)
        lat = (self.initial_latent(B) if latent is None
               else np.broadcast_to(np.asarray(latent, dtype=bool), (B, L)).copy())
        lagged = Xa[:, np.maximum(np.arange(T) - self.lag, 0)]
        readings = np.zeros((B, T, len(self.sensor_names)), dtype=bool)
        latents = np.zeros((B, T, L), dtype=bool)
        for k in range(T):
            prev = lagged[:, max(k - 1, 0)]
            readings[:, k], lat = self.read(prev, lagged[:, k], lat)
            latents[:, k] = lat
        if single:
            return readings[0], latents[0]
        return readings, latents

    # ------------------------------------------------------------------ demonstrations
    def demonstrate(self, seed: int, n_demos: int | None = None) -> list[Demonstration]:
        """Seeded scripted demonstrations (:class:`~tli_verify.tasks.demonstrator.Demonstrator`).

        Raises
        ------
        TaskError
            The task has no demonstrator.
        """
        if self.demonstrator is None:
            raise TaskError(f"{self.where}: no [demonstrator] table")
        return self.demonstrator.demonstrate(self, seed, n_demos)

    def _states(self, X: npt.ArrayLike, name: str = "states", *, finite: bool = False
                ) -> FloatArray:
        """``X`` as float states of this task's dimension (the boundary check of every public
        method that takes states); ``finite``: NaN and infinities refused too (region tests
        classify them, a clearance or a sensor reading of them means nothing)."""
        try:
            Xa = np.asarray(X, dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            raise bad_type(TaskError, f"{self.where}: {name}: expected numbers, got "
                           f"{type(X).__name__}") from None
        if Xa.shape[-1:] != (self.dim,):
            raise TaskError(f"{self.where}: {name} must have {self.dim} coordinates, got "
                            f"shape {Xa.shape}")
        if finite and not np.isfinite(Xa).all():
            raise TaskError(f"{self.where}: {name}: NaN or infinite coordinates")
        return Xa


# ------------------------------------------------------------------------------ parsing
def _keys(raw: Any, allowed: Sequence[str], where: str) -> Mapping[str, Any]:
    if not isinstance(raw, dict):
        raise TaskError(f"{where}: expected a table")
    unknown = sorted(set(raw) - set(allowed))
    if unknown:
        raise TaskError(f"{where}: unknown key {unknown[0]!r} (allowed: {', '.join(allowed)})")
    return raw


def _text(raw: Any, where: str, *, limit: int = 200, one_line: bool = True) -> str:
    if not isinstance(raw, str) or len(raw) > limit or (one_line and any(
            ord(ch) < 0x20 or 0x7F <= ord(ch) < 0xA0 for ch in raw)):
        raise TaskError(f"{where}: expected {'one line of ' if one_line else ''}text of at "
                        f"most {limit} characters")
    return raw


def _name(raw: Any, where: str) -> str:
    if not isinstance(raw, str) or not fml.is_name(raw) or len(raw) > 64:
        raise TaskError(f"{where}: {raw!r} is not a valid name (an identifier: letters, "
                        "digits and _, not true/false/prev, at most 64 characters)")
    return raw


def load_task(path: str | os.PathLike[str], *,
              entry_points: Callable[[str], object] | None = None) -> Task:
    """Load and validate a task file.

    Parameters
    ----------
    path : path-like
    entry_points : callable, optional
        ``name -> object`` resolving a ``sensor_model`` entry point (default:
        :func:`tli_verify.tasks.plugins.entry_point`).

    Raises
    ------
    TaskError
        (exit 2) Naming the file and the field of the first problem.
    """
    from tli_verify.io import read_text

    text = read_text(path, what="task", error=TaskError)
    return parse_task(text, path=str(path), entry_points=entry_points)


def parse_task(text: str, *, path: str | None = None,
               entry_points: Callable[[str], Any] | None = None) -> Task:
    """Parse the TOML text of a task file (module docstring).

    Raises
    ------
    TaskError
        (exit 2) Naming the file and the field.
    """
    from tli_verify.io import check_numbers, validate_schema

    where = path or "<task>"
    if not text.strip():
        raise TaskError(f"{where}: empty task file")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise TaskError(f"{where}: invalid TOML: {exc}") from None
    except RecursionError:
        raise TaskError(f"{where}: arrays or tables nested too deeply") from None
    except ValueError as exc:  # an integer of more than 4300 digits
        raise TaskError(f"{where}: invalid TOML: {exc}") from None
    check_numbers(data, where=where, error=TaskError)
    task = _build(data, where, text, path, entry_points)
    validate_schema(data, "task.schema.json", where=where, error=TaskError)
    return task


def _build(data: Mapping[str, Any], where: str, text: str, path: str | None,
           entry_points: Callable[[str], Any] | None) -> Task:
    _keys(data, TASK_KEYS, where)
    if "name" not in data:
        raise TaskError(f"{where}: missing 'name'")
    name = _text(data["name"], f"{where}: name", limit=100)
    if not name.strip():
        raise TaskError(f"{where}: name: must not be empty")
    description = _text(data.get("description", ""), f"{where}: description", limit=10_000,
                        one_line=False)
    if "state" not in data:
        raise TaskError(f"{where}: missing the [state] table (the workspace box: lower, upper; "
                        "optional names)")
    st = _keys(data["state"], ("names", "lower", "upper"), f"{where}: [state]")
    for k in ("lower", "upper"):
        if k not in st:
            raise TaskError(f"{where}: state.{k}: missing (the workspace box)")
    if not isinstance(st["lower"], list) or not 1 <= len(st["lower"]) <= MAX_TASK_DIM:
        raise TaskError(f"{where}: state.lower: expected 1 to {MAX_TASK_DIM} numbers (the "
                        "dimension n)")
    dim = len(st["lower"])
    lo = vector(st["lower"], dim, f"{where}: state.lower")
    hi = vector(st["upper"], dim, f"{where}: state.upper")
    if not np.all(lo < hi):
        raise TaskError(f"{where}: state: the workspace box needs lower < upper in every "
                        "coordinate")
    names_raw = st.get("names", [f"x{i}" for i in range(dim)])
    if not isinstance(names_raw, list) or len(names_raw) != dim:
        raise TaskError(f"{where}: state.names: expected {dim} names (one per coordinate)")
    state_names = tuple(_text(v, f"{where}: state.names[{i}]", limit=64)
                        for i, v in enumerate(names_raw))
    if len(set(state_names)) != dim:
        raise TaskError(f"{where}: state.names: names must be distinct")
    lag = number(data.get("lag", 0), f"{where}: lag", lo=0, hi=MAX_LAG, integer=True)
    dt = number(data.get("dt", DEFAULT_DT_FLOAT), f"{where}: dt", lo=1e-6, hi=10.0)
    if dt <= 0:
        raise TaskError(f"{where}: dt: must be > 0")
    background = _name(data.get("background", "outside"), f"{where}: background")
    bg_color = _color(data.get("background_color", "#ffffff"), f"{where}: background_color")
    partition = _partition(data.get("regions", {}), dim, background, bg_color, where)
    region_names = set(partition.names) | {la.name for la in partition.layers}
    model: SensorModel
    source = TaskSource("file" if path is not None else "code", path=path,
                        sha256=hashlib.sha256(text.encode("utf-8")).hexdigest()
                        if path is not None else None)
    if "sensor_model" in data:
        for key in ("sensors", "latches"):
            if key in data:
                raise TaskError(f"{where}: [{key}] and sensor_model: the sensors come from one "
                                "of them")
        ep = _text(data["sensor_model"], f"{where}: sensor_model", limit=100)
        model, source = _entry_sensor_model(ep, where, source, entry_points, dim, partition)
    else:
        latches = _latches(data.get("latches", {}), region_names, where)
        model = FormulaSensors(partition, _sensor_formulas(data.get("sensors"), region_names,
                                                          latches, where), latches)
    goal = _goal(data.get("goal", {}), model.sensor_names, where)
    starts = _starts(data.get("starts", {}), dim, lo, hi, partition, where)
    pert = _perturbations(data.get("perturbations", {}), where)
    demo = (parse_demonstrator(data["demonstrator"], dim=dim, where=where)
            if "demonstrator" in data else None)
    spec = data.get("spec")
    if spec is not None:
        spec = _text(spec, f"{where}: spec", limit=1000)
    return Task(name=name, description=description, state_names=state_names,
                lo=tuple(lo.tolist()), hi=tuple(hi.tolist()), partition=partition,
                sensor_model=model, lag=int(lag), dt=dt, goal=goal, starts=starts,
                perturbations=pert, demonstrator=demo, source=source, spec=spec)


def _color(raw: Any, where: str) -> str:
    from matplotlib.colors import is_color_like

    if not isinstance(raw, str) or len(raw) > 40 or not is_color_like(raw):
        raise TaskError(f"{where}: {raw!r} is not a colour (e.g. \"#f7e27a\" or \"tab:blue\")")
    return raw


def _partition(raw: Any, dim: int, background: str, bg_color: str, where: str) -> Partition:
    if not isinstance(raw, dict):
        raise TaskError(f"{where}: [regions]: expected a table of regions")
    if len(raw) > MAX_REGIONS:
        raise TaskError(f"{where}: more than {MAX_REGIONS} regions")
    built: dict[str, Region] = {}
    busy: list[str] = []

    def named(ref: str, at: str) -> Region:
        if ref in built:
            return built[ref]
        if ref in busy:
            raise TaskError(f"{at}: region {ref!r} is defined in terms of itself "
                            f"({' -> '.join([*busy, ref])})")
        if ref not in raw:
            raise TaskError(f"{at}: unknown region {ref!r} (regions: "
                            f"{', '.join(raw) or 'none'})")
        return make(ref)

    def make(rname: str) -> Region:
        busy.append(rname)
        table = raw[rname]
        at = f"{where}: regions.{rname}"
        if not isinstance(table, dict):
            raise TaskError(f"{at}: expected a table with a shape key")
        shape = {k: v for k, v in table.items() if k not in ("color", "layer")}
        region = parse_region(shape, dim=dim, where=at, named=named)
        busy.pop()
        built[rname] = region
        return region

    cells: list[NamedRegion] = []
    layers: list[NamedRegion] = []
    for i, rname in enumerate(raw):
        at = f"{where}: regions.{rname}"
        _name(rname, at)
        if rname == background:
            raise TaskError(f"{at}: {rname!r} is the background's name")
        region = named(rname, at)
        table = raw[rname]
        color = _color(table.get("color", DEFAULT_COLORS[i % len(DEFAULT_COLORS)]),
                       f"{at}.color")
        layer = table.get("layer", False)
        if not isinstance(layer, bool):
            raise TaskError(f"{at}.layer: expected true or false")
        (layers if layer else cells).append(NamedRegion(rname, region, color, layer))
    return Partition(tuple(cells), background, bg_color, tuple(layers))


def _latches(raw: Any, regions: set[str], where: str) -> tuple[Latch, ...]:
    if not isinstance(raw, dict):
        raise TaskError(f"{where}: [latches]: expected a table of latches")
    if len(raw) > MAX_LATCHES:
        raise TaskError(f"{where}: more than {MAX_LATCHES} latches")
    names = list(raw)
    out: list[Latch] = []
    for i, lname in enumerate(names):
        at = f"{where}: latches.{lname}"
        _name(lname, at)
        if lname in regions:
            raise TaskError(f"{at}: {lname!r} is also a region's name")
        table = _keys(raw[lname], ("initial", "set", "reset"), at)
        initial = table.get("initial", False)
        if not isinstance(initial, bool):
            raise TaskError(f"{at}.initial: expected true or false")
        if "set" not in table:
            raise TaskError(f"{at}: missing 'set' (the formula that sets it)")
        every = regions | set(names)
        later = set(names[i:])
        parsed = []
        for key in ("set", "reset"):
            f = fml.parse(table.get(key, "false"), names=every, where=f"{at}.{key}")
            early = sorted(f.now & later)
            if early:
                raise TaskError(f"{at}.{key}: {f.text!r} reads latch {early[0]!r} before it "
                                f"is updated: write prev({early[0]}) (latches update in the "
                                "order listed)")
            parsed.append(f)
        out.append(Latch(lname, initial, parsed[0], parsed[1]))
    return tuple(out)


def _sensor_formulas(raw: Any, regions: set[str], latches: tuple[Latch, ...], where: str
                     ) -> tuple[tuple[str, fml.Formula], ...]:
    from tli_verify.logic.ltl import is_ap_name

    if not isinstance(raw, dict) or not raw:
        raise TaskError(f"{where}: [sensors]: expected a table sensor = formula (the spec's "
                        "inputs)")
    if len(raw) > MAX_SENSORS:
        raise TaskError(f"{where}: more than {MAX_SENSORS} sensors")
    names = regions | {la.name for la in latches}
    out = []
    for sname, text in raw.items():
        at = f"{where}: sensors.{sname}"
        if not is_ap_name(sname):
            raise TaskError(f"{at}: {sname!r} is not a valid sensor (spec input) name")
        out.append((sname, fml.parse(text, names=names, where=at)))
    return tuple(out)


def _goal(raw: Any, sensors: Sequence[str], where: str) -> Goal:
    t = _keys(raw, ("modes", "sensors"), f"{where}: [goal]")
    modes_raw = t.get("modes", "sinks")
    modes: tuple[str, ...] | None
    if modes_raw == "sinks":
        modes = None
    elif isinstance(modes_raw, list) and modes_raw and all(isinstance(m, str) for m in modes_raw):
        modes = tuple(modes_raw)
    else:
        raise TaskError(f"{where}: goal.modes: expected \"sinks\" or a non-empty list of mode "
                        "names")
    gs = t.get("sensors", [])
    if not isinstance(gs, list) or not all(isinstance(s, str) for s in gs):
        raise TaskError(f"{where}: goal.sensors: expected a list of sensor names")
    unknown = [s for s in gs if s not in sensors]
    if unknown:
        raise TaskError(f"{where}: goal.sensors: {unknown[0]!r} is not a sensor of the task "
                        f"({', '.join(sensors)})")
    return Goal(modes, tuple(gs))


def _starts(raw: Any, dim: int, lo: FloatArray, hi: FloatArray, partition: Partition,
            where: str) -> Starts:
    t = _keys(raw, ("nominal", "region", "random"), f"{where}: [starts]")
    nominal_raw = t.get("nominal", [])
    if not isinstance(nominal_raw, list) or len(nominal_raw) > 1000:
        raise TaskError(f"{where}: starts.nominal: expected a list of at most 1000 states")
    nominal = []
    for i, p in enumerate(nominal_raw):
        x = vector(p, dim, f"{where}: starts.nominal[{i}]")
        if not np.all((x >= lo) & (x <= hi)):
            raise TaskError(f"{where}: starts.nominal[{i}]: {x.tolist()} is outside the "
                            "workspace")
        nominal.append(tuple(x.tolist()))
    region = t.get("region")
    known = set(partition.names) | {la.name for la in partition.layers}
    if region is not None and region not in known:
        raise TaskError(f"{where}: starts.region: unknown region {region!r} (regions: "
                        f"{', '.join(sorted(known))})")
    if region is not None:  # random starts are drawn in its box within the workspace
        for nr in (*partition.cells, *partition.layers):
            if nr.name == region:
                rlo, rhi = nr.region.bounds()
                if not np.all(np.maximum(lo, rlo) <= np.minimum(hi, rhi)):
                    raise TaskError(f"{where}: starts.region: region {region!r} lies outside "
                                    "the workspace: no start can be drawn in it")
    random = t.get("random", False)
    if not isinstance(random, bool):
        raise TaskError(f"{where}: starts.random: expected true or false, got {random!r}")
    return Starts(tuple(nominal), region, random)


def _perturbations(raw: Any, where: str) -> PerturbationBounds:
    from tli_verify.limits import MAX_CAMPAIGN_STEPS, MAX_PUSHES

    t = _keys(raw, ("max_magnitude", "window", "max_pushes"), f"{where}: [perturbations]")
    mag = t.get("max_magnitude")
    return PerturbationBounds(
        max_magnitude=None if mag is None else number(mag, f"{where}: perturbations."
                                                      "max_magnitude", lo=0.0, hi=1e6),
        window=int(number(t.get("window", 700), f"{where}: perturbations.window", lo=1,
                          hi=MAX_CAMPAIGN_STEPS, integer=True)),
        max_pushes=int(number(t.get("max_pushes", 3), f"{where}: perturbations.max_pushes",
                              lo=0, hi=MAX_PUSHES, integer=True)))


def _entry_sensor_model(name: str, where: str, source: TaskSource,
                        entry_points: Callable[[str], Any] | None, dim: int,
                        partition: Partition) -> tuple[SensorModel, TaskSource]:
    from tli_verify.tasks.plugins import entry_point, entry_point_source

    resolve = entry_points or entry_point
    try:
        obj = resolve(name)
    except TliError as exc:
        raise TaskError(f"{where}: sensor_model {name!r}: {exc}") from None
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # SystemExit too: a plug-in never ends the process
        raise TaskError(f"{where}: sensor_model {name!r}: the entry point does not load "
                        f"({_raised(exc)})") from None
    try:
        model = obj(dim=dim, partition=partition)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:
        raise TaskError(f"{where}: sensor_model {name!r}: the entry point failed to build a "
                        f"sensor model ({_raised(exc)})") from None
    try:
        conforms = isinstance(model, SensorModel)  # reads its attributes (properties run)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:
        raise TaskError(f"{where}: sensor_model {name!r}: reading the sensor model's "
                        f"attributes raised {_raised(exc)}") from None
    if not conforms:
        raise TaskError(f"{where}: sensor_model {name!r}: the entry point returned "
                        f"{type(model).__name__}, not a sensor model (sensor_names, "
                        "latent_names, cell_based, initial_latent, read)")
    model = PluginSensors(model, name=name, where=where)
    info = entry_point_source(name) if entry_points is None else {}
    return model, replace(source, entry_point=name, distribution=info.get("distribution"),
                          version=info.get("version"), source_sha256=info.get("source_sha256"))
