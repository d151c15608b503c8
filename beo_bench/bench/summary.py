"""A run's summary from its result rows (``summary.json``; docs/design.md "Public names").

**Failures count in every mean.** A failed view (the backend raised, broke the ``Estimate``
contract, overran the item timeout or killed its worker) has no estimate, so its row holds
no metric values (``results.jsonl`` keeps it that way); the summary scores it at each
metric's worst case (:func:`worst_cases`): class wrong, rotation error 180 degrees (a gross
error and a NOCS miss), viewpoint bins wrong, IoU and F-score 0, and the caps below for the
unbounded errors. So a backend that fails on hard views cannot look better for it, and
``metrics["failure_rate"]`` stands beside the means. A value that an answered view has no
finite number for (the Chamfer distance of an empty shape, the MSPD of an estimate behind
the camera) scores the worst case too, and every capped metric's values are clipped at the
cap, so no answer scores worse than no answer:

- translation error: :data:`TRANSLATION_CAP_CM` (50 cm: objects are 0.45-1.1 m from the
  camera and at most ~45 cm across, so an estimate 50 cm off is nowhere near);
- MSSD: :data:`MSSD_CAP_CM` (1 m: the translation cap plus more than any object's
  diameter); MSPD: the image diagonal in pixels;
- size error: :data:`SIZE_CAP_PCT` (100%);
- Chamfer-L1: :data:`CHAMFER_CAP` (sqrt 3, the unit cube's diagonal: no two points of
  shapes in the cube are further apart);
- EDT error: :func:`edt_cap`, ``D sqrt(3) sqrt(D^3)`` at resolution D (the error bound: no
  voxel's distance can differ by more than the grid's diagonal).

``failure_kinds`` says how views failed (``backend error``: it raised or broke the
contract; ``timeout``: it overran the item timeout; ``worker died``: it crashed or exited
its worker process). Failed items have no time, so the timing metrics cover the answered
views only. Rows scored with the true class given (the ``class-given`` track) are left out
of the class metrics, and ``metrics["class_given"]`` says so.

**Intervals resample items.** Every mean carries a 95% percentile bootstrap interval
(seeded) that resamples *items* (the ``item`` of the rows), the unit a suite draws: a
tabletop item is a scene whose views share the clutter, lighting and camera, so resampling
views as if independent would make the intervals too narrow.

**One definition.** Each per-view value comes from :func:`view_values` (the gross-error and
NOCS definitions from :mod:`beo_bench.metrics`); the means, the per-category table and a
paired comparison of two runs all read it.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from typing import Any

import numpy as np

from beo_bench import metrics
from beo_bench.bench.columns import SUMMARY_PER_CATEGORY
from beo_bench.bench.suites import Suite

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


def _field(rows: list[dict[str, Any]], key: str, worst: float) -> np.ndarray:
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


def _where_measured(flags: np.ndarray, *columns: np.ndarray) -> np.ndarray:
    """Indicator ``flags`` as floats, NaN where any of ``columns`` was not measured."""
    out = flags.astype(np.float64)
    for c in columns:
        out[np.isnan(c)] = np.nan
    return out


def _flags(rows: list[dict[str, Any]], key: str, missing: float) -> np.ndarray:
    """A boolean field as 0/1 floats, ``missing`` where a row lacks it."""
    return np.array([float(bool(r[key])) if key in r else missing for r in rows])


def view_values(suite: Suite, rows: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Per summary metric that is a mean over views, each view's value (NaN: not scored,
    e.g. the class of a view told its class): the one definition the summary's means and
    intervals, the per-category table and paired comparisons use. Failures and non-finite
    values are at their worst case (:func:`worst_cases`)."""
    out: dict[str, np.ndarray] = {"failure_rate": _flags(rows, "failure", 0.0)}
    if suite.kind == "pick":
        out["pick_success"] = _flags(rows, "success", 0.0)
        # an episode that chose nothing (no estimate, no visible object) did not find it
        out["target_found_rate"] = _flags(rows, "chosen_is_target", 0.0)
        return out
    out["class_acc"] = np.array(
        [np.nan if r.get("class_given") else float(bool(r.get("correct"))) for r in rows]
    )
    worst = worst_cases(suite)

    def col(key: str) -> np.ndarray:
        return _field(rows, key, worst[key])

    if suite.protocol != "known-pose":
        rot, trans = col("rot_err_deg"), col("trans_err_cm")
        out["rot_err_deg_mean"] = rot
        out["gross_err_rate"] = _where_measured(metrics.is_gross_error(rot), rot)
        for name, (deg, cm) in metrics.NOCS_THRESHOLDS.items():
            out[f"acc_{name}"] = _where_measured(metrics.pose_hits(rot, trans, deg, cm), rot, trans)
        out["trans_err_cm_mean"] = trans
        out["size_err_pct_mean"] = col("size_err_pct")
        out["mssd_cm_mean"] = col("mssd_cm")
        out["mspd_px_mean"] = col("mspd_px")
    for key in ("iou", "iou_cam", "edt_err", "fscore", "chamfer_l1"):
        out[f"{key}_mean"] = col(key)
    return out


