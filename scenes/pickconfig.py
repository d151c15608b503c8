"""``PickConfig``: BEOPick-v0's settings, checked once.

One frozen record holds what ``gym.make("BEOPick-v0", ...)`` takes (docs/env.md,
"Arguments"), and the env (``BEOPickEnv``),
:class:`~beo_bench.scenes.tabletop.TabletopScenes` and the bench's tabletop and pick items
are all made from it. It is checked when it is made: a bad setting is an
:class:`~beo_bench.errors.EnvConfigError` saying what to change, so nothing made from a
config checks it again. It lives below the envs (docs/design.md "Layers") because the
scenes are made from it too.
"""

from __future__ import annotations

import math
import numbers
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench.errors import EnvConfigError
from beo_bench.objects import ObjectSet, pickable_categories
from beo_bench.scenes.builder import TableConfig
from beo_bench.scenes.camera import CameraRig, Intrinsics
from beo_bench.scenes.renderer import UINT8_LABELS
from beo_bench.scenes.sensors import SENSORS, SensorError, check_sensor_name, make_sensor

if TYPE_CHECKING:
    from beo_bench.scenes.sensors import Sensor

OBS_MODES = ("image", "pointcloud")
"""The observation modes: ``image`` (depth + segmentation images) and ``pointcloud``
(segmented camera-frame points sampled from the depth image)."""

RENDER_MODES = ("rgb_array", "depth_array")
"""``render_mode`` values besides None. There is no ``human`` mode: the env is made for
headless machines, and gymnasium's pygame window wrapper fails there at the first reset."""

DEFAULT_NUM_POINTS = 4096
"""Points per observation in ``obs_mode="pointcloud"`` when ``num_points`` is not given
(ManiSkill's and PointNet's usual size)."""

MAX_NUM_POINTS = 2**20
"""The most points an observation may hold (``num_points``; 1,048,576): 16 MiB of float32
points and labels per observation, and every pixel of a 1024 x 1024 image. Points beyond an
image's pixel count only repeat pixels (see ``BEOPickEnv._sample_points``), so more adds no
information, while ``num_points=10**9`` took 22 GB at the first ``reset`` and was killed
for memory; a fixed cap rather than the pixel count keeps the bound the same at every image
size."""

MIN_TARGET_PIXELS_640x480 = 50
"""Default least number of target pixels at 640x480 (the suites' ``min_pixels``: a
scored view needs at least as many), scaled by image area for other sizes."""


def default_categories() -> tuple[str, ...]:
    """BEOPick-v0's default ``categories`` (the ``target_class`` list, and the class list
    its scenes' views carry): every registered category meant to be picked, sorted
    (:func:`beo_bench.objects.pickable_categories`)."""
    return pickable_categories()


def default_min_target_pixels(intrinsics: Intrinsics) -> int:
    """:data:`MIN_TARGET_PIXELS_640x480` scaled by the image area (at least 1)."""
    area = intrinsics.width * intrinsics.height / (640 * 480)
    return max(1, round(MIN_TARGET_PIXELS_640x480 * area))


