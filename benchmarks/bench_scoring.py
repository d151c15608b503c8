"""Scoring figures: what scoring one view costs, and that completion is measured
without a sampling floor.

- CPU ms per scored view of warm ``pose-3dof`` items (render, predict, score) for the
  ``oracle`` and ``random`` backends, whose own predictions are cheap, so scoring dominates;
  and of its parts: completion (exact point-to-surface distances for Chamfer-L1 and the
  F-score) and the pose metrics (rotation, symmetric translation, size, MSSD, MSPD).
- The F-score of a perfect estimate given as 0.9 / 0.1 probabilities, and of a truth's
  surface sampled twice, over one instance of each category (the sample-to-sample floor
  beside it).

``python benchmarks/run.py scoring`` runs it (about a minute on 2 cores).
"""

from __future__ import annotations

import time

import numpy as np
import trimesh
from harness import report

from beo_bench import metrics
from beo_bench.bench import evaluate as E
from beo_bench.bench import scoring as S
from beo_bench.bench.suites import get_suite
from beo_bench.objects import ObjectSet
from beo_bench.types import Estimate, GroundTruth

VIEWS = 110


def _cpu_ms(fn, n: int) -> float:
    t0 = time.process_time()
    fn()
    return 1000 * (time.process_time() - t0) / n


def per_view() -> None:
    suite = get_suite("pose-3dof").with_overrides(size=VIEWS)
    for backend, kwargs in (("oracle", {}), ("random", {"mean_instances": 4})):
        ev = E.Evaluator.of(suite, backend, kwargs)
        for i in range(VIEWS):  # warm: meshes, voxels, this process's truth cache
            ev.run_item(i)
        whole = _cpu_ms(lambda: [ev.run_item(i) for i in range(VIEWS)], VIEWS)  # noqa: B023
        cases = [ev.items.isolated_view(i) for i in range(VIEWS)]
        ests = [ev.predict(i, 0, v)[0] for i, (v, _) in enumerate(cases)]
        truths = [S.truth_shape(gt.key, suite.resolution) for _, gt in cases]
        shapes = [S.resample(e.shape, suite.resolution) for e in ests]
        surf = _cpu_ms(
            lambda: [
                metrics.surface_scores(S.grid_surface(s), t.surface)
                for s, t in zip(shapes, truths, strict=True)  # noqa: B023
            ],
            VIEWS,
        )
        pose = _cpu_ms(
            lambda: [
                S.score_pose(e, gt, t, v.K)
                for (v, gt), e, t in zip(cases, ests, truths, strict=True)  # noqa: B023
            ],
            VIEWS,
        )
        ev.close()
        report(f"{backend}: CPU per scored view, pose-3dof, warm", whole, "ms")
        report(f"  {backend}: of which Chamfer-L1 and F-score (exact)", surf, "ms")
        report(f"  {backend}: of which pose metrics with MSSD and MSPD", pose, "ms")


def no_floor() -> None:
    objects = ObjectSet("test")
    perfect, itself, floor = [], [], []
    for cat in objects.categories:
        inst = objects.get(cat, 3)
        truth = S.truth_shape(inst.key, 32)
        gt = GroundTruth.of(inst, objects.categories, np.eye(3), np.array([0.0, 0.0, 0.6]))
        probs = np.full(len(objects.categories), 1 / len(objects.categories))
        shape = np.where(truth.voxels, 0.9, 0.1).astype(np.float32)
        perfect.append(S.score_shape(Estimate(probs, gt.R_cam, gt.t_cam, gt.size, shape), gt,
                                     truth)["fscore"])  # fmt: skip
        mesh = S.grid_mesh(truth.voxels)
        points = np.asarray(trimesh.sample.sample_surface(mesh, S.SURFACE_POINTS, seed=1)[0])
        other = metrics.Surface(mesh.vertices, mesh.faces, points)
        itself.append(metrics.fscore(other, truth.surface))
        floor.append(metrics.fscore(points, truth.surface.samples))
    report("F-score of a perfect 0.9/0.1 estimate, worst of 11 classes", min(perfect), "",
           ">= 0.99", min(perfect) >= 0.99)  # fmt: skip
    report("F-score of a surface against itself, worst of 11 classes", min(itself), "",
           ">= 0.99", min(itself) >= 0.99)  # fmt: skip
    report("  the same, sample to sample (the old floor), worst", min(floor), "")


def main() -> None:
    per_view()
    no_floor()
