"""The pick suite at the power its claims need (issue 47): 500 episodes whose targets are
balanced over the pickable classes (episode i's of class i mod C, asked of the env through
its ``target_class`` reset option), the smoke set's 8 episodes of 8 classes, and the
tabletop suite's scenes left as the seed draws them."""

from __future__ import annotations

from collections import Counter

import numpy as np

from beo_bench.bench.kinds import get_kind
from beo_bench.bench.kinds.pick import target_class
from beo_bench.bench.suites import SMOKE_SIZES, Kind, episode_seed, get_suite
from beo_bench.objects import pickable_categories


def test_the_pick_suite_gives_every_class_at_least_25_targets() -> None:
    pick = get_suite("pick")
    assert (pick.size, pick.version) == (500, 5)  # v4 was 100 episodes, targets as drawn
    cats = pickable_categories()
    counts = Counter(cats[target_class(i, len(cats))] for i in range(pick.size))
    assert set(counts) == set(cats) and min(counts.values()) >= 25
    assert sorted(set(counts.values())) == [27, 28]  # 500 = 18 x 27 + 14
    # the smoke set's episodes are 8 different classes: stratification costs it nothing
    smoke = [target_class(i, len(cats)) for i in range(SMOKE_SIZES[Kind.PICK])]
    assert len(set(smoke)) == SMOKE_SIZES[Kind.PICK] == 8


def test_pick_episodes_ask_the_env_for_their_target_class() -> None:
    """Episode i's observation asks for class i mod C, the scene holds it as the target,
    and its row says so; the episode is the env's reset with the seed and that option."""
    suite = get_suite("pick")
    items = get_kind(Kind.PICK).open(suite, False)
    try:
        env = items.env
        cats = env.categories
        for i in (0, 5, 17, 18, 19, 499):
            obs = items.reset(i)  # type: ignore[attr-defined]
            want = cats[i % len(cats)]
            assert cats[obs["target_class"]] == want, i
            truth = {g.label: g.category for g in env.ground_truth()}
            assert truth[env.target_label] == want
            again, _ = env.reset(seed=episode_seed(suite, i), options={"target_class": want})
            np.testing.assert_array_equal(again["depth"], obs["depth"])
        assert items.templates(3)[0]["category"] == cats[3]
    finally:
        items.close()


def test_tabletop_scenes_are_the_seeds_own_draw() -> None:
    """The tabletop suite asks for no target: its scene i is the env's plain reset with the
    episode seed, as before the option existed."""
    from beo_bench.envs.pick import BEOPickEnv
    from beo_bench.scenes.pickconfig import PickConfig

    suite = get_suite("tabletop")
    items = get_kind(Kind.TABLETOP).open(suite, False)
    plain = BEOPickEnv(PickConfig(image_size=suite.image_size, sensor=suite.sensor))
    try:
        for i in range(3):
            obs = items.reset(i)  # type: ignore[attr-defined]
            want, _ = plain.reset(seed=episode_seed(suite, i))
            for k in want:
                np.testing.assert_array_equal(obs[k], want[k])
    finally:
        items.close()
        plain.close()