@dataclass(frozen=True)
class PickConfig:
    """BEOPick-v0's settings (docs/env.md "Arguments"), checked when made.

    The fields take what ``gym.make`` takes and hold it in one form: ``num_objects`` a
    count or a (min, max) pair (held as the pair), ``categories`` a list of names (held as
    a tuple), ``image_size`` any two whole numbers, ``camera`` a ``CameraRig`` or a dict of
    its fields (held as the rig), ``table`` None for the default ``TableConfig``. What the
    settings imply is worked out here once: :attr:`object_set`, :attr:`classes` (what
    ``target_class`` indexes), :attr:`intrinsics`, :attr:`target_pixels`, :attr:`points`.
    """

    split: str = "test"
    """Object split: "train", "val" or "test" (ignored when ``objects`` is given)."""
    num_objects: tuple[int, int] = (1, 4)
    """(min, max) objects per scene, of distinct categories."""
    categories: tuple[str, ...] | None = None
    """Category names to draw from, in ``target_class`` order; None: every pickable one
    (or, with ``objects``, the set's)."""
    objects: ObjectSet | None = None
    """An object set to draw from instead of the library's ``split`` (e.g. a dataset's)."""
    image_size: tuple[int, int] = (640, 480)
    """(width, height) in pixels."""
    fovy_deg: float = 45.0
    """Vertical field of view, degrees."""
    camera: CameraRig = field(default_factory=CameraRig)
    """Where cameras are sampled (around the table top's centre)."""
    sensor: str = "ideal"
    """The depth sensor's name (docs/sensors.md)."""
    render_mode: str | None = None
    """None, "rgb_array" or "depth_array"."""
    table: TableConfig = field(default_factory=TableConfig)
    """The physical set-up."""
    min_target_pixels: int | None = None
    """The least visible pixels of the target; None: 50 at 640x480, scaled with the area."""
    obs_mode: str = "image"
    """"image" or "pointcloud"."""
    num_points: int | None = None
    """Points per observation (pointcloud mode only); None: :data:`DEFAULT_NUM_POINTS`."""
    cache_root: Path | None = None
    """The asset cache the library's objects are kept in (ignored when ``objects`` is given:
    its instances name theirs); None: ``$BEO_BENCH_CACHE``, read at each use."""

    # what the settings imply, worked out by __post_init__ (not arguments)
    object_set: ObjectSet = field(init=False, repr=False, compare=False)
    """The objects drawn from: ``objects``, or the library's ``split`` of ``categories``."""
    classes: tuple[str, ...] = field(init=False, repr=False, compare=False)
    """The categories drawn from, in ``target_class`` order."""
    intrinsics: Intrinsics = field(init=False, repr=False, compare=False)
    """The depth camera of ``image_size`` and ``fovy_deg``."""

    def __post_init__(self) -> None:
        # every check of BEOPick-v0's settings, in the order gym.make meets them
        if self.render_mode is not None and self.render_mode not in RENDER_MODES:
            raise EnvConfigError(
                f"render_mode={self.render_mode!r}: use None, 'rgb_array' or 'depth_array' "
                "(there is no window on a headless machine: save 'rgb_array' frames instead)"
            )
        categories = None if self.categories is None else _category_names(self.categories)
        try:
            objects = (
                self.objects
                if self.objects is not None
                else ObjectSet(self.split, categories, cache_root=self.cache_root)
            )
        except Exception as e:  # unknown split or category: say so at make time
            raise EnvConfigError(f"BEOPick-v0: {e}") from e
        if categories is not None:
            classes = categories
        else:
            classes = objects.categories if self.objects is not None else default_categories()
        missing = [c for c in classes if c not in objects.categories]
        if missing:
            raise EnvConfigError(
                f"categories {missing} are not in the object set "
                f"{list(objects.categories)}; choose among those"
            )
        lo, hi = _count_range(self.num_objects)
        if not 1 <= lo <= hi:
            raise EnvConfigError(
                f"num_objects={self.num_objects}: give a count >= 1 or a range (min, max) with "
                "1 <= min <= max"
            )
        if hi > len(classes):
            raise EnvConfigError(
                f"num_objects={self.num_objects}: scenes hold objects of distinct categories, "
                f"and only {len(classes)} categories are available ({list(classes)}); lower "
                "num_objects"
            )
        width, height = _image_size(self.image_size)
        try:
            intrinsics = Intrinsics(width, height, float(self.fovy_deg))
        except (TypeError, ValueError) as e:
            raise EnvConfigError(
                f"image_size={self.image_size}, fovy_deg={self.fovy_deg}: {e}"
            ) from e
        camera: Any = self.camera
        try:
            rig = camera if isinstance(camera, CameraRig) else CameraRig(**(camera or {}))
        except (TypeError, ValueError) as e:
            raise EnvConfigError(f"camera={camera}: {e}") from e
        if not isinstance(self.sensor, str):
            raise EnvConfigError(
                f"sensor={self.sensor!r}: give a sensor's name, one of {', '.join(SENSORS)}"
            )
        try:
            check_sensor_name(self.sensor)
        except SensorError as e:
            raise EnvConfigError(f"BEOPick-v0: {e}") from e
        min_pixels = self.min_target_pixels
        if min_pixels is not None and _whole(min_pixels, "min_target_pixels") < 1:
            raise EnvConfigError(
                f"min_target_pixels={min_pixels}: give at least 1 (an episode needs a "
                "visible target)"
            )
        if self.obs_mode not in OBS_MODES:
            raise EnvConfigError(f"obs_mode={self.obs_mode!r}: use 'image' or 'pointcloud'")
        n = self.num_points
        if n is not None and self.obs_mode != "pointcloud":
            raise EnvConfigError(
                f"num_points={n} only applies to obs_mode='pointcloud'; pass "
                "obs_mode='pointcloud' or drop num_points"
            )
        if n is not None and _whole(n, "num_points") < 1:
            raise EnvConfigError(f"num_points={n}: give at least 1 point")
        if n is not None and int(n) > MAX_NUM_POINTS:
            raise EnvConfigError(
                f"num_points={n}: give at most {MAX_NUM_POINTS:,} points (MAX_NUM_POINTS, "
                "2**20: more only repeats pixels and would exhaust memory at reset)"
            )
        # each field in its one form (object.__setattr__: the record is frozen)
        held = {
            "categories": categories,
            "num_objects": (lo, hi),
            "image_size": (width, height),
            "fovy_deg": float(self.fovy_deg),
            "camera": rig,
            "table": self.table if self.table is not None else TableConfig(),
            "min_target_pixels": None if min_pixels is None else int(min_pixels),
            "num_points": None if n is None else int(n),
            "object_set": objects,
            "classes": classes,
            "intrinsics": intrinsics,
        }
        for name, value in held.items():
            object.__setattr__(self, name, value)

    @property
    def max_objects(self) -> int:
        """The most objects a scene holds (segmentation labels 1..max_objects)."""
        return self.num_objects[1]

    @property
    def target_pixels(self) -> int:
        """``min_target_pixels``, or its default for the image size."""
        if self.min_target_pixels is not None:
            return self.min_target_pixels
        return default_min_target_pixels(self.intrinsics)

    @property
    def points(self) -> int:
        """``num_points``, or :data:`DEFAULT_NUM_POINTS`."""
        return DEFAULT_NUM_POINTS if self.num_points is None else self.num_points

    @property
    def seg_dtype(self) -> np.dtype[Any]:
        """The segmentation's dtype: labels 0..k in one byte per pixel while they fit, as
        the renderer gives them (a 640x480 observation 2.46 -> 1.54 MB)."""
        return np.dtype(np.uint8 if self.max_objects <= UINT8_LABELS else np.int32)

    def make_sensor(self) -> Sensor:
        """A new depth sensor of this config (sensors hold scratch arrays: one each env).
        A sensor that cannot serve the image size is an :class:`EnvConfigError`."""
        try:
            return make_sensor(self.sensor, self.intrinsics)
        except SensorError as e:
            raise EnvConfigError(f"BEOPick-v0: {e}") from e


