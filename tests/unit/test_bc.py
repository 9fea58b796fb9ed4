"""The behaviour-cloning baseline (paper appendix E.2): architecture, bound, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from tli_verify.ds.bc import BCPolicy, train_bc
from tli_verify.errors import ModelError


def _data(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    X = rng.uniform(-3, 3, size=(300, 2))
    A = np.array([[-1.0, 2.0], [-2.0, -1.0]])
    return X, X @ A.T


def test_architecture_bound_and_fit() -> None:
    X, Y = _data(np.random.default_rng(0))
    bc = train_bc(X, Y, seed=1, max_epochs=300)
    assert isinstance(bc, BCPolicy)
    assert [w.shape for w in bc.weights] == [(2, 100), (100, 100), (100, 2)]
    assert bc.bound == 50.0 and 1 <= bc.epochs <= 300
    pred = bc.velocity(X)
    err = np.mean(np.linalg.norm(pred - Y, axis=1)) / np.mean(np.linalg.norm(Y, axis=1))
    assert err < 0.15
    far = bc.velocity(np.array([[1e4, -1e4], [-1e5, 3e4]]))
    assert np.all(np.abs(far) <= 50.0)
    np.testing.assert_allclose(bc(X[:3]), pred[:3], rtol=1e-12, atol=1e-12)


def test_seeded() -> None:
    X, Y = _data(np.random.default_rng(0))
    a = train_bc(X, Y, seed=3, max_epochs=30)
    b = train_bc(X, Y, seed=3, max_epochs=30)
    c = train_bc(X, Y, seed=4, max_epochs=30)
    np.testing.assert_array_equal(a.velocity(X), b.velocity(X))
    assert not np.array_equal(a.velocity(X), c.velocity(X))


def test_bad_input() -> None:
    with pytest.raises(ModelError):
        train_bc(np.zeros((5, 2)), np.zeros((5, 3)), seed=0)
    with pytest.raises(ModelError):
        train_bc(np.full((5, 2), np.nan), np.zeros((5, 2)), seed=0)
    X, Y = _data(np.random.default_rng(0))
    bc = train_bc(X, Y, seed=0, max_epochs=5)
    with pytest.raises(ModelError):
        bc.velocity(np.zeros((3, 3)))
