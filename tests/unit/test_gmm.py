"""GMM mixing functions gamma_k(x) (paper eq. 4): log-space posterior and the two fitters."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from tli_verify.ds.gmm import GMM, fit_em_bic, fit_pcgmm
from tli_verify.errors import ModelError


def mixture() -> GMM:
    return GMM(priors=np.array([0.2, 0.5, 0.3]),
               means=np.array([[0.0, 0.0], [3.0, 1.0], [-2.0, 4.0]]),
               covs=np.array([np.eye(2), [[2.0, 0.5], [0.5, 1.0]], 0.3 * np.eye(2)]))


def test_posterior_matches_bayes_rule() -> None:
    g = mixture()
    X = np.random.default_rng(0).normal(scale=3, size=(50, 2))
    dens = np.stack([g.priors[k] * multivariate_normal(g.means[k], g.covs[k]).pdf(X)
                     for k in range(3)], axis=1)
    np.testing.assert_allclose(g.posterior(X), dens / dens.sum(axis=1, keepdims=True),
                               rtol=1e-10, atol=1e-14)


def test_posterior_is_stable_far_away() -> None:
    g = mixture()
    X = np.array([[1e6, -1e6], [1e150, 0.0], [-3e4, 2e4]])
    gamma = g.posterior(X)
    assert np.all(np.isfinite(gamma))
    np.testing.assert_allclose(gamma.sum(axis=1), 1.0)


def test_arrays_are_copied_and_frozen() -> None:
    priors = np.array([0.5, 0.5])
    g = GMM(priors=priors, means=np.zeros((2, 2)), covs=np.stack([np.eye(2)] * 2))
    priors[0] = 0.9
    assert g.priors[0] == 0.5
    with pytest.raises(ValueError, match="read-only"):
        g.means[0, 0] = 1.0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"covs": np.stack([np.eye(2), -np.eye(2)])}, "not symmetric positive definite"),
        ({"priors": np.array([0.5, 0.0])}, "finite and positive"),
        ({"means": np.zeros((3, 2))}, r"means must have shape \(2, n\)"),
    ],
)
def test_invalid_mixtures(kwargs: dict[str, np.ndarray], message: str) -> None:
    base = {"priors": np.array([0.5, 0.5]), "means": np.zeros((2, 2)),
            "covs": np.stack([np.eye(2)] * 2)}
    with pytest.raises(ModelError, match=message):
        GMM(**{**base, **kwargs})


def _two_motions() -> tuple[np.ndarray, np.ndarray]:
    """Two straight strokes in different directions, sharing no region."""
    s = np.linspace(0, 1, 80)[:, None]
    X = np.vstack([np.hstack([10 * s, 0 * s]), np.hstack([10 + 0 * s, 10 * s])])
    V = np.vstack([np.tile([1.0, 0.0], (80, 1)), np.tile([0.0, 1.0], (80, 1))])
    return X, V


def test_pcgmm_separates_motion_directions_and_is_seeded() -> None:
    X, V = _two_motions()
    g = fit_pcgmm(X, V, seed=0)
    assert 2 <= g.n_components <= 12
    labels = g.posterior(X).argmax(axis=1)
    assert not set(labels[:70]) & set(labels[90:])  # no component spans both strokes
    again = fit_pcgmm(X, V, seed=0)
    np.testing.assert_array_equal(g.means, again.means)
    np.testing.assert_array_equal(g.covs, again.covs)


def test_pcgmm_tiny_data_is_one_component() -> None:
    g = fit_pcgmm(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.1]]),
                  np.ones((3, 2)), seed=0)
    assert g.n_components == 1


def test_em_bic_picks_k_from_data() -> None:
    rng = np.random.default_rng(1)
    blobs = np.vstack([rng.normal(c, 0.3, size=(100, 2)) for c in ([0, 0], [6, 0], [0, 6])])
    assert fit_em_bic(blobs, seed=0).n_components == 3
    assert fit_em_bic(rng.normal(size=(200, 2)), seed=0).n_components == 1


def test_fitters_reject_bad_data() -> None:
    with pytest.raises(ModelError, match="NaN or Inf"):
        fit_em_bic(np.array([[0.0, np.nan], [1.0, 1.0]]), seed=0)
    with pytest.raises(ModelError, match="velocities must be finite"):
        fit_pcgmm(np.zeros((5, 2)), np.zeros((4, 2)), seed=0)
