"""The physical perturbation strategies and draws of the Franka campaign.

Bounds (property tests over the strategies and over seeded draws), the shrinking the encoding
promises (fewer, smaller, later), and determinism of :func:`draw` in this process and in a fresh
one with other modules imported.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, find, given, settings
from hypothesis import strategies as st
from hypothesis.errors import NoSuchExample

pytest.importorskip("mujoco")

from tli_verify.errors import TliError
from tli_verify.sim.loop import Perturbation, draw_perturbations
from tli_verify.sim.perturbations import (
    PUSH_DURATION,
    PUSH_FORCE,
    PUSH_WINDOW,
    TILT_DELAY,
    TILT_DURATION,
    TILT_TORQUE,
    draw,
    trial_perturbations,
)

REPO = Path(__file__).resolve().parents[2]
TOL = 1e-9


def within(value: float, bounds: tuple[float, float]) -> bool:
    return bounds[0] - TOL <= value <= bounds[1] + TOL


def assert_bounded(p: Perturbation) -> None:
    assert len(p.wrench) == 6 and all(math.isfinite(w) for w in p.wrench)
    if p.kind == "push":
        force = math.sqrt(sum(w * w for w in p.wrench[:3]))
        assert within(force, PUSH_FORCE), force
        assert p.wrench[3:] == (0.0, 0.0, 0.0)  # a force only
        assert within(p.duration, PUSH_DURATION)
        assert within(p.start, PUSH_WINDOW)
    else:
        assert p.kind == "tilt"
        assert p.wrench[:3] == (0.0, 0.0, 0.0) and p.wrench[4:] == (0.0, 0.0)  # about x only
        assert within(-p.wrench[3], TILT_TORQUE), p.wrench  # -15..-25 Nm
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
    """A failure that needs any push shrinks to one push, of the smallest force and duration,
    at the end of the window (later), and no tilt (fewer)."""
    ps = _minimal(lambda ps: any(p.kind == "push" for p in ps))
    assert len(ps) == 1
    (p,) = ps
    assert p.kind == "push"
    assert math.sqrt(sum(w * w for w in p.wrench[:3])) == pytest.approx(PUSH_FORCE[0])
    assert p.duration == pytest.approx(PUSH_DURATION[0])
    assert p.start == pytest.approx(PUSH_WINDOW[1])


def test_shrinks_to_one_smallest_latest_tilt() -> None:
    ps = _minimal(lambda ps: any(p.kind == "tilt" for p in ps))
    assert len(ps) == 1
    (p,) = ps
    assert p.kind == "tilt"
    assert -p.wrench[3] == pytest.approx(TILT_TORQUE[0])
    assert p.duration == pytest.approx(TILT_DURATION[0])
    assert p.start == pytest.approx(TILT_DELAY[1])


def test_shrinking_keeps_what_the_failure_needs() -> None:
    """A failure needing a strong, early push keeps exactly that much of it -- the force shrinks
    to the threshold, the start to the latest time that still fails -- and whatever else is
    left is the simplest perturbation (smallest, latest; hypothesis may stop before deleting
    it)."""
    ps = _minimal(lambda ps: any(p.kind == "push" and p.start <= 2.0
                                 and math.sqrt(sum(w * w for w in p.wrench[:3])) >= 30.0
                                 for p in ps))
    needed = [p for p in ps if p.start == pytest.approx(2.0)]
    assert len(needed) == 1 and needed[0].kind == "push"
    assert math.sqrt(sum(w * w for w in needed[0].wrench[:3])) == pytest.approx(30.0, abs=1e-6)
    assert needed[0].duration == pytest.approx(PUSH_DURATION[0])
    for p in ps:
        if p is not needed[0]:
            assert p.duration == pytest.approx(PUSH_DURATION[0] if p.kind == "push"
                                               else TILT_DURATION[0])
            assert p.start == pytest.approx(PUSH_WINDOW[1] if p.kind == "push"
                                            else TILT_DELAY[1])


def test_draw_is_deterministic_and_seeds_differ() -> None:
    assert draw(7) == draw(7)
    assert draw(7, pushes=2, tilts=2) == draw(7, pushes=2, tilts=2)
    firsts = {draw(s)[0] for s in range(10)}
    assert len(firsts) == 10  # ten seeds, ten different pushes
    assert draw(3, pushes=0, tilts=0) == []


def test_draw_is_the_same_in_a_fresh_process_with_other_modules_imported() -> None:
    """Another interpreter, which imports modules full of constants before drawing (hypothesis
    would otherwise mix such "local constants" into its draws), draws the same perturbations as
    this process, where unguarded hypothesis draws of the same strategy ran first (they fill
    hypothesis's per-bounds constants cache)."""
    with pytest.raises(NoSuchExample):  # unguarded: local constants cached per bounds
        find(trial_perturbations(max_pushes=3, max_tilts=3), lambda ps: False,
             settings=settings(database=None, max_examples=300, phases=[Phase.generate]))
    code = ("import json, sys\n"
            "import tli_verify.verify.oracle, tli_verify.logic.gr1, tli_verify.sim.controller\n"
            "from tli_verify.sim.perturbations import draw\n"
            "print(json.dumps([[p.to_dict() for p in draw(s)] for s in range(6)]))\n")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True, cwd=REPO, env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin"},
                         timeout=120).stdout
    here = [[p.to_dict() for p in draw(s)] for s in range(6)]
    assert json.loads(out) == json.loads(json.dumps(here))


def test_the_public_api_fallback_draws_within_bounds_deterministically() -> None:
    from tli_verify.sim.perturbations import _draw_by_find

    strategy = trial_perturbations(min_pushes=1, min_tilts=1)
    first = _draw_by_find(strategy, 5)
    assert first == _draw_by_find(strategy, 5)
    assert [p.kind for p in first] == ["push", "tilt"]
    for p in first:
        assert_bounded(p)


def test_isolated_draws_restore_hypothesis_state() -> None:
    from hypothesis.internal.conjecture import providers

    from tli_verify.sim.perturbations import isolated_draws

    cache, getter = providers.CONSTANTS_CACHE, providers._get_local_constants
    with isolated_draws():
        assert providers.CONSTANTS_CACHE is not cache
        assert providers._get_local_constants is not getter
    assert providers.CONSTANTS_CACHE is cache and providers._get_local_constants is getter
