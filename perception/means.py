"""What the baselines learn from the object library's ``train`` split: per-class mean
shapes and sizes, and how objects rest on a table.

The ``random`` bound predicts the means, ``icp`` aligns observations to them. Computed once
per (categories, resolution, instances) and cached atomically in the asset cache.

The rest prior (:class:`~beo_bench.types.RestPrior`) is the tilt of objects' up from the
world's up in the training split's own tabletop scenes: what HBEO and the MDN absorb from
their tabletop training crops, fitted here so that ``beo`` (its pose prior P(R), eq. 3.22)
and ``icp`` (its starting rotations) may use it on the ``tabletop`` and ``pick`` views
(docs/benchmark.md, "What a backend is told"). It is published
(``perception/published/rest-prior``, ``beo-bench publish rest-prior`` refits it) so that
every machine uses the same one.
"""

from __future__ import annotations

import functools
import hashlib
import multiprocessing as mp
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from beo_bench.objects import cache
from beo_bench.objects.datasets import object_set
from beo_bench.objects.prepare import prepare
from beo_bench.types import RestPrior

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset

MEANS_VERSION = 1
REST_SCENES = 300
"""Training-split tabletop scenes the rest prior is fitted on (about 750 objects)."""
REST_SEED = 91_000
"""Their base seed (scene i is ``BEOPick-v0``'s draw under seed ``REST_SEED + i`` from the
``train`` split: none of a suite's scenes, which are of the ``test`` split)."""
REST_BANDWIDTH_DEG = 1.0
"""The kernel's width: above the physics' settling jitter (0.01-0.1 deg in these scenes)
and below the searches' finest steps, so a pose a degree from a training tilt is not
penalised."""


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
    cache_root: Path | None = None,
) -> ClassMeans:
    """Means over the first ``per_category`` (default: all) ``train`` instances of each
    category (see :func:`training_voxels`), cached. On a user's ``dataset`` (None: the
    procedural library) its instances instead: its ``train`` split, or every model when a
    class has none there (a small folder's hash split). ``cache_root``: the asset cache
    (None: the environment's)."""
    from beo_bench.objects.datasets import reference_split

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
            categories, resolution, per_category, progress, dataset, split, cache_root
        )
        return {
            "shape": np.asarray([grids[c].mean(axis=0) for c in categories], dtype=np.float32),
            "size": np.asarray([sizes[c].mean(axis=0) for c in categories], dtype=np.float64),
        }

    if dataset is None and per_category is None:
        # the library's every training instance: the published means, when they hold these
        # classes at this resolution (bitwise what ``compute`` gives: no training voxels)
        got = published_class_means(tuple(categories), resolution)
        if got is not None:
            return got
    arrays = cache.cached("classmeans", key, settings, compute, cache_root)
    return ClassMeans(tuple(categories), arrays["shape"], arrays["size"])


CLASS_MEANS_STEM = "class-means"
"""The published means of every library class over all its ``train`` instances
(``perception/published/class-means``; ``beo-bench publish class-means`` refits them)."""


def means_arrays(counts: np.ndarray, n: np.ndarray, size: np.ndarray) -> ClassMeans:
    """The means from their lossless storage: per class the (D, D, D) count of training
    instances filling each cell (uint8: at most 255 instances) and the instance count ``n``.
    ``count / n`` in float64, cast to float32, is bitwise ``grids.mean(axis=0)`` cast to
    float32 (a bool array's mean is its exact integer sum over n)."""
    shape = (counts.astype(np.float64) / n.astype(np.float64)[:, None, None, None]).astype(
        np.float32
    )
    return ClassMeans((), shape, np.asarray(size, dtype=np.float64))


@functools.lru_cache(maxsize=1)
def _published_means() -> tuple[dict[str, object], dict[str, np.ndarray]] | None:
    from beo_bench.objects import LIBRARY_VERSION
    from beo_bench.perception import published

    if f"{CLASS_MEANS_STEM}.npz" not in published.manifest():
        return None
    meta, arrays = published.read(CLASS_MEANS_STEM)
    if meta.get("library_version") != LIBRARY_VERSION or meta.get("version") != MEANS_VERSION:
        return None  # made for another object library or means format: computed instead
    return meta, arrays


def published_class_means(categories: tuple[str, ...], resolution: int) -> ClassMeans | None:
    """The published means of ``categories`` at ``resolution`` over every ``train``
    instance of the library, or None when they are not published so (computed then)."""
    got = _published_means()
    if got is None:
        return None
    meta, arrays = got
    names = list(meta["categories"])  # type: ignore[call-overload]
    if meta.get("D") != resolution or not set(categories) <= set(names):
        return None
    idx = [names.index(c) for c in categories]
    m = means_arrays(arrays["counts"][idx], arrays["n"][idx], arrays["size"][idx])
    return ClassMeans(tuple(categories), m.shape, m.size)


