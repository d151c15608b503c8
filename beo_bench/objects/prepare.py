"""Process many instances in parallel worker processes: voxels, surface samples and
collision parts (CoACD for loaded meshes) land in the cache, and per-instance statistics
come back.

Workers receive unbuilt copies of the instances (their recipes: procedural parameters, or a
file's path and loading options; not meshes) that name the cache directory
(``ObjectInstance.cache_dir``), and build them themselves, so nothing large crosses process
boundaries, no dataset root has to be known there and no worker reads its environment for
the cache; the cache's atomic writes make concurrent workers safe.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import pickle
import time
import warnings
from collections.abc import Iterable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace
from typing import Any, Literal

from tqdm import tqdm

from beo_bench.errors import BeoBenchError
from beo_bench.objects import cache
from beo_bench.objects.datasets.meshfile import UnknownSizeWarning, warn_unknown_size
from beo_bench.objects.instance import ObjectInstance
from beo_bench.objects.processing import DEFAULT_RESOLUTION
from beo_bench.objects.symmetry import symmetry_name


@dataclass(frozen=True)
class InstanceStats:
    """What processing one instance measured."""

    key: str
    category: str
    extents: tuple[float, float, float]
    """Bounding-box size (x, y, z) in metres."""
    volume: float
    symmetry: str
    """:func:`~beo_bench.objects.symmetry.symmetry_name` of the group: ``none``, ``<n>-fold``
    (cyclic), ``<n>-fold+flips`` (dihedral: a box with distinct sides is ``2-fold+flips``),
    ``continuous``, ``continuous+flip``, ..."""
    parts: int
    generate_s: float
    """Building the mesh (primitives and union, or reading and repairing a file)."""
    process_s: float
    """Voxels, surface samples and collision parts (cold: computed; warm: from cache)."""


def process(inst: ObjectInstance, D: int = DEFAULT_RESOLUTION) -> InstanceStats:
    """Build one instance and fill its cache entries."""
    t0 = time.perf_counter()
    mesh = inst.mesh
    t1 = time.perf_counter()
    inst.voxels(D)
    inst.surface_points()
    parts = inst.collision_parts()
    label = symmetry_name(inst.symmetry)
    t2 = time.perf_counter()
    return InstanceStats(
        key=inst.key,
        category=inst.category,
        extents=(float(mesh.extents[0]), float(mesh.extents[1]), float(mesh.extents[2])),
        volume=float(mesh.volume),
        symmetry=label,
        parts=len(parts),
        generate_s=t1 - t0,
        process_s=t2 - t1,
    )


def _process_unbuilt(inst: ObjectInstance, D: int) -> tuple[dict[str, Any], list[Warning]]:
    """:func:`process` in a worker, with the warnings it raised: recorded, not printed (a
    worker's default printout is Python's two-line form with the source line, once per
    worker), for the parent to show once (:func:`_reemit`)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        d = asdict(process(inst, D))
    d["extents"] = tuple(d["extents"])
    return d, [_picklable(w.message) for w in caught if isinstance(w.message, Warning)]


def _picklable(w: Warning) -> Warning:
    """``w``, or its text as a plain ``UserWarning`` when it does not survive pickling
    (a warning class defined in a function, arguments that do not pickle)."""
    try:
        pickle.loads(pickle.dumps(w))
    except Exception:
        return UserWarning(f"{type(w).__name__}: {w}")
    return w


def _reemit(ws: list[Warning], seen: set[tuple[type, str]]) -> None:
    """Show warnings a worker recorded, each once (``seen``: what this call showed before;
    an unknown-size warning once per process, as loading in this process gives it)."""
    for w in ws:
        if isinstance(w, UnknownSizeWarning):
            warn_unknown_size(w.category)
        elif (type(w), str(w)) not in seen:
            seen.add((type(w), str(w)))
            warnings.warn(w, stacklevel=2)


def prepare(
    instances: Iterable[ObjectInstance],
    D: int = DEFAULT_RESOLUTION,
    workers: int | None = None,
    progress: bool = True,
    on_error: Literal["raise", "skip"] = "raise",
) -> list[InstanceStats]:
    """Process ``instances`` with ``workers`` processes (default: all cores; 1 runs in this
    process); results come back in input order.

    An instance that fails (a corrupt file, a mesh that cannot be repaired) does not stop
    the others: afterwards ``on_error="raise"`` raises the first failure, naming how many
    failed, and ``"skip"`` leaves the failures out of the result.

    The entries go to each instance's cache (``ObjectInstance.cache_dir``; None: the
    environment's, read here, once): a worker is handed it with the instance, never through
    its environment (a forkserver keeps the environment of its first use).
    """
    insts = list(instances)
    workers = (os.cpu_count() or 1) if workers is None else workers
    bar = tqdm(
        total=len(insts), desc="processing objects", unit="obj", disable=None if progress else True
    )
    out: list[InstanceStats] = []
    failed: list[tuple[str, BeoBenchError]] = []
    if workers <= 1 or len(insts) <= 1:
        for inst in insts:
            try:
                out.append(process(inst, D))
            except BeoBenchError as e:
                failed.append((inst.key, e))
            bar.update()
    else:
        # forkserver: workers start clean; a forked copy of a process that already runs
        # embree, torch or GL threads can deadlock
        ctx = mp.get_context("forkserver")
        root = cache.cache_root()
        # replace(): a copy without the built mesh, which would otherwise be pickled too
        unbuilt = [replace(i, cache_dir=i.cache_dir or root) for i in insts]
        seen: set[tuple[type, str]] = set()
        with ProcessPoolExecutor(workers, mp_context=ctx) as pool:
            futures = [(i.key, pool.submit(_process_unbuilt, i, D)) for i in unbuilt]
            for key, f in futures:
                try:
                    stats, said = f.result()
                    out.append(InstanceStats(**stats))
                    _reemit(said, seen)
                except BeoBenchError as e:
                    failed.append((key, e))
                bar.update()
    bar.close()
    if failed and on_error == "raise":
        key, first = failed[0]
        raise type(first)(
            f"{len(failed)} of {len(insts)} instances failed; first: {key}: {first}"
        ) from first
    return out
