"""Perturbations of the Franka trials: a person's hand that drags the ladle, and its sampler.

A perturbation is the environment's, not the robot's: a *person's hand* grabs the ladle (the
rig's carrier body) when the perturbation starts, drags it along a smooth path and lets go
after ``duration`` s. The robot's policy never sees it (it only sees the sensors, and the
executive is told "perturbed"); the oracle may know it.

Two levels (:data:`LEVELS`):

* ``"motion"`` -- a *push*: the hand translates the ladle by a ``displacement`` of
  :data:`PUSH_DISTANCE` m in a direction within :data:`MAX_ELEVATION` degrees of the
  horizontal, over a duration in :data:`PUSH_DURATION` s (at least the one that keeps the
  hand's peak speed, :data:`MIN_JERK_PEAK` ``|d| / duration``, within :data:`PUSH_PEAK_SPEED`),
  starting at a time in :data:`PUSH_WINDOW` s of the trial;
* ``"task"`` -- a *tilt*: the hand turns the ladle by a ``rotation`` vector of
  :data:`TILT_ANGLE` rad about an axis within :data:`MAX_ELEVATION` degrees of the horizontal
  (any azimuth) over :data:`TILT_DURATION` s, which spills the soup; it starts a delay in
  :data:`TILT_DELAY` s after the soup is carried out of the soup bowl
  (:func:`tli_verify.sim.loop.run_trial` counts a tilt's ``start`` from there).

The path follows the minimum-jerk profile :func:`min_jerk`,
``s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5`` (Flash and Hogan 1985: how people move a hand from
point to point), and the hand is a clipped spring-damper to the moving grab target
(:class:`PersonHand`): a person can be pushed back, and pushes no harder than
:data:`HAND_MAX_FORCE` N (:data:`HAND_MAX_TORQUE` Nm).

:func:`draw` gives the perturbations of one trial, deterministic in the seed in any process,
drawn *uniformly* (numpy, stream :attr:`~tli_verify.defaults.Stream.PERTURBATIONS`): every start,
distance, duration, angle and direction equally likely within its bounds, none piled at the
bounds. The hypothesis strategies :func:`pushes`, :func:`tilts` and
:func:`trial_perturbations` cover the same bounds for property tests; their encoding shrinks
toward **fewer** perturbations (lists), **smaller** ones (distance and angle toward their lower
bounds), **later** ones and **shorter** ones. The trial loop (:mod:`tli_verify.sim.loop`) and
the physical campaign (:mod:`tli_verify.sim.campaign`, whose evidence trials draw with
:func:`draw` too) both use this module.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 7.2 (the perturbed scooping trials: a person
pushes the robot and tilts the spoon) and Asm. 2 (finitely many perturbations).
T. Flash and N. Hogan, "The coordination of arm movements: an experimentally confirmed
mathematical model", J. Neuroscience 5(7), 1985 (the minimum-jerk hand path).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from hypothesis import strategies as st

from tli_verify.defaults import Stream, rng
from tli_verify.errors import TliError

__all__ = [
    "HAND_DAMPING",
    "HAND_MAX_FORCE",
    "HAND_MAX_TORQUE",
    "HAND_ROT_DAMPING",
    "HAND_ROT_STIFFNESS",
    "HAND_STIFFNESS",
    "KINDS",
    "LEVELS",
    "MAX_ELEVATION",
    "MIN_JERK_PEAK",
    "PUSH_DISTANCE",
    "PUSH_DURATION",
    "PUSH_PEAK_SPEED",
    "PUSH_WINDOW",
    "TILT_ANGLE",
    "TILT_DELAY",
    "TILT_DURATION",
    "TILT_PEAK_SPEED",
    "PersonHand",
    "Perturbation",
    "draw",
    "min_jerk",
    "min_push_duration",
    "pushes",
    "tilts",
    "trial_perturbations",
    "zone_direction",
]

FloatArray = npt.NDArray[np.float64]

_MS = 1000
"""Times are in whole milliseconds (a readable, replayable case)."""

LEVELS: tuple[str, ...] = ("motion", "task")
"""Physical perturbation levels: ``"motion"`` pushes, ``"task"`` tilts (they spill)."""
KINDS: tuple[str, ...] = ("push", "tilt")
"""A perturbation's ``kind``, one per level of :data:`LEVELS`."""

