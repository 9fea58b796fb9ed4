"""Seeded random single-mode tasks: the paper's single-mode study (Sec. 7.1, appendix E).

A random convex polygon is the mode -- a :class:`~tli_verify.tasks.regions.Polytope` region of
a :class:`~tli_verify.tasks.task.Task` built here in memory, whose one sensor ``inside``
reports whether the state lies in it (the same task type the task files load). An
attractor ``x*`` lies inside, and 1-3 synthetic "human" demonstrations run from far inside the
mode to ``x*``. Everything random takes a seed (``numpy.random.Generator``).

Demonstrations are quadratic Bezier curves ``start -> via -> x*`` whose three control points lie
in the mode, so the whole curve does (a Bezier curve stays in the convex hull of its control
points and the mode is convex). They are timed with a minimum-jerk profile, so the velocity
vanishes at both ends like a human reaching motion, and sampled at 200 states each (the paper's
"about 200 pairs of states and velocities").
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from tli_verify.errors import ModelError
from tli_verify.tasks import formula
from tli_verify.tasks.regions import Polytope
from tli_verify.tasks.task import FormulaSensors, NamedRegion, Partition, Task

__all__ = ["ConvexMode", "Demo", "SingleModeTask", "make_task", "polygon_task",
           "random_convex_mode"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True, eq=False)
class ConvexMode(Polytope):
    """A convex polygon ``{x : A x <= b}`` in the plane: a polytope region with its vertices.

    Attributes
    ----------
    A : ndarray, shape (k, 2)
        Unit outward edge normals.
    b : ndarray, shape (k,)
        Offsets: the mode is ``A x <= b``.
    vertices : ndarray, shape (k, 2)
        Counter-clockwise vertices.
    """

    vertices: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))

    @classmethod
    def from_vertices(cls, vertices: npt.ArrayLike) -> ConvexMode:
        """Build from counter-clockwise vertices of a convex polygon, shape (k, 2), k >= 3.

        Raises
        ------
        ModelError
            If the polygon is not strictly convex and counter-clockwise.
        """
        V = np.array(vertices, dtype=np.float64)
        if V.ndim != 2 or V.shape[1] != 2 or V.shape[0] < 3 or not np.all(np.isfinite(V)):
            raise ModelError(f"vertices must be a finite (k, 2) array with k >= 3, got {V.shape}")
        E = np.roll(V, -1, axis=0) - V
        cross = E[:, 0] * np.roll(E, -1, axis=0)[:, 1] - E[:, 1] * np.roll(E, -1, axis=0)[:, 0]
        if not np.all(cross > 0):
            raise ModelError("vertices must form a strictly convex counter-clockwise polygon")
        N = np.column_stack([E[:, 1], -E[:, 0]])
        N /= np.linalg.norm(N, axis=1, keepdims=True)
        b = np.einsum("ij,ij->i", N, V)
        for arr in (V, N, b):
            arr.setflags(write=False)
        return cls(A=N, b=b, vertices=V)

    def margin(self, X: npt.ArrayLike) -> FloatArray:
        """Signed distance inside the polygon: ``min_j (b_j - A_j . x)``, shape (N,).

        Positive inside, zero on the boundary, negative outside.
        """
        Xa = np.asarray(X, dtype=np.float64)
        return np.asarray(np.min(self.b - Xa @ self.A.T, axis=-1))

    def contains(self, X: npt.ArrayLike) -> npt.NDArray[np.bool_]:
        """The mode sensor: True where the state is in the (closed) polygon.

        Parameters
        ----------
        X : array_like, shape (N, 2)

        Returns
        -------
        ndarray of bool, shape (N,)
        """
        Xa = np.asarray(X, dtype=np.float64)
        return np.asarray(np.all(Xa @ self.A.T <= self.b, axis=-1))

    def sample_inside(self, rng: np.random.Generator, count: int, *,
                      min_margin: float = 0.0) -> FloatArray:
        """Uniform samples from the polygon shrunk by ``min_margin``, shape (count, 2)."""
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        out: list[FloatArray] = []
        got = 0
        for _ in range(1000):
            cand = rng.uniform(lo, hi, size=(max(4 * count, 16), 2))
            ok = cand[self.margin(cand) >= min_margin]
            out.append(ok)
            got += len(ok)
            if got >= count:
                return np.concatenate(out)[:count]
        raise ModelError(f"cannot sample {count} states with margin {min_margin} in the mode")


@dataclass(frozen=True, slots=True, eq=False)
class Demo:
    """One demonstration: states and velocities, each shape (T, 2), ending at ``x*``."""

    X: FloatArray
    Xdot: FloatArray


def polygon_task(mode: ConvexMode, workspace: float, *, name: str = "single-mode") -> Task:
    """The task of one convex mode: the polygon is region ``mode`` of the square workspace
    ``[0, workspace]^2`` (the rest is ``outside``), read by the one sensor ``inside``."""
    partition = Partition((NamedRegion("mode", mode, "#9ed99b"),), "outside", "#ffffff")
    sensors = FormulaSensors(partition, (("inside", formula.parse(
        "mode", names={"mode", "outside"}, where=f"{name}: sensors.inside")),))
    return Task(name=name, description="a random convex mode (paper Sec. 7.1)",
                state_names=("x0", "x1"), lo=(0.0, 0.0), hi=(float(workspace),) * 2,
                partition=partition, sensor_model=sensors)


@dataclass(frozen=True, slots=True, eq=False)
class SingleModeTask:
    """A single-mode reaching task: the mode, its attractor and the demonstrations.

    Attributes
    ----------
    mode : ConvexMode
        The mode's region.
    attractor : ndarray, shape (2,)
    demos : tuple of Demo
    workspace : float
        Side of the square workspace ``[0, workspace]^2`` holding the mode.
    """

    mode: ConvexMode
    attractor: FloatArray
    demos: tuple[Demo, ...]
    workspace: float

    @property
    def task(self) -> Task:
        """The task (:func:`polygon_task`): the mode as region ``mode``, sensor ``inside``."""
        return polygon_task(self.mode, self.workspace)

    @property
    def states(self) -> FloatArray:
        """All demonstrated states, shape (sum T, 2)."""
        return np.concatenate([d.X for d in self.demos])

    @property
    def velocities(self) -> FloatArray:
        """All demonstrated velocities, shape (sum T, 2)."""
        return np.concatenate([d.Xdot for d in self.demos])


def random_convex_mode(rng: np.random.Generator, *, workspace: float = 20.0) -> ConvexMode:
    """A random convex polygon of 5-8 vertices in ``[0, workspace]^2``.

    Vertices are drawn at sorted random angles and radii between 30% and 48% of the workspace
    around its centre; the convex hull of the draw is the mode.
    """
    from scipy.spatial import ConvexHull

    c = np.full(2, workspace / 2.0)
    for _ in range(100):
        k = int(rng.integers(5, 9))
        ang = np.sort(rng.uniform(0.0, 2.0 * np.pi, size=k))
        rad = rng.uniform(0.30, 0.48, size=k) * workspace
        pts = c + rad[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
        hull = ConvexHull(pts)
        V = pts[hull.vertices]  # counter-clockwise in 2D
        if len(V) >= 4 and hull.volume > 0.25 * workspace**2:
            return ConvexMode.from_vertices(V)
    raise ModelError("could not draw a convex mode")  # pragma: no cover - vanishingly rare


def _min_jerk(tau: FloatArray) -> tuple[FloatArray, FloatArray]:
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    ds = 30 * tau**2 - 60 * tau**3 + 30 * tau**4
    return s, ds


def make_task(
    rng: np.random.Generator,
    *,
    workspace: float = 20.0,
    n_demos: int | None = None,
    samples: int = 200,
    speed: float = 4.0,
) -> SingleModeTask:
    """Draw a mode, an attractor and 1-3 demonstrations (paper appendix E.1).

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of all randomness.
    workspace : float, optional
        Side of the square workspace.
    n_demos : int, optional
        Number of demonstrations; drawn from {1, 2, 3} if omitted.
    samples : int, optional
        States per demonstration.
    speed : float, optional
        Mean speed of a demonstration (workspace units per second).

    Returns
    -------
    SingleModeTask
    """
    mode = random_convex_mode(rng, workspace=workspace)
    k = int(rng.integers(1, 4)) if n_demos is None else int(n_demos)
    if k < 1:
        raise ModelError("need at least one demonstration")
    inner = 0.08 * workspace
    # attractor near one side of the mode (a reaching target), demos from the far side
    cand = mode.sample_inside(rng, 64, min_margin=inner)
    edge_dist = mode.margin(cand)
    x_star = cand[int(np.argmin(edge_dist))]
    demos = []
    for _ in range(k):
        pool = mode.sample_inside(rng, 64, min_margin=inner)
        far = pool[np.linalg.norm(pool - x_star, axis=1) >= 0.5 * workspace]
        start = far[0] if len(far) else pool[int(np.argmax(np.linalg.norm(pool - x_star, axis=1)))]
        via = mode.sample_inside(rng, 1, min_margin=0.5 * inner)[0]
        tau = np.linspace(0.0, 1.0, samples)
        # length of the Bezier path, for the timing
        fine = np.linspace(0.0, 1.0, 400)[:, None]
        path = (1 - fine) ** 2 * start + 2 * (1 - fine) * fine * via + fine**2 * x_star
        length = float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))
        duration = max(length / speed, 1e-3)
        s, ds = _min_jerk(tau)
        u = s[:, None]
        X = (1 - u) ** 2 * start + 2 * (1 - u) * u * via + u**2 * x_star
        dXdu = 2 * (1 - u) * (via - start) + 2 * u * (x_star - via)
        Xdot = dXdu * (ds / duration)[:, None]
        X[-1] = x_star
        Xdot[-1] = 0.0
        demos.append(Demo(X=X, Xdot=Xdot))
    return SingleModeTask(mode=mode, attractor=x_star.copy(), demos=tuple(demos),
                          workspace=float(workspace))
