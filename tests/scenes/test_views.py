"""Backend-ready views: ``IsolatedView.to_view`` and ``View.from_observation`` give a
perception backend what the isolated and tabletop suites give it, a published backend
predicts on both, and unusable input is refused with a message that says why."""

from __future__ import annotations

import numpy as np
import pytest

from beo_bench.backend import get_backend, validate_estimate
from beo_bench.errors import ViewError
from beo_bench.objects import ObjectSet, categories
from beo_bench.scenes import OBJECT_RIG, IsolatedRenderer, look_at
from beo_bench.types import View, ViewpointPrior


@pytest.fixture(scope="module")
def hbeo():
    return get_backend("hbeo")  # the published network: no training, no ground truth


@pytest.fixture(scope="module")
def isolated():
    inst = ObjectSet("test").get("mug", 1)
    with IsolatedRenderer() as r:
        drawn = r.sample_views(inst, np.random.default_rng(4), 1)[0]
        chosen = r.render(inst, look_at(np.array([0.3, -0.25, 0.2]), np.zeros(3)))
    return drawn, chosen


@pytest.fixture(scope="module")
def scene():
    import gymnasium as gym

    import beo_bench  # noqa: F401  (registers the ids)

    env = gym.make("BEOPick-v0", image_size=(160, 120), num_objects=3)
    obs, _ = env.reset(seed=2)
    u = env.unwrapped
    yield obs, u.target_label, u.categories, u.ground_truth()
    env.close()


def test_isolated_view_gives_the_pixels_an_isolated_suite_gives(isolated, hbeo) -> None:
    iv, _ = isolated
    view = iv.to_view()
    assert view.categories == categories()  # the built-in library's classes
    np.testing.assert_array_equal(view.depth, iv.depth)
    np.testing.assert_array_equal(view.mask, iv.mask)
    np.testing.assert_array_equal(view.K, iv.K)
    # the render's own frame, with the object at the origin: it gives the pose away, which
    # is why the suites replace it by a random rigid frame (tests/bench/test_protocol_probe.py)
    np.testing.assert_array_equal(view.cam_to_world, iv.cam_to_world)
    # drawn from the object rig: the suites publish that rig's distribution with the view
    assert view.viewpoint_prior == ViewpointPrior.of_rig(OBJECT_RIG)
    # no truth field and none of a protocol's hints
    assert view.ground_truth is None and view.class_hint is None
    assert view.up_hint is None and view.pose_hint is None
    est = validate_estimate(hbeo.predict(view), view)
    assert est.class_probs.shape == (len(categories()),)
    assert view.categories[est.class_index] == "mug"


def test_isolated_view_of_a_chosen_pose_has_no_prior(isolated, hbeo) -> None:
    _, iv = isolated
    assert iv.viewpoint_prior is None
    view = iv.to_view(["bowl", "can", "mug"])
    assert view.categories == ("bowl", "can", "mug") and view.viewpoint_prior is None
    est = validate_estimate(hbeo.predict(view), view)
    assert est.class_probs.shape == (3,)


def test_isolated_view_refuses_classes_without_its_own(isolated) -> None:
    iv, _ = isolated
    with pytest.raises(ViewError, match="'mug', which is not among categories"):
        iv.to_view(("bowl", "can"))
    with pytest.raises(ViewError, match="one string"):
        iv.to_view("mug")


def test_observation_view_is_the_tabletop_suites_view(scene, hbeo) -> None:
    obs, target, cats, gts = scene
    view = View.from_observation(obs, target, cats)
    np.testing.assert_array_equal(view.mask, obs["segmentation"] == target)
    assert view.mask.sum() == next(g.pixels for g in gts if g.label == target)
    np.testing.assert_array_equal(view.depth, obs["depth"])
    np.testing.assert_array_equal(view.K, obs["intrinsics"])
    np.testing.assert_array_equal(view.cam_to_world, obs["cam_to_world"])
    np.testing.assert_array_equal(view.segmentation, obs["segmentation"])
    assert view.categories == tuple(cats) and view.ground_truth is None
    est = validate_estimate(hbeo.predict(view), view)
    assert est.class_probs.shape == (len(cats),)
    # every visible object makes a view, as the tabletop suite scores them
    for g in gts:
        if g.pixels:
            assert View.from_observation(obs, g.label, cats).mask.sum() == g.pixels


@pytest.mark.parametrize(
    ("label", "match"),
    [
        (0, "0 is the background and table"),
        (9, "label 9 shows no pixel"),
        (300, "label 300 shows no pixel"),
        (1.0, "must be an integer"),
        (True, "must be an integer"),
    ],
)
def test_observation_view_refuses_labels_that_are_not_visible_objects(scene, label, match) -> None:
    obs, _, cats, gts = scene
    present = sorted(g.label for g in gts if g.pixels)
    with pytest.raises(ViewError, match=match) as err:
        View.from_observation(obs, label, cats)
    if "pixel" in match:
        assert str(present) in str(err.value)  # it names the labels that are in view


def test_observation_view_refuses_other_dicts(scene) -> None:
    obs, target, cats, _ = scene
    partial = {k: v for k, v in obs.items() if k != "intrinsics"}
    with pytest.raises(ViewError, match=r"no 'intrinsics'.*reset\(\) or step\(\)"):
        View.from_observation(partial, target, cats)
    with pytest.raises(ViewError, match="one string"):
        View.from_observation(obs, target, "mug")
