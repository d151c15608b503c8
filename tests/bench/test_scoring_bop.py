"""The field's figures of a view (``bench.scoring.score_bop``): BOP 2019's average recalls and
NOCS's box-IoU hits per row (``tally.recall_values``) on rows written by hand, the summary's
columns of them (``tally.estimate_values``), and an in-tree run of the bounds, whose rows
carry the BOP fields and whose figures are those of a perfect and of a random estimate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beo_bench.bench.rows import read_rows
from beo_bench.bench.scoring import BOP_FIELDS
from beo_bench.bench.suites import get_suite
from beo_bench.bench.tally import estimate_values, recall_values
from tests.bench.runs import FAST_RANDOM, short_run
from tests.bench.synthetic_runs import pose_row

AR_KEYS = ("ar_vsd", "ar_mssd", "ar_mspd", "ar_bop")
IOU_KEYS = ("iou3d_25", "iou3d_50", "iou3d_75")
DIAMETER_MM = 128.0  # a power of two: a fraction of it times it is exact


def bop_row(**values) -> dict:
    """A scored view with perfect BOP errors (every VSD tau 0, MSSD and MSPD 0, the box
    IoU 1); ``values`` override them."""
    row = {
        "failure": None,
        "bop_vsd": [0.0] * 10,
        "bop_mssd_mm": 0.0,
        "bop_mspd_px": 0.0,
        "bop_diameter_mm": DIAMETER_MM,
        "bop_visib_fract": 1.0,
        "iou3d": 1.0,
    }
    row.update(values)
    return row


def one(row: dict, width: int = 640) -> dict[str, float]:
    """The figures of a single row, as plain floats."""
    return {k: float(v[0]) for k, v in recall_values([row], width).items()}


# -- recall_values on rows made by hand ------------------------------------------------------
def test_a_perfect_row_is_found_at_every_threshold() -> None:
    got = one(bop_row())
    assert got == {**dict.fromkeys(AR_KEYS, 1.0), **dict.fromkeys(IOU_KEYS, 1.0)}


def test_a_failed_row_is_a_miss_everywhere() -> None:
    # a failed view's row has the diameter and the visible fraction, no errors
    row = {"failure": "RuntimeError: boom", "bop_diameter_mm": 100.0, "bop_visib_fract": 1.0}
    got = one(row)
    assert got == {**dict.fromkeys(AR_KEYS, 0.0), **dict.fromkeys(IOU_KEYS, 0.0)}
    # a failure is a miss even when it carries errors: they are not the view's estimate's
    assert one(bop_row(failure="timeout after 60 s"))["ar_bop"] == 0.0


def test_a_view_below_visib_gt_min_is_no_target() -> None:
    rows = [bop_row(bop_visib_fract=0.05), bop_row(bop_visib_fract=0.1), bop_row()]
    got = recall_values(rows, 640)
    for key in (*AR_KEYS, *IOU_KEYS):
        assert math.isnan(got[key][0]), key  # 5 % visible: left out of the means
        assert got[key][1] == 1.0 and got[key][2] == 1.0, key  # 10 % is a target (>=)
    # a failure below visib_gt_min is no target either (not a miss)
    low_fail = {"failure": "x", "bop_diameter_mm": 100.0, "bop_visib_fract": 0.05}
    assert math.isnan(one(low_fail)["ar_bop"])


def test_bop_recall_shares_are_used_as_they_are() -> None:
    # errors that alone would score 1 everywhere: the shares of BOP's matching win
    row = bop_row(bop_recall={"vsd": 0.3, "mssd": 0.5, "mspd": 0.7}, iou3d=0.6)
    got = one(row)
    assert got["ar_vsd"] == pytest.approx(0.3)
    assert got["ar_mssd"] == pytest.approx(0.5)
    assert got["ar_mspd"] == pytest.approx(0.7)
    assert got["ar_bop"] == pytest.approx(0.5)
    assert (got["iou3d_25"], got["iou3d_50"], got["iou3d_75"]) == (1.0, 1.0, 0.0)


def test_vsd_average_recall_over_taus_and_thresholds() -> None:
    # 0.07 at every tau: the threshold 0.05 misses, 0.10 ... 0.50 find it: 9 of 10
    assert one(bop_row(bop_vsd=[0.07] * 10))["ar_vsd"] == pytest.approx(0.9)
    # one tau at 1.0 (a whole row of thresholds missed), the others 0: 90 of 100 pairs
    assert one(bop_row(bop_vsd=[1.0] + [0.0] * 9))["ar_vsd"] == pytest.approx(0.9)
    # a mix: tau 0 at 0.22 (0.25 ... 0.50 find it: 6), tau 1 at 0.5 (none: strict), rest 0
    vsd = [0.22, 0.5] + [0.0] * 8
    assert one(bop_row(bop_vsd=vsd))["ar_vsd"] == pytest.approx((6 + 0 + 80) / 100)


def test_mssd_at_exactly_a_threshold_is_a_miss() -> None:
    # 32 mm of a 128 mm diameter is 0.25 exactly: 0.25 is a miss (strict <), 0.30 ... 0.50
    # are hits: 5 of 10
    assert 32.0 / DIAMETER_MM == 0.25
    got = one(bop_row(bop_mssd_mm=32.0))
    assert got["ar_mssd"] == pytest.approx(0.5)
    assert got["ar_bop"] == pytest.approx((1.0 + 0.5 + 1.0) / 3)
    # just below: 0.25 finds it too
    assert one(bop_row(bop_mssd_mm=31.99))["ar_mssd"] == pytest.approx(0.6)
    # the diameter scales the thresholds: 32 mm of 640 mm is 0.05 (a miss at 0.05 only)
    assert one(bop_row(bop_mssd_mm=32.0, bop_diameter_mm=640.0))["ar_mssd"] == pytest.approx(0.9)


def test_mspd_thresholds_scale_with_the_image_width() -> None:
    # 128 px wide: BOP's 5 ... 50 px of a 640-px image are 1 ... 10 px here
    assert one(bop_row(bop_mspd_px=1.0), 128)["ar_mspd"] == pytest.approx(0.9)  # 1 px: a miss
    assert one(bop_row(bop_mspd_px=0.99), 128)["ar_mspd"] == 1.0
    assert one(bop_row(bop_mspd_px=4.5), 128)["ar_mspd"] == pytest.approx(0.6)  # 5 ... 10
    # the same 4.5 px in a 640-px image is below every threshold; 5 px misses the first
    assert one(bop_row(bop_mspd_px=4.5), 640)["ar_mspd"] == 1.0
    assert one(bop_row(bop_mspd_px=5.0), 640)["ar_mspd"] == pytest.approx(0.9)
    # no projection (the estimate behind the camera): a miss
    assert one(bop_row(bop_mspd_px=None), 128)["ar_mspd"] == 0.0


def test_box_iou_hits_are_strictly_above_the_threshold() -> None:
    got = one(bop_row(iou3d=0.5))
    assert (got["iou3d_25"], got["iou3d_50"], got["iou3d_75"]) == (1.0, 0.0, 0.0)
    got = one(bop_row(iou3d=None))
    assert (got["iou3d_25"], got["iou3d_50"], got["iou3d_75"]) == (0.0, 0.0, 0.0)


# -- the summary's columns (tally.estimate_values) --------------------------------------------
def test_rows_without_bop_fields_give_no_average_recalls() -> None:
    """A run made before the field's figures: its rows have no diameter, so no ar_* or
    iou3d_* column (a failure alone is no figure), while the rest is there."""
    suite = get_suite("pose-3dof")
    rows = [pose_row(0), pose_row(1, failure="RuntimeError: boom"), pose_row(2)]
    values = estimate_values(suite, rows)
    assert not [k for k in values if k.startswith(("ar_", "iou3d_"))]
    assert "rot_err_deg_mean" in values and "iou_mean" in values
    # one row with the figures is enough for the columns; the older rows count as misses
    rows[0].update(bop_row())
    values = estimate_values(suite, rows)
    assert values["ar_bop"].tolist() == [1.0, 0.0, 0.0]


def test_pose_only_rows_have_no_shape_values_but_an_ordinary_failure_scores_iou_0() -> None:
    suite = get_suite("pose-3dof")
    failed = pose_row(0, failure="RuntimeError: boom")
    scored_pose_only = {**pose_row(1), "pose_only": True}
    failed_pose_only = {**pose_row(2, failure="no estimate in the results file"), "pose_only": True}
    values = estimate_values(suite, [failed, scored_pose_only, failed_pose_only])
    for key in ("iou_mean", "iou_cam_mean", "fscore_mean"):
        assert values[key][0] == 0.0, key  # an ordinary failure: at its worst case
        assert np.isnan(values[key][1:]).all(), key  # pose only: not measured
    for key in ("edt_err_mean", "chamfer_l1_mean"):
        assert values[key][0] > 0 and np.isnan(values[key][1:]).all(), key
    # the pose metrics of a pose-only failure still count at their worst case
    assert values["rot_err_deg_mean"][2] == 180.0 and values["failure_rate"][2] == 1.0


def test_a_pose_only_failure_has_no_size_error() -> None:
    suite = get_suite("pose-3dof")
    failed_pose_only = {**pose_row(0, failure="no estimate in the results file"), "pose_only": True}
    values = estimate_values(suite, [failed_pose_only, {**pose_row(1), "pose_only": True}])
    assert np.isnan(values["size_err_pct_mean"][0])


# -- in-tree runs: the bounds -----------------------------------------------------------------
def _rows(tmp_path, backend: str, n: int) -> list[dict]:
    return read_rows(tmp_path / f"pose-3dof-{backend}-{n}" / "results.jsonl")


def test_oracle_run_scores_every_field_figure_perfectly(tmp_path) -> None:
    s = short_run(tmp_path, "pose-3dof", "oracle", 3, workers=1)
    m = s["metrics"]
    assert s["failures"] == 0
    assert m["ar_bop"] == 1.0 and m["iou3d_50"] == 1.0
    assert m["ar_vsd"] == m["ar_mssd"] == m["ar_mspd"] == 1.0
    rows = _rows(tmp_path, "oracle", 3)
    assert len(rows) == 3
    for r in rows:
        assert set(BOP_FIELDS) <= set(r), r["item"]
        assert len(r["bop_vsd"]) == 10 and max(r["bop_vsd"]) == 0.0
        assert r["bop_mssd_mm"] < 1e-6 and r["bop_mspd_px"] < 1e-6
        assert r["bop_diameter_mm"] > 10.0  # mm: objects of a few cm to a few dm
        assert r["bop_visib_fract"] == 1.0  # an isolated view is never occluded
        assert r["iou3d"] == pytest.approx(1.0)


def test_random_run_scores_far_below(tmp_path) -> None:
    s = short_run(tmp_path, "pose-3dof", "random", 3, opts=FAST_RANDOM, workers=1)
    assert s["metrics"]["ar_bop"] < 0.2
    rows = _rows(tmp_path, "random", 3)
    for r in rows:
        assert set(BOP_FIELDS) <= set(r), r["item"]