PUSH_WINDOW = (0.5, 6.0)
"""A push starts in this window, s after the trial's start (a nominal trial scoops from about
1.5 s, carries the soup out of the bowl at about 3.3 s and is above the target at about 5.7 s)."""
PUSH_DISTANCE = (0.10, 0.30)
"""How far a push moves the ladle, m (``|displacement|``)."""
PUSH_DURATION = (0.5, 3.0)
"""Duration of a push, s (from the grab to letting go)."""
PUSH_PEAK_SPEED = 0.3
"""The fastest a person's hand moves in a push, m/s: a push lasts at least
:func:`min_push_duration` of its distance."""
MIN_JERK_PEAK = 1.875
"""Peak of the minimum-jerk speed profile ``s'(tau)`` (at ``tau = 1/2``): a path of length
``L`` over ``T`` s peaks at ``1.875 L / T``."""
MAX_ELEVATION = 30.0
"""Degrees: a push's direction and a tilt's axis lie within this of the horizontal plane
(uniformly on that zone of the sphere: ``z`` uniform in ``[-sin, sin]``, azimuth uniform)."""
TILT_DELAY = (0.0, 1.5)
"""A tilt starts this long after the soup is carried out of the soup bowl, s."""
TILT_DURATION = (0.5, 3.0)
"""Duration of a tilt, s."""
TILT_PEAK_SPEED = 0.8
"""The fastest a person's hand turns the ladle in a tilt, rad/s: a tilt lasts at least
``1.875 angle / TILT_PEAK_SPEED`` (a faster turn drives the Panda's wrist past its 2.61 rad/s
joint-velocity limit: its reflex stops the robot, as it would on the real one)."""
TILT_ANGLE = (0.6, 1.2)
"""Angle a tilt turns the ladle by, rad (35-70 degrees: enough to spill a level spoon)."""

HAND_STIFFNESS = 1500.0
"""The hand's translational stiffness, N/m: a firm grip on a moving target (a person's arm
holding a posture is of the order of 10^2-10^3 N/m; a grab-and-drag is at the stiff end). With
:data:`HAND_MAX_FORCE` the spring saturates 8 cm from its target."""
HAND_DAMPING = 2.0 * math.sqrt(HAND_STIFFNESS * 1.0)
"""The hand's translational damping, N s/m: critical for a 1 kg body (the free hand's carrier
with the ladle is 1.13 kg), about 77 N s/m."""
HAND_MAX_FORCE = 80.0
"""Largest force the hand applies, N (a person's deliberate push is 50-120 N)."""
HAND_ROT_STIFFNESS = 40.0
"""The hand's rotational stiffness, Nm/rad (a wrist twisting a handle)."""
HAND_ROT_DAMPING = 2.0
"""The hand's rotational damping, Nm s/rad (over-damped for the carrier's ~0.013 kg m^2, stable
at MuJoCo's 2 ms step: ``c dt / I`` about 0.3)."""
HAND_RELEASE = 0.25
"""Seconds over which the hand lets go at the end of a perturbation (its wrench fades linearly
to zero: a person opens the hand, the arm is not released from a stretched spring at once)."""
HAND_MAX_TORQUE = 8.0
"""Largest torque the hand applies, Nm (a person's wrist, roughly 10-15 Nm at most)."""


def min_jerk(tau: float) -> float:
    """The minimum-jerk profile ``s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5``, ``tau`` clipped to
    ``[0, 1]``: 0 at rest before, 1 at rest after, zero speed and acceleration at both ends."""
    x = min(max(float(tau), 0.0), 1.0)
    return x * x * x * (10.0 + x * (-15.0 + 6.0 * x))


def _ms(bounds: tuple[float, float]) -> tuple[int, int]:
    return round(bounds[0] * _MS), round(bounds[1] * _MS)


def _min_push_ms(distance: float, peak_speed: float, floor_ms: int) -> int:
    need = MIN_JERK_PEAK * float(distance) / float(peak_speed) * _MS
    return max(floor_ms, math.ceil(need - 1e-9))


def min_push_duration(distance: float, *, peak_speed: float = PUSH_PEAK_SPEED,
                      duration: tuple[float, float] = PUSH_DURATION) -> float:
    """The shortest duration of a push of ``distance`` m, s (on the millisecond grid).

    ``max(duration[0], 1.875 distance / peak_speed)``, rounded up to the millisecond, so the
    minimum-jerk path never moves faster than ``peak_speed``.
    """
    return _min_push_ms(distance, peak_speed, _ms(duration)[0]) / _MS


def zone_direction(z: float, azimuth: float) -> tuple[float, float, float]:
    """The unit vector of height ``z`` and ``azimuth`` (rad): ``(r cos a, r sin a, z)``,
    ``r = sqrt(1 - z^2)``. With ``z`` and ``azimuth`` uniform it is uniform on the sphere's zone
    (Archimedes: a zone's area is proportional to its height)."""
    r = math.sqrt(max(0.0, 1.0 - z * z))
    return (r * math.cos(azimuth), r * math.sin(azimuth), float(z))


def _vector(name: str, value: Any) -> tuple[float, float, float]:
    try:
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise TliError(f"perturbation: {name} must be 3 numbers, got {value!r}") from None
    if len(out) != 3 or not all(math.isfinite(v) for v in out):
        raise TliError(f"perturbation: {name} must be 3 finite numbers, got {value!r}")
    return out[0], out[1], out[2]


_ZERO = (0.0, 0.0, 0.0)


