"""The soup bowl's pit at the far side and a bowl already scooped from (tli_verify.sim.scene)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mujoco")

from tli_verify.errors import TliError
from tli_verify.sim.demos import MocapRig
from tli_verify.sim.scene import (
    N_BEADS,
    SOUP_BOWL,
    SOUP_CENTER,
    SOUP_FLAT,
    SOUP_PIT,
    SOUP_SLOPE,
    TARGET_BOWL,
    soup_floor,
)

pytestmark = pytest.mark.sim


def test_floor_height_is_flat_in_the_pit_and_rises_on_the_funnel() -> None:
    pit_y = float(SOUP_CENTER[1] + SOUP_PIT[1])
    assert soup_floor(pit_y) == pytest.approx(SOUP_BOWL.floor)
    assert soup_floor(pit_y + 0.9 * SOUP_FLAT) == pytest.approx(SOUP_BOWL.floor)
    near = pit_y + 0.1
    assert soup_floor(near) == pytest.approx(
        SOUP_BOWL.floor + (0.1 - SOUP_FLAT) * math.tan(SOUP_SLOPE))


@pytest.mark.parametrize("seed", [0, 3])
def test_the_beads_gather_in_the_pit_against_the_far_wall(seed: int) -> None:
    rig = MocapRig(seed)
    pos = rig.data.xpos[rig.ids.bead_bodies]
    assert SOUP_BOWL.inside(pos).all()
    # every bead on the far side of the bowl's centre: ahead of a ladle sliding towards -y
    assert (pos[:, 1] < SOUP_CENTER[1]).all()
    assert np.median(pos[:, 1]) < SOUP_CENTER[1] + SOUP_PIT[1] + SOUP_FLAT


def test_a_bowl_already_scooped_from_keeps_the_other_beads_out_of_the_task() -> None:
    rig = MocapRig(1, in_bowl=12)
    pos = rig.data.xpos[rig.ids.bead_bodies]
    inside = SOUP_BOWL.inside(pos)
    assert inside.sum() == 12 and inside[:12].all()
    assert not TARGET_BOWL.inside(pos, above=0.3).any()
    assert (pos[12:, 0] > 0.7).all()  # parked on the table's far edge, at rest
    assert float(np.abs(rig.data.cvel[rig.ids.bead_bodies[12:]]).max()) < 1e-3
    with pytest.raises(TliError, match="in_bowl"):
        MocapRig(1, in_bowl=N_BEADS + 1)
