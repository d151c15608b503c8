"""BEOPick-v0 follows gymnasium's and the RL libraries' conventions: the time limit is the
episode's length, copies and pickles continue the episode, unsupported render modes and
misspelt keywords fail at ``gym.make``, the point-cloud mode, and the env checkers."""

from __future__ import annotations

import copy
import inspect
import os
import pickle
import re
import subprocess
import sys
import warnings
from dataclasses import fields
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.wrappers import TimeLimit

import beo_bench  # noqa: F401  (registers the ids)
from beo_bench.envs.pick import KEYWORDS, BEOPickEnv
from beo_bench.errors import EnvConfigError
from beo_bench.objects import ObjectSet
from beo_bench.scenes.camera import backproject, project
from beo_bench.scenes.pickconfig import PickConfig

SMALL = {"image_size": (64, 48), "num_objects": 1}
AIR = [0.4, 0.3, 0.9, 0.0, 1.0, 0.0, 0.0, 0.08]  # above a table corner: lifts nothing
DOCS = Path(__file__).resolve().parents[2] / "docs" / "env.md"


# -- the time limit ----------------------------------------------------------------------------
def _time_limit(env: gym.Env) -> TimeLimit | None:
    while isinstance(env, gym.Wrapper):
        if isinstance(env, TimeLimit):
            return env
        env = env.env
    return None


@pytest.mark.parametrize("kwargs, steps", [({}, 1), ({"max_episode_steps": 3}, 3)])
def test_the_time_limit_is_the_episode_length(kwargs, steps) -> None:
    """Gymnasium's TimeLimit alone says how many grasps an episode allows: every miss
    leaves it open (not terminated), and the limit truncates it at the last one."""
    assert gym.spec("BEOPick-v0").max_episode_steps == 1  # registered: one grasp
    e = gym.make("BEOPick-v0", **SMALL, **kwargs)
    try:
        assert e.spec.max_episode_steps == steps
        e.reset(seed=0)
        for attempt in range(1, steps + 1):
            _, _, terminated, truncated, info = e.step(AIR)
            assert info["attempt"] == attempt and not terminated
            assert truncated == (attempt == steps)
    finally:
        e.close()


def test_without_a_time_limit_misses_never_end_the_episode() -> None:
    e = gym.make("BEOPick-v0", max_episode_steps=-1, **SMALL)
    try:
        assert _time_limit(e) is None
        e.reset(seed=0)
        for _ in range(2):
            assert e.step(AIR)[2:4] == (False, False)
    finally:
        e.close()


def test_make_from_the_spec_rebuilds_the_same_limits() -> None:
    e = gym.make("BEOPick-v0", max_episode_steps=3, **SMALL)
    again = gym.make(e.spec)
    assert again.spec.max_episode_steps == 3 and again.unwrapped.config == e.unwrapped.config
    e.close()
    again.close()


def test_vector_envs_get_the_limit_too() -> None:
    envs = gym.make_vec(
        "BEOPick-v0", num_envs=2, vectorization_mode="sync", max_episode_steps=2, **SMALL
    )
    assert all(sub.spec.max_episode_steps == 2 for sub in envs.envs)
    envs.close()


# -- agents in [-1, 1] -------------------------------------------------------------------------
def _rescaled(env: gym.Env) -> gym.Env:
    """The env as SB3's agents see it (docs/env.md, "RL libraries"): actions in [-1, 1]."""
    return gym.wrappers.RescaleAction(env, np.float32(-1), np.float32(1))


@pytest.mark.parametrize("mode", [None, "sync", "async"])
def test_a_zero_action_through_rescale_action_is_a_valid_grasp(mode) -> None:
    """A policy initialised at zero acts at the space's centre, whose quaternion part is
    zero: the identity orientation (docs/env.md, "Action space"), never an ActionError, in
    a single env and in both of gym.make_vec's modes."""
    if mode is None:
        env = _rescaled(gym.make("BEOPick-v0", **SMALL))
        env.reset(seed=0)
        zero = np.zeros(8, np.float32)
        assert np.all(env.action(zero)[3:7] == 0)  # the quaternion the env is given
        _, reward, term, trunc, info = env.step(zero)
        assert reward == 0.0 and (term or trunc) and info["reason"] == "nothing_lifted"
        env.close()
        return
    envs = gym.make_vec(
        "BEOPick-v0", num_envs=2, vectorization_mode=mode, wrappers=[_rescaled], **SMALL
    )
    assert envs.single_action_space == gym.spaces.Box(-1, 1, (8,), np.float32)
    envs.reset(seed=0)
    _, reward, term, trunc, info = envs.step(np.zeros((2, 8), np.float32))
    assert (reward == 0).all() and (term | trunc).all()
    assert list(info["reason"]) == ["nothing_lifted"] * 2
    envs.close()


