"""HBEO-MDN's posterior is pinned (issue 26, point 5): its sample weights are the mixture
density (eq. 5.7) times the silhouette prior 1 / (e^4 + eps) (eq. 5.8, e the SDF error of
eq. 5.6), and the prior decides where the likelihood alone would choose wrong.

``perception/hbeo/backend.py`` ``predict``: ``rotation_samples(..., prior=mode == "posterior")``
gives each of the N samples its log density and (posterior) its error e; the estimate's
``pose_weights`` are the normalised scores, ``rotation`` the highest-scoring sample. With
``prior=False`` there, the posterior is the likelihood and both tests below fail; so they
do with the prior 1 / (e^2 + eps), or with its inverse (e^4 + eps) (each mutation made
and reverted)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from beo_bench.backend import sample_views
from beo_bench.metrics import rotation_error
from beo_bench.objects import ObjectSet
from beo_bench.perception.hbeo import backend as hbeo
from beo_bench.perception.hbeo.backend import (
    BY_MODE,
    Forward,
    MDNLikelihoodBackend,
    MDNPosteriorBackend,
)
from beo_bench.perception.hbeo.crop import make_crop
from beo_bench.perception.hbeo.net import Mixture
from beo_bench.perception.hbeo.silhouette import sdf_errors, silhouettes

EPS = 1e-6
"""eps of eq. 5.8's prior 1 / (e^4 + eps): a guard against e = 0 (e is in pixels, e^4 is
10^4 or more for any mask that is not the observed one)."""


def expected_weights(log_likelihood: np.ndarray, e: np.ndarray | None) -> np.ndarray:
    """Normalised posterior weights, computed here apart from the backend: the density
    (eq. 5.7) times the prior 1 / (e^4 + eps) (eq. 5.8), or the density alone (e None)."""
    w = np.exp(log_likelihood - log_likelihood.max())
    if e is not None:
        w = w / (e**4 + EPS)
    return w / w.sum()


def test_eps_is_eq_5_8s() -> None:
    assert hbeo.PRIOR_EPS == EPS


# -- the published network on real views ---------------------------------------------------
@pytest.fixture(scope="module")
def views():
    return sample_views(picks=[("car", 1), ("chair", 2), ("mug", 3), ("sofa", 4)], seed=5)


def test_posterior_weights_are_the_likelihood_times_the_silhouette_prior(views) -> None:
    """On the published ``hbeo-mdn`` model: the posterior's ``pose_weights`` are its
    samples' densities times 1 / (e^4 + eps), normalised, and its rotation is their mode;
    the likelihood's are the densities alone, over the same samples. The prior moves the
    weights on every view, so a posterior without it is told apart."""
    post = MDNPosteriorBackend()
    lik = MDNLikelihoodBackend()
    for view in views:
        s = post.rotation_samples(view, prior=True)
        assert s.silhouette_error is not None and len(s.R) == post.options.samples
        want = expected_weights(s.log_likelihood, s.silhouette_error)
        density = expected_weights(s.log_likelihood, None)
        # the prior moves some weight by more than 5% of it (by 10-50% on these views)
        assert np.abs(want / density - 1).max() > 0.05, "the prior should move the weights"
        est = post.predict(view)
        assert np.array_equal(est.pose_samples, s.R)  # the same N samples
        np.testing.assert_allclose(est.pose_weights, want, rtol=1e-9, atol=1e-12)
        assert rotation_error(est.rotation, s.R[int(np.argmax(want))]) < 1e-6
        assert est.info["silhouette_error"] == pytest.approx(
            s.silhouette_error[int(np.argmax(want))], rel=1e-12
        )
        # the likelihood mode: same samples (same crop, same seed), weights = densities
        est_l = lik.predict(view)
        assert np.array_equal(est_l.pose_samples, s.R)
        np.testing.assert_allclose(est_l.pose_weights, density, rtol=1e-9, atol=1e-12)


# -- a constructed case: the true shape, two samples ---------------------------------------
class AtTheMeans(Mixture):
    """A mixture whose N = M draws are its components' means, one each: the samples are
    fixed, and each sample's density is its component's weight times the peak density."""

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        assert n == self.means.shape[1]
        return self.means.double().numpy()


def test_the_prior_of_the_true_shape_overturns_the_likelihoods_choice() -> None:
    """Given the true shape, size and translation of a car, and an MDN that puts weight 0.7
    on a wrong rotation (turned 90 degrees about the car's own up) and 0.3 on the true one:
    the likelihood (eq. 5.7) picks the wrong sample, the silhouette prior of the true shape
    re-projected at each sample (eq. 5.6, 5.8) prefers the true one by far more than
    0.7 / 0.3, and the posterior picks the true one."""
    (view,) = sample_views(picks=[("car", 1)], seed=5)
    gt = view.ground_truth
    truth = ObjectSet("test").get("car", 1).voxels(32).astype(np.float32)
    crop = make_crop(view.depth, view.mask, view.K)
    R_true = np.asarray(gt.R_cam, dtype=np.float64)
    R_wrong = R_true @ Rotation.from_euler("z", 90, degrees=True).as_matrix()
    # the network's rotations are relative to the crop's ray (R_cam = R_ray R_rel)
    w = [Rotation.from_matrix(crop.R_ray.T @ R).as_rotvec() for R in (R_wrong, R_true)]
    mix = AtTheMeans(
        log_weights=torch.log(torch.tensor([[0.7, 0.3]], dtype=torch.float64)),
        means=torch.tensor(np.stack(w)[None]),
        variances=torch.full((1, 2, 3), 0.01, dtype=torch.float64),
    )
    f = Forward(
        crop=crop,
        class_probs=np.eye(len(view.categories))[gt.class_index],
        rotation=R_wrong,
        translation=np.asarray(gt.t_cam, dtype=np.float64),
        size=np.asarray(gt.size, dtype=np.float64),
        shape=truth,
        mixture=mix,
    )
    # the prior on its own, from the pieces the posterior uses: the true sample's
    # re-projection matches the observed mask far better
    masks = silhouettes(
        torch.from_numpy(truth), f.size, np.stack([R_wrong, R_true]), f.translation, view.K, crop
    )
    e = sdf_errors(crop.mask, masks)
    assert (e[0] / e[1]) ** 4 > 10 * (0.7 / 0.3)

    chosen = {}
    for mode in ("likelihood", "posterior"):
        b = BY_MODE[mode](samples=2)
        b.forward = lambda _view, f=f: f  # type: ignore[method-assign]
        est = b.predict(view)
        np.testing.assert_allclose(est.pose_samples, [R_wrong, R_true], atol=1e-12)
        chosen[mode] = est
    lik, post = chosen["likelihood"], chosen["posterior"]
    assert rotation_error(lik.rotation, R_wrong) < 1e-6  # the likelihood chooses wrong
    assert post.pose_weights[1] > post.pose_weights[0]
    assert rotation_error(post.rotation, R_true) < 1e-6  # the prior overturns it
    ll = np.log([0.7, 0.3])
    np.testing.assert_allclose(lik.pose_weights, expected_weights(ll, None), rtol=1e-6)
    np.testing.assert_allclose(post.pose_weights, expected_weights(ll, e), rtol=1e-6)
