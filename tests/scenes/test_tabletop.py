"""TabletopScenes draws BEOPick-v0's scenes without the env: the same seed gives the env's
observation and ground truth, bit for bit; and the scenes never import the envs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from beo_bench.errors import EnvConfigError
from beo_bench.objects import ObjectSet
from beo_bench.scenes.pickconfig import PickConfig, default_categories
from beo_bench.scenes.tabletop import NoVisibleTargetError, TabletopScenes

CATS = ("bowl", "mug", "can")
SIZE = (64, 48)


def _same(a: object, b: object) -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b)  # same keys in the same order
        for k in a:
            _same(a[k], b[k])
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype
        np.testing.assert_array_equal(a, b)
    else:
        assert a == b


def test_reset_is_the_envs_reset_bit_for_bit() -> None:
    from beo_bench.envs.pick import BEOPickEnv

    objects = ObjectSet("test", CATS)
    config = PickConfig(objects=objects, image_size=SIZE, num_objects=(1, 3))
    env = BEOPickEnv(config)
    scenes = TabletopScenes(config)
    try:
        assert env.categories == CATS and config.target_pixels == 1
        for seed in (0, 7, None):  # None: both continue from the last seed's generator
            obs_e, info = env.reset(seed=seed)
            obs_s, truths = scenes.reset(seed)
            _same(obs_e, obs_s)
            assert len(truths) == info["num_objects"]
            for g_e, g_s in zip(env.ground_truth(), truths, strict=True):
                assert g_e.__dict__.keys() == g_s.__dict__.keys()
                for k, v in g_e.__dict__.items():
                    _same(v, getattr(g_s, k))
            assert scenes.target == env.target_label
            assert truths[scenes.target - 1].pixels == info["target_pixels"]
            np.testing.assert_array_equal(scenes.render().depth, obs_s["depth"])
    finally:
        env.close()
        scenes.close()


# A draw without a target class, as it was before the option existed (scene, camera and
# target of each seed; the last three are the tabletop suite's episodes 0-2): (seed, the
# drawn (category, instance index), target label, cam_to_world's x translation)
UNREQUESTED = [
    (0, [("chair", 8), ("bowl", 40), ("box", 32), ("desk", 45)], 3, 0.353312649),
    (1, [("chair", 1), ("mug", 7)], 2, 0.544149325),
    (2, [("box", 16), ("bottle", 30), ("bathtub", 40), ("car", 36)], 3, 0.537356836),
    (3, [("bathtub", 1), ("bed", 4), ("bowl", 16), ("bottle", 21)], 3, -0.405043895),
    (89, [("bowl", 36), ("airplane", 27), ("chair", 14), ("mug", 45)], 2, -0.091368654),
    (1877641100, [("desk", 37), ("bottle", 14), ("mug", 45)], 3, -0.087251843),
    (712186952, [("bathtub", 27)], 1, 0.220286644),
    (869875063, [("monitor", 34), ("car", 40), ("bowl", 30)], 3, 0.417628693),
]


def test_a_draw_without_a_target_class_is_the_seeds_scene_as_it_always_was() -> None:
    """The target-class option leaves the plain draw alone: every existing seed, the
    tabletop suite's included, gives the scene it gave before."""
    scenes = TabletopScenes(PickConfig(image_size=SIZE))
    try:
        for seed, drawn, target, cam_x in UNREQUESTED:
            scenes.reset(seed)
            assert scenes.drawn is not None
            assert scenes.drawn[0] == drawn and scenes.target == target, seed
            assert scenes.cam[0, 3] == pytest.approx(cam_x, abs=1e-9)
    finally:
        scenes.close()


def test_a_requested_target_class_is_the_envs_too_and_drawn_as_the_plain_draw_would() -> None:
    """``reset(seed, target_category)`` is the env's ``reset(seed=..., options=...)`` bit for
    bit, its target of that class; and the classes beside the target are those of a plain
    draw whose target is of that class: the target's label uniform, the other classes
    equally likely."""
    from beo_bench.envs.pick import BEOPickEnv

    objects = ObjectSet("test", CATS)
    config = PickConfig(objects=objects, image_size=SIZE, num_objects=(1, 3))
    env = BEOPickEnv(config)
    scenes = TabletopScenes(config)
    try:
        for seed, asked in [(0, "can"), (4, "bowl"), (4, "mug")]:
            obs_e, _ = env.reset(seed=seed, options={"target_class": asked})
            obs_s, truths = scenes.reset(seed, asked)
            _same(obs_e, obs_s)
            assert truths[scenes.target - 1].category == asked == CATS[obs_s["target_class"]]
        with pytest.raises(ValueError, match=r"'sofa' is not among .*choose one of"):
            scenes.reset(0, "sofa")
    finally:
        env.close()
        scenes.close()
    many = TabletopScenes(
        PickConfig(objects=ObjectSet("test", ("bowl", "mug", "can", "bottle")), image_size=SIZE)
    )
    rng = np.random.default_rng(0)
    n = 3000
    labels = np.zeros(3)
    others: dict[str, int] = {}
    for _ in range(n):
        cats = many._with_target(rng, 3, "mug")
        assert len(set(cats)) == 3 and "mug" in cats
        labels[cats.index("mug")] += 1
        for c in cats:
            others[c] = others.get(c, 0) + (c != "mug")
    np.testing.assert_allclose(labels / n, 1 / 3, atol=0.03)  # seeded; 3.5 standard errors
    assert others.pop("mug") == 0
    np.testing.assert_allclose(np.array(list(others.values())) / n, 2 / 3, atol=0.03)


def test_close_is_not_final_and_errors_are_the_envs() -> None:
    objects = ObjectSet("test", ("bowl",))
    scenes = TabletopScenes(
        PickConfig(objects=objects, num_objects=(1, 1), image_size=SIZE, min_target_pixels=1)
    )
    first, _ = scenes.reset(0)
    scenes.close()
    assert scenes.scene is None and scenes.renderer is None
    again, _ = scenes.reset(0)
    _same(first, again)
    assert scenes.render_rgb().shape == (SIZE[1], SIZE[0], 3)
    scenes.close()
    assert set(CATS) <= set(default_categories())
    hidden = TabletopScenes(
        PickConfig(
            objects=objects,
            num_objects=(1, 1),
            image_size=SIZE,
            min_target_pixels=SIZE[0] * SIZE[1] + 1,
        )
    )
    with pytest.raises(NoVisibleTargetError, match="min_target_pixels"):
        hidden.reset(0)
    hidden.close()


def test_bad_settings_are_refused() -> None:
    objects = ObjectSet("test", ("bowl", "mug"))
    with pytest.raises(EnvConfigError, match="not in the object set"):
        PickConfig(objects=objects, categories=("bowl", "sofa"))
    with pytest.raises(EnvConfigError, match="num_objects"):
        PickConfig(objects=objects, num_objects=(1, 3))
    with pytest.raises(EnvConfigError, match="num_objects"):
        PickConfig(objects=objects, num_objects=(0, 1))


def test_scenes_never_import_the_envs() -> None:
    """Data flows objects -> scenes -> envs (docs/design.md): what lies below the envs,
    the perception backends included, draws its tabletop scenes from here."""
    root = Path(__file__).resolve().parents[2]
    for path in [*sorted((root / "scenes").glob("*.py")), root / "perception" / "hbeo" / "data.py"]:
        assert "beo_bench.envs" not in path.read_text(), path
