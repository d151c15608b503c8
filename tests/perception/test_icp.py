"""The ``icp`` backend: conformance, exact recovery of a synthetic pose, better than chance on
rendered views in the 1-DOF protocol, and clear errors on unusable views."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from beo_bench.backend import check_backend, get_backend, sample_views
from beo_bench.errors import ViewError
from beo_bench.geometry import axis_angle, symmetry_transformations
from beo_bench.objects import ObjectSet
from beo_bench.perception.icp.backend import ICPBackend, mean_surface
from beo_bench.perception.means import class_means
from beo_bench.scenes.camera import OBJECT_RIG, Intrinsics, look_at
from beo_bench.types import View

FAST = {"mean_instances": 4}  # small class means: the test session's cache starts cold
ASYMMETRIC = ("mug", "car", "sofa", "chair")


@pytest.fixture(scope="module")
def views() -> list[View]:
    return sample_views(3)


@pytest.fixture(scope="module")
def icp() -> ICPBackend:
    return get_backend("icp", **FAST)


def _angle_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return float(
        np.degrees((Rotation.from_matrix(R_a).inv() * Rotation.from_matrix(R_b)).magnitude())
    )


def test_icp_is_registered_and_conforms(icp, views) -> None:
    check_backend(icp, views)  # 3-DOF (no up hint), class given
    e = icp.predict(views[0])
    assert e.class_index == views[0].class_hint
    assert e.shape.dtype == np.float32 and e.shape.shape == (32, 32, 32)
    assert e.info["starts"] == 24 and e.info["residual_mm"] >= 0


def test_class_by_best_fit_gives_a_distribution(views) -> None:
    # without a class hint (the class-free track) every class is fitted
    view = replace(views[0], class_hint=None)
    b = get_backend("icp", starts=8, iterations=10, **FAST)
    check_backend(b, [view])
    e = b.predict(view)
    assert np.all(e.class_probs > 0) and abs(e.class_probs.sum() - 1) < 1e-9
    assert len(e.info["class_scores_mm"]) == len(views[0].categories)


def _synthetic_view(
    category: str, yaw_deg: float, offset: np.ndarray
) -> tuple[View, np.ndarray, np.ndarray]:
    """A depth image of the class-mean surface itself (dense marching-cubes vertices,
    z-buffered) at a known pose: yawed by ``yaw_deg`` about its up, moved by ``offset``,
    seen from 30 degrees elevation at 0.6 m."""
    cats = ObjectSet("test", ASYMMETRIC).categories
    means = class_means(cats, 32, FAST["mean_instances"])
    c = cats.index(category)
    dense = mean_surface(means.shape[c], means.size[c], n_points=100_000)
    el = np.radians(30.0)
    cam_to_world = look_at(0.6 * np.array([np.cos(el), 0.3, np.sin(el)]), np.zeros(3))
    world_to_cam = np.linalg.inv(cam_to_world)
    R = world_to_cam[:3, :3] @ axis_angle([0, 0, 1], np.radians(yaw_deg))
    t = world_to_cam[:3, :3] @ offset + world_to_cam[:3, 3]
    X = dense.points @ R.T + t
    front = np.sum((dense.normals @ R.T) * X, axis=1) < 0  # faces the camera
    X = X[front]
    intr = Intrinsics(128, 128, 45.0)
    K = intr.K
    u = np.rint(K[0, 0] * X[:, 0] / X[:, 2] + K[0, 2]).astype(int)
    v = np.rint(K[1, 1] * X[:, 1] / X[:, 2] + K[1, 2]).astype(int)
    depth = np.full((intr.height, intr.width), np.inf)
    np.minimum.at(depth, (v, u), X[:, 2])  # z-buffer: the nearest point per pixel
    depth[~np.isfinite(depth)] = 0.0
    view = View(depth.astype(np.float32), depth > 0, K, cam_to_world, cats, class_hint=c)
    return view, R, t


@pytest.mark.parametrize("point_to_plane", [True, False])
def test_recovers_a_synthetic_pose_in_the_1dof_protocol(point_to_plane) -> None:
    view, R, t = _synthetic_view("sofa", 70.0, np.array([0.02, -0.01, 0.0]))
    b = get_backend("icp", point_to_plane=point_to_plane, **FAST)
    e = b.predict(replace(view, up_hint=R[:, 2]))
    assert _angle_deg(e.rotation, R) < 5.0
    assert np.linalg.norm(e.translation - t) < 0.01
    # the up axis is kept exactly: only the yaw was estimated
    np.testing.assert_allclose(e.rotation[:, 2], R[:, 2], atol=1e-6)


def test_beats_chance_on_rendered_views_in_the_1dof_protocol() -> None:
    """Yaw error (minimised over each instance's symmetries) on rendered test-split views of
    mostly asymmetric categories: a random yaw averages 90 degrees and lands within 15
    degrees 1 time in 12. (Seen: mean 29, median 2 degrees, 15 of 20 within 15; the misses
    are mugs, whose mean shape barely shows a handle, and front/back flips.)"""
    from beo_bench.scenes.isolated import IsolatedRenderer

    objects = ObjectSet("test", ASYMMETRIC)
    cats = objects.categories
    b = get_backend("icp", **FAST)
    rng = np.random.default_rng(7)
    errors = []
    with IsolatedRenderer() as r:
        for c in cats:
            for i in range(5):
                inst = objects.get(c, i)
                v = r.render(inst, OBJECT_RIG.sample(rng, np.zeros(3)))
                view = View(
                    v.depth,
                    v.mask,
                    v.K,
                    v.cam_to_world,
                    cats,
                    class_hint=cats.index(c),
                    up_hint=v.R_cam[:, 2],
                )
                e = b.predict(view)
                syms = symmetry_transformations(inst.symmetry)
                errors.append(min(_angle_deg(e.rotation, v.R_cam @ T[:3, :3]) for T in syms))
    errors = np.array(errors)
    assert errors.mean() < 45.0, errors
    assert np.median(errors) < 15.0, errors
    assert np.mean(errors < 15.0) >= 0.6, errors


def test_empty_mask_or_no_depth_raises(icp, views) -> None:
    with pytest.raises(ViewError, match="no pixel with valid depth"):
        icp.predict(replace(views[0], mask=np.zeros_like(views[0].mask)))
    with pytest.raises(ViewError, match="no pixel with valid depth"):
        icp.predict(replace(views[0], depth=np.zeros_like(views[0].depth)))


def test_rejects_bad_options_and_hints(icp, views) -> None:
    with pytest.raises(ValueError, match="trim"):
        ICPBackend(trim=0.0)
    with pytest.raises(ViewError, match="up_hint"):
        icp.predict(replace(views[0], up_hint=np.zeros(3)))
