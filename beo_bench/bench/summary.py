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

from collections.abc import Sequence
from typing import Any

import numpy as np

from beo_bench import metrics
from beo_bench.bench.columns import SUMMARY_PER_CATEGORY
from beo_bench.bench.kinds import get_kind
from beo_bench.bench.rows import Row, json_rows
from beo_bench.bench.rundir import Summary
from beo_bench.bench.suites import Suite
from beo_bench.bench.tally import (
    CHAMFER_CAP,
    GROSS_ERROR_DEG,
    HIGHER_IS_BETTER,
    MEDIANS,
    MSSD_CAP_CM,
    SIZE_CAP_PCT,
    TIMING_KEYS,
    TRANSLATION_CAP_CM,
    WORST_ROTATION_DEG,
    Tally,
    edt_cap,
    failure_kind,
    failure_kinds,
    worst_cases,
)

__all__ = [
    "CHAMFER_CAP",
    "GROSS_ERROR_DEG",
    "HIGHER_IS_BETTER",
    "MSSD_CAP_CM",
    "SIZE_CAP_PCT",
    "TIMING_KEYS",
    "TRANSLATION_CAP_CM",
    "WORST_ROTATION_DEG",
    "edt_cap",
    "failure_kind",
    "failure_kinds",
    "scoring",
    "summarise",
    "view_values",
    "worst_cases",
]


def view_values(suite: Suite, rows: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Per summary metric that is a mean over views, each view's value (NaN: not scored,
    e.g. the class of a view told its class): the one definition the summary's means and
    intervals, the per-category table and paired comparisons use (the suite's item kind
    says which metrics its rows give). Failures and non-finite values are at their worst
    case (:func:`worst_cases`)."""
    return get_kind(suite.kind).view_values(suite, rows)


def _collect(suite: Suite, rows: Sequence[Row], classes: int, intervals: bool = True) -> Tally:
    """The metrics a suite measures, over ``rows`` (of a suite of ``classes`` classes)."""
    M = Tally(np.array([r.item for r in rows]), intervals, classes)
    data = json_rows(rows)
    values = view_values(suite, data)
    get_kind(suite.kind).collect(M, data, values)
    for name, v in values.items():
        M.mean(name, v)
        if name in MEDIANS:
            M.median(MEDIANS[name], v)
    return M


def _per_category(suite: Suite, rows: Sequence[Row], classes: int) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for cat in sorted({r.category for r in rows}):
        sub = [r for r in rows if r.category == cat]
        M = _collect(suite, sub, classes, intervals=False)
        out[cat] = {"n": len(sub), **{k: M.m[k] for k in SUMMARY_PER_CATEGORY if k in M.m}}
    return out


def scoring(suite: Suite) -> dict[str, Any]:
    """How the summary scored (recorded in it): the F-score's ``tau``, the worst cases a
    failure counts as, and the bootstrap's unit."""
    return {
        "fscore_tau": metrics.FSCORE_TAU,
        "fscore_tau_unit": "fraction of the object's largest extent (the unit cube's side)",
        "worst_case": get_kind(suite.kind).worst_cases(suite),
        "bootstrap_unit": "item",
    }


def summarise(
    suite: Suite,
    backend: str,
    rows: Sequence[Row],
    uses_class_hint: bool = False,
    model_digest: str | None = None,
    privileged: bool = False,
    provenance: dict[str, Any] | None = None,
) -> Summary:
    """The summary of a run's rows (sorted by item and view, so it does not depend on the
    order in which workers finished), with what the run record says about its backend
    (whether it can use the class hint, its model's digest, whether it was handed the
    truth) and the run's provenance. Its ``categories`` are the suite's whole class list
    (``View.categories``), whichever classes the rows show."""
    from beo_bench.bench.runs import suite_categories

    # the suite's classes, in order, not the rows': a short run lacking a class still
    # names every class in its confusion matrix (and never "class 2" for a name)
    categories = list(suite_categories(suite))
    M = _collect(suite, rows, len(categories))
    ms = np.array([np.nan if r.ms is None else r.ms for r in rows])
    stats = metrics.runtime_stats(ms / 1000.0)
    if stats["n"]:
        M.m["ms_per_view_median"] = stats["ms_median"]
        M.m["ms_per_view_p95"] = stats["ms_p95"]
        M.m["views_per_s"] = stats["hz"]
    data = json_rows(rows)
    get_kind(suite.kind).timing(M, data)
    return Summary(
        categories=categories,
        suite=suite.name,
        suite_version=suite.version,
        track=suite.track,
        backend=backend,
        n=len(rows),
        failures=sum(1 for r in rows if r.failure),
        failure_kinds=failure_kinds(data),
        metrics=M.m,
        ci95=M.ci,
        per_category=_per_category(suite, rows, len(categories)),
        scoring=scoring(suite),
        seed=suite.seed,
        uses_class_hint=uses_class_hint,
        model_digest=model_digest,
        privileged=privileged,
        provenance=provenance or {},
        sensor=suite.sensor,
    )