@dataclass(frozen=True, slots=True)
class Perturbation:
    """One perturbation: a person's hand moving the ladle (module doc).

    Attributes
    ----------
    kind : str
        ``"push"`` (motion level: :attr:`displacement`) or ``"tilt"`` (task level: spills;
        :attr:`rotation`).
    start : float
        Seconds (millisecond grid): after the trial's start (push), or after the soup is carried
        out of the soup bowl (tilt).
    duration : float
        Seconds (millisecond grid) from the grab to letting go.
    displacement : tuple of float, length 3
        A push's translation of the ladle, m, world frame (zero for a tilt).
    rotation : tuple of float, length 3
        A tilt's rotation vector (axis times angle, rad, world frame, about the grab point;
        zero for a push).
    """

    kind: str
    start: float
    duration: float
    displacement: tuple[float, float, float] = field(default=_ZERO)
    rotation: tuple[float, float, float] = field(default=_ZERO)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise TliError(f"perturbation: kind must be one of {KINDS}, got {self.kind!r}")
        for name in ("start", "duration"):
            value = getattr(self, name)
            if not isinstance(value, int | float) or isinstance(value, bool) or not (
                    math.isfinite(value) and value >= 0):
                raise TliError(f"perturbation: {name} must be a finite number >= 0 s, "
                               f"got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.duration <= 0:
            raise TliError(f"perturbation: duration must be > 0 s, got {self.duration!r}")
        d = _vector("displacement", self.displacement)
        r = _vector("rotation", self.rotation)
        if self.kind == "push" and r != _ZERO:
            raise TliError(f"perturbation: a push has no rotation, got {r}")
        if self.kind == "tilt" and d != _ZERO:
            raise TliError(f"perturbation: a tilt has no displacement, got {d}")
        object.__setattr__(self, "displacement", d)
        object.__setattr__(self, "rotation", r)

    @property
    def motion(self) -> tuple[float, float, float]:
        """The commanded motion: :attr:`displacement` (push) or :attr:`rotation` (tilt)."""
        return self.displacement if self.kind == "push" else self.rotation

    @property
    def magnitude(self) -> float:
        """``|motion|``: a push's distance (m) or a tilt's angle (rad)."""
        return math.sqrt(sum(c * c for c in self.motion))

    @property
    def peak_speed(self) -> float:
        """The hand's peak speed on the minimum-jerk path, m/s (push) or rad/s (tilt)."""
        return MIN_JERK_PEAK * self.magnitude / self.duration

    def to_dict(self) -> dict[str, Any]:
        """The JSON record; :meth:`from_dict` reads it back exactly."""
        key = "displacement" if self.kind == "push" else "rotation"
        return {"kind": self.kind, "start": self.start, "duration": self.duration,
                key: list(self.motion)}

    @classmethod
    def from_dict(cls, record: Mapping[str, Any]) -> Perturbation:
        """The perturbation of a :meth:`to_dict` record.

        Raises
        ------
        TliError
            A field is missing, unknown or malformed (naming it).
        """
        if not isinstance(record, Mapping):
            raise TliError(f"perturbation record must be an object, got {record!r}")
        kind = record.get("kind")
        if kind not in KINDS:
            raise TliError(f"perturbation record: kind must be one of {KINDS}, got {kind!r}")
        key = "displacement" if kind == "push" else "rotation"
        allowed = {"kind", "start", "duration", key, "applied_at"}
        extra = sorted(set(record) - allowed)
        if extra:
            raise TliError(f"perturbation record: unknown field(s) {extra} for a {kind}")
        for name in ("start", "duration", key):
            if name not in record:
                raise TliError(f"perturbation record: missing field {name!r}")
        motion = _vector(key, record[key])
        return cls(str(kind), record["start"], record["duration"],
                   **{key: motion})


# --- rotations (numpy; world frame) -------------------------------------------------------

def _hat(w: FloatArray) -> FloatArray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _norm(v: FloatArray) -> float:
    """``np.linalg.norm`` of a 1-D float64 array, without its Python-level wrapper: the same
    ``sqrt(v . v)`` (BLAS ``ddot``, then the square root), bit for bit."""
    v = v.ravel(order="K")  # what np.linalg.norm hands to dot (a copy when strided)
    return math.sqrt(float(v.dot(v)))


def _exp(w: FloatArray) -> FloatArray:
    """Rotation matrix of the rotation vector ``w`` (Rodrigues)."""
    theta = _norm(w)
    if theta < 1e-12:
        return np.eye(3) + _hat(w)
    k = _hat(w / theta)
    return np.eye(3) + math.sin(theta) * k + (1.0 - math.cos(theta)) * (k @ k)


def _log(r: FloatArray) -> FloatArray:
    """Rotation vector of the rotation matrix ``r`` (angle in ``[0, pi]``)."""
    cos = min(1.0, max(-1.0, (float(r.trace()) - 1.0) / 2.0))
    theta = math.acos(cos)
    (_, r01, r02), (r10, _, r12), (r20, r21, _) = r.tolist()
    vee = np.array(((r21 - r12) / 2.0, (r02 - r20) / 2.0, (r10 - r01) / 2.0))
    if theta < 1e-6:
        return vee
    if math.pi - theta > 1e-4:
        return theta / math.sin(theta) * vee
    # near pi: the axis from the symmetric part (R + I) / 2 = u u^T
    b = (r + np.eye(3)) / 2.0
    i = int(np.argmax(np.diag(b)))
    u = b[:, i] / math.sqrt(max(float(b[i, i]), 1e-12))
    if float(u @ vee) < 0:
        u = -u
    return theta * u / _norm(u)


def _matrix(orientation: npt.ArrayLike) -> FloatArray:
    """A rotation matrix from a quaternion ``(w, x, y, z)`` (MuJoCo's convention) or a 3x3 (or
    flat 9) matrix."""
    a = np.asarray(orientation, dtype=np.float64)
    if a.shape == (4,):
        w, x, y, z = a / float(np.linalg.norm(a))
        return np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    if a.size == 9:
        return a.reshape(3, 3).copy()
    raise TliError(f"PersonHand: an orientation is a quaternion (4,) or a matrix (3, 3), got "
                   f"shape {a.shape}")


def _clip_norm(v: FloatArray, limit: float) -> FloatArray:
    n = _norm(v)
    return v * (limit / n) if n > limit else v


class PersonHand:
    """A person's hand carrying out one :class:`Perturbation` on the ladle.

    At the first :meth:`wrench` call at or after :attr:`start` (or at :meth:`grab`) the hand
    takes the carrier's pose ``(p0, R0)``; until :attr:`end` it pulls it toward the moving
    target ``p0 + s(t) d`` (push) or ``exp(s(t) [rotation]) R0`` (tilt; ``s`` is
    :func:`min_jerk` of ``(t - start) / duration``) with

    ``F = clip_norm(k (p_target - p) - c v, f_max)`` and
    ``tau = clip_norm(k_r log(R_target R^T) - c_r omega, tau_max)``,

    the hand holding the other part of the pose where it grabbed it (a push does not turn the
    ladle, a tilt does not move its grab point). After :attr:`end` it has let go (zero wrench).

    Parameters
    ----------
    perturbation : Perturbation
    start : float, optional
        Absolute time of the grab, s (default ``perturbation.start``; the loop passes a tilt's
        start counted from the moment the soup leaves the bowl).
    stiffness, damping, max_force : float, optional
        ``k`` (N/m), ``c`` (N s/m), ``f_max`` (N); defaults :data:`HAND_STIFFNESS`,
        :data:`HAND_DAMPING`, :data:`HAND_MAX_FORCE`.
    rot_stiffness, rot_damping, max_torque : float, optional
        ``k_r`` (Nm/rad), ``c_r`` (Nm s/rad), ``tau_max`` (Nm); defaults
        :data:`HAND_ROT_STIFFNESS`, :data:`HAND_ROT_DAMPING`, :data:`HAND_MAX_TORQUE`.

    Attributes
    ----------
    start, end : float
        When the hand grabs and lets go, s.
    max_force, max_torque : float
        The largest ``|F|`` (N) and ``|tau|`` (Nm) applied so far.
    """

    def __init__(self, perturbation: Perturbation, *, start: float | None = None,
                 stiffness: float = HAND_STIFFNESS, damping: float = HAND_DAMPING,
                 max_force: float = HAND_MAX_FORCE, rot_stiffness: float = HAND_ROT_STIFFNESS,
                 rot_damping: float = HAND_ROT_DAMPING,
                 max_torque: float = HAND_MAX_TORQUE) -> None:
        gains = {"stiffness": stiffness, "damping": damping, "max_force": max_force,
                 "rot_stiffness": rot_stiffness, "rot_damping": rot_damping,
                 "max_torque": max_torque}
        for name, value in gains.items():
            if not (math.isfinite(value) and value >= 0):
                raise TliError(f"PersonHand: {name} must be finite and >= 0, got {value!r}")
        self.perturbation = perturbation
        self.start = float(perturbation.start if start is None else start)
        self.end = self.start + perturbation.duration
        self.k, self.c, self.f_max = float(stiffness), float(damping), float(max_force)
        self.k_r, self.c_r = float(rot_stiffness), float(rot_damping)
        self.tau_max = float(max_torque)
        self.max_force = 0.0
        self.max_torque = 0.0
        self._motion = np.array(perturbation.motion, dtype=np.float64)
        self._p0: FloatArray | None = None
        self._r0: FloatArray | None = None
        self._last_p: FloatArray | None = None
        self._last_r: FloatArray | None = None

    def active(self, t: float) -> bool:
        """Whether the hand acts at time ``t``: ``start <= t < end``."""
        return self.start <= t < self.end

    @property
    def grabbed(self) -> bool:
        """Whether the hand has taken the grab pose."""
        return self._p0 is not None

    def grab(self, pos: npt.ArrayLike, orientation: npt.ArrayLike) -> None:
        """Take the grab pose ``(p0, R0)`` (position, m; quaternion ``(w, x, y, z)`` or 3x3)."""
        self._p0 = np.array(pos, dtype=np.float64).reshape(3)
        self._r0 = _matrix(orientation)
        self._last_p, self._last_r = self._p0.copy(), self._r0.copy()

    @property
    def commanded(self) -> FloatArray:
        """The commanded motion: the displacement (m) or rotation vector (rad), shape (3,)."""
        return self._motion.copy()

    @property
    def achieved(self) -> FloatArray | None:
        """The motion at the last pose the hand saw, relative to the grab, shape (3,): the
        displacement (push) or the rotation vector of ``R R0^T`` (tilt); None before the grab."""
        if self._p0 is None or self._last_p is None or self._last_r is None or self._r0 is None:
            return None
        if self.perturbation.kind == "push":
            return self._last_p - self._p0
        return _log(self._last_r @ self._r0.T)

    def progress(self, t: float) -> float:
        """``s`` of the minimum-jerk path at time ``t`` (0 before the start, 1 after the end)."""
        return min_jerk((t - self.start) / self.perturbation.duration)

    def target(self, t: float) -> tuple[FloatArray, FloatArray]:
        """The grab target at ``t``: position (3,) and rotation matrix (3, 3).

        Raises
        ------
        TliError
            Before the grab.
        """
        if self._p0 is None or self._r0 is None:
            raise TliError("PersonHand.target: the hand has not grabbed the ladle yet")
        s = self.progress(t)
        if self.perturbation.kind == "push":
            return self._p0 + s * self._motion, self._r0
        return self._p0, _exp(s * self._motion) @ self._r0

    def wrench(self, t: float, pos: npt.ArrayLike, orientation: npt.ArrayLike,
               vel: npt.ArrayLike, omega: npt.ArrayLike, *, own_only: bool = False
               ) -> FloatArray:
        """The hand's wrench on the carrier at time ``t``, world frame.

        Parameters
        ----------
        t : float
            Seconds (the clock of :attr:`start`).
        pos : array_like, shape (3,)
            The grabbed point (the carrier's centre of mass, where ``xfrc_applied`` acts), m.
        orientation : array_like
            The carrier's orientation: quaternion ``(w, x, y, z)`` or rotation matrix.
        vel, omega : array_like, shape (3,)
            Linear (m/s) and angular (rad/s) velocity, world frame.
        own_only : bool, optional
            Another hand holds the ladle too: this one applies only its own part (a push its
            force, a tilt its torque) and does not hold the rest of the pose, which the other
            hand moves (two hands each holding the other's part rigidly fought each other:
            70 N between them).

        Returns
        -------
        ndarray, shape (6,)
            Force (N) and torque (Nm); zeros when the hand is not :meth:`active`. The first
            active call grabs the ladle at ``(pos, orientation)`` unless :meth:`grab` did.
        """
        if not self.active(t):
            return np.zeros(6)
        p = np.asarray(pos, dtype=np.float64).reshape(3)
        r = _matrix(orientation)
        if self._p0 is None:
            self.grab(p, r)
        self._last_p, self._last_r = p.copy(), r
        p_target, r_target = self.target(t)
        # the spring-dampers per component on floats (numpy's elementwise roundings)
        k, c, k_r, c_r = self.k, self.c, self.k_r, self.c_r
        (x, y, z), (tx, ty, tz) = p.tolist(), p_target.tolist()
        vx, vy, vz = np.asarray(vel, dtype=np.float64).reshape(3).tolist()
        force = _clip_norm(np.array((k * (tx - x) - c * vx, k * (ty - y) - c * vy,
                                     k * (tz - z) - c * vz)), self.f_max)
        ax, ay, az = _log(r_target @ r.T).tolist()
        wx, wy, wz = np.asarray(omega, dtype=np.float64).reshape(3).tolist()
        torque = _clip_norm(np.array((k_r * ax - c_r * wx, k_r * ay - c_r * wy,
                                      k_r * az - c_r * wz)), self.tau_max)
        if own_only:
            if self.perturbation.kind == "push":
                torque = np.zeros(3)
            else:
                force = np.zeros(3)
        fade = min(1.0, max(0.0, (self.end - t) / HAND_RELEASE))
        force, torque = fade * force, fade * torque  # the person lets go over HAND_RELEASE
        self.max_force = max(self.max_force, _norm(force))
        self.max_torque = max(self.max_torque, _norm(torque))
        return np.concatenate([force, torque])


# --- hypothesis strategies (property tests; shrinking) ------------------------------------

def _check_range(name: str, lo: float, hi: float, *, positive: bool = False) -> None:
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi) or lo < 0 or (
            positive and lo <= 0):
        raise TliError(f"{name}: need {'0 < ' if positive else '0 <= '}lo <= hi, finite; got "
                       f"({lo}, {hi})")


