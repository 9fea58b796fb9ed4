"""The scooping task's sensors, computed from the physics (paper Sec. 7.2).

Never a scripted flag: every reading comes from the simulator's state in ``mjData``.

* ``r`` -- *the spoon is in the soup bowl's region*: the tray frame's origin (site
  ``ladle_tray``) lies inside the soup bowl's volume, extended ``R_ABOVE`` over its rim. It is
  the ladle's geometry against the bowl's, not "a bead touches the ladle": that would stay on
  while the soup is carried away.
* ``s`` -- *soup on the spoon*: at least one bead rests on the ladle: its centre lies in the
  tray's volume (within the tray radius, between the tray floor and one bead diameter above the
  rim, in the tray frame) and it touches a tray geom (a contact with the floor or rim, or its
  centre within ``FLOOR_GAP`` of resting height over the floor) -- or touches such a bead (a
  second layer).
* ``t`` -- *at the target*: the tray frame's origin is above the target bowl (within its
  radius, between its floor and ``T_ABOVE`` over its rim) **and** there is soup to deliver: a
  bead on the ladle, or in the target bowl or the column above it (falling in while
  pouring). An empty spoon over the target is not "at the
  target": the task is not done, and the executive keeps reaching for the soup.

The spec's modes (``specs/franka-scoop.toml``) label the readings: ``a = !r & !s & !t``,
``b = r & !s & !t``, ``c = s & !t`` (soup on the spoon overrides the bowl region, as pink
overrides yellow in the 2-D world), ``d = t``; every reading is labelled.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt

from tli_verify.sim.scene import (
    BEAD_RADIUS,
    RIM_HEIGHT,
    SOUP_BOWL,
    TARGET_BOWL,
    TRAY_RADIUS,
    SceneIds,
    scene_ids,
)

__all__ = ["HOLD", "R_ABOVE", "SENSOR_NAMES", "T_ABOVE", "Debounce", "Reading", "ScoopSensors"]

BoolArray = npt.NDArray[np.bool_]
FloatArray = npt.NDArray[np.float64]

SENSOR_NAMES = ("r", "s", "t")
R_ABOVE = 0.02
"""How far over the soup bowl's rim (m) its region extends."""
T_ABOVE = 0.25
"""How far over the target bowl's rim (m) "above the target" extends."""
FLOOR_GAP = 0.003
"""A bead whose centre is within this (m) of one radius above the tray floor lies on it."""
HOLD = 3
"""Control periods a raw sensor value must hold before the debounced reading takes it
(:class:`Debounce`: 3 periods of 20 ms)."""


@dataclass(frozen=True, slots=True, eq=False)
class Reading:
    """One reading and the physical facts behind it.

    Attributes
    ----------
    r, s, t : bool
        The sensors (module doc).
    on_ladle : ndarray of bool, shape (30,)
        Beads resting on the ladle.
    in_target : ndarray of bool, shape (30,)
        Beads inside the target bowl.
    tray : ndarray, shape (3,)
        World position of the tray frame.
    """

    r: bool
    s: bool
    t: bool
    on_ladle: BoolArray
    in_target: BoolArray
    tray: FloatArray

    def to_dict(self) -> dict[str, bool]:
        """``{"r": .., "s": .., "t": ..}``."""
        return {"r": self.r, "s": self.s, "t": self.t}


