"""The benchmark's headline orderings, pinned on small models trained here, on
rendered test-split views drawn by the isolated suites' rig (slow-marked; each test takes
seconds once its models are trained, well under a minute on 2 cores in all):

- at a known pose, BEO completes the object better than the class-mean shape (the
  ``icp`` baseline there; the dissertation's Table 3.1);
- given the class, BEO's pose beats the dissertation's plain ICP (``icp-plain``) in the
  1-DOF and the 3-DOF protocol (Figures 3.6 and 4.3; 3-DOF with the rig's pose prior);
- HBEO-MDN's posterior (with the silhouette prior) errs less than HBEO in 3-DOF (chapter 5):
  the MDN's median is lower while its mean is not (a few of its samples land on the wrong
  mode), so the median is what is pinned; the published default models order both.

The numbers seen are in each test's comments; every assertion held for every seed tried."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from beo_bench.backend import get_backend, sample_views
from beo_bench.metrics import rotation_error, voxel_iou
from beo_bench.objects import instance_from_key
from beo_bench.perception.beo.backend import BEOBackend
from beo_bench.perception.beo.model import BEOConfig, train_beo
from beo_bench.perception.beo.model import model_path as beo_model_path
from beo_bench.perception.hbeo.backend import BY_MODE
from beo_bench.perception.hbeo.data import DatasetConfig
from beo_bench.perception.hbeo.model import HBEOConfig, model_path
from beo_bench.perception.hbeo.train import train_hbeo
from beo_bench.perception.means import class_means
from beo_bench.scenes.camera import OBJECT_RIG
from beo_bench.types import View, ViewpointPrior

pytestmark = pytest.mark.slow

BEO_CATS = ("car", "chair", "mug", "sofa")  # asymmetric: the pose is not free
BEO_INSTANCES = 100
HBEO_CATS = ("mug", "car")


@pytest.fixture(scope="module")
def beo_model() -> str:
    """A BEO model on 100 training instances per class (the class means use the same)."""
    model = train_beo(BEOConfig(categories=BEO_CATS, per_category=BEO_INSTANCES))
    model.save(beo_model_path("test-headline-beo"))
    return "test-headline-beo"


@pytest.fixture(scope="module")
def views() -> list[View]:
    """Three test-split instances per class, class given, from the object rig."""
    picks = [(c, i) for i in range(3) for c in BEO_CATS]
    return sample_views(categories=BEO_CATS, split="test", seed=5, picks=picks)


@pytest.fixture(scope="module")
def completion_views() -> list[View]:
    """Eight test-split instances per class: completion varies more from object to object
    than pose does (a misread class completes as the wrong class), so its mean needs more
    views than three per class to stand out from the class mean's."""
    picks = [(c, i) for i in range(8) for c in BEO_CATS]
    return sample_views(categories=BEO_CATS, split="test", seed=5, picks=picks)


def _rot_err(est_R: np.ndarray, view: View) -> float:
    gt = view.ground_truth
    assert gt is not None
    return rotation_error(est_R, gt.R_cam, gt.symmetry)


def test_beo_completes_better_than_the_class_mean_at_a_known_pose(
    beo_model, completion_views
) -> None:
    beo = BEOBackend(model=beo_model)
    mean_shape = get_backend("icp", mean_instances=BEO_INSTANCES)  # the nearest class mean
    means = class_means(BEO_CATS, 32, BEO_INSTANCES)
    ious: dict[str, list[float]] = {"beo": [], "class mean": [], "true class mean": []}
    for v in completion_views:
        gt = v.ground_truth
        assert gt is not None
        known = replace(v, class_hint=None, pose_hint=(gt.R_cam, gt.t_cam, gt.size))
        truth = instance_from_key(gt.key).voxels(32)
        ious["beo"].append(voxel_iou(beo.predict(known).shape > 0.5, truth))
        ious["class mean"].append(voxel_iou(mean_shape.predict(known).shape > 0.5, truth))
        ious["true class mean"].append(voxel_iou(means.shape[gt.class_index] > 0.5, truth))
    m = {k: float(np.mean(x)) for k, x in ious.items()}
    # seen: 0.473 against 0.387 (and 0.389 for the true class's mean) over the 32 views;
    # the first 12 alone give 0.444 against 0.402
    assert m["beo"] > m["class mean"] + 0.05, m
    assert m["beo"] > m["true class mean"] + 0.05, m


