"""Render an isolated instance from a camera pose: the small scenes API that training-set
rendering and the perception suites use without going through the env.

The object sits at the world origin in its canonical frame, so its pose in the camera frame
is simply the inverse of ``cam_to_world``. A compiled model per instance is kept (LRU) so
that many views of one instance cost one render each.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from beo_bench.objects.instance import ObjectInstance
from beo_bench.scenes.builder import build_isolated
from beo_bench.scenes.camera import OBJECT_RIG, CameraRig, Intrinsics
from beo_bench.scenes.noise import DepthNoise, apply_noise
from beo_bench.scenes.renderer import Renderer
from beo_bench.types import Mat3, Mat4, Vec3, View, ViewpointPrior

if TYPE_CHECKING:
    from beo_bench.scenes.sensors import Sensor


@dataclass
class IsolatedView:
    """One view of an isolated instance.

    ``depth``: (H, W) float32 metric z-depth, 0 = no surface; ``mask``: (H, W) bool, the
    object's pixels; ``K``: OpenCV intrinsics; ``cam_to_world``: 4x4, OpenCV camera axes;
    ``R_cam``, ``t_cam``: the object's canonical frame in the camera frame (ground truth);
    ``viewpoint_prior``: the distribution the camera pose was drawn from when the renderer's
    rig drew it (``IsolatedRenderer.sample_views``), None for a pose the caller chose.
    A perception backend takes :meth:`to_view`.
    """

    depth: np.ndarray
    mask: np.ndarray
    K: Mat3
    cam_to_world: Mat4
    R_cam: Mat3
    t_cam: Vec3
    key: str
    category: str
    viewpoint_prior: ViewpointPrior | None = None

    def to_view(self, categories: Sequence[str] | None = None) -> View:
        """What a perception backend's ``predict`` takes: the fields an isolated suite gives
        (depth, mask, ``K``, ``cam_to_world``, the class list and, for rig-drawn views, the
        viewpoint prior) and no truth field. ``categories``: the classes the
        estimate's ``class_probs`` index, default the built-in library's
        (``beo_bench.objects.categories()``); they must include this instance's category.
        Suites' protocol hints are left out (``dataclasses.replace(view, class_hint=...,
        up_hint=...)`` adds them). ``cam_to_world`` is the render's own, with the object
        at the origin in its canonical frame, so it gives the pose away: the suites replace
        it by a random rigid frame (``beo_bench.bench.kinds.isolated.world_frame``). Raises
        :class:`~beo_bench.errors.ViewError` for a class list without the instance's
        category."""
        from beo_bench.errors import ViewError

        if categories is None:
            from beo_bench.objects import categories as library_categories

            cats = library_categories()
        elif isinstance(categories, str):
            raise ViewError(
                f"categories={categories!r} is one string: give a sequence of class names"
            )
        else:
            cats = tuple(categories)
        if self.category not in cats:
            raise ViewError(
                f"this view shows a {self.category!r}, which is not among categories {cats}: "
                "pass the class list it belongs to (e.g. a dataset's categories)"
            )
        return View(
            depth=self.depth,
            mask=self.mask,
            K=self.K,
            cam_to_world=self.cam_to_world,
            categories=cats,
            viewpoint_prior=self.viewpoint_prior,
        )


class IsolatedRenderer:
    """Renders views of isolated instances; reuse one for many views (it owns a GL
    context).

    ``sensor``: the depth sensor views are captured by (a name of
    ``beo_bench.scenes.sensors.SENSORS`` or a ``Sensor`` made for ``intrinsics``; default
    ``ideal``, the render as it is); :meth:`render` draws its noise from the generator
    given per call, and may name another sensor for one view. ``noise`` (a
    :class:`~beo_bench.scenes.noise.DepthNoise`) is HBEO's training augmentation, applied
    to the ideal render; it is no suite's sensor."""

    def __init__(
        self,
        intrinsics: Intrinsics | None = None,
        rig: CameraRig = OBJECT_RIG,
        cache_models: int = 8,
        sensor: str | Sensor | None = None,
    ) -> None:
        self.intrinsics = intrinsics or Intrinsics(128, 128, 45.0)
        self.rig = rig
        self._sensors: dict[str, Sensor] = {}
        self.sensor = self._sensor(sensor if sensor is not None else "ideal")
        self._renderer = Renderer(self.intrinsics, max_geom=1000)
        self._models: OrderedDict[str, tuple[Any, Any]] = OrderedDict()
        self._cache_models = cache_models
        self._bound: str | None = None
        self._K = self.intrinsics.K

    def _bind(self, instance: ObjectInstance) -> Any:
        key = instance.key
        if key in self._models:
            self._models.move_to_end(key)
        else:
            self._models[key] = build_isolated(instance, self.intrinsics)
            if len(self._models) > self._cache_models:
                old, _ = self._models.popitem(last=False)
                if old == self._bound:
                    self._bound = None
        model, data = self._models[key]
        if self._bound != key:
            labels = np.ones(model.ngeom, dtype=np.int32)
            self._renderer.bind(model, labels)
            self._bound = key
        return data

    def _sensor(self, sensor: str | Sensor) -> Sensor:
        """The sensor ``sensor`` names, made once per name for this renderer's image."""
        from beo_bench.scenes.sensors import Sensor, make_sensor

        if isinstance(sensor, Sensor):
            if sensor.shape != (self.intrinsics.height, self.intrinsics.width):
                raise ValueError(
                    f"sensor {sensor.name!r} was made for {sensor.shape[1]}x{sensor.shape[0]} "
                    f"images, this renderer's are {self.intrinsics.width}x"
                    f"{self.intrinsics.height}: make it with the renderer's intrinsics"
                )
            return sensor
        if sensor not in self._sensors:
            self._sensors[sensor] = make_sensor(sensor, self.intrinsics)
        return self._sensors[sensor]

    def render(
        self,
        instance: ObjectInstance,
        cam_to_world: Mat4,
        noise: DepthNoise | None = None,
        rng: np.random.Generator | None = None,
        sensor: str | Sensor | None = None,
    ) -> IsolatedView:
        """The view of ``instance`` from ``cam_to_world`` (OpenCV axes; the object is at the
        origin in its canonical frame), captured by ``sensor`` (default: the renderer's),
        which draws from ``rng`` (a sensor other than ``ideal`` needs one). ``noise``: HBEO's
        training augmentation on the ideal render instead (not with a sensor)."""
        data = self._bind(instance)
        T = np.asarray(cam_to_world, dtype=np.float64)
        frame = self._renderer.render(data, T)
        capture = self.sensor if sensor is None else self._sensor(sensor)
        if not capture.ideal:
            if noise is not None:
                raise ValueError(
                    "noise= (HBEO's DepthNoise augmentation) applies to the ideal render: "
                    f"not with sensor {capture.name!r}"
                )
            if rng is None:
                raise ValueError(
                    f"sensor {capture.name!r} draws its noise from rng: pass a generator"
                )
            frame = capture.capture(self._renderer, data, T, rng, frame)
        depth = frame.depth
        if noise is not None:
            depth = apply_noise(depth, rng if rng is not None else np.random.default_rng(0), noise)
        # float64 in, float64 out (numpy's stubs type the inverse as any floating dtype)
        inv = cast(Mat4, np.linalg.inv(T))
        return IsolatedView(
            depth=depth,
            mask=(frame.segmentation > 0) & (depth > 0),
            K=self._K.copy(),
            cam_to_world=T.copy(),
            R_cam=inv[:3, :3].copy(),
            t_cam=inv[:3, 3].copy(),
            key=instance.key,
            category=instance.category,
        )

    def render_rgb(self, instance: ObjectInstance, cam_to_world: Mat4) -> np.ndarray:
        """(H, W, 3) uint8 colour image of ``instance`` from ``cam_to_world`` (OpenCV axes):
        what a BOP export writes as the view's ``rgb`` (no backend sees it)."""
        data = self._bind(instance)
        return self._renderer.render_rgb(data, np.asarray(cam_to_world, dtype=np.float64))

    def sample_views(
        self, instance: ObjectInstance, rng: np.random.Generator, n: int
    ) -> list[IsolatedView]:
        """``n`` views from cameras sampled by this renderer's rig around the origin, each
        carrying the rig's ``viewpoint_prior``."""
        origin = np.zeros(3)
        prior = ViewpointPrior.of_rig(self.rig)
        return [
            replace(self.render(instance, self.rig.sample(rng, origin)), viewpoint_prior=prior)
            for _ in range(n)
        ]

    def close(self) -> None:
        """Free the GL context and the cached models."""
        self._renderer.close()
        self._models.clear()
        self._bound = None

    def __enter__(self) -> IsolatedRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def render_isolated(
    instance: ObjectInstance, cam_to_world: Mat4, intrinsics: Intrinsics | None = None
) -> IsolatedView:
    """One view with a throw-away renderer (convenient, slow: use IsolatedRenderer for
    many views)."""
    with IsolatedRenderer(intrinsics) as r:
        return r.render(instance, cam_to_world)
