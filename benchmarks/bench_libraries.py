"""Libraries against our own code, in the same run: where a well-kept library could replace
hand-written code, is it as fast, and does it give the same numbers? (Issue 51, "Libraries
where they serve": swap only where every result stays the same and the library is as fast.)

- Point-to-surface distances (``metrics.Surface.distances``: the exact point-to-triangle
  distance over the ``NEAREST_TRIANGLES`` triangles with the nearest centroids), against
  trimesh's exact ``proximity.closest_point`` (an R-tree of the triangles' boxes), and the
  point-to-triangle kernel alone against ``trimesh.triangles.closest_point`` on the same
  candidate triangles. Queries: 1024 samples of another instance's surface, as Chamfer-L1
  and the F-score take them, against 32^3 marching-cubes truths (``scoring.truth_shape``).
  Embree (``embreex``) casts rays only: it has no point query, so it is no candidate here.
- Bootstrap intervals: ``stats.bootstrap_ci`` with ``groups`` (the summary's cluster
  bootstrap over items) and ``stats.ratio_interval`` (``compare``'s and the gate's paired
  interval) against ``scipy.stats.bootstrap`` with the same resamples (``paired=True`` over
  the items' sums and view counts, the same seeded ``numpy`` generator, the percentile
  method). scipy has no cluster bootstrap of its own: the statistic passed is ours.

For each: the library's time over ours (paired, alternating calls), and how far its results
are from ours (0: bit for bit). ``python benchmarks/run.py libraries`` runs it (about a
minute on 2 cores).
"""

from __future__ import annotations

import numpy as np
import trimesh
from harness import paired_median_times, report
from scipy import stats as scipy_stats

from beo_bench import metrics, stats
from beo_bench.bench import scoring as S
from beo_bench.objects import ObjectSet

CATEGORIES = 6
REPEAT = 7
RESAMPLES = 1000


# -- point-to-surface distances -----------------------------------------------------------------
def _kernel_trimesh(surface: metrics.Surface, q: np.ndarray) -> np.ndarray:
    """``Surface.distances`` with trimesh's point-to-triangle kernel on the same candidates."""
    k = min(metrics.NEAREST_TRIANGLES, len(surface.triangles))
    _, idx = surface._centroids.query(q, k=k)  # type: ignore[union-attr]
    tri = surface.triangles[np.asarray(idx).reshape(len(q), k)].reshape(-1, 3, 3)
    near = trimesh.triangles.closest_point(tri, np.repeat(q, k, axis=0))
    d = np.linalg.norm(near - np.repeat(q, k, axis=0), axis=1).reshape(len(q), k)
    return d.min(axis=1)


def distances() -> None:
    objects = ObjectSet("test")
    cases = []
    for cat in objects.categories[:CATEGORIES]:
        truth = S.truth_shape(objects.get(cat, 3).key, 32)
        other = S.truth_shape(objects.get(cat, 4).key, 32)
        mesh = S.grid_mesh(truth.voxels, mirror_outside=True)
        _ = mesh.triangles_tree  # built once per truth, as Surface's centroid tree is
        cases.append((truth.surface, mesh, np.asarray(other.surface.samples)))

    def ours() -> list[np.ndarray]:
        return [s.distances(q) for s, _, q in cases]

    def exact() -> list[np.ndarray]:
        return [trimesh.proximity.closest_point(m, q)[1] for _, m, q in cases]

    def kernel() -> list[np.ndarray]:
        return [_kernel_trimesh(s, q) for s, _, q in cases]

    mine = ours()
    t_exact, t_ours = paired_median_times(exact, ours, REPEAT)
    t_kernel, t_ours2 = paired_median_times(kernel, ours, REPEAT)
    d_exact = np.concatenate([a - b for a, b in zip(mine, exact(), strict=True)])
    d_kernel = np.concatenate([np.abs(a - b) for a, b in zip(mine, kernel(), strict=True)])
    tau = metrics.FSCORE_TAU
    crossed = [int(np.sum((a < tau) != (b < tau))) for a, b in zip(mine, exact(), strict=True)]
    chamfer = [abs(float(a.mean()) - float(b.mean())) for a, b in zip(mine, exact(), strict=True)]
    kernel_chamfer = [
        float(a.mean()) == float(b.mean()) for a, b in zip(mine, kernel(), strict=True)
    ]
    n = sum(len(q) for *_, q in cases)
    report(f"Surface.distances (ours), {n} points to {len(cases)} truths", 1000 * t_ours, "ms")
    report("  trimesh.proximity.closest_point (exact) over ours, same run", t_exact / t_ours,
           "x", "<= 1 to swap", t_exact <= t_ours)  # fmt: skip
    report("  share of points whose distance differs from ours", float(np.mean(d_exact != 0)),
           "", "0 to swap", bool(np.all(d_exact == 0)),
           f"{np.mean(d_exact > 1e-9):.3g} by more than 1e-9, where k = 4 misses")  # fmt: skip
    report("  ours - exact, at most (ours is an upper bound)", float(d_exact.max()), "",
           note=f"{d_exact.max():.3g} of the side, {d_exact.min():.3g} at least")  # fmt: skip
    report("  points crossing the F-score's tau, of all", float(sum(crossed)), "", "0 to swap",
           sum(crossed) == 0)  # fmt: skip
    report("  a view's Chamfer-L1 term moves by at most", max(chamfer), "", "0 to swap",
           max(chamfer) == 0, f"{max(chamfer):.3g}")  # fmt: skip
    report("  trimesh.triangles.closest_point kernel, same candidates, over ours",
           t_kernel / t_ours2, "x", "<= 1 to swap", t_kernel <= t_ours2)  # fmt: skip
    report("  its distances differ from ours by at most", float(d_kernel.max()), "",
           "0 to swap", bool(np.all(d_kernel == 0)),
           f"{d_kernel.max():.3g}, on {np.mean(d_kernel != 0):.3g} of the points; a view's "
           f"Chamfer-L1 term bit for bit on {sum(kernel_chamfer)} of {len(cases)}")  # fmt: skip


