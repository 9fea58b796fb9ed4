"""Batched episodes whose executives learn *different* cuts share each mode's DS evaluation
(``run_episodes``: the LPV-DS once per distinct DS, then each cut set's modulation) and still
agree with one-at-a-time episodes (paper eq. 7: ``M(x) f(x)``, ``f`` independent of the cuts)."""

from __future__ import annotations

import numpy as np

from tli_verify.experiments.fig7 import NOMINAL_START
from tli_verify.experiments.scoop_task import scoop_setup
from tli_verify.runtime.episodes import run_variant, run_variant_batch


def test_episodes_with_different_learned_cuts_agree_with_single_runs() -> None:
    setup = scoop_setup()
    fig7 = {957: np.array([6.09, 6.01])}  # the documented Fig. 7 case (a displacement)
    starts = np.array([NOMINAL_START, NOMINAL_START, [-6.0, 0.0]])
    tables: list[dict[int, np.ndarray]] = [fig7, {}, {340: np.array([0.0, 8.0])}]
    batch = run_variant_batch(setup, "LTL-DS", starts, tables, steps=3000)
    models = {id(r.model) for r in batch}
    assert len(models) >= 2  # the Fig. 7 episode learned a cut the others did not
    assert batch[0].cuts_added >= 1 and batch[1].cuts_added == 0
    for x0, table, got in zip(starts, tables, batch, strict=True):
        one = run_variant(setup, "LTL-DS", x0, table, steps=3000)
        assert got.success and got.modes == one.modes and got.cuts_added == one.cuts_added
        np.testing.assert_allclose(got.states, one.states, rtol=1e-9, atol=1e-9)


def test_modulate_is_velocity_split_in_two() -> None:
    setup = scoop_setup()
    res = run_variant(setup, "LTL-DS", NOMINAL_START,
                      {957: np.array([6.09, 6.01])}, steps=3000)
    mm = next(m for m in res.model.modes.values() if m.cuts)
    X = np.random.default_rng(0).uniform(-8, 8, size=(50, 2))
    np.testing.assert_array_equal(mm.modulate(X, mm.ds.velocity(X), dt=0.01),
                                  mm.velocity(X, dt=0.01))


def test_each_episode_gets_its_own_cut_set_on_the_shared_ds() -> None:
    """Two episodes side by side from the same state at the soup surface: one executive knows
    the Fig. 7 cut of mode b (it stays in the soup), the other does not (it leaves). One batched
    DS evaluation, two modulations: each must match its own single run."""
    from tli_verify.runtime.events import InvarianceFailure
    from tli_verify.runtime.executive import LTLDSPolicy
    from tli_verify.runtime.loop import run_episode, run_episodes
    from tli_verify.runtime.task_sensors import TaskSensors

    setup = scoop_setup()
    learned = run_variant(setup, "LTL-DS", NOMINAL_START, {957: np.array([6.09, 6.01])},
                          steps=3000)
    fail = next(e for e in learned.events if isinstance(e, InvarianceFailure))
    x0 = np.asarray(fail.last_inside)

    def policies() -> list[LTLDSPolicy]:
        return [LTLDSPolicy(setup.automaton, m, setup.certificate)
                for m in (learned.model, setup.model)]

    batch = run_episodes(policies(), [TaskSensors(setup.task) for _ in range(2)],
                         np.array([x0, x0]), steps=40)
    singles = [run_episode(p, TaskSensors(setup.task), x0, steps=40) for p in policies()]
    assert batch[0].modes[:10] != batch[1].modes[:10]  # the cut matters here
    for got, one in zip(batch, singles, strict=True):
        assert got.modes == one.modes
        np.testing.assert_allclose(got.states, one.states, rtol=1e-9, atol=1e-9)
