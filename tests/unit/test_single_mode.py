"""The single-mode study's machinery: rollouts, start sampling, cut learning, aggregation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tli_verify.boundary.cuts import inside_cuts
from tli_verify.errors import TliError
from tli_verify.experiments.single_mode import (
    POLICIES,
    SingleModeConfig,
    learn_cuts,
    rollout,
    run,
    sample_starts,
)
from tli_verify.experiments.single_mode_report import markdown, summarize, write_outputs
from tli_verify.tasks.generate import ConvexMode

SQUARE = ConvexMode.from_vertices([[0, 0], [10, 0], [10, 10], [0, 10]])
GOAL = np.array([5.0, 1.5])
SPIRAL = np.array([[-0.4, 2.0], [-2.0, -0.4]])


def _spiral(X: np.ndarray) -> np.ndarray:
    return (X - GOAL) @ SPIRAL.T


def test_rollout_semantics() -> None:
    starts = np.array([[5.0, 5.0], [9.5, 9.5], [5.2, 1.6]])
    res = rollout(lambda X: -(X - GOAL), starts, SQUARE.contains, GOAL, record=True)
    assert res.success.all() and not res.left.any()
    assert res.paths is not None and res.paths.shape == (1001, 3, 2)
    assert res.reached[2]  # starts inside the goal radius: success at t = 0
    out = rollout(lambda X: np.tile([100.0, 0.0], (len(X), 1)), starts, SQUARE.contains, GOAL,
                  record=True)
    np.testing.assert_array_equal(out.success, [False, False, True])
    out = rollout(lambda X: np.tile([100.0, 0.0], (len(X), 1)), starts[:2], SQUARE.contains,
                  GOAL, record=True)
    assert out.left.all() and not out.success.any()
    assert SQUARE.contains(out.last_inside).all() and not SQUARE.contains(out.outside).any()
    steps = np.linalg.norm(np.diff(out.paths, axis=0), axis=2)
    assert steps.max() <= 0.01 * 20.0 + 1e-12  # speed cap 20, dt 0.01
    np.testing.assert_array_equal(out.entry, starts[:2])
    stuck = rollout(lambda X: np.zeros_like(X), starts[:2], SQUARE.contains, GOAL)
    assert stuck.reachability_failures.all()


def test_sample_starts() -> None:
    rng = np.random.default_rng(0)
    demo = np.array([[1.0, 1.0], [9.9, 9.9], [5.0, 5.0]])
    S0 = sample_starts(demo, SQUARE.contains, rng, count=50, std=0.0)
    assert all(any(np.array_equal(s, d) for d in demo) for s in S0)
    S = sample_starts(demo, SQUARE.contains, rng, count=200, std=3.0)
    assert S.shape == (200, 2) and SQUARE.contains(S).all()
    assert len(np.unique(S, axis=0)) > 150


def test_cut_learning_makes_a_stable_ds_invariant() -> None:
    """A spiralling linear DS leaves the square; cuts fix every start (Thm. 1 in practice)."""
    starts = SQUARE.sample_inside(np.random.default_rng(0), 40, min_margin=0.5)
    nominal = rollout(_spiral, starts, SQUARE.contains, GOAL)
    assert nominal.left.sum() > 10
    learned = learn_cuts(_spiral, starts, SQUARE.contains, GOAL, np.random.default_rng(1),
                         config=SingleModeConfig(), lyapunov=np.eye(2))
    assert learned.converged and learned.final.success.all()
    assert 1 <= len(learned.cuts) <= 5
    assert learned.curve[0] == pytest.approx(nominal.success.mean())
    assert learned.curve[-1] == 1.0 and len(learned.curve) == len(learned.cuts) + 1
    assert inside_cuts(starts, learned.cuts, tol=1e-9).all()  # "entries" keeps starts inside
    for _, last, out in learned.failures:
        assert SQUARE.contains(last[None])[0] and not SQUARE.contains(out[None])[0]


def test_config_validation() -> None:
    for bad in (dict(trials=0), dict(starts=0), dict(noise_percent=(-5,)), dict(seed=-1),
                dict(cut_constraints="all"), dict(max_cuts=-1)):
        with pytest.raises(TliError):
            SingleModeConfig(**bad).validate()  # type: ignore[arg-type]


def test_tiny_study_is_deterministic_across_workers(tmp_path) -> None:
    cfg = SingleModeConfig(trials=2, starts=12, noise_percent=(0, 30), steps=400,
                           bc_max_epochs=20, heldout=False, max_cuts=3)
    one, rec = run(cfg, workers=1, record_trial=0)
    two, _ = run(cfg, workers=2, record_trial=None)
    assert [t.success for t in one] == [t.success for t in two]
    assert [t.curve for t in one] == [t.curve for t in two]
    summary = summarize(one, cfg, seconds=1.0, workers=1)
    assert set(summary["success"]) == set(POLICIES)
    for row in summary["success"].values():
        assert set(row) == {"0", "30"} and all(0.0 <= v <= 1.0 for v in row.values())
    files = write_outputs(summary, rec, tmp_path)
    names = {f.name for f in files}
    assert names == {"single_mode.json", "single_mode.md", "single_mode_cuts.png",
                     "single_mode_rollouts.png"}
    data = json.loads((tmp_path / "single_mode.json").read_text())
    assert data["success"] == summary["success"]
    md = markdown(summary)
    assert "| DS+mod |" in md and "(100)" in md
