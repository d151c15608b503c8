"""What the item kinds share: the items' base interface, and scoring the views of an item
that are each scored on an estimate (isolated views, tabletop scenes' objects)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from beo_bench.bench import tally
from beo_bench.bench.scoring import Answer, base_row, view_row
from beo_bench.bench.suites import Kind, Suite
from beo_bench.types import Estimate, GroundTruth, View

Rows = list[dict[str, Any]]
Announce = Callable[[Rows], None]
"""Told an item's rows as far as they are known before the backend is called (the
worker pool's ``begin`` message)."""

Predict = Callable[[int, int, View], Answer]
"""The run's backend on view ``j`` of item ``index``: its estimate (None where it failed),
seconds, failure (:meth:`beo_bench.bench.evaluate.Evaluator.predict`)."""


def no_announce(rows: Rows) -> None:
    pass


class Items(ABC):
    """A suite's items without a backend: the views item ``index`` scores, their truth,
    and the item's rows before any backend call (what a failed item's rows need when its
    backend hung or crashed). A backend sees a View and nothing else (docs/benchmark.md,
    "What a backend is told"): :meth:`views` returns only the views, and the truth is
    looked up after the backend has answered (privileged bounds aside), so it is not a
    local of any frame on predict's call stack."""

    def __init__(
        self, suite: Suite, class_given: bool = False, cache_root: Path | None = None
    ) -> None:
        self.suite = suite
        self.class_given = class_given
        self.cache_root = cache_root
        """The asset cache the items' objects are kept in (the run's
        ``RunContext.cache_root``; None: the environment's)."""

    @abstractmethod
    def views(self, index: int) -> list[View]: ...

    @abstractmethod
    def truths(self, index: int, views: list[View]) -> list[GroundTruth]: ...

    @abstractmethod
    def truth_of(self, index: int, view: View) -> GroundTruth:
        """The truth of one of item ``index``'s views (after :meth:`views`)."""

    @abstractmethod
    def templates(self, index: int) -> Rows: ...

    def close(self) -> None:  # noqa: B027 (a default: nothing held)
        """Release what the items hold (a renderer, an env)."""

    def cases(self, index: int) -> list[tuple[View, GroundTruth]]:
        """The views (with their truth) that item ``index`` scores."""
        views = self.views(index)
        return list(zip(views, self.truths(index, views), strict=True))

    def base_rows(self, index: int, views: list[View]) -> Rows:
        truths = self.truths(index, views)
        return [
            base_row(index, j, v, gt, self.class_given)
            for j, (v, gt) in enumerate(zip(views, truths, strict=True))
        ]


class RunItem(Protocol):
    """Scores item ``index`` of ``items`` (its suite: ``items.suite``) with ``predict`` and
    returns its rows; ``announce`` is told the rows known before ``predict`` is called;
    ``robust``: the backend asks for the grasp most robust to its pose samples (its
    capability ``grasp="robust"``; the pick kind reads it)."""

    def __call__(
        self, items: Items, predict: Predict, index: int, announce: Announce, *, robust: bool
    ) -> Rows: ...


def run_view_item(
    items: Items, predict: Predict, index: int, announce: Announce, *, robust: bool = False
) -> Rows:
    """An item whose views are each scored on their estimate: the views, announced, then
    every prediction, then the truths and the rows."""
    suite = items.suite
    views = items.views(index)
    announce(items.base_rows(index, views))
    answers = [predict(index, j, v) for j, v in enumerate(views)]
    truths = items.truths(index, views)
    return [
        view_row(
            base_row(index, j, v, gt, items.class_given),
            v,
            gt,
            answer,
            suite.resolution,
            suite.protocol.scores_pose,
            suite.dataset,
            items.cache_root,
        )
        for j, (v, gt, answer) in enumerate(zip(views, truths, answers, strict=True))
    ]


def failed_view_rows(templates: Rows, reason: str) -> Rows:
    """The rows of an item whose backend never answered (``reason``: ``timeout after 60
    s``, ``worker died: signal 6``): scored as a backend's exception is (class wrong, no
    pose or shape: the summary counts each at its worst case). No time is recorded."""
    rows = [{**t, "failure": reason, "pred_class": -1, "correct": False} for t in templates]
    if rows:
        rows[0]["item_rows"] = len(rows)
    return rows


def no_timing(M: tally.Tally, rows: Rows) -> None:
    """No timing beyond the per-view one."""