class ScoopSensors:
    """The r, s, t sensors of a scene built by :mod:`tli_verify.sim.scene`.

    Parameters
    ----------
    model : mujoco.MjModel
    ids : SceneIds, optional
        Default: looked up in ``model``.
    """

    __slots__ = ("_bead_of_geom", "_bead_rows", "_is_tray", "_views", "ids", "model")

    def __init__(self, model: mujoco.MjModel, ids: SceneIds | None = None) -> None:
        self.model = model
        self.ids = scene_ids(model) if ids is None else ids
        self._bead_of_geom = np.full(model.ngeom, -1, dtype=np.int64)
        self._bead_of_geom[self.ids.bead_geoms] = np.arange(self.ids.bead_geoms.size)
        self._is_tray = np.zeros(model.ngeom, dtype=bool)
        self._is_tray[list(self.ids.ladle_geoms)] = True
        b = self.ids.bead_bodies
        # the beads' rows of xpos: a slice (a view, no copy) when their ids are consecutive
        self._bead_rows: slice | npt.NDArray[np.int64] = (
            slice(int(b[0]), int(b[0]) + b.size)
            if b.size and np.array_equal(b, np.arange(b[0], b[0] + b.size)) else b)
        self._views: tuple[mujoco.MjData, FloatArray, FloatArray, FloatArray] | None = None

    def _bind(self, data: mujoco.MjData) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Views of ``data``'s body positions (``xpos``), the tray site's position and its
        rotation matrix (3, 3), made once per ``data``: each attribute access of ``MjData``
        builds a new array object, and ``MjData`` never reallocates its arrays."""
        v = self._views
        if v is None or v[0] is not data:
            site = self.ids.tray_site
            v = (data, data.xpos, data.site_xpos[site], data.site_xmat[site].reshape(3, 3))
            self._views = v
        return v[1], v[2], v[3]

    def _beads(self, data: mujoco.MjData) -> FloatArray:
        """The beads' world positions, shape (30, 3) (a view of ``data.xpos`` when their body
        ids are consecutive: read it before the next step)."""
        return self._bind(data)[0][self._bead_rows]

    def _local(self, data: mujoco.MjData, beads: FloatArray | None = None) -> FloatArray:
        """Bead centres in the tray frame, shape (30, 3) (``beads``: their world positions,
        :meth:`_beads`, when already read)."""
        xpos, site_pos, rot = self._bind(data)
        if beads is None:
            beads = xpos[self._bead_rows]
        return np.asarray((beads - site_pos) @ rot)

    def in_tray_volume(self, data: mujoco.MjData) -> BoolArray:
        """Beads whose centre lies in the tray's volume (tray frame; module doc), shape (30,)."""
        local = self._local(data)
        radial = np.hypot(local[:, 0], local[:, 1])
        return (radial < TRAY_RADIUS) & (local[:, 2] > 0.0) & \
            (local[:, 2] < RIM_HEIGHT + 2 * BEAD_RADIUS)

    def on_ladle(self, data: mujoco.MjData, beads: FloatArray | None = None) -> BoolArray:
        """Beads resting on the ladle, shape (30,).

        In the tray's volume and touching a tray geom (a contact), or lying on the tray floor
        (centre within ``FLOOR_GAP`` of one radius above it: a bead that rolls or bounces on
        the floor loses its contact for a step now and then), or touching such a bead.
        ``beads``: the beads' world positions (``data.xpos`` of the bead bodies) when already
        read.
        """
        local = self._local(data, beads)
        radial = np.hypot(local[:, 0], local[:, 1])
        inside = (radial < TRAY_RADIUS) & (local[:, 2] > 0.0) & \
            (local[:, 2] < RIM_HEIGHT + 2 * BEAD_RADIUS)
        if not np.count_nonzero(inside):  # (any(): numpy's Python-level reduction)
            return inside
        touching = local[:, 2] < BEAD_RADIUS + FLOOR_GAP
        pairs = data.contact.geom[: data.ncon]
        bead = self._bead_of_geom[pairs]  # (ncon, 2): each side's bead, -1 for other geoms
        is_bead = bead >= 0
        # the beads in a contact whose other side is a tray geom
        touching[bead[is_bead & self._is_tray[pairs[:, ::-1]]]] = True
        on = inside & touching
        b0, b1 = bead[:, 0], bead[:, 1]
        both = is_bead[:, 0] & is_bead[:, 1]
        for _ in range(2):  # beads lying on beads that lie on the tray
            if not np.count_nonzero(both):
                break
            u, v = b0[both], b1[both]
            more = on.copy()
            more[u[on[v]]] = True
            more[v[on[u]]] = True
            more &= inside
            if not np.count_nonzero(more != on):
                break
            on = more
        return on

    def in_target(self, data: mujoco.MjData) -> BoolArray:
        """Beads inside the target bowl, shape (30,)."""
        return TARGET_BOWL.inside(self._beads(data))

    def over_target(self, data: mujoco.MjData) -> BoolArray:
        """Beads in the target bowl or in the column above it (falling in), shape (30,)."""
        return TARGET_BOWL.inside(self._beads(data), above=T_ABOVE)

    def read(self, data: mujoco.MjData) -> Reading:
        """The reading at the current state of ``data`` (after ``mj_step``/``mj_forward``).

        Returns
        -------
        Reading
        """
        xpos, site_pos, _ = self._bind(data)
        tray = site_pos.copy()
        beads = xpos[self._bead_rows]  # read once for the three tests
        on = self.on_ladle(data, beads)
        target = TARGET_BOWL.inside(beads)
        x, y, z = tray.tolist()
        r = SOUP_BOWL.contains(x, y, z, above=R_ABOVE)
        above_target = TARGET_BOWL.contains(x, y, z, above=T_ABOVE)
        s = bool(np.count_nonzero(on))
        t = above_target and (s or bool(np.count_nonzero(TARGET_BOWL.inside(beads,
                                                                     above=T_ABOVE))))
        return Reading(r=r, s=s, t=t, on_ladle=on, in_target=target, tray=tray)


class Debounce:
    """The sensors as the executive sees them: each of r, s, t debounced (paper Sec. 7.2).

    A physical sensor chatters where the physics does: a carried bead that bounces on the
    tray floor loses its contact for a few milliseconds, and a raw ``s`` would switch
    the executive c -> a -> c and count each blink as an invariance failure (a cut learned
    from a bounce). As a real soup sensor is filtered, each sensor here changes only after
    its raw value has held the new value for ``hold`` consecutive control periods; the
    first reading is taken as it is. The filtered readings are still functions of the
    physics (of its last ``hold`` states), never a scripted flag.

    Call :meth:`update` once per control period, with the raw reading of that period.

    Parameters
    ----------
    hold : int, optional
        Default :data:`HOLD`; 1 passes the raw readings through.
    """

    __slots__ = ("_count", "_state", "hold")

    def __init__(self, hold: int = HOLD) -> None:
        if hold < 1:
            raise ValueError(f"hold must be >= 1, got {hold}")
        self.hold = int(hold)
        self._state: list[bool] | None = None
        self._count = [0, 0, 0]

    def update(self, raw: Reading) -> Reading:
        """The debounced reading after this period's raw ``raw`` (its other fields kept).

        Parameters
        ----------
        raw : Reading

        Returns
        -------
        Reading
        """
        values = [raw.r, raw.s, raw.t]
        if self._state is None:
            self._state = values
        for i, v in enumerate(values):
            if v == self._state[i]:
                self._count[i] = 0
                continue
            self._count[i] += 1
            if self._count[i] >= self.hold:
                self._state[i] = v
                self._count[i] = 0
        r, s, t = self._state
        return Reading(r=r, s=s, t=t, on_ladle=raw.on_ladle, in_target=raw.in_target,
                       tray=raw.tray)