def _whole(value: Any, what: str) -> int:
    """``value`` as an int when it is a whole number (an int, or a float without fraction);
    strings are refused too, since ``int("3")`` would hide a setting of the wrong type."""
    real = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if not real or not math.isfinite(value) or float(value) != int(value):
        raise EnvConfigError(f"{what}={value!r}: give a whole number")
    return int(value)


def _count_range(num_objects: Any) -> tuple[int, int]:
    """(min, max) of a ``num_objects`` given as a count or a (min, max) pair."""
    if isinstance(num_objects, numbers.Real) and not isinstance(num_objects, bool):
        n = _whole(num_objects, "num_objects")
        return n, n
    if isinstance(num_objects, np.ndarray):
        num_objects = num_objects.tolist()  # a 0-d array becomes a scalar, refused below
    if isinstance(num_objects, (tuple, list)) and len(num_objects) == 2:
        lo, hi = num_objects
        return _whole(lo, "num_objects"), _whole(hi, "num_objects")
    raise EnvConfigError(
        f"num_objects={num_objects!r}: give a count such as 2 or a range (min, max) such as (1, 4)"
    )


def _image_size(image_size: Any) -> tuple[int, int]:
    """(width, height) of an ``image_size``; a string is refused ("640" would otherwise
    unpack digit by digit)."""
    if isinstance(image_size, np.ndarray):
        image_size = image_size.tolist()
    if not isinstance(image_size, (tuple, list)) or len(image_size) != 2:
        raise EnvConfigError(
            f"image_size={image_size!r}: give (width, height) in pixels as two whole numbers, "
            "e.g. (640, 480)"
        )
    width, height = image_size
    return _whole(width, "image_size width"), _whole(height, "image_size height")


def _category_names(categories: Any) -> tuple[str, ...]:
    """The ``categories`` setting as a tuple of names, each once: ``target_class`` indexes
    this list, so a repeated name would make two labels mean one class."""
    if isinstance(categories, str) or not isinstance(categories, (tuple, list)):
        raise EnvConfigError(
            f"categories={categories!r}: give a list of category names, e.g. ['mug', 'bowl']"
        )
    if not all(isinstance(c, str) for c in categories):
        raise EnvConfigError(f"categories={categories!r}: every entry must be a category name")
    repeated = sorted(c for c, n in Counter(categories).items() if n > 1)
    if repeated:
        raise EnvConfigError(
            f"categories lists {repeated} more than once: give each category once (the "
            "target_class is an index into this list)"
        )
    return tuple(categories)
