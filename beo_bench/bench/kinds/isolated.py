"""Isolated items: one object at the origin in its canonical frame, viewed from the object
rig; one scored view per item (the ``known-pose``, ``pose-1dof`` and ``pose-3dof`` suites)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from beo_bench.bench.kinds.common import ItemKind, Items, Rows
from beo_bench.bench.suites import Kind, Protocol, Suite, item_rng
from beo_bench.geometry import rigid
from beo_bench.objects import ObjectSet
from beo_bench.objects.datasets import object_set
from beo_bench.types import GroundTruth, View, ViewpointPrior

WORLD_OFFSET_M = 1.0
"""Half the side of the cube an isolated view's world origin is drawn from (m): larger than
the rig's camera distance (0.45-0.8 m), so the camera's world position hides the object's."""


def categories(suite: Suite) -> tuple[str, ...]:
    """The class list the views carry: the suite's objects' classes."""
    return object_set(suite.dataset, suite.split, suite.categories).categories


def rig(suite: Suite) -> Any:
    """The camera rig of the suite's viewpoint (``Suite.viewpoint``)."""
    from beo_bench.scenes.camera import OBJECT_RIG, TOP_DOWN_RIG

    return TOP_DOWN_RIG if suite.viewpoint == "top-down" else OBJECT_RIG


def world_frame(rng: np.random.Generator, protocol: Protocol) -> np.ndarray:
    """A random rigid world frame for an isolated view (4x4, applied on the left of the
    rig's ``cam_to_world``): a yaw about +z where the protocol keeps up up (1-DOF, which
    reveals it), a uniformly random rotation otherwise; and a translation uniform in a 2 m
    cube, so the camera's position says nothing about where the object is."""
    if protocol.world_frame == "random-yaw":
        yaw = rng.uniform(0.0, 2 * np.pi)
        Q = Rotation.from_rotvec([0.0, 0.0, yaw]).as_matrix()
    else:
        Q = Rotation.random(random_state=rng).as_matrix()
    return rigid(Q, rng.uniform(-WORLD_OFFSET_M, WORLD_OFFSET_M, 3))


class IsolatedItems(Items):
    """The suite's isolated views, rendered with one reused renderer."""

    def __init__(
        self, suite: Suite, class_given: bool = False, cache_root: Path | None = None
    ) -> None:
        super().__init__(suite, class_given, cache_root)
        self._renderer: Any = None
        self._objects_: ObjectSet | None = None

    @property
    def renderer(self) -> Any:
        """The renderer (made on first use: a driver that only writes failed rows of a
        scene suite never makes one)."""
        if self._renderer is None:
            from beo_bench.scenes.camera import Intrinsics
            from beo_bench.scenes.isolated import IsolatedRenderer

            w, h = self.suite.image_size
            self._renderer = IsolatedRenderer(
                Intrinsics(w, h, self.suite.fovy_deg),
                rig=rig(self.suite),
                sensor=self.suite.sensor,
            )
        return self._renderer

    @property
    def _objects(self) -> ObjectSet:
        if self._objects_ is None:
            s = self.suite
            self._objects_ = object_set(
                s.dataset, s.split, s.categories, cache_root=self.cache_root
            )
        return self._objects_

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def _draw(self, index: int) -> tuple[np.random.Generator, Any, np.ndarray]:
        """Item ``index``'s instance and camera pose (``cam_to_world`` with the object at the
        origin in its canonical frame), with the generator left where they were drawn."""
        rng = item_rng(self.suite, index)
        cats = self._objects.categories
        cat = cats[index % len(cats)]  # classes balanced over items
        inst = self._objects.get(cat, int(rng.integers(self._objects.count(cat))))
        return rng, inst, self.renderer.rig.sample(rng, np.zeros(3))

    def scene(self, index: int) -> tuple[Any, np.ndarray]:
        """Item ``index``'s instance and its camera's ``cam_to_world`` in the object's frame
        (the object at the origin, as the renderer places it): what a BOP export renders
        its colour image and silhouette from."""
        _, inst, T = self._draw(index)
        return inst, T

    def isolated_view_only(self, index: int) -> View:
        """The view of item ``index``: exactly what its protocol reveals."""
        protocol = self.suite.protocol
        rng, inst, T = self._draw(index)
        # The world frame is a random rigid frame, so cam_to_world tells a backend no more
        # than the protocol does: up (1-DOF) or nothing (3-DOF, known-pose), and never where
        # the object is (the renderer puts it at the origin). It is drawn before the sensor
        # draws its noise, so an item's instance, camera and world frame are the same
        # under every sensor (the ideal sensor draws nothing: its items are as they were).
        frame = world_frame(rng, protocol)
        iv = self.renderer.render(inst, T, rng=rng)
        cam_to_world = frame @ iv.cam_to_world
        return View(
            # the rig's viewpoint distribution is part of the protocol (a pose prior any
            # backend may use); it reveals nothing about this view's pose
            viewpoint_prior=ViewpointPrior.of_rig(self.renderer.rig),
            depth=iv.depth,
            mask=iv.mask,
            K=iv.K,
            cam_to_world=cam_to_world,
            categories=self._objects.categories,
            up_hint=iv.R_cam[:, 2].copy() if protocol.up_hint else None,
            pose_hint=(iv.R_cam, iv.t_cam, np.asarray(inst.size, dtype=np.float64))
            if protocol.pose_hint
            else None,
        )

    def isolated_truth(self, index: int) -> GroundTruth:
        """The truth about item ``index``, drawn again without rendering: the renderer's
        object sits at the origin in its canonical frame, so its pose in the camera is the
        inverse of the rig's ``cam_to_world``."""
        _, inst, T = self._draw(index)
        inv = np.linalg.inv(T)
        return GroundTruth.of(inst, self._objects.categories, inv[:3, :3], inv[:3, 3])

    def isolated_view(self, index: int) -> tuple[View, GroundTruth]:
        """Item ``index``'s view and its truth (for tests, recordings and benchmarks; the
        evaluator itself asks for the truth only after the backend has answered)."""
        return self.isolated_view_only(index), self.isolated_truth(index)

    def views(self, index: int) -> list[View]:
        return [self.isolated_view_only(index)]

    def truths(self, index: int, views: list[View]) -> list[GroundTruth]:
        return [self.isolated_truth(index)]

    def truth_of(self, index: int, view: View) -> GroundTruth:
        return self.isolated_truth(index)

    def templates(self, index: int) -> Rows:
        return self.base_rows(index, self.views(index))


ISOLATED = ItemKind(Kind.ISOLATED, categories, IsolatedItems)
"""Isolated items: each view scored on its estimate (the defaults of :class:`ItemKind`)."""