def _check_elevation(name: str, elevation: float) -> float:
    if not (math.isfinite(elevation) and 0.0 <= elevation <= 90.0):
        raise TliError(f"{name}: need 0 <= elevation <= 90 degrees, got {elevation}")
    return math.sin(math.radians(elevation))


def _later(window: tuple[float, float]) -> st.SearchStrategy[float]:
    """A time in ``window`` (s, millisecond grid), encoded as its distance before the window's
    end: it shrinks to the end (later)."""
    lo, hi = _ms(window)
    return st.floats(0.0, float(hi - lo)).map(lambda early: (hi - round(early)) / _MS)


def _smaller(bounds: tuple[float, float]) -> st.SearchStrategy[float]:
    """A value in ``bounds``, encoded as its distance above the lower bound in thousandths (mm
    or mrad): it shrinks to the lower bound (smaller), and to whole thousandths on the way (a
    float in ``[lo, hi]`` itself would shrink to the "simplest" number there, e.g. 0.25 in
    ``[0.1, 0.3]``)."""
    lo, hi = bounds
    return st.floats(0.0, (hi - lo) * _MS).map(lambda x: min(hi, lo + x / _MS))


def _directions(z_max: float) -> st.SearchStrategy[tuple[float, float, float]]:
    """Unit vectors on the zone ``|z| <= z_max``; shrink toward ``+x``."""
    return st.tuples(st.floats(-z_max, z_max),
                     st.floats(0.0, 2.0 * math.pi, exclude_max=True)).map(
        lambda za: zone_direction(*za))


