"""The on-disk asset cache: content-addressed, checksummed, written atomically.

Entries live under a root directory, one ``.npz`` file
per (mesh content hash, processing settings), in one directory per kind (:data:`KINDS`).
Writers go through a temporary file in the same directory and ``os.replace``
(:func:`beo_bench.atomic.atomic_write`), so a reader in another process sees either nothing
or the whole file, and a killed writer leaves only a ``.tmp`` file that the next writer
ignores.

The root is an argument (``root=``) of every function that reads or writes the cache: a
run carries its own (``RunContext.cache_root``) down to its workers. A function given none
uses :func:`cache_root`, ``$BEO_BENCH_CACHE`` (default ``~/.cache/beo_bench``) read at the
call; nothing in this package writes that variable.

Every entry carries a checksum of its arrays (``__checksum__``); an entry that does not
match it, has none (written by an older version) or cannot be read is recomputed and
rewritten, never trusted. So is one whose arrays, checksum and all, are not what the kind's
writer makes (names, dtypes, shapes from the entry's settings, value ranges:
:func:`entry_problem`): a checksum shows a file is whole, not who wrote it. Headers are
checked before anything is unpacked (:mod:`beo_bench.safe_npz`).

The cache only deletes what it made: when it creates its root it writes a
``CACHEDIR.TAG`` (https://bford.info/cachedir/, which also keeps backup tools out), and
:func:`clear` removes only the known kind directories of a root that carries that tag, so a
``$BEO_BENCH_CACHE`` pointing at ``$HOME`` by mistake loses nothing.
"""

from __future__ import annotations

import errno
import hashlib
import json
import logging
import os
import shutil
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from beo_bench.atomic import atomic_write
from beo_bench.errors import CacheDirError, InvalidNameError, UsageError
from beo_bench.names import check_name

CACHE_ENV = "BEO_BENCH_CACHE"

TAG_NAME = "CACHEDIR.TAG"
TAG_SIGNATURE = "Signature: 8a477f597d28d172789f06886806bc55"
"""The Cache Directory Tagging signature: the tag's first line."""
TAG_TEXT = (
    f"{TAG_SIGNATURE}\n"
    "# This directory is the asset cache of beo-bench (object meshes, voxels, models, ...).\n"
    "# `beo-bench cache clear` removes only the kinds of entry it lists below it.\n"
    "# For information about cache directory tags see https://bford.info/cachedir/\n"
)
CHECKSUM_KEY = "__checksum__"
"""The array of an entry holding the checksum of the others (see :func:`array_checksum`)."""

_log = logging.getLogger(__name__)

KINDS: dict[str, str] = {
    "generated": "procedural meshes of the built-in categories",
    "loaded": "dataset meshes as built from their files",
    "voxels": "solid occupancy grids of each instance",
    "surface": "surface samples of each instance",
    "coacd": "convex collision parts (CoACD) of each instance",
    "symmetry": "estimated rotational symmetry of loaded meshes",
    "rest": "each instance's stable resting pose on the table",
    "classmeans": "per-class mean shapes (icp, random)",
    "truth": "the true grids' surface samples and EDTs that scoring uses",
    "models": "trained BEO / HBEO / HBEO-MDN models",
    "datasets": "rendered HBEO training crops",
}
"""Every kind of entry the cache holds, with a line each (``beo-bench cache clear --kind``
accepts exactly these: a kind is a name, never a path)."""


def default_root() -> Path:
    """Where the cache lives without ``$BEO_BENCH_CACHE``: ``~/.cache/beo_bench``."""
    return Path.home() / ".cache" / "beo_bench"


def cache_root() -> Path:
    """The cache directory the environment names (``$BEO_BENCH_CACHE`` or
    ``~/.cache/beo_bench``), read at each call and never written: the edge a run resolves its
    root at (``RunContext.cache_root``), and what a function given no ``root`` uses."""
    return Path(os.environ.get(CACHE_ENV) or default_root())


def resolve_root(root: Path | str | None) -> Path:
    """``root``, or the environment's (:func:`cache_root`) when none is given."""
    return cache_root() if root is None else Path(root)


MIN_FREE_BYTES = 256 << 20
"""Free space the cache's file system must have when a command starts (256 MiB): a run's
entries for a few hundred objects (voxels, surface samples, collision parts) take tens of
MB and a trained model up to 100 MB, so below this a run would likely stop midway on a full
disk; rendered HBEO training sets need more (docs/reference-models.md)."""

