"""The item kinds capture through the suite's sensor: an isolated item is the same instance,
camera and world frame under every sensor, only its depth is the sensor's; the scene kinds'
env is made with the suite's sensor. ``IsolatedRenderer`` keeps HBEO's ``DepthNoise`` path."""

from __future__ import annotations

import numpy as np
import pytest

from beo_bench.bench.kinds.isolated import IsolatedItems
from beo_bench.bench.kinds.tabletop import SceneItems
from beo_bench.bench.suites import get_suite
from beo_bench.scenes.camera import OBJECT_RIG
from beo_bench.scenes.isolated import IsolatedRenderer
from beo_bench.scenes.noise import DepthNoise


def _view(suite, index: int):
    items = IsolatedItems(suite)
    try:
        return items.isolated_view_only(index)
    finally:
        items.close()


@pytest.mark.parametrize("suite", ["pose-1dof", "known-pose"])
def test_an_isolated_item_is_the_same_under_every_sensor_but_its_depth(suite) -> None:
    s = get_suite(suite)
    ideal, kinect, again = (
        _view(s, 4),
        _view(s.with_sensor("kinect-v1"), 4),
        _view(s.with_sensor("kinect-v1"), 4),
    )
    np.testing.assert_array_equal(ideal.cam_to_world, kinect.cam_to_world)
    for hint in ("up_hint", "pose_hint"):  # what the protocol tells: the same
        a, b = getattr(ideal, hint), getattr(kinect, hint)
        assert (a is None) == (b is None)
        pairs = zip(a, b, strict=True) if isinstance(a, tuple) else [(a, b)]
        for x, y in pairs:
            np.testing.assert_array_equal(x, y)
    both = ideal.mask & kinect.mask
    assert both.sum() > 50 and not np.array_equal(ideal.depth, kinect.depth)
    assert np.abs(ideal.depth[both] - kinect.depth[both]).max() < 0.1
    assert not (kinect.mask & (kinect.depth == 0)).any()  # the mask: pixels with depth
    np.testing.assert_array_equal(kinect.depth, again.depth)  # item i's noise: (seed, i)


def test_the_scene_kinds_env_captures_with_the_suite_sensor() -> None:
    for sensor, want in ((None, "kinect-v1"), ("ideal", "ideal")):
        items = SceneItems(get_suite("tabletop").with_sensor(sensor))
        try:
            assert items.env.sensor.name == want
        finally:
            items.close()


def test_the_isolated_renderer_keeps_hbeo_noise_and_takes_a_sensor() -> None:
    from beo_bench.objects import ObjectSet

    mug = ObjectSet("test", ["mug"]).get("mug", 0)
    T = OBJECT_RIG.sample(np.random.default_rng(0), np.zeros(3))
    with IsolatedRenderer() as r:
        ideal = r.render(mug, T)
        noisy = r.render(mug, T, DepthNoise(), np.random.default_rng(1))
        noisy2 = r.render(mug, T, DepthNoise(), np.random.default_rng(1))
        kinect = r.render(mug, T, rng=np.random.default_rng(1), sensor="kinect-v1")
        with pytest.raises(ValueError, match="ideal render"):
            r.render(mug, T, DepthNoise(), np.random.default_rng(1), sensor="kinect-v1")
        with pytest.raises(ValueError, match="pass a generator"):
            r.render(mug, T, sensor="kinect-v1")
    np.testing.assert_array_equal(noisy.depth, noisy2.depth)
    assert not np.array_equal(noisy.depth, ideal.depth)
    assert not np.array_equal(kinect.depth, ideal.depth)
    assert not np.array_equal(kinect.depth, noisy.depth)
    with IsolatedRenderer(sensor="kinect-v1") as r:  # the renderer's own sensor
        own = r.render(mug, T, rng=np.random.default_rng(1))
    np.testing.assert_array_equal(own.depth, kinect.depth)
