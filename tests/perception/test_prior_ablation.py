"""Chapter 5's ablation options of ``hbeo-mdn-posterior`` (issue 48): each one changes the
silhouette prior's input it names, and nothing else.

Mutations made and reverted: ignoring ``prior_shape=truth`` (the estimate's shape kept),
ignoring ``prior_translation=truth``, ``select=prior`` scoring density x prior,
``select=oracle`` picking the first sample, ``sdf_errors`` ignoring ``valid``, and
``prior_pixels=view`` comparing in the crop: each fails a test below."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from beo_bench.backend import get_spec, sample_views
from beo_bench.errors import UsageError, ViewError
from beo_bench.metrics import rotation_error
from beo_bench.objects import ObjectSet
from beo_bench.perception.hbeo.backend import (
    Forward,
    HBEOBackend,
    HBEOOptions,
    MDNLikelihoodBackend,
    MDNPosteriorBackend,
    companion_model,
)
from beo_bench.perception.hbeo.crop import make_crop
from beo_bench.perception.hbeo.silhouette import (
    align_centroids,
    project_masks,
    sdf_errors,
    silhouettes,
    view_window,
)


@pytest.fixture(scope="module")
def views():
    return sample_views(picks=[("car", 1), ("sofa", 4), ("mug", 3)], seed=5)


def test_the_ablation_options_are_the_posteriors_and_truth_makes_it_privileged() -> None:
    with pytest.raises(UsageError, match=r"does not use select \(an option of hbeo-mdn-post"):
        MDNLikelihoodBackend(select="prior")
    with pytest.raises(UsageError, match="prior_grid"):
        HBEOBackend(prior_grid=64)
    with pytest.raises(ValueError, match="prior_grid=48"):
        HBEOOptions(prior_grid=48)
    with pytest.raises(ValueError, match="select='best'"):
        HBEOOptions(select="best")  # type: ignore[arg-type]
    spec = get_spec("hbeo-mdn-posterior")
    for opts, privileged in (
        ({}, False),
        ({"select": "prior"}, False),
        ({"prior_grid": 64, "prior_pixels": "view", "prior_occlusion": True}, False),
        ({"select": "oracle"}, True),
        ({"prior_shape": "truth"}, True),
        ({"prior_translation": "truth"}, True),
    ):
        caps = spec.capabilities_of(spec.parse(opts))
        assert caps.privileged is privileged, opts


def test_select_oracle_and_prior_choose_the_dissertations_baselines(views) -> None:
    """Random Sample + Oracle picks the sample nearest the truth; Random Sample + SDF
    Error the sample of least silhouette error, whatever its density."""
    oracle = MDNPosteriorBackend(select="oracle")
    prior = MDNPosteriorBackend(select="prior")
    post = MDNPosteriorBackend()
    picked_other = 0
    for view in views:
        gt = view.ground_truth
        est = oracle.predict(view)
        errs = [rotation_error(R, gt.R_cam, gt.symmetry) for R in est.pose_samples]
        assert rotation_error(est.rotation, gt.R_cam, gt.symmetry) == pytest.approx(min(errs))
        s = post.rotation_samples(view)
        assert s.silhouette_error is not None
        est_p = prior.predict(view)
        assert est_p.info["silhouette_error"] == pytest.approx(s.silhouette_error.min())
        picked_other += int(np.argmin(s.silhouette_error)) != int(
            np.argmax(np.asarray(post.predict(view).pose_weights))
        )
    assert picked_other > 0  # the prior alone is not the posterior


def _car_forward(view, shape: np.ndarray, t: np.ndarray) -> Forward:
    gt = view.ground_truth
    crop = make_crop(view.depth, view.mask, view.K)
    return Forward(
        crop=crop,
        class_probs=np.eye(len(view.categories))[gt.class_index],
        rotation=np.asarray(gt.R_cam, dtype=np.float64),
        translation=t,
        size=np.asarray(gt.size, dtype=np.float64) * 0.7,
        shape=shape,
        mixture=None,
    )


def _rotations(gt) -> np.ndarray:
    R = np.asarray(gt.R_cam, dtype=np.float64)
    turns = Rotation.from_euler("z", [[0], [90], [180]], degrees=True).as_matrix()
    return np.stack([R @ T for T in turns])


def test_the_truth_options_hand_the_prior_the_true_shape_and_translation() -> None:
    """A wrong estimate (a mug's voxels, 70% of the size, 3 cm off): with the truth options
    the prior's errors are exactly those of the true shape at its size and translation."""
    (view,) = sample_views(picks=[("car", 1)], seed=5)
    gt = view.ground_truth
    truth = ObjectSet("test").get("car", 1).voxels(32).astype(np.float32)
    wrong = ObjectSet("test").get("mug", 1).voxels(32).astype(np.float32)
    t_true = np.asarray(gt.t_cam, dtype=np.float64)
    f = _car_forward(view, wrong, t_true + np.array([0.03, 0.0, 0.0]))
    R = _rotations(gt)

    def want(shape: np.ndarray, size: np.ndarray, t: np.ndarray) -> np.ndarray:
        masks = silhouettes(torch.from_numpy(shape), size, R, t, view.K, f.crop)
        return sdf_errors(f.crop.mask, masks)

    def got(**opts: object) -> np.ndarray:
        b = MDNPosteriorBackend(**opts)  # type: ignore[arg-type]
        return b.silhouette_errors(view, f, R)

    np.testing.assert_array_equal(got(), want(wrong, f.size, f.translation))
    np.testing.assert_array_equal(got(prior_shape="truth"), want(truth, gt.size, f.translation))
    np.testing.assert_array_equal(got(prior_translation="truth"), want(wrong, f.size, t_true))
    both = got(prior_shape="truth", prior_translation="truth")
    np.testing.assert_array_equal(both, want(truth, gt.size, t_true))
    assert both[0] < both[1]  # the true rotation fits best (a car's half-turn nearly fits)
    blind = MDNPosteriorBackend(prior_shape="truth")
    with pytest.raises(ViewError, match="ground_truth"):
        blind.silhouette_errors(replace(view, ground_truth=None), f, R)


def test_view_pixels_and_the_64_grid_compare_the_same_object(views) -> None:
    """``prior_pixels=view`` compares in the view's own pixels (the padded box of its mask),
    ``prior_grid=64`` the decode resampled: the true shape at the truth still fits its
    true rotation best, and each differs from the crop's 32^3 comparison."""
    (view,) = sample_views(picks=[("car", 1)], seed=5)
    gt = view.ground_truth
    truth = ObjectSet("test").get("car", 1).voxels(32).astype(np.float32)
    f = _car_forward(view, truth, np.asarray(gt.t_cam, dtype=np.float64))
    R = _rotations(gt)
    base = MDNPosteriorBackend(prior_translation="truth").silhouette_errors(view, f, R)
    on_view = MDNPosteriorBackend(prior_pixels="view", prior_translation="truth")
    e_view = on_view.silhouette_errors(view, f, R)
    affine, hw, (y0, x0) = view_window(view)
    masks = project_masks(torch.from_numpy(truth), f.size, R, gt.t_cam, view.K, affine, hw)
    observed = np.asarray(view.mask)[y0 : y0 + hw[0], x0 : x0 + hw[1]] & (
        np.asarray(view.depth)[y0 : y0 + hw[0], x0 : x0 + hw[1]] > 0
    )
    np.testing.assert_array_equal(e_view, sdf_errors(observed, masks))
    assert not np.allclose(e_view, base)
    e64 = MDNPosteriorBackend(prior_grid=64, prior_translation="truth").silhouette_errors(
        view, f, R
    )
    assert not np.allclose(e64, base)
    for e in (base, e_view, e64):
        assert int(np.argmin(e)) == 0


def test_only_pixels_no_other_object_covers_count() -> None:
    """``sdf_errors(valid=)``: a difference confined to invalid pixels costs nothing; and
    ``prior_occlusion`` takes the invalid pixels from the view's other labels."""
    obs = np.zeros((20, 20), dtype=bool)
    obs[5:15, 5:15] = True
    bigger = obs.copy()
    bigger[5:15, 15:18] = True  # what an occluder on the right would hide
    valid = np.ones_like(obs)
    valid[:, 15:] = False
    full = sdf_errors(obs, bigger[None])
    assert full[0] > 0
    # the SDF changes near the hidden part too, so only far less of the error remains
    assert sdf_errors(obs, bigger[None], valid)[0] < 0.5 * full[0]
    assert sdf_errors(obs, obs[None], valid)[0] == 0.0

    (view,) = sample_views(picks=[("car", 1)], seed=5)
    gt = view.ground_truth
    truth = ObjectSet("test").get("car", 1).voxels(32).astype(np.float32)
    f = _car_forward(view, truth, np.asarray(gt.t_cam, dtype=np.float64))
    R = _rotations(gt)
    seg = np.asarray(view.mask).astype(np.uint8)
    us = np.nonzero(view.mask)[1]
    seg[:, us.max() - 3 :] = np.where(seg[:, us.max() - 3 :] == 1, 1, 2)  # another object
    occluded = replace(view, segmentation=seg)
    b = MDNPosteriorBackend(prior_occlusion=True, prior_translation="truth")
    plain = MDNPosteriorBackend(prior_translation="truth")
    assert np.array_equal(b.silhouette_errors(view, f, R), plain.silhouette_errors(view, f, R))
    assert not np.array_equal(
        b.silhouette_errors(occluded, f, R), plain.silhouette_errors(occluded, f, R)
    )


def test_the_hbeo_options_take_the_hbeo_networks_shape_and_translation(views) -> None:
    """``prior_shape=hbeo`` re-projects the hbeo network's shape at its size, and
    ``prior_translation=hbeo`` places it at its translation; the replicate seed<k>-hbeo-mdn
    pairs with seed<k>-hbeo, and a model with no hbeo beside it is refused."""
    assert companion_model(None) is None
    assert companion_model("seed2-hbeo-mdn") == "seed2-hbeo"
    with pytest.raises(UsageError, match="no hbeo network"):
        MDNPosteriorBackend(prior_shape="hbeo", model="mine")
    hb = HBEOBackend()
    both = MDNPosteriorBackend(prior_shape="hbeo", prior_translation="hbeo")
    mdn = MDNPosteriorBackend()
    for view in views[:2]:
        f, g = mdn.forward(view), hb.forward(view)
        R = mdn.rotation_samples(view, f, prior=False).R
        masks = silhouettes(torch.from_numpy(g.shape), g.size, R, g.translation, view.K, f.crop)
        np.testing.assert_array_equal(
            both.silhouette_errors(view, f, R), sdf_errors(f.crop.mask, masks)
        )
        shape_only = MDNPosteriorBackend(prior_shape="hbeo").silhouette_errors(view, f, R)
        masks = silhouettes(torch.from_numpy(g.shape), g.size, R, f.translation, view.K, f.crop)
        np.testing.assert_array_equal(shape_only, sdf_errors(f.crop.mask, masks))


def test_aligned_translation_moves_each_silhouette_onto_the_observed_centroid() -> None:
    """``align_centroids`` shifts a mask by whole pixels onto the observed centroid, and
    ``prior_translation=aligned`` compares the shifted silhouettes: 3 cm of translation
    error then costs the true rotation its lead no more."""
    obs = np.zeros((30, 30), dtype=bool)
    obs[10:20, 8:14] = True
    moved = np.zeros_like(obs)
    moved[13:23, 5:11] = True
    empty = np.zeros_like(obs)
    out = align_centroids(np.stack([moved, empty]), obs)
    assert np.array_equal(out[0], obs) and not out[1].any()

    (view,) = sample_views(picks=[("car", 1)], seed=5)
    gt = view.ground_truth
    truth = ObjectSet("test").get("car", 1).voxels(32).astype(np.float32)
    off = np.asarray(gt.t_cam, dtype=np.float64) + np.array([0.03, -0.02, 0.0])
    f = replace(_car_forward(view, truth, off), size=np.asarray(gt.size, dtype=np.float64))
    R = _rotations(gt)
    masks = silhouettes(torch.from_numpy(truth), f.size, R, off, view.K, f.crop)
    want = sdf_errors(f.crop.mask, align_centroids(masks, f.crop.mask))
    aligned = MDNPosteriorBackend(prior_translation="aligned").silhouette_errors(view, f, R)
    np.testing.assert_array_equal(aligned, want)
    assert not np.array_equal(aligned, sdf_errors(f.crop.mask, masks))
    assert int(np.argmin(aligned)) == 0