def pushes(*, distance: tuple[float, float] = PUSH_DISTANCE,
           duration: tuple[float, float] = PUSH_DURATION,
           window: tuple[float, float] = PUSH_WINDOW, peak_speed: float = PUSH_PEAK_SPEED,
           elevation: float = MAX_ELEVATION) -> st.SearchStrategy[Perturbation]:
    """Motion-level pushes: the hand drags the ladle by a displacement.

    Parameters
    ----------
    distance : (float, float), optional
        Bounds of ``|displacement|``, m.
    duration : (float, float), optional
        Bounds, s; a push of ``|d|`` lasts at least :func:`min_push_duration` ``(|d|)``.
    window : (float, float), optional
        Start times, s after the trial's start.
    peak_speed : float, optional
        The hand's top speed, m/s.
    elevation : float, optional
        Largest angle of the direction above or below the horizontal, degrees.

    Returns
    -------
    SearchStrategy of Perturbation
        ``kind = "push"``; shrinks toward the smallest distance, the shortest duration, the
        latest start and the direction ``+x``.

    Raises
    ------
    TliError
        Bad bounds (naming them), or a duration too short for the longest push at
        ``peak_speed``.
    """
    _check_range("push distance", *distance, positive=True)
    _check_range("push duration", *duration, positive=True)
    _check_range("push window", *window)
    if not (math.isfinite(peak_speed) and peak_speed > 0):
        raise TliError(f"push peak_speed: need a finite speed > 0 m/s, got {peak_speed}")
    z_max = _check_elevation("push elevation", elevation)
    lo_ms, hi_ms = _ms(duration)
    if _min_push_ms(distance[1], peak_speed, lo_ms) > hi_ms:
        raise TliError(f"push duration: at most {duration[1]} s cannot move the ladle "
                       f"{distance[1]} m at {peak_speed} m/s or slower (needs "
                       f"{_min_push_ms(distance[1], peak_speed, lo_ms) / _MS} s)")

    @st.composite
    def build(draw_: st.DrawFn) -> Perturbation:
        start = draw_(_later(window))
        size = draw_(_smaller(distance))
        length = draw_(st.integers(_min_push_ms(size, peak_speed, lo_ms), hi_ms)) / _MS
        unit = draw_(_directions(z_max))
        return Perturbation("push", start, length,
                            displacement=(size * unit[0], size * unit[1], size * unit[2]))

    return build()


