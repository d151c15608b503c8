"""Tabletop items: a BEOPick-v0 scene with 1-4 objects; every object with at least
``min_pixels`` visible pixels is one scored view (the ``tabletop`` suite)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench.bench.kinds.common import ItemKind, Items, Rows
from beo_bench.bench.suites import Kind, Suite, episode_seed
from beo_bench.errors import UserDataError
from beo_bench.types import GroundTruth, View

if TYPE_CHECKING:
    from beo_bench.scenes.pickconfig import PickConfig


def categories(suite: Suite) -> tuple[str, ...]:
    """The class list the views carry: a dataset's classes, or the env's default ones."""
    if suite.dataset is not None:
        from beo_bench.objects.datasets import object_set

        return object_set(suite.dataset, suite.split, suite.categories).categories
    from beo_bench.objects import pickable_categories

    return pickable_categories()  # BEOPick-v0's default class list


def pick_config(suite: Suite, cache_root: Path | None = None) -> PickConfig:
    """The BEOPick-v0 settings of a tabletop or pick suite's scenes: its split, image and
    sensor (the scenes' depth as the suite's sensor captures it); on a dataset, the user's
    objects, up to four of distinct classes a scene; its objects kept in the cache at
    ``cache_root`` (None: the environment's)."""
    from beo_bench.scenes.pickconfig import PickConfig

    objects, num_objects = None, (1, 4)
    if suite.dataset is not None:
        objects = suite.dataset.objects(suite.split, suite.categories, cache_root=cache_root)
        num_objects = (1, min(4, len(objects.categories)))
    return PickConfig(
        split=suite.split,
        num_objects=num_objects,
        objects=objects,
        image_size=suite.image_size,
        fovy_deg=suite.fovy_deg,
        sensor=suite.sensor,
        cache_root=cache_root,
    )


def view_label(view: View) -> int:
    """The segmentation label of the object a scene view shows."""
    return int(np.asarray(view.segmentation)[np.asarray(view.mask)][0])


class SceneItems(Items):
    """The suite's BEOPick-v0 scenes, from one reused env."""

    def __init__(
        self, suite: Suite, class_given: bool = False, cache_root: Path | None = None
    ) -> None:
        super().__init__(suite, class_given, cache_root)
        self._env: Any = None

    @property
    def env(self) -> Any:
        if self._env is None:
            from beo_bench.envs.pick import BEOPickEnv

            self._env = BEOPickEnv(pick_config(self.suite, self.cache_root))
        return self._env

    def close(self) -> None:
        if self._env is not None:
            self._env.close()
            self._env = None

    def reset(self, index: int) -> dict[str, Any]:
        """The env reset to item ``index``'s episode; its observation. On a user's dataset,
        a target no camera pose shows (objects loaded too small to see, as a file in the
        wrong units makes them) is the data's fault, said in one line with the flags that
        fix it (a :class:`~beo_bench.errors.UserDataError`), never reported as a bug."""
        from beo_bench.scenes.tabletop import NoVisibleTargetError

        try:
            obs, _ = self.env.reset(
                seed=episode_seed(self.suite, index), options=self.reset_options(index)
            )
        except NoVisibleTargetError as e:
            if self.suite.dataset is None:
                raise  # the library's own objects: that is beo-bench's to fix
            raise UserDataError(
                f"item {index} of {self.suite.name}: {e}; with --objects, objects this small "
                "are usually in other units than detected: give --units or --size METRES"
            ) from e
        return obs

    def reset_options(self, index: int) -> dict[str, Any] | None:
        """The env's reset options of item ``index``: none, the scene is the seed's (the
        pick suite asks for its episodes' target classes: :class:`~.pick.PickItems`)."""
        return None

    def scene_views(self, obs: dict[str, Any]) -> list[View]:
        """The scored views of the scene ``obs`` shows: every object with ``min_pixels``."""
        env = self.env
        cats = env.categories
        labels = [g.label for g in env.ground_truth() if g.pixels >= self.suite.min_pixels]
        return [View.from_observation(obs, label, cats) for label in labels]

    def scene_truths(self, views: list[View]) -> list[GroundTruth]:
        """The truth of each view of the env's current scene."""
        env = self.env
        by_label = {g.label: g for g in env.ground_truth()}
        cats = env.categories
        out = []
        for v in views:
            g = by_label[view_label(v)]
            out.append(GroundTruth.of(g, cats, g.R_cam, g.t_cam))
        return out

    def views(self, index: int) -> list[View]:
        return self.scene_views(self.reset(index))

    def truths(self, index: int, views: list[View]) -> list[GroundTruth]:
        """(The env must still hold item ``index``'s episode.)"""
        return self.scene_truths(views)

    def truth_of(self, index: int, view: View) -> GroundTruth:
        return self.scene_truths([view])[0]

    def templates(self, index: int) -> Rows:
        return self.base_rows(index, self.views(index))


def primary_metric(suite: Suite) -> str:
    """The class accuracy: in a scene the target is chosen by class before any pose counts
    (the isolated suites gate the pose)."""
    return "class_acc"


TABLETOP = ItemKind(Kind.TABLETOP, categories, SceneItems, primary_metric=primary_metric)
"""Tabletop items: each visible object's view scored on its estimate."""
