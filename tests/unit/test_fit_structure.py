"""The A-fit's structure (fit_a(structure=), learn_lpvds(blocks=)): decoupled groups of
coordinates, as a pose task's learner keeps position and orientation (issue 35)."""

from __future__ import annotations

import numpy as np
import pytest

from tli_verify.ds.lpvds import learn_lpvds
from tli_verify.ds.lyapunov import block_structure, fit_a
from tli_verify.errors import SolverError


def _biased_pose_data(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 6-D 'pose' whose position sweeps to x* with a velocity the linear law does not
    explain (a constant drift along y), while the orientation sits at a constant offset from
    its attractor: the offset can stand in for a bias."""
    rng = np.random.default_rng(seed)
    x_star = np.zeros(6)
    t = np.linspace(0.0, 3.0, 60)
    X, V = [], []
    for _ in range(3):
        p0 = rng.normal(size=3) * 2.0
        pos = np.exp(-t)[:, None] * p0
        vel = -pos + np.array([0.0, 0.3, 0.0])
        rot = np.tile([0.05, 0.0, -0.04], (t.size, 1)) + rng.normal(scale=1e-4, size=(t.size, 3))
        X.append(np.hstack([pos, rot]))
        V.append(np.hstack([vel, -0.2 * rot]))
    return np.vstack(X), np.vstack(V), x_star


def test_block_structure_masks_the_cross_entries() -> None:
    m = block_structure(6, [[3, 4, 5]])
    assert m[:3, :3].all() and m[3:, 3:].all()
    assert not m[:3, 3:].any() and not m[3:, :3].any()
    assert block_structure(3, [[0], [2]]).tolist() == [[True, False, False],
                                                       [False, True, False],
                                                       [False, False, True]]
    with pytest.raises(SolverError, match="two groups"):
        block_structure(4, [[0, 1], [1, 2]])
    with pytest.raises(SolverError, match="outside"):
        block_structure(4, [[4]])


def test_a_free_fit_uses_the_orientation_offset_as_a_bias_and_the_blocks_do_not() -> None:
    """The failure the pose learner's default avoids: with every entry free, the position's
    velocity leans on the near-constant orientation offset (large cross entries); decoupled,
    the cross entries are exactly 0 and the position block is the data's own."""
    X, V, x_star = _biased_pose_data(0)
    gamma = np.ones((len(X), 1))
    free, _ = fit_a(X, V, gamma, x_star, np.eye(6), eps=1e-3)
    blocked, info = fit_a(X, V, gamma, x_star, np.eye(6), eps=1e-3,
                          structure=block_structure(6, [[3, 4, 5]]))
    assert info.status == "optimal"
    assert np.abs(free[0][:3, 3:]).max() > 1.0  # 0.3 dm/s of drift over a 0.05 rad offset
    assert np.all(blocked[0][:3, 3:] == 0.0) and np.all(blocked[0][3:, :3] == 0.0)
    # still a certified-stable fit: the LMI holds for the structured A
    sym = blocked[0] + blocked[0].T
    assert np.linalg.eigvalsh(sym).max() < 0.0


def test_learn_lpvds_records_its_blocks_and_keeps_them_in_every_component() -> None:
    X, V, x_star = _biased_pose_data(1)
    ds, info = learn_lpvds(X, V, x_star, seed=0, rate_budget=0.03, control_dt=0.02,
                           blocks=[[3, 4, 5]])
    assert info.blocks == ((3, 4, 5),)
    A = np.asarray(ds.A)
    assert np.all(A[:, :3, 3:] == 0.0) and np.all(A[:, 3:, :3] == 0.0)
    _, plain = learn_lpvds(X, V, x_star, seed=0, rate_budget=0.03, control_dt=0.02)
    assert plain.blocks == ()


def test_a_structure_without_a_free_diagonal_is_refused() -> None:
    X, V, x_star = _biased_pose_data(2)
    mask = np.ones((6, 6), dtype=bool)
    mask[0, 0] = False
    with pytest.raises(SolverError, match="free diagonal"):
        fit_a(X, V, np.ones((len(X), 1)), x_star, np.eye(6), structure=mask)
