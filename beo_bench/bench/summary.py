"""A run's summary from its result rows (``summary.json``; DESIGN.md "Public names").

Failed views (the backend raised or broke the ``Estimate`` contract) count as wrong: class
wrong, rotation error 180 degrees (so they are gross errors), viewpoint bins wrong, IoU and
F-score 0. Their EDT error, Chamfer distance, translation and size errors are undefined and
left out; the ``failures`` count says how many, and ``failure_kinds`` how they failed
(``backend error``: it raised or broke the contract; ``timeout``: it overran the item
timeout; ``worker died``: it crashed or exited its worker process). Such items have no
time, so the timing metrics cover the answered views only. Rows scored with the true class
given (the dissertation's ICP protocol, ``Suite.class_hint``) are left out of the class
metrics, and ``metrics["class_given"]`` says so. Every mean carries a bootstrap 95%
interval (seeded).
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from beo_bench import metrics
from beo_bench.bench.suites import Suite

WORST_ROTATION_DEG = 180.0
TIMING_KEYS = ("ms_per_view_median", "ms_per_view_p95", "views_per_s", "ms_per_decision_median")
"""Metrics that measure time (they vary from run to run; everything else is deterministic)."""
GROSS_ERROR_DEG = 15.0
"""The gross-error threshold of [Burchfiel] Table 5.2."""


def _col(rows: list[dict[str, Any]], key: str, fail: float | None) -> np.ndarray:
    """Column ``key`` as floats; a failed row without the value gets ``fail`` (None: NaN,
    left out of means)."""
    vals = []
    for r in rows:
        v = r.get(key)
        if r.get("failure") and key not in r:
            v = fail
        vals.append(np.nan if v is None else float(v))
    return np.asarray(vals, dtype=np.float64)


def _viewpoints(rows: list[dict[str, Any]], key: str) -> np.ndarray:
    """(N, 2) (azimuth, elevation) in degrees, NaN where missing (a failure)."""
    return np.array([r.get(key) or (np.nan, np.nan) for r in rows], dtype=np.float64)


class _Metrics:
    """Collects metric values and their bootstrap intervals."""

    def __init__(self) -> None:
        self.m: dict[str, Any] = {}
        self.ci: dict[str, Any] = {}

    def mean(self, name: str, values: np.ndarray) -> None:
        v = values[np.isfinite(values)]
        if len(v):
            self.m[name] = float(v.mean())
            self.ci[name] = list(metrics.bootstrap_ci(v))

    def median(self, name: str, values: np.ndarray) -> None:
        v = values[np.isfinite(values)]
        if len(v):
            self.m[name] = float(np.median(v))
            self.ci[name] = list(metrics.bootstrap_ci(v, np.median))


def _classes(M: _Metrics, rows: list[dict[str, Any]]) -> None:
    scored = [r for r in rows if not r.get("class_given")]
    if not scored:
        M.m["class_given"] = True
        return
    M.mean("class_acc", np.array([bool(r.get("correct")) for r in scored], dtype=np.float64))
    C = 1 + max(r["true_class"] for r in rows)
    true = np.array([r["true_class"] for r in scored])
    pred = np.array([r.get("pred_class", -1) for r in scored])
    ok = (pred >= 0) & (pred < C)
    M.m["confusion"] = metrics.confusion_matrix(pred[ok], true[ok], C).tolist()


def _pose(M: _Metrics, rows: list[dict[str, Any]]) -> None:
    rot = _col(rows, "rot_err_deg", WORST_ROTATION_DEG)
    if not np.isfinite(rot).any():
        return
    M.mean("rot_err_deg_mean", rot)
    M.median("rot_err_deg_median", rot)
    M.mean("gross_err_rate", (rot > GROSS_ERROR_DEG).astype(np.float64))
    M.m["rot_err_deg"] = rot.tolist()  # for the CDF plots
    trans = _col(rows, "trans_err_cm", None)
    M.mean("trans_err_cm_mean", trans)
    M.median("trans_err_cm_median", trans)
    M.mean("size_err_pct_mean", _col(rows, "size_err_pct", None))
    # NOCS accuracies: a failure (NaN translation) counts as a miss
    t = np.where(np.isfinite(trans), trans, np.inf)
    for name, (deg, cm) in metrics.NOCS_THRESHOLDS.items():
        M.mean(f"acc_{name}", ((rot <= deg) & (t <= cm)).astype(np.float64))
    est, gt = _viewpoints(rows, "viewpoint_est"), _viewpoints(rows, "viewpoint_gt")
    for n in metrics.AZIMUTH_BINS:
        M.m[f"azimuth_acc_{n}"] = metrics.viewpoint_bin_accuracy(est, gt, n, 1)["azimuth"]
    for n in metrics.ELEVATION_BINS:
        M.m[f"elevation_acc_{n}"] = metrics.viewpoint_bin_accuracy(est, gt, 1, n)["elevation"]


def _completion(M: _Metrics, rows: list[dict[str, Any]]) -> None:
    M.mean("iou_mean", _col(rows, "iou", 0.0))
    M.mean("iou_cam_mean", _col(rows, "iou_cam", 0.0))
    M.mean("edt_err_mean", _col(rows, "edt_err", None))
    M.mean("fscore_mean", _col(rows, "fscore", 0.0))
    M.mean("chamfer_l1_mean", _col(rows, "chamfer_l1", None))


def _pick(M: _Metrics, rows: list[dict[str, Any]]) -> None:
    M.mean("pick_success", np.array([bool(r.get("success")) for r in rows], dtype=np.float64))
    s = metrics.pick_summary(
        [bool(r.get("success")) for r in rows], [r.get("reason") for r in rows]
    )
    M.m["pick_failure_reasons"] = dict(sorted(s["failure_reasons"].items()))
    chosen = [r["chosen_is_target"] for r in rows if "chosen_is_target" in r]
    if chosen:
        M.mean("target_found_rate", np.array(chosen, dtype=np.float64))


def _collect(suite: Suite, rows: list[dict[str, Any]]) -> _Metrics:
    """The metrics a suite measures, over ``rows``."""
    M = _Metrics()
    if suite.kind == "pick":
        _pick(M, rows)
        return M
    _classes(M, rows)
    if suite.protocol != "known-pose":
        _pose(M, rows)
    _completion(M, rows)
    return M


def _per_category(suite: Suite, rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for cat in sorted({r["category"] for r in rows}):
        sub = [r for r in rows if r["category"] == cat]
        M = _collect(suite, sub)
        keep = ("pick_success", "class_acc", "rot_err_deg_mean", "rot_err_deg_median",
                "gross_err_rate", "iou_mean", "fscore_mean")  # fmt: skip
        out[cat] = {"n": len(sub), **{k: M.m[k] for k in keep if k in M.m}}
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


def summarise(suite: Suite, backend: str, rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The summary of a run's rows (sorted by item and view, so it does not depend on the
    order in which workers finished)."""
    M = _collect(suite, rows)
    stats = metrics.runtime_stats(_col(rows, "ms", None) / 1000.0)
    if stats["n"]:
        M.m["ms_per_view_median"] = stats["ms_median"]
        M.m["ms_per_view_p95"] = stats["ms_p95"]
        M.m["views_per_s"] = stats["hz"]
    if suite.kind == "pick":
        M.median("ms_per_decision_median", _col(rows, "ms_decision", None))
    names = {r["true_class"]: r["category"] for r in rows}
    categories = [names.get(i, f"class {i}") for i in range(1 + max(names, default=-1))]
    return {
        "categories": categories,
        "suite": suite.name,
        "suite_version": suite.version,
        "backend": backend,
        "n": len(rows),
        "failures": sum(1 for r in rows if r.get("failure")),
        "failure_kinds": failure_kinds(rows),
        "metrics": M.m,
        "ci95": M.ci,
        "per_category": _per_category(suite, rows),
        "seed": suite.seed,
    }
