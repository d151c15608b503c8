"""The metric columns of every results table, in one place.

``beo-bench run`` and ``compare`` print a plain-text table, ``beo-bench leaderboard`` writes
Markdown tables, and ``compare`` and the leaderboard's paired verdicts say whether a
difference is an improvement: all of them read a metric's label, scale, format and
direction from :data:`METRICS`, so a metric added or relabelled here changes every table.
Which metrics the narrower tables show (the per-category tables, the paired verdicts, the
out-of-distribution degradation) is chosen here too, by key, checked against
:data:`METRICS` on import.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MetricSpec:
    """How a ``summary["metrics"]`` entry is shown and judged."""

    key: str
    """Its key in ``summary["metrics"]`` (and ``summary["ci95"]``)."""
    label: str
    """The leaderboard's column header."""
    short: str
    """The plain-text table's header (at most 9 characters)."""
    scale: float
    """Shown as ``value * scale`` (100 for rates shown in percent)."""
    fmt: str
    """``str.format`` pattern of the scaled value."""
    higher_is_better: bool
    """Direction: a paired difference is ``better`` when it moves this way."""
    board: bool = True
    """A column of the leaderboard's suite tables."""
    brief: bool = False
    """A column of the plain-text table of ``run`` and ``compare`` (kept narrow)."""
    paired: bool = True
    """A mean over views, so ``compare`` can pair it item by item (medians and timings
    cannot be)."""

    def format(self, value: float | None) -> str:
        """The value as the tables show it; ``-`` when absent or not finite."""
        if value is None or not np.isfinite(value):
            return "-"
        return self.fmt.format(value * self.scale)

    def format_diff(self, value: float) -> str:
        """A difference of two values, signed (``+1.2``, ``-3.4%``)."""
        if not np.isfinite(value):
            return "-"
        text = self.fmt.format(value * self.scale)
        return text if text.startswith("-") else "+" + text

    def format_interval(self, diff: float, lo: float, hi: float) -> str:
        """A paired difference with its 95% interval: ``+1.2 [-0.3, +2.8]``."""
        return f"{self.format_diff(diff)} [{self.format_diff(lo)}, {self.format_diff(hi)}]"


