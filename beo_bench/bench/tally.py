"""The pieces a run's summary is computed with: each metric's worst case, the per-view value
columns, and the accumulator of means, medians and bootstrap intervals over items
(:class:`Tally`). The item kinds (:mod:`beo_bench.bench.kinds`) say which metrics their rows
give; :mod:`beo_bench.bench.summary` puts the summary together (its docstring explains the
rules: failures count in every mean at their worst case, intervals resample items).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from typing import Any

import numpy as np

from beo_bench import metrics, stats
from beo_bench.bench.suites import Suite
from beo_bench.bop import nocs, protocol

SAMPLE_FIELDS = ("sample_best_err_deg", "sample_best_rank", "sample_spread_deg")
"""Row fields of a backend that returns rotation samples, in the order
:func:`beo_bench.bench.scoring.score_samples` computes them: the best sample's error (deg),
its rank under the weights, the samples' spread (deg)."""

WORST_ROTATION_DEG = 180.0
"""What a failed view's rotation error counts as (the largest possible)."""
TRANSLATION_CAP_CM = 50.0
"""The translation error's worst case (and cap), centimetres."""
MSSD_CAP_CM = 100.0
"""MSSD's worst case (and cap), centimetres."""
SIZE_CAP_PCT = 100.0
"""The size error's worst case (and cap), percent."""
CHAMFER_CAP = math.sqrt(3.0)
"""Chamfer-L1's worst case (and cap), in the unit cube's units."""
TIMING_KEYS = ("ms_per_view_median", "ms_per_view_p95", "views_per_s", "ms_per_decision_median")
"""Metrics that measure time (they vary from run to run; everything else is deterministic)."""
GROSS_ERROR_DEG = metrics.GROSS_ERROR_DEG
"""The gross-error threshold of [Burchfiel] Table 5.2 (defined in :mod:`beo_bench.metrics`)."""
HALF_TURN_DEG = 150.0
"""A rotation error at least this large counts as a half turn (a flip of a near-symmetric
object) in ``half_turn_gross_rate``."""


def edt_cap(resolution: int) -> float:
    """The EDT error's worst case (and cap) at ``resolution`` D: ``D sqrt(3) sqrt(D^3)``,
    the norm of a difference of at most a grid diagonal in each of the D^3 voxels."""
    D = float(resolution)
    return D * math.sqrt(3.0) * D**1.5


def worst_cases(suite: Suite) -> dict[str, float]:
    """Per row field, what a failed view (or a value that is not a finite number) scores
    on ``suite``; fields whose larger values are worse are also clipped at it."""
    w, h = suite.image_size
    return {
        "rot_err_deg": WORST_ROTATION_DEG,
        "trans_err_cm": TRANSLATION_CAP_CM,
        "size_err_pct": SIZE_CAP_PCT,
        "mssd_cm": MSSD_CAP_CM,
        "mspd_px": float(math.hypot(w, h)),
        "iou": 0.0,
        "iou_cam": 0.0,
        "fscore": 0.0,
        "edt_err": edt_cap(suite.resolution),
        "chamfer_l1": CHAMFER_CAP,
    }


HIGHER_IS_BETTER = frozenset({"iou", "iou_cam", "fscore"})
"""Row fields whose worst case is their least value (0); the others are capped errors."""


def field_values(rows: list[dict[str, Any]], key: str, worst: float) -> np.ndarray:
    """Column ``key`` as floats, each view at its worst case where it failed or has no
    finite value, errors clipped at ``worst``; NaN where the field was not measured."""
    vals = np.full(len(rows), np.nan)
    for i, r in enumerate(rows):
        if r.get("failure") and r.get(key) is None:
            vals[i] = worst
        elif key in r:
            v = r[key]
            vals[i] = float(v) if v is not None and math.isfinite(float(v)) else worst
    if key not in HIGHER_IS_BETTER:
        vals = np.minimum(vals, worst)  # NaN stays NaN
    return vals


def where_measured(flags: np.ndarray, *columns: np.ndarray) -> np.ndarray:
    """Indicator ``flags`` as floats, NaN where any of ``columns`` was not measured."""
    out = flags.astype(np.float64)
    for c in columns:
        out[np.isnan(c)] = np.nan
    return out


def flags(rows: list[dict[str, Any]], key: str, missing: float) -> np.ndarray:
    """A boolean field as 0/1 floats, ``missing`` where a row lacks it."""
    return np.array([float(bool(r[key])) if key in r else missing for r in rows])