_FIX = f"set {CACHE_ENV} to a writable directory with free space"


def check_root(
    writable: bool = True, min_free: int = MIN_FREE_BYTES, root: Path | None = None
) -> Path:
    """The cache root, checked once as a command starts, so that a cache that cannot work
    fails now with one line rather than later inside a worker: it must be a directory (or
    not exist yet: it is then created, as the first entry would create it) and, when
    ``writable``, accept a new file and have ``min_free`` bytes free.
    :class:`~beo_bench.errors.CacheDirError` (exit status 2) says which and how to fix it.
    ``root``: the cache to check (default: the environment's)."""
    root = resolve_root(root)
    named = os.environ.get(CACHE_ENV)  # only to say where the root came from
    where = (
        f"the asset cache {root} (${CACHE_ENV})"
        if named and Path(named) == root
        else (f"the asset cache {root}")
    )
    if root.exists() and not root.is_dir():
        raise CacheDirError(f"{where} is not a directory; {_FIX}")
    if not root.exists() and not writable:
        return root  # nothing cached yet: an empty cache to report
    try:
        root.mkdir(parents=True, exist_ok=True)
        if writable:
            # a real write: permission bits say nothing on a read-only mount, or for root
            fd, probe = tempfile.mkstemp(prefix=".write-probe.", suffix=".tmp", dir=root)
            os.close(fd)
            os.unlink(probe)  # our own empty probe file
    except OSError as e:
        why = e.strerror or type(e).__name__
        if e.errno in (errno.ENOTDIR, errno.EEXIST):
            why = "a file is in the way of the directory"
        raise CacheDirError(f"{where} is not writable ({why}); {_FIX}") from e
    if writable:
        free = shutil.disk_usage(root).free
        if free < min_free:
            raise CacheDirError(
                f"{where} has {free / 2**20:.0f} MiB free, under the {min_free / 2**20:.0f} "
                f"MiB a run needs; free some space or {_FIX}"
            )
    return root


