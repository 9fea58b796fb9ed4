"""The bundled task files read exactly as the Python worlds they replaced.

Each of ``tasks/scoop.toml``, ``cooking.toml``, ``color-tracing.toml`` and ``inspection.toml``
is compared with the former class (kept for this purpose in ``tests/support/legacy_worlds``) on
at least 100,000 sampled state histories: random walks through and beyond the workspace with
random jumps (perturbations), so every region, every boundary crossing and every latch
transition is exercised. Readings (every sensor at every step) and the latent history must be
identical, for sensor lags 0 and 19; the true regions must agree by name.

Regions are closed sets in priority order; the former cooking world used strict inequalities
on two segments (``x1 = 3`` and ``x1 = 7`` with ``5 <= x2 < 7``), a set of measure zero the
samples never hit: a separate test pins that documented difference on exactly those points.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.support.legacy_worlds import LEGACY
from tli_verify.tasks.registry import find_task

HISTORIES = 100_000
STEPS = 12


def _histories(lo: np.ndarray, hi: np.ndarray, rng: np.random.Generator, *,
               count: int = HISTORIES, steps: int = STEPS) -> np.ndarray:
    """``count`` walks of ``steps`` states, shape (B, T, 2): steps of 3 % of the workspace,
    10 % jumps to uniform states, starting anywhere in the box grown by 10 %."""
    span = hi - lo
    big_lo, big_hi = lo - 0.1 * span, hi + 0.1 * span
    X = np.empty((count, steps, 2))
    X[:, 0] = rng.uniform(big_lo, big_hi, size=(count, 2))
    for k in range(1, steps):
        step = rng.normal(scale=0.03 * span, size=(count, 2))
        jump = rng.random(count) < 0.1
        X[:, k] = np.where(jump[:, None], rng.uniform(big_lo, big_hi, size=(count, 2)),
                           X[:, k - 1] + step)
    return X


@pytest.mark.parametrize("name", sorted(LEGACY))
@pytest.mark.parametrize("lag", [0, 19])
def test_readings_identical_on_100k_histories(name: str, lag: int) -> None:
    old = LEGACY[name](lag=lag)
    task = find_task(name).with_lag(lag)
    # the lag shifts the same per-step map: 10,000 longer histories suffice for it
    X = _histories(np.array(old.lo), np.array(old.hi), np.random.default_rng([7, lag]),
                   **({"count": 10_000, "steps": 60} if lag else {}))
    want, want_latent = old.sensors_and_latent(X)
    got, got_latent = task.sensors_and_latent(X)
    assert task.sensor_names == old.sensor_names
    np.testing.assert_array_equal(got, want)
    # the latches the task keeps are the former latent state of the same name (cooking's old
    # latent also copied the reading's ch and br, which the task reads from the regions)
    common = [n for n in task.latent_names if n in old.latent_names]
    assert common == list(task.latent_names)
    for n in common:
        np.testing.assert_array_equal(got_latent[..., task.latent_names.index(n)],
                                      want_latent[..., old.latent_names.index(n)])
    # every sensor takes both values somewhere (the samples exercise the whole model)
    assert want.any(axis=(0, 1)).all() and (~want).any(axis=(0, 1)).all()


@pytest.mark.parametrize("name", sorted(LEGACY))
def test_true_regions_agree_by_name(name: str) -> None:
    old = LEGACY[name]()
    task = find_task(name)
    assert set(task.region_names) == set(old.region_names)
    X = np.random.default_rng(3).uniform(np.array(old.lo) - 1, np.array(old.hi) + 1,
                                         size=(200_000, 2))
    np.testing.assert_array_equal(task.true_mode(X), old.true_mode(X))
    assert task.lo == old.lo and task.hi == old.hi


def test_cooking_differs_only_on_its_documented_boundary_segments() -> None:
    old, task = LEGACY["cooking"](), find_task("cooking")
    # a lattice through every boundary of the regions, and the segments themselves
    g = np.linspace(0.0, 10.0, 401)  # step 0.025: hits 3, 5, 7 exactly
    X = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    differ = task.true_mode(X) != old.true_mode(X)
    on_segments = np.isin(X[:, 0], (3.0, 7.0)) & (X[:, 1] >= 5.0) & (X[:, 1] < 7.0)
    np.testing.assert_array_equal(differ, on_segments)
    assert on_segments.sum() > 100


@pytest.mark.parametrize("name", ["scoop", "color-tracing", "inspection"])
def test_other_worlds_agree_on_their_boundaries_too(name: str) -> None:
    old, task = LEGACY[name](), find_task(name)
    lo, hi = np.array(old.lo), np.array(old.hi)
    gx = np.linspace(lo[0], hi[0], 4 * int(hi[0] - lo[0]) * 10 + 1)
    gy = np.linspace(lo[1], hi[1], 4 * int(hi[1] - lo[1]) * 10 + 1)
    X = np.stack(np.meshgrid(gx, gy), axis=-1).reshape(-1, 2)
    np.testing.assert_array_equal(task.true_mode(X), old.true_mode(X))
    np.testing.assert_array_equal(task.sensors(X[:, None, :])[:, 0],
                                  old.sensors(X[:, None, :])[:, 0])