def tilts(*, angle: tuple[float, float] = TILT_ANGLE,
          duration: tuple[float, float] = TILT_DURATION,
          delay: tuple[float, float] = TILT_DELAY,
          elevation: float = MAX_ELEVATION) -> st.SearchStrategy[Perturbation]:
    """Task-level tilts: the hand turns the ladle about a near-horizontal axis (spills the soup).

    Parameters
    ----------
    angle : (float, float), optional
        Bounds of the rotation's angle, rad.
    duration : (float, float), optional
        Bounds, s.
    delay : (float, float), optional
        Start, s after the soup is carried out of the soup bowl.
    elevation : float, optional
        Largest angle of the axis above or below the horizontal, degrees.

    Returns
    -------
    SearchStrategy of Perturbation
        ``kind = "tilt"``; shrinks toward the smallest angle, the shortest duration, the
        longest delay and the axis ``+x``.
    """
    _check_range("tilt angle", *angle, positive=True)
    _check_range("tilt duration", *duration, positive=True)
    _check_range("tilt delay", *delay)
    z_max = _check_elevation("tilt elevation", elevation)
    lo_ms, hi_ms = _ms(duration)

    def build(parts: tuple[float, int, float, tuple[float, float, float]]) -> Perturbation:
        start, length, a, u = parts
        length = max(length, _min_push_ms(a, TILT_PEAK_SPEED, lo_ms))
        return Perturbation("tilt", start, length / _MS, rotation=(a * u[0], a * u[1], a * u[2]))

    return st.tuples(_later(delay), st.integers(lo_ms, hi_ms), _smaller(angle),
                     _directions(z_max)).map(build)


