"""VBPCA (Bishop 1999b) and the shrinkage covariance of eq. 3.9, on synthetic data where
the right answer is known."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import subspace_angles
from scipy.stats import multivariate_normal

from beo_bench.perception.beo.shrinkage import shrinkage_covariance
from beo_bench.perception.beo.vbpca import VBPCAConfig, fit_vbpca, ppca_log_likelihood


def low_rank(n: int, d: int = 300, q: int = 4, noise: float = 0.5, seed: int = 0):
    rng = np.random.default_rng(seed)
    W = rng.normal(size=(d, q)) * np.array([5.0, 4.0, 3.0, 2.0])[:q]
    mu = rng.normal(size=d)

    def draw(m: int) -> np.ndarray:
        return rng.normal(size=(m, q)) @ W.T + mu + noise * rng.normal(size=(m, d))

    return W, mu, draw


def test_recovers_a_known_low_rank_subspace_with_a_monotone_bound() -> None:
    W, _, draw = low_rank(60)
    fit = fit_vbpca(draw(60), VBPCAConfig(variance_fraction=0.999))
    # ARD switches off the surplus columns: four directions carry all the variance
    assert np.sum(fit.variances > 1e-3 * fit.variances[0]) == 4
    angles = np.degrees(subspace_angles(fit.W[:, :4], W))
    assert angles.max() < 5.0
    assert fit.noise_var == pytest.approx(0.25, rel=0.1)
    b = np.asarray(fit.bound)
    assert len(b) > 5
    assert np.all(np.diff(b) >= -1e-9 * np.abs(b[1:]))


def test_few_samples_overfit_less_than_plain_pca_on_held_out_likelihood() -> None:
    _, _, draw = low_rank(12, seed=1)
    train, held = draw(12), draw(200)
    fit = fit_vbpca(train, VBPCAConfig(variance_fraction=0.999))
    vb = fit.log_likelihood(held).mean()
    # plain PCA as maximum-likelihood probabilistic PCA (Tipping & Bishop 1999) with as many
    # components as the data allow: the noise is the mean of the discarded eigenvalues
    n, d = train.shape
    q = n - 2
    mu = train.mean(axis=0)
    _, s, Vt = np.linalg.svd(train - mu, full_matrices=False)
    ev = np.concatenate([s**2 / n, np.zeros(d - len(s))])
    var = ev[q:].mean()
    W = Vt[:q].T * np.sqrt(ev[:q] - var)
    pca = ppca_log_likelihood(held, W, mu, var).mean()
    assert vb > pca + 100  # nats per held-out vector


def test_ppca_log_likelihood_matches_the_dense_gaussian() -> None:
    rng = np.random.default_rng(2)
    W, mu = rng.normal(size=(20, 3)), rng.normal(size=20)
    X = rng.normal(size=(5, 20))
    dense = multivariate_normal(mu, W @ W.T + 0.3 * np.eye(20)).logpdf(X)
    np.testing.assert_allclose(ppca_log_likelihood(X, W, mu, 0.3), dense, rtol=1e-9)


def test_shrinkage_is_positive_definite_and_beats_the_sample_covariance_when_n_is_small() -> None:
    rng = np.random.default_rng(3)
    p = 30
    A = rng.normal(size=(p, p))
    true = A @ A.T / p + np.eye(p)
    errs_sample, errs_shrunk = [], []
    for seed in range(10):
        X = np.random.default_rng(seed).multivariate_normal(np.zeros(p), true, size=20)
        s = shrinkage_covariance(X)
        assert 0 <= s.delta <= 1 and 0 <= s.lam <= 1
        assert np.linalg.eigvalsh(s.covariance)[0] > 0  # the sample covariance is singular
        errs_sample.append(np.linalg.norm(np.cov(X.T) - true))
        errs_shrunk.append(np.linalg.norm(s.covariance - true))
    assert np.mean(errs_shrunk) < 0.8 * np.mean(errs_sample)


def test_shrinkage_vanishes_with_plenty_of_data() -> None:
    X = np.random.default_rng(4).normal(size=(20000, 5)) * np.arange(1, 6)
    s = shrinkage_covariance(X)
    assert s.delta < 0.01 and s.lam < 0.01


def test_bad_input_is_refused() -> None:
    with pytest.raises(ValueError, match="NaN"):
        fit_vbpca(np.full((4, 10), np.nan))
    with pytest.raises(ValueError, match="n >= 2"):
        fit_vbpca(np.ones((1, 10)))
