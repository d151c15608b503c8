"""A run's summary from its result rows (``summary.json``; DESIGN.md "Public names").

Failed views (the backend raised or broke the ``Estimate`` contract) count as wrong: class
wrong, rotation error 180 degrees (so they are gross errors), IoU and F-score 0. Their EDT
error, Chamfer distance, translation and size errors are undefined and left out; the
``failures`` count says how many. Every mean carries a bootstrap 95% interval (seeded).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from beo_bench import metrics
from beo_bench.suites import Suite

WORST_ROTATION_DEG = 180.0


def _col(rows: list[dict[str, Any]], key: str, fail: float | None) -> np.ndarray:
    vals = []
    for r in rows:
        v = r.get(key)
        if r.get("failure") and key not in r:
            v = fail
        vals.append(np.nan if v is None else float(v))
    return np.asarray(vals, dtype=np.float64)


def summarise(suite: Suite, backend: str, rows: list[dict[str, Any]]) -> dict[str, Any]:
    n = len(rows)
    failures = sum(1 for r in rows if r.get("failure"))
    m: dict[str, Any] = {}
    ci: dict[str, Any] = {}

    def mean(name: str, values: np.ndarray, scale: float = 1.0) -> None:
        v = values[np.isfinite(values)] * scale
        if len(v) == 0:
            return
        m[name] = float(v.mean())
        ci[name] = list(metrics.bootstrap_ci(v))

    if suite.kind != "pick":
        correct = np.array([bool(r.get("correct")) for r in rows], dtype=np.float64)
        mean("class_acc", correct)
        C = 1 + max([r["true_class"] for r in rows] + [r.get("pred_class", -1) for r in rows])
        true = np.array([r["true_class"] for r in rows])
        pred = np.array([r.get("pred_class", -1) for r in rows])
        ok = pred >= 0
        m["confusion"] = metrics.confusion_matrix(pred[ok], true[ok], C).tolist()
        if suite.protocol != "known-pose":
            rot = _col(rows, "rot_err_deg", WORST_ROTATION_DEG)
            mean("rot_err_deg_mean", rot)
            if np.isfinite(rot).any():
                m["rot_err_deg_median"] = float(np.nanmedian(rot))
                ci["rot_err_deg_median"] = list(metrics.bootstrap_ci(rot, np.median))
                mean("gross_err_rate", (rot > 15.0).astype(np.float64))
                m["rot_err_deg"] = rot.tolist()  # for CDF plots
            trans = _col(rows, "trans_err_cm", None)
            mean("trans_err_cm_mean", trans)
            mean("size_err_pct_mean", _col(rows, "size_err_pct", None))
            if np.isfinite(trans).any():
                good = (
                    (rot <= 5) & (trans <= 2),
                    (rot <= 5) & (trans <= 5),
                    (rot <= 10) & (trans <= 5),
                )
                for name, g in zip(
                    ("acc_5deg2cm", "acc_5deg5cm", "acc_10deg5cm"), good, strict=True
                ):
                    mean(name, g.astype(np.float64))
        mean("iou_mean", _col(rows, "iou", 0.0))
        mean("edt_err_mean", _col(rows, "edt_err", None))
        mean("fscore_mean", _col(rows, "fscore", 0.0))
        mean("chamfer_l1_mean", _col(rows, "chamfer_l1", None))
    else:
        success = np.array([bool(r.get("success")) for r in rows], dtype=np.float64)
        mean("pick_success", success)
        reasons: dict[str, int] = {}
        for r in rows:
            if not r.get("success"):
                reasons[str(r.get("reason"))] = reasons.get(str(r.get("reason")), 0) + 1
        m["pick_failure_reasons"] = dict(sorted(reasons.items()))
        chosen = [r.get("chosen_is_target") for r in rows if "chosen_is_target" in r]
        if chosen:
            mean("target_found_rate", np.array(chosen, dtype=np.float64))
    ms = _col(rows, "ms", None)
    if np.isfinite(ms).any():
        m["ms_per_view_median"] = float(np.nanmedian(ms))
        m["ms_per_view_p95"] = float(np.nanpercentile(ms, 95))
    per_cat: dict[str, dict[str, float]] = {}
    for cat in sorted({r["category"] for r in rows}):
        sub = [r for r in rows if r["category"] == cat]
        d: dict[str, float] = {"n": len(sub)}
        if suite.kind == "pick":
            d["pick_success"] = float(np.mean([bool(r.get("success")) for r in sub]))
        else:
            d["class_acc"] = float(np.mean([bool(r.get("correct")) for r in sub]))
            if suite.protocol != "known-pose":
                rot = _col(sub, "rot_err_deg", WORST_ROTATION_DEG)
                d["rot_err_deg_mean"] = float(np.nanmean(rot)) if np.isfinite(rot).any() else None
            iou = _col(sub, "iou", 0.0)
            d["iou_mean"] = float(np.nanmean(iou)) if np.isfinite(iou).any() else None
        per_cat[cat] = d
    names = {r["true_class"]: r["category"] for r in rows}
    categories = [names.get(i, f"class {i}") for i in range(1 + max(names, default=-1))]
    return {
        "categories": categories,
        "suite": suite.name,
        "suite_version": suite.version,
        "backend": backend,
        "n": n,
        "failures": failures,
        "metrics": m,
        "ci95": ci,
        "per_category": per_cat,
        "seed": suite.seed,
    }
