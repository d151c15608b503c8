"""Per-class mean shapes and sizes from the object library's ``train`` split.

The ``random`` bound predicts them, ``icp`` aligns observations to them. Computed once per
(categories, resolution, instances) and cached atomically in the asset cache.
"""

from __future__ import annotations

import hashlib
import multiprocessing as mp
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from beo_bench.objects import cache
from beo_bench.objects.dataset import object_set
from beo_bench.objects.prepare import prepare

if TYPE_CHECKING:
    from beo_bench.objects.dataset import Dataset

MEANS_VERSION = 1


@dataclass(frozen=True)
class ClassMeans:
    """``shape[c]``: (D, D, D) float32 mean occupancy of class c's training voxels (the
    fraction of instances filling each cell); ``size[c]``: (3,) mean extents (m)."""

    categories: tuple[str, ...]
    shape: np.ndarray  # (C, D, D, D) float32
    size: np.ndarray  # (C, 3)


def class_means(
    categories: tuple[str, ...],
    resolution: int = 32,
    per_category: int | None = None,
    progress: bool = False,
    dataset: Dataset | None = None,
) -> ClassMeans:
    """Means over the first ``per_category`` (default: all) ``train`` instances of each
    category (see :func:`training_voxels`), cached. On a user's ``dataset`` (None: the
    procedural library) its instances instead: its ``train`` split, or every model when a
    class has none there (a small folder's hash split)."""
    from beo_bench.objects.dataset import reference_split

    settings: dict[str, object] = {
        "version": MEANS_VERSION,
        "categories": list(categories),
        "D": resolution,
        "n": per_category,
    }
    split = "train"
    if dataset is not None:  # only then: the library's cache keys stay as they were
        split = reference_split(dataset, categories)
        settings["dataset"] = dataset.identity()
        settings["split"] = split
    key = hashlib.sha256(repr(sorted(settings.items())).encode()).hexdigest()

    def compute() -> dict[str, np.ndarray]:
        grids, sizes = training_voxels(
            categories, resolution, per_category, progress, dataset, split
        )
        return {
            "shape": np.asarray([grids[c].mean(axis=0) for c in categories], dtype=np.float32),
            "size": np.asarray([sizes[c].mean(axis=0) for c in categories], dtype=np.float64),
        }

    arrays = cache.cached("classmeans", key, settings, compute)
    return ClassMeans(tuple(categories), arrays["shape"], arrays["size"])


def training_voxels(
    categories: tuple[str, ...],
    resolution: int = 32,
    per_category: int | None = None,
    progress: bool = False,
    dataset: Dataset | None = None,
    split: str = "train",
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Per category, the (n, D, D, D) bool voxel grids and (n, 3) extents of the first
    ``per_category`` (default: all) ``train`` instances. The first call voxelises them in
    worker processes (one per core; in this process inside a daemonic worker, which may not
    start children), which also caches their meshes, samples and parts; later calls read
    the disk cache. ``dataset``: a user's dataset instead of the procedural library, and
    ``split`` instead of ``train``."""
    objects = object_set(dataset, split, categories, per_category)
    workers = 1 if mp.current_process().daemon else None
    prepare(objects, D=resolution, workers=workers, progress=progress)
    grids, sizes = {}, {}
    for c in categories:
        insts = objects.instances(c)
        grids[c] = np.stack([i.voxels(resolution) for i in insts])
        sizes[c] = np.stack([np.asarray(i.size, dtype=np.float64) for i in insts])
    return grids, sizes