def estimate_primary(suite: Suite) -> str:
    """The primary metric of a suite whose views are each scored on an estimate: the class
    accuracy when the pose is given (Table 3.1's headline), else the > 15 deg gross-error
    rate (Table 5.2's): a rate, scored in both tracks, that one bad view moves by at most
    one view's share (a mean rotation error can move by 180 deg / n)."""
    return "gross_err_rate" if suite.protocol.scores_pose else "class_acc"


# -- the run's report (beo_bench.bench.worstviews): its worst rows, and each one's view again ---
@dataclass(frozen=True)
class Ranking:
    """A run's rows ordered worst first by the suite's primary error."""

    criterion: str
    """What the order is by, as the report says it (``rotation error, largest first``)."""
    order: list[int]
    """Indices into the rows, worst first."""


@dataclass(frozen=True)
class ReportCase:
    """What the report shows of one row: the view it scored (rebuilt from its item index:
    items are deterministic), the truth about the object it shows, and the backend's
    estimate for it again (None: the row failed, or it was not re-predicted)."""

    row: dict[str, Any]
    view: View
    truth: GroundTruth
    estimate: Estimate | None = None
    note: str = ""
    """Anything the report should say about how the case was rebuilt."""


def rank_view_rows(suite: Suite, rows: Rows) -> Ranking:
    """Views scored on an estimate, worst first: by rotation error where the suite scores
    the pose (a failure counts as 180 degrees), else by the class (misclassified first,
    then the true class's probability, lowest first), then the voxel IoU, lowest first."""
    if suite.protocol.scores_pose:
        worst = tally.worst_cases(suite)["rot_err_deg"]
        rot = tally.field_values(rows, "rot_err_deg", worst)
        rot = np.where(np.isnan(rot), -1.0, rot)  # not measured: last
        order = sorted(range(len(rows)), key=lambda i: (-rot[i], rows[i]["item"]))
        return Ranking("rotation error, largest first (a failed view counts as 180 deg)", order)

    def key(i: int) -> tuple[bool, bool, float, float, int]:
        r = rows[i]
        prob = r.get("class_prob_true")
        iou = r.get("iou")
        return (
            not r.get("failure"),
            bool(r.get("correct")),
            1.0 if prob is None else float(prob),
            1.0 if iou is None else float(iou),
            int(r["item"]),
        )

    order = sorted(range(len(rows)), key=key)
    return Ranking(
        "failed, then misclassified, then by the true class's probability (lowest first)",
        order,
    )


def view_report_case(items: Items, row: dict[str, Any], predict: Predict | None) -> ReportCase:
    """Row ``row``'s view rebuilt from its item, with its truth; and, given ``predict``, the
    backend's estimate for it again."""
    index, j = int(row["item"]), int(row["view"])
    views = items.views(index)
    truth = items.truths(index, views)[j]  # before predicting: a scene is still this item's
    if predict is None:
        return ReportCase(row, views[j], truth)
    est, _, failure = predict(index, j, views[j])
    note = f"predicting it again failed: {failure}" if failure else ""
    return ReportCase(row, views[j], truth, est, note)


@dataclass(frozen=True)
class ItemKind:
    """What one item kind does, as its module (:mod:`.isolated`, :mod:`.tabletop`,
    :mod:`.pick`) defines it; the defaults are those of items whose views are each scored on
    an estimate."""

    kind: Kind
    categories: Callable[[Suite], tuple[str, ...]]
    """The class list the views of a suite carry."""
    open: Callable[[Suite, bool, Path | None], Items]
    """The suite's items without a backend (``open(suite, class_given, cache_root)``)."""
    run_item: RunItem = run_view_item
    failed_rows: Callable[[Rows, str], Rows] = failed_view_rows
    view_values: Callable[[Suite, Rows], dict[str, np.ndarray]] = tally.estimate_values
    collect: Callable[[tally.Tally, Rows, dict[str, np.ndarray]], None] = tally.collect_estimates
    timing: Callable[[tally.Tally, Rows], None] = no_timing
    worst_cases: Callable[[Suite], dict[str, float]] = tally.worst_cases
    primary_metric: Callable[[Suite], str] = estimate_primary
    """The ``summary["metrics"]`` key that ``beo-bench gate`` judges a suite by unless told
    other metrics (``--metrics``): one metric, so one test and no multiple comparisons."""

    rank_rows: Callable[[Suite, Rows], Ranking] = rank_view_rows
    """The rows worst first by the suite's primary error (the report's order)."""
    report_case: Callable[[Items, dict[str, Any], Predict | None], ReportCase] = view_report_case
    """A row's view again, for the report (``report_case(items, row, predict)``; ``predict``
    None: the row is shown without an estimate)."""