# -- bootstrap intervals ------------------------------------------------------------------------
def _scipy_ratio(d: np.ndarray, n: np.ndarray, seed: int, confidence: float) -> tuple[float, float]:
    """The cluster bootstrap of ``sum(d) / sum(n)`` by ``scipy.stats.bootstrap``: the units
    resampled as pairs, the same generator, the percentile interval."""
    res = scipy_stats.bootstrap(
        (d, n),
        lambda x, y, axis: x.sum(axis=axis) / y.sum(axis=axis),
        n_resamples=RESAMPLES,
        paired=True,
        vectorized=True,
        confidence_level=confidence,
        method="percentile",
        rng=np.random.default_rng(seed),
    )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def _summary_case(rng: np.random.Generator, items: int, views: int) -> tuple[np.ndarray, ...]:
    """Per-view rotation errors of ``items`` scenes of ``views`` views that share a scene's
    difficulty, their item labels, and the items' sums and view counts."""
    scene = rng.gamma(2.0, 10.0, items)
    v = np.repeat(scene, views) + rng.normal(0, 3.0, items * views)
    g = np.repeat(np.arange(items), views)
    return v, g, np.bincount(g, weights=v), np.bincount(g).astype(np.float64)


def bootstrap() -> None:
    rng = np.random.default_rng(0)
    worst = {"summary": 0.0, "paired": 0.0}
    same = {"summary": True, "paired": True}
    times = {"summary": [], "paired": []}
    for items, views in ((30, 1), (300, 1), (100, 4), (1000, 1)):
        v, g, sums, counts = _summary_case(rng, items, views)
        ours = stats.bootstrap_ci(v, np.mean, RESAMPLES, 0.95, 0, groups=g)
        theirs = _scipy_ratio(sums, counts, 0, 0.95)
        worst["summary"] = max(
            worst["summary"], *(abs(a - b) for a, b in zip(ours, theirs, strict=True))
        )
        same["summary"] &= ours == theirs
        t_lib, t_ours = paired_median_times(
            lambda s=sums, c=counts: _scipy_ratio(s, c, 0, 0.95),
            lambda v=v, g=g: stats.bootstrap_ci(v, np.mean, RESAMPLES, 0.95, 0, groups=g),
            REPEAT,
        )
        times["summary"].append(t_lib / t_ours)
        d = sums - rng.permutation(sums)  # a paired difference per item
        ours = stats.ratio_interval(d, counts, RESAMPLES, 0, tail=100 * (1 - 0.95) / 2)
        theirs = _scipy_ratio(d, counts, 0, 0.95)
        worst["paired"] = max(
            worst["paired"], *(abs(a - b) for a, b in zip(ours, theirs, strict=True))
        )
        same["paired"] &= ours == theirs
        t_lib, t_ours = paired_median_times(
            lambda d=d, c=counts: _scipy_ratio(d, c, 0, 0.95),
            lambda d=d, c=counts: stats.ratio_interval(d, c, RESAMPLES, 0, 100 * (1 - 0.95) / 2),
            REPEAT,
        )
        times["paired"].append(t_lib / t_ours)
    for what, label in (("summary", "bootstrap_ci(groups=items)"), ("paired", "ratio_interval")):
        report(f"scipy.stats.bootstrap over stats.{label}, worst of 4 sizes, same run",
               max(times[what]), "x", "<= 1 to swap", max(times[what]) <= 1,
               f"best {min(times[what]):.3g}x")  # fmt: skip
        report("  its interval ends differ from ours by at most", worst[what], "",
               "0 to swap", same[what], f"{worst[what]:.3g}")  # fmt: skip


def main() -> None:
    distances()
    bootstrap()


if __name__ == "__main__":
    main()
