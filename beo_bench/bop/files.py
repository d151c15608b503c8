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

Every file is written atomically (:mod:`beo_bench.atomic`), and only inside a dataset root
that :func:`claim_dataset_dir` created or marked: an existing non-empty folder that
beo-bench did not make is refused and left untouched (:class:`ForeignOutputError`), and so
is a symbolic link at any folder or file below the root that a writer would write (nothing
is written through a link). Inside :func:`export_dir` (what ``beo-bench export`` uses) one
process writes at a time, every file written is listed in the root's ledger, a file there
that the ledger does not list as unchanged since beo-bench wrote it is never overwritten,
and :meth:`ExportLedger.finish` removes the files of an earlier export that this one did not
write again (only those: a file the user changed or added is kept). A file
that does not follow the format raises :class:`~beo_bench.errors.BopFormatError` naming the
file and the key that is wrong.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any

import cv2
import numpy as np
import trimesh
from numpy.typing import NDArray

from beo_bench import outdir
from beo_bench.atomic import atomic_write_bytes
from beo_bench.errors import BeoBenchError, BopFormatError, UsageError
from beo_bench.types import ContinuousSymmetry, Mat3, Mat4, Symmetry, Vec3

__all__ = [
    "CAMERA_NAME",
    "CATEGORY_MAP_NAME",
    "EMPTY_BBOX",
    "FILES_NAME",
    "LOCK_NAME",
    "MARKER_NAME",
    "MODELS_DIR",
    "MODELS_INFO_NAME",
    "SCENE_CAMERA_NAME",
    "SCENE_GT_INFO_NAME",
    "SCENE_GT_NAME",
    "TARGETS_NAME",
    "BopImage",
    "BopScene",
    "BopTarget",
    "ContinuousSymmetryMm",
    "DatasetBusyError",
    "ExportLedger",
    "ForeignOutputError",
    "GtInfo",
    "GtInstance",
    "ModelInfo",
    "ObjectEntry",
    "SceneCamera",
    "SceneGt",
    "SceneWriter",
    "claim_dataset_dir",
    "export_dir",
    "mask_bbox",
    "model_info",
    "model_path",
    "read_category_map",
    "read_model_ply",
    "read_models_info",
    "read_scene",
    "read_targets",
    "scene_ids",
    "scene_path",
    "write_camera",
    "write_category_map",
    "write_file",
    "write_model_ply",
    "write_models_info",
    "write_targets",
]

MARKER_NAME = ".beo_bench_bop"
"""The marker file of a dataset root this package created (see :func:`claim_dataset_dir`)."""
MARKER_TEXT = (
    "This BOP dataset folder was written by beo-bench (beo-bench export); beo-bench may\n"
    "overwrite the files it wrote here. Delete this file to make beo-bench refuse the folder.\n"
)
FILES_NAME = ".beo_bench_bop_files"
"""The ledger of an export (:class:`ExportLedger`): one JSON line per file written."""
LOCK_NAME = ".beo_bench_bop.lock"
"""Locked (``flock``, with the PID in it) by the export writing the folder."""
MODELS_DIR = "models"
"""The models folder (``models[_MODELTYPE]`` in the format documentation)."""
MODELS_INFO_NAME = "models_info.json"
TARGETS_NAME = "test_targets_bop19.json"
"""The test targets of the BOP 2019 localization task, at the dataset root."""
CATEGORY_MAP_NAME = "beo_bench_objects.json"
"""beo-bench's own file beside ``models_info.json``: obj_id -> category, split, key."""
CAMERA_NAME = "camera.json"
SCENE_CAMERA_NAME = "scene_camera.json"
SCENE_GT_NAME = "scene_gt.json"
SCENE_GT_INFO_NAME = "scene_gt_info.json"
EMPTY_BBOX = (-1, -1, -1, -1)
"""The box of an empty mask, as ``scripts/calc_gt_info.py`` of the toolkit writes it."""
_UINT16_MAX = 65535


class ForeignOutputError(UsageError):
    """An output folder or file that beo-bench did not create: a non-empty folder without
    the marker, or a file outside a folder that :func:`claim_dataset_dir` claimed. Nothing
    in it is touched."""


