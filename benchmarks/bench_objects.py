"""Object library figures: generation + voxelisation, parallel throughput,
collision parts (procedural and CoACD), and processing the whole default library."""

from __future__ import annotations

import time

from harness import median_time, report, use_fresh_cache

from beo_bench.geometry import no_symmetry
from beo_bench.objects import DEFAULT_SPLIT_SIZES, ObjectSet, categories
from beo_bench.objects.instance import ObjectInstance
from beo_bench.objects.objectset import procedural_instance
from beo_bench.objects.prepare import prepare
from beo_bench.objects.registry import Generated


def main() -> None:
    cats = categories()
    use_fresh_cache()
    # 1. generate + voxelise (32^3) one instance, cold cache, fresh instance objects
    keys = [(c, i) for i in range(4) for c in cats]
    it = iter(keys)

    def one() -> None:
        c, i = next(it)
        procedural_instance(c, "val", i).voxels(32)

    t = median_time(one, repeat=len(keys))
    report(
        "generate + voxelise 32^3, one instance (median)",
        1000 * t,
        "ms",
        "< 100 ms",
        t < 0.1,
        f"{len(keys)} instances over {len(cats)} categories",
    )

    # 1b. generation alone (parameters, parts, union, checks) per category: the slowest
    # category bounds how fast a cold library builds
    from beo_bench.objects.registry import generate, instance_params

    per_cat = {}
    for c in cats:
        params = [instance_params(c, "val", i) for i in range(8)]
        pit = iter(params)
        per_cat[c] = median_time(lambda c=c, pit=pit: generate(c, next(pit)), repeat=len(params))
    worst = max(per_cat, key=per_cat.__getitem__)
    report(
        "generate one instance, slowest category (median of 8)",
        1000 * per_cat[worst],
        "ms",
        "< 60 ms",
        per_cat[worst] < 0.06,
        f"{worst}; " + ", ".join(f"{c} {1000 * t:.0f}" for c, t in sorted(per_cat.items())),
    )

    # 2. throughput with 2 worker processes (pool start-up included)
    use_fresh_cache()
    objs = ObjectSet("train", per_category=8)
    t0 = time.perf_counter()
    prepare(objs, workers=2, progress=False)
    rate = len(objs) / (time.perf_counter() - t0)
    report(
        "instances/s, 2 workers (generate, voxels, samples, parts)",
        rate,
        "inst/s",
        ">= 20 /s",
        rate >= 20,
        f"{len(objs)} instances, cold cache",
    )

    # 3. collision parts of a procedural instance (built with the instance: exact parts)
    it2 = iter([(c, i) for i in range(4, 8) for c in cats])

    def parts() -> None:
        c, i = next(it2)
        procedural_instance(c, "val", i).collision_parts()

    t = median_time(parts, repeat=4 * len(cats))
    report("collision parts of a procedural instance (median)", 1000 * t, "ms", "< 50 ms", t < 0.05)

    # 4. CoACD on an outside mug-like mesh, then the cached second call
    mug = procedural_instance("mug", "test", 0).mesh.copy()
    outside = ObjectInstance(
        key="bench/mug",
        category="mug",
        split="test",
        index=0,
        source="folder",
        build=lambda _root: Generated(mug, None, no_symmetry()),
    )
    t0 = time.perf_counter()
    hulls = outside.collision_parts()
    cold = time.perf_counter() - t0
    report(
        "CoACD on an outside mug-like mesh",
        cold,
        "s",
        "report",
        None,
        f"{len(hulls)} hulls, threshold 0.1, preprocess off",
    )
    warm = median_time(outside.collision_parts, repeat=5)
    report("CoACD result, cached second call", 1000 * warm, "ms", "< 10 ms", warm < 0.01)

    # 4b. symmetry estimation of a loaded mesh (nearly equal moments: the slowest case)
    from beo_bench.objects.symmetry import estimate_symmetry

    mug_mesh = procedural_instance("mug", "test", 0).mesh
    t = median_time(lambda: estimate_symmetry(mug_mesh), repeat=3)
    report("estimate the symmetry group of a mug-like mesh (median)", t, "s", "< 1 s", t < 1.0)

    # 5. the whole default library, cold then warm
    use_fresh_cache()
    every = [inst for split in DEFAULT_SPLIT_SIZES for inst in ObjectSet(split)]
    t0 = time.perf_counter()
    prepare(every, workers=2, progress=False)
    cold = time.perf_counter() - t0
    report(
        "whole default library, cold (2 workers)",
        cold,
        "s",
        "report",
        None,
        f"{len(every)} instances, {len(every) / cold:.1f} inst/s",
    )
    t0 = time.perf_counter()
    prepare(every, workers=2, progress=False)
    warm = time.perf_counter() - t0
    report(
        "whole default library, warm (2 workers)",
        warm,
        "s",
        "report",
        None,
        "meshes rebuilt, voxels/samples from cache",
    )


if __name__ == "__main__":
    main()
