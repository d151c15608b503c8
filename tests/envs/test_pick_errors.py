"""BEOPick-v0 refuses bad settings, bad actions and out-of-order calls with one
``beo_bench.errors`` exception that says what to change (never a bare numpy, GL or
gymnasium traceback, and never a silent reinterpretation of the input)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded

import beo_bench  # noqa: F401  (registers the ids)
from beo_bench.envs.pick import EnvStateError, parse_action
from beo_bench.errors import ActionError, BeoBenchError, EnvConfigError
from beo_bench.scenes.camera import MAX_IMAGE_SIDE
from beo_bench.scenes.gripper import MAX_OPENING

SMALL = {"image_size": (64, 48), "num_objects": 1}
DOWN = [0.0, 1.0, 0.0, 0.0]  # wxyz: gripper +z = world -z
AIR = [0.4, 0.3, 0.9]  # above a table corner: a grasp there lifts nothing, quickly


@pytest.fixture(scope="module")
def env():
    e = gym.make("BEOPick-v0", **SMALL)
    yield e
    e.close()


@pytest.mark.parametrize(
    "kwargs, match",
    [
        # the GL renderbuffer limit: must fail at make, not as a GL FatalError at reset
        ({"image_size": (20000, 100)}, f"at most {MAX_IMAGE_SIDE}"),
        ({"image_size": (64, MAX_IMAGE_SIDE + 1)}, f"at most {MAX_IMAGE_SIDE}"),
        # strings: "64" used to unpack to a 6x4 image, ("640", "480") to be parsed
        ({"image_size": "64"}, r"\(width, height\)"),
        ({"image_size": ("640", "480")}, "whole number"),
        ({"image_size": (64.5, 48)}, "whole number"),
        ({"image_size": 640}, r"\(width, height\)"),
        ({"image_size": np.array(640)}, r"\(width, height\)"),
        ({"image_size": np.ones((2, 2), int)}, "whole number"),
        ({"num_objects": "three"}, "num_objects"),
        ({"num_objects": "2"}, "num_objects"),
        ({"num_objects": (1, "x")}, "num_objects"),
        ({"num_objects": {"min": 1}}, "num_objects"),
        ({"num_objects": 1.5}, "whole number"),
        ({"min_target_pixels": "x"}, "min_target_pixels"),
        ({"categories": ["mug", "bowl", "mug"]}, r"\['mug'\] more than once"),
        ({"categories": "mug"}, "list of category names"),
        ({"categories": ["mug", 3]}, "category name"),
    ],
)
def test_bad_settings_are_env_config_errors_at_make(kwargs, match) -> None:
    with pytest.raises(EnvConfigError, match=match):
        gym.make("BEOPick-v0", **kwargs)


def test_whole_numbers_of_any_numeric_type_are_accepted() -> None:
    e = gym.make(
        "BEOPick-v0",
        image_size=np.array([64, 48]),
        num_objects=np.int64(1),
        num_points=2.0,
        obs_mode="pointcloud",
    )
    cfg = e.unwrapped.config
    assert (cfg.intrinsics.width, cfg.intrinsics.height) == (64, 48)
    assert cfg.num_objects == (1, 1) and cfg.num_points == 2 and type(cfg.num_points) is int
    e.close()


@pytest.mark.parametrize(
    "action, match",
    [
        ("abc", "not numeric"),
        ("0 0 1 0 1 0 0 0.05", "not numeric"),
        ({"position": [0, 0, 1]}, "not numeric"),
        (["0", "0", "1", "0", "1", "0", "0", "0.05"], "not numeric"),  # was parsed silently
        ([[0, 0, 1], [0, 1, 0, 0], [0.05]], "not an array of 8 numbers"),
        (np.ones(8, dtype=bool), "not numeric"),
        (None, "not numeric"),
        ([*AIR, *DOWN, MAX_OPENING + 0.01], r"outside the gripper's range \[0, 0.08\]"),
        ([*AIR, *DOWN, -0.01], r"outside the gripper's range \[0, 0.08\]"),
        ([*AIR, *DOWN, 5.0], "opening"),
    ],
)
def test_bad_actions_are_action_errors(env, action, match) -> None:
    env.reset(seed=0)
    with pytest.raises(ActionError, match=match):
        env.step(action)


def test_opening_bounds_are_accepted_including_float32_rounding() -> None:
    for opening in (0.0, MAX_OPENING, np.float32(MAX_OPENING), MAX_OPENING + 1e-7, -1e-7):
        _, o = parse_action(np.r_[AIR, DOWN, opening].astype(np.float32))
        assert 0.0 <= o <= MAX_OPENING


def test_step_after_success_raises_until_reset() -> None:
    e = gym.make("BEOPick-v0", image_size=(96, 72), max_episode_steps=3)
    try:
        e.reset(seed=3)
        grasp = e.unwrapped.ground_truth_grasps()[0].action
        _, reward, terminated, truncated, _ = e.step(grasp)
        assert reward == 1.0 and terminated and not truncated  # a success ends the episode
        with pytest.raises(EnvStateError, match=r"terminated.*call reset\(\)"):
            e.step([*AIR, *DOWN, MAX_OPENING])
        with pytest.raises(BeoBenchError):  # one family for every user error
            e.step([*AIR, *DOWN, MAX_OPENING])
        e.reset(seed=3)
        _, _, terminated, _, info = e.step([*AIR, *DOWN, MAX_OPENING])  # a new episode acts
        assert not terminated and info["attempt"] == 1
    finally:
        e.close()


def test_step_before_reset() -> None:
    e = gym.make("BEOPick-v0", **SMALL)
    try:
        with pytest.raises(ResetNeeded):  # gymnasium's order check, through gym.make
            e.step([*AIR, *DOWN, MAX_OPENING])
        with pytest.raises(EnvStateError, match=r"call reset\(\) before step\(\)"):
            e.unwrapped.step([*AIR, *DOWN, MAX_OPENING])  # the env's own check, unwrapped
        with pytest.raises(EnvStateError, match="reset"):
            e.unwrapped.ground_truth()
    finally:
        e.close()


def test_num_points_is_bounded_at_make() -> None:
    """Issue 50, attack 18: num_points=10**9 took 22 GB at reset and was killed for
    memory; it is refused at make, naming the limit."""
    from beo_bench.scenes.pickconfig import MAX_NUM_POINTS

    assert MAX_NUM_POINTS == 2**20
    for n in (10**9, MAX_NUM_POINTS + 1):
        with pytest.raises(EnvConfigError, match=r"give at most 1,048,576 points \(MAX_NUM_POINTS"):
            gym.make("BEOPick-v0", obs_mode="pointcloud", num_points=n, **SMALL)
    gym.make("BEOPick-v0", obs_mode="pointcloud", num_points=MAX_NUM_POINTS, **SMALL).close()


def test_grasp_judges_as_step_does_and_ends_the_episode_without_looking_again(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``grasp``: step's success and info for the same grasp of the same scene, and the
    episode ends even on a miss, with no settling or new observation (the pick items' one
    grasp an episode)."""
    env = gym.make("BEOPick-v0", image_size=(96, 72), max_episode_steps=3).unwrapped
    try:
        miss = [*AIR, *DOWN, MAX_OPENING]
        env.reset(seed=3)
        _, reward, _, _, by_step = env.step(miss)
        env.reset(seed=3)
        looks = []
        real = env._observe
        monkeypatch.setattr(env, "_observe", lambda *a: looks.append(1) or real(*a))
        success, by_grasp = env.grasp(miss)
        assert success is (reward > 0) is False and by_grasp == by_step
        assert looks == []  # a miss is not seen again
        with pytest.raises(EnvStateError, match=r"grasp\(\) after the episode terminated"):
            env.grasp(miss)
        with pytest.raises(EnvStateError, match=r"call reset\(\)"):
            env.step(miss)
        env.reset(seed=3)
        assert env.grasp(env.ground_truth_grasps()[0].action)[0] is True
    finally:
        env.close()
