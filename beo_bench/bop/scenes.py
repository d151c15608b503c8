"""BOP scenes: a scene's images (depth, RGB, masks) and its ground truth, written
(:class:`SceneWriter`) and read (:func:`read_scene`) from the format's documentation (the
BOP toolkit's ``docs/bop_datasets_format.md``; :mod:`beo_bench.bop.files` describes the
dataset root and its units).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from beo_bench import outdir
from beo_bench.bop.files import _id, _id_keyed, _json_text, _load_json, _Where, scene_path
from beo_bench.bop.store import (
    EMPTY_BBOX,
    SCENE_CAMERA_NAME,
    SCENE_GT_INFO_NAME,
    SCENE_GT_NAME,
    _store,
    _writable,
)
from beo_bench.errors import BopFormatError
from beo_bench.types import Mat3, Vec3

__all__ = [
    "BopImage",
    "BopScene",
    "GtInfo",
    "GtInstance",
    "SceneCamera",
    "SceneGt",
    "SceneWriter",
    "mask_bbox",
    "read_scene",
    "scene_ids",
]


_UINT16_MAX = 65535


# -- images -----------------------------------------------------------------------------------
def _write_png(path: Path, image: NDArray[Any]) -> None:
    ok, buf = cv2.imencode(".png", image)
    if not ok:  # pragma: no cover - OpenCV encodes any uint8/uint16 image
        raise ValueError(f"{path}: OpenCV could not encode the image")
    _store(path, buf.tobytes())


def _read_png(path: Path, flags: int) -> NDArray[Any]:
    try:
        data = np.frombuffer(path.read_bytes(), dtype=np.uint8)
    except FileNotFoundError:
        raise BopFormatError(f"{path}: image missing; export the scene again") from None
    except OSError as e:
        raise BopFormatError(f"{path}: cannot be read ({e}); export the scene again") from None
    image = cv2.imdecode(data, flags) if len(data) else None
    if image is None:
        raise BopFormatError(f"{path}: not a readable image; export the scene again")
    return image


def mask_bbox(mask: NDArray[Any]) -> tuple[int, int, int, int]:
    """``(x, y, width, height)`` of a mask's pixels as the toolkit's ``misc.calc_2d_bbox``
    computes it (width = max x - min x, so one pixel is 0 wide); ``(-1, -1, -1, -1)`` for
    an empty mask (``scripts/calc_gt_info.py``)."""
    ys, xs = np.nonzero(mask)
    if len(xs) == 0:
        return EMPTY_BBOX
    x0, y0 = int(xs.min()), int(ys.min())
    return (x0, y0, int(xs.max()) - x0, int(ys.max()) - y0)


def _matrix(R: NDArray[Any], name: str) -> Mat3:
    M = np.asarray(R, dtype=np.float64)
    if M.shape != (3, 3) or not np.isfinite(M).all():
        raise ValueError(f"{name} of shape {M.shape}: give a finite 3x3 matrix")
    return M


def _vector(t: NDArray[Any] | Sequence[float], name: str) -> Vec3:
    v = np.asarray(t, dtype=np.float64).reshape(-1)
    if v.shape != (3,) or not np.isfinite(v).all():
        raise ValueError(f"{name} of shape {v.shape}: give a finite 3-vector")
    return v


# -- scene writer -----------------------------------------------------------------------------
@dataclass(frozen=True)
class GtInstance:
    """One annotated object instance of an image, as :meth:`SceneWriter.add_image` takes it:
    the pose maps the model frame to the camera frame (OpenCV axes), in metres."""

    obj_id: int
    R_m2c: Mat3
    t_m2c_m: Vec3
    mask: NDArray[np.bool_]
    """(H, W) the full silhouette (occluded parts included) within the image."""
    mask_visib: NDArray[np.bool_]
    """(H, W) its visible part (a subset of ``mask``)."""
    px_count_all: int | None = None
    """The silhouette's pixel count including any part outside the image (the toolkit
    renders a larger image for it); None: the pixels of ``mask``."""


class SceneWriter:
    """Writes one scene folder ``ROOT/SPLIT/SCENE_ID`` of the BOP-scenewise format
    (``docs/bop_datasets_format.md``): per image ``rgb/IM_ID.png``, ``depth/IM_ID.png``
    (uint16, depth in mm = value x ``depth_scale``, 0 = no measurement),
    ``mask/IM_ID_GT_IDX.png`` and ``mask_visib/IM_ID_GT_IDX.png`` (0/255), and, when the
    scene is closed, ``scene_camera.json``, ``scene_gt.json`` and ``scene_gt_info.json``
    keyed by the image id as a string. ``depth_scale``: mm per depth unit (0.1 stores up
    to 6.5535 m in 0.1 mm steps; 1.0 up to 65.535 m in 1 mm steps). The root must have been
    claimed (:func:`claim_dataset_dir`). Images written earlier under the same names are
    replaced; the JSON files list what the scene holds. Use it as a context manager, or
    call :meth:`close`; an exception inside the ``with`` block leaves the JSON files
    unwritten. ``withhold_gt`` writes the scene as the BOP challenge ships a test split:
    no ``scene_gt.json``, ``scene_gt_info.json``, ``mask`` or ``mask_visib`` (nothing that
    gives a pose or an object's pixels away): the images and ``scene_camera.json`` only."""

    def __init__(
        self,
        root: Path | str,
        split: str,
        scene_id: int,
        *,
        depth_scale: float = 1.0,
        withhold_gt: bool = False,
    ) -> None:
        if not (isinstance(depth_scale, int | float) and depth_scale > 0):
            raise ValueError(f"depth_scale {depth_scale}: must be a positive number (mm/unit)")
        if not math.isfinite(depth_scale):
            raise ValueError(f"depth_scale {depth_scale}: must be finite")
        self.path = scene_path(root, split, scene_id)
        _writable(self.path / SCENE_GT_NAME)
        self.scene_id = int(scene_id)
        self.depth_scale = float(depth_scale)
        self.withhold_gt = bool(withhold_gt)
        self._camera: dict[int, dict[str, Any]] = {}
        self._gt: dict[int, list[dict[str, Any]]] = {}
        self._gt_info: dict[int, list[dict[str, Any]]] = {}
        self._closed = False

    def __enter__(self) -> SceneWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close()

    def depth_png(self, depth_m: NDArray[Any]) -> NDArray[np.uint16]:
        """The depth PNG's values for ``depth_m`` (metres): round(depth_mm / depth_scale);
        NaN, infinite and non-positive depths are 0 (no measurement). A depth the uint16
        range cannot hold is a ValueError naming a ``depth_scale`` that would."""
        d = np.asarray(depth_m, dtype=np.float64)
        valid = np.isfinite(d) & (d > 0)
        units = np.where(valid, np.round(np.where(valid, d, 0.0) * 1000.0 / self.depth_scale), 0)
        if units.max(initial=0) > _UINT16_MAX:
            far = float(d[valid].max())
            raise ValueError(
                f"depth {far:.3f} m does not fit a 16-bit depth PNG at depth_scale "
                f"{self.depth_scale} (at most {_UINT16_MAX * self.depth_scale / 1000:.3f} m): "
                f"use depth_scale >= {far * 1000 / _UINT16_MAX:.4g}, or mark far pixels as "
                "missing (inf)"
            )
        return units.astype(np.uint16)

    def add_image(
        self,
        im_id: int,
        *,
        rgb: NDArray[np.uint8],
        depth_m: NDArray[Any],
        K: NDArray[Any],
        gts: Sequence[GtInstance],
        R_w2c: NDArray[Any] | None = None,
        t_w2c_m: NDArray[Any] | Sequence[float] | None = None,
    ) -> None:
        """Write image ``im_id``'s PNGs and keep its JSON entries. ``rgb``: (H, W, 3) uint8
        RGB; ``depth_m``: (H, W) metres along the optical axis; ``K``: 3x3 intrinsics;
        ``gts``: the annotated instances (their order gives the masks' GT_IDX);
        ``R_w2c``/``t_w2c_m``: the optional world-to-camera pose (metres)."""
        if self._closed:
            raise ValueError(f"{self.path}: the scene is closed; open a new SceneWriter")
        im_id = _id(im_id, "im_id")
        if im_id in self._camera:
            raise ValueError(f"{self.path}: image {im_id} was already added")
        rgb = np.asarray(rgb)
        if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ValueError(f"rgb of {rgb.dtype} {rgb.shape}: give an (H, W, 3) uint8 image")
        hw = rgb.shape[:2]
        if np.shape(depth_m) != hw:
            raise ValueError(f"depth of shape {np.shape(depth_m)}: must be {hw} as the rgb image")
        Km = _matrix(K, "K")
        if (R_w2c is None) != (t_w2c_m is None):
            raise ValueError("give both R_w2c and t_w2c_m, or neither")
        depth = self.depth_png(depth_m)
        masks = []
        for g_idx, g in enumerate(gts):
            m = np.asarray(g.mask, dtype=bool)
            mv = np.asarray(g.mask_visib, dtype=bool)
            if m.shape != hw or mv.shape != hw:
                raise ValueError(f"gt {g_idx}: masks of {m.shape}, {mv.shape}: must be {hw}")
            if (mv & ~m).any():
                raise ValueError(f"gt {g_idx}: mask_visib has pixels outside mask")
            masks.append((m, mv))
        camera: dict[str, Any] = {
            "cam_K": Km.reshape(-1).tolist(),
            "depth_scale": self.depth_scale,
        }
        if R_w2c is not None and t_w2c_m is not None:
            camera["cam_R_w2c"] = _matrix(R_w2c, "R_w2c").reshape(-1).tolist()
            camera["cam_t_w2c"] = (_vector(t_w2c_m, "t_w2c_m") * 1000.0).tolist()
        gt_list, info_list = [], []
        for g, (m, mv) in zip(gts, masks, strict=True):
            gt_list.append(
                {
                    "cam_R_m2c": _matrix(g.R_m2c, "R_m2c").reshape(-1).tolist(),
                    "cam_t_m2c": (_vector(g.t_m2c_m, "t_m2c_m") * 1000.0).tolist(),
                    "obj_id": _id(g.obj_id, "obj_id"),
                }
            )
            n_all = int(m.sum()) if g.px_count_all is None else int(g.px_count_all)
            n_visib = int(mv.sum())
            info_list.append(
                {
                    "bbox_obj": list(mask_bbox(m)),
                    "bbox_visib": list(mask_bbox(mv)),
                    "px_count_all": n_all,
                    "px_count_valid": int((m & (depth > 0)).sum()),
                    "px_count_visib": n_visib,
                    "visib_fract": n_visib / n_all if n_all > 0 else 0.0,
                }
            )
        name = f"{im_id:06d}"
        _write_png(self.path / "rgb" / f"{name}.png", np.ascontiguousarray(rgb[:, :, ::-1]))
        _write_png(self.path / "depth" / f"{name}.png", depth)
        for g_idx, (m, mv) in enumerate([] if self.withhold_gt else masks):
            for sub, mk in (("mask", m), ("mask_visib", mv)):
                _write_png(self.path / sub / f"{name}_{g_idx:06d}.png", mk.astype(np.uint8) * 255)
        self._camera[im_id] = camera
        self._gt[im_id] = gt_list
        self._gt_info[im_id] = info_list

    def close(self) -> None:
        """Write the scene's three JSON files (atomically; ``scene_camera.json`` alone when
        the ground truth is withheld); once."""
        if self._closed:
            return
        files: list[tuple[str, Mapping[int, Any]]] = [(SCENE_CAMERA_NAME, self._camera)]
        if not self.withhold_gt:
            files += [(SCENE_GT_NAME, self._gt), (SCENE_GT_INFO_NAME, self._gt_info)]
        for name, content in files:
            _store(self.path / name, _json_text(content))
        self._closed = True


# -- scene reader -----------------------------------------------------------------------------
@dataclass(frozen=True)
class SceneCamera:
    """A ``scene_camera.json`` entry: ``K`` (3, 3), ``depth_scale`` (mm per depth unit),
    the optional world-to-camera pose (``t_w2c_mm`` in mm)."""

    K: Mat3
    depth_scale: float
    R_w2c: Mat3 | None = None
    t_w2c_mm: Vec3 | None = None


@dataclass(frozen=True)
class SceneGt:
    """A ``scene_gt.json`` instance: the model-to-camera pose, ``t_m2c_mm`` in mm."""

    obj_id: int
    R_m2c: Mat3
    t_m2c_mm: Vec3


@dataclass(frozen=True)
class GtInfo:
    """A ``scene_gt_info.json`` instance (boxes ``(x, y, width, height)``, pixel counts)."""

    bbox_obj: tuple[int, int, int, int]
    bbox_visib: tuple[int, int, int, int]
    px_count_all: int
    px_count_valid: int
    px_count_visib: int
    visib_fract: float


@dataclass(frozen=True)
class BopImage:
    """One image of a scene: its camera, its instances and (when the scene has a
    ``scene_gt_info.json``) their info, in the order of ``scene_gt.json`` (GT_IDX)."""

    im_id: int
    camera: SceneCamera
    gt: tuple[SceneGt, ...]
    gt_info: tuple[GtInfo, ...] | None


@dataclass(frozen=True)
class BopScene:
    """A scene folder read back (:func:`read_scene`); the images are loaded on demand."""

    path: Path
    scene_id: int
    images: dict[int, BopImage] = field(default_factory=dict)

    def _image(self, im_id: int) -> BopImage:
        if im_id not in self.images:
            raise BopFormatError(
                f"{self.path / SCENE_CAMERA_NAME}: no image {im_id} (it lists "
                f"{outdir.shown([str(i) for i in sorted(self.images)])})"
            )
        return self.images[im_id]

    def rgb(self, im_id: int) -> NDArray[np.uint8]:
        """``rgb/IM_ID.png`` as (H, W, 3) uint8 RGB."""
        self._image(im_id)
        bgr = _read_png(self.path / "rgb" / f"{im_id:06d}.png", cv2.IMREAD_COLOR)
        return np.ascontiguousarray(bgr[:, :, ::-1])

    def depth_mm(self, im_id: int) -> NDArray[np.float64]:
        """``depth/IM_ID.png`` in mm (the PNG's values x ``depth_scale``; 0 = missing)."""
        image = self._image(im_id)
        path = self.path / "depth" / f"{im_id:06d}.png"
        raw = _read_png(path, cv2.IMREAD_UNCHANGED)
        if raw.dtype != np.uint16 or raw.ndim != 2:
            raise BopFormatError(
                f"{path}: a depth image must be a 16-bit single-channel PNG, got "
                f"{raw.dtype} {raw.shape}; export the scene again"
            )
        return raw.astype(np.float64) * image.camera.depth_scale

    def _mask(self, sub: str, im_id: int, gt_idx: int) -> NDArray[np.bool_]:
        image = self._image(im_id)
        if not 0 <= gt_idx < len(image.gt):
            raise BopFormatError(
                f'{self.path / SCENE_GT_NAME} key "{im_id}": no instance {gt_idx} (it has '
                f"{len(image.gt)})"
            )
        path = self.path / sub / f"{im_id:06d}_{gt_idx:06d}.png"
        raw = _read_png(path, cv2.IMREAD_UNCHANGED)
        if raw.ndim != 2:
            raise BopFormatError(f"{path}: a mask must be a single-channel PNG, got {raw.shape}")
        return raw > 0

    def mask(self, im_id: int, gt_idx: int) -> NDArray[np.bool_]:
        """``mask/IM_ID_GT_IDX.png``: the instance's full silhouette."""
        return self._mask("mask", im_id, gt_idx)

    def mask_visib(self, im_id: int, gt_idx: int) -> NDArray[np.bool_]:
        """``mask_visib/IM_ID_GT_IDX.png``: the visible part of the silhouette."""
        return self._mask("mask_visib", im_id, gt_idx)


def scene_ids(root: Path | str, split: str) -> list[int]:
    """The scene ids of ``ROOT/SPLIT`` (its folders named by 6-digit ids), sorted."""
    d = Path(root) / split
    if not d.is_dir():
        raise BopFormatError(f"{d}: split folder missing")
    return sorted(
        int(p.name) for p in d.iterdir() if p.is_dir() and len(p.name) == 6 and p.name.isdigit()
    )


def _read_camera(w: _Where, entry: Any) -> SceneCamera:
    e = w.mapping(entry)
    K = w.at("cam_K").numbers(w.get(e, "cam_K"), 9, "a 3x3 matrix saved row-wise")
    scale = w.at("depth_scale").number(w.get(e, "depth_scale"))
    if scale <= 0:
        raise w.at("depth_scale").error(f"must be positive (mm per depth unit), got {scale}")
    if ("cam_R_w2c" in e) != ("cam_t_w2c" in e):
        raise w.error("cam_R_w2c and cam_t_w2c go together: give both or neither")
    R = t = None
    if "cam_R_w2c" in e:
        R = w.at("cam_R_w2c").numbers(e["cam_R_w2c"], 9, "a 3x3 rotation saved row-wise")
        R = R.reshape(3, 3)
        t = w.at("cam_t_w2c").numbers(e["cam_t_w2c"], 3, "a translation in mm")
    return SceneCamera(K=K.reshape(3, 3), depth_scale=scale, R_w2c=R, t_w2c_mm=t)


def _read_gt(w: _Where, entry: Any) -> SceneGt:
    e = w.mapping(entry)
    R = w.at("cam_R_m2c").numbers(w.get(e, "cam_R_m2c"), 9, "a 3x3 rotation saved row-wise")
    t = w.at("cam_t_m2c").numbers(w.get(e, "cam_t_m2c"), 3, "a translation in mm")
    obj_id = w.at("obj_id").integer(w.get(e, "obj_id"))
    return SceneGt(obj_id=obj_id, R_m2c=R.reshape(3, 3), t_m2c_mm=t)


def _read_gt_info(w: _Where, entry: Any) -> GtInfo:
    e = w.mapping(entry)

    def box(k: str) -> tuple[int, int, int, int]:
        items = w.at(k).array(w.get(e, k))
        if len(items) != 4 or any(isinstance(v, bool) or not isinstance(v, int) for v in items):
            raise w.at(k).error(f"must be 4 integers (x, y, width, height), got {items!r}")
        return (items[0], items[1], items[2], items[3])

    names = ("px_count_all", "px_count_valid", "px_count_visib")
    counts = {k: w.at(k).integer(w.get(e, k)) for k in names}
    fract = w.at("visib_fract").number(w.get(e, "visib_fract"))
    if not 0.0 <= fract <= 1.0:
        raise w.at("visib_fract").error(f"must lie in [0, 1], got {fract}")
    return GtInfo(
        bbox_obj=box("bbox_obj"), bbox_visib=box("bbox_visib"), visib_fract=fract, **counts
    )


def read_scene(root: Path | str, split: str, scene_id: int, *, require_gt: bool = True) -> BopScene:
    """Read ``ROOT/SPLIT/SCENE_ID``'s ``scene_camera.json``, ``scene_gt.json`` and (when
    present) ``scene_gt_info.json``; each must list the same image ids, and the info one
    entry per instance. ``require_gt=False`` accepts a scene without ``scene_gt.json``
    (a test split whose ground truth is private): its images then have no instances and
    no info. A
    missing or damaged file, a missing key or a value of the wrong kind raises
    :class:`BopFormatError` naming the file and key."""
    path = scene_path(root, split, scene_id)
    if not path.is_dir():
        raise BopFormatError(f"{path}: scene folder missing (split {split!r}, scene {scene_id})")
    wc = _Where(path / SCENE_CAMERA_NAME)
    cameras = {
        k: _read_camera(wc.at(str(k)), v) for k, v in _id_keyed(wc, _load_json(wc.path)).items()
    }
    wg = _Where(path / SCENE_GT_NAME)
    gts: dict[int, tuple[SceneGt, ...]] = {k: () for k in cameras}
    has_gt = require_gt or wg.path.exists()
    if has_gt:
        content = _id_keyed(wg, _load_json(wg.path))
        if set(content) != set(cameras):
            raise wg.error(_key_difference(set(content), set(cameras), SCENE_CAMERA_NAME))
        gts = {
            k: tuple(_read_gt(wg.at(str(k)).at(i), g) for i, g in enumerate(wg.at(str(k)).array(v)))
            for k, v in content.items()
        }
    wi = _Where(path / SCENE_GT_INFO_NAME)
    infos: dict[int, tuple[GtInfo, ...]] | None = None
    if has_gt and wi.path.exists():
        content = _id_keyed(wi, _load_json(wi.path))
        if set(content) != set(cameras):
            raise wi.error(_key_difference(set(content), set(cameras), SCENE_CAMERA_NAME))
        infos = {}
        for k, v in content.items():
            items = wi.at(str(k)).array(v)
            if len(items) != len(gts[k]):
                raise wi.at(str(k)).error(
                    f"has {len(items)} entries but {SCENE_GT_NAME} has {len(gts[k])} instances"
                )
            infos[k] = tuple(_read_gt_info(wi.at(str(k)).at(i), x) for i, x in enumerate(items))
    images = {
        k: BopImage(
            im_id=k, camera=cameras[k], gt=gts[k], gt_info=None if infos is None else infos[k]
        )
        for k in sorted(cameras)
    }
    return BopScene(path=path, scene_id=int(scene_id), images=images)


def _key_difference(keys: set[int], expected: set[int], other: str) -> str:
    extra = sorted(keys - expected)
    missing = sorted(expected - keys)
    parts = []
    if missing:
        parts.append(f"lacks image ids {outdir.shown([str(i) for i in missing])}")
    if extra:
        parts.append(f"has image ids {outdir.shown([str(i) for i in extra])} not in {other}")
    return " and ".join(parts) + f" (must list the same images as {other})"
