"""Sensors a Franka could have: r, s, t from a wrist F/T sensor and the arm's kinematics.

:class:`~tli_verify.sim.sensors.ScoopSensors` (kind ``"ideal"``) is privileged: its ``s``
reads every bead's exact position and MuJoCo's contact list, its ``t`` needs beads on the spoon.
:class:`FrankaSensors` (kind ``"franka"``) reads only what a Franka Panda with a wrist
force/torque sensor could measure, with noise, latency, low-pass filtering and thresholds
with hysteresis, all seeded (:data:`~tli_verify.defaults.Stream.SENSORS`). The paper's robot
sensed the soup with a rendered wrist-camera colour count and the arm's pose (Wang et al.,
"Temporal Logic Imitation: Learning Plan-Satisficing Motion Policies from Demonstrations",
CoRL 2022, Sec. 7.2); a force reading is the other way the issue names.

What a real Franka has
    Joint torque sensors in all 7 joints, from which libfranka estimates the external wrench
    at the end effector (``O_F_ext_hat_K``, ``K_F_ext_hat_K``); its noise and model error are
    of the order of 1 N, fifty bead weights here, too coarse for 2 g beads. A wrist F/T sensor
    between flange and tool (e.g. an ATI Mini45, resolution about 1/16 N in Fz) is an add-on;
    it is what :func:`tli_verify.sim.scene.add_wrist_ft` simulates (site ``ladle_ft`` at the
    mount, MuJoCo ``force``/``torque`` sensors). The arm's joint encoders give the tool's pose
    by forward kinematics (repeatability about 0.1 mm), and its velocity and acceleration.

The measurements (one per control period, :data:`CONTROL_PERIOD`)
    *Wrench*: ``F`` (N, world frame) = the force sensor's reading rotated by the site's
    orientation, plus a constant bias per axis (``force_bias``, drawn once per seed) and
    Gaussian noise: ``force_noise`` (default 0.05 N) per axis and raw sample at
    ``force_rate`` (1 kHz), a reading averaging the samples of one control period, so
    ``0.05 / sqrt(20)`` = 0.011 N per reading. (The physics is sampled once per period, at
    the reading; only the noise is averaged.)

    *Ladle's inertial force*: ``m a'``, with ``m`` the ladle's mass (known: the tool's load
    entered in Franka Desk) and ``a' = a - g`` the acceleration of its centre of mass minus
    gravity, from the kinematics the robot knows (``J qdd + Jdot qd``; here
    :func:`mujoco.mj_objectAcceleration`), plus Gaussian noise (``accel_noise``, m/s^2). At
    rest ``m a' = (0, 0, m g)``, the ladle's weight.

    *Load*: ``L = (F - m a') . z`` (world up): the downward force of whatever rests on the
    tray, zero for an empty ladle however it moves (the parent's force is ``m a'`` minus the
    contact forces on the ladle). Tared at the first reading (the ladle empty and at rest, as
    at a trial's start): the tare (all three axes) averages ``tare_samples`` readings, so it
    removes the bias up to ``force_noise / sqrt(tare_samples)``.

    *Pose*: the tray frame's position by forward kinematics plus a constant calibration
    offset (``calibration``: where the robot believes the bowls are, drawn once per seed) and
    Gaussian noise (``pose_noise`` per axis and reading).

Latency
    Each channel (r, t: the pose; s: the load) passes through a FIFO of its last
    ``latency_* + 1`` measurements: the sensor reports the one ``latency_*`` control periods
    old (the first measurement fills the FIFO).

The sensors
    * ``s`` -- *soup on the spoon*: the load, clipped below at ``-s_on`` (the bowl's floor
      pushing the tray up reads as newtons of negative load: never soup), low-passed (first
      order, time constant ``load_tau`` = 0.1 s), with hysteresis: on at ``s_on``, off below
      ``s_off``. A bead weighs :data:`BEAD_WEIGHT` = 0.0196 N, the empty ladle 1.236 N; the
      noise after the filter is 0.0035 N (0.011 N per reading times ``sqrt(a / (2 - a))``,
      ``a = period / (load_tau + period)``), so the defaults, 0.75 and 0.3 bead weights, put
      ``s_on`` 4 noise stds above an empty ladle and one bead 4 stds above ``s_off``: ``s`` is
      "at least one bead", as the ideal sensor's, and does not chatter. With the inertial
      force compensated, the noise-free load of 3 carried beads stayed within 0.056-0.062 N
      through a trial's carry and pour.

      *The F/T cannot weigh the soup while the tray is pressed on the bowl's floor or into
      the pile* (a trial's push read -18 to -54 N of load with beads already on the tray).
      While the contact force (:attr:`Measurement.contact`: horizontal, or pushing the tray
      up) exceeds ``contact_hold`` (0.05 N: 4 noise stds of a reading; 0.25 N let the release
      of a floor contact drag the filter below ``s_off`` for 3 periods with 2 beads on), the
      load is taken as unobservable and the filter and ``s`` hold their values: ``s`` comes on only
      once the tray leaves the floor (in trials 0.4-1 s after the ideal sensor's), and a
      carried spoon that touches the floor again does not read as spilled.
    * ``r`` -- *in the soup bowl's region*: the estimated tray position inside the soup
      bowl's volume extended :data:`~tli_verify.sim.sensors.R_ABOVE` over its rim, as the
      ideal sensor, with hysteresis ``region_hysteresis`` (on ``h/2`` inside the boundary,
      off ``h/2`` outside). Not contact-gated: the demonstrations' mode a ends where the tray
      enters this region, before the ladle touches anything (the learned mode-a DS's
      attractor lies there; in a nominal trial the tray entered the region 1.2 s before the
      F/T saw its first contact, 0.25 N), so an ``r`` that waited for a contact force would
      not come on at mode a's attractor and the executive would not start the scoop. The
      contact force is reported (:attr:`FrankaSensors.last`) and only gates ``s``.
    * ``t`` -- *at the target*: the estimated tray position above the target bowl (within its
      radius, up to :data:`~tli_verify.sim.sensors.T_ABOVE` over its rim), with the same
      hysteresis; pose only, no knowledge of beads (the ideal ``t`` also needs soup to
      deliver).

The :class:`~tli_verify.sim.sensors.Reading`'s ``on_ladle`` and ``in_target`` (and
:meth:`FrankaSensors.in_target`, which counts the delivered beads) come from the ideal
sensor's ground truth, for the records and the oracle only: r, s, t never use them.

Call :meth:`FrankaSensors.read` once per control period (filter and FIFO advance on each
call).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, fields, replace
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from tli_verify.defaults import Stream
from tli_verify.defaults import rng as default_rng
from tli_verify.errors import InputError, TliError
from tli_verify.sim.scene import (
    BEAD_MASS,
    FT_FORCE,
    FT_SITE,
    FT_TORQUE,
    SOUP_BOWL,
    TARGET_BOWL,
    Bowl,
    SceneIds,
    scene_ids,
)
from tli_verify.sim.sensors import R_ABOVE, T_ABOVE, Reading, ScoopSensors

__all__ = [
    "BEAD_WEIGHT",
    "CONTROL_PERIOD",
    "SENSOR_KINDS",
    "FrankaSensors",
    "Measurement",
    "SensorSettings",
    "make_sensors",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

CONTROL_PERIOD = 0.02
"""The control period (s) between two :meth:`FrankaSensors.read` calls: the loop's
``CONTROL_DT`` (:mod:`tli_verify.sim.demos`)."""
BEAD_WEIGHT = BEAD_MASS * 9.81
"""One bead's weight (N): 0.0196."""
SENSOR_KINDS = ("franka", "ideal")
"""The kinds :func:`make_sensors` builds."""