def test_a_zero_quaternion_is_the_identity_orientation() -> None:
    from beo_bench.envs.pick import parse_action

    T, opening = parse_action([0.1, 0.2, 0.9, 0, 0, 0, 0, 0.05])
    np.testing.assert_array_equal(T[:3, :3], np.eye(3))
    np.testing.assert_array_equal(T[:3, 3], [0.1, 0.2, 0.9])
    assert opening == 0.05
    T1, _ = parse_action([0.1, 0.2, 0.9, 1, 0, 0, 0, 0.05])
    np.testing.assert_array_equal(T, T1)


# -- copy and pickle ---------------------------------------------------------------------------
def _assert_same_obs(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])


@pytest.mark.parametrize("obs_mode", ["image", "pointcloud"])
def test_copies_continue_the_episode_exactly(obs_mode) -> None:
    """A deep copy and a pickled copy, made mid-episode through gym.make's wrappers, give the
    same next step (physics, observation, reward) and the same next unseeded reset (RNG)."""
    kw = {"num_points": 512} if obs_mode == "pointcloud" else {}
    e = gym.make(
        "BEOPick-v0",
        image_size=(96, 72),
        max_episode_steps=3,
        sensor="kinect-v1",
        obs_mode=obs_mode,
        **kw,
    )
    e.reset(seed=3)
    grasps = e.unwrapped.ground_truth_grasps()
    assert grasps
    e.step(AIR)  # a miss: the scene settles again and is observed anew
    copies = [copy.deepcopy(e), pickle.loads(pickle.dumps(e))]
    try:
        for c in copies:
            assert c.unwrapped._renderer is None  # never copied: made when next needed
            assert c.spec.max_episode_steps == 3 and _time_limit(c)._elapsed_steps == 1
        results = [env.step(grasps[0].action) for env in (e, *copies)]
        assert results[0][4]["success"]  # the step exercises the physics of a real lift
        for r in results[1:]:
            _assert_same_obs(results[0][0], r[0])
            assert r[1:4] == results[0][1:4]
            assert r[4]["lift_height"] == results[0][4]["lift_height"]
        resets = [env.reset()[0] for env in (e, *copies)]
        for r in resets[1:]:
            _assert_same_obs(resets[0], r)
    finally:
        for env in (e, *copies):
            env.close()


def test_copy_before_reset_and_after_close() -> None:
    e = BEOPickEnv(PickConfig(**SMALL))
    c = copy.deepcopy(e)
    assert c.scene is None and c.config is e.config  # frozen: shared, never copied
    p = pickle.loads(pickle.dumps(e))
    assert p.config == e.config and p.config.classes == e.config.classes
    obs_c, _ = c.reset(seed=4)
    obs_e, _ = e.reset(seed=4)
    _assert_same_obs(obs_e, obs_c)
    e.close()
    assert pickle.loads(pickle.dumps(e)).scene is None
    c.close()


def test_no_traceback_at_exit_after_copies_and_unclosed_envs() -> None:
    code = (
        "import copy, pickle, gymnasium as gym, beo_bench\n"
        "e = gym.make('BEOPick-v0', image_size=(64, 48), num_objects=1, render_mode='rgb_array')\n"
        "e.reset(seed=0); e.render()\n"
        "c = copy.deepcopy(e); p = pickle.loads(pickle.dumps(e))\n"
        "c.step([0.4, 0.3, 0.9, 0, 1, 0, 0, 0.08]); p.render()\n"
        "print('done')\n"  # nothing closed: interpreter exit cleans up
    )
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300
    )
    assert out.returncode == 0 and out.stdout.strip() == "done", out.stderr
    assert out.stderr == ""


# -- render modes and keywords -----------------------------------------------------------------
@pytest.mark.parametrize("mode", ["human", "rgb_array_list", "ansi"])
def test_unsupported_render_modes_fail_at_make(mode) -> None:
    with pytest.raises(EnvConfigError, match="use None, 'rgb_array' or 'depth_array'"):
        gym.make("BEOPick-v0", render_mode=mode, **SMALL)


