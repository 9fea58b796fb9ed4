"""What every 2-D task world provides: true regions, a sensor model, a scripted demonstrator.

A *world* is data, hidden from the learner (paper Sec. 3: the learner sees sensor readings,
never the mode boundaries):

* **true regions** -- named sets of states (the coloured regions of the paper's figures) that
  partition the workspace; :meth:`WorldBase.region_index` / :meth:`WorldBase.true_mode` are
  vectorised membership tests over ``(N, n)`` states;
* a **sensor model** -- the spec's inputs (atomic propositions) computed from the state, its
  history and a latent world state (scooping: is there soup on the spoon?). One step is
  :meth:`WorldBase.read` ``(x_prev, x, latent) -> (reading, latent)``, vectorised over a batch
  of episodes; :meth:`WorldBase.sensors` scans a whole history. The sensors may lag: with
  ``lag = L`` the reading at step ``k`` is computed from the state at step ``k - L`` (the
  authors' code reads the position 19 steps back; default 0);
* a **seeded scripted demonstrator** -- smooth minimum-jerk paths through waypoints whose
  readings follow the spec's demonstrated mode sequence, written as demonstration CSVs
  (:func:`tli_verify.demos.demo_to_csv`) with one column per sensor;
* its **specs** under ``specs/`` (their ``[modes]`` labels are over this world's sensors);
* a **picture** of its regions (:func:`plot_world`).

The closed-loop executive (``tli_verify.runtime``) consumes worlds; worlds do not depend on it.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from tli_verify.demos import Demonstration, demo_to_csv
from tli_verify.errors import ModelError
from tli_verify.io import atomic_write_text

__all__ = ["World", "WorldBase", "min_jerk_path", "plot_world", "write_demos"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]


@runtime_checkable
class World(Protocol):
    """What a consumer (the closed-loop executive, an experiment) needs from a world.

    :class:`WorldBase` implements it; see there for the meaning of each member.
    """

    @property
    def lag(self) -> int: ...

    name: ClassVar[str]
    sensor_names: ClassVar[tuple[str, ...]]
    latent_names: ClassVar[tuple[str, ...]]
    region_names: ClassVar[tuple[str, ...]]

    def region_index(self, X: npt.ArrayLike) -> IntArray: ...

    def true_mode(self, X: npt.ArrayLike) -> npt.NDArray[np.str_]: ...

    def initial_latent(self, batch: int) -> BoolArray: ...

    def read(self, x_prev: FloatArray, x: FloatArray, latent: BoolArray
             ) -> tuple[BoolArray, BoolArray]: ...

    def sensors(self, X: npt.ArrayLike,
                latent: npt.ArrayLike | None = None) -> BoolArray: ...


def min_jerk_path(waypoints: npt.ArrayLike, duration: float, dt: float
                  ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """A human-like reaching path through waypoints, at rest at both ends.

    A piecewise-linear path through the waypoints, its corners rounded by a natural cubic
    spline in the chord-length parameter, timed with a minimum-jerk profile
    ``s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5`` (Flash & Hogan 1985), as the convex world's and
    the former scoop generator's demonstrations.

    Parameters
    ----------
    waypoints : array_like, shape (W, n), W >= 2
    duration : float
        Seconds.
    dt : float
        Sampling period (s).

    Returns
    -------
    t : ndarray, shape (T,)
    x : ndarray, shape (T, n)
    dx : ndarray, shape (T, n)
        Analytic velocities (zero at both ends).
    """
    from scipy.interpolate import CubicSpline

    W = np.asarray(waypoints, dtype=np.float64)
    if W.ndim != 2 or W.shape[0] < 2:
        raise ModelError(f"need at least 2 waypoints as a (W, n) array, got {W.shape}")
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    tau = t / duration
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    ds = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / duration
    chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(W, axis=0), axis=1))])
    spline = CubicSpline(chord / chord[-1], W, bc_type="natural")
    x = np.asarray(spline(s), dtype=np.float64)
    dx = np.asarray(spline(s, 1), dtype=np.float64) * ds[:, None]
    return t, x, dx


@dataclass(frozen=True, slots=True)
class WorldBase:
    """Common behaviour of the 2-D task worlds (subclasses are frozen dataclasses).

    Attributes
    ----------
    lag : int
        Sensor lag in steps: the reading at step ``k`` is computed from the state at step
        ``max(k - lag, 0)`` (default 0; the authors' scooping code reads 19 steps back).

    Class attributes (set by each world)
    ------------------------------------
    name : str
    specs : tuple of str
        Spec files (under ``specs/``) written over this world's sensors.
    sensor_names : tuple of str
        The spec inputs, in column order.
    latent_names : tuple of str
        The latent world state (booleans), in column order.
    region_names : tuple of str
        The true regions, in index order (:meth:`region_index`).
    region_colors : tuple of str
        Matplotlib colours of the regions (pictures).
    lo, hi : tuple of float
        The workspace box ``[lo, hi]``.
    """

    lag: int = 0

    name: ClassVar[str] = "world"
    specs: ClassVar[tuple[str, ...]] = ()
    sensor_names: ClassVar[tuple[str, ...]] = ()
    latent_names: ClassVar[tuple[str, ...]] = ()
    region_names: ClassVar[tuple[str, ...]] = ()
    region_colors: ClassVar[tuple[str, ...]] = ()
    lo: ClassVar[tuple[float, ...]] = (0.0, 0.0)
    hi: ClassVar[tuple[float, ...]] = (1.0, 1.0)

    def __post_init__(self) -> None:
        if not isinstance(self.lag, int) or self.lag < 0:
            raise ModelError(f"{self.name}: sensor lag must be a non-negative int, got "
                             f"{self.lag!r}")

    # ----------------------------------------------------------------- true regions
    def region_index(self, X: npt.ArrayLike) -> IntArray:
        """Index into :attr:`region_names` of the true region of each state.

        Parameters
        ----------
        X : array_like, shape (N, 2) (or (..., 2))

        Returns
        -------
        ndarray of int, shape (N,)
        """
        raise NotImplementedError

    def region_one(self, x: Sequence[float]) -> int:
        """:meth:`region_index` of one state (worlds may override it with a scalar test).

        Parameters
        ----------
        x : sequence of float, length 2

        Returns
        -------
        int
        """
        return int(self.region_index(np.asarray(x, dtype=np.float64)[None, :])[0])

    def region_masks(self, X: npt.ArrayLike) -> dict[str, BoolArray]:
        """Membership of every true region, ``{name: (N,) bool}`` (a partition)."""
        idx = self.region_index(X)
        return {name: np.asarray(idx == i) for i, name in enumerate(self.region_names)}

    def in_region(self, name: str, X: npt.ArrayLike) -> BoolArray:
        """Membership of one named true region, shape (N,)."""
        if name not in self.region_names:
            raise ModelError(f"{self.name}: no region {name!r} (regions: "
                             f"{', '.join(self.region_names)})")
        return np.asarray(self.region_index(X) == self.region_names.index(name))

    def true_mode(self, X: npt.ArrayLike) -> npt.NDArray[np.str_]:
        """Name of the true region of each state, shape (N,) (hidden from the learner)."""
        return np.asarray(self.region_names, dtype=np.str_)[self.region_index(X)]

    def in_workspace(self, X: npt.ArrayLike) -> BoolArray:
        """Whether each state lies in the workspace box, shape (N,)."""
        Xa = np.asarray(X, dtype=np.float64)
        return np.asarray(np.all((Xa >= np.array(self.lo)) & (Xa <= np.array(self.hi)),
                                 axis=-1))

    def sample_region(self, name: str, count: int, rng: np.random.Generator) -> FloatArray:
        """``count`` uniform random states of a true region (rejection sampling), (count, n).

        Raises
        ------
        ModelError
            Unknown region, or the region is too small to hit (below about 1e-4 of the box).
        """
        lo, hi = np.array(self.lo), np.array(self.hi)
        out: list[FloatArray] = []
        got = 0
        for _ in range(200):
            X = rng.uniform(lo, hi, size=(max(4 * count, 64), lo.size))
            ok = X[self.in_region(name, X)]
            out.append(ok)
            got += len(ok)
            if got >= count:
                return np.concatenate(out)[:count]
        raise ModelError(f"{self.name}: cannot sample {count} states of region {name!r}")

    # ----------------------------------------------------------------- sensors
    def initial_latent(self, batch: int) -> BoolArray:
        """The latent state at the start of an episode, shape (batch, len(latent_names))."""
        return np.zeros((batch, len(self.latent_names)), dtype=bool)

    def read(self, x_prev: FloatArray, x: FloatArray, latent: BoolArray
             ) -> tuple[BoolArray, BoolArray]:
        """One step of the sensor model, vectorised over a batch of episodes.

        Parameters
        ----------
        x_prev : ndarray, shape (B, n)
            The (lagged) state the previous reading was computed from (``x`` itself at the
            first step).
        x : ndarray, shape (B, n)
            The (lagged) state of this reading.
        latent : ndarray of bool, shape (B, L)
            The latent state after the previous reading.

        Returns
        -------
        reading : ndarray of bool, shape (B, m)
            Sensor values in :attr:`sensor_names` order.
        latent : ndarray of bool, shape (B, L)
            The updated latent state.
        """
        raise NotImplementedError

    def sensors(self, X: npt.ArrayLike, latent: npt.ArrayLike | None = None) -> BoolArray:
        """Sensor readings along a state history (with the world's lag).

        Parameters
        ----------
        X : array_like, shape (T, n) or (B, T, n)
            One history, or a batch of B histories of equal length.
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
        Xa = np.asarray(X, dtype=np.float64)
        single = Xa.ndim == 2
        if single:
            Xa = Xa[None]
        if Xa.ndim != 3 or Xa.shape[1] < 1:
            raise ModelError(f"{self.name}: states must be (T, n) or (B, T, n), got "
                             f"{np.shape(X)}")
        B, T, _ = Xa.shape
        lat = (self.initial_latent(B) if latent is None
               else np.broadcast_to(np.asarray(latent, dtype=bool),
                                    (B, len(self.latent_names))).copy())
        lagged = Xa[:, np.maximum(np.arange(T) - self.lag, 0)]
        readings = np.zeros((B, T, len(self.sensor_names)), dtype=bool)
        latents = np.zeros((B, T, len(self.latent_names)), dtype=bool)
        for k in range(T):
            prev = lagged[:, max(k - 1, 0)]
            readings[:, k], lat = self.read(prev, lagged[:, k], lat)
            latents[:, k] = lat
        if single:
            return readings[0], latents[0]
        return readings, latents

    # ----------------------------------------------------------------- demonstrations
    def demonstrate(self, seed: int, n_demos: int | None = None) -> list[Demonstration]:
        """Seeded scripted demonstrations with sensor columns (subclasses).

        Parameters
        ----------
        seed : int
        n_demos : int, optional
            Number of demonstrations (each world has a default).

        Returns
        -------
        list of Demonstration
        """
        raise NotImplementedError

    def _demo(self, label: str, waypoints: npt.ArrayLike, duration: float, dt: float
              ) -> Demonstration:
        """A minimum-jerk demonstration through waypoints, read by this world's sensors."""
        t, x, dx = min_jerk_path(waypoints, duration, dt)
        return Demonstration(path=f"<{self.name} demo {label}>", t=t, x=x, dx=dx,
                             sensor_names=self.sensor_names, sensors=self.sensors(x),
                             velocities_from_file=True)


def write_demos(world: WorldBase, directory: str | os.PathLike[str], *, seed: int = 0,
                n_demos: int | None = None, prefix: str | None = None) -> list[Path]:
    """Write ``world.demonstrate(seed, n_demos)`` as ``<prefix>_<i>.csv`` (atomic writes).

    Parameters
    ----------
    world : WorldBase
    directory : path-like
    seed : int, optional
    n_demos : int, optional
    prefix : str, optional
        File name prefix (default: the world's name).

    Returns
    -------
    list of Path
    """
    out = []
    stem = prefix or world.name
    for i, demo in enumerate(world.demonstrate(seed, n_demos), start=1):
        path = Path(directory) / f"{stem}_{i}.csv"
        atomic_write_text(path, f"# {world.name} demonstration {i} "
                                f"(tli_verify.worlds, {type(world).__name__}, seed={seed})\n"
                          + demo_to_csv(demo))
        out.append(path)
    return out


def plot_world(world: WorldBase, path: str | os.PathLike[str], *,
               demos: Sequence[Demonstration] = (), title: str | None = None,
               resolution: int = 400) -> None:
    """Draw the world's true regions (and demonstrations) to a PNG.

    Parameters
    ----------
    world : WorldBase
    path : path-like
        Output PNG (written atomically by :func:`tli_verify.plotting.save_figure`).
    demos : sequence of Demonstration, optional
        Drawn in black, with their start marked.
    title : str, optional
    resolution : int, optional
        Grid points per axis.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    from tli_verify.plotting import save_figure

    lo, hi = np.array(world.lo), np.array(world.hi)
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], resolution),
                         np.linspace(lo[1], hi[1], resolution))
    idx = world.region_index(np.column_stack([gx.ravel(), gy.ravel()])).reshape(gx.shape)
    width = 5.0 * (hi[0] - lo[0]) / max(hi[1] - lo[1], 1e-9)
    fig, ax = plt.subplots(figsize=(min(max(width, 4.0), 10.0) + 1.8, 5.0))
    ax.imshow(idx, origin="lower", extent=(lo[0], hi[0], lo[1], hi[1]),
              cmap=ListedColormap(list(world.region_colors)), vmin=-0.5,
              vmax=len(world.region_names) - 0.5, interpolation="nearest", aspect="equal")
    for d in demos:
        ax.plot(d.x[:, 0], d.x[:, 1], color="k", linewidth=1.0)
        ax.plot(d.x[0, 0], d.x[0, 1], marker="o", color="k", markersize=4)
    ax.legend(handles=[Patch(facecolor=c, edgecolor="0.3", label=n)
                       for n, c in zip(world.region_names, world.region_colors, strict=True)],
              loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    ax.set_xlabel("x1")
    ax.set_ylabel("x2")
    ax.set_title(title or f"{world.name}: true regions and demonstrations", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)