@dataclass(frozen=True, slots=True)
class SensorSettings:
    """Noise, latency, filter and thresholds of :class:`FrankaSensors` (module doc).

    Attributes
    ----------
    force_noise : float
        Std (N) of the force sensor's Gaussian noise, per axis and raw sample.
    force_rate : float
        The force sensor's sample rate (Hz). One reading averages the samples of one
        control period: its noise std is ``force_noise / sqrt(force_rate * period)``.
    force_bias : float
        Std (N) of the force sensor's constant offset per axis (drawn once per seed).
    tare_samples : int
        Raw samples the tare averages (its residual: ``force_noise / sqrt(tare_samples)``).
    accel_noise : float
        Std (m/s^2) of the kinematic acceleration estimate's noise, per axis and reading.
    load_tau : float
        Time constant (s) of the load's first-order low-pass; 0: none.
    s_on, s_off : float
        Load (N) at which ``s`` turns on, and below which it turns off (``s_off <= s_on``).
    contact_hold : float
        Contact force (N, :attr:`Measurement.contact`) beyond which the load is hidden (the
        tray pressed on the bowl's floor or into the pile): the filter and ``s`` hold.
    pose_noise : float
        Std (m) of the kinematic tray position's noise, per axis and reading.
    calibration : float
        Std (m) of the constant offset of the tray position against the bowls, per axis
        (drawn once per seed: the bowls' positions as the robot believes them).
    region_hysteresis : float
        Width (m) of the hysteresis band around the bowls' regions (r and t).
    latency_r, latency_s, latency_t : int
        Latency of each sensor, in control periods (:data:`CONTROL_PERIOD`).
    period : float
        Control period (s): the time between two readings (the low-pass's step).
    seed : int
        Seeds the noise, bias and calibration (:data:`~tli_verify.defaults.Stream.SENSORS`).
    """

    force_noise: float = 0.05
    force_rate: float = 1000.0
    force_bias: float = 0.5
    tare_samples: int = 500
    accel_noise: float = 0.02
    load_tau: float = 0.1
    s_on: float = 0.75 * BEAD_WEIGHT
    s_off: float = 0.3 * BEAD_WEIGHT
    contact_hold: float = 0.05
    pose_noise: float = 0.0005
    calibration: float = 0.001
    region_hysteresis: float = 0.004
    latency_r: int = 0
    latency_s: int = 1
    latency_t: int = 0
    period: float = CONTROL_PERIOD
    seed: int = 0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            where = f"SensorSettings.{f.name}"
            if f.name in ("tare_samples", "latency_r", "latency_s", "latency_t", "seed"):
                if isinstance(value, bool) or not isinstance(value, int | np.integer):
                    raise InputError(f"{where}: an integer, got {value!r}")
                low = 1 if f.name == "tare_samples" else 0
                if value < low:
                    raise InputError(f"{where}: must be >= {low}, got {value}")
                continue
            if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
                raise InputError(f"{where}: a number, got {value!r}")
            if not math.isfinite(float(value)):
                raise InputError(f"{where}: must be finite, got {value!r}")
            if f.name in ("period", "force_rate") and value <= 0:
                raise InputError(f"{where}: must be > 0, got {value}")
            if f.name not in ("s_off",) and value < 0:
                raise InputError(f"{where}: must be >= 0, got {value}")
        if self.s_off > self.s_on:
            raise InputError(f"SensorSettings.s_off: {self.s_off} N is above s_on "
                             f"{self.s_on} N (the hysteresis band needs s_off <= s_on)")