def recall_values(rows: list[dict[str, Any]], image_width: int) -> dict[str, np.ndarray]:
    """Per view, its share of BOP's average recalls (``ar_vsd``, ``ar_mssd``, ``ar_mspd``
    and their mean ``ar_bop``) and NOCS's box-IoU hits (``iou3d_25``/``50``/``75``): with
    one estimate per target, a recall at one threshold is the mean over targets of "its
    error is below the threshold", so the average recall is the mean over targets of each
    one's hit rate over the thresholds (BOP's ``eval_bop19_pose``: VSD over every
    (tau, threshold), MSSD over fractions of the diameter, MSPD over pixels scaled by
    ``image_width / 640``). A failed view is a miss (0); a view below ``visib_gt_min`` is
    no target (NaN: left out of the means, as BOP leaves it out of the denominator)."""
    n = len(rows)
    vsd_th = np.asarray(protocol.VSD_THRESHOLDS)
    mssd_th = np.asarray(protocol.MSSD_THRESHOLDS)
    mspd_th = np.asarray(protocol.MSPD_THRESHOLDS_PX) * (image_width / 640.0)
    out = {k: np.zeros(n) for k in ("ar_vsd", "ar_mssd", "ar_mspd")}
    ious = {f"iou3d_{round(100 * t)}": np.zeros(n) for t in nocs.NOCS_IOU_THRESHOLDS}
    for i, r in enumerate(rows):
        if r.get("bop_visib_fract", 1.0) < protocol.VISIB_GT_MIN:
            for v in (*out.values(), *ious.values()):
                v[i] = np.nan
            continue
        shares = r.get("bop_recall")
        if shares is not None:  # matched as BOP matches several estimates (bopscore)
            for k in ("vsd", "mssd", "mspd"):
                out[f"ar_{k}"][i] = float(shares[k])
        elif r.get("failure") or r.get("bop_vsd") is None:
            continue  # not found: a miss at every threshold
        else:
            vsd = np.asarray(r["bop_vsd"], dtype=np.float64)
            out["ar_vsd"][i] = np.mean(vsd[:, None] < vsd_th[None, :])
            diam = float(r["bop_diameter_mm"])
            out["ar_mssd"][i] = np.mean(float(r["bop_mssd_mm"]) < mssd_th * diam)
            px = r.get("bop_mspd_px")
            out["ar_mspd"][i] = 0.0 if px is None else np.mean(float(px) < mspd_th)
        iou = r.get("iou3d")
        for t, v in zip(nocs.NOCS_IOU_THRESHOLDS, ious.values(), strict=True):
            # NOCS's compute_3d_matches: iou > threshold, strictly, in float32
            v[i] = float(iou is not None and np.float32(iou) > np.float32(t))
    out["ar_bop"] = (out["ar_vsd"] + out["ar_mssd"] + out["ar_mspd"]) / 3.0
    return {**out, **ious}


def estimate_values(suite: Suite, rows: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Of views scored on an estimate (isolated and tabletop items): per summary metric
    that is a mean over views, each view's value (NaN: not scored,
    e.g. the class of a view told its class): the one definition the summary's means and
    intervals, the per-category table and paired comparisons use. Failures and non-finite
    values are at their worst case (:func:`worst_cases`)."""
    out: dict[str, np.ndarray] = {"failure_rate": flags(rows, "failure", 0.0)}
    out["class_acc"] = np.array(
        [np.nan if r.get("class_given") else float(bool(r.get("correct"))) for r in rows]
    )
    worst = worst_cases(suite)

    def col(key: str) -> np.ndarray:
        return field_values(rows, key, worst[key])

    # a run scored from a BOP results file estimates poses only: its size and shape columns
    # are left out (NaN), not scored at the worst case as a failure's would be
    posed_only = np.array([bool(r.get("pose_only")) for r in rows], dtype=bool)
    if suite.protocol.scores_pose:
        rot, trans = col("rot_err_deg"), col("trans_err_cm")
        out["rot_err_deg_mean"] = rot
        out["gross_err_rate"] = where_measured(metrics.is_gross_error(rot), rot)
        for name, (deg, cm) in metrics.NOCS_THRESHOLDS.items():
            out[f"acc_{name}"] = where_measured(metrics.pose_hits(rot, trans, deg, cm), rot, trans)
        out["trans_err_cm_mean"] = trans
        size = col("size_err_pct")
        size[posed_only] = np.nan
        out["size_err_pct_mean"] = size
        out["mssd_cm_mean"] = col("mssd_cm")
        out["mspd_px_mean"] = col("mspd_px")
        if any("bop_diameter_mm" in r for r in rows):
            # the field's figures (BOP 2019's average recalls, NOCS's box IoU): rows of runs
            # older than them have none, and get none (a failure alone is no figure)
            out.update(recall_values(rows, suite.image_size[0]))
    for key in ("iou", "iou_cam", "edt_err", "fscore", "chamfer_l1"):
        v = col(key)
        v[posed_only] = np.nan
        out[f"{key}_mean"] = v
    if any(SAMPLE_FIELDS[0] in r for r in rows):
        # a sampling backend's samples (scoring.score_samples): measured on the views it
        # answered, NaN on failures (a failure has no samples to rank; it counts in the
        # rotation error at its worst case already)
        for key in SAMPLE_FIELDS:
            out[f"{key}_mean"] = np.array(
                [float(r[key]) if r.get(key) is not None else np.nan for r in rows]
            )
        # the same on the gross errors alone (> 15 deg, NaN on the other views): whether
        # the samples of a view the pick got wrong hold a right one, and where the weights
        # rank it; and how many of those errors are half turns (a front told from a back:
        # what a silhouette prior, eq. 5.6, cannot see on a near-symmetric object)
        if suite.protocol.scores_pose:
            best = out["sample_best_err_deg_mean"]  # NaN on failures: they have no samples
            gross = np.where(metrics.is_gross_error(rot) & ~np.isnan(best), 1.0, np.nan)
            out["sample_best_rank_gross_mean"] = gross * out["sample_best_rank_mean"]
            out["sample_near_true_gross_rate"] = gross * (best <= GROSS_ERROR_DEG)
            out["half_turn_gross_rate"] = gross * (rot >= HALF_TURN_DEG)
    return out


class Tally:
    """Collects metric values and their bootstrap intervals (over ``items``)."""

    def __init__(
        self, items: np.ndarray, intervals: bool = True, classes: int | None = None
    ) -> None:
        self.items = items
        self.intervals = intervals
        self.classes = classes
        """The suite's number of classes (the confusion matrix's side; None: as many as the
        rows' largest true class needs)."""
        self.m: dict[str, Any] = {}
        self.ci: dict[str, Any] = {}

    def _stat(self, name: str, values: np.ndarray, statistic: Callable[..., Any]) -> None:
        keep = np.isfinite(values)
        v = values[keep]
        if not len(v):
            return
        self.m[name] = float(statistic(v))
        if self.intervals:
            self.ci[name] = list(stats.bootstrap_ci(v, statistic, groups=self.items[keep]))

    def mean(self, name: str, values: np.ndarray) -> None:
        self._stat(name, values, np.mean)

    def median(self, name: str, values: np.ndarray) -> None:
        self._stat(name, values, np.median)