METRICS: tuple[MetricSpec, ...] = (
    MetricSpec("rot_err_deg_mean", "rot. error mean (deg)", "rot mean", 1, "{:.1f}", False,
               brief=True),
    MetricSpec("rot_err_deg_median", "median (deg)", "rot med", 1, "{:.1f}", False, brief=True,
               paired=False),
    MetricSpec("gross_err_rate", "> 15 deg", ">15deg", 100, "{:.1f}%", False, brief=True),
    MetricSpec("acc_10deg5cm", "10deg5cm", "10deg5cm", 100, "{:.1f}%", True),
    # the field's figures (bench.scoring): BOP 2019's average recalls, NOCS's report
    MetricSpec("ar_bop", "BOP AR", "BOP AR", 1, "{:.3f}", True),
    MetricSpec("ar_vsd", "AR_VSD", "AR_VSD", 1, "{:.3f}", True, board=False),
    MetricSpec("ar_mssd", "AR_MSSD", "AR_MSSD", 1, "{:.3f}", True, board=False),
    MetricSpec("ar_mspd", "AR_MSPD", "AR_MSPD", 1, "{:.3f}", True, board=False),
    MetricSpec("acc_5deg2cm", "5deg2cm", "5deg2cm", 100, "{:.1f}%", True, board=False),
    MetricSpec("acc_5deg5cm", "5deg5cm", "5deg5cm", 100, "{:.1f}%", True, board=False),
    MetricSpec("acc_10deg2cm", "10deg2cm", "10deg2cm", 100, "{:.1f}%", True, board=False),
    MetricSpec("iou3d_25", "3D IoU25", "IoU25", 100, "{:.1f}%", True, board=False),
    MetricSpec("iou3d_50", "3D IoU50", "IoU50", 100, "{:.1f}%", True, board=False),
    MetricSpec("iou3d_75", "3D IoU75", "IoU75", 100, "{:.1f}%", True, board=False),
    MetricSpec("trans_err_cm_mean", "transl. (cm)", "trans cm", 1, "{:.2f}", False, brief=True),
    MetricSpec("size_err_pct_mean", "size error (%)", "size %", 1, "{:.1f}", False, board=False),
    MetricSpec("mssd_cm_mean", "MSSD (cm)", "MSSD cm", 1, "{:.2f}", False),
    MetricSpec("mspd_px_mean", "MSPD (px)", "MSPD px", 1, "{:.1f}", False, board=False),
    MetricSpec("class_acc", "class acc.", "class acc", 100, "{:.1f}%", True, brief=True),
    MetricSpec("iou_mean", "IoU", "IoU", 1, "{:.3f}", True, brief=True),
    MetricSpec("iou_cam_mean", "posed IoU", "posed IoU", 1, "{:.3f}", True),
    MetricSpec("edt_err_mean", "EDT error", "EDT", 1, "{:.1f}", False, brief=True),
    MetricSpec("chamfer_l1_mean", "Chamfer-L1", "Chamfer", 1, "{:.4f}", False, board=False),
    # tau: evaluate.FSCORE_TAU, 1% of the canonical cube's side (the label states it)
    MetricSpec("fscore_mean", "F-score@1%", "F@1%", 1, "{:.3f}", True, brief=True),
    MetricSpec("pick_success", "pick success", "pick", 100, "{:.1f}%", True, brief=True),
    MetricSpec("target_found_rate", "target found", "found", 100, "{:.1f}%", True),
    MetricSpec("failure_rate", "failed", "failed", 100, "{:.1f}%", False, board=False),
    # a sampling backend's samples (scoring.score_samples): the ablations pair them
    MetricSpec("sample_best_err_deg_mean", "best sample's rot. error (deg)", "best smp", 1,
               "{:.1f}", False, board=False),
    MetricSpec("sample_best_rank_mean", "rank of the best sample", "best rank", 1, "{:.2f}",
               False, board=False),
    # the same on the views with a gross error (> 15 deg) alone
    MetricSpec("sample_best_rank_gross_mean", "rank of the best sample, gross errors",
               "rank >15", 1, "{:.2f}", False, board=False),
    MetricSpec("sample_near_true_gross_rate", "gross errors with a sample within 15 deg",
               "near >15", 100, "{:.1f}%", True, board=False),
    MetricSpec("half_turn_gross_rate", "gross errors that are half turns (>= 150 deg)",
               "halfturns", 100, "{:.1f}%", False, board=False),
    MetricSpec("ms_per_view_median", "ms/view", "ms/view", 1, "{:.1f}", False, brief=True,
               paired=False),
)  # fmt: skip
"""Every metric a table shows, in the order of the columns."""

BY_KEY: dict[str, MetricSpec] = {m.key: m for m in METRICS}

_RATES = (
    "gross_err_rate", "acc_10deg5cm", "ar_bop", "ar_vsd", "ar_mssd", "ar_mspd", "acc_5deg2cm",
    "acc_5deg5cm", "acc_10deg2cm", "iou3d_25", "iou3d_50", "iou3d_75", "class_acc", "iou_mean",
    "iou_cam_mean", "fscore_mean", "pick_success", "target_found_rate", "failure_rate",
    "sample_near_true_gross_rate", "half_turn_gross_rate",
)  # fmt: skip
RANGES: dict[str, tuple[float, float]] = {
    **dict.fromkeys(_RATES, (0.0, 1.0)),
    # degrees: a rotation is at most a half turn away (a failure scores 180)
    "rot_err_deg_mean": (0.0, 180.0),
    "rot_err_deg_median": (0.0, 180.0),
    "sample_best_err_deg_mean": (0.0, 180.0),
    # the caps a view's value is clipped at (bench.tally: TRANSLATION_CAP_CM, SIZE_CAP_PCT,
    # MSSD_CAP_CM, CHAMFER_CAP; tests/bench/test_gate.py checks they agree)
    "trans_err_cm_mean": (0.0, 50.0),
    "size_err_pct_mean": (0.0, 100.0),
    "mssd_cm_mean": (0.0, 100.0),
    "chamfer_l1_mean": (0.0, math.sqrt(3.0)),
}
"""Each metric's range of a view's value (a mean over views lies in it too): rates and
scores in [0, 1], errors at least 0 and at most the cap a view is clipped at. A metric not
listed (the MSPD and EDT errors, whose caps depend on the suite; ranks; times) is any
finite number >= 0 (:func:`value_range`). A baseline file's values are checked against
it."""


def value_range(key: str) -> tuple[float, float]:
    """The range of metric ``key``'s values (:data:`RANGES`; else ``[0, inf)``, finite)."""
    return RANGES.get(key, (0.0, math.inf))