@dataclass(frozen=True, slots=True, eq=False)
class Measurement:
    """What :class:`FrankaSensors` measured at one reading (before latency).

    Attributes
    ----------
    force : ndarray, shape (3,)
        Noisy, biased F/T force in the world frame (N).
    torque : ndarray, shape (3,)
        Noise-free F/T torque about the site, world frame (Nm; not used by r, s, t).
    inertial : ndarray, shape (3,)
        The ladle's estimated ``m a'`` (N, world frame).
    load : float
        Tared load along gravity, ``(F - m a' - tare) . z`` (N), before latency and filter.
    filtered : float
        The low-passed, delayed load ``s`` thresholds (N).
    contact : float
        Contact force (N) other than a load: ``max(|R_xy|, -R_z)`` of the residual
        ``R = F - m a' - tare``, horizontal or pushing the ladle up (``s`` holds beyond
        ``contact_hold``).
    tray : ndarray, shape (3,)
        The estimated tray position (m), before latency.
    """

    force: FloatArray
    torque: FloatArray
    inertial: FloatArray
    load: float
    filtered: float
    contact: float
    tray: FloatArray


def _signed_distance(bowl: Bowl, p: FloatArray, above: float) -> float:
    """Signed distance (m; < 0 inside) of ``p`` (shape (3,)) to the region
    ``bowl.inside(p, above=above)`` tests: radial, floor and top bounds (a box distance)."""
    radial = math.hypot(float(p[0] - bowl.center[0]), float(p[1] - bowl.center[1]))
    z = float(p[2] - bowl.center[2])
    return max(radial - bowl.radius, (bowl.floor - 1e-3) - z, z - (bowl.height + above))