class _Metrics:
    """Collects metric values and their bootstrap intervals (over ``items``)."""

    def __init__(self, items: np.ndarray, intervals: bool = True) -> None:
        self.items = items
        self.intervals = intervals
        self.m: dict[str, Any] = {}
        self.ci: dict[str, Any] = {}

    def _stat(self, name: str, values: np.ndarray, statistic: Callable[..., Any]) -> None:
        keep = np.isfinite(values)
        v = values[keep]
        if not len(v):
            return
        self.m[name] = float(statistic(v))
        if self.intervals:
            self.ci[name] = list(metrics.bootstrap_ci(v, statistic, groups=self.items[keep]))

    def mean(self, name: str, values: np.ndarray) -> None:
        self._stat(name, values, np.mean)

    def median(self, name: str, values: np.ndarray) -> None:
        self._stat(name, values, np.median)


def _classes(M: _Metrics, rows: list[dict[str, Any]], acc: np.ndarray) -> None:
    scored = [r for r in rows if not r.get("class_given")]
    if not scored:
        M.m["class_given"] = True
        return
    M.mean("class_acc", acc)
    C = 1 + max(r["true_class"] for r in rows)
    true = np.array([r["true_class"] for r in scored])
    pred = np.array([r.get("pred_class", -1) for r in scored])
    ok = (pred >= 0) & (pred < C)
    M.m["confusion"] = metrics.confusion_matrix(pred[ok], true[ok], C).tolist()


MEDIANS = {"rot_err_deg_mean": "rot_err_deg_median", "trans_err_cm_mean": "trans_err_cm_median"}
"""Means that also get a median (of the same per-view values)."""


def _pose(M: _Metrics, rows: list[dict[str, Any]], values: dict[str, np.ndarray]) -> None:
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


def _pick(M: _Metrics, rows: list[dict[str, Any]]) -> None:
    s = metrics.pick_summary(
        [bool(r.get("success")) for r in rows], [r.get("reason") for r in rows]
    )
    M.m["pick_failure_reasons"] = dict(sorted(s["failure_reasons"].items()))


def _collect(suite: Suite, rows: list[dict[str, Any]], intervals: bool = True) -> _Metrics:
    """The metrics a suite measures, over ``rows``."""
    M = _Metrics(np.array([r["item"] for r in rows]), intervals)
    values = view_values(suite, rows)
    if suite.kind == "pick":
        _pick(M, rows)
    else:
        _classes(M, rows, values.pop("class_acc"))
        if "rot_err_deg_mean" in values:
            _pose(M, rows, values)
    for name, v in values.items():
        M.mean(name, v)
        if name in MEDIANS:
            M.median(MEDIANS[name], v)
    return M


def _per_category(suite: Suite, rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for cat in sorted({r["category"] for r in rows}):
        sub = [r for r in rows if r["category"] == cat]
        M = _collect(suite, sub, intervals=False)
        out[cat] = {"n": len(sub), **{k: M.m[k] for k in SUMMARY_PER_CATEGORY if k in M.m}}
    return out


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


def scoring(suite: Suite) -> dict[str, Any]:
    """How the summary scored (recorded in it): the F-score's ``tau``, the worst cases a
    failure counts as, and the bootstrap's unit."""
    return {
        "fscore_tau": metrics.FSCORE_TAU,
        "fscore_tau_unit": "fraction of the object's largest extent (the unit cube's side)",
        "worst_case": worst_cases(suite) if suite.kind != "pick" else {},
        "bootstrap_unit": "item",
    }


def _ms(rows: list[dict[str, Any]], key: str) -> np.ndarray:
    return np.array([np.nan if r.get(key) is None else float(r[key]) for r in rows])


def summarise(suite: Suite, backend: str, rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The summary of a run's rows (sorted by item and view, so it does not depend on the
    order in which workers finished)."""
    M = _collect(suite, rows)
    stats = metrics.runtime_stats(_ms(rows, "ms") / 1000.0)
    if stats["n"]:
        M.m["ms_per_view_median"] = stats["ms_median"]
        M.m["ms_per_view_p95"] = stats["ms_p95"]
        M.m["views_per_s"] = stats["hz"]
    if suite.kind == "pick":
        M.median("ms_per_decision_median", _ms(rows, "ms_decision"))
    names = {r["true_class"]: r["category"] for r in rows}
    categories = [names.get(i, f"class {i}") for i in range(1 + max(names, default=-1))]
    return {
        "categories": categories,
        "suite": suite.name,
        "suite_version": suite.version,
        "track": getattr(suite, "track", None),
        "backend": backend,
        "n": len(rows),
        "failures": sum(1 for r in rows if r.get("failure")),
        "failure_kinds": failure_kinds(rows),
        "metrics": M.m,
        "ci95": M.ci,
        "per_category": _per_category(suite, rows),
        "scoring": scoring(suite),
        "seed": suite.seed,
    }
