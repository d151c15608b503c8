"""BOP dataset files, written and read from the format's documentation.

The reference is the BOP toolkit's ``docs/bop_datasets_format.md`` (the "BOP-scenewise"
format; github.com/thodan/bop_toolkit) with the templates of its
``bop_toolkit_lib/dataset_params.py`` and the file conventions of ``bop_toolkit_lib/inout.py``.
The toolkit is not on PyPI, so this module implements the files from that documentation.
A dataset root written here holds::

    ROOT/
      .beo_bench_bop                    marker: the folder is ours (see claim_dataset_dir)
      .beo_bench_bop_files              the files an export wrote here (ExportLedger)
      .beo_bench_bop.lock               held by the one export writing here (export_dir)
      camera.json                       optional (write_camera): one camera for all images
      test_targets_bop19.json           write_targets
      models/
        models_info.json                write_models_info (entries from model_info)
        obj_OBJ_ID.ply                  write_model_ply (OBJ_ID: 6 digits)
        beo_bench_objects.json          write_category_map (beo-bench specific)
      SPLIT/SCENE_ID/                   SceneWriter (SCENE_ID: 6 digits)
        scene_camera.json  scene_gt.json  scene_gt_info.json
        rgb/IM_ID.png  depth/IM_ID.png  mask/IM_ID_GT_IDX.png  mask_visib/IM_ID_GT_IDX.png

Units are the format's: millimetres for models, translations and depth (``depth_scale``
converts a depth PNG's values to mm); rotations and ``cam_K`` are saved row-wise as 9
numbers; the keys of the per-scene JSON files and of ``models_info.json`` are the image or
object ids as decimal strings. The writers take the package's units (metres, names ending
in ``_m``) and convert; the readers return the format's units (names ending in ``_mm``).

Every file is written through :mod:`beo_bench.bop.store` (atomically, only inside a dataset
root beo-bench owns, never through a link); the scenes are :mod:`beo_bench.bop.scenes`. A file
that does not follow the format raises :class:`~beo_bench.errors.BopFormatError` naming the
file and the key that is wrong.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from numpy.typing import NDArray

from beo_bench.bop.store import (
    CATEGORY_MAP_NAME,
    MODELS_DIR,
    MODELS_INFO_NAME,
    TARGETS_NAME,
    _store,
)
from beo_bench.errors import BopFormatError
from beo_bench.types import ContinuousSymmetry, Mat4, Symmetry, Vec3

__all__ = [
    "BopTarget",
    "ContinuousSymmetryMm",
    "ModelInfo",
    "ObjectEntry",
    "model_info",
    "model_path",
    "read_category_map",
    "read_model_ply",
    "read_models_info",
    "read_targets",
    "scene_path",
    "write_camera",
    "write_category_map",
    "write_model_ply",
    "write_models_info",
    "write_targets",
]


# -- paths ------------------------------------------------------------------------------------
def model_path(root: Path | str, obj_id: int) -> Path:
    """``ROOT/models/obj_OBJ_ID.ply`` (``model_tpath`` of the toolkit's dataset_params)."""
    return Path(root) / MODELS_DIR / f"obj_{_id(obj_id, 'obj_id'):06d}.ply"


def scene_path(root: Path | str, split: str, scene_id: int) -> Path:
    """``ROOT/SPLIT/SCENE_ID`` with the scene id in 6 digits (BOP-scenewise layout)."""
    if not split or "/" in split or "\\" in split or split in (".", ".."):
        raise ValueError(f"split {split!r}: use a plain folder name such as 'test' or 'val'")
    return Path(root) / split / f"{_id(scene_id, 'scene_id'):06d}"


def _id(value: int, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
        raise ValueError(f"{name} {value!r}: BOP ids are non-negative integers")
    return int(value)


# -- JSON -------------------------------------------------------------------------------------
def _json_text(content: Mapping[Any, Any] | Sequence[Any]) -> str:
    """The toolkit's ``inout.save_json`` layout: one entry a line, keys sorted (numerically
    for the id keys), each entry's own keys sorted."""

    def dump(v: Any) -> str:
        return json.dumps(v, sort_keys=True, allow_nan=False)

    if isinstance(content, Mapping):
        items = sorted(content.items(), key=lambda kv: (int(kv[0]), str(kv[0])))
        lines = [f'  "{int(k)}": {dump(v)}' for k, v in items]
    else:
        lines = [f"  {dump(v)}" for v in content]
    open_, close = ("{", "}") if isinstance(content, Mapping) else ("[", "]")
    return open_ + "\n" + ",\n".join(lines) + ("\n" if lines else "") + close + "\n"


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _load_json(path: Path) -> Any:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise BopFormatError(f"{path}: file missing (the BOP format requires it)") from None
    except (OSError, UnicodeDecodeError) as e:
        raise BopFormatError(f"{path}: cannot be read ({e}); restore or re-export it") from None
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except ValueError as e:
        raise BopFormatError(
            f"{path}: not valid JSON ({e}); restore the file or export the dataset again"
        ) from None


class _Where:
    """Error messages that name a file and a key."""

    def __init__(self, path: Path, key: str = "") -> None:
        self.path = path
        self.key = key

    def at(self, key: object) -> _Where:
        k = f"[{key!r}]" if isinstance(key, str) else f"[{key}]"
        return _Where(self.path, self.key + k)

    def error(self, what: str) -> BopFormatError:
        key = f" key {self.key}" if self.key else ""
        return BopFormatError(f"{self.path}{key}: {what}; see the BOP format documentation")

    def mapping(self, value: Any) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.error(f"must be a JSON object, got {type(value).__name__}")
        return value

    def array(self, value: Any) -> list[Any]:
        if not isinstance(value, list):
            raise self.error(f"must be a JSON list, got {type(value).__name__}")
        return value

    def get(self, obj: dict[str, Any], key: str) -> Any:
        if key not in obj:
            raise self.at(key).error("missing")
        return obj[key]

    def number(self, value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(f"must be a number, got {value!r}")
        if not math.isfinite(value):
            raise self.error(f"must be finite, got {value!r}")
        return float(value)

    def integer(self, value: Any) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise self.error(f"must be a non-negative integer, got {value!r}")
        return value

    def numbers(self, value: Any, n: int, what: str) -> NDArray[np.float64]:
        items = self.array(value)
        if len(items) != n:
            raise self.error(f"must be {n} numbers ({what}), got {len(items)}")
        return np.array([self.at(i).number(v) for i, v in enumerate(items)], dtype=np.float64)

    def id_key(self, key: str) -> int:
        if not key.isdigit() or (len(key) > 1 and key.startswith("0") and key != "0"):
            raise self.at(key).error("keys must be ids written as decimal integers")
        return int(key)


def _id_keyed(where: _Where, content: Any) -> dict[int, Any]:
    return {where.id_key(k): v for k, v in where.mapping(content).items()}


# -- models -----------------------------------------------------------------------------------
def _vertices(vertices_m: NDArray[Any]) -> NDArray[np.float64]:
    v = np.asarray(vertices_m, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise ValueError(f"vertices of shape {v.shape}: give an (N, 3) array with N >= 1")
    if not np.isfinite(v).all():
        raise ValueError("vertices with NaN or infinite coordinates: repair the mesh first")
    return v


def write_model_ply(
    path: Path | str,
    vertices_m: NDArray[Any],
    faces: NDArray[Any],
    *,
    normals: NDArray[Any] | None = None,
    binary: bool = False,
) -> None:
    """Write a model as BOP ships it (``docs/bop_datasets_format.md``, "3D object models"):
    a PLY in millimetres (``vertices_m`` x 1000) with vertex normals, whose header declares
    what the toolkit's ``inout.load_ply`` reads: ``element vertex`` with ``float x y z nx ny
    nz`` and ``element face`` with ``property list uchar int vertex_indices`` (triangles).
    ``normals`` default to trimesh's angle-weighted vertex normals (the format documentation
    describes MeshLab's angle-weighted sum of the incident face normals). ASCII (as the
    BOP datasets are) unless ``binary`` (little-endian)."""
    v = _vertices(vertices_m)
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise ValueError(f"faces of shape {f.shape}: give an (M, 3) array of triangles, M >= 1")
    if not np.issubdtype(f.dtype, np.integer) or f.min() < 0 or f.max() >= len(v):
        raise ValueError(f"faces must be integer indices into the {len(v)} vertices")
    if normals is None:
        n = np.asarray(trimesh.Trimesh(v, f, process=False).vertex_normals, dtype=np.float64)
    else:
        n = np.asarray(normals, dtype=np.float64)
        if n.shape != v.shape or not np.isfinite(n).all():
            raise ValueError(f"normals of shape {n.shape}: give finite normals shaped {v.shape}")
    header = (
        "ply\n"
        f"format {'binary_little_endian' if binary else 'ascii'} 1.0\n"
        "comment written by beo-bench; units: mm (BOP)\n"
        f"element vertex {len(v)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        f"element face {len(f)}\n"
        "property list uchar int vertex_indices\n"
        "end_header\n"
    ).encode("ascii")
    vn = np.hstack([v * 1000.0, n])
    if binary:
        vert = vn.astype("<f4").tobytes()
        face = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
        face["n"] = 3
        face["i"] = f
        body = vert + face.tobytes()
    else:
        vtext = "".join(
            f"{x:.6f} {y:.6f} {z:.6f} {a:.6f} {b:.6f} {c:.6f}\n" for x, y, z, a, b, c in vn
        )
        ftext = "".join(f"3 {i} {j} {k}\n" for i, j, k in f.tolist())
        body = (vtext + ftext).encode("ascii")
    _store(path, header + body)


def read_model_ply(path: Path | str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A BOP model's vertices (N, 3), in the file's units (mm for BOP), and triangles."""
    path = Path(path)
    if not path.is_file():
        raise BopFormatError(f"{path}: model file missing; export the models again")
    try:
        mesh = trimesh.load(path, file_type="ply", process=False, force="mesh")
    except Exception as e:  # trimesh raises many types on a damaged file
        raise BopFormatError(f"{path}: not a readable PLY mesh ({e}); export it again") from None
    if not isinstance(mesh, trimesh.Trimesh):
        raise BopFormatError(f"{path}: not a triangle mesh; export it again")
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    if len(v) == 0 or len(f) == 0:
        raise BopFormatError(f"{path}: PLY with no vertices or faces; export it again")
    return v, f


def _diameter(v: NDArray[np.float64]) -> float:
    """The largest distance between two points (over the convex hull's vertices)."""
    from scipy.spatial import ConvexHull, QhullError
    from scipy.spatial.distance import pdist

    pts = np.unique(v, axis=0)
    if len(pts) < 2:
        return 0.0
    try:
        pts = pts[ConvexHull(pts).vertices]
    except (QhullError, ValueError):
        pass  # flat or degenerate: every point is a candidate
    return float(pdist(pts).max())


def model_info(vertices_m: NDArray[Any], symmetry: Symmetry) -> dict[str, Any]:
    """The ``models_info.json`` entry of a model (``docs/bop_datasets_format.md``, "3D object
    models"; ``scripts/calc_model_info.py``): ``diameter`` (the largest distance between two
    vertices), the 3D box ``min_x, min_y, min_z, size_x, size_y, size_z``, all in mm, and
    the symmetries in the toolkit's form (``misc.get_symmetry_transformations``):
    ``symmetries_discrete``, each a 4x4 transform flattened row-wise with its translation
    in mm, and ``symmetries_continuous``, each ``{"axis": [3], "offset": [3 mm]}``. A kind
    of symmetry the object lacks is left out, as in the BOP datasets. ``symmetry`` is our
    group (:class:`beo_bench.types.Symmetry`: BOP form in metres)."""
    v = _vertices(vertices_m) * 1000.0
    lo, hi = v.min(axis=0), v.max(axis=0)
    info: dict[str, Any] = {"diameter": _diameter(v)}
    for i, a in enumerate("xyz"):
        info[f"min_{a}"] = float(lo[i])
        info[f"size_{a}"] = float(hi[i] - lo[i])
    discrete = []
    for T in symmetry.get("discrete", []):
        M = np.array(T, dtype=np.float64)
        if M.shape != (4, 4) or not np.isfinite(M).all():
            raise ValueError(f"discrete symmetry of shape {M.shape}: give finite 4x4 transforms")
        M[:3, 3] *= 1000.0
        discrete.append([float(x) for x in M.reshape(-1)])
    continuous = []
    for c in symmetry.get("continuous", []):
        axis = np.asarray(c["axis"], dtype=np.float64)
        offset = np.asarray(c["offset"], dtype=np.float64) * 1000.0
        if axis.shape != (3,) or offset.shape != (3,) or not np.any(axis):
            raise ValueError("a continuous symmetry needs a non-zero 3-vector axis and offset")
        continuous.append({"axis": axis.tolist(), "offset": offset.tolist()})
    if discrete:
        info["symmetries_discrete"] = discrete
    if continuous:
        info["symmetries_continuous"] = continuous
    return info


def write_models_info(path: Path | str, infos: Mapping[int, Mapping[str, Any]]) -> None:
    """Write ``models_info.json``: ``infos`` (obj_id -> :func:`model_info` entry) keyed by
    the obj_id as a string, in the toolkit's ``save_json`` layout."""
    content = {str(_id(k, "obj_id")): dict(v) for k, v in infos.items()}
    _store(path, _json_text(content))


@dataclass(frozen=True)
class ContinuousSymmetryMm:
    """A ``symmetries_continuous`` entry: rotation about ``axis`` through ``offset_mm``."""

    axis: Vec3
    offset_mm: Vec3


@dataclass(frozen=True)
class ModelInfo:
    """A ``models_info.json`` entry, in the format's units (mm)."""

    obj_id: int
    diameter_mm: float
    min_mm: Vec3
    """(min_x, min_y, min_z)."""
    size_mm: Vec3
    """(size_x, size_y, size_z)."""
    symmetries_discrete: tuple[Mat4, ...] = ()
    """4x4 transforms, translation in mm."""
    symmetries_continuous: tuple[ContinuousSymmetryMm, ...] = ()

    def symmetry(self) -> Symmetry:
        """The group in our form (:class:`beo_bench.types.Symmetry`, metres)."""
        discrete = []
        for T in self.symmetries_discrete:
            M = np.array(T, dtype=np.float64)
            M[:3, 3] /= 1000.0
            discrete.append(M.tolist())
        continuous: list[ContinuousSymmetry] = [
            {"axis": c.axis.tolist(), "offset": (c.offset_mm / 1000.0).tolist()}
            for c in self.symmetries_continuous
        ]
        return {"continuous": continuous, "discrete": discrete}


def _model_entries(root: Path | str, name: str) -> Iterator[tuple[int, _Where, dict[str, Any]]]:
    """Each entry of the models folder's JSON file ``name`` (``root`` itself when it names a
    .json file, else ``ROOT/models/NAME``): ``(obj_id, where, entry)``, the entry an object."""
    path = Path(root)
    if path.suffix != ".json":  # a dataset root
        path = path / MODELS_DIR / name
    w = _Where(path)
    for obj_id, entry in _id_keyed(w, _load_json(path)).items():
        we = w.at(str(obj_id))
        yield obj_id, we, we.mapping(entry)


def read_models_info(root: Path | str) -> dict[int, ModelInfo]:
    """``ROOT/models/models_info.json`` (or ``root`` itself when it names a .json file), by
    obj_id; a :class:`BopFormatError` naming the file and key for a damaged entry."""
    out = {}
    for obj_id, we, e in _model_entries(root, MODELS_INFO_NAME):
        wd = we.at("symmetries_discrete")
        discrete = tuple(
            wd.at(i).numbers(T, 16, "a 4x4 transform saved row-wise").reshape(4, 4)
            for i, T in enumerate(wd.array(e.get("symmetries_discrete", [])))
        )
        continuous = []
        wc = we.at("symmetries_continuous")
        for i, c in enumerate(wc.array(e.get("symmetries_continuous", []))):
            wi = wc.at(i)
            ci = wi.mapping(c)
            axis = wi.at("axis").numbers(wi.get(ci, "axis"), 3, "an axis")
            if not np.any(axis):
                raise wi.at("axis").error("must not be the zero vector")
            offset = wi.at("offset").numbers(wi.get(ci, "offset"), 3, "a point in mm")
            continuous.append(ContinuousSymmetryMm(axis=axis, offset_mm=offset))

        def num(k: str, we: _Where = we, e: dict[str, Any] = e) -> float:
            return we.at(k).number(we.get(e, k))

        out[obj_id] = ModelInfo(
            obj_id=obj_id,
            diameter_mm=num("diameter"),
            min_mm=np.array([num("min_x"), num("min_y"), num("min_z")]),
            size_mm=np.array([num("size_x"), num("size_y"), num("size_z")]),
            symmetries_discrete=discrete,
            symmetries_continuous=tuple(continuous),
        )
    return out


# -- category map (beo-bench specific) --------------------------------------------------------
@dataclass(frozen=True)
class ObjectEntry:
    """What ``beo_bench_objects.json`` says of one obj_id: beo-bench's own file (not part of
    the BOP format) beside ``models_info.json``, mapping each BOP object back to the object
    it was exported from. Fields: ``category`` (the category name, e.g. ``"mug"``),
    ``split`` (the instance split it came from, e.g. ``"test"``) and ``key`` (its instance
    key, from which ``beo_bench.objects.instance_from_key`` rebuilds the instance)."""

    category: str
    split: str
    key: str


def write_category_map(path: Path | str, entries: Mapping[int, ObjectEntry]) -> None:
    """Write ``beo_bench_objects.json``: ``{"OBJ_ID": {"category": ..., "key": ...,
    "split": ...}}`` keyed by the obj_id as a string (as ``models_info.json``)."""
    content: dict[str, dict[str, str]] = {}
    for obj_id, e in entries.items():
        for name in ("category", "split", "key"):
            if not isinstance(getattr(e, name), str) or not getattr(e, name):
                raise ValueError(f"obj_id {obj_id}: {name} must be a non-empty string")
        content[str(_id(obj_id, "obj_id"))] = {
            "category": e.category,
            "split": e.split,
            "key": e.key,
        }
    _store(path, _json_text(content))


def read_category_map(path: Path | str) -> dict[int, ObjectEntry]:
    """``beo_bench_objects.json`` (or ``ROOT/models/beo_bench_objects.json`` for a dataset
    root), by obj_id."""
    out = {}
    for obj_id, we, e in _model_entries(path, CATEGORY_MAP_NAME):
        fields = {}
        for name in ("category", "split", "key"):
            value = we.get(e, name)
            if not isinstance(value, str) or not value:
                raise we.at(name).error(f"must be a non-empty string, got {value!r}")
            fields[name] = value
        out[obj_id] = ObjectEntry(**fields)
    return out


# -- targets and camera -----------------------------------------------------------------------
@dataclass(frozen=True)
class BopTarget:
    """An entry of ``test_targets_bop19.json`` (BOP Challenge 2019, "test targets"): estimate
    the poses of ``inst_count`` instances of ``obj_id`` in image ``im_id`` of scene
    ``scene_id``."""

    scene_id: int
    im_id: int
    obj_id: int
    inst_count: int


def write_targets(path: Path | str, targets: Iterable[BopTarget]) -> None:
    """Write ``test_targets_bop19.json``: a JSON list of ``{"im_id", "inst_count",
    "obj_id", "scene_id"}`` objects (the toolkit's ``save_json`` layout for a list)."""
    content = []
    for t in targets:
        row = {k: _id(getattr(t, k), k) for k in ("im_id", "inst_count", "obj_id", "scene_id")}
        if row["inst_count"] < 1:
            raise ValueError(f"target {t}: inst_count must be at least 1")
        content.append(row)
    _store(path, _json_text(content))


def read_targets(path: Path | str) -> list[BopTarget]:
    """``test_targets_bop19.json`` (or ``ROOT/test_targets_bop19.json`` for a root)."""
    path = Path(path)
    if path.suffix != ".json":  # a dataset root
        path = path / TARGETS_NAME
    w = _Where(path)
    out = []
    for i, item in enumerate(w.array(_load_json(path))):
        wi = w.at(i)
        d = wi.mapping(item)
        ids = {k: wi.at(k).integer(wi.get(d, k)) for k in ("scene_id", "im_id", "obj_id")}
        count = wi.at("inst_count").integer(wi.get(d, "inst_count"))
        if count < 1:
            raise wi.at("inst_count").error("must be at least 1")
        out.append(BopTarget(inst_count=count, **ids))
    return out


def write_camera(
    path: Path | str, K: NDArray[Any], width: int, height: int, depth_scale: float
) -> None:
    """Write the dataset root's ``camera.json`` (``cx, cy, fx, fy, width, height,
    depth_scale``: the toolkit's ``inout.load_cam_params``), for when every image shares
    one camera. Optional in the format: the per-image cameras are in ``scene_camera.json``."""
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3) or K[0, 1] != 0 or K[1, 0] != 0 or not np.isfinite(K).all():
        raise ValueError("camera.json holds a pinhole K without skew: give a finite 3x3 K")
    if not (depth_scale > 0 and math.isfinite(depth_scale)):
        raise ValueError(f"depth_scale {depth_scale}: must be a positive number (mm per unit)")
    content = {
        "cx": float(K[0, 2]),
        "cy": float(K[1, 2]),
        "depth_scale": float(depth_scale),
        "fx": float(K[0, 0]),
        "fy": float(K[1, 1]),
        "height": int(height),
        "width": int(width),
    }
    _store(path, json.dumps(content, sort_keys=True, indent=2) + "\n")