def mesh_hash(mesh: trimesh.Trimesh) -> str:
    """A content hash of a mesh's geometry (vertices rounded to 1e-9 m, and faces)."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(np.round(mesh.vertices, 9), dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    return h.hexdigest()[:32]


def check_kind(kind: str) -> str:
    """``kind`` if it is one of :data:`KINDS`; else :class:`UsageError` listing them."""
    if kind not in KINDS:
        kinds = ", ".join(KINDS)
        try:
            check_name(kind, "cache kind")
        except InvalidNameError as e:  # a path: say so, and what a kind is
            raise InvalidNameError(f"{e}; a cache kind is one of {kinds}") from None
        raise UsageError(
            f"unknown cache kind {kind!r}: use one of {kinds} (`beo-bench cache info` lists "
            "what the cache holds)"
        )
    return kind


def entry_path(kind: str, content: str, settings: dict[str, Any], root: Path | None = None) -> Path:
    """Where the ``kind`` entry of ``content`` processed with ``settings`` lives in the cache
    at ``root`` (default: the environment's)."""
    check_name(content, "cache content key")
    s = hashlib.sha256(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:16]
    return resolve_root(root) / check_kind(kind) / content[:2] / f"{content}-{s}.npz"


# -- the root's tag: what the cache may delete ------------------------------------------------
_claimed: set[str] = set()
"""Roots found or made tagged in this process (so the tag is looked at once per root)."""


def is_tagged(root: Path) -> bool:
    """Whether ``root`` carries the tag this package writes (another program's
    ``CACHEDIR.TAG`` does not count: its directory is not ours to clear)."""
    try:
        text = (root / TAG_NAME).read_text(errors="replace")
    except OSError:
        return False
    return text.startswith(TAG_SIGNATURE) and "beo-bench" in text


def claim_root(root: Path | None = None) -> bool:
    """Tag the cache root as this package's, when this package creates it: it does not
    exist yet, is empty, or is the default ``~/.cache/beo_bench`` (which only this package
    uses; so a cache made by an older version without a tag is adopted). A non-empty
    directory that ``$BEO_BENCH_CACHE`` points at is left untagged: entries are still
    written there on request, but :func:`clear` will not delete anything in it. Returns
    whether the root is tagged."""
    root = resolve_root(root)
    if str(root) in _claimed:
        return True
    if not is_tagged(root):
        try:
            if root.exists() and any(root.iterdir()) and root != default_root():
                return False
            root.mkdir(parents=True, exist_ok=True)
            with open(root / TAG_NAME, "x") as f:  # "x": never overwrite someone's file
                f.write(TAG_TEXT)
        except FileExistsError:  # another process tagged it first (or a foreign tag)
            return is_tagged(root)
        except OSError:  # not a directory, or not writable: then nothing is ours here
            return False
    _claimed.add(str(root))
    return True


def claim_for(path: Path, root: Path | None = None) -> None:
    """Call before writing ``path``: tags the cache ``root`` (default: the environment's)
    first when ``path`` lies in it (a model saved elsewhere, e.g. a test's temporary
    directory, claims nothing)."""
    root = resolve_root(root).absolute()
    if Path(path).absolute().is_relative_to(root):
        claim_root(root)


# -- entries ------------------------------------------------------------------------------------
def array_checksum(arrays: Mapping[str, np.ndarray]) -> str:
    """32 hex digits of SHA-256 over the arrays' names, dtypes, shapes and bytes (in name
    order, :data:`CHECKSUM_KEY` left out): the bytes a reader gets, whatever the file's
    compression or zip headers."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        if name == CHECKSUM_KEY:
            continue
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}:{a.dtype.str}:{a.shape};".encode())
        try:
            h.update(a.data)  # the array's own buffer, not a tobytes() copy
        except (TypeError, ValueError, BufferError):  # dtypes without a buffer (datetime)
            h.update(a.tobytes())
    return h.hexdigest()[:32]


def with_checksum(arrays: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``arrays`` and their :func:`array_checksum` under :data:`CHECKSUM_KEY`."""
    if CHECKSUM_KEY in arrays:
        raise ValueError(f"{CHECKSUM_KEY!r} is reserved for the entry's checksum")
    return {**arrays, CHECKSUM_KEY: np.array(array_checksum(arrays))}


def checksum_problem(arrays: Mapping[str, np.ndarray]) -> str | None:
    """Why ``arrays`` (read back from a file written with :func:`with_checksum`) cannot be
    trusted, or None when their checksum matches."""
    if CHECKSUM_KEY not in arrays:
        return "it has no checksum (written by an older version)"
    if str(arrays[CHECKSUM_KEY]) != array_checksum(arrays):
        return "its arrays do not match their checksum"
    return None


def atomic_save_npz(path: Path, **arrays: np.ndarray) -> None:
    """Write ``arrays`` to ``path`` so that no reader ever sees a partial file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(path, perms=0o600) as f:  # private to the user, as it always was
        members: dict[str, Any] = dict(arrays)  # (typed: mypy reads **arrays as savez options)
        np.savez_compressed(f, **members)


ENTRY_BUDGET = 256 << 20
"""Most bytes one entry may unpack to (the largest, a dense real mesh's parts, take a few
MB): a file declaring more is damage or a zip bomb, refused before it is unpacked."""

_PARTS = {"vertices": (None, 3), "counts": (None,), "faces": (None, 3), "face_counts": (None,)}
_MESH = {"vertices": (None, 3), "faces": (None, 3), "symmetry": ()}
_SHAPES: dict[str, Callable[[dict[str, Any]], dict[str, tuple[int | None, ...]]]] = {
    # each kind's arrays as its writer (objects.instance, loaders, objectset, means) makes
    # them; a voxel grid's packed length follows from D, so a short one is refused
    "voxels": lambda s: {"occ": ((int(s["D"]) ** 3 + 7) // 8,)},
    "surface": lambda s: {"points": (int(s["n"]), 3), "normals": (int(s["n"]), 3)},
    "coacd": lambda s: dict(_PARTS),
    "loaded": lambda s: {"vertices": (None, 3), "faces": (None, 3)},
    "symmetry": lambda s: {"continuous": (None, 6), "discrete": (None, 4, 4)},
    "generated": lambda s: {**_MESH, **{f"part_{k}": v for k, v in _PARTS.items()}},
    "classmeans": lambda s: {
        "shape": (len(s["categories"]), *(int(s["D"]),) * 3),
        "size": (len(s["categories"]), 3),
    },
    "truth": lambda s: {"samples": (None, 3), "edt2": (int(s["D"]),) * 3, "own": (None,)},
}
_KINDS: dict[str, dict[str, str]] = {
    "voxels": {"occ": "u"},
    "truth": {"edt2": "i"},
    "generated": {"symmetry": "U", "faces": "i", "part_counts": "i", "part_faces": "i"},
    "coacd": {"counts": "i", "faces": "i", "face_counts": "i"},
    "loaded": {"faces": "i"},
}
"""dtype kinds other than real floats, per kind and array (counts and indices are
integers, packed bits unsigned bytes, a symmetry record text)."""


def _parts_problem(a: Mapping[str, np.ndarray], p: str = "") -> str | None:
    """Why packed convex parts (processing.pack_parts) would unpack to wrong meshes."""
    counts, face_counts = a[f"{p}counts"], a[f"{p}face_counts"]
    if len(counts) != len(face_counts) or (counts < 0).any() or (face_counts < 0).any():
        return "part counts that do not pair up"
    if counts.sum() != len(a[f"{p}vertices"]) or face_counts.sum() != len(a[f"{p}faces"]):
        return "part counts that do not add up to the vertices and faces"
    limit = np.repeat(counts, face_counts)[:, None]  # each face indexes its own part
    if len(a[f"{p}faces"]) and ((a[f"{p}faces"] < 0) | (a[f"{p}faces"] >= limit)).any():
        return "part faces indexing outside their part"
    return None


def entry_problem(kind: str, arrays: Mapping[str, np.ndarray]) -> str | None:
    """Why the arrays of a ``kind`` entry, of the right names, dtypes and shapes, hold
    values its writer never makes (NaN, out-of-range indices or occupancies), or None."""
    floats = [a for a in arrays.values() if a.dtype.kind == "f"]
    if not all(np.isfinite(a).all() for a in floats):
        return "NaN or infinite values"
    if kind == "surface":
        norms = np.linalg.norm(arrays["normals"], axis=1)
        if len(norms) and np.abs(norms - 1).max() > 1e-3:
            return "normals that are not unit vectors"
    if kind == "truth":
        edt2, D = arrays["edt2"], len(arrays["edt2"])
        if len(arrays["samples"]) > 1 << 20 or (
            edt2.size and (edt2.min() < 0 or edt2.max() > 3 * D * D)
        ):
            return "more samples than scoring takes, or squared distances outside the grid"
    if kind == "classmeans":
        shape, size = arrays["shape"], arrays["size"]
        if (shape.size and (shape.min() < 0 or shape.max() > 1)) or (size <= 0).any():
            return "mean occupancies outside [0, 1] or sizes that are not positive"
    if kind in ("generated", "loaded"):
        faces, n = arrays["faces"], len(arrays["vertices"])
        if len(faces) == 0 or faces.min() < 0 or faces.max() >= n:
            return "mesh faces indexing outside its vertices"
        return _parts_problem(arrays, "part_") if kind == "generated" else None
    if kind == "coacd":
        return _parts_problem(arrays)
    return None


def _read_entry(
    path: Path, kind: str | None = None, settings: dict[str, Any] | None = None
) -> dict[str, np.ndarray] | None:
    """The verified arrays of the entry at ``path``, or None when it is missing or cannot be
    trusted (unreadable, truncated, no or wrong checksum; for a ``kind`` this package
    knows, made with ``settings``: other names, dtypes, shapes or values than its writer
    makes): then it is recomputed. Each member's header is checked before it is unpacked
    (:func:`beo_bench.safe_npz.read_npz`), so a zip bomb costs no memory."""
    from beo_bench.safe_npz import REAL, TEXT, read_npz

    if not path.exists():
        return None
    shapes = None
    try:
        if kind in _SHAPES and settings is not None:
            shapes = {**_SHAPES[kind](settings), CHECKSUM_KEY: ()}
    except (KeyError, TypeError, ValueError):  # settings of another form: no shapes known
        shapes = None
    kinds = {**_KINDS.get(kind or "", {}), CHECKSUM_KEY: TEXT}
    try:
        # allow_pickle stays off in read_npz: an entry is arrays, never code
        arrays = read_npz(
            path,
            budget=ENTRY_BUDGET,
            kinds=kinds if shapes is not None else REAL + TEXT,
            shapes=shapes,
            names=None if shapes is None else shapes.keys(),
        )
        if shapes is not None and set(arrays) | {CHECKSUM_KEY} != set(shapes):
            raise ValueError(f"arrays {sorted(arrays)}, expected {sorted(shapes)}")
    except Exception as e:  # zip, zlib, format and OS errors alike: a torn or damaged file
        _log.warning("cache entry %s is unreadable (%s); recomputing it", path, e)
        return None
    problem = checksum_problem(arrays)
    if problem is None and shapes is not None:
        # a valid checksum proves only that the file is whole, not that its writer was us
        problem = entry_problem(str(kind), arrays)
    if problem is not None:
        # an old entry is expected after an upgrade; a wrong checksum means damage
        log = _log.debug if CHECKSUM_KEY not in arrays else _log.warning
        log("cache entry %s: %s; recomputing it", path, problem)
        return None
    del arrays[CHECKSUM_KEY]
    return arrays


def cached(
    kind: str,
    content: str,
    settings: dict[str, Any],
    compute: Callable[[], dict[str, np.ndarray]],
    root: Path | None = None,
) -> dict[str, np.ndarray]:
    """Load an entry from the cache at ``root`` (default: the environment's), or compute and
    store it. An entry that cannot be read or does not match its checksum or its kind's
    arrays (a disk error, a tampered or an older file) is recomputed and atomically replaced
    rather than trusted."""
    root = resolve_root(root)
    path = entry_path(kind, content, settings, root)
    found = _read_entry(path, kind, settings)
    if found is not None:
        return found
    arrays = {k: np.asarray(v) for k, v in compute().items()}
    claim_for(path, root)
    try:
        atomic_save_npz(path, **with_checksum(arrays))
    except OSError as e:
        if e.errno not in _UNWRITABLE:
            raise
        # the user's set-up, not a bug: said as such, also from a worker (bench.pool)
        raise CacheDirError(
            f"cannot write the asset cache entry {path} ({e.strerror}); {_FIX}"
        ) from e
    return arrays


_UNWRITABLE = (errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC, errno.EDQUOT, errno.ENOTDIR)
"""Write errors that mean the cache directory cannot take entries (not a failing disk)."""


# -- info and clear -------------------------------------------------------------------------------
def _kind_dirs(root: Path, kinds: list[str]) -> list[Path]:
    """The directories of ``kinds`` under ``root``: real directories only. A symbolic link
    in their place was not made by the cache and is never followed out of the root."""
    out = []
    for kind in kinds:
        d = root / kind
        if d.is_symlink():
            _log.warning("%s is a symbolic link, not a cache directory: left alone", d)
        elif d.is_dir():
            out.append(d)
    return out


def _tree_bytes(top: Path) -> tuple[int, int]:
    """(``.npz`` files, bytes of all files) under ``top``; links are counted as links, never
    followed."""
    entries, size = 0, 0
    for dirpath, _, files in os.walk(top):  # os.walk does not follow directory links
        for f in files:
            st = os.lstat(os.path.join(dirpath, f))
            size += st.st_size
            entries += f.endswith(".npz")
    return entries, size


def info(root: Path | None = None) -> dict[str, Any]:
    """Per-kind entry counts and sizes (known kinds only) of the cache at ``root`` (default:
    the environment's)."""
    root = resolve_root(root)
    kinds: dict[str, dict[str, int]] = {}
    for d in _kind_dirs(root, sorted(KINDS)):
        entries, size = _tree_bytes(d)
        kinds[d.name] = {"entries": entries, "bytes": size}
    return {"root": str(root), "kinds": kinds, "bytes": sum(k["bytes"] for k in kinds.values())}


def clear(kind: str | None = None, root: Path | None = None) -> int:
    """Remove every entry (or every entry of ``kind``, one of :data:`KINDS`); returns bytes
    freed. Only the known kind directories of a root this package tagged are removed:
    anything else in the root, and any root without the tag, is left alone
    (:class:`UsageError` for an unknown kind or an untagged root holding kind directories).
    ``root``: the cache to clear (default: the environment's)."""
    kinds = list(KINDS) if kind is None else [check_kind(kind)]
    root = resolve_root(root)
    targets = _kind_dirs(root, kinds)
    if not targets:
        return 0
    if not claim_root(root):
        raise UsageError(
            f"{root} does not carry beo-bench's {TAG_NAME}, so it may not be a beo-bench cache "
            f"and nothing was deleted: check ${CACHE_ENV}; if it is an old beo-bench cache, "
            f"delete what you want yourself (e.g. `rm -r {targets[0]}`)"
        )
    freed = 0
    for d in targets:
        freed += _tree_bytes(d)[1]
        shutil.rmtree(d)  # fd-based on Linux: links inside are removed, never followed
    return freed
