"""The scored views whose rows ``test_scoring_values`` pins: items of ``pose-3dof`` (the BOP
figures, pose and completion metrics) and ``known-pose`` (completion only), each with
estimates that take every path of the scoring code: the truth itself (the oracle's case),
a damaged pose with soft, noisy occupancy, another instance's shape (a class mean's case:
another surface, another EDT), an empty shape and a full one. Deterministic: the values
written by ``python -m tests.bench.scoring_cases`` (the unchanged scoring code's, before the
scoring speed-up of issue 52) are the reference."""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.spatial.transform import Rotation

REFERENCE = Path(__file__).parent / "data" / "scoring_reference.json"
ITEMS = {"pose-3dof": (0, 1, 2, 3, 4, 5, 6, 7), "known-pose": (0, 1)}


def estimates(
    gt: Any, voxels: np.ndarray, other: np.ndarray, seed: int
) -> Iterator[tuple[str, Any]]:
    """The estimates scored for one view (name, Estimate)."""
    from beo_bench.types import Estimate

    rng = np.random.default_rng(seed)
    n = len(gt.categories) if hasattr(gt, "categories") else 18
    probs = np.full(n, 1.0 / n)
    R, t, size = np.asarray(gt.R_cam), np.asarray(gt.t_cam), np.asarray(gt.size)
    v = voxels.astype(np.float32)
    yield "truth", Estimate(probs, R, t, size, v)
    turn = Rotation.from_rotvec(rng.normal(size=3) * 0.15).as_matrix()
    soft = ndimage.gaussian_filter(v, 0.8) + rng.normal(0.0, 0.08, v.shape)
    soft = np.clip(soft, 0.0, 1.0).astype(np.float32)
    yield "damaged", Estimate(probs, turn @ R, t + rng.normal(0, 0.02, 3), size * 1.1, soft)
    yield "other", Estimate(probs, R, t, size * 0.9, other.astype(np.float32))
    yield "empty", Estimate(probs, R, t, size, np.zeros_like(v))
    yield "full", Estimate(probs, R, t, size, np.ones_like(v))


def rows() -> dict[str, dict[str, Any]]:
    """Every case's scored row, by ``suite/item/estimate``."""
    from beo_bench.bench import scoring as S
    from beo_bench.bench.evaluate import ItemViews
    from beo_bench.bench.pool import clean_row
    from beo_bench.bench.suites import get_suite

    out: dict[str, dict[str, Any]] = {}
    for name, items in ITEMS.items():
        suite = get_suite(name).with_overrides(size=max(items) + 1)
        views = ItemViews(suite)
        try:
            cases = [views.isolated_view(i) for i in items]
        finally:
            views.close()
        for k, (i, (view, gt)) in enumerate(zip(items, cases, strict=True)):
            voxels = S.truth_shape(gt.key, suite.resolution).voxels
            other_gt = cases[(k + 1) % len(cases)][1]
            other = S.truth_shape(other_gt.key, suite.resolution).voxels
            for what, est in estimates(gt, voxels, other, seed=1000 * k + i):
                row = S.view_row(
                    S.base_row(i, 0, view, gt, False), view, gt, (est, 0.0, None),
                    suite.resolution, suite.protocol.scores_pose,
                )  # fmt: skip
                out[f"{name}/{i}/{what}"] = clean_row(row)
    return out


if __name__ == "__main__":
    REFERENCE.write_text(json.dumps(rows(), indent=1, sort_keys=True) + "\n")
    sys.stdout.write(f"wrote {REFERENCE}\n")
