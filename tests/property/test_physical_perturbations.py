"""The physical perturbation strategies and seeded draws of the Franka campaign.

Bounds (property tests over the strategies and over seeded draws) and the shrinking the
encoding promises (fewer, smaller, later, shorter). Uniformity and determinism of ``draw`` and
the person's hand: ``tests/unit/test_sim_perturbations.py``.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, Phase, find, given, settings
from hypothesis import strategies as st

pytest.importorskip("mujoco")

from tli_verify.errors import TliError
from tli_verify.sim.loop import draw_perturbations
from tli_verify.sim.perturbations import (
    MAX_ELEVATION,
    PUSH_DISTANCE,
    PUSH_DURATION,
    PUSH_PEAK_SPEED,
    PUSH_WINDOW,
    TILT_ANGLE,
    TILT_DELAY,
    TILT_DURATION,
    TILT_PEAK_SPEED,
    Perturbation,
    min_push_duration,
    trial_perturbations,
)

TOL = 1e-9
Z_MAX = math.sin(math.radians(MAX_ELEVATION))


def within(value: float, bounds: tuple[float, float]) -> bool:
    return bounds[0] - TOL <= value <= bounds[1] + TOL


def assert_bounded(p: Perturbation) -> None:
    assert len(p.motion) == 3 and all(math.isfinite(c) for c in p.motion)
    assert abs(p.motion[2]) <= Z_MAX * p.magnitude + TOL  # within 30 degrees of horizontal
    if p.kind == "push":
        assert p.rotation == (0.0, 0.0, 0.0)  # a translation only
        assert within(p.magnitude, PUSH_DISTANCE), p
        assert within(p.duration, (min_push_duration(p.magnitude), PUSH_DURATION[1]))
        assert p.peak_speed <= PUSH_PEAK_SPEED + TOL
        assert within(p.start, PUSH_WINDOW)
    else:
        assert p.kind == "tilt"
        assert p.displacement == (0.0, 0.0, 0.0)  # a rotation only
        assert within(p.magnitude, TILT_ANGLE), p
        assert within(p.duration, TILT_DURATION)
        assert within(p.start, TILT_DELAY)
    assert round(p.start * 1000) == pytest.approx(p.start * 1000, abs=1e-6)  # on the ms grid
    assert round(p.duration * 1000) == pytest.approx(p.duration * 1000, abs=1e-6)


@st.composite
def counts(draw_: st.DrawFn) -> tuple[int, int, int, int]:
    max_p = draw_(st.integers(0, 3))
    max_t = draw_(st.integers(0, 3))
    return draw_(st.integers(0, max_p)), max_p, draw_(st.integers(0, max_t)), max_t


@given(st.data(), counts())
@settings(max_examples=60, suppress_health_check=[HealthCheck.too_slow])
def test_drawn_perturbations_respect_the_bounds_and_counts(
        data: st.DataObject, c: tuple[int, int, int, int]) -> None:
    min_p, max_p, min_t, max_t = c
    ps = data.draw(trial_perturbations(min_pushes=min_p, max_pushes=max_p, min_tilts=min_t,
                                       max_tilts=max_t))
    n_push = sum(p.kind == "push" for p in ps)
    n_tilt = sum(p.kind == "tilt" for p in ps)
    assert min_p <= n_push <= max_p and min_t <= n_tilt <= max_t
    assert [p.kind for p in ps] == ["push"] * n_push + ["tilt"] * n_tilt
    for kind in ("push", "tilt"):
        starts = [p.start for p in ps if p.kind == kind]
        assert starts == sorted(set(starts))  # sorted, one per start
    for p in ps:
        assert_bounded(p)


@given(st.integers(0, 2**32 - 1))
@settings(max_examples=25, deadline=None)
def test_seeded_draws_are_one_push_and_one_tilt_within_bounds(seed: int) -> None:
    ps = draw_perturbations(seed)  # loop's entry point: the campaign's draw
    assert [p.kind for p in ps] == ["push", "tilt"]
    for p in ps:
        assert_bounded(p)


def test_levels_select_the_kinds() -> None:
    only_motion = trial_perturbations(max_pushes=2, max_tilts=2, min_pushes=1,
                                      levels=("motion",))
    ps = find(only_motion, lambda ps: len(ps) == 2,
              settings=settings(database=None, max_examples=200, phases=[Phase.generate]))
    assert {p.kind for p in ps} == {"push"}
    with pytest.raises(TliError):
        trial_perturbations(min_tilts=1, levels=("motion",))
    with pytest.raises(TliError):
        trial_perturbations(levels=("free",))


def _minimal(condition: object) -> tuple[Perturbation, ...]:
    return find(trial_perturbations(max_pushes=3, max_tilts=3), condition,  # type: ignore[arg-type]
                settings=settings(database=None, max_examples=500,
                                  phases=[Phase.generate, Phase.shrink]))


def test_shrinks_to_one_smallest_latest_push() -> None:
    """A failure that needs any push shrinks to one push, of the smallest distance and
    duration, at the end of the window (later), along +x, and no tilt (fewer)."""
    ps = _minimal(lambda ps: any(p.kind == "push" for p in ps))
    assert len(ps) == 1
    (p,) = ps
    assert p.kind == "push"
    assert p.displacement == pytest.approx((PUSH_DISTANCE[0], 0.0, 0.0))
    assert p.duration == pytest.approx(min_push_duration(PUSH_DISTANCE[0]))
    assert p.start == pytest.approx(PUSH_WINDOW[1])


def test_shrinks_to_one_smallest_latest_tilt() -> None:
    ps = _minimal(lambda ps: any(p.kind == "tilt" for p in ps))
    assert len(ps) == 1
    (p,) = ps
    assert p.kind == "tilt"
    assert p.rotation == pytest.approx((TILT_ANGLE[0], 0.0, 0.0))
    # the shortest a turn of that angle may last (the person's peak turning speed)
    assert p.duration == pytest.approx(max(TILT_DURATION[0],
                                           1.875 * TILT_ANGLE[0] / TILT_PEAK_SPEED), abs=1e-3)
    assert p.start == pytest.approx(TILT_DELAY[1])


def test_shrinking_keeps_what_the_failure_needs() -> None:
    """A failure needing a long, early push keeps exactly that much of it -- the distance
    shrinks to the threshold, the start to the latest time that still fails, the duration to
    the shortest that distance allows -- and whatever else is left is the simplest
    perturbation (smallest, latest, shortest; hypothesis may stop before deleting it)."""
    ps = _minimal(lambda ps: any(p.kind == "push" and p.start <= 2.0 and p.magnitude >= 0.2
                                 for p in ps))
    needed = [p for p in ps if p.kind == "push" and p.start == pytest.approx(2.0)]
    assert len(needed) == 1
    assert needed[0].magnitude == pytest.approx(0.2, abs=1e-6)
    assert needed[0].duration == pytest.approx(min_push_duration(needed[0].magnitude))
    for p in ps:
        if p is not needed[0]:
            assert p.duration == pytest.approx(
                min_push_duration(p.magnitude) if p.kind == "push"
                else max(TILT_DURATION[0], 1.875 * p.magnitude / TILT_PEAK_SPEED), abs=1e-3)
            assert p.start == pytest.approx(PUSH_WINDOW[1] if p.kind == "push"
                                            else TILT_DELAY[1])