def trial_perturbations(*, max_pushes: int = 1, max_tilts: int = 1, min_pushes: int = 0,
                        min_tilts: int = 0, levels: Sequence[str] = LEVELS,
                        push: st.SearchStrategy[Perturbation] | None = None,
                        tilt: st.SearchStrategy[Perturbation] | None = None,
                        ) -> st.SearchStrategy[tuple[Perturbation, ...]]:
    """The perturbations of one physical trial: pushes, then tilts, each sorted by start.

    Parameters
    ----------
    max_pushes, max_tilts : int, optional
        At most this many of each (paper Asm. 2: finitely many).
    min_pushes, min_tilts : int, optional
        At least this many.
    levels : sequence of str, optional
        Subset of :data:`LEVELS`: without ``"motion"`` no push, without ``"task"`` no tilt.
    push, tilt : SearchStrategy of Perturbation, optional
        Default :func:`pushes` and :func:`tilts` with the module's bounds.

    Returns
    -------
    SearchStrategy of tuple of Perturbation
        Shrinks toward fewer, smaller, later, shorter perturbations (module doc); two
        perturbations of one kind drawn with the same start are one (the first).
    """
    bad = [lv for lv in levels if lv not in LEVELS]
    if bad or not levels:
        raise TliError(f"trial_perturbations: levels must be a non-empty subset of {LEVELS}, "
                       f"got {list(levels)}")
    if not (0 <= min_pushes <= max_pushes and 0 <= min_tilts <= max_tilts):
        raise TliError("trial_perturbations: need 0 <= min <= max pushes and tilts, got "
                       f"pushes {min_pushes}..{max_pushes}, tilts {min_tilts}..{max_tilts}")
    if "motion" not in levels:
        if min_pushes:
            raise TliError("trial_perturbations: min_pushes > 0 without the motion level")
        max_pushes = 0
    if "task" not in levels:
        if min_tilts:
            raise TliError("trial_perturbations: min_tilts > 0 without the task level")
        max_tilts = 0

    def unique(items: list[Perturbation]) -> tuple[Perturbation, ...]:
        by_start: dict[float, Perturbation] = {}
        for p in items:
            by_start.setdefault(p.start, p)
        return tuple(by_start[s] for s in sorted(by_start))

    push_list = st.lists(push if push is not None else pushes(), min_size=min_pushes,
                         max_size=max_pushes).map(unique)
    tilt_list = st.lists(tilt if tilt is not None else tilts(), min_size=min_tilts,
                         max_size=max_tilts).map(unique)
    return st.tuples(push_list, tilt_list).map(lambda pt: pt[0] + pt[1]).filter(
        lambda ps: sum(p.kind == "push" for p in ps) >= min_pushes
        and sum(p.kind == "tilt" for p in ps) >= min_tilts)


# --- the uniform sampler of the trials ----------------------------------------------------

def _uniform_direction(g: np.random.Generator, z_max: float) -> tuple[float, float, float]:
    z = float(g.uniform(-z_max, z_max))
    return zone_direction(z, float(g.uniform(0.0, 2.0 * math.pi)))


def _sample_motion(g: np.random.Generator, window: tuple[float, float],
                   size: tuple[float, float], duration: tuple[float, float],
                   peak_speed: float) -> tuple[float, float, tuple[float, float, float]]:
    """``(start, length, vector)`` of one push or tilt: the start on the millisecond grid of
    ``window``, the size uniform in ``size``, the length on the grid from the minimum-jerk
    floor to ``duration[1]``, the direction uniform on the zone (draws in this order)."""
    lo_ms, hi_ms = _ms(duration)
    w_lo, w_hi = _ms(window)
    start = int(g.integers(w_lo, w_hi + 1)) / _MS
    a = float(g.uniform(*size))
    length = int(g.integers(_min_push_ms(a, peak_speed, lo_ms), hi_ms + 1)) / _MS
    u = _uniform_direction(g, math.sin(math.radians(MAX_ELEVATION)))
    return start, length, (a * u[0], a * u[1], a * u[2])


def _sample_push(g: np.random.Generator) -> Perturbation:
    start, length, v = _sample_motion(g, PUSH_WINDOW, PUSH_DISTANCE, PUSH_DURATION,
                                      PUSH_PEAK_SPEED)
    return Perturbation("push", start, length, displacement=v)


