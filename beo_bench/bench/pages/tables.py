"""A leaderboard page's Markdown tables: per suite, per category, per field, the dissertation's
Tables 3.1/4.1 form and the ModelNet10 confusions.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from beo_bench.bench.columns import (
    BOARD_PER_CATEGORY,
    BOARD_PER_CATEGORY_DEFAULT,
    FIELD_KEYS,
    NOCS_PER_CATEGORY,
    MetricSpec,
    board_columns,
    markdown_table,
    spec,
)
from beo_bench.bench.pages.entries import (
    HINT_UNUSED,
    TABLE_5_1_CATEGORIES,
    Row,
    _bound_mark,
    dissertation_modelnet10,
    is_bound,
    label,
    model_digest,
)


# -- cells ---------------------------------------------------------------------------------------
def _value(s: dict[str, Any], m: MetricSpec) -> str:
    """A run's value of ``m`` as a table shows it; *given* for the class accuracy of a run
    told the class."""
    if m.key == "class_acc" and s["metrics"].get("class_given"):
        return "given"
    return m.format(s["metrics"].get(m.key))


def _cell(s: dict[str, Any], m: MetricSpec) -> str:
    if m.key == "class_acc" and s["metrics"].get("class_given"):
        return "given"
    v = s["metrics"].get(m.key)
    if v is None:
        return "-"
    text = m.format(v)
    ci = s.get("ci95", {}).get(m.key)
    if ci and all(c is not None and np.isfinite(c) for c in ci):
        lo, hi = (m.format(c).rstrip("%") for c in ci)
        text += f" [{lo}, {hi}]"
    return text


def _ordered(rows: list[Row]) -> list[Row]:
    return sorted(rows, key=lambda r: (is_bound(r.summary), label(r.summary)))


def _name(r: Row, views: int | None = None) -> str:
    """The row's name: backend and options, then its marks (bound, hint not used, partial)."""
    s = r.summary
    bound = _bound_mark(s)
    marks = [bound] if bound else []
    if r.borrowed:
        marks.append(HINT_UNUSED)
    if views is not None and s["n"] < views:
        marks.append(f"partial: {s['n']} of {views} views")
    return " ".join([label(s), *(f"*({m})*" for m in marks)])


def _as_rows(rows: list[Row] | list[dict[str, Any]]) -> list[Row]:
    return [r if isinstance(r, Row) else Row(r) for r in rows]


def suite_table(rows: list[Row] | list[dict[str, Any]]) -> str:
    """The Markdown table of one section: a row per backend, the columns any of them has,
    and its model digest last."""
    rows = _as_rows(rows)
    summaries = [r.summary for r in rows]
    has = {k for s in summaries for k in s["metrics"]}
    if any(s["metrics"].get("class_given") for s in summaries):
        has.add("class_acc")
    cols = [m for m in board_columns() if m.key in has]
    views = max((s["n"] for s in summaries), default=0)
    body = [
        [_name(r, views), r.summary["n"], r.summary["failures"]]
        + [_cell(r.summary, m) for m in cols]
        + [f"`{model_digest(r.summary)}`"]
        for r in _ordered(rows)
    ]
    head = ["backend", "n", "failures", *(m.label for m in cols), "model"]
    return markdown_table(head, body, "l" + "r" * (len(cols) + 2) + "l")


def category_table(suite: str, rows: list[Row] | list[dict[str, Any]]) -> str:
    """Per metric of ``BOARD_PER_CATEGORY``: categories as rows, backends as columns."""
    summaries = [r.summary for r in _ordered(_as_rows(rows))]
    tables = []
    for key in BOARD_PER_CATEGORY.get(suite, BOARD_PER_CATEGORY_DEFAULT):
        if any(key in d for s in summaries for d in s.get("per_category", {}).values()):
            tables.append(_metric_category_table(summaries, spec(key)))
    if not tables:
        tables.append(_metric_category_table(summaries, spec("iou_mean")))
    return "\n\n".join(tables)