class DatasetBusyError(BeoBenchError):
    """Another process is exporting into the same folder (it holds :data:`LOCK_NAME`)."""


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


# -- ownership --------------------------------------------------------------------------------
def claim_dataset_dir(root: Path | str) -> Path:
    """Make ``root`` a dataset root the writers of this module may write into: create it
    (with its parents) when missing, mark it when empty, accept it when it carries the
    marker (:data:`MARKER_NAME`) of an earlier export. A non-empty folder without the
    marker is the user's: :class:`ForeignOutputError`, and nothing in it is touched."""
    root = Path(root)
    if root.exists() and not root.is_dir():
        raise ForeignOutputError(
            f"{root} is a file, not a folder: give the BOP export a new or empty folder"
        )
    root.mkdir(parents=True, exist_ok=True)
    held = outdir.foreign_files(root, MARKER_NAME)
    if held:
        raise ForeignOutputError(
            f"{root} is a non-empty folder that beo-bench did not create (it holds "
            f"{outdir.shown(held)} and no {MARKER_NAME}): give the BOP export a new or empty "
            "folder; nothing in this one is touched"
        )
    if held is not None:
        outdir.mark(root, MARKER_NAME, MARKER_TEXT)
    return root


def _claimed_root(path: Path) -> Path | None:
    """The nearest folder above ``path`` that carries the marker, if any."""
    for d in path.absolute().parents:
        m = d / MARKER_NAME
        if m.is_file() and not m.is_symlink():
            return d
    return None


def _link_error(link: Path) -> ForeignOutputError:
    try:
        to = f" (to {os.readlink(link)})"
    except OSError:  # pragma: no cover - it was a link a moment ago
        to = ""
    return ForeignOutputError(
        f"{link} is a symbolic link{to}: the BOP export never writes through a link, and "
        "nothing was written through this one; remove the link, or export into a new DIR"
    )


def _inside(root: Path, path: Path) -> None:
    """Create ``path``'s folders below ``root`` one at a time, refusing a symbolic link (or
    a file) at any of them and a symbolic link at ``path``; and refuse a ``path`` that
    resolves outside ``root``."""
    rel = path.relative_to(root)
    d = root
    for part in rel.parts[:-1]:
        d = d / part
        if d.is_symlink():
            raise _link_error(d)
        if not d.exists():
            d.mkdir(exist_ok=True)
        elif not d.is_dir():
            raise ForeignOutputError(
                f"{d} is a file where the BOP export writes a folder: move it away, or "
                "export into a new DIR"
            )
    if path.is_symlink():
        raise _link_error(path)
    real = root.resolve()
    if real != path.parent.resolve() and real not in path.parent.resolve().parents:
        raise ForeignOutputError(  # pragma: no cover - a link on the way is refused above
            f"{path} resolves outside the export folder {root}: nothing written there"
        )


def _target(path: Path | str) -> tuple[Path, Path]:
    """``path`` (absolute) with its folders created, and its claimed dataset root, after
    checking it lies in that root and no link is on the way (:func:`_inside`)."""
    path = Path(path).absolute()
    root = _claimed_root(path)
    if root is None:
        raise ForeignOutputError(
            f"{path} is not inside a BOP dataset folder that beo-bench created: claim the "
            "dataset root with claim_dataset_dir() first (it refuses a non-empty folder that "
            "beo-bench did not create)"
        )
    _inside(root, path)
    return path, root


def _writable(path: Path | str) -> Path:
    """``path``, with its folder created, after checking it lies in a claimed dataset root."""
    return _target(path)[0]


def _store(path: Path | str, data: bytes | str) -> None:
    """Write ``path`` atomically inside its claimed root; inside :func:`export_dir`, only
    where its ledger allows, and listed there."""
    target, root = _target(path)
    ledger = _LEDGERS.get(root)
    if ledger is not None:
        ledger.before(target)
    atomic_write_bytes(target, data)
    if ledger is not None:
        ledger.after(target)


def write_file(path: Path | str, data: bytes | str) -> None:
    """Write one more file of a dataset root (``data``: bytes, or text as UTF-8) as the
    writers of this module write theirs: atomically, checked and listed (:func:`_store`)."""
    _store(path, data)


