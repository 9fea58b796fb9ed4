"""The debounced sensors of the MuJoCo loop (tli_verify.sim.sensors.Debounce)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("mujoco")

from tli_verify.sim.sensors import Debounce, Reading


def _reading(r: bool, s: bool, t: bool) -> Reading:
    return Reading(r=r, s=s, t=t, on_ladle=np.zeros(30, dtype=bool),
                   in_target=np.zeros(30, dtype=bool), tray=np.zeros(3))


def _reference(raw: list[bool], hold: int) -> list[bool]:
    """The specification: the output takes a new value once the raw input has held it for
    ``hold`` consecutive periods; the first reading is taken as it is."""
    out = [raw[0]]
    for k in range(1, len(raw)):
        run = raw[max(0, k - hold + 1):k + 1]
        out.append(raw[k] if len(run) == hold and all(v == raw[k] for v in run)
                   and raw[k] != out[-1] else out[-1])
    return out


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.booleans(), st.booleans(), st.booleans()), min_size=1,
                max_size=40), st.integers(1, 5))
def test_each_sensor_follows_the_specification(raw: list[tuple[bool, bool, bool]],
                                               hold: int) -> None:
    deb = Debounce(hold)
    got = [deb.update(_reading(*v)) for v in raw]
    for i, name in enumerate("rst"):
        want = _reference([v[i] for v in raw], hold)
        assert [getattr(g, name) for g in got] == want


def test_a_blip_shorter_than_hold_is_ignored_and_a_hold_is_taken() -> None:
    deb = Debounce(3)
    seq = [(True, True, False)] * 2 + [(True, False, False)] * 2 + [(True, True, False)] \
        + [(True, False, False)] * 3
    s = [deb.update(_reading(*v)).s for v in seq]
    assert s == [True, True, True, True, True, True, True, False]


def test_hold_one_passes_raw_readings_and_other_fields_are_kept() -> None:
    deb = Debounce(1)
    raw = _reading(False, True, True)
    raw.on_ladle[3] = True
    out = deb.update(raw)
    assert (out.r, out.s, out.t) == (False, True, True) and out.on_ladle[3]
    with pytest.raises(ValueError, match="hold"):
        Debounce(0)
