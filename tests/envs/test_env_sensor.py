"""BEOPick-v0's ``sensor=``: the observation's depth is the sensor's capture of the scene,
its noise drawn from the env's generator (the seed fixes it), the segmentation the ideal
one; a bad name or the removed ``noise=`` fail at ``gym.make`` with one line saying what to
pass."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import beo_bench  # noqa: F401  (registers BEOPick-v0)
from beo_bench.errors import EnvConfigError
from beo_bench.scenes.sensors import make_sensor

SIZE = (160, 120)


def _reset(seed: int, **kw) -> dict:
    env = gym.make("BEOPick-v0", image_size=SIZE, **kw)
    try:
        obs, _ = env.reset(seed=seed)
        return obs
    finally:
        env.close()


def test_kinect_depth_differs_from_ideal_and_the_seed_fixes_it() -> None:
    ideal = _reset(3)
    kinect = _reset(3, sensor="kinect-v1")
    again = _reset(3, sensor="kinect-v1")
    other = _reset(4, sensor="kinect-v1")
    assert kinect["depth"].dtype == np.float32 and kinect["depth"].shape == SIZE[::-1]
    # the same scene and camera, its depth the sensor's: noisy, with pixels left without
    np.testing.assert_array_equal(kinect["cam_to_world"], ideal["cam_to_world"])
    np.testing.assert_array_equal(kinect["segmentation"], ideal["segmentation"])
    seen = (kinect["depth"] > 0) & (ideal["depth"] > 0)
    assert np.mean(kinect["depth"][seen] != ideal["depth"][seen]) > 0.5
    assert np.abs(kinect["depth"][seen] - ideal["depth"][seen]).max() < 0.1  # millimetres
    assert np.count_nonzero(ideal["depth"] > 0) > np.count_nonzero(kinect["depth"] > 0)
    # the same seed gives the same noise, another seed another capture
    np.testing.assert_array_equal(kinect["depth"], again["depth"])
    assert not np.array_equal(kinect["depth"], other["depth"])
    # the ideal sensor is the render as it is (and the default)
    np.testing.assert_array_equal(_reset(3, sensor="ideal")["depth"], ideal["depth"])


AIR = [0.4, 0.3, 0.9, 0.0, 1.0, 0.0, 0.0, 0.08]  # above a table corner: lifts nothing


def test_each_observation_draws_new_noise_from_the_env_generator() -> None:
    """After a miss the scene is observed again: where its ideal depth is as it was, the
    capture is a new one (the noise comes from ``np_random``, which has moved on)."""
    depths = {}
    for sensor in ("ideal", "kinect-v1"):
        env = gym.make("BEOPick-v0", image_size=SIZE, sensor=sensor, max_episode_steps=2)
        try:
            first, _ = env.reset(seed=3)
            second, *_ = env.step(AIR)
            depths[sensor] = (first["depth"], second["depth"])
        finally:
            env.close()
    a, b = depths["ideal"]
    still = (a == b) & (a > 0)  # what the gripper's visit left as it was
    assert still.mean() > 0.5
    a, b = depths["kinect-v1"]
    assert np.mean(a[still] != b[still]) > 0.5


def test_the_scene_capture_draws_from_the_generator_it_is_given() -> None:
    """``TabletopScenes.capture`` (what the env calls): another generator, other noise on
    the same scene; the ideal frame it is given is not rendered again."""
    env = gym.make("BEOPick-v0", image_size=SIZE)
    try:
        obs, _ = env.reset(seed=5)
        scenes = env.unwrapped._tabletop
        sensor = make_sensor("kinect-v1", env.unwrapped.config.intrinsics)
        a = scenes.capture(sensor, np.random.default_rng(0))
        b = scenes.capture(sensor, np.random.default_rng(0))
        c = scenes.capture(sensor, np.random.default_rng(1))
        np.testing.assert_array_equal(a.depth, b.depth)
        assert not np.array_equal(a.depth, c.depth)
        np.testing.assert_array_equal(a.segmentation, obs["segmentation"])
    finally:
        env.close()


def test_a_bad_sensor_or_the_old_noise_argument_fails_at_make() -> None:
    with pytest.raises(EnvConfigError, match="did you mean 'kinect-v1'") as e:
        gym.make("BEOPick-v0", sensor="kinect")
    assert "\n" not in str(e.value)
    with pytest.raises(EnvConfigError, match="sensor="):
        gym.make("BEOPick-v0", sensor=True)
    # the keyword sensor= replaced is no keyword at all now
    with pytest.raises(EnvConfigError, match=r"unknown keyword arguments \['noise'\]"):
        gym.make("BEOPick-v0", noise=True)