@pytest.mark.parametrize("mode", ["rgb_array", "depth_array"])
def test_supported_render_modes_are_not_wrapped(mode) -> None:
    e = gym.make("BEOPick-v0", render_mode=mode, **SMALL)
    assert e.render_mode == mode and e.unwrapped.render_mode == mode
    e.reset(seed=0)
    assert e.render().shape[:2] == (48, 64)
    e.close()


def test_keywords_are_the_configs_typed_and_documented_fields() -> None:
    params = [f for f in fields(PickConfig) if f.init]
    assert tuple(f.name for f in params) == KEYWORDS and len(KEYWORDS) == 14
    assert all(f.type for f in params)
    doc = inspect.getdoc(BEOPickEnv)
    for section in (
        "Description",
        "Action Space",
        "Observation Space",
        "Rewards",
        "Starting State",
        "Episode End",
        "Arguments",
        "Version History",
    ):
        assert f"## {section}\n" in doc
    for name in KEYWORDS:
        assert f"``{name}``" in doc  # every argument is documented


def test_misspelt_keyword_is_named_with_a_suggestion() -> None:
    with pytest.raises(EnvConfigError, match=r"'num_point': did you mean 'num_points'"):
        gym.make("BEOPick-v0", num_point=2)
    with pytest.raises(TypeError, match="num_point"):  # Python's own error, unwrapped
        PickConfig(num_point=2)  # type: ignore[call-arg]
    # the episode's length is gymnasium's max_episode_steps alone
    with pytest.raises(EnvConfigError, match=r"unknown keyword arguments \['max_attempts'\]"):
        gym.make("BEOPick-v0", max_attempts=2)
    with pytest.raises(EnvConfigError, match=r"num_points=.* only applies to obs_mode"):
        gym.make("BEOPick-v0", num_points=100)
    with pytest.raises(EnvConfigError, match="obs_mode='depth'"):
        gym.make("BEOPick-v0", obs_mode="depth")


def test_make_with_the_module_prefix_needs_no_import() -> None:
    code = (
        "import gymnasium as gym\n"
        "try:\n"
        "    gym.make('BEOPick-v0')\n"
        "except gym.error.NameNotFound as e:\n"
        "    print('NameNotFound')\n"
        "e = gym.make('beo_bench:BEOPick-v0', image_size=(32, 24), num_objects=1)\n"
        "obs, _ = e.reset(seed=0)\n"
        "print(obs['depth'].shape)\n"
        "e.close()\n"
    )
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["NameNotFound", "(24,", "32)"]


# -- segmentation dtype ------------------------------------------------------------------------
def test_segmentation_is_one_byte_while_labels_fit() -> None:
    e = gym.make("BEOPick-v0", image_size=(64, 48))
    assert e.observation_space["segmentation"].dtype == np.uint8
    obs, _ = e.reset(seed=0)
    assert obs["segmentation"].dtype == np.uint8 and e.observation_space.contains(obs)
    e.close()
    # 255 object labels do not fit a byte beside the background: int32
    base = ObjectSet("test", ["mug"])
    many = {f"c{i:03d}": [base.get("mug", 0)] for i in range(255)}
    objects = ObjectSet.from_instances("test", many, "test")
    big = BEOPickEnv(PickConfig(objects=objects, num_objects=255))
    assert big.config.max_objects == 255
    assert big.observation_space["segmentation"].dtype == np.int32