# -- the ledger of an export --------------------------------------------------------------------
_LEDGERS: dict[Path, ExportLedger] = {}
"""The open ledger of each dataset root this process is exporting into."""
_OWN_NAMES = (MARKER_NAME, FILES_NAME, LOCK_NAME)


def _stat_key(path: Path) -> list[int]:
    st = path.lstat()
    return [st.st_ino, st.st_size, st.st_mtime_ns]


class ExportLedger:
    """The files beo-bench wrote into a dataset root, in ``ROOT/.beo_bench_bop_files``: a
    journal of JSON lines (``{"path": REL}`` before a file is written, ``{"path": REL,
    "stat": [inode, size, mtime_ns]}`` after, ``{"path": REL, "gone": true}`` when removed),
    appended as the export goes, so an export cut short leaves a ledger that still lists
    every file it wrote; :meth:`finish` rewrites it (atomically) to the files of this
    export. A file is beo-bench's to overwrite or remove only while it is listed with the
    inode, size and modification time it had when written (a file the user replaced or
    edited is theirs)."""

    def __init__(self, root: Path) -> None:
        self.root = root.absolute()
        self.path = self.root / FILES_NAME
        self.old = self._read()
        self.new: dict[str, list[int]] = {}
        self._fd: int | None = None

    def _read(self) -> dict[str, list[int] | None]:
        if self.path.is_symlink():
            raise _link_error(self.path)
        try:
            text = self.path.read_text()
        except FileNotFoundError:
            held = [
                n for n in outdir.foreign_files(self.root, MARKER_NAME) or [] if n not in _OWN_NAMES
            ]
            if held:
                raise ForeignOutputError(
                    f"{self.root} was exported by an earlier beo-bench, which kept no list of "
                    f"the files it wrote ({FILES_NAME}), so an export cannot tell its stale "
                    f"files from yours (it holds {outdir.shown(held)}): export into a new or "
                    "empty DIR; nothing in this one is touched"
                ) from None
            return {}
        entries: dict[str, list[int] | None] = {}
        for line in text.splitlines():
            try:
                e = json.loads(line)
                rel = e["path"]
                stat = e.get("stat")
            except (ValueError, TypeError, KeyError):
                continue  # a line cut short by a killed export: its file is still listed
            if not isinstance(rel, str) or not self._valid(rel):
                continue
            if e.get("gone"):
                entries.pop(rel, None)
            elif isinstance(stat, list) and len(stat) == 3:
                entries[rel] = [int(v) for v in stat]
            else:
                entries[rel] = None  # being written: unknown until its stat line
        return entries

    @staticmethod
    def _valid(rel: str) -> bool:
        p = Path(rel)
        own = p.name in _OWN_NAMES
        return bool(rel) and not p.is_absolute() and ".." not in p.parts and not own

    def _rel(self, path: Path) -> str:
        return path.relative_to(self.root).as_posix()

    def _append(self, entry: dict[str, Any]) -> None:
        if self._fd is None:
            flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC
            self._fd = os.open(self.path, flags, 0o644)
        data = (json.dumps(entry, sort_keys=True) + "\n").encode()
        while data:
            data = data[os.write(self._fd, data) :]

    def owns(self, path: Path) -> bool:
        """Whether ``path`` is a file this export or an earlier one wrote and nobody has
        changed since (a missing ``path`` is nobody's)."""
        rel = self._rel(path)
        if rel in self.new:
            return True
        if rel not in self.old:
            return False
        try:
            return self.old[rel] in (None, _stat_key(path))
        except FileNotFoundError:
            return False

    def check(self, path: Path) -> None:
        """Refuse (:class:`ForeignOutputError`) when ``path`` is a file that is not
        beo-bench's (:meth:`owns`), which an export must not overwrite."""
        rel = self._rel(path)
        if os.path.lexists(path) and not self.owns(path):
            changed = "was changed after beo-bench wrote it"
            why = changed if rel in self.old else "is not a file beo-bench wrote"
            raise ForeignOutputError(
                f"{path} {why}, and the export would overwrite it: move it out of the "
                "export, or export into a new DIR; it is left as it is"
            )

    def before(self, path: Path) -> None:
        """Refuse to overwrite a file that is not beo-bench's; note the write to come."""
        self.check(path)
        self._append({"path": self._rel(path)})

    def after(self, path: Path) -> None:
        """List the file just written."""
        rel = self._rel(path)
        self.new[rel] = _stat_key(path)
        self._append({"path": rel, "stat": self.new[rel]})

    def remove(self, path: Path) -> bool:
        """Remove ``path`` when it is beo-bench's (:meth:`owns`); whether it was."""
        rel = self._rel(path)
        for d in list(path.relative_to(self.root).parents)[:-1]:
            if (self.root / d).is_symlink() or not (self.root / d).is_dir():
                return False  # never remove through a link (or a folder that is not one)
        try:
            if path.is_symlink() or not path.is_file() or not self.owns(path):
                return False
        except OSError:
            return False
        path.unlink()
        self.new.pop(rel, None)
        self.old.pop(rel, None)
        self._append({"path": rel, "gone": True})
        return True

    def finish(self) -> tuple[int, list[str]]:
        """Remove the files of earlier exports this one did not write again (only those
        still as beo-bench wrote them), and the folders that leaves empty; rewrite the
        ledger to this export's files. Returns the files removed and the ones kept (changed
        or replaced by someone else, or of unknown state)."""
        removed, kept = 0, []
        folders: set[Path] = set()
        for rel in sorted(set(self.old) - set(self.new)):
            path = self.root / rel
            if not os.path.lexists(path):
                continue
            if self.remove(path):
                removed += 1
                folders.update(p for p in Path(rel).parents if p != Path("."))
            else:
                kept.append(rel)
        for d in sorted(folders, key=lambda p: len(p.parts), reverse=True):
            full = self.root / d
            if full.is_dir() and not full.is_symlink():
                with contextlib.suppress(OSError):
                    full.rmdir()  # only when empty: a user's file keeps its folder
        self.close()
        text = "".join(
            json.dumps({"path": rel, "stat": st}, sort_keys=True) + "\n"
            for rel, st in sorted(self.new.items())
        )
        atomic_write_bytes(self.path, text)
        self.old = dict(self.new)
        return removed, kept

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


