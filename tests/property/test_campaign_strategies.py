"""The public perturbation strategies (tli_verify.verify.strategies).

Properties: sequences are finite, sorted, in the window, with magnitudes up to the workspace
size (paper Asm. 2 and the appendix's perturbation distribution); motion-level pushes keep the
state in its true region, task-level pushes land in their target region; the JSON form round
trips; and hypothesis's shrinker, on this encoding, goes to fewer, smaller, later perturbations.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, find, given, settings
from hypothesis import strategies as st

from tli_verify.errors import TliError
from tli_verify.tasks.registry import find_task
from tli_verify.verify.strategies import (
    Case,
    Push,
    apply_push,
    case_from_json,
    case_to_json,
    cases,
    push_sequences,
    starts,
    workspace_size,
)

TASK = find_task("scoop")
D = workspace_size(TASK)


@given(push_sequences(TASK, max_pushes=4, window=300))
def test_sequences_are_finite_sorted_and_bounded(seq: tuple[Push, ...]) -> None:
    assert len(seq) <= 4
    steps = [p.step for p in seq]
    assert steps == sorted(set(steps))
    assert all(1 <= s <= 300 for s in steps)
    assert all(p.magnitude <= D * (1 + 1e-9) for p in seq)
    assert all((p.level == "task") == (p.target is not None) for p in seq)


@given(st.data())
def test_motion_level_push_stays_in_its_region(data: st.DataObject) -> None:
    x = np.array(data.draw(starts(TASK)))
    (p,) = data.draw(push_sequences(TASK, max_pushes=1, min_pushes=1, levels=("motion",)))
    y = apply_push(TASK, x, p)
    assert TASK.region_one(y) == TASK.region_one(x)
    assert bool(TASK.in_workspace(y[None])[0])
    assert np.linalg.norm(y - x) <= p.magnitude + 1e-9


@given(st.data())
def test_task_level_push_lands_in_its_target_region(data: st.DataObject) -> None:
    x = np.array(data.draw(starts(TASK)))
    (p,) = data.draw(push_sequences(TASK, max_pushes=1, min_pushes=1, levels=("task",)))
    y = apply_push(TASK, x, p)
    assert p.target is not None
    assert TASK.region_names[TASK.region_one(y)] == p.target


@given(st.data())
def test_free_push_is_the_clipped_displacement(data: st.DataObject) -> None:
    x = np.array(data.draw(starts(TASK)))
    (p,) = data.draw(push_sequences(TASK, max_pushes=1, min_pushes=1, levels=("free",)))
    y = apply_push(TASK, x, p)
    assert np.allclose(y, np.clip(x + np.array(p.displacement), TASK.lo, TASK.hi))


@given(starts(TASK, regions=("white", "pink")))
def test_starts_lie_in_the_requested_regions(x: tuple[float, ...]) -> None:
    assert TASK.region_names[TASK.region_one(x)] in ("white", "pink")


@given(cases(TASK, max_pushes=3))
def test_case_json_round_trips(case: Case) -> None:
    assert case_from_json(case_to_json(case), dim=2) == case


@pytest.mark.parametrize("doc", [
    {"start": [0.0], "perturbations": []},
    {"start": [0.0, 0.0], "perturbations": [{"step": 0, "displacement": [1.0, 0.0]}]},
    {"start": [0.0, 0.0], "perturbations": [{"step": 3, "displacement": [1.0, 0.0]},
                                            {"step": 2, "displacement": [1.0, 0.0]}]},
    {"start": [0.0, 0.0], "perturbations": [{"step": 3, "displacement": [1.0, math.nan]}]},
    {"start": [0.0, 0.0], "perturbations": [{"step": 3, "displacement": [1.0, 0.0],
                                             "level": "task"}]},
    {"start": [0.0, 0.0], "perturbations": [{"step": 3, "displacement": [1.0, 0.0],
                                             "level": "sideways"}]},
])
def test_malformed_case_json_is_refused(doc: dict) -> None:  # type: ignore[type-arg]
    with pytest.raises(TliError, match="case"):
        case_from_json(doc, dim=2, where="case")


_SHRINK = settings(database=None, max_examples=400, deadline=None, derandomize=True,
                   phases=[Phase.generate, Phase.shrink],
                   suppress_health_check=list(HealthCheck))


def test_shrinks_toward_fewer_smaller_later_perturbations() -> None:
    # "a perturbation larger than 3 before step 200": the minimal sequence is one push just
    # over magnitude 3 (hypothesis prefers the simplest float: 4.0), at step 199 (the latest
    # that qualifies), level "free", direction +x1 (angle 0)
    window = 300

    def big_early(seq: tuple[Push, ...]) -> bool:
        return any(p.magnitude > 3.0 and p.step < 200 for p in seq)

    seq = find(push_sequences(TASK, max_pushes=4, window=window), big_early,
               settings=_SHRINK)
    assert len(seq) == 1
    (p,) = seq
    assert p.step == 199
    assert 3.0 < p.magnitude <= 4.0
    assert p.level == "free"
    assert p.displacement[1] == 0.0


def test_shrinks_a_pair_to_the_latest_pair() -> None:
    def two_big(seq: tuple[Push, ...]) -> bool:
        return sum(p.magnitude > 1.0 for p in seq) >= 2

    seq = find(push_sequences(TASK, max_pushes=4, window=100), two_big, settings=_SHRINK)
    assert [p.step for p in seq] == [99, 100]
    assert all(p.magnitude <= 2.0 for p in seq)


def test_deleting_a_push_keeps_the_others_in_place() -> None:
    # "a push before step 100 and one after step 200": the minimal sequence is exactly two
    # zero pushes at the latest qualifying steps (no filler pushes kept to hold the others)
    def both(seq: tuple[Push, ...]) -> bool:
        return any(p.step < 100 for p in seq) and any(p.step > 200 for p in seq)

    seq = find(push_sequences(TASK, max_pushes=4, window=300), both, settings=_SHRINK)
    assert [p.step for p in seq] == [99, 300]
    assert all(p.magnitude == 0.0 and p.level == "free" for p in seq)


@pytest.mark.parametrize(("x", "d"), [
    # found by hypothesis (randomized run): the segment leaves the non-convex white region,
    # re-enters it, and the bisection's half-way point landed in another region
    ((6.38277672, -6.68813149), (-12.68167984, 4.49101731)),
    ((6.08676385, 0.70525252), (-8.29578748, -10.05082835)),
    ((7.07002553, 0.15364898), (-14.46701903, -6.17403078)),
])
def test_motion_level_push_across_a_non_convex_region_stays_in_it(
        x: tuple[float, float], d: tuple[float, float]) -> None:
    start = np.array(x)
    here = TASK.region_one(list(start))
    y = apply_push(TASK, start, Push(step=1, displacement=d, level="motion"))
    free = np.clip(start + np.array(d), TASK.lo, TASK.hi)
    assert TASK.region_one(list(free)) != here  # the free push would leave the region
    assert TASK.region_one(list(y)) == here
    assert np.linalg.norm(y - start) <= np.linalg.norm(d) + 1e-9
