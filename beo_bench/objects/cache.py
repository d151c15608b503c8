"""The on-disk asset cache: content-addressed, written atomically.

Entries live under ``$BEO_BENCH_CACHE`` (default ``~/.cache/beo_bench``), one ``.npz`` file
per (mesh content hash, processing settings). Writers go through a temporary file in the
same directory and ``os.replace``, so a reader in another process sees either nothing or the
whole file, and a killed writer leaves only a ``.tmp`` file that :func:`clear` and the next
writer ignore.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

CACHE_ENV = "BEO_BENCH_CACHE"


def cache_root() -> Path:
    """The cache directory (``$BEO_BENCH_CACHE`` or ``~/.cache/beo_bench``)."""
    return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "beo_bench")


def mesh_hash(mesh: trimesh.Trimesh) -> str:
    """A content hash of a mesh's geometry (vertices rounded to 1e-9 m, and faces)."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(np.round(mesh.vertices, 9), dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    return h.hexdigest()[:32]


def entry_path(kind: str, content: str, settings: dict[str, Any]) -> Path:
    """Where the ``kind`` entry of ``content`` processed with ``settings`` lives."""
    s = hashlib.sha256(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:16]
    return cache_root() / kind / content[:2] / f"{content}-{s}.npz"


def atomic_save_npz(path: Path, **arrays: np.ndarray) -> None:
    """Write ``arrays`` to ``path`` so that no reader ever sees a partial file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez_compressed(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def cached(
    kind: str, content: str, settings: dict[str, Any], compute: Callable[[], dict[str, np.ndarray]]
) -> dict[str, np.ndarray]:
    """Load an entry, or compute and store it. A corrupt entry (e.g. from a disk error) is
    recomputed rather than trusted."""
    path = entry_path(kind, content, settings)
    if path.exists():
        try:
            with np.load(path) as z:
                return {k: z[k] for k in z.files}
        except Exception:
            path.unlink(missing_ok=True)
    arrays = compute()
    atomic_save_npz(path, **arrays)
    return arrays


def info() -> dict[str, Any]:
    """Per-kind entry counts and sizes."""
    root = cache_root()
    kinds: dict[str, dict[str, int]] = {}
    if root.exists():
        for d in sorted(p for p in root.iterdir() if p.is_dir()):
            files = [f for f in d.rglob("*.npz")]
            kinds[d.name] = {"entries": len(files), "bytes": sum(f.stat().st_size for f in files)}
    return {"root": str(root), "kinds": kinds, "bytes": sum(k["bytes"] for k in kinds.values())}


def clear(kind: str | None = None) -> int:
    """Remove every entry (or every entry of ``kind``); returns bytes freed."""
    root = cache_root()
    target = root / kind if kind else root
    if not target.exists():
        return 0
    freed = sum(f.stat().st_size for f in target.rglob("*") if f.is_file())
    shutil.rmtree(target)
    return freed
