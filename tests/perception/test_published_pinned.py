"""The published models are pinned to the committed leaderboards (issue 26, point 4).

The default ``beo``, ``hbeo``, ``hbeo-mdn-likelihood`` and ``hbeo-mdn-posterior`` load the
published weights (``perception/published/``, docs/reference-models.md). Each is run here
on the first items of a leaderboard suite: the views come from the runner's own
:class:`~beo_bench.bench.evaluate.ItemViews` (item i is the leaderboard's item i), and each
estimate is scored with the functions the runner's ``score_pose`` / ``score_shape`` call
(``rotation_error`` under the symmetry group, ``voxel_iou`` at the suite's resolution), so
these are the first rows of that leaderboard. The rest of the runner's scoring (surfaces,
EDT, camera-frame IoU: 40% of an item's time) is skipped, and the backends of one
suite share its rendered views. Class accuracy, the median rotation error and the mean IoU
must lie near the committed values, which are read from ``leaderboards/<suite>.json`` at
test time (never copied here: the leaderboards are regenerated from the code, and this test
holds the code to them).

Suites per backend, chosen for time (14 s in all on 2 busy cores, cold cache): ``beo``
on ``known-pose`` (class and completion with the pose given, Table 3.1; its pose search
takes ~350 ms a view on the pose suites, ~20 ms here), the three networks on ``pose-3dof``
class-free (Tables 4.1, 5.1: rotation, class and completion from nothing but the view).
``N_ITEMS`` = 72 items are four of each of the 18 classes (the suites balance classes over
item indices, ``index % 18``). A suite whose leaderboard page is not regenerated yet (a
campaign made suite by suite, ``all --update``) skips its backends, saying so.

**Tolerances** come from the leaderboard's 95% bootstrap interval [lo, hi] over its
n_lb items. Its half-width hw = (hi - lo) / 2 is about 1.96 sigma / sqrt(n_lb), sigma the
per-item spread of the statistic. The test's items are the leaderboard's first n_test, a
subsample: its statistic differs from the leaderboard's by sigma sqrt(1/n_test - 1/n_lb)
<= sigma / sqrt(n_test) = hw sqrt(n_lb / n_test) / 1.96 (one standard deviation). The
tolerance is SAFETY = 2 times hw sqrt(n_lb / n_test), about 4 standard deviations: the
first items of a seeded suite are no more special than any others, and the test is
deterministic (same items, same published weights), so what passes once keeps passing
unless the code changes; a change of the crop or of BEO's observation moves the numbers by
several times that (the mutations in the module's last comment). A proportion moves in
steps of one item, 1/n_test, and its bootstrap interval is [1, 1] at 100%: its tolerance
is at least one item.
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from beo_bench import metrics
from beo_bench.backend import get_backend, validate_estimate
from beo_bench.bench.evaluate import ItemViews
from beo_bench.bench.runs import RunConfig, RunContext
from beo_bench.bench.scoring import resample
from beo_bench.bench.suites import get_suite
from beo_bench.objects import instance_from_key

# slow: 14 s on 2 busy cores with a cold asset cache (the limit is 30 s); `make test` runs it
pytestmark = pytest.mark.slow

LEADERBOARDS = Path(__file__).resolve().parents[2] / "leaderboards"
N_ITEMS = 72
"""Items per backend: four of each of the 18 classes, the leaderboard's first 72."""
SAFETY = 2.0
"""Tolerance = SAFETY x the leaderboard's 95% half-width x sqrt(n_lb / n_test) (docstring)."""
PROPORTIONS = ("class_acc",)
"""Metrics that are fractions of items: their tolerance is at least one item."""

POSE = ("class_acc", "rot_err_deg_median", "iou_mean")
PINNED: dict[str, tuple[str, str | None, tuple[str, ...]]] = {
    # backend: suite, track, pinned metrics
    "beo": ("known-pose", None, ("class_acc", "iou_mean")),  # the pose is given
    "hbeo": ("pose-3dof", "class-free", POSE),
    "hbeo-mdn-likelihood": ("pose-3dof", "class-free", POSE),
    "hbeo-mdn-posterior": ("pose-3dof", "class-free", POSE),
}


def leaderboard_row(suite: str, backend: str, track: str | None) -> dict[str, Any]:
    """The committed summary of ``backend`` with its default options (the published model)
    in ``track`` of ``suite``."""
    path = LEADERBOARDS / f"{suite}.json"
    if not path.is_file():
        pytest.skip(f"leaderboards/{suite}.json is not regenerated at this suite version yet")
    rows = json.loads(path.read_text())
    found = [
        r
        for r in rows
        if r["backend"] == backend
        and r.get("track") == track
        and not r.get("provenance", {}).get("backend_kwargs")
        # the suite's own sensor: a page may also hold the same backend under others
        and r.get("sensor", get_suite(suite).sensor) == get_suite(suite).sensor
    ]
    assert len(found) == 1, (
        f"leaderboards/{suite}.json holds {len(found)} rows of {backend} (default options, "
        f"track {track}, the suite's own sensor); expected one"
    )
    return found[0]


