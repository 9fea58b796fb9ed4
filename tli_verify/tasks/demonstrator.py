"""A task's scripted demonstrator: seeded minimum-jerk paths through jittered waypoints.

The bundled tasks and a user's own task generate their demonstrations the same way
(``tli demos TASK``): each demonstration follows a *script* -- a start point and waypoints,
each moved by seeded noise -- as a smooth path timed with a minimum-jerk profile (at rest at
both ends, like a human reaching motion), sampled every ``dt`` seconds and read by the task's
sensors. Demonstration ``i`` follows script ``i mod (number of scripts)``.

Random draws, per demonstration and in this order, from one ``numpy.random.default_rng(seed)``:
``start_jitter > 0``: ``uniform(-start_jitter, start_jitter, size=n)`` added to the start; then,
if any waypoint has a jitter, ``normal(scale=sigma, size=(J, n))`` with ``J`` the number of
waypoints whose jitter is not zero, row ``j`` times its jitter added to the ``j``-th of them.

References
----------
Flash and Hogan, "The coordination of arm movements", J. Neurosci. 1985 (minimum jerk).
Wang et al., "Temporal Logic Imitation", CoRL 2022, Sec. 7 (a few demonstrations per task).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from tli_verify.demos import Demonstration, demo_to_csv
from tli_verify.errors import TaskError
from tli_verify.io import atomic_write_text
from tli_verify.limits import MAX_DEMO_SAMPLES, MAX_INPUT_BYTES
from tli_verify.tasks.fields import number, vector


class Task(Protocol):
    """What the demonstrator needs of a task (:class:`tli_verify.tasks.task.Task`)."""

    @property
    def name(self) -> str: ...

    @property
    def dim(self) -> int: ...

    @property
    def where(self) -> str: ...

    @property
    def sensor_names(self) -> tuple[str, ...]: ...

    @property
    def demonstrator(self) -> Demonstrator | None: ...

    def sensors(self, X: npt.ArrayLike, latent: npt.ArrayLike | None = None
                ) -> npt.NDArray[np.bool_]: ...


__all__ = ["Demonstrator", "Script", "min_jerk_path", "write_demos"]

FloatArray = npt.NDArray[np.float64]

MAX_DEMOS = 1000
"""Most demonstrations one ``tli demos`` call writes."""


def min_jerk_path(waypoints: npt.ArrayLike, duration: float, dt: float
                  ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """A human-like reaching path through waypoints, at rest at both ends.

    A piecewise-linear path through the waypoints, its corners rounded by a natural cubic
    spline in the chord-length parameter, timed with a minimum-jerk profile
    ``s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5`` (Flash & Hogan 1985).

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

    Raises
    ------
    TaskError
        Fewer than 2 waypoints, or two consecutive waypoints that coincide everywhere.
    """
    from scipy.interpolate import CubicSpline

    W = np.asarray(waypoints, dtype=np.float64)
    if W.ndim != 2 or W.shape[0] < 2:
        raise TaskError(f"need at least 2 waypoints as a (W, n) array, got {W.shape}")
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    tau = t / duration
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    ds = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / duration
    chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(W, axis=0), axis=1))])
    steps = np.diff(chord)
    if not np.all(steps > 0):
        k = int(np.argmin(steps > 0))
        raise TaskError(f"two consecutive waypoints coincide (points {k} and {k + 1} of the "
                        "path, the start counted as point 0)")
    spline = CubicSpline(chord / chord[-1], W, bc_type="natural")
    x = np.asarray(spline(s), dtype=np.float64)
    dx = np.asarray(spline(s, 1), dtype=np.float64) * ds[:, None]
    return t, x, dx


@dataclass(frozen=True, slots=True)
class Script:
    """One demonstration script.

    Attributes
    ----------
    label : str
    start : tuple of float, length n
    start_jitter : float
        Half-width of the uniform noise on each start coordinate.
    waypoints : tuple of tuple of float, each length n
        Visited in order after the start (the last one is where the demonstration ends).
    jitter : tuple of float
        Per waypoint, the factor of the normal noise (0: fixed).
    duration : float or None
        Seconds (None: the demonstrator's).
    """

    label: str
    start: tuple[float, ...]
    start_jitter: float
    waypoints: tuple[tuple[float, ...], ...]
    jitter: tuple[float, ...]
    duration: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """The script's TOML/JSON form."""
        out: dict[str, Any] = {"label": self.label, "start": list(self.start),
                               "start_jitter": self.start_jitter,
                               "waypoints": [list(w) for w in self.waypoints],
                               "jitter": list(self.jitter)}
        if self.duration is not None:
            out["duration"] = self.duration
        return out


@dataclass(frozen=True, slots=True)
class Demonstrator:
    """The scripted demonstrator of a task (module docstring).

    Attributes
    ----------
    scripts : tuple of Script
    count : int
        Demonstrations written by default.
    duration : float
        Seconds per demonstration (a script may override it).
    dt : float
        Sampling period of the demonstrations (s).
    sigma : float
        Standard deviation of the waypoint noise (times each waypoint's jitter).
    """

    scripts: tuple[Script, ...]
    count: int
    duration: float
    dt: float
    sigma: float

    def demonstrate(self, task: Task, seed: int, n_demos: int | None = None
                    ) -> list[Demonstration]:
        """Seeded demonstrations with the task's sensor columns.

        Parameters
        ----------
        task : Task
            Its sensors read the paths (with its sensor lag).
        seed : int
        n_demos : int, optional
            Default :attr:`count`.

        Returns
        -------
        list of Demonstration
            With analytic velocities.
        """
        count = self.count if n_demos is None else int(n_demos)
        if not 1 <= count <= MAX_DEMOS:
            raise TaskError(f"demonstrations: count must be in [1, {MAX_DEMOS}], got {count}")
        rng = np.random.default_rng(seed)
        out = []
        n = task.dim
        for i in range(count):
            s = self.scripts[i % len(self.scripts)]
            start = np.array(s.start, dtype=np.float64)
            if s.start_jitter > 0:
                start = start + rng.uniform(-s.start_jitter, s.start_jitter, size=n)
            W = np.array(s.waypoints, dtype=np.float64)
            moving = [k for k, j in enumerate(s.jitter) if j != 0.0]
            if moving:
                noise = rng.normal(scale=self.sigma, size=(len(moving), n))
                W = W.copy()
                for row, k in enumerate(moving):
                    W[k] = W[k] + s.jitter[k] * noise[row]
            try:
                t, x, dx = min_jerk_path(np.vstack([start, W]),
                                         s.duration if s.duration is not None
                                         else self.duration, self.dt)
            except TaskError as exc:  # name the file and the script
                k = i % len(self.scripts)
                raise TaskError(f"{task.where}: demonstrator.scripts[{k}] ({s.label}), "
                                f"demonstration {i + 1}: {exc} (with its start and jitter "
                                "drawn from seed {seed})".replace("{seed}", str(seed))
                                ) from None
            out.append(Demonstration(path=f"<{task.name} demo {i + 1} ({s.label})>", t=t, x=x,
                                     dx=dx, sensor_names=task.sensor_names,
                                     sensors=task.sensors(x), velocities_from_file=True))
        return out

    def to_dict(self) -> dict[str, Any]:
        """The ``[demonstrator]`` table."""
        return {"count": self.count, "duration": self.duration, "dt": self.dt,
                "sigma": self.sigma, "scripts": [s.to_dict() for s in self.scripts]}


def write_demos(task: Task, directory: str | os.PathLike[str], *, seed: int = 0,
                n_demos: int | None = None, prefix: str | None = None) -> list[Path]:
    """Write a task's scripted demonstrations as ``<prefix>_<i>.csv`` (atomic writes).

    Parameters
    ----------
    task : Task
        With a demonstrator.
    directory : path-like
    seed : int, optional
    n_demos : int, optional
    prefix : str, optional
        File name prefix (default: the task's name).

    Returns
    -------
    list of Path

    Raises
    ------
    TaskError
        The task has no demonstrator.
    """
    if task.demonstrator is None:
        raise TaskError(f"{task.where}: no [demonstrator] table: the task cannot write "
                        "demonstrations (record your own as CSV files)")
    out = []
    stem = prefix or task.name
    for i, demo in enumerate(task.demonstrator.demonstrate(task, seed, n_demos), start=1):
        path = Path(directory) / f"{stem}_{i}.csv"
        atomic_write_text(path, f"# {task.name} demonstration {i} (tli demos, seed={seed})\n"
                          + demo_to_csv(demo))
        out.append(path)
    return out


_CSV_ROW_BYTES = 25
"""Most bytes one number of a demonstration CSV takes (``repr`` of a double and a comma)."""


def _check_samples(duration: float, dt: float, dim: int, where: str) -> None:
    """Refuse, when the task loads, a demonstration ``tli learn`` would refuse: more than
    ``MAX_DEMO_SAMPLES`` samples, or a CSV that may exceed ``MAX_INPUT_BYTES`` (a row holds
    ``t``, the state, its velocity and up to 64 sensors)."""
    samples = int(duration / dt) + 1
    row = (1 + 2 * dim) * _CSV_ROW_BYTES + 2 * 64
    if samples > MAX_DEMO_SAMPLES or samples * row > MAX_INPUT_BYTES:
        most = min(MAX_DEMO_SAMPLES, MAX_INPUT_BYTES // row)
        raise TaskError(f"{where}: {duration:g} s at dt = {dt:g} s gives {samples:,} samples "
                        f"per demonstration; at most {most:,} in {dim} dimensions "
                        "(MAX_DEMO_SAMPLES, and the CSV tli learn reads is at most "
                        "MAX_INPUT_BYTES)")


def parse_demonstrator(raw: Any, *, dim: int, where: str) -> Demonstrator:
    """The ``[demonstrator]`` table of a task file.

    Raises
    ------
    TaskError
        (exit 2) Naming the field.
    """
    here = f"{where}: demonstrator"
    if not isinstance(raw, dict):
        raise TaskError(f"{here}: expected a table")
    allowed = {"count", "duration", "dt", "sigma", "scripts"}
    unknown = sorted(set(raw) - allowed)
    if unknown:
        raise TaskError(f"{here}: unknown key {unknown[0]!r} (allowed: "
                        f"{', '.join(sorted(allowed))})")
    scripts_raw = raw.get("scripts")
    if not isinstance(scripts_raw, list) or not scripts_raw:
        raise TaskError(f"{here}.scripts: expected at least one [[demonstrator.scripts]] table")
    duration = number(raw.get("duration", 10.0), f"{here}.duration", lo=1e-3, hi=1e4)
    dt = number(raw.get("dt", 0.05), f"{here}.dt", lo=1e-4, hi=10.0)
    _check_samples(duration, dt, dim, f"{here}.duration")
    sigma = number(raw.get("sigma", 1.0), f"{here}.sigma", lo=0.0, hi=1e6)
    count_raw = raw.get("count", len(scripts_raw))
    if not isinstance(count_raw, int) or isinstance(count_raw, bool) or \
            not 1 <= count_raw <= MAX_DEMOS:
        raise TaskError(f"{here}.count: expected an integer in [1, {MAX_DEMOS}]")
    scripts = []
    for i, s in enumerate(scripts_raw):
        at = f"{here}.scripts[{i}]"
        if not isinstance(s, dict):
            raise TaskError(f"{at}: expected a table")
        keys = {"label", "start", "start_jitter", "waypoints", "jitter", "duration"}
        bad = sorted(set(s) - keys)
        if bad:
            raise TaskError(f"{at}: unknown key {bad[0]!r} (allowed: {', '.join(sorted(keys))})")
        wps = s.get("waypoints")
        if not isinstance(wps, list) or not wps or len(wps) > 1000:
            raise TaskError(f"{at}.waypoints: expected 1 to 1000 points")
        waypoints = tuple(tuple(vector(w, dim, f"{at}.waypoints[{k}]").tolist())
                          for k, w in enumerate(wps))
        jit = s.get("jitter", [0.0] * len(wps))
        if isinstance(jit, int | float) and not isinstance(jit, bool):
            jit = [jit] * len(wps)
        jitter = tuple(vector(jit, len(wps), f"{at}.jitter").tolist())
        if any(j < 0 for j in jitter):
            raise TaskError(f"{at}.jitter: factors must be >= 0")
        label = s.get("label", f"script {i + 1}")
        if not isinstance(label, str) or "\n" in label or len(label) > 200:
            raise TaskError(f"{at}.label: expected one line of text")
        sd = s.get("duration")
        scripts.append(Script(
            label=label, start=tuple(vector(s.get("start"), dim, f"{at}.start").tolist()),
            start_jitter=number(s.get("start_jitter", 0.0), f"{at}.start_jitter", lo=0.0,
                                hi=1e6),
            waypoints=waypoints, jitter=jitter,
            duration=None if sd is None else number(sd, f"{at}.duration", lo=1e-3, hi=1e4)))
        if sd is not None:  # a script's own duration is held to the same limits
            _check_samples(scripts[-1].duration or duration, dt, dim, f"{at}.duration")
    return Demonstrator(scripts=tuple(scripts), count=int(count_raw), duration=duration, dt=dt,
                        sigma=sigma)

