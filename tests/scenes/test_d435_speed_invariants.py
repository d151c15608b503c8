"""What d435's faster capture keeps: the disparity search covers every surface of the scene,
the worker-thread path returns the same depth as the serial one, the texture test is the
exact window variance, and a depth-only render is the render's depth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beo_bench.scenes.camera import Intrinsics
from beo_bench.scenes.sensors import d435 as d435_mod
from beo_bench.scenes.sensors import make_sensor
from beo_bench.scenes.sensors.validation import Bench

VGA = Intrinsics(640, 480, 45.0)


@pytest.fixture(scope="module")
def bench():
    with Bench(make_sensor("d435", VGA)) as b:
        yield b


def test_search_spans_the_scenes_disparities(bench) -> None:
    s = bench.sensor
    fb = s.f * d435_mod.BASELINE
    for near, far in ((0.5, 0.5), (0.6, 1.0), (0.8, 2.6), (0.33, 3.0), (3.0, 3.0)):
        left = np.full(s.shape, far, np.float32)
        left[200:300, 300:400] = near
        right = np.zeros(s.shape, np.float32)
        found = s._window(left, right)
        assert found is not None
        _, (d0, nd) = found
        assert nd % 16 == 0 and d0 >= 0 and d0 + nd <= s.num_disparities
        assert d0 <= math.floor(fb / far) - 1 and d0 + nd >= math.ceil(fb / near) + 1


def test_nothing_seen_is_no_window(bench) -> None:
    z = np.zeros(bench.sensor.shape, np.float32)
    assert bench.sensor._window(z, z) is None


@pytest.mark.parametrize("angle", [0, 60])
def test_threaded_and_serial_captures_agree(bench, monkeypatch, angle) -> None:
    s = bench.sensor
    data = bench._plane()
    T = bench.camera(1.0, angle)
    threaded = s.capture(bench.renderer, data, T, np.random.default_rng(3)).depth
    monkeypatch.setattr(d435_mod, "PARALLEL_MIN_PIXELS", 10**9)
    serial = s.capture(bench.renderer, data, T, np.random.default_rng(3)).depth
    assert np.array_equal(threaded, serial)
    assert (threaded > 0).mean() > 0.5


def test_texture_test_is_the_exact_window_variance(bench) -> None:
    import cv2

    s = bench.sensor
    rng = np.random.default_rng(0)
    k = (s._block, s._block)
    for spread in (3.0, 6.0, 20.0):
        img = np.clip(rng.normal(60, spread, s.shape), 0, 255).astype(np.uint8)
        im = img.astype(np.float64)
        s1 = cv2.boxFilter(im, -1, k, normalize=False, borderType=cv2.BORDER_REPLICATE)
        s2 = cv2.boxFilter(im * im, -1, k, normalize=False, borderType=cv2.BORDER_REPLICATE)
        n = k[0] * k[1]
        # n^2 times the window's variance, exact in float64 (integers below 2^53)
        flat = n * s2 - s1 * s1 < d435_mod.TEXTURE_MIN_DN**2 * n * n
        assert 0 < flat.mean() < 1 or spread != 6.0
        assert np.array_equal(s.textureless(img), flat)


def test_depth_only_render_is_the_renders_depth(bench) -> None:
    data = bench._plane()
    T = bench.camera(1.0, 30)
    assert np.array_equal(
        bench.renderer.render_depth(data, T), bench.renderer.render(data, T).depth
    )


def test_left_image_made_over_its_own_box_is_the_same(monkeypatch) -> None:
    """An isolated object: the worker makes the left image over the object's bounding box
    only, which is smaller than the matched window."""
    from beo_bench.objects import ObjectSet
    from beo_bench.scenes.isolated import IsolatedRenderer

    iso = IsolatedRenderer(Intrinsics(128, 128, 45.0))
    try:
        inst = ObjectSet("test").get("chair", 0)
        depths = []
        for threshold in (1, 10**9):
            monkeypatch.setattr(d435_mod, "PARALLEL_MIN_PIXELS", threshold)
            sensor = make_sensor("d435", iso.intrinsics)
            for v in range(3):
                view = iso.rig.sample(np.random.default_rng(v), np.zeros(3))
                iso.render(inst, view)
                renderer, data = iso._renderer, iso._models[inst.key][1]
                depths.append(sensor.capture(renderer, data, view, np.random.default_rng(v)).depth)
    finally:
        iso.close()
    for a, b in zip(depths[:3], depths[3:], strict=True):
        assert np.array_equal(a, b)
        assert (a > 0).sum() > 100
