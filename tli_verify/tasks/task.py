"""A task as data: state space, regions, sensors, goal, starts, perturbations, demonstrator.

:class:`Task` is what the closed loop, the campaigns and the pictures ask about a user's task, in
any dimension ``n``. Its values live in :mod:`tli_verify.tasks.values`, its sensors in
:mod:`tli_verify.tasks.sensing`; a task file is read by :mod:`tli_verify.tasks.taskfile` (the
format). The names of those modules are re-exported here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import numpy.typing as npt

from tli_verify.defaults import DEFAULT_DT_FLOAT
from tli_verify.demos import Demonstration, PoseDemonstration, finite_difference_velocities
from tli_verify.errors import TaskError, bad_type
from tli_verify.tasks.demonstrator import Demonstrator
from tli_verify.tasks.fields import number, vector
from tli_verify.tasks.orientation import OrientationChart
from tli_verify.tasks.regions import Primitive
from tli_verify.tasks.sensing import (
    FormulaSensors,
    Latch,
    PluginSensors,
    SensorModel,
)
from tli_verify.tasks.values import (
    DEFAULT_COLORS,
    MAX_LAG,
    MAX_LATCHES,
    MAX_REGIONS,
    MAX_SENSORS,
    MAX_TASK_DIM,
    TASK_KEYS,
    BoolArray,
    FloatArray,
    Goal,
    IntArray,
    NamedRegion,
    Partition,
    PerturbationBounds,
    Starts,
    TaskSource,
)

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
    "FormulaSensors",
    "Goal",
    "IntArray",
    "Latch",
    "NamedRegion",
    "Partition",
    "PerturbationBounds",
    "PluginSensors",
    "SensorModel",
    "Starts",
    "Task",
    "TaskSource",
    "number",
    "vector",
]


@dataclass(frozen=True, slots=True, eq=False)
class Task:
    """A task: all the closed loop, the campaigns and the pictures need about the environment.

    It is what the runtime, the campaigns and the oracle run against: the members below are what
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
    orientation : OrientationChart or None
        A pose task's orientation coordinates and their chart
        (:mod:`tli_verify.tasks.orientation`); None for a task on positions only.
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
    orientation: OrientationChart | None = None

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
        first is the former Python tasks' stream of draws, which seeded anchors rely on).

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

    def pose_demonstration(self, demo: PoseDemonstration) -> Demonstration:
        """A recorded pose demonstration (position and unit quaternion per sample,
        :func:`tli_verify.demos.load_pose_demo`) as a demonstration of this pose task: the
        position fills the state's other coordinates in order, the orientation becomes the
        task's orientation coordinates (:meth:`OrientationChart.coordinates`: either sign of a
        quaternion gives the same state), the velocities are finite differences (as
        :func:`tli_verify.demos.load_demo` takes them) and the task's sensors read the path.

        Parameters
        ----------
        demo : PoseDemonstration

        Returns
        -------
        Demonstration

        Raises
        ------
        TaskError
            The task has no orientation coordinates, the file's position has the wrong size,
            or a sample lies outside the workspace (e.g. an orientation beyond the chart).
        """
        chart = self.orientation
        if chart is None:
            raise TaskError(f"{self.where}: not a pose task ([state] has no orientation): "
                            f"{demo.path} records orientations")
        others = [i for i in range(self.dim) if not chart.start <= i < chart.start + 3]
        if demo.x.shape[1] != len(others):
            raise TaskError(f"{demo.path}: {demo.x.shape[1]} position coordinate(s), but task "
                            f"{self.name!r} has {len(others)} besides its orientation")
        x = np.empty((demo.n_samples, self.dim))
        x[:, others] = demo.x
        x[:, chart.columns] = chart.coordinates(demo.q)
        outside = np.flatnonzero(~self.in_workspace(x))
        if outside.size:
            i = int(outside[0])
            raise TaskError(f"{demo.path}: line {int(demo.lines[i])}: the pose is outside the "
                            f"workspace of task {self.name!r} (state "
                            f"{[round(v, 4) for v in x[i].tolist()]})")
        dx = finite_difference_velocities(demo.t, x, where=demo.path, lines=demo.lines)
        return Demonstration(path=demo.path, t=demo.t, x=x, dx=dx,
                             sensor_names=self.sensor_names, sensors=self.sensors(x),
                             lines=demo.lines)

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


