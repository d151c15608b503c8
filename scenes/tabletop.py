"""BEOPick-v0's tabletop scenes, without the env: draw, settle, look, render.

:class:`TabletopScenes` is what ``BEOPickEnv.reset`` runs (docs/design.md "Environments"):
1-k objects of distinct categories placed on the table in their rest poses with a random
yaw (:mod:`.layout`), compiled (:mod:`.builder`), settled by physics (:mod:`.execute`) and
seen by one depth camera sampled around the table (:mod:`.camera`), the target drawn among
the placed objects and guaranteed to show at least ``min_target_pixels`` pixels. The env
delegates to it; code below the envs (HBEO's training crops, ``beo_bench.perception``)
uses it directly, since backends never import envs.

One generator drives every draw, in the order the env always made them, so a seed gives
the same scene, camera, target and image here as in ``BEOPickEnv.reset(seed=...)``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench.errors import BeoBenchError
from beo_bench.scenes.builder import Scene, build_tabletop
from beo_bench.scenes.execute import park, settle
from beo_bench.scenes.layout import ObjectTooLargeError, PlacementError, place_objects
from beo_bench.scenes.renderer import Frame, Renderer
from beo_bench.types import Mat4, ObjectState

if TYPE_CHECKING:
    from beo_bench.scenes.pickconfig import PickConfig
    from beo_bench.scenes.sensors import Sensor

SCENE_DRAWS = 20
"""Object draws a reset tries before giving up (placement failures and scenes whose
target stays hidden both count)."""

CAMERA_DRAWS = 10
"""Camera poses a reset tries per scene for a visible target before drawing a new scene
(a target hidden behind a larger object is usually seen from another side)."""


class NoVisibleTargetError(BeoBenchError, RuntimeError):
    """``reset`` found no scene whose target shows at least ``min_target_pixels`` pixels:
    an episode without a visible target cannot be solved, so none is produced."""


class TabletopScenes:
    """Tabletop scenes drawn as BEOPick-v0 draws them (``config``: its settings; the
    env's own), and the current one.

    :meth:`reset` draws a new scene and returns its observation and ground truth (the env's
    ``obs_mode="image"`` observation without sensor noise, and ``env.ground_truth()``);
    :meth:`draw` is the same from a caller's generator. The current scene stays for physics
    and more renders (``scene``, ``cam``, ``target``, :meth:`render`, :meth:`render_rgb`)
    until the next draw. The renderer's GL context is made on the first render and freed by
    :meth:`close`; a later draw makes a new one.
    """

    def __init__(self, config: PickConfig) -> None:
        self.config = config  # checked when it was made
        # the current scene: what was drawn (category, index) and placed where, the camera
        # and the target's label
        self.scene: Scene | None = None
        self.drawn: tuple[list[tuple[str, int]], list[Mat4]] | None = None
        self.cam: Mat4 = np.eye(4)
        self.target = 0
        self.renderer: Renderer | None = None
        self._bound: Scene | None = None  # the scene the renderer holds
        self._rng: np.random.Generator | None = None

    # -- drawing ---------------------------------------------------------------------------------
    def reset(
        self, seed: int | None = None, target_category: str | None = None
    ) -> tuple[dict[str, Any], list[ObjectState]]:
        """A new scene: its observation (``depth``, ``segmentation``, ``target_class``,
        ``intrinsics``, ``cam_to_world``, as BEOPick-v0's without noise) and every object's
        ground truth. ``seed`` starts the generator anew (the env's ``reset(seed=...)``
        gives the same scene); without it the draws continue from the last reset's.
        ``target_category``: the class the target must be (:meth:`draw`)."""
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)  # gymnasium's seeding, bit for bit
        frame, _ = self.draw(self._rng, target_category)
        obs = self.observation(frame)
        return obs, self.ground_truth(obs["segmentation"])

    def draw(
        self, rng: np.random.Generator, target_category: str | None = None
    ) -> tuple[Frame, int]:
        """Draw a scene from ``rng`` (objects, placement, camera, target) and make it the
        current one; returns its rendering and the target's visible pixels.

        ``target_category`` (one of ``categories``; the env's ``reset(options={"target_class":
        ...})``): every scene drawn holds an object of that class, and it is the target.
        The scene is then drawn from the unrequested draw's distribution given that target
        class: as many objects, the others a uniform choice among the remaining classes, the
        target's label uniform among them. None draws exactly as before the option existed
        (the same seed, the same scene, bit for bit).

        Raises :class:`NoVisibleTargetError` when no scene and camera of
        :data:`SCENE_DRAWS` x :data:`CAMERA_DRAWS` shows ``min_target_pixels`` of the
        target, :class:`~beo_bench.scenes.layout.PlacementError` when no draw fit on the
        table and :class:`~beo_bench.scenes.layout.ObjectTooLargeError` for an object too
        large for the table."""
        cfg = self.config
        if target_category is not None and target_category not in cfg.classes:
            raise ValueError(
                f"target category {target_category!r} is not among the classes drawn from; "
                f"choose one of {list(cfg.classes)}"
            )
        placed, best = 0, (-1, "")
        look_at = np.array([0.0, 0.0, cfg.table.table_height])
        # Draws happen in the order they always did, so a seed whose first scene and camera
        # show the target gives the episode it gave before the visibility guarantee.
        for _ in range(SCENE_DRAWS):
            k = int(rng.integers(cfg.num_objects[0], cfg.num_objects[1] + 1))
            if target_category is None:
                cats = [cfg.classes[j] for j in rng.choice(len(cfg.classes), k, replace=False)]
            else:
                cats = self._with_target(rng, k, target_category)
            drawn = [(c, int(rng.integers(cfg.object_set.count(c)))) for c in cats]
            insts = [cfg.object_set.get(c, i) for c, i in drawn]
            try:
                poses = place_objects(
                    insts,
                    rng,
                    cfg.table.table_height,
                    cfg.table.area_half,
                    table_half=cfg.table.table_half,
                )
            except ObjectTooLargeError:
                raise  # no other draw makes this object fit: say which one it is
            except PlacementError:
                continue  # these did not fit: draw another set (deterministic under the seed)
            placed += 1
            self.scene = build_tabletop(insts, poses, cfg.intrinsics, cfg.table)
            self.drawn = (drawn, [np.array(T, dtype=np.float64) for T in poses])
            park(self.scene)
            settle(self.scene)
            self.cam = cfg.camera.sample(rng, look_at)
            if target_category is None:
                self.target = int(rng.integers(k)) + 1
            else:  # the requested class is the target: nothing to draw
                self.target = cats.index(target_category) + 1
            for view in range(CAMERA_DRAWS):
                if view:
                    self.cam = cfg.camera.sample(rng, look_at)
                frame = self.render()
                pixels = int(np.count_nonzero(frame.segmentation == self.target))
                if pixels >= cfg.target_pixels:
                    break
                if pixels > best[0]:
                    best = (pixels, f"{cats[self.target - 1]} among {cats}")
            else:
                continue  # hidden from every camera pose: draw another scene
            break
        else:
            if not placed:
                raise PlacementError(
                    f"{SCENE_DRAWS} draws of objects did not fit on the table without overlap; "
                    "use fewer objects (num_objects) or a larger TableConfig.area_half"
                )
            raise NoVisibleTargetError(
                f"BEOPick-v0 reset: in {placed} scenes x {CAMERA_DRAWS} camera poses the target "
                f"never showed {cfg.target_pixels} pixels (best {best[0]}: {best[1]}); "
                f"lower min_target_pixels, use a larger image_size, or a camera rig that "
                f"frames the table (camera=...)"
            )
        return frame, pixels

    def _with_target(self, rng: np.random.Generator, k: int, target: str) -> list[str]:
        """``k`` distinct classes, ``target`` among them at a uniform position (its label),
        the others a uniform choice of the remaining classes in a uniform order: the
        unrequested draw's classes given that its target is of class ``target`` (there, the
        target's class is uniform whatever k, so k keeps its own distribution)."""
        others = [c for c in self.config.classes if c != target]
        cats = [others[j] for j in rng.choice(len(others), k - 1, replace=False)]
        cats.insert(int(rng.integers(k)), target)
        return cats

    def restore(
        self, drawn: list[tuple[str, int]], poses: list[Mat4], cam: Mat4, target: int
    ) -> Scene:
        """Make the scene of an earlier draw current again (a copy of an env): ``drawn``
        (category, index) placed at ``poses``, seen from ``cam``, target label ``target``.
        Returns the newly compiled scene, at rest where it was placed (not settled)."""
        insts = [self.config.object_set.get(c, i) for c, i in drawn]
        self.scene = build_tabletop(insts, poses, self.config.intrinsics, self.config.table)
        self.drawn = (drawn, poses)
        self.cam = cam
        self.target = target
        return self.scene

    # -- looking ---------------------------------------------------------------------------------
    def _bound_renderer(self) -> Renderer:
        """The renderer, (re)created when there is none (first render, after ``close``) and
        bound to the current scene."""
        assert self.scene is not None
        if self.renderer is None:
            self.renderer = Renderer(self.config.intrinsics)
            self._bound = None
        if self._bound is not self.scene:
            self.renderer.bind(self.scene.model, self.scene.geom_labels)
            self._bound = self.scene
        return self.renderer

    def render(self) -> Frame:
        """Depth and segmentation of the current scene from ``cam``."""
        assert self.scene is not None
        return self._bound_renderer().render(self.scene.data, self.cam)

    def capture(
        self, sensor: Sensor, rng: np.random.Generator, frame: Frame | None = None
    ) -> Frame:
        """What ``sensor`` (made for ``intrinsics``) returns of the current scene from
        ``cam``, its noise drawn from ``rng``; ``frame``: the scene's ideal rendering from
        ``cam`` when the caller has it (:meth:`draw` returns it), so it is not rendered
        again. The segmentation stays the ideal one (docs/sensors.md)."""
        assert self.scene is not None
        return sensor.capture(self._bound_renderer(), self.scene.data, self.cam, rng, frame)

    def render_rgb(self) -> np.ndarray:
        """(H, W, 3) uint8 colour image of the current scene from ``cam``."""
        assert self.scene is not None
        return self._bound_renderer().render_rgb(self.scene.data, self.cam)

    @property
    def target_class(self) -> int:
        """The target's index in ``categories``."""
        assert self.scene is not None
        return int(self.config.classes.index(self.scene.instances[self.target - 1].category))

    def observation(self, frame: Frame) -> dict[str, Any]:
        """The current scene's observation from its rendering ``frame``: ``depth``,
        ``segmentation`` (``seg_dtype``), ``target_class``, ``intrinsics`` and
        ``cam_to_world`` (BEOPick-v0's ``obs_mode="image"`` layout)."""
        return {
            "depth": frame.depth,
            # the renderer may already give uint8 labels: then this is no copy
            "segmentation": frame.segmentation.astype(self.config.seg_dtype, copy=False),
            "target_class": self.target_class,
            "intrinsics": self.config.intrinsics.K,
            "cam_to_world": self.cam.copy(),
        }

    def ground_truth(self, segmentation: np.ndarray) -> list[ObjectState]:
        """Per object of the current scene: label, category, key, symmetry, size, pose in
        camera and world frames, and its pixels in ``segmentation`` (the current view's)."""
        assert self.scene is not None
        world_to_cam = np.linalg.inv(self.cam)
        counts = np.bincount(segmentation.ravel(), minlength=len(self.scene.instances) + 1)
        out = []
        for i, inst in enumerate(self.scene.instances):
            Tw = self.scene.object_pose(i)
            Tc = world_to_cam @ Tw
            out.append(
                ObjectState(
                    label=i + 1,
                    category=inst.category,
                    key=inst.key,
                    symmetry=inst.symmetry,
                    size=np.asarray(inst.size, dtype=np.float64),
                    R_cam=Tc[:3, :3].copy(),
                    t_cam=Tc[:3, 3].copy(),
                    R_world=Tw[:3, :3].copy(),
                    t_world=Tw[:3, 3].copy(),
                    pixels=int(counts[i + 1]),
                )
            )
        return out

    def close(self) -> None:
        """Free the renderer (its GL context) and forget the current scene. Not final: a
        later draw starts again with a new renderer."""
        if self.renderer is not None:
            self.renderer.close()
            self.renderer = None
        self._bound = None
        self.scene = None
        self.drawn = None