def test_beo_given_the_class_beats_plain_icp_in_1dof(beo_model, views) -> None:
    beo = BEOBackend(model=beo_model)
    plain = get_backend("icp-plain", mean_instances=BEO_INSTANCES)
    errs: dict[str, list[float]] = {"beo": [], "icp-plain": []}
    for v in views:
        gt = v.ground_truth
        assert gt is not None
        one_dof = replace(v, up_hint=gt.R_cam[:, 2].copy())  # class given: v has the hint
        errs["beo"].append(_rot_err(beo.predict(one_dof).rotation, v))
        errs["icp-plain"].append(_rot_err(plain.predict(one_dof).rotation, v))
    m = {k: float(np.mean(x)) for k, x in errs.items()}
    # seen: 13.5 against 55.5 degrees mean (plain ICP flips 4 of 12 views by 150+)
    assert m["beo"] < m["icp-plain"] - 20, errs


def test_beo_given_the_class_beats_plain_icp_in_3dof(beo_model, views) -> None:
    beo = BEOBackend(model=beo_model)
    plain = get_backend("icp-plain", mean_instances=BEO_INSTANCES)
    prior = ViewpointPrior.of_rig(OBJECT_RIG)
    errs: dict[str, list[float]] = {"beo": [], "icp-plain": []}
    for v in views:
        three_dof = replace(v, viewpoint_prior=prior)  # as pose-3dof gives its views
        errs["beo"].append(_rot_err(beo.predict(three_dof).rotation, v))
        errs["icp-plain"].append(_rot_err(plain.predict(three_dof).rotation, v))
    m = {k: float(np.mean(x)) for k, x in errs.items()}
    # seen: 36.5 against 91.1 degrees mean (plain ICP's one upright start is 90+ off on 7
    # of 12 views; BEO's prior keeps its search among the poses the rig draws)
    assert m["beo"] < m["icp-plain"] - 20, errs


@pytest.fixture(scope="module")
def hbeo_models() -> dict[str, str]:
    """HBEO and HBEO-MDN on 900 crops of two classes, 10 epochs (seconds on 2 cores). At 6
    epochs the MDN's median was a coin toss over data seeds (18.9 to 55.4 degrees for seeds
    7-9, and a 1-ulp change of the rendered depth moved seed 7 from 18.9 to 48.9); at 10 it
    settles (seeds 7-10 below)."""
    subspace = train_beo(BEOConfig(categories=HBEO_CATS, per_category=10))
    subspace.save(beo_model_path("test-headline-subspace"))
    data = DatasetConfig(
        categories=HBEO_CATS,
        images=900,
        val_images=225,
        shard_size=150,
        per_category=10,
        tabletop_share=0.0,
        seed=7,
    )
    names = {}
    for kind in ("hbeo", "hbeo-mdn"):
        cfg = HBEOConfig(
            kind=kind,  # type: ignore[arg-type]
            dataset=data,
            epochs=10,
            batch_size=32,
            beo_model="test-headline-subspace",
        )
        names[kind] = f"test-headline-{kind}"
        train_hbeo(cfg, model_path(names[kind]), progress=False, workers=1)
    return names


def test_hbeo_mdn_errs_less_than_hbeo_in_3dof(hbeo_models) -> None:
    picks = [(c, i) for i in range(24) for c in HBEO_CATS]
    views = [
        replace(v, class_hint=None)
        for v in sample_views(categories=HBEO_CATS, split="test", seed=3, picks=picks)
    ]
    median = {}
    for mode, kind in (("hbeo", "hbeo"), ("likelihood", "hbeo-mdn"), ("posterior", "hbeo-mdn")):
        b = BY_MODE[mode](model=hbeo_models[kind])  # type: ignore[arg-type]
        median[mode] = float(np.median([_rot_err(b.predict(v).rotation, v) for v in views]))
    # seen, medians over these 48 views for data seeds 7 / 8 / 9 / 10: hbeo 27.3 / 18.9 /
    # 22.3 / 21.5, likelihood 19.9 / 19.1 / 19.3 / 19.2, posterior (with the silhouette
    # prior) 17.0 / 16.7 / 18.7 / 14.3. The posterior beats hbeo for every seed (by 2.2 to
    # 10.3 degrees); the likelihood alone does not at this size, so it is not pinned.
    assert median["posterior"] < median["hbeo"], median
