"""BEOPick-v0 never produces an episode without a visible target."""

from __future__ import annotations

import numpy as np
import pytest

from beo_bench.envs.pick import BEOPickEnv
from beo_bench.scenes.builder import TableConfig
from beo_bench.scenes.layout import ObjectTooLargeError
from beo_bench.scenes.pickconfig import PickConfig
from beo_bench.scenes.tabletop import NoVisibleTargetError


def test_target_is_visible_in_every_episode() -> None:
    # seed 89 at the defaults hid the target completely (0 pixels) before the guarantee
    env = BEOPickEnv()
    assert env.config.target_pixels == 50
    try:
        for seed in range(100):
            obs, info = env.reset(seed=seed)
            pixels = int(np.count_nonzero(obs["segmentation"] == env.target_label))
            assert pixels >= 50, f"seed {seed}: the target shows {pixels} pixels"
            assert info["target_pixels"] == pixels
            assert env.ground_truth()[env.target_label - 1].pixels == pixels
    finally:
        env.close()


def test_unreachable_visibility_raises_instead_of_a_blind_episode() -> None:
    env = BEOPickEnv(PickConfig(image_size=(32, 24), num_objects=1, min_target_pixels=32 * 24 + 1))
    try:
        with pytest.raises(NoVisibleTargetError, match="min_target_pixels"):
            env.reset(seed=0)
    finally:
        env.close()


def test_object_too_large_for_the_table_is_refused() -> None:
    table = TableConfig(table_half=(0.03, 0.03), area_half=(0.01, 0.01))
    env = BEOPickEnv(
        PickConfig(image_size=(32, 24), num_objects=1, categories=("bottle",), table=table)
    )
    try:
        with pytest.raises(ObjectTooLargeError, match=r"bottle.*footprint radius"):
            env.reset(seed=0)
    finally:
        env.close()