def _push(fifo: deque[Any], value: Any) -> None:
    """Append ``value`` to a latency FIFO; the first value fills it (the sensor's start)."""
    if not fifo:
        fifo.extend([value] * (fifo.maxlen or 1))
    else:
        fifo.append(value)


class _Hysteresis:
    """A boolean from a scalar with a band: on at ``value >= on``, off at ``value < off``."""

    __slots__ = ("off", "on", "state")

    def __init__(self, on: float, off: float) -> None:
        self.on, self.off = float(on), float(off)
        self.state: bool | None = None

    def update(self, value: float) -> bool:
        if self.state is None:  # first value: the band's midpoint decides
            self.state = value >= (self.on + self.off) / 2
        elif self.state and value < self.off:
            self.state = False
        elif not self.state and value >= self.on:
            self.state = True
        return self.state


class FrankaSensors:
    """The r, s, t sensors of a Franka with a wrist F/T sensor (module doc).

    The same interface as :class:`~tli_verify.sim.sensors.ScoopSensors`: :meth:`read` gives
    a :class:`~tli_verify.sim.sensors.Reading`, :meth:`in_target` counts delivered beads.

    Parameters
    ----------
    model : mujoco.MjModel
        A scene of :mod:`tli_verify.sim.scene` with the wrist F/T sensor
        (:func:`~tli_verify.sim.scene.add_wrist_ft`, added by ``add_ladle``).
    ids : SceneIds, optional
        Default: looked up in ``model``.
    settings : SensorSettings, optional
        Default ``SensorSettings()``.
    seed : int, optional
        Replaces ``settings.seed`` when given.

    Raises
    ------
    TliError
        The model has no wrist F/T sensor.
    """

    def __init__(self, model: mujoco.MjModel, ids: SceneIds | None = None,
                 settings: SensorSettings | None = None, *, seed: int | None = None) -> None:
        cfg = SensorSettings() if settings is None else settings
        if seed is not None:
            cfg = replace(cfg, seed=int(seed))
        self.settings = cfg
        self.model = model
        self.ids = scene_ids(model) if ids is None else ids
        self.truth = ScoopSensors(model, self.ids)
        """The ideal sensors: ground truth for the records (``on_ladle``, ``in_target``)."""

        def need(kind: mujoco.mjtObj, name: str) -> int:
            i = int(mujoco.mj_name2id(model, kind, name))
            if i < 0:
                raise TliError(f"franka sensors: the model has no {name!r} (a wrist F/T "
                               "sensor: build the ladle with tli_verify.sim.scene.add_ladle)")
            return i

        self._site = need(mujoco.mjtObj.mjOBJ_SITE, FT_SITE)
        self._force_adr = int(model.sensor_adr[need(mujoco.mjtObj.mjOBJ_SENSOR, FT_FORCE)])
        self._torque_adr = int(model.sensor_adr[need(mujoco.mjtObj.mjOBJ_SENSOR, FT_TORQUE)])
        self.ladle_mass = float(model.body_subtreemass[self.ids.ladle_body])
        """The ladle's mass (kg): the tool load the robot is told."""
        self._rng = default_rng(cfg.seed, Stream.SENSORS)
        self._bias = self._rng.normal(0.0, cfg.force_bias, size=3) if cfg.force_bias > 0 \
            else np.zeros(3)
        self._offset = self._rng.normal(0.0, cfg.calibration, size=3) if cfg.calibration > 0 \
            else np.zeros(3)
        self._tare: FloatArray | None = None
        self._filtered: float | None = None
        self._alpha = 1.0 if cfg.load_tau == 0 else cfg.period / (cfg.load_tau + cfg.period)
        self._fifo_load: deque[tuple[float, float]] = deque(maxlen=cfg.latency_s + 1)
        self._fifo_r: deque[FloatArray] = deque(maxlen=cfg.latency_r + 1)
        self._fifo_t: deque[FloatArray] = deque(maxlen=cfg.latency_t + 1)
        self._s = _Hysteresis(cfg.s_on, cfg.s_off)
        half = cfg.region_hysteresis / 2
        self._r = _Hysteresis(half, -half)  # of minus the signed distance: > 0 inside
        self._t = _Hysteresis(half, -half)
        self._acc = np.zeros(6)
        self.last: Measurement | None = None
        """The latest :class:`Measurement` (diagnostics)."""

    def _noise(self, std: float, size: int = 3) -> FloatArray:
        out: FloatArray = self._rng.normal(0.0, std, size=size) if std > 0 else np.zeros(size)
        return out

    def wrench(self, data: mujoco.MjData) -> tuple[FloatArray, FloatArray]:
        """The noise-free F/T reading in the world frame (the parent's wrench on the ladle).

        Parameters
        ----------
        data : mujoco.MjData
            After ``mj_step`` or ``mj_forward`` (which compute the sensors).

        Returns
        -------
        force : ndarray, shape (3,)
            N; at rest ``(0, 0, m g)`` plus the weight of what rests on the ladle.
        torque : ndarray, shape (3,)
            Nm, about the site ``ladle_ft``.
        """
        rot = data.site_xmat[self._site].reshape(3, 3)
        f = rot @ data.sensordata[self._force_adr:self._force_adr + 3]
        tq = rot @ data.sensordata[self._torque_adr:self._torque_adr + 3]
        return np.asarray(f, dtype=np.float64), np.asarray(tq, dtype=np.float64)

    def inertial_force(self, data: mujoco.MjData) -> FloatArray:
        """``m (a - g)`` of the ladle from the kinematics, noise-free (N, world), shape (3,)."""
        mujoco.mj_objectAcceleration(self.model, data, mujoco.mjtObj.mjOBJ_BODY,
                                     self.ids.ladle_body, self._acc, 0)
        return self.ladle_mass * self._acc[3:].copy()

    def measure(self, data: mujoco.MjData) -> Measurement:
        """One noisy measurement (advances the noise stream; no latency, no filter).

        Parameters
        ----------
        data : mujoco.MjData

        Returns
        -------
        Measurement
            ``filtered`` is NaN here (:meth:`read` fills it).
        """
        cfg = self.settings
        per_reading = cfg.force_noise / math.sqrt(max(1.0, cfg.force_rate * cfg.period))
        force, torque = self.wrench(data)
        inertial = self.inertial_force(data)
        if self._tare is None:  # the first reading: empty and at rest; the tare averages
            self._tare = force - inertial + self._bias + \
                self._noise(cfg.force_noise / math.sqrt(cfg.tare_samples))
        force = force + self._bias + self._noise(per_reading)
        acc = inertial + self.ladle_mass * self._noise(cfg.accel_noise)
        tray = data.site_xpos[self.ids.tray_site] + self._offset + self._noise(cfg.pose_noise)
        residual = force - acc - self._tare
        return Measurement(force=force, torque=torque, inertial=acc, load=float(residual[2]),
                           filtered=math.nan,
                           contact=max(float(np.hypot(residual[0], residual[1])),
                                       -float(residual[2])),
                           tray=np.asarray(tray, dtype=np.float64))

    def read(self, data: mujoco.MjData) -> Reading:
        """The reading at the current state of ``data``; call once per control period.

        Parameters
        ----------
        data : mujoco.MjData
            After ``mj_step``/``mj_forward``.

        Returns
        -------
        Reading
            r, s, t from the measurements (module doc); ``on_ladle``, ``in_target`` and
            ``tray`` are the ground truth (records only).
        """
        cfg = self.settings
        m = self.measure(data)
        _push(self._fifo_load, (m.load, m.contact))
        _push(self._fifo_r, m.tray)
        _push(self._fifo_t, m.tray)
        # the oldest: latency_s periods ago; clipped below at -s_on (the bowl's floor pushing
        # the tray up reads as a negative load of newtons, never soup: unclipped, the filter
        # took half a second to recover from a push into the pile)
        load, contact = self._fifo_load[0]
        load = max(load, -cfg.s_on)
        prev = 0.0 if self._filtered is None else self._filtered  # tared: starts at 0
        if contact <= cfg.contact_hold:  # else: the load is hidden; filter and s hold
            self._filtered = prev + self._alpha * (load - prev)
            s = self._s.update(self._filtered)
        else:
            self._filtered = prev
            s = bool(self._s.state)
        r = self._r.update(-_signed_distance(SOUP_BOWL, self._fifo_r[0], R_ABOVE))
        t = self._t.update(-_signed_distance(TARGET_BOWL, self._fifo_t[0], T_ABOVE))
        self.last = replace(m, filtered=self._filtered)
        return Reading(r=r, s=s, t=t, on_ladle=self.truth.on_ladle(data),
                       in_target=self.truth.in_target(data),
                       tray=data.site_xpos[self.ids.tray_site].copy())

    def on_ladle(self, data: mujoco.MjData) -> BoolArray:
        """Ground truth: beads resting on the ladle, shape (30,) (records only)."""
        return self.truth.on_ladle(data)

    def in_target(self, data: mujoco.MjData) -> BoolArray:
        """Ground truth: beads inside the target bowl, shape (30,) (the trial's count)."""
        return self.truth.in_target(data)


