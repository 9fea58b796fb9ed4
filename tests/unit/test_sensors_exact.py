"""The ideal scooping sensors (:class:`~tli_verify.sim.sensors.ScoopSensors`) read exactly what
their plain formulation reads, over a scooping trial's states.

:meth:`ScoopSensors.read` is written for speed (views of ``MjData`` made once, the beads'
positions read once, the tray's bowl tests on floats by :meth:`~tli_verify.sim.scene.Bowl.contains`,
the contact pairs looked up once); the reference here is the sensors the plain way, as first
written: every reading (``r``, ``s``, ``t``, the beads on the ladle and in the target bowl) must be
equal, at every control period of a nominal Panda trial (beads on the ladle, over the target,
poured) -- the trials' outcomes bind the evidence.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.support.sim import require_panda

pytestmark = pytest.mark.sim


def _plain_read(sensors: Any, data: Any) -> tuple[bool, bool, bool, np.ndarray, np.ndarray]:
    """The reading of the plain formulation (the sensors as first written)."""
    from tli_verify.sim import sensors as sensors_module
    from tli_verify.sim.scene import BEAD_RADIUS, RIM_HEIGHT, SOUP_BOWL, TARGET_BOWL, TRAY_RADIUS
    from tli_verify.sim.sensors import R_ABOVE, T_ABOVE

    ids = sensors.ids
    site = ids.tray_site
    rot = data.site_xmat[site].reshape(3, 3)
    local = np.asarray((data.xpos[ids.bead_bodies] - data.site_xpos[site]) @ rot)
    radial = np.hypot(local[:, 0], local[:, 1])
    inside = (radial < TRAY_RADIUS) & (local[:, 2] > 0.0) & \
        (local[:, 2] < RIM_HEIGHT + 2 * BEAD_RADIUS)
    on = inside
    if inside.any():
        bead_of_geom = np.full(sensors.model.ngeom, -1, dtype=np.int64)
        bead_of_geom[ids.bead_geoms] = np.arange(ids.bead_geoms.size)
        is_tray = np.zeros(sensors.model.ngeom, dtype=bool)
        is_tray[list(ids.ladle_geoms)] = True
        touching = local[:, 2] < BEAD_RADIUS + sensors_module.FLOOR_GAP
        pairs = data.contact.geom[: data.ncon]
        b0, b1 = bead_of_geom[pairs[:, 0]], bead_of_geom[pairs[:, 1]]
        touching[b0[(b0 >= 0) & is_tray[pairs[:, 1]]]] = True
        touching[b1[(b1 >= 0) & is_tray[pairs[:, 0]]]] = True
        on = inside & touching
        both = (b0 >= 0) & (b1 >= 0)
        for _ in range(2):
            if not both.any():
                break
            u, v = b0[both], b1[both]
            more = on.copy()
            more[u[on[v]]] = True
            more[v[on[u]]] = True
            more &= inside
            if (more == on).all():
                break
            on = more
    tray = data.site_xpos[site].copy()
    target = TARGET_BOWL.inside(data.xpos[ids.bead_bodies])
    r = bool(SOUP_BOWL.inside(tray, above=R_ABOVE))
    s = bool(on.any())
    t = bool(TARGET_BOWL.inside(tray, above=T_ABOVE)) and (
        s or bool(TARGET_BOWL.inside(data.xpos[ids.bead_bodies], above=T_ABOVE).any()))
    return r, s, t, on, target


def test_readings_equal_the_plain_formulation_over_a_trial() -> None:
    require_panda()
    from tli_verify.sim import sensors as sensors_module
    from tli_verify.sim.franka_project import load_policy
    from tli_verify.sim.loop import run_trial

    seen: dict[str, int] = {"periods": 0, "on_ladle": 0, "t": 0, "contacts": 0}

    def frame(rig: Any) -> None:
        got = rig.sensors.read(rig.data)
        r, s, t, on, target = _plain_read(rig.sensors, rig.data)
        assert (got.r, got.s, got.t) == (r, s, t)
        assert np.array_equal(got.on_ladle, on)
        assert np.array_equal(got.in_target, target)
        assert np.array_equal(rig.sensors.on_ladle(rig.data), on)
        assert np.array_equal(rig.sensors.in_target(rig.data), target)
        seen["periods"] += 1
        seen["on_ladle"] += int(on.sum()) > 0
        seen["t"] += t
        # the contact rule alone (no bead counts as lying on the floor): the pairs' lookup
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(sensors_module, "FLOOR_GAP", -1.0)
            by_contact = _plain_read(rig.sensors, rig.data)[3]
            assert np.array_equal(rig.sensors.on_ladle(rig.data), by_contact)
        seen["contacts"] += int(by_contact.sum()) > 0

    res = run_trial(load_policy("LTL-DS"), 2, perturbations=[], frame=frame,
                    sensors="ideal")  # the ideal sensors are the ones compared
    # the trial exercised every reading: beads on the ladle, the tray over the target
    assert seen["periods"] > 100 and seen["on_ladle"] > 10 and seen["t"] > 10, seen
    assert seen["contacts"] > 10, seen
    assert res.delivered >= 1
