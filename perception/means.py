"""Per-class mean shapes and sizes from the object library's ``train`` split.

The ``random`` bound predicts them, ``icp`` aligns observations to them. Computed once per
(categories, resolution, instances) and cached atomically in the asset cache.
"""

from __future__ import annotations

import hashlib
import multiprocessing as mp
from dataclasses import dataclass

import numpy as np

from beo_bench.objects import ObjectSet, cache
from beo_bench.objects.prepare import prepare

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
) -> ClassMeans:
    """Means over the first ``per_category`` (default: all) ``train`` instances of each
    category. The first call voxelises the training instances in worker processes (one per
    core; in this process inside a daemonic worker, which may not start children) and
    caches the result."""
    settings = {
        "version": MEANS_VERSION,
        "categories": list(categories),
        "D": resolution,
        "n": per_category,
    }
    key = hashlib.sha256(repr(sorted(settings.items())).encode()).hexdigest()

    def compute() -> dict[str, np.ndarray]:
        objects = ObjectSet("train", categories, per_category=per_category)
        # instances are generated and voxelised in parallel (and their meshes, samples and
        # parts cached for later); the means below then read the disk cache
        workers = 1 if mp.current_process().daemon else None
        prepare(objects, D=resolution, workers=workers, progress=progress)
        shapes, sizes = [], []
        for c in categories:
            insts = objects.instances(c)
            shapes.append(np.mean([i.voxels(resolution) for i in insts], axis=0))
            sizes.append(np.mean([i.size for i in insts], axis=0))
        return {
            "shape": np.asarray(shapes, dtype=np.float32),
            "size": np.asarray(sizes, dtype=np.float64),
        }

    arrays = cache.cached("classmeans", key, settings, compute)
    return ClassMeans(tuple(categories), arrays["shape"], arrays["size"])
