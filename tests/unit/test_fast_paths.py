"""Single-state fast paths of the closed loop agree with the general (batched) paths.

The fast paths (``GMM.posterior_one``, ``LPVDS.velocity`` on one state, ``Task.region_one``,
the automaton's reading lookup cache, ``TaskSensors`` on the scalar region test) compute the
same math in plain Python; only float summation order may differ, so floats are compared to
1e-12 relative and integers/modes exactly.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.ds.gmm import GMM
from tli_verify.ds.lpvds import LPVDS
from tli_verify.errors import ModelError
from tli_verify.logic.automaton import AssumptionViolation, TaskAutomaton
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import load_spec
from tli_verify.runtime.task_sensors import TaskSensors
from tli_verify.tasks.registry import find_task
from tli_verify.tasks.task import Task


def _random_ds(rng: np.random.Generator, n: int, k: int) -> LPVDS:
    means = rng.normal(scale=4.0, size=(k, n))
    L = rng.normal(size=(k, n, n))
    covs = np.einsum("kij,klj->kil", L, L) + 0.05 * np.eye(n)
    priors = rng.uniform(0.1, 1.0, size=k)
    priors /= priors.sum()
    A = rng.normal(size=(k, n, n))
    return LPVDS(attractor=rng.normal(size=n), priors=priors, means=means, covs=covs, A=A,
                 P=np.eye(n))


@settings(max_examples=40)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 4), k=st.integers(1, 7),
       scale=st.sampled_from([0.5, 5.0, 40.0]))
def test_single_state_posterior_and_velocity_match_batched(seed: int, n: int, k: int,
                                                           scale: float) -> None:
    rng = np.random.default_rng(seed)
    ds = _random_ds(rng, n, k)
    mix = GMM(priors=ds.priors, means=ds.means, covs=ds.covs)
    X = rng.normal(scale=scale, size=(8, n))
    P = mix.posterior(X)
    F = ds.velocity(X)
    for x, p, f in zip(X, P, F, strict=True):
        one = np.array(mix.posterior_one(x.tolist()))
        assert one.shape == (k,)
        np.testing.assert_allclose(one, p, rtol=1e-12, atol=1e-14)
        v = ds.velocity(x)  # 1-D float64: the plain-Python path
        assert v.shape == (n,) and v.dtype == np.float64
        tol = 1e-12 * max(1.0, float(np.abs(f).max()))
        np.testing.assert_allclose(v, f, rtol=1e-12, atol=tol)
        np.testing.assert_allclose(v, ds.velocity(x.tolist()), rtol=1e-12, atol=tol)


def test_single_state_velocity_rejects_wrong_dimension() -> None:
    ds = _random_ds(np.random.default_rng(0), 2, 3)
    with pytest.raises(ModelError, match="shape"):
        ds.velocity(np.zeros(3))


def test_scoop_scalar_region_test_matches_array_test() -> None:
    world = find_task("scoop")
    rng = np.random.default_rng(1)
    edges = [-8.0, -4.0, 2.0, 6.0, 8.0, np.nextafter(-4.0, 0), np.nextafter(2.0, 0),
             np.nextafter(6.0, 7), np.nextafter(6.0, 0), np.nan, np.inf, -np.inf]
    grid = np.array(list(itertools.product(edges, edges)))
    X = np.vstack([grid, rng.uniform(-9.0, 9.0, size=(2000, 2))])
    want = world.region_index(X)
    got = np.array([world.region_one(x.tolist()) for x in X])
    np.testing.assert_array_equal(got, want)


@pytest.fixture(scope="module")
def scoop_automaton(specs_dir: Path) -> TaskAutomaton:
    return synthesize(load_spec(specs_dir / "scoop.toml"))


def test_automaton_lookup_cache_matches_uncached(scoop_automaton: TaskAutomaton) -> None:
    aut = scoop_automaton
    readings = [frozenset(c) for r in range(len(aut.inputs) + 1)
                for c in itertools.combinations(aut.inputs, r)]

    def uncached(state: int, reading: frozenset[str]) -> int | None:
        return next((t.target for t in aut.transitions
                     if t.source == state and t.matches(reading)), None)

    for _ in range(2):  # the second pass answers from the cache
        for state in range(len(aut.states)):
            for reading in readings:
                want = uncached(state, reading)
                if want is None:
                    with pytest.raises(AssumptionViolation):
                        aut.next_mode(state, reading)
                    continue
                assert aut.next_mode(state, reading) == (want, aut.states[want].mode)
                # other reading forms agree with the cached frozenset
                assert aut.next_mode(state, sorted(reading))[0] == want
                assert aut.next_mode(state, {v: v in reading for v in aut.inputs})[0] == want


@pytest.mark.parametrize("lag", [0, 3])
def test_world_sensors_scalar_regions_match_uncached_reads(lag: int) -> None:
    world = find_task("scoop").with_lag(lag)
    assert world.lag == lag
    rng = np.random.default_rng(2 + lag)
    fast, slow = TaskSensors(world), TaskSensors(world, region_cache=False)
    x = np.array([-5.0, 4.0])
    fast.reset(x)
    slow.reset(x)
    # a walk that visits every region, with jumps (perturbations)
    for t in range(600):
        step = rng.normal(scale=0.6, size=2)
        if t % 97 == 0:
            step = rng.uniform(-12.0, 12.0, size=2)
        x = np.clip(x + step, -8.0, 8.0)
        assert fast.read(x) == slow.read(x)
        assert fast.latent == slow.latent


class _PlainSensors:
    """A sensor model that is not a TaskSensors: run_episodes takes the general path."""

    def __init__(self, world: Task) -> None:
        self.inner = TaskSensors(world, region_cache=False)

    def reset(self, x0: np.ndarray) -> None:
        self.inner.reset(x0)

    def read(self, x: np.ndarray) -> dict[str, bool]:
        return self.inner.read(x)


def test_batched_fast_path_matches_general_path() -> None:
    from tli_verify.experiments.scoop_task import scoop_setup
    from tli_verify.runtime.episodes import random_start
    from tli_verify.runtime.loop import run_episodes
    from tli_verify.runtime.setup import make_policy

    setup = scoop_setup()
    world = setup.task
    base = make_policy(setup, "LTL-DS")
    rng = np.random.default_rng(5)
    n = 12
    starts = np.array([random_start(world, setup.automaton, rng) for _ in range(n)])
    pushes = {(i, t): rng.uniform(-10.0, 10.0, size=2)
              for i in range(n) for t in rng.integers(1, 400, size=2).tolist()}

    def perturb(i: int, t: int, x: np.ndarray) -> np.ndarray | None:
        d = pushes.get((i, t))
        return None if d is None else np.clip(x + d, -8.0, 8.0)

    fast = run_episodes([base.fork() for _ in range(n)], [TaskSensors(world) for _ in range(n)],
                        starts, steps=600, perturb=perturb)
    slow = run_episodes([base.fork() for _ in range(n)], [_PlainSensors(world) for _ in range(n)],
                        starts, steps=600, perturb=perturb)
    assert sum(len(r.events) for r in fast) > n  # perturbations and mode changes happened
    for a, b in zip(fast, slow, strict=True):
        assert (a.success, a.steps, a.modes, a.automaton_states) == \
            (b.success, b.steps, b.modes, b.automaton_states)
        assert [type(e).__name__ for e in a.events] == [type(e).__name__ for e in b.events]
        np.testing.assert_allclose(a.states, b.states, rtol=1e-12, atol=1e-12)


def test_batched_loop_calls_an_overridden_decide() -> None:
    """A subclass's decide() (e.g. the no-replan ablation) is not bypassed by the fast path."""
    from tli_verify.experiments.scoop_task import scoop_setup
    from tli_verify.runtime.executive import LTLDSPolicy
    from tli_verify.runtime.loop import run_episodes
    from tli_verify.runtime.setup import make_policy

    class Counting(LTLDSPolicy):
        calls = 0

        def decide(self, x: Any, sensors: Any, *, perturbed: bool = False) -> str:
            type(self).calls += 1
            return super().decide(x, sensors, perturbed=perturbed)

    setup = scoop_setup()
    base = make_policy(setup, "LTL-DS")
    pols = []
    for _ in range(3):
        p = object.__new__(Counting)
        fork = base.fork()
        for name in LTLDSPolicy.__slots__:
            setattr(p, name, getattr(fork, name))
        pols.append(p)
    starts = np.array([[-5.0, 4.0], [-2.0, -6.0], [7.0, 0.0]])
    res = run_episodes(pols, [TaskSensors(setup.task) for _ in starts], starts, steps=300)
    assert Counting.calls == sum(r.steps for r in res) > 0
