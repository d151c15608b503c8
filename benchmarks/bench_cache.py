"""Asset cache figures: the cost of a hot (on-disk) cache read on the paths every backend
and scene takes, voxel grids (32^3) and surface samples, including the entry's checksum
check; and the checksum alone. Run alone with ``python benchmarks/run.py cache``."""

from __future__ import annotations

from harness import median_ms_per_item, report, use_fresh_cache

from beo_bench.objects import ObjectSet, cache

REPEAT = 5
"""Loads timed per instance (each reads the entry from disk: the cache keeps no copy)."""


def main() -> None:
    use_fresh_cache()
    objects = ObjectSet("test", ("mug", "car", "chair", "bowl"), per_category=5)
    insts = [objects.get(c, i) for c in objects.categories for i in range(5)]
    for inst in insts:  # fill the cache (the cold path is bench_objects' business)
        inst.voxels(32)
        inst.surface_points()
    items = [inst for inst in insts for _ in range(REPEAT)]
    vox = median_ms_per_item(lambda i: i.voxels(32), items)
    report("hot voxels(32) load from the disk cache", vox, "ms", "< 2 ms", vox < 2)
    surf = median_ms_per_item(lambda i: i.surface_points(), items)
    report("hot surface_points() load from the disk cache", surf, "ms", "< 2 ms", surf < 2)
    checksum = getattr(cache, "array_checksum", None)
    if checksum is not None:
        arrays = {
            "points": insts[0].surface_points()[0],
            "normals": insts[0].surface_points()[1],
        }
        ms = median_ms_per_item(lambda a: checksum(a), [arrays] * 50)
        report("checksum of one surface entry (arrays only)", ms, "ms", "report")


if __name__ == "__main__":
    main()