def make_sensors(kind: str, model: mujoco.MjModel, ids: SceneIds | None = None, *,
                 seed: int = 0, settings: SensorSettings | None = None) -> Any:
    """The r, s, t sensors of ``kind`` for a scene.

    Parameters
    ----------
    kind : str
        One of :data:`SENSOR_KINDS`: ``"franka"`` (:class:`FrankaSensors`) or ``"ideal"``
        (:class:`~tli_verify.sim.sensors.ScoopSensors`, noise-free and privileged).
    model : mujoco.MjModel
    ids : SceneIds, optional
    seed : int, optional
        The Franka sensors' noise (replaces ``settings.seed``); the ideal ones ignore it.
    settings : SensorSettings, optional
        Franka only; an error for ``"ideal"``.

    Returns
    -------
    FrankaSensors or ScoopSensors
        Both have ``read(data) -> Reading`` and ``in_target(data)``.

    Raises
    ------
    InputError
        An unknown kind, or settings for the ideal sensors.
    """
    if kind == "franka":
        return FrankaSensors(model, ids, settings, seed=seed)
    if kind == "ideal":
        if settings is not None:
            raise InputError("sensors 'ideal': take no settings (noise-free; the settings "
                             "are the 'franka' sensors')")
        return ScoopSensors(model, ids)
    raise InputError(f"sensor kind {kind!r}: one of {', '.join(SENSOR_KINDS)}")