def field_table(rows: list[Row] | list[dict[str, Any]]) -> str:
    """The field's own figures of a section (docs/bop.md): BOP 2019's average recalls
    (AR_VSD, AR_MSSD, AR_MSPD and their mean) and the NOCS report (pose accuracies, 3D box
    IoU as NOCS's reference code computes it), a row per backend; "" when no run has them
    (runs made before they were scored)."""
    have = [r for r in _ordered(_as_rows(rows)) if "ar_bop" in r.summary["metrics"]]
    if not have:
        return ""
    cols = [spec(k) for k in FIELD_KEYS]
    body = [[_name(r)] + [m.format(r.summary["metrics"].get(m.key)) for m in cols] for r in have]
    return (
        "The field's figures (docs/bop.md): BOP 2019's average recalls and the NOCS report:\n\n"
        + markdown_table(["backend", *(m.label for m in cols)], body)
    )


def _folded(summary: str, table: str) -> str:
    """A table folded under its one-line summary (``<details>``)."""
    return "\n".join([f"<details><summary>{summary}</summary>", "", table, "", "</details>"])


def nocs_class_tables(rows: list[Row] | list[dict[str, Any]]) -> str:
    """Per method (bounds left out), the NOCS report per class: the pose accuracies and
    the 3D box IoU hits, folded (``<details>``); "" without such runs."""
    cols = [spec(k) for k in NOCS_PER_CATEGORY]
    out = []
    for r in _ordered(_as_rows(rows)):
        per = r.summary.get("per_category", {})
        if is_bound(r.summary) or not any("iou3d_50" in d for d in per.values()):
            continue
        body = [
            [c, per[c].get("n", 0)] + [m.format(per[c].get(m.key)) for m in cols]
            for c in sorted(per)
        ]
        table = markdown_table(["category", "n", *(m.label for m in cols)], body)
        out.append(_folded(f"NOCS report per class: {_name(r)}", table))
    return "\n\n".join(out)


def table_5_1(rows: list[Row]) -> str:
    """Tables 5.1 and 5.2 of the dissertation in their own form: a row per backend, the mean
    rotation error and the > 15 deg rate for car, plane (``airplane``) and couch (``sofa``).
    Empty when the rows hold none of those categories."""
    ordered = _ordered(rows)
    cats = [
        c
        for c in TABLE_5_1_CATEGORIES
        if any(c in r.summary.get("per_category", {}) for r in ordered)
    ]
    if not cats:
        return ""
    mean, gross = spec("rot_err_deg_mean"), spec("gross_err_rate")
    body = []
    for r in ordered:
        pc = r.summary.get("per_category", {})
        cells = [
            f"{mean.format(pc.get(c, {}).get(mean.key))} / "
            f"{gross.format(pc.get(c, {}).get(gross.key))}"
            for c in cats
        ]
        body.append([label(r.summary), *cells])
    return (
        "In the form of the dissertation's Tables 5.1 (mean rotation error, deg) and 5.2 "
        "(> 15 deg), per category:\n\n" + markdown_table(["backend", *cats], body)
    )


def modelnet10_table(suite: str, rows: list[Row]) -> str:
    """Tables 3.1 and 4.1 in their own form: a row per backend with its class accuracy per
    ModelNet10 class and over all of them, and the dissertation's row. Empty for a suite
    without a dissertation row or rows without classes."""
    from beo_bench.objects.sets import MODELNET10

    theirs_row = dissertation_modelnet10(suite)
    if theirs_row is None:
        return ""
    ordered = [r for r in _ordered(rows) if r.summary["metrics"].get("class_acc") is not None]
    if not ordered:
        return ""
    acc = spec("class_acc")
    cats = list(MODELNET10)
    body = [
        [label(r.summary)]
        + [acc.format(r.summary.get("per_category", {}).get(c, {}).get(acc.key)) for c in cats]
        + [acc.format(r.summary["metrics"].get(acc.key))]
        for r in ordered
    ]
    name, total, theirs = theirs_row
    cells = [acc.format(theirs[c]) if c in theirs else "" for c in cats]
    body.append([f"dissertation: {name}", *cells, acc.format(total)])
    head = ["method", *(c.replace("_", " ") for c in cats), "all"]
    return (
        "Class accuracy in the form of the dissertation's Tables 3.1 and 4.1, per ModelNet10 "
        "class:\n\n" + markdown_table(head, body)
    )


