"""TabletopScenes draws BEOPick-v0's scenes without the env: the same seed gives the env's
observation and ground truth, bit for bit; and the scenes never import the envs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from beo_bench.objects import ObjectSet
from beo_bench.scenes.camera import Intrinsics
from beo_bench.scenes.tabletop import (
    NoVisibleTargetError,
    TabletopScenes,
    default_categories,
)

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
    env = BEOPickEnv(objects=objects, image_size=SIZE, num_objects=(1, 3))
    scenes = TabletopScenes(objects, num_objects=(1, 3), intrinsics=Intrinsics(*SIZE))
    try:
        assert scenes.categories == env.categories and scenes.seg_dtype == env.seg_dtype
        assert scenes.min_target_pixels == env.min_target_pixels == 1
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


def test_close_is_not_final_and_errors_are_the_envs() -> None:
    from beo_bench.envs import pick

    objects = ObjectSet("test", ("bowl",))
    scenes = TabletopScenes(
        objects, num_objects=(1, 1), intrinsics=Intrinsics(*SIZE), min_target_pixels=1
    )
    first, _ = scenes.reset(0)
    scenes.close()
    assert scenes.scene is None and scenes.renderer is None
    again, _ = scenes.reset(0)
    _same(first, again)
    assert scenes.render_rgb().shape == (SIZE[1], SIZE[0], 3)
    scenes.close()
    # the env's names are the scenes' own
    assert pick.NoVisibleTargetError is NoVisibleTargetError
    assert pick.default_categories is default_categories
    assert set(CATS) <= set(default_categories())
    hidden = TabletopScenes(
        objects,
        num_objects=(1, 1),
        intrinsics=Intrinsics(*SIZE),
        min_target_pixels=SIZE[0] * SIZE[1] + 1,
    )
    with pytest.raises(NoVisibleTargetError, match="min_target_pixels"):
        hidden.reset(0)
    hidden.close()


def test_bad_settings_are_refused() -> None:
    objects = ObjectSet("test", ("bowl", "mug"))
    with pytest.raises(ValueError, match="not in the object set"):
        TabletopScenes(objects, ["bowl", "sofa"])
    with pytest.raises(ValueError, match="num_objects"):
        TabletopScenes(objects, num_objects=(1, 3))
    with pytest.raises(ValueError, match="num_objects"):
        TabletopScenes(objects, num_objects=(0, 1))


def test_scenes_never_import_the_envs() -> None:
    """Data flows objects -> scenes -> envs (docs/design.md): what lies below the envs,
    the perception backends included, draws its tabletop scenes from here."""
    root = Path(__file__).resolve().parents[2]
    for path in [*sorted((root / "scenes").glob("*.py")), root / "perception" / "hbeo_data.py"]:
        assert "beo_bench.envs" not in path.read_text(), path