# -- point clouds ------------------------------------------------------------------------------
def test_pointcloud_points_lie_on_the_rendered_surfaces() -> None:
    img = gym.make("BEOPick-v0", image_size=(96, 72), num_objects=3)
    pc = gym.make("BEOPick-v0", image_size=(96, 72), num_objects=3, obs_mode="pointcloud")
    try:
        obs_i, _ = img.reset(seed=7)
        obs_p, _ = pc.reset(seed=7)  # same scene and camera: the draws before sampling match
        assert pc.observation_space.contains(obs_p)
        assert set(obs_p) == {
            "points",
            "point_labels",
            "target_class",
            "intrinsics",
            "cam_to_world",
        }
        pts, labels = obs_p["points"], obs_p["point_labels"]
        assert pts.shape == (4096, 3) and pts.dtype == np.float32
        assert labels.shape == (4096,) and labels.dtype == np.uint8
        K, depth, seg = obs_p["intrinsics"], obs_i["depth"], obs_i["segmentation"]
        np.testing.assert_array_equal(obs_p["cam_to_world"], obs_i["cam_to_world"])
        uv = np.rint(project(pts, K)).astype(int)
        assert np.all(pts[:, 2] > 0)
        np.testing.assert_allclose(pts[:, 2], depth[uv[:, 1], uv[:, 0]], rtol=1e-6)
        np.testing.assert_array_equal(labels, seg[uv[:, 1], uv[:, 0]])
        # distinct pixels (no repeats while enough have depth), all on the depth's surface
        assert len(np.unique(uv, axis=0)) == 4096 <= np.count_nonzero(depth)
        # each point is its pixel's back-projection (row of backproject's row-major output)
        valid = depth > 0
        row = np.cumsum(valid.ravel()) - 1
        surface = backproject(depth, K)[row[uv[:, 1] * depth.shape[1] + uv[:, 0]]]
        np.testing.assert_allclose(pts, surface, rtol=1e-6, atol=1e-7)
        assert set(np.unique(labels)) <= set(np.unique(seg))
        assert obs_p["target_class"] == obs_i["target_class"]
        assert np.any(labels == pc.unwrapped.target_label)
    finally:
        img.close()
        pc.close()


def test_pointcloud_is_deterministic_and_pads_with_repeats() -> None:
    kw = {"image_size": (16, 12), "num_objects": 1, "obs_mode": "pointcloud"}
    a = gym.make("BEOPick-v0", num_points=500, **kw)  # 192 pixels: fewer than 500
    b = gym.make("BEOPick-v0", num_points=500, **kw)
    try:
        oa, _ = a.reset(seed=1)
        ob, _ = b.reset(seed=1)
        _assert_same_obs(oa, ob)
        valid = np.count_nonzero(a.unwrapped._image["depth"] > 0)
        first = oa["points"][:valid]
        assert len(np.unique(first, axis=0)) == valid  # every valid pixel once, first
        rest = {tuple(p) for p in oa["points"][valid:]}
        assert rest <= {tuple(p) for p in first}  # then repeats of real points, no zeros
        assert np.all(oa["points"][:, 2] > 0)
        oc, _ = a.reset(seed=2)
        assert not np.array_equal(oc["points"], oa["points"])
    finally:
        a.close()
        b.close()


# -- env checkers ------------------------------------------------------------------------------
def _documented_warnings() -> dict[str, str]:
    """The warnings docs/env.md explains: its lines ``- checker: `message start` ...``."""
    found = re.findall(r"^- (gymnasium|sb3): `([^`]+)`", DOCS.read_text(), flags=re.M)
    return {text: checker for checker, text in found}


@pytest.mark.parametrize("obs_mode", ["image", "pointcloud"])
def test_env_checkers_pass_with_only_the_documented_warnings(obs_mode) -> None:
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    documented = _documented_warnings()
    assert documented, "docs/env.md lists no checker warnings"
    seen: set[tuple[str, str]] = set()
    kw = {"num_points": 256} if obs_mode == "pointcloud" else {}
    for checker, check in (("gymnasium", check_env), ("sb3", sb3_check_env)):
        for render_mode in (None, "rgb_array", "depth_array"):
            e = gym.make("BEOPick-v0", obs_mode=obs_mode, render_mode=render_mode, **SMALL, **kw)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                check(e.unwrapped)
            e.close()
            for w in caught:
                text = re.sub(r"^WARN: ", "", re.sub(r"\x1b\[[0-9;]*m", "", str(w.message)))
                match = [d for d in documented if text.startswith(d)]
                assert match, f"{checker} warned something docs/env.md does not explain: {text}"
                assert documented[match[0]] == checker, text
                seen.add((checker, match[0]))
    expected = {
        ("gymnasium", "For Box action spaces, we recommend using a symmetric and normalized"),
        ("sb3", "We recommend you to use a symmetric and normalized Box action space"),
    }
    names = ["cam_to_world", "intrinsics"]
    names += ["depth", "segmentation"] if obs_mode == "image" else ["points"]
    expected |= {
        ("sb3", f"Your observation {n} has an unconventional shape (neither an image, nor a 1D")
        for n in names
    }
    assert seen == expected