def publish_class_means(
    root: Path | None = None, resolution: int = 32, progress: bool = False
) -> str:
    """Compute the means of every library class over all its ``train`` instances (cached
    in the asset cache) and publish them, stored losslessly (:func:`means_arrays`); returns
    the npz's SHA-256. Refuses to write means that would not read back bitwise."""
    from beo_bench.objects import LIBRARY_VERSION, categories
    from beo_bench.perception import published

    cats = tuple(categories())
    grids, sizes = training_voxels(cats, resolution, None, progress)
    n = np.asarray([len(grids[c]) for c in cats], dtype=np.int64)
    if n.max() > 255:
        raise ValueError(f"{n.max()} training instances of a class: uint8 counts hold 255")
    counts = np.stack([grids[c].sum(axis=0) for c in cats]).astype(np.uint8)
    size = np.stack([sizes[c].mean(axis=0) for c in cats]).astype(np.float64)
    back = means_arrays(counts, n, size)
    want = np.asarray([grids[c].mean(axis=0) for c in cats], dtype=np.float32)
    if not np.array_equal(back.shape, want):  # the storage's promise, checked on the data
        raise AssertionError("the published class means would not read back bitwise")
    meta = {
        "format": 1,
        "version": MEANS_VERSION,
        "library_version": LIBRARY_VERSION,
        "categories": list(cats),
        "D": resolution,
        "split": "train",
    }
    arrays: dict[str, np.ndarray] = {"counts": counts, "n": n, "size": size}
    sha = published.write(CLASS_MEANS_STEM, meta, arrays, root or published.PUBLISHED_DIR)
    _published_means.cache_clear()
    return sha


def training_voxels(
    categories: tuple[str, ...],
    resolution: int = 32,
    per_category: int | None = None,
    progress: bool = False,
    dataset: Dataset | None = None,
    split: str = "train",
    cache_root: Path | None = None,
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Per category, the (n, D, D, D) bool voxel grids and (n, 3) extents of the first
    ``per_category`` (default: all) ``train`` instances. The first call voxelises them in
    worker processes (one per core; in this process inside a daemonic worker, which may not
    start children), which also caches their meshes, samples and parts; later calls read
    the disk cache. ``dataset``: a user's dataset instead of the procedural library, and
    ``split`` instead of ``train``; ``cache_root``: the asset cache (None: the
    environment's)."""
    objects = object_set(dataset, split, categories, per_category, cache_root)
    workers = 1 if mp.current_process().daemon else None
    prepare(objects, D=resolution, workers=workers, progress=progress)
    grids, sizes = {}, {}
    for c in categories:
        insts = objects.instances(c)
        grids[c] = np.stack([i.voxels(resolution) for i in insts])
        sizes[c] = np.stack([np.asarray(i.size, dtype=np.float64) for i in insts])
    return grids, sizes


def fit_rest_prior(
    scenes: int = REST_SCENES,
    seed: int = REST_SEED,
    bandwidth_deg: float = REST_BANDWIDTH_DEG,
    progress: bool = False,
) -> RestPrior:
    """The rest prior of the ``train`` split: every object's tilt (degrees between its
    canonical up and the world's up) in ``scenes`` tabletop scenes drawn as BEOPick-v0
    draws them (its default classes, settled by physics), sorted."""
    from tqdm import tqdm

    from beo_bench.scenes.pickconfig import PickConfig
    from beo_bench.scenes.tabletop import TabletopScenes

    tables = TabletopScenes(PickConfig(split="train"))  # BEOPick-v0's default classes
    tilts: list[float] = []
    try:
        for i in tqdm(range(scenes), desc="rest prior", disable=None if progress else True):
            _, truth = tables.reset(seed=seed + i)
            for g in truth:
                cos = float(np.clip(np.asarray(g.R_world)[2, 2], -1.0, 1.0))
                tilts.append(float(np.degrees(np.arccos(cos))))
    finally:
        tables.close()
    return RestPrior(tuple(sorted(tilts)), float(bandwidth_deg))


def rest_prior_meta(prior: RestPrior) -> dict[str, object]:
    """The published rest prior's ``rest-prior.json``: how it was fitted and its digest."""
    from beo_bench.perception.digest import state_digest

    return {
        "format": 1,
        "bandwidth_deg": prior.bandwidth_deg,
        "objects": len(prior.tilt_deg),
        "scenes": REST_SCENES,
        "seed": REST_SEED,
        "split": "train",
        "digest": state_digest(rest_prior_arrays(prior)),
    }


def rest_prior_arrays(prior: RestPrior) -> dict[str, np.ndarray]:
    return {
        "tilt_deg": np.asarray(prior.tilt_deg, dtype=np.float64),
        "bandwidth_deg": np.asarray(prior.bandwidth_deg, dtype=np.float64),
    }


@functools.lru_cache(maxsize=1)
def rest_prior() -> tuple[RestPrior, str]:
    """The published rest prior and its digest (checked against the manifest when read)."""
    from beo_bench.perception import published

    meta, arrays = published.read("rest-prior")
    prior = RestPrior(tuple(float(t) for t in arrays["tilt_deg"]), float(arrays["bandwidth_deg"]))
    return prior, str(meta["digest"])


def publish_rest_prior(root: Path | None = None, progress: bool = False) -> str:
    """Fit the rest prior on the training split's scenes and publish it (``beo-bench
    publish rest-prior``); returns its npz's SHA-256."""
    from beo_bench.perception import published

    prior = fit_rest_prior(progress=progress)
    return published.write(
        "rest-prior",
        rest_prior_meta(prior),
        rest_prior_arrays(prior),
        root or published.PUBLISHED_DIR,
    )
