"""The summary of a run's rows: failures count at their worst case in every mean (and the
failure rate stands beside them), errors are capped, the per-view flags are the metrics'
own definitions, and intervals resample items (a tabletop scene's views move together)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beo_bench import metrics, stats
from beo_bench.bench import summary as S
from beo_bench.bench.rows import rows_of
from beo_bench.bench.rundir import Summary
from beo_bench.bench.suites import Suite, get_suite

POSE = get_suite("pose-3dof")
TABLETOP = get_suite("tabletop")

LOWER_IS_BETTER = {"rot_err_deg_mean", "gross_err_rate", "trans_err_cm_mean",
                   "size_err_pct_mean", "mssd_cm_mean", "mspd_px_mean", "edt_err_mean",
                   "chamfer_l1_mean", "failure_rate"}  # fmt: skip


def _summarise(suite: Suite, rows: list[dict]) -> Summary:
    """The summary of rows given as JSON objects."""
    return S.summarise(suite, "x", rows_of(rows))


def _row(item: int, view: int = 0, **values) -> dict:
    """A scored view; ``values`` override the metrics of a perfect one."""
    row = {
        "item": item,
        "view": view,
        "key": f"proc/v2/mug/test/{item}",
        "category": "mug",
        "true_class": 0,
        "class_given": False,
        "failure": None,
        "pred_class": 0,
        "correct": True,
        "rot_err_deg": 0.0,
        "trans_err_cm": 0.0,
        "size_err_pct": 0.0,
        "mssd_cm": 0.0,
        "mspd_px": 0.0,
        "viewpoint_est": [10.0, 20.0],
        "viewpoint_gt": [10.0, 20.0],
        "iou": 1.0,
        "iou_cam": 1.0,
        "edt_err": 0.0,
        "fscore": 1.0,
        "chamfer_l1": 0.0,
        "ms": 5.0,
    }
    row.update(values)
    return row


def _failed(item: int, view: int = 0, reason: str = "RuntimeError: boom") -> dict:
    """A view whose backend failed: no metric values (as ``results.jsonl`` keeps it)."""
    keep = ("item", "view", "key", "category", "true_class", "class_given")
    return {**{k: v for k, v in _row(item, view).items() if k in keep},
            "failure": reason, "pred_class": -1, "correct": False}  # fmt: skip


def test_a_failure_scores_the_worst_case_in_every_mean() -> None:
    ok = [_row(i, rot_err_deg=2.0, trans_err_cm=1.0, iou=0.8, fscore=0.9) for i in range(8)]
    some_failed = [*ok[:6], _failed(6), _failed(7, reason="timeout after 60 s")]
    a, b = _summarise(POSE, ok), _summarise(POSE, some_failed)
    worst = S.worst_cases(POSE)
    means = [k for k in S.view_values(POSE, ok) if k != "class_acc"]
    assert set(means) >= {"rot_err_deg_mean", "trans_err_cm_mean", "size_err_pct_mean",
                          "mssd_cm_mean", "mspd_px_mean", "edt_err_mean", "chamfer_l1_mean",
                          "iou_mean", "iou_cam_mean", "fscore_mean", "acc_10deg5cm"}  # fmt: skip
    for key in [*means, "class_acc"]:
        worse = b["metrics"][key] > a["metrics"][key]
        better = b["metrics"][key] < a["metrics"][key]
        assert worse if key in LOWER_IS_BETTER else better, key
    m = b["metrics"]
    # by hand: 6 views as answered, 2 at the worst case
    assert m["rot_err_deg_mean"] == pytest.approx((6 * 2.0 + 2 * 180.0) / 8)
    assert m["trans_err_cm_mean"] == pytest.approx((6 * 1.0 + 2 * 50.0) / 8)
    assert m["edt_err_mean"] == pytest.approx(2 * S.edt_cap(32) / 8)
    assert m["chamfer_l1_mean"] == pytest.approx(2 * math.sqrt(3) / 8)
    assert m["mspd_px_mean"] == pytest.approx(2 * math.hypot(128, 128) / 8)
    assert m["iou_mean"] == pytest.approx(6 * 0.8 / 8) and m["fscore_mean"] == pytest.approx(
        6 * 0.9 / 8
    )
    assert m["gross_err_rate"] == 0.25 and m["acc_10deg5cm"] == 0.75
    assert m["failure_rate"] == 0.25 and b["failures"] == 2
    assert b["failure_kinds"] == {"backend error": 1, "timeout": 1}
    assert m["rot_err_deg"][6:] == [180.0, 180.0]  # the CDF's values, failures included
    assert worst["edt_err"] == pytest.approx(32 * math.sqrt(3) * 32**1.5)
    assert b["scoring"]["worst_case"] == worst and b["scoring"]["fscore_tau"] == 0.01


def test_errors_are_capped_and_a_missing_value_of_an_answer_is_its_worst_case() -> None:
    rows = [
        _row(0, trans_err_cm=300.0, mssd_cm=500.0, size_err_pct=250.0, edt_err=1e9),
        _row(1, chamfer_l1=None, mspd_px=None),  # an empty shape; an estimate behind the camera
    ]
    v = S.view_values(POSE, rows)
    assert v["trans_err_cm_mean"].tolist() == [S.TRANSLATION_CAP_CM, 0.0]
    assert v["mssd_cm_mean"].tolist() == [S.MSSD_CAP_CM, 0.0]
    assert v["size_err_pct_mean"].tolist() == [S.SIZE_CAP_PCT, 0.0]
    assert v["edt_err_mean"].tolist() == [S.edt_cap(32), 0.0]
    assert v["chamfer_l1_mean"].tolist() == [0.0, S.CHAMFER_CAP]
    assert v["mspd_px_mean"].tolist() == [0.0, math.hypot(128, 128)]
    # the pose metrics of a known-pose suite are not measured at all
    known = S.view_values(get_suite("known-pose"), [_failed(0)])
    assert "rot_err_deg_mean" not in known and known["iou_mean"].tolist() == [0.0]


def test_gross_errors_and_nocs_accuracies_are_the_metrics_definitions() -> None:
    rot = [1.0, 15.0, 15.5, 4.9, 9.0, 30.0]
    trans = [1.0, 1.0, 1.0, 2.5, 4.99, 0.0]
    pairs = enumerate(zip(rot, trans, strict=True))
    rows = [_row(i, rot_err_deg=r, trans_err_cm=t) for i, (r, t) in pairs]
    rows.append(_failed(len(rows)))
    m = _summarise(POSE, rows)["metrics"]
    rot_w, trans_w = [*rot, 180.0], [*trans, S.TRANSLATION_CAP_CM]
    assert m["gross_err_rate"] == metrics.gross_error_rate(rot_w) == 3 / 7
    for name, acc in metrics.nocs_accuracies(rot_w, trans_w).items():
        assert m[f"acc_{name}"] == acc
    assert m["acc_5deg2cm"] == 1 / 7 and m["acc_10deg5cm"] == 3 / 7
    assert S.GROSS_ERROR_DEG == metrics.GROSS_ERROR_DEG


def _scenes(n: int, views: int, seed: int = 0) -> list[dict]:
    """Tabletop rows: each scene's views share most of their error (the scene's clutter)."""
    rng = np.random.default_rng(seed)
    rows = []
    for item in range(n):
        scene = rng.normal(40.0, 25.0)
        for v in range(views):
            rot = float(np.clip(scene + rng.normal(0.0, 3.0), 0.0, 180.0))
            rows.append(_row(item, v, rot_err_deg=rot, iou=float(np.clip(rot / 180, 0, 1))))
    return rows


def test_intervals_resample_items_not_views() -> None:
    rows = _scenes(60, 4)
    s = _summarise(TABLETOP, rows)
    rot = np.array([r["rot_err_deg"] for r in rows])
    lo, hi = s["ci95"]["rot_err_deg_mean"]
    by_view = np.subtract(*stats.bootstrap_ci(rot)[::-1])
    by_item = np.subtract(*stats.bootstrap_ci(rot, groups=[r["item"] for r in rows])[::-1])
    assert hi - lo == pytest.approx(by_item)
    assert hi - lo > 1.5 * by_view  # the views of a scene are nearly copies: ~sqrt(4) wider
    assert lo < s["metrics"]["rot_err_deg_mean"] < hi
    med_lo, med_hi = s["ci95"]["rot_err_deg_median"]
    assert med_lo <= s["metrics"]["rot_err_deg_median"] <= med_hi
    # one view per item (isolated suites): the same interval as resampling views
    single = [_row(i, rot_err_deg=float(r)) for i, r in enumerate(rot[:60])]
    got = _summarise(POSE, single)["ci95"]["rot_err_deg_mean"]
    assert got == pytest.approx(list(stats.bootstrap_ci(rot[:60])))


def test_views_told_their_class_are_not_scored_on_it() -> None:
    rows = [_row(0, class_given=True), _row(1, class_given=True, correct=False)]
    m = _summarise(POSE, rows)["metrics"]
    assert m["class_given"] is True and "class_acc" not in m
    mixed = [*rows, _row(2, correct=False), _failed(3)]
    assert _summarise(POSE, mixed)["metrics"]["class_acc"] == 0.0


def test_a_pick_episode_that_chose_nothing_did_not_find_the_target() -> None:
    pick = get_suite("pick")
    rows = [
        {"item": 0, "view": 0, "category": "mug", "true_class": 0, "failure": None,
         "success": True, "reason": "lifted", "chosen_is_target": True, "ms": 3.0,
         "ms_decision": 9.0},
        {"item": 1, "view": 0, "category": "mug", "true_class": 0, "failure": "timeout after 9 s",
         "success": False, "reason": "timeout"},
        {"item": 2, "view": 0, "category": "mug", "true_class": 0, "failure": None,
         "success": False, "reason": "no_estimate", "ms": 1.0, "ms_decision": 2.0},
    ]  # fmt: skip
    s = _summarise(pick, rows)
    m = s["metrics"]
    assert m["pick_success"] == pytest.approx(1 / 3)
    assert m["target_found_rate"] == pytest.approx(1 / 3)
    assert m["failure_rate"] == pytest.approx(1 / 3)
    assert m["pick_failure_reasons"] == {"no_estimate": 1, "timeout": 1}
    assert m["ms_per_decision_median"] == pytest.approx(5.5)


def test_a_sampling_backend_is_scored_on_its_best_sample_and_that_samples_rank() -> None:
    """The samples' figures (scoring.score_samples): the best sample's error under the
    symmetry group, its rank under the weights (0: put first), the samples' spread; in the
    summary as means over the views answered (a failure has no samples: not counted)."""
    from beo_bench.bench.scoring import score_samples
    from beo_bench.geometry import axis_angle, cyclic_z
    from beo_bench.types import Estimate, GroundTruth

    z = np.array([0.0, 0.0, 1.0])
    S_ = np.stack([axis_angle(z, np.radians(a)) for a in (30.0, 2.0, 181.0, 10.0)])
    gt = GroundTruth(
        key="k", category="mug", class_index=0, R_cam=np.eye(3), t_cam=np.zeros(3),
        size=np.ones(3), symmetry=cyclic_z(2),
    )  # fmt: skip
    est = Estimate(
        class_probs=np.array([1.0]), rotation=S_[0], translation=np.zeros(3),
        size=np.ones(3), shape=np.zeros((2, 2, 2)), pose_samples=S_,
        pose_weights=np.array([0.4, 0.1, 0.3, 0.2]),
    )  # fmt: skip
    out = score_samples(est, gt)
    # 181 deg is 1 deg from the half turn that the 2-fold group makes the truth
    assert out["sample_best_err_deg"] == pytest.approx(1.0)
    assert out["sample_best_rank"] == 1  # weights order: 30, 181, 10, 2 deg
    assert out["sample_spread_deg"] == pytest.approx(np.median([0.0, 28.0, 151.0, 20.0]))
    rows = [_row(0, sample_best_err_deg=1.0, sample_best_rank=1, sample_spread_deg=20.0),
            _row(1, sample_best_err_deg=3.0, sample_best_rank=5, sample_spread_deg=30.0),
            _failed(2)]  # fmt: skip
    m = _summarise(POSE, rows)["metrics"]
    assert m["sample_best_err_deg_mean"] == 2.0 and m["sample_best_rank_mean"] == 3.0
    assert m["sample_spread_deg_mean"] == 25.0
    assert "sample_best_rank_mean" not in _summarise(POSE, [_row(0)])["metrics"]


def test_the_gross_errors_of_a_sampling_backend_are_scored_apart() -> None:
    """On the views whose pick errs by more than 15 deg alone: the best sample's rank,
    whether a sample lies within 15 deg of the truth, whether the error is a half turn
    (docs/results.md's account of the silhouette prior); a failure has no samples and
    counts in none of them, a view within 15 deg in none either."""
    rows = [
        _row(0, rot_err_deg=5.0, sample_best_err_deg=1.0, sample_best_rank=0,
             sample_spread_deg=2.0),
        _row(1, rot_err_deg=176.0, sample_best_err_deg=4.0, sample_best_rank=14,
             sample_spread_deg=5.0),
        _row(2, rot_err_deg=40.0, sample_best_err_deg=30.0, sample_best_rank=6,
             sample_spread_deg=9.0),
        _failed(3),
    ]  # fmt: skip
    m = _summarise(POSE, rows)["metrics"]
    assert m["sample_best_rank_gross_mean"] == 10.0  # views 1 and 2
    assert m["sample_near_true_gross_rate"] == 0.5  # view 1's best sample is 4 deg off
    assert m["half_turn_gross_rate"] == 0.5  # 176 deg is, 40 deg is not


def test_a_run_lacking_classes_names_every_class_of_its_suite() -> None:
    """A short tabletop run whose views show two classes: the summary's class list is the
    suite's (every class, in its order, which the rows' ``true_class`` indexes), so its
    confusion matrix, the confusions table and the plot name each class, never "class 2",
    and a prediction of a class no view shows still counts."""
    import matplotlib

    matplotlib.use("Agg")
    from beo_bench.bench.pages.plots import confusion_figure
    from beo_bench.bench.pages.tables import confused_pairs
    from beo_bench.bench.runs import suite_categories

    cats = list(suite_categories(TABLETOP))
    bed, chair, table = cats.index("bed"), cats.index("chair"), cats.index("table")
    assert table > chair > bed  # the last class a row shows is not the last predicted
    rows = [
        _row(0, 0, category="bed", true_class=bed, pred_class=bed),
        _row(0, 1, category="chair", true_class=chair, pred_class=table, correct=False),
        _row(1, 0, category="bed", true_class=bed, pred_class=chair, correct=False),
    ]
    s = _summarise(TABLETOP, rows)
    assert s["categories"] == cats
    conf = np.asarray(s["metrics"]["confusion"])
    assert conf.shape == (len(cats), len(cats))
    assert conf[chair, table] == 1 and conf[bed, chair] == 1 and conf.sum() == 3
    assert set(confused_pairs(s)) == {("chair", "table", 1, 1), ("bed", "chair", 1, 2)}
    fig = confusion_figure(s["metrics"]["confusion"], s["categories"], "tabletop")
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == cats
    assert [t.get_text().split(" (")[0] for t in ax.get_yticklabels()] == cats