def confused_pairs(s: dict[str, Any], top: int = 3) -> list[tuple[str, str, int, int]]:
    """The ``top`` most frequent (true class, predicted class, count, true-class views)
    confusions of a run, from its confusion matrix; empty without one."""
    conf = s["metrics"].get("confusion")
    cats = s.get("categories")
    if not conf or not cats:
        return []
    M = np.asarray(conf)
    pairs = [
        (cats[i], cats[j], int(M[i, j]), int(M[i].sum()))
        for i in range(len(cats))
        for j in range(len(cats))
        if i != j and M[i, j] > 0
    ]
    pairs.sort(key=lambda p: (-p[2], p[0], p[1]))
    return pairs[:top]


def confused_pairs_table(rows: list[Row]) -> str:
    """Each backend's most frequent confusions (true -> predicted, views of the true class),
    as chapter 4 accounts for HBEO's gain over BEO; empty when no row has a confusion
    matrix."""
    body = []
    for r in _ordered(rows):
        pairs = [] if is_bound(r.summary) else confused_pairs(r.summary)
        if pairs:
            body.append(
                [label(r.summary), "; ".join(f"{a} -> {b} {k}/{n}" for a, b, k, n in pairs)]
            )
    if not body:
        return ""
    return "Most frequent confusions (true -> predicted: views of the true class):\n\n" + (
        markdown_table(["backend", "confusions"], body, "l")
    )


def confusion_counts(suite: str, rows: list[Row]) -> str:
    """Each backend's confusion matrix in counts (rows: the true class, columns: the
    predicted one, abbreviated as the rows), on the suites with a dissertation row (its
    Tables 3.1 and 4.1 are per-class accuracies; chapter 4 reads the confusions behind
    them). Folded, one block per backend; empty elsewhere."""
    if dissertation_modelnet10(suite) is None:
        return ""
    blocks = []
    for r in _ordered(rows):
        conf, cats = r.summary["metrics"].get("confusion"), r.summary.get("categories")
        if is_bound(r.summary) or not conf or not cats:
            continue
        M = np.asarray(conf, dtype=int)
        # the diagonal (views read right) in bold, the confusions plain
        body = [
            [c.replace("_", " ")] + [f"**{k}**" if j == i else str(k) for j, k in enumerate(row)]
            for i, (c, row) in enumerate(zip(cats, M, strict=True))
        ]
        head = ["true / predicted", *(c.replace("_", " ")[:5] for c in cats)]
        summary = f"Confusion matrix of {label(r.summary)} (counts)"
        blocks.append(_folded(summary, markdown_table(head, body)))
    return "\n\n".join(blocks)


def _category_table(
    rows: list[dict[str, Any]],
    title: str,
    cell: Callable[[dict[str, Any]], str],
    counts: bool = True,
) -> str:
    """Categories as rows, the runs as columns: ``cell`` of each run's figures for the
    category (``{}`` where it has none); ``counts``: the category's views after its name."""
    cats = sorted({c for s in rows for c in s.get("per_category", {})})
    body = []
    for c in cats:
        per = [s.get("per_category", {}).get(c, {}) for s in rows]
        n = [max(d.get("n", 0) for d in per)] if counts else []
        body.append([c, *n, *(cell(d) for d in per)])
    head = ["category", *(["n"] if counts else []), *(label(s) for s in rows)]
    return f"{title}\n\n" + markdown_table(head, body)


def _metric_category_table(rows: list[dict[str, Any]], m: MetricSpec) -> str:
    return _category_table(rows, f"{m.label} per category:", lambda d: m.format(d.get(m.key)))