_LAYOUT = (MODELS_DIR, "test", "train", TARGETS_NAME, CAMERA_NAME, *_OWN_NAMES)


def _links_in(root: Path) -> Path | None:
    """A symbolic link at a path of the layout below ``root`` (or anywhere under its
    ``models``, ``test`` and ``train`` folders), if any."""
    for name in _LAYOUT:
        top = root / name
        if top.is_symlink():
            return top
        if top.is_dir():
            for d, dirs, files in os.walk(top):
                for n in dirs + files:
                    if (Path(d) / n).is_symlink():
                        return Path(d) / n
    return None


@contextlib.contextmanager
def export_dir(root: Path | str, extra: Sequence[str] = ()) -> Iterator[ExportLedger]:
    """Claim ``root`` (:func:`claim_dataset_dir`), lock it (``ROOT/.beo_bench_bop.lock``:
    a second export gets a :class:`DatasetBusyError` naming the holder's PID), refuse it
    when a symbolic link stands where the export writes (``extra``: more names at the root
    it writes), and open its :class:`ExportLedger`, which the writers of this module use
    inside the ``with`` block."""
    root = claim_dataset_dir(root).absolute()
    link = _links_in(root) or next((root / n for n in extra if (root / n).is_symlink()), None)
    if link is not None:
        raise _link_error(link)

    def busy(pid: str) -> DatasetBusyError:
        return DatasetBusyError(
            f"{root} is being exported into by another process (PID {pid}, holding "
            f"{root / LOCK_NAME}): wait for it to finish or stop it, or export into another "
            "DIR (two exports into one folder would mix their images)"
        )

    with outdir.locked(root / LOCK_NAME, busy):
        ledger = ExportLedger(root)
        _LEDGERS[root] = ledger
        try:
            yield ledger
        finally:
            _LEDGERS.pop(root, None)
            ledger.close()


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