def collect_classes(M: Tally, rows: list[dict[str, Any]], acc: np.ndarray) -> None:
    scored = [r for r in rows if not r.get("class_given")]
    if not scored:
        M.m["class_given"] = True
        return
    M.mean("class_acc", acc)
    # the suite's classes, not the rows': a short run that lacks a class (or a prediction
    # of a class no row holds) still gets the whole matrix, in the suite's class order
    C = max(M.classes or 0, 1 + max(r["true_class"] for r in rows))
    true = np.array([r["true_class"] for r in scored])
    pred = np.array([r.get("pred_class", -1) for r in scored])
    ok = (pred >= 0) & (pred < C)
    M.m["confusion"] = metrics.confusion_matrix(pred[ok], true[ok], C).tolist()


MEDIANS = {"rot_err_deg_mean": "rot_err_deg_median", "trans_err_cm_mean": "trans_err_cm_median"}
"""Means that also get a median (of the same per-view values)."""


def collect_pose(M: Tally, rows: list[dict[str, Any]], values: dict[str, np.ndarray]) -> None:
    rot = values["rot_err_deg_mean"]
    if not np.isfinite(rot).any():
        return
    M.m["rot_err_deg"] = rot.tolist()  # for the CDF plots
    est, gt = _viewpoints(rows, "viewpoint_est"), _viewpoints(rows, "viewpoint_gt")
    for n in metrics.AZIMUTH_BINS:
        M.m[f"azimuth_acc_{n}"] = metrics.viewpoint_bin_accuracy(est, gt, n, 1)["azimuth"]
    for n in metrics.ELEVATION_BINS:
        M.m[f"elevation_acc_{n}"] = metrics.viewpoint_bin_accuracy(est, gt, 1, n)["elevation"]


def _viewpoints(rows: list[dict[str, Any]], key: str) -> np.ndarray:
    """(N, 2) (azimuth, elevation) in degrees, NaN where missing (a failure)."""
    return np.array([r.get(key) or (np.nan, np.nan) for r in rows], dtype=np.float64)


def collect_estimates(M: Tally, rows: list[dict[str, Any]], values: dict[str, np.ndarray]) -> None:
    """The class metrics (the accuracy is taken out of ``values``) and, where poses were
    scored, the rotation errors and viewpoint accuracies of views scored on an estimate."""
    collect_classes(M, rows, values.pop("class_acc"))
    if "rot_err_deg_mean" in values:
        collect_pose(M, rows, values)


def failure_kind(failure: str) -> str:
    """``timeout``, ``worker died`` or ``backend error`` (see the module docstring)."""
    if failure.startswith("timeout after"):
        return "timeout"
    if failure.startswith(("worker died", "worker exited")):
        return "worker died"
    return "backend error"


def failure_kinds(rows: list[dict[str, Any]]) -> dict[str, int]:
    """How many rows failed, by :func:`failure_kind`."""
    kinds = Counter(failure_kind(str(r["failure"])) for r in rows if r.get("failure"))
    return dict(sorted(kinds.items()))