def _keys(*keys: str) -> tuple[str, ...]:
    """``keys``, each of which must have a spec in :data:`METRICS` (a typo fails on import,
    not in a table that silently lacks the column)."""
    missing = [k for k in keys if k not in BY_KEY]
    if missing:
        raise KeyError(f"no MetricSpec for {missing}: add them to METRICS")
    return keys


_keys(*RANGES)  # a typo in RANGES fails on import

SUMMARY_PER_CATEGORY: tuple[str, ...] = _keys(
    "pick_success", "class_acc", "rot_err_deg_mean", "rot_err_deg_median", "gross_err_rate",
    "iou_mean", "fscore_mean", "failure_rate", *(
        "ar_bop", "acc_5deg2cm", "acc_5deg5cm", "acc_10deg2cm", "acc_10deg5cm",
        "iou3d_25", "iou3d_50", "iou3d_75"),
)  # fmt: skip
"""The metrics of a summary's per-category entries (``summary["per_category"]``)."""
BOARD_PER_CATEGORY: dict[str, tuple[str, ...]] = {
    "pick": _keys("pick_success"),
    "known-pose": _keys("class_acc"),
    "modelnet10-known-pose": _keys("class_acc", "iou_mean"),
}
"""The leaderboard's per-category tables' metrics per suite (default:
:data:`BOARD_PER_CATEGORY_DEFAULT`)."""
BOARD_PER_CATEGORY_DEFAULT: tuple[str, ...] = _keys("rot_err_deg_mean", "gross_err_rate")
"""Mean rotation error and the gross error rate, as the dissertation's Tables 5.1 and 5.2."""
FIELD_KEYS: tuple[str, ...] = _keys(
    "ar_vsd", "ar_mssd", "ar_mspd", "ar_bop", "acc_5deg2cm", "acc_5deg5cm", "acc_10deg2cm",
    "acc_10deg5cm", "iou3d_25", "iou3d_50", "iou3d_75",
)  # fmt: skip
"""The field's figures of a pose suite's page: BOP 2019's average recalls and the NOCS
report (pose accuracies and 3D box IoU), per run and per class."""
NOCS_PER_CATEGORY: tuple[str, ...] = FIELD_KEYS[4:]
"""The NOCS report's per-class columns."""
VERDICT_KEYS: tuple[str, ...] = _keys("rot_err_deg_mean", "gross_err_rate")
"""The metrics of the leaderboard's paired-verdicts tables."""
DEGRADATION_KEYS: tuple[str, ...] = _keys(
    "rot_err_deg_mean", "gross_err_rate", "class_acc", "iou_mean"
)
"""The metrics of an ``-ood`` suite's in -> out of distribution table."""
ROBUSTNESS_KEYS: tuple[str, ...] = _keys(
    "rot_err_deg_mean", "gross_err_rate", "class_acc", "iou_mean", "pick_success"
)
"""The metrics of a suite page's robustness table (a backend under each depth sensor), those
its runs have."""


def spec(key: str) -> MetricSpec:
    """The spec of ``key`` (a programming error, not a user's, when it has none)."""
    return BY_KEY[key]


def board_columns() -> tuple[MetricSpec, ...]:
    """The leaderboard's suite-table columns."""
    return tuple(m for m in METRICS if m.board)


def brief_columns() -> tuple[MetricSpec, ...]:
    """The plain-text table's columns."""
    return tuple(m for m in METRICS if m.brief)


def markdown_table(
    head: Sequence[object], rows: Iterable[Sequence[object]], align: str = "lr"
) -> str:
    """The one renderer of every generated Markdown table (the leaderboard's pages, the doc
    tables, the ablations): a header, its alignment row and a line per row, cells as given
    (``str()``). ``align``: a letter per column, ``l`` left or ``r`` right, the last letter
    repeated over the remaining columns (default: the first left, the others right, numbers
    after a name)."""
    marks = [("---:" if a == "r" else "---") for a in align.ljust(len(head), align[-1])]
    lines = [_md_row(head), "|" + "".join(f"{m}|" for m in marks[: len(head)])]
    lines += [_md_row(r) for r in rows]
    return "\n".join(lines)


def verdict_cell(verdict: str) -> str:
    """A paired verdict as a table shows it: a difference found in bold."""
    return verdict if verdict == "no difference" else f"**{verdict}**"


def _md_row(cells: Sequence[object]) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"