def _sample_tilt(g: np.random.Generator) -> Perturbation:
    start, length, v = _sample_motion(g, TILT_DELAY, TILT_ANGLE, TILT_DURATION,
                                      TILT_PEAK_SPEED)
    return Perturbation("tilt", start, length, rotation=v)


_MAX_DRAWN = 100
"""Most perturbations of one kind :func:`draw` gives (far fewer than the distinct starts)."""


def draw(seed: int, *, pushes: int = 1, tilts: int = 1) -> list[Perturbation]:
    """The perturbations of trial ``seed``: deterministic in ``seed``, in any process.

    Every quantity is drawn uniformly with numpy from
    :func:`tli_verify.defaults.rng` ``(seed, Stream.PERTURBATIONS)`` (spawned into one
    independent stream for the pushes and one for the tilts, so the tilts do not depend on how
    many pushes are asked for): a push's start on the millisecond grid of :data:`PUSH_WINDOW`,
    its distance in :data:`PUSH_DISTANCE`, its duration on the millisecond grid from
    :func:`min_push_duration` of the distance to ``PUSH_DURATION[1]`` (uniform given the
    distance), its direction uniform on the zone within :data:`MAX_ELEVATION` of the horizontal;
    a tilt's delay in :data:`TILT_DELAY`, duration in :data:`TILT_DURATION`, angle in
    :data:`TILT_ANGLE`, axis uniform on the same zone. Two perturbations of one kind never
    share a start (a repeated start is drawn again).

    Parameters
    ----------
    seed : int
        ``>= 0``.
    pushes, tilts : int, optional
        How many of each (the paper's trials: one push, one tilt).

    Returns
    -------
    list of Perturbation
        The pushes sorted by start, then the tilts sorted by start.
    """
    if pushes < 0 or tilts < 0:
        raise TliError(f"draw: pushes and tilts must be >= 0, got {pushes}, {tilts}")
    if int(seed) < 0:
        raise TliError(f"draw: seed must be >= 0, got {seed}")
    if pushes > _MAX_DRAWN or tilts > _MAX_DRAWN:
        raise TliError(f"draw: at most {_MAX_DRAWN} pushes and tilts, got {pushes}, {tilts}")
    push_rng, tilt_rng = rng(int(seed), Stream.PERTURBATIONS).spawn(2)
    out: list[Perturbation] = []
    for n, g, sample in ((pushes, push_rng, _sample_push), (tilts, tilt_rng, _sample_tilt)):
        by_start: dict[float, Perturbation] = {}
        while len(by_start) < n:
            p = sample(g)
            by_start.setdefault(p.start, p)
        out.extend(by_start[s] for s in sorted(by_start))
    return out


# --- the perturbing hands, every physics step (kept apart from the control loop) ----------


def step_with_hands(rig: Any, substeps: int, t: float, hands: list[PersonHand | None],
                     applied: list[float]) -> None:
    """``substeps`` physics steps from time ``t``, the active hands' wrench recomputed at each.

    A hand reads the carrier's centre of mass (``xipos``, where ``xfrc_applied`` acts), its
    orientation (``ximat``) and its velocity there (``mj_objectVelocity``, world frame) -- the
    state of the last ``mj_forward``, i.e. one physics step (2 ms) old after an ``mj_step`` --
    and the sum of the active hands' wrenches goes in ``rig.push``. ``applied[i]`` gets the time
    hand ``i`` first acted. Without an active hand this is ``rig.step(substeps)``.
    """
    live = [(i, h) for i, h in enumerate(hands)
            if h is not None and h.start < t + substeps * float(rig.model.opt.timestep)
            and h.end > t]
    if not live:
        rig.push[:] = 0.0
        rig.step(substeps)
        return
    import mujoco

    model, data = rig.model, rig.data
    dt = float(model.opt.timestep)
    body, kind = rig.carrier, mujoco.mjtObj.mjOBJ_BODY
    vel6 = np.zeros(6)
    omega, vel = vel6[:3], vel6[3:]  # views: mj_objectVelocity writes (rotation, translation)
    # views of the carrier's rows (MjData never reallocates; the hand copies what it keeps)
    pos, orientation = data.xipos[body], data.ximat[body]
    push, object_velocity = rig.push, mujoco.mj_objectVelocity

    def before(j: int) -> None:
        tj = t + j * dt
        total = np.zeros(6)
        acting = [(i, hand) for i, hand in live if hand.active(tj)]
        both = len(acting) > 1
        for i, hand in acting:
            object_velocity(model, data, kind, body, vel6, 0)
            total += hand.wrench(tj, pos, orientation, vel, omega, own_only=both)
            if math.isnan(applied[i]):
                applied[i] = tj
        push[:] = total

    rig.step(substeps, before=before)
    rig.push[:] = 0.0