def tolerance(metric: str, row: dict[str, Any], n_test: int) -> float:
    """How far the test's value of ``metric`` may lie from the leaderboard's (docstring)."""
    lo, hi = row["ci95"][metric]
    tol = SAFETY * 0.5 * (hi - lo) * math.sqrt(row["n"] / n_test)
    if metric in PROPORTIONS:
        tol = max(tol, 1.0 / n_test)
    return tol


@functools.cache
def scores(suite_name: str, track: str | None) -> dict[str, dict[str, Any]]:
    """Every pinned backend of ``suite_name`` on its first N_ITEMS items: per backend, its
    model digest and the per-item values (``correct``, ``rot_err_deg``, ``iou``). The views
    are rendered once and answered by each backend in turn."""
    suite = get_suite(suite_name).with_overrides(track=track)
    assert not suite.gives_class  # the views carry no class hint: what class-free runs see
    names = [b for b, (s, t, _) in PINNED.items() if (s, t) == (suite_name, track)]
    backends = {b: get_backend(b) for b in names}
    for name, b in backends.items():
        b.prepare(RunContext.of(RunConfig(suite, name)))  # as the runner prepares it
    out: dict[str, dict[str, Any]] = {
        b: {"digest": be.model_digest(), "correct": [], "rot_err_deg": [], "iou": []}
        for b, be in backends.items()
    }
    items = ItemViews(suite)
    try:
        for i in range(N_ITEMS):
            ((view, gt),) = items.cases(i)  # item i of the suite, as the runner draws it
            truth = instance_from_key(gt.key).voxels(suite.resolution)
            for b, backend in backends.items():
                est = validate_estimate(backend.predict(view), view)
                o = out[b]
                o["correct"].append(est.class_index == gt.class_index)
                o["rot_err_deg"].append(metrics.rotation_error(est.rotation, gt.R_cam, gt.symmetry))
                o["iou"].append(metrics.voxel_iou(resample(est.shape, suite.resolution), truth))
    finally:
        items.close()
    return out


@pytest.mark.parametrize("backend", list(PINNED))
def test_the_published_model_scores_as_its_leaderboard_row(backend: str) -> None:
    suite_name, track, names = PINNED[backend]
    suite = get_suite(suite_name)
    row = leaderboard_row(suite_name, backend, track)
    # the row is of these items and this model: the suite as it is now, the published weights
    assert row["suite_version"] == suite.version, (
        f"leaderboards/{suite_name}.json is of suite version {row['suite_version']}, the "
        f"suite is at {suite.version}: regenerate the leaderboard"
    )
    assert row["n"] >= N_ITEMS
    got = scores(suite_name, track)[backend]
    assert got["digest"] == row["model_digest"], (
        f"{backend} loads model {got['digest']}, its leaderboard row is of {row['model_digest']}"
    )
    # the summary's definitions (beo_bench.bench.summary), none of these views failing
    value = {
        "class_acc": float(np.mean(got["correct"])),
        "rot_err_deg_median": float(np.median(got["rot_err_deg"])),
        "iou_mean": float(np.mean(got["iou"])),
    }
    report, bad = [], []
    for m in names:
        ref, tol = row["metrics"][m], tolerance(m, row, N_ITEMS)
        line = f"{m} {value[m]:.4f} on {N_ITEMS} items, leaderboard {ref:.4f} +- {tol:.4f}"
        report.append(line)
        if abs(value[m] - ref) > tol + 1e-12:
            bad.append(line)
    label = f"{suite_name}@{track}" if track else suite_name
    print(f"{backend} on {label}: " + "; ".join(report))
    assert not bad, f"{backend} on {label} is off its leaderboard row: " + "; ".join(bad)


# Mutation checks, each made here and reverted (issue 26 point 4). Unmutated, the 66 items
# give beo class accuracy 0.83 and IoU 0.53; hbeo 1.00, median 5.8 deg, IoU 0.64; the MDN
# modes 1.00, 3.2 / 3.1 deg, IoU 0.49. Mutated:
# - perception/hbeo/crop.py, depth relief doubled, 2 (d - z_ref) / scale: hbeo median 18.9
#   deg (leaderboard 6.8 +- 3.5), IoU 0.43; the MDN modes 11.9 / 11.6 deg (2.7 +- 1.4 / 1.5),
#   class accuracy 0.91: three of four fail. Even 1.25 (d - z_ref) / scale fails the MDN
#   modes (4.9 / 5.0 deg);
# - the depth sign flipped, (z_ref - d) / scale: class accuracy 0.15-0.17, medians 42-44
#   deg, IoU 0.05-0.10: three of four fail;
# - the mask channel dropped (channel 1 all 0): class accuracy 0.33-0.45, medians 27-32 deg,
#   IoU 0.14: three of four fail;
# - perception/beo/observe.py, no free-space carving (no voxel known empty): beo's class
#   accuracy 0.09, IoU 0.21; carving one margin past the observed surface (z < fd + margin):
#   IoU 0.30 (leaderboard 0.57 +- 0.12): beo fails.
