"""``beo-bench leaderboard``: regenerate ``leaderboards/`` from run summaries.

Per suite: ``<suite>.md``, ``<suite>.json`` (the summaries behind the tables, with their
provenance), ``<suite>_paired.json`` (the paired verdicts), and the plots
(``<suite>[_<track>]_rot_cdf.png``, ``..._confusion_<backend>.png``,
``..._error_vs_samples.png``); ``README.md`` indexes them.

Only runs scored under the same rules share a table:

- a suite with tracks (``Suite.class_hint``: the pose suites) gets a part per track,
  ``class-given`` then ``class-free``; a backend that cannot use the class hint is run in
  ``class-free`` only and listed in the ``class-given`` table too, marked *(hint not
  used)*: it would score the same there;
- within a track, one section per (seed, items): the suite's own seed and the largest run
  first. A section of fewer items than the suite's size says *partial*, and a row with
  fewer views than its section's others says so too;
- only the newest suite version is tabulated (older versions' scores are not comparable;
  the page says how many runs were left out);
- a row is a backend with its options (``icp (starts=48)``) and its model's digest (8 hex
  digits; ``-`` for none); one row per backend and options in a section.

The first section of each track also gets the per-category tables (on the ModelNet10
suites also Tables 3.1/4.1's form, the most frequent confusions and each backend's
confusion matrix in counts), the plots, and the paired verdicts: each method against the
baselines (:data:`BASELINES`), B - A on mean rotation error and the > 15 deg rate over the
items both runs scored, with a bootstrap interval over items and a verdict
(:mod:`beo_bench.bench.compare`).

Runs under a depth sensor other than the suite's own (``--sensor``; the tabletop suite's
own is ``kinect-v1``, the others' ``ideal``) are tabulated the same way in the page's part
for that sensor (``## sensor d435``), after the suite's own; a page with runs under more
than one sensor gets a robustness table (:func:`robustness`): per backend and headline
metric (:data:`~beo_bench.bench.columns.ROBUSTNESS_KEYS`) its value under each sensor,
``ideal -> kinect-v1 -> d435``, each paired with the first on the same items (item ``i``
is the same scene under every sensor), written into ``<suite>_paired.json`` with
``"pairing": "sensor"``. A page whose runs are all at the suite's own sensor is as it was
before sensors existed.

A pick page (:func:`is_pick_suite`) also holds every run's episodes in its JSON, one short
record each (:func:`attach_episodes`, :data:`EPISODE_FIELDS`), pairs each method with
``hbeo`` and the MDN's two modes with each other episode by episode (:func:`pick_comparisons`:
an interval, an exact McNemar p and a verdict, ``"pairing": "method"`` in its
``_paired.json``), and counts its successes per category (:func:`pick_category_table`).
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from beo_bench.atomic import atomic_write_bytes
from beo_bench.backend import IN_TREE, in_tree
from beo_bench.bench import ablations, compare, rundir
from beo_bench.bench.columns import (
    BOARD_PER_CATEGORY,
    BOARD_PER_CATEGORY_DEFAULT,
    DEGRADATION_KEYS,
    FIELD_KEYS,
    NOCS_PER_CATEGORY,
    ROBUSTNESS_KEYS,
    VERDICT_KEYS,
    MetricSpec,
    board_columns,
    markdown_table,
    spec,
    verdict_cell,
)
from beo_bench.bench.kinds.pick import AUDIT_FIELDS
from beo_bench.bench.runs import RunError, backend_label, options_label
from beo_bench.bench.scoring import PICK_ERRORS
from beo_bench.errors import UsageError

BOUNDS: dict[str, str] = {n: IN_TREE[n].role for n in in_tree("upper bound", "lower bound")}
PRIVILEGED_MARK = "privileged: given the truth"
"""How a row is marked whose backend was handed the ground truth (``privileged``) and is not
one of the :data:`BOUNDS`: such rows are listed with the bounds and never ranked or paired."""


SCORED_MARK = "scored file"
"""How the row of a scored BOP results file (``beo-bench score``) is marked: ``m (scored
file)``. Such a row is a method's, whatever its name: never a bound or a baseline."""


def is_scored_file(s: dict[str, Any]) -> bool:
    """Whether the run is a scored results file's (its provenance's ``bop_results``)."""
    prov = s.get("provenance") or {}
    return isinstance(prov, dict) and bool(prov.get("bop_results"))


def is_bound(s: dict[str, Any]) -> bool:
    """Whether a run is a bound, not a method: ``oracle``, ``random``, or any backend that
    was handed the truth (its summary's ``privileged``); never a scored file's."""
    if is_scored_file(s):
        return False
    return s["backend"] in BOUNDS or bool(s.get("privileged"))


def _bound_mark(s: dict[str, Any]) -> str | None:
    if is_scored_file(s):
        return None
    if s["backend"] in BOUNDS:
        return BOUNDS[s["backend"]]
    return PRIVILEGED_MARK if s.get("privileged") else None


BASELINES: tuple[str, ...] = in_tree("baseline")
"""The baselines every method is paired against (default options only): the
dissertation's plain ICP and this benchmark's multi-start ICP."""
DIAGNOSTIC = in_tree("diagnostic")
"""Backends that are analysis tools, not methods (never paired)."""
TRACK_ORDER: tuple[str | None, ...] = ("class-given", "class-free", None)
TRACK_NOTES = {
    "class-given": "The true class is given to every backend that can use it (the "
    "dissertation's pose comparisons, Figures 3.6 and 4.3); rows marked *(hint not used)* "
    "are the class-free runs of backends that cannot use it (they would score the same).",
    "class-free": "No backend is told the class.",
}
HINT_UNUSED = "hint not used"

TABLE_5_1_CATEGORIES: tuple[str, ...] = ("car", "airplane", "sofa")
"""The categories of the dissertation's Tables 5.1 and 5.2 (car, plane, couch)."""
TABLE_5_1_SUITES: tuple[str, ...] = ("pose-3dof", "pose-3dof-percat")
"""The suites whose pages carry a table in the form of Tables 5.1/5.2."""
PER_CATEGORY_SUITES: tuple[str, ...] = ("pose-3dof-percat",)
"""Suites whose ablations are paired per category too, as Tables 5.1/5.2 report them."""
DISSERTATION_MODELNET10: dict[str, tuple[str, float, dict[str, float]]] = {
    # per class: BEO's known-pose row of Table 3.1 on the three classes chapter 4 quotes
    "modelnet10-known-pose": (
        "BEO, known pose (Table 3.1; 3DShapeNets 54.4%)",
        0.763,
        {"bathtub": 0.480, "desk": 0.465, "night_stand": 0.558},
    ),
    # per class: BEO's 1-DOF row of Table 3.1 on the same three classes (not the known-pose
    # row's 48.0 / 46.5 / 55.8%, which this row once carried by mistake, issue 47)
    "modelnet10-1dof": (
        "BEO, 1-DOF (Table 3.1)",
        0.545,
        {"bathtub": 0.040, "desk": 0.163, "night_stand": 0.360},
    ),
    # per class: HBEO's 3-DOF row of Table 4.1 on the same three classes
    "modelnet10-3dof": (
        "HBEO, 3-DOF (Table 4.1)",
        0.818,
        {"bathtub": 0.913, "desk": 0.576, "night_stand": 0.813},
    ),
}
"""The dissertation's ModelNet10 class accuracy beside each ``modelnet10-*`` suite's
per-class table, in the form of Tables 3.1 and 4.1: the row's name, its accuracy over all
classes, and the per-class accuracies this project has. Those are the three classes (desk,
night stand, bathtub) that chapter 4 quotes to explain HBEO's gain over BEO, each row's own
figures for them (Table 3.1's known-pose and 1-DOF rows, Table 4.1's 3-DOF row); the
tables' other per-class cells are not in this project's sources and stay empty.
docs/results.md's chapter-4 table reads the same figures from here."""
MODELNET10_OUR_VIEWS: dict[str, str] = {
    "known-pose+modelnet10": "modelnet10-known-pose",
    "pose-1dof+modelnet10": "modelnet10-1dof",
    "pose-3dof+modelnet10": "modelnet10-3dof",
}
"""Our viewpoint suites restricted to the ModelNet10 set (``--categories modelnet10``), each
with the ``modelnet10-*`` suite of the same protocol: their pages carry the same per-class
table and the same dissertation row, so our viewpoint distribution reads beside chapter 3's
top-down view (docs/results.md)."""
OOD_SUFFIX = "-ood"
DIGEST_CHARS = 8


def dissertation_modelnet10(suite: str) -> tuple[str, float, dict[str, float]] | None:
    """The dissertation's ModelNet10 row for ``suite`` (:data:`DISSERTATION_MODELNET10`),
    also for its twin over our viewpoints (:data:`MODELNET10_OUR_VIEWS`); None elsewhere."""
    return DISSERTATION_MODELNET10.get(MODELNET10_OUR_VIEWS.get(suite, suite))


# -- what a table row is -------------------------------------------------------------------------
@dataclass(frozen=True)
class Row:
    """A run as a leaderboard row: its summary, its directory (for paired comparisons) and
    whether it stands in a track it was not run in (a backend that cannot use the hint)."""

    summary: dict[str, Any]
    path: Path | None = None
    borrowed: bool = False


def load_summaries(runs: Path) -> list[dict[str, Any]]:
    """Every ``summary.json`` under ``runs``."""
    return [r.summary for r in load_rows(runs)]


def load_rows(runs: Path) -> list[Row]:
    """Every ``summary.json`` under ``runs``, with its run directory (an unreadable one is
    a :class:`~beo_bench.errors.CorruptDataError` naming it and how to rewrite it)."""
    return [
        Row(summary, where)
        for where, summary in (
            rundir.load_summary(p) for p in sorted(Path(runs).rglob(rundir.SUMMARY_NAME))
        )
    ]


def label(s: dict[str, Any]) -> str:
    """A summary's row name: the backend and its options; a scored file's method marked
    (:data:`SCORED_MARK`), so it never reads, or pairs, as an in-tree backend."""
    name = backend_label(s["backend"], _kwargs(s))
    return f"{name} ({SCORED_MARK})" if is_scored_file(s) else name


def _kwargs(s: dict[str, Any]) -> dict[str, Any]:
    return s.get("provenance", {}).get("backend_kwargs") or {}


def model_digest(s: dict[str, Any]) -> str:
    """The run's model digest, shortened; ``-`` when the backend has no learned model."""
    digest = s.get("model_digest") or s.get("provenance", {}).get("model_digest")
    return str(digest)[:DIGEST_CHARS] if digest else "-"


def items(s: dict[str, Any]) -> int:
    """How many items the run covers (its suite's size; its row count when not recorded)."""
    size = rundir.summary_size(s)
    return size if size is not None else int(s["n"])


def suite_size(name: str) -> int | None:
    """The registered suite's own size (None for a suite this package does not know)."""
    from beo_bench.bench.suites import SUITES, base_name

    name = base_name(name)  # a suite on a user's dataset has its base suite's size
    return SUITES[name].size if name in SUITES else None


def suite_seed(name: str) -> int | None:
    from beo_bench.bench.suites import SUITES, base_name

    name = base_name(name)
    return SUITES[name].seed if name in SUITES else None


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


def _savefig(fig: Any, path: Path) -> None:
    import io

    buf = io.BytesIO()
    fig.savefig(buf, dpi=100, format="png", metadata={"Software": None})
    atomic_write_bytes(path, buf.getvalue())


def _slug(text: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in text).strip("_")


ERROR_BINS: dict[str, tuple[str, str, tuple[float, ...]]] = {
    "rot_err_deg": ("rotation error", "deg", (0, 5, 15, 30, 60, 180)),
    "trans_err_cm": ("translation error", "cm", (0, 0.5, 1, 2, 4, 100)),
    "iou_cam": ("IoU in the camera frame", "", (0, 0.25, 0.5, 0.75, 1)),
}
"""The bins of pick's success against each error of the grasped estimate (issue 49)."""


def error_bins(eps: list[dict[str, Any]], key: str) -> list[tuple[float, float, int]]:
    """(median error, success rate, episodes) of each non-empty bin of ``eps`` by ``key``
    (:data:`ERROR_BINS`; the last bin holds its upper edge)."""
    from itertools import pairwise

    edges = ERROR_BINS[key][2]
    out = []
    for lo, hi in pairwise(edges):
        top = hi if hi == edges[-1] else np.nextafter(hi, -np.inf)
        sel = [e for e in eps if e.get(key) is not None and lo <= e[key] <= top]
        if sel:
            rate = sum(bool(e["success"]) for e in sel) / len(sel)
            out.append((float(np.median([e[key] for e in sel])), rate, len(sel)))
    return out


def found_target_episodes(s: dict[str, Any]) -> list[dict[str, Any]]:
    """A pick row's episodes that chose their target and record its estimate's errors."""
    eps = [e for e in episodes(s).values() if e.get("chosen_is_target")]
    return [e for e in eps if e.get("rot_err_deg") is not None]


def _pick_error_plot(out: Path, prefix: str, title: str, summaries: list[dict[str, Any]]) -> str:
    """Pick success against each error of the grasped estimate, binned (each point at its
    bin's median error, sized by its episodes): every perception row pooled, then each."""
    import matplotlib.pyplot as plt

    per = {label(s): found_target_episodes(s) for s in summaries}
    per = {k: v for k, v in per.items() if v}
    fig, axes = plt.subplots(1, len(ERROR_BINS), figsize=(13, 4), constrained_layout=True)
    pooled = [e for v in per.values() for e in v]
    for ax, (key, (what, unit, _)) in zip(axes, ERROR_BINS.items(), strict=True):
        for name, eps in [("every row", pooled), *per.items()]:
            pts = error_bins(eps, key)
            if not pts:
                continue
            x, y, n = (np.array(v) for v in zip(*pts, strict=True))
            bold = name == "every row"
            ax.plot(
                x,
                y,
                "k-" if bold else "-",
                lw=2.5 if bold else 1,
                label=name,
                zorder=3 if bold else 2,
            )
            ax.scatter(x, y, s=4 + 40 * n / max(n.max(), 1), color="k" if bold else None, zorder=4)
        ax.set_xlabel(f"{what} ({unit})" if unit else what)
        ax.set_ylim(0, 1)
        if key == "trans_err_cm":
            ax.set_xscale("log")  # bins of 0.5 to 4 cm: even on a log axis
    axes[0].set_ylabel("pick success (episodes that chose their target)")
    axes[-1].legend(fontsize="x-small")
    fig.suptitle(f"{title}: success against the grasped estimate's error")
    name = f"{prefix}_success_vs_error.png"
    _savefig(fig, out / name)
    plt.close(fig)
    return name


def _plots(out: Path, prefix: str, title: str, rows: list[Row]) -> list[str]:
    """The rotation-error CDF, error against samples and confusion plots of one section;
    file names start with ``prefix`` (the suite, and its track)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    ordered = [r.summary for r in _ordered(rows)]
    with_rot = [s for s in ordered if s["metrics"].get("rot_err_deg")]
    if with_rot:
        fig, ax = plt.subplots(figsize=(6, 4), constrained_layout=True)
        for s in with_rot:
            e = np.sort(np.asarray(s["metrics"]["rot_err_deg"], dtype=float))
            e = e[np.isfinite(e)]
            ax.step(e, np.arange(1, len(e) + 1) / len(e), where="post", label=label(s))
        ax.set_xlabel("rotation error (deg, symmetry-aware)")
        ax.set_ylabel("fraction of views")
        ax.set_xlim(-3, 180)  # a perfect backend's step at 0 stays visible
        ax.set_ylim(0, 1)
        ax.axvline(15, color="grey", lw=0.8, ls="--")
        ax.legend(fontsize="small")
        ax.set_title(f"{title}: rotation-error CDF")
        name = f"{prefix}_rot_cdf.png"
        _savefig(fig, out / name)
        plt.close(fig)
        written.append(name)
    sampled = [s for s in with_rot if "samples" in _kwargs(s)]
    if sampled:
        written.append(_error_vs_samples(out, prefix, title, with_rot, sampled))
    perceiving = [s for s in ordered if not is_bound(s) and s["backend"] not in DIAGNOSTIC]
    if any(found_target_episodes(s) for s in perceiving):
        written.append(_pick_error_plot(out, prefix, title, perceiving))
    drawn: set[str] = set()
    for r in _ordered(rows):
        conf = r.summary["metrics"].get("confusion")
        if not conf or r.borrowed:  # a borrowed run's plot is its own track's
            continue
        # a variant of a row above with the same model and the same class decisions (an
        # ablation of the pose step, another sample count) would draw the same matrix again
        key = json.dumps([r.summary.get("model_digest"), conf])
        if key in drawn:
            continue
        drawn.add(key)
        written.append(_confusion(out, prefix, title, r.summary, conf))
    return written


def _confusion(out: Path, prefix: str, title: str, s: dict[str, Any], conf: Any) -> str:
    import matplotlib.pyplot as plt

    fig = confusion_figure(conf, s.get("categories"), f"{title} / {label(s)}")
    name = f"{prefix}_confusion_{_slug(label(s))}.png"
    _savefig(fig, out / name)
    plt.close(fig)
    return name


def confusion_figure(conf: Any, categories: list[str] | None, title: str) -> Any:
    """The confusion matrix ``conf`` (true class x predicted class, counts) as a figure:
    each cell's colour is its row-normalised rate (the fraction of the true class), and its
    text the count itself (at 2 views a class, 1 of 2 and 50% of many read alike); the true
    classes' labels carry their view counts."""
    import matplotlib.pyplot as plt

    c = np.asarray(conf, dtype=float)
    k = len(c)
    side = max(5.0, 2.2 + 0.45 * k)  # cells of about 0.4 inch (10.3 inches at 18 classes)
    fig, ax = plt.subplots(figsize=(side + 0.8, side), constrained_layout=True)
    totals = c.sum(axis=1)
    norm = c / np.maximum(totals[:, None], 1)
    im = ax.imshow(norm, vmin=0, vmax=1, cmap="Blues")
    size = 9 if k <= 12 else max(5, 9 - (k - 12) // 3)
    for i in range(k):
        for j in range(k):
            v = c[i, j]
            text = f"{v:.0f}" if float(v).is_integer() else f"{v:.1f}"
            colour = "white" if norm[i, j] > 0.55 else ("0.6" if v == 0 else "black")
            ax.text(j, i, text, ha="center", va="center", fontsize=size, color=colour)
    ax.set_xlabel("predicted class")
    ax.set_ylabel("true class (views)")
    if categories and len(categories) == k:
        ax.set_xticks(range(k), categories, rotation=90)
        rows = [f"{n} ({t:.0f})" for n, t in zip(categories, totals, strict=True)]
        ax.set_yticks(range(k), rows)
    fig.colorbar(im, ax=ax, shrink=0.8, label="fraction of the true class")
    ax.set_title(f"{title}\n(cell: views; colour: fraction of the row)", fontsize="small")
    return fig


MDN_DEFAULT_SAMPLES = 25
"""N for an MDN row without a ``samples`` option (``HBEOOptions.samples``' default; a test
keeps the two equal): its point on the error-against-N curve."""


def _series(s: dict[str, Any]) -> str:
    """The curve a sampling row belongs to: its backend and options but ``samples``."""
    return backend_label(s["backend"], {k: v for k, v in _kwargs(s).items() if k != "samples"})


def sample_curves(
    with_rot: list[dict[str, Any]], sampled: list[dict[str, Any]]
) -> dict[str, list[tuple[int, float, Any]]]:
    """Figure 5.3's curves: per backend and options but ``samples`` (:func:`_series`; the
    shared network and each category's own are two curves), (N, mean rotation error, its
    interval) of every row of that series, N ascending, a row without ``samples`` at
    :data:`MDN_DEFAULT_SAMPLES`; bounds left out."""
    keys = {_series(s) for s in sampled}
    lines: dict[str, list[tuple[int, float, Any]]] = {}
    for s in with_rot:
        if is_bound(s) or _series(s) not in keys:
            continue
        ci = s.get("ci95", {}).get("rot_err_deg_mean")
        n = int(_kwargs(s).get("samples", MDN_DEFAULT_SAMPLES))
        lines.setdefault(_series(s), []).append((n, s["metrics"]["rot_err_deg_mean"], ci))
    return {k: sorted(v, key=lambda p: p[0]) for k, v in lines.items()}


def _error_vs_samples(
    out: Path,
    prefix: str,
    title: str,
    with_rot: list[dict[str, Any]],
    sampled: list[dict[str, Any]],
) -> str:
    """Mean rotation error against N, the samples drawn (dissertation Figure 5.3): a line
    per sampling backend and its other options (the shared network and each category's
    own are two lines), through its rows at N = 5, the default and 100; the plain backends
    (no options) as horizontal references."""
    import matplotlib.pyplot as plt

    lines = sample_curves(with_rot, sampled)
    fig, ax = plt.subplots(figsize=(6, 4), constrained_layout=True)
    for name, pts in sorted(lines.items()):
        x = [p[0] for p in pts]
        y = [p[1] for p in pts]
        ax.plot(x, y, marker="o", label=name)
        lo = [p[2][0] if p[2] else p[1] for p in pts]
        hi = [p[2][1] if p[2] else p[1] for p in pts]
        ax.fill_between(x, lo, hi, alpha=0.15)
    # the plain methods as references, those within twice the curves' range (a far-off
    # baseline would squash the curves this plot is about)
    top = 2 * max(y for pts in lines.values() for _, y, _ in pts)
    others = [s for s in with_rot if not _kwargs(s) and label(s) not in lines and not is_bound(s)]
    styles = iter(["--", ":", "-.", (0, (5, 1)), (0, (1, 3))] * 4)
    for i, s in enumerate(o for o in others if o["metrics"]["rot_err_deg_mean"] <= top):
        ax.axhline(
            s["metrics"]["rot_err_deg_mean"],
            ls=next(styles),
            lw=1,
            label=label(s),
            color=f"C{i + len(lines)}",
        )
    ax.set_ylim(0, top)
    ax.set_xscale("log")
    ax.set_xlabel("N, rotation samples drawn")
    ax.set_ylabel("mean rotation error (deg)")
    ax.legend(fontsize="small")
    ax.set_title(f"{title}: error against N (cf. Figure 5.3)", fontsize="medium")
    name = f"{prefix}_error_vs_samples.png"
    _savefig(fig, out / name)
    plt.close(fig)
    return name


# -- grouping: tracks and sections ---------------------------------------------------------------
@dataclass(frozen=True)
class Section:
    """Runs of one suite version, track, seed and item count: the rows of one table."""

    suite: str
    version: int
    track: str | None
    seed: int | None
    items: int
    rows: list[Row]

    @property
    def partial(self) -> str | None:
        """``200 of the suite's 550 items`` when the runs cover fewer items than the suite's
        registered size, else None."""
        size = suite_size(self.suite)
        if size is None or self.items >= size:
            return None
        return f"{self.items} of the suite's {size} items"

    @property
    def title(self) -> str:
        """``seed 2000, 500 items``, with ``(partial: ...)`` below the suite's size."""
        text = f"seed {self.seed}, {self.items} items"
        return text + (f" (partial: {self.partial})" if self.partial else "")


def _track_key(track: str | None) -> int:
    return TRACK_ORDER.index(track) if track in TRACK_ORDER else len(TRACK_ORDER)


def _one_per_label(rows: list[Row]) -> list[Row]:
    """One row per backend and options: the run with the most views (then the first)."""
    best: dict[str, Row] = {}
    for r in rows:
        key = label(r.summary)
        if key not in best or r.summary["n"] > best[key].summary["n"]:
            best[key] = r
    return _ordered(list(best.values()))


def track_rows(rows: list[Row]) -> dict[str | None, list[Row]]:
    """Each track's rows (tracks in :data:`TRACK_ORDER`): its own runs, and in
    ``class-given`` the class-free runs of backends that cannot use the hint (borrowed,
    unless the backend has a class-given run with the same options, seed and items)."""
    by_track: dict[str | None, list[Row]] = {}
    for r in rows:
        by_track.setdefault(rundir.track_of(r.summary), []).append(r)
    given = by_track.get("class-given")
    if given is not None:
        own = {(label(r.summary), r.summary.get("seed"), items(r.summary)) for r in given}
        for r in by_track.get(compare.CLASS_FREE, []):
            key = (label(r.summary), r.summary.get("seed"), items(r.summary))
            if compare.hint_unused(r.summary) and key not in own:
                given.append(Row(r.summary, r.path, borrowed=True))
    return {t: by_track[t] for t in sorted(by_track, key=_track_key)}


def sections(suite: str, version: int, track: str | None, rows: list[Row]) -> list[Section]:
    """The track's rows cut by (seed, items): the suite's own seed first, then the most
    items first."""
    groups: dict[tuple[Any, int], list[Row]] = {}
    for r in rows:
        groups.setdefault((r.summary.get("seed"), items(r.summary)), []).append(r)
    own = suite_seed(suite)
    order = sorted(groups, key=lambda k: (k[0] != own, -k[1], str(k[0])))
    return [Section(suite, version, track, k[0], k[1], _one_per_label(groups[k])) for k in order]


# -- paired verdicts -----------------------------------------------------------------------------
@dataclass(frozen=True)
class Verdict:
    """One method against one baseline on one metric (B = method, A = baseline)."""

    track: str | None
    method: str
    baseline: str
    result: compare.PairedResult
    sensor: str | None = None
    """The sensor of both runs when it is not the suite's own (None: the suite's own)."""


def _is_method(s: dict[str, Any]) -> bool:
    if is_scored_file(s):
        return True
    return not is_bound(s) and s["backend"] not in (*BASELINES, *DIAGNOSTIC)


def paired_verdicts(section: Section, sensor: str | None = None) -> list[Verdict]:
    """Each method of the section against each baseline run with default options, on
    :data:`VERDICT_KEYS`, when both runs' results are at hand with the same items."""
    baselines = [
        r for b in BASELINES for r in section.rows if label(r.summary) == b and r.path is not None
    ]
    methods = [r for r in section.rows if _is_method(r.summary) and r.path is not None]
    out = []
    loaded: dict[Path, compare.Run | None] = {}
    for m in methods:
        for b in baselines:
            a_run, b_run = _run(b, loaded), _run(m, loaded)
            if a_run is None or b_run is None or a_run.items != b_run.items:
                continue
            both = {p.key for p in compare.pairable(a_run.summary, b_run.summary)}
            keys = [k for k in VERDICT_KEYS if k in both]
            try:
                results = compare.paired_runs(a_run, b_run, keys)
            except UsageError:  # not the same items scored the same way: no verdict
                continue
            out += [
                Verdict(section.track, label(m.summary), label(b.summary), r, sensor)
                for r in results
            ]
    return out


def _run(r: Row, loaded: dict[Path, compare.Run | None]) -> compare.Run | None:
    """The row's run with its result rows (None when they cannot be read or paired)."""
    assert r.path is not None
    if r.path not in loaded:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # damaged lines were reported by the run
                loaded[r.path] = compare.run_from(r.path, r.summary)
        except UsageError:
            loaded[r.path] = None
    return loaded[r.path]


def verdict_table(verdicts: list[Verdict]) -> str:
    """The Markdown table of paired verdicts: a row per (method, baseline), per metric
    B - A with its 95% interval and the verdict for the method; "" without verdicts."""
    if not verdicts:
        return ""
    keys = [k for k in VERDICT_KEYS if any(v.result.key == k for v in verdicts)]
    pairs: dict[tuple[str, str], dict[str, compare.PairedResult]] = {}
    for v in verdicts:
        pairs.setdefault((v.method, v.baseline), {})[v.result.key] = v.result
    body = [[method, base, *_verdict_cells(res, keys)] for (method, base), res in pairs.items()]
    return (
        "Paired verdicts (exploratory: each method against each baseline on the items both "
        "scored; 95% bootstrap intervals that resample items; *better* / *worse* when the "
        f"interval excludes 0, {UNCORRECTED_NOTE}):\n\n"
        + markdown_table(
            ["method", "baseline", *_verdict_head("method - baseline", keys)],
            body,
            "llr" + "rl" * len(keys),
        )
    )


def _verdict_head(diff: str, keys: list[str]) -> list[str]:
    """The headers of a paired table's items and its (difference, verdict) columns."""
    return [
        "items",
        *(x for k in keys for x in (f"{spec(k).label}: {diff} [95%]", f"verdict, {UNCORRECTED}")),
    ]


def _verdict_cells(res: dict[str, Any], keys: list[str] | tuple[str, ...]) -> list[object]:
    """The items and the (difference [95%], verdict) cells of one paired row, "-" for a
    metric the pair lacks."""
    cells: list[object] = [max(r.n_items for r in res.values())]
    for k in keys:
        r = res.get(k)
        if r is None:
            cells += ["-", "-"]
            continue
        cells += [r.spec.format_interval(r.diff, r.lo, r.hi), verdict_cell(r.verdict)]
    return cells


def _verdict_json(v: Verdict) -> dict[str, Any]:
    out = compare.paired_json(v.result, "baseline", v.track, v.method, v.baseline)
    if v.sensor is not None:  # the suite's own sensor's entries are as they always were
        out["sensor"] = v.sensor
    return out


# -- primary comparisons (issue 47) --------------------------------------------------------------
@dataclass(frozen=True)
class Primary:
    """A comparison a page exists to make, declared before its runs (docs/benchmark.md,
    "Primary comparisons"): B = ``method`` against A = ``baseline`` (row labels) on
    ``metric`` in ``track``. ``source`` says why: a dissertation ordering (its table or
    figure; ``expected`` ``"better"``: the dissertation found the method ahead) or the
    page's own question (``expected`` None: no side is expected)."""

    method: str
    baseline: str
    metric: str
    track: str | None
    source: str
    expected: str | None = "better"


def _beo_over_plain_icp(source: str) -> tuple[Primary, ...]:
    """Figures 3.6 (1-DOF) and 4.3 (3-DOF): BEO errs less in rotation than plain ICP, every
    method told the class; on the mean and on the share above 15 deg."""
    return tuple(
        Primary("beo", "icp-plain", key, "class-given", source)
        for key in ("rot_err_deg_mean", "gross_err_rate")
    )


def _chapter_5(track: str | None, samples: tuple[str, ...] = ("",)) -> tuple[Primary, ...]:
    """Chapter 5: each MDN mode errs less in rotation than HBEO (Table 5.1's mean, Table
    5.2's share above 15 deg), and the posterior (eq. 5.6's silhouette prior) less than the
    likelihood on the mean (Table 5.1), at each sample count in ``samples`` (row-label
    suffixes: ``""`` the default N = 25, :data:`N100`)."""
    tables = (("rot_err_deg_mean", "Table 5.1"), ("gross_err_rate", "Table 5.2"))
    return (
        *(
            Primary(f"hbeo-mdn-{mode}", "hbeo", key, track, table)
            for mode in ("likelihood", "posterior")
            for key, table in tables
        ),
        *(
            Primary(
                f"hbeo-mdn-posterior{n}",
                f"hbeo-mdn-likelihood{n}",
                "rot_err_deg_mean",
                track,
                "Table 5.1 (eq. 5.6's prior)",
            )
            for n in samples
        ),
    )


N100 = " (samples=100)"
PER_CAT = "per_category=true"
_KNOWN_POSE = (Primary("beo", "icp", "class_acc", None, "Table 3.1"),)
"""Table 3.1: at a known pose BEO reads the class better than 3DShapeNets; here the nearest
class-mean shape (``icp``) stands in for the shape-matching baseline."""
_HBEO_OVER_BEO = "Table 4.1"
_3DOF = (*_beo_over_plain_icp("Figure 4.3"),
         Primary("hbeo", "beo", "class_acc", "class-free", _HBEO_OVER_BEO))  # fmt: skip
PICK_METHODS: tuple[str, ...] = ("beo", "hbeo-mdn-likelihood", "hbeo-mdn-posterior", "icp",
                                 "icp-plain")  # fmt: skip
ROBUST = options_label({"grasp": "robust"})
"""The option of a row whose grasp is planned over its pose samples (``Capabilities.grasp``)."""
PRIMARY_COMPARISONS: dict[str, tuple[Primary, ...]] = {
    "known-pose": _KNOWN_POSE,
    "modelnet10-known-pose": _KNOWN_POSE,
    "pose-1dof": _beo_over_plain_icp("Figure 3.6"),
    "modelnet10-1dof": _beo_over_plain_icp("Figure 3.6"),
    "pose-3dof": (*_3DOF, *_chapter_5("class-free", ("", N100))),
    "pose-3dof-ood": (*_3DOF, *_chapter_5("class-free", ("", N100))),
    "modelnet10-3dof": (*_3DOF, *_chapter_5("class-free")),
    "pose-3dof-percat": (
        *_chapter_5("class-free", ("", N100)),
        # chapter 5's own setting (issue 48): each category's network, the class given
        *(
            Primary(
                f"hbeo-mdn-posterior ({PER_CAT}{n})",
                f"hbeo-mdn-likelihood ({PER_CAT}{n})",
                key,
                "class-given",
                f"{table} (eq. 5.6's prior, per-category networks)",
            )
            for n, key, table in (
                ("", "rot_err_deg_mean", "Table 5.1"),
                ("", "gross_err_rate", "Table 5.2"),
                (", samples=100", "rot_err_deg_mean", "Table 5.1"),
            )
        ),
    ),
    "tabletop": (Primary("hbeo", "beo", "class_acc", None, _HBEO_OVER_BEO), *_chapter_5(None)),
    "pick": (
        *(
            Primary(m, "hbeo", "pick_success", None, "pick: each method against hbeo", None)
            for m in PICK_METHODS
        ),
        Primary(
            "hbeo-mdn-posterior",
            "hbeo-mdn-likelihood",
            "pick_success",
            None,
            "pick: the MDN's two modes",
            None,
        ),
        # declared before its runs: does planning over the posterior's samples pick more
        # often than planning on its single best sample (the same estimates)?
        Primary(
            f"hbeo-mdn-posterior ({ROBUST})",
            "hbeo-mdn-posterior",
            "pick_success",
            None,
            "pick: a grasp planned over the MDN's pose samples",
            None,
        ),
    ),
}
"""Per leaderboard page, the few comparisons it exists to make (docs/benchmark.md, "Primary
comparisons", is generated from this): the dissertation's orderings on the suites that test
them, and at ``pick`` method against method. A suite restricted to a class set
(``SUITE+SET``) has its base suite's. Each page's found comparisons are one family,
Holm-corrected (:func:`primary_results`); every other verdict on a page is exploratory and
says it is uncorrected."""
DISSERTATION_PROTOCOL: tuple[str, ...] = (
    "modelnet10-known-pose", "modelnet10-1dof", "modelnet10-3dof", "pose-3dof-percat"
)  # fmt: skip
"""The suites that run the dissertation's own protocol: Table 3.1's top-down ModelNet10 views
at a known pose and at 1-DOF (Figure 3.6), Table 4.1's ModelNet10 classes at 3-DOF (Figure
4.3), Tables 5.1/5.2's car, airplane and sofa views. Every other suite is this benchmark's."""
PRIMARY_ALPHA = 0.05
"""The family-wise error rate of each page's primary comparisons (Holm)."""
NOT_RUN = "not run"
UNCORRECTED = "uncorrected"
UNCORRECTED_NOTE = (
    "uncorrected for the page's many comparisons (its primary comparisons are the corrected ones)"
)
"""How an exploratory verdict says it is uncorrected (its column, and its table's note)."""


def primary_comparisons(suite: str) -> tuple[Primary, ...]:
    """The page's declared comparisons (:data:`PRIMARY_COMPARISONS`; a ``SUITE+SET`` or a
    suite on a user's dataset has its base suite's)."""
    from beo_bench.bench.suites import base_name

    return PRIMARY_COMPARISONS.get(suite, PRIMARY_COMPARISONS.get(base_name(suite), ()))


def ordering_verdict(expected: str | None, verdict: str) -> str | None:
    """Whether a dissertation ordering (the method ``expected`` to be ``better``) holds on a
    paired ``verdict``: ``holds`` when it is the expected one, ``no difference`` when the test
    cannot tell (an ordering that is not shown does not hold), ``fails`` when it goes the
    other way; None for a comparison with no expected side."""
    if expected is None:
        return None
    if verdict in ("no difference", NOT_RUN):
        return verdict
    return "holds" if verdict == expected else "fails"


@dataclass(frozen=True)
class PrimaryResult:
    """A declared comparison on its page: the paired result (None when the page lacks one of
    the two runs, or they scored other items), the sign-flip p and the Holm-adjusted one
    over the page's ``family`` of found comparisons."""

    primary: Primary
    result: compare.PairedResult | None
    p: float = 1.0
    p_holm: float = 1.0
    family: int = 0

    @property
    def verdict(self) -> str:
        """``better`` / ``worse`` for the method when the Holm-adjusted p is at most
        :data:`PRIMARY_ALPHA`, else ``no difference``; :data:`NOT_RUN` without a result."""
        r = self.result
        if r is None:
            return NOT_RUN
        if self.p_holm > PRIMARY_ALPHA or r.diff == 0:
            return "no difference"
        return "better" if (r.diff > 0) == r.spec.higher_is_better else "worse"

    @property
    def ordering(self) -> str | None:
        return ordering_verdict(self.primary.expected, self.verdict)


def primary_results(suite: str, tracks: dict[str | None, list[Section]]) -> list[PrimaryResult]:
    """Every declared comparison of the page (:func:`primary_comparisons`) on its track's
    first section (the suite's own sensor): B - A over the items both runs scored, with the
    paired bootstrap interval (:func:`beo_bench.bench.compare.paired_runs`) and the
    sign-flip p over items that ``beo-bench gate`` uses (:func:`beo_bench.stats.sign_flip_p`),
    Holm-adjusted over the comparisons found (:func:`beo_bench.stats.holm`): one family per
    page."""
    from beo_bench.stats import holm, per_item_sums, sign_flip_p

    loaded: dict[Path, compare.Run | None] = {}
    found: list[tuple[Primary, compare.PairedResult | None, float]] = []
    for pc in primary_comparisons(suite):
        secs = tracks.get(pc.track)
        rows = {label(r.summary): r for r in secs[0].rows if r.path is not None} if secs else {}
        m, b = rows.get(pc.method), rows.get(pc.baseline)
        a_run = _run(b, loaded) if b is not None else None
        b_run = _run(m, loaded) if m is not None else None
        if a_run is None or b_run is None or a_run.items != b_run.items:
            found.append((pc, None, 1.0))
            continue
        try:
            got = compare.paired_runs(a_run, b_run, [pc.metric])
        except UsageError:  # not the same items scored the same way
            got = []
        if not got:
            found.append((pc, None, 1.0))
            continue
        va, vb = compare.view_values(a_run), compare.view_values(b_run)
        sa, sb, _ = per_item_sums(va[pc.metric], vb[pc.metric])
        found.append((pc, got[0], sign_flip_p(sb - sa)))
    ran = [i for i, (_, r, _) in enumerate(found) if r is not None]
    adjusted = dict(zip(ran, holm([found[i][2] for i in ran]), strict=True))
    return [
        PrimaryResult(pc, r, p, adjusted.get(i, 1.0), len(ran))
        for i, (pc, r, p) in enumerate(found)
    ]


PRIMARY_NOTE = (
    "Primary comparisons: what this page exists to compare, declared before its runs "
    '(docs/benchmark.md, "Primary comparisons"). Each pairs the method (B) with the baseline '
    "(A) on the items both scored: B - A with its 95% bootstrap interval (items resampled) "
    "and the two-sided sign-flip p over items (`beo-bench gate`'s test), adjusted by Holm's "
    "step-down over this page's {n} primary comparisons (one family); *better* / *worse* "
    "when the adjusted p is at most {alpha:g}. A dissertation ordering *holds* when its "
    "method is better, *fails* when it is worse; *no difference* does not hold. Every other "
    "verdict on this page is exploratory and uncorrected."
)


def primary_table(results: list[PrimaryResult]) -> str:
    """The page's primary comparisons, Holm-corrected (:data:`PRIMARY_NOTE`); "" when the
    page declares none."""
    if not results:
        return ""
    body: list[list[object]] = []
    for x in results:
        pc, r = x.primary, x.result
        which = [pc.source, pc.track or "-", pc.method, pc.baseline]
        if r is None:
            body.append([*which, spec(pc.metric).label, "-", "-", "-", "-", NOT_RUN, "-"])
            continue
        diff = r.spec.format_interval(r.diff, r.lo, r.hi)
        p = [f"{x.p:.3g}", f"{x.p_holm:.3g}", verdict_cell(x.verdict)]
        body.append([*which, r.spec.label, r.n_items, diff, *p, x.ordering or "-"])
    head = [
        "why",
        "track",
        "method",
        "baseline",
        "metric",
        "items",
        "method - baseline [95%]",
        "p",
        "p (Holm)",
        "verdict (Holm)",
        "the dissertation's ordering",
    ]
    note = PRIMARY_NOTE.format(n=results[0].family, alpha=PRIMARY_ALPHA)
    return f"{note}\n\n" + markdown_table(head, body, "lllllrrrrll")


def _primary_json(x: PrimaryResult) -> dict[str, Any]:
    """A found primary comparison as ``<suite>_paired.json`` holds it (``pairing``
    ``primary``): the paired result, its p, Holm's p, the corrected verdict (the bootstrap
    interval's own is ``uncorrected_verdict``), the declaration and the ordering."""
    assert x.result is not None
    pc = x.primary
    out = compare.paired_json(x.result, "primary", pc.track, pc.method, pc.baseline)
    return {
        **out,
        "verdict": x.verdict,
        "uncorrected_verdict": x.result.verdict,
        "p": x.p,
        "p_holm": x.p_holm,
        "family": x.family,
        "source": pc.source,
        "expected": pc.expected,
        "ordering": x.ordering,
    }


# -- the other tables ----------------------------------------------------------------------------
def degradation_table(base: str, base_rows: list[Any], suite: str, rows: list[Any]) -> str:
    """Each backend on ``base`` (in-distribution) and on ``suite`` (its ``-ood`` twin),
    metric by metric: ``in -> out``."""
    base_s = [r.summary if isinstance(r, Row) else r for r in base_rows]
    ood = _as_rows(rows)
    by_label = {label(s): s for s in base_s}
    both = [r for r in ood if label(r.summary) in by_label]
    cols = [spec(k) for k in DEGRADATION_KEYS]
    body = [
        [_name(r)]
        + [" -> ".join(_value(x, m) for x in (by_label[label(r.summary)], r.summary)) for m in cols]
        for r in both
    ]
    return f"In distribution (`{base}`) -> out of distribution (`{suite}`):\n\n" + (
        markdown_table(["backend", *(m.label for m in cols)], body)
    )


def gap_table(rows: list[dict[str, Any]]) -> str:
    """Where each backend's pick failures come from (``swap`` runs): its success rate, then
    with the true class, pose or shape swapped in (one at a time), against the oracle.
    Empty without swap runs."""
    key = "pick_success"
    swaps: dict[str, dict[str, float]] = {}
    for s in rows:
        kw = _kwargs(s)
        if s["backend"] == "swap" and key in s["metrics"]:
            base = str(kw.get("base", "icp"))
            swaps.setdefault(base, {})[str(kw.get("truth", "class"))] = s["metrics"][key]
    if not swaps:
        return ""
    plain = {label(s): s["metrics"].get(key) for s in rows}
    oracle = plain.get("oracle")
    parts = ("class", "pose", "shape")
    fmt = replace(spec(key), fmt="{:.0f}%")  # whole percent: the table is read for its gaps
    body = [
        [
            base,
            fmt.format(plain.get(base)),
            *(fmt.format(got.get(p)) for p in parts),
            fmt.format(plain.get("oracle (mesh=false)")),
            fmt.format(oracle),
        ]
        for base, got in sorted(swaps.items())
    ]
    head = [
        "backend",
        "pick success",
        "true class",
        "true pose (and size)",
        "true shape",
        "oracle (voxels)",
        "oracle",
    ]
    return (
        "Where the gap to the oracle comes from (`swap`: the backend's estimate with one "
        "component replaced by the truth; shape swaps plan on the true voxels):\n\n"
        + markdown_table(head, body)
    )


# -- pick: its episodes, method against method, counts per category ----------------------------
PICK_REFERENCE = "hbeo"
"""The row every other method of a pick page is paired against, episode by episode (issue
47: the page says whether hbeo, the MDN and icp differ at picking)."""
ROBUST_PAIRS: tuple[tuple[str, str], ...] = tuple(
    (m, f"{m} ({ROBUST})") for m in ("hbeo-mdn-likelihood", "hbeo-mdn-posterior")
)
"""Each MDN row and its twin planning over its pose samples (the same estimates)."""
PICK_MODE_PAIRS: tuple[tuple[str, str], ...] = (
    ("hbeo-mdn-likelihood", "hbeo-mdn-posterior"),
    *ROBUST_PAIRS,
)
"""Further (A, B) pairs of a pick page: the MDN's two modes against each other."""
PICK_METRIC = "pick_success"
EPISODE_AUDIT: tuple[str, ...] = (*AUDIT_FIELDS, "plan_ms", "grasp_share")
"""What an episode records of its executed grasp (:data:`~beo_bench.bench.kinds.pick.
AUDIT_FIELDS`: the shake, the contacts, the analytic force-closure check) and of planning
it (milliseconds; the robust planner's share of pose samples the grasp holds in)."""
EPISODE_FIELDS: tuple[str, ...] = (
    "item", "category", "success", "reason", "chosen_is_target", *PICK_ERRORS, *EPISODE_AUDIT,
)  # fmt: skip
"""A pick run's per-episode record in its page's JSON: one short list per episode, in this
order (the summary's ``episode_fields`` names them, ``episodes`` holds the lists), so that
any two rows pair on the same episodes from the committed JSON alone, and anyone can draw
success against the grasped estimate's errors (:data:`~beo_bench.bench.scoring.
PICK_ERRORS`, to 3 decimals; null where the episode chose nothing or its run predates
them)."""
PICK_METHOD_NOTE = (
    "Method against method (exploratory: every method against hbeo and the MDN's two modes "
    "against each other, on pick success over the same episodes, B - A; 95% bootstrap "
    "intervals that resample episodes; *better* / *worse* when the interval excludes 0, "
    "uncorrected for the page's many comparisons; `B only` / `A only`: the episodes only one "
    "of the two picked, whose split gives p, the exact McNemar test; bounds and privileged "
    "rows are never paired):"
)


def is_pick_suite(suite: str) -> bool:
    """Whether ``suite`` is a pick suite (``pick``, also on a user's dataset)."""
    from beo_bench.bench.suites import Kind, UnknownSuiteError, base_suite

    try:
        return base_suite(suite).kind is Kind.PICK
    except UnknownSuiteError:
        return False


def episode_records(rows: Iterable[dict[str, Any]]) -> list[list[Any]]:
    """A pick run's result rows as its per-episode records (:data:`EPISODE_FIELDS`), by
    item: what pairs it with another run of the same items after the fact."""
    out = []
    for r in sorted(rows, key=lambda r: int(r["item"])):
        if int(r.get("view", 0)) != 0:
            continue  # an episode is one row; a later view would be another record
        found = r.get("chosen_is_target")
        out.append(
            [
                int(r["item"]),
                r.get("category"),
                bool(r.get("success")),  # a failed episode did not pick (as the summary)
                r.get("reason"),
                None if found is None else bool(found),  # None: nothing was chosen
                *(None if r.get(k) is None else round(float(r[k]), 3) for k in PICK_ERRORS),
                *(_record(r.get(k)) for k in EPISODE_AUDIT),
            ]
        )
    return out


def _record(value: Any) -> Any:
    """A recorded value as the page's JSON keeps it: bools as bools, numbers to 3 decimals."""
    if value is None or isinstance(value, bool):
        return value
    return round(float(value), 3)


def attach_episodes(rows: list[Row]) -> None:
    """Give each pick row's summary its per-episode records (``episode_fields``,
    ``episodes``: :func:`episode_records` of its ``results.jsonl``), which the page's JSON
    then holds. A row without its run (a kept page's) keeps what it has."""
    loaded: dict[Path, compare.Run | None] = {}
    for r in rows:
        run = _run(r, loaded) if r.path is not None else None
        if run is not None:
            r.summary["episode_fields"] = list(EPISODE_FIELDS)
            r.summary["episodes"] = episode_records(run.rows)


def episodes(summary: dict[str, Any]) -> dict[int, dict[str, Any]]:
    """A pick row's per-episode records by item, each as a dict of its fields; ``{}`` for a
    row without them."""
    fields = summary.get("episode_fields", EPISODE_FIELDS)
    records = (dict(zip(fields, rec, strict=True)) for rec in summary.get("episodes", []))
    return {int(d["item"]): d for d in records}


def mcnemar_p(b_only: int, a_only: int) -> float:
    """The exact two-sided McNemar p-value of two methods' successes on the same episodes:
    under no difference each of the ``b_only + a_only`` discordant episodes goes either way
    with probability 1/2 (a sign test; the episodes both or neither picked say nothing).
    1 without discordant episodes."""
    n = b_only + a_only
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, i) for i in range(min(b_only, a_only) + 1))
    return min(1.0, 2 * tail / 2**n)  # exact integers: no underflow at n in the hundreds


@dataclass(frozen=True)
class MethodComparison:
    """Method B against method A on a pick page: B - A on :data:`PICK_METRIC` over the
    episodes both ran (one entry of the page's primary comparisons)."""

    suite: str
    track: str | None
    a: str
    """The reference's row name (``hbeo``, ``hbeo-mdn-likelihood``)."""
    b: str
    metric: str
    a_value: float
    b_value: float
    diff: float
    """``b_value - a_value``."""
    ci95: tuple[float, float]
    """The paired bootstrap interval of ``diff`` (episodes resampled,
    :func:`beo_bench.bench.compare.paired_metric`)."""
    p_value: float
    """:func:`mcnemar_p` of the discordant episodes (what a Holm correction takes)."""
    verdict: str
    """For B: ``better`` / ``worse`` when ``ci95`` excludes 0, else ``no difference``."""
    episodes: int
    b_only: int
    """Episodes B picked and A did not."""
    a_only: int
    sensor: str | None = None
    """The runs' sensor when it is not the suite's own."""


def compare_picks(
    section: Section, a: dict[str, Any], b: dict[str, Any], sensor: str | None = None
) -> MethodComparison | None:
    """B - A on the episodes both rows' records hold (None when they share none)."""
    ea, eb = episodes(a), episodes(b)
    common = sorted(ea.keys() & eb.keys())
    if not common:
        return None
    va = {(i, 0): float(bool(ea[i]["success"])) for i in common}
    vb = {(i, 0): float(bool(eb[i]["success"])) for i in common}
    r = compare.paired_metric(va, vb, PICK_METRIC)
    assert r is not None  # every common episode has a value
    b_only = sum(vb[k] > va[k] for k in va)
    a_only = sum(va[k] > vb[k] for k in va)
    return MethodComparison(
        section.suite,
        section.track,
        label(a),
        label(b),
        PICK_METRIC,
        r.a,
        r.b,
        r.diff,
        (r.lo, r.hi),
        mcnemar_p(b_only, a_only),
        r.verdict,
        len(common),
        b_only,
        a_only,
        sensor,
    )


def pick_comparisons(section: Section, sensor: str | None = None) -> list[MethodComparison]:
    """A pick section's method comparisons, as data: every method against
    :data:`PICK_REFERENCE`, then the pairs of :data:`PICK_MODE_PAIRS`, each on the episodes
    both rows' records hold (:func:`attach_episodes`). Bounds, privileged and diagnostic
    rows are never paired; a pair whose rows are not both there, or share no episode's
    record, is left out."""
    rows = {
        label(r.summary): r.summary
        for r in section.rows
        if not is_bound(r.summary) and r.summary["backend"] not in DIAGNOSTIC
    }
    pairs = [(PICK_REFERENCE, m) for m in rows if m != PICK_REFERENCE and PICK_REFERENCE in rows]
    pairs += [(a, b) for a, b in PICK_MODE_PAIRS if a in rows and b in rows]
    found = (compare_picks(section, rows[a], rows[b], sensor) for a, b in pairs)
    return [c for c in found if c is not None]


def _p_text(p: float) -> str:
    return "<0.001" if p < 0.001 else f"{p:.3f}"


def pick_comparison_table(comparisons: list[MethodComparison]) -> str:
    """The Markdown table of a pick section's method comparisons; "" without any."""
    if not comparisons:
        return ""
    m = spec(PICK_METRIC)
    body = [
        [c.b, c.a, c.episodes, m.format(c.a_value), m.format(c.b_value),
         m.format_interval(c.diff, *c.ci95), c.b_only, c.a_only, _p_text(c.p_value),
         verdict_cell(c.verdict)]
        for c in comparisons
    ]  # fmt: skip
    head = ["method (B)", "against (A)", "episodes", "A", "B", "B - A [95%]", "B only",
            "A only", "p", f"verdict, {UNCORRECTED}"]  # fmt: skip
    return f"{PICK_METHOD_NOTE}\n\n" + markdown_table(head, body, "llrrrrrrrl")


def pick_comparison_json(c: MethodComparison) -> dict[str, Any]:
    """One method comparison as ``<suite>_paired.json`` holds it (``"pairing": "method"``,
    the keys of the other pairings plus the p-value and the discordant counts)."""
    out = {
        "pairing": "method",
        "track": c.track,
        "method": c.b,
        "baseline": c.a,
        "metric": c.metric,
        "baseline_value": c.a_value,
        "method_value": c.b_value,
        "diff": c.diff,
        "ci95": list(c.ci95),
        "verdict": c.verdict,
        "items": c.episodes,
        "views": c.episodes,
        "p_value": c.p_value,
        "test": "exact McNemar",
        "method_only": c.b_only,
        "baseline_only": c.a_only,
    }
    if c.sensor is not None:  # as the verdicts of a sensor's part
        out["sensor"] = c.sensor
    return out


def pick_category_table(rows: list[Row]) -> str:
    """Pick success per category with its counts (successes / episodes, then the rate):
    categories as rows, backends as columns; "" without per-category figures."""
    summaries = [r.summary for r in _ordered(rows)]
    if not any(s.get("per_category") for s in summaries):
        return ""

    def cell(d: dict[str, Any]) -> str:
        rate, n = d.get(PICK_METRIC), int(d.get("n", 0))
        if rate is None or not n:
            return "-"
        k = round(rate * n)  # a mean over n episodes of 0 or 1: exactly k / n
        return f"{k}/{n} ({100 * k / n:.0f}%)"

    title = "pick success per category (successes / episodes):"
    return _category_table(summaries, title, cell, counts=False)


_EPISODES_MARK = "\x00episodes of row {}"


def page_json(shown: list[dict[str, Any]]) -> str:
    """A page's JSON (its rows' summaries, indented, keys sorted) with each per-episode
    record on one line: 500 episodes a row stay 500 lines, not 3,500."""
    held, records = [], {}
    for i, s in enumerate(shown):
        if "episodes" in s:
            mark = _EPISODES_MARK.format(i)
            records[json.dumps(mark)] = s["episodes"]
            s = {**s, "episodes": mark}
        held.append(s)
    text = json.dumps(held, indent=2, sort_keys=True)
    for mark, recs in records.items():  # a row's keys sit 4 deep, their list items 6
        lines = ",\n".join(" " * 6 + json.dumps(rec) for rec in recs)
        text = text.replace(mark, "[\n" + lines + "\n" + " " * 4 + "]" if recs else "[]", 1)
    return text + "\n"


# -- sensors -------------------------------------------------------------------------------------
SENSOR_NOTE = (
    "The same items as the suite's own sections, the depth captured by the `{sensor}` sensor "
    "(docs/sensors.md) instead of the suite's own `{own}`."
)


def _order_of(sensor: str) -> tuple[int, str]:
    """Sensors in the order of ``SENSORS`` (ideal, kinect-v1, d435), others after them."""
    from beo_bench.scenes.sensors import SENSORS

    return (SENSORS.index(sensor) if sensor in SENSORS else len(SENSORS), sensor)


def _sensor_key(tag: str | None) -> tuple[int, str]:
    """Sensor parts: the suite's own (None) first, then the others in ``SENSORS`` order."""
    return (-1, "") if tag is None else _order_of(tag)


def sensor_rows(rows: list[Row]) -> dict[str | None, list[Row]]:
    """The rows by the sensor they were captured by: None for the suite's own
    (:func:`~beo_bench.bench.rundir.sensor_tag_of`), then each other sensor, in the order
    of ``SENSORS``."""
    groups: dict[str | None, list[Row]] = {}
    for r in rows:
        groups.setdefault(rundir.sensor_tag_of(r.summary), []).append(r)
    return {k: groups[k] for k in sorted(groups, key=_sensor_key)}


@dataclass(frozen=True)
class SensorPair:
    """One backend's run under ``sensor`` against its run under ``baseline_sensor`` (the
    first sensor with a run of it, in the order of ``SENSORS``), on one metric."""

    track: str | None
    backend: str
    sensor: str
    baseline_sensor: str
    result: compare.PairedResult


def _sensor_json(p: SensorPair) -> dict[str, Any]:
    out = compare.paired_json(p.result, "sensor", p.track, p.backend, p.backend)
    return {**out, "sensor": p.sensor, "baseline_sensor": p.baseline_sensor}


ROBUSTNESS_NOTE = (
    "Each backend under each depth sensor (docs/sensors.md) it was run with, from each "
    "sensor's first section: item i is the same scene under every sensor, so the runs pair "
    "item by item."
)


@dataclass(frozen=True)
class Robustness:
    """A suite's robustness table: per track (None on a suite without tracks) its tables,
    and the pairings behind them."""

    tracks: list[tuple[str | None, str]]
    pairs: list[SensorPair]

    def markdown(self, level: str = "###") -> str:
        """The tables, each track's under a heading of ``level``; "" without tables."""
        if not self.tracks:
            return ""
        parts = [f"{level} {t} track\n\n{text}" if t else text for t, text in self.tracks]
        return "\n\n".join([ROBUSTNESS_NOTE, *parts])


def robustness(suite: str, parts: dict[str | None, dict[str | None, list[Section]]]) -> Robustness:
    """The robustness table of a suite with runs under more than one sensor, and its
    pairings (empty otherwise). Per track, from each sensor's first section: per
    backend, the headline metrics (:data:`ROBUSTNESS_KEYS`) under each sensor, ``ideal ->
    kinect-v1 -> d435``; then each sensor's run paired with the backend's run under the
    first of them (B - A over the items both scored, a bootstrap interval that resamples
    items, a verdict: :func:`beo_bench.bench.compare.paired_runs`)."""
    from beo_bench.bench.rundir import default_sensor_of

    own = default_sensor_of(suite)
    names = {tag: own if tag is None else tag for tag in parts}
    if len(set(names.values())) < 2:
        return Robustness([], [])
    order = sorted(parts, key=lambda t: _order_of(names[t]))  # ideal -> kinect-v1 -> d435
    tracks = sorted({t for p in parts.values() for t in p}, key=_track_key)
    blocks: list[tuple[str | None, str]] = []
    pairs: list[SensorPair] = []
    loaded: dict[Path, compare.Run | None] = {}
    for track in tracks:
        # each sensor's first section of the track: its own runs (not borrowed ones)
        firsts = {names[t]: parts[t][track][0] for t in order if parts[t].get(track)}
        if len(firsts) < 2:
            continue
        sensors = list(firsts)
        runs: dict[str, dict[str, Row]] = {}
        for sensor, sec in firsts.items():
            for r in sec.rows:
                if not r.borrowed and r.summary["backend"] not in DIAGNOSTIC:
                    runs.setdefault(label(r.summary), {})[sensor] = r
        ordered = sorted(runs, key=lambda b: _order_key(runs[b]))
        backends = [b for b in ordered if len(runs[b]) > 1]  # under two sensors at least
        if not backends:
            continue
        keys = [
            k
            for k in ROBUSTNESS_KEYS
            if any(k in r.summary["metrics"] for b in backends for r in runs[b].values())
        ]
        head = " -> ".join(f"`{x}`" for x in sensors)
        body: list[list[str]] = []
        track_pairs: list[SensorPair] = []
        shorter = False
        for b in backends:
            got = runs[b]
            ref = next(x for x in sensors if x in got)
            mine: list[SensorPair] = []
            for x in sensors:
                if x == ref or x not in got:
                    continue
                mine += _sensor_pairs(track, b, ref, got[ref], x, got[x], keys, loaded)
            # a sensor run over fewer items (pick's 200 of 500): every cell on the items all
            # of this backend's runs scored, as the paired rows below compare them
            common = _common_values(got[ref], mine)
            shorter |= bool(common)
            cells = [
                " -> ".join(
                    (
                        spec(k).format(common[(x, k)])
                        if (x, k) in common
                        else _value(got[x].summary, spec(k))
                    )
                    if x in got
                    else "-"
                    for x in sensors
                )
                for k in keys
            ]
            first = next(r for r in got.values())
            body.append([_name(first), *cells])
            track_pairs += mine
        lines = [markdown_table(["backend", *(f"{spec(k).label}: {head}" for k in keys)], body)]
        if shorter:
            lines += ["", SHORTER_NOTE]
        pairs += track_pairs
        table = sensor_verdict_table(track_pairs)
        blocks.append((track, "\n".join(lines) + ("\n\n" + table if table else "")))
    return Robustness(blocks, pairs)


SHORTER_NOTE = (
    "Where a sensor's runs cover fewer items than the first sensor's, a backend's figures "
    "under every sensor are over the items all of its runs scored, the paired rows' items."
)


def _common_values(ref: Row, pairs: list[SensorPair]) -> dict[tuple[str, str], float]:
    """(sensor, metric) -> the value over the items common to the pairs, when some sensor's
    run covers fewer items than the reference run and every pair has the same items; empty
    when each covers the reference's items (the summaries' figures are these)."""
    if not pairs:
        return {}
    n_items = {p.result.n_items for p in pairs}
    if len(n_items) != 1 or n_items == {items(ref.summary)}:
        return {}
    out = {(p.sensor, p.result.key): p.result.b for p in pairs}
    out.update({(p.baseline_sensor, p.result.key): p.result.a for p in pairs})
    return out


def _order_key(runs: dict[str, Row]) -> tuple[bool, str]:
    r = next(iter(runs.values()))
    return (is_bound(r.summary), label(r.summary))


def _sensor_pairs(
    track: str | None,
    backend: str,
    ref: str,
    a: Row,
    sensor: str,
    b: Row,
    keys: list[str],
    loaded: dict[Path, compare.Run | None],
) -> list[SensorPair]:
    """``b`` (under ``sensor``) against ``a`` (under ``ref``) on ``keys``, over the items
    both scored; none when either run's results are not at hand or they are not the same
    items (another seed)."""
    if a.path is None or b.path is None:
        return []
    a_run, b_run = _run(a, loaded), _run(b, loaded)
    if a_run is None or b_run is None or not a_run.items & b_run.items:
        return []
    both = {m.key for m in compare.pairable(a_run.summary, b_run.summary)}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", compare.ComparisonWarning)  # a shorter run: its items
            wanted = [k for k in keys if k in both]
            results = compare.paired_runs(a_run, b_run, wanted, across_sensors=True)
    except UsageError:  # another seed or version: not the same items
        return []
    return [SensorPair(track, backend, sensor, ref, r) for r in results]


def sensor_verdict_table(pairs: list[SensorPair]) -> str:
    """The paired verdicts of the robustness table: a row per (backend, sensor), per metric
    sensor - baseline sensor with its 95% interval and the verdict; "" without pairs."""
    if not pairs:
        return ""
    keys = [k for k in ROBUSTNESS_KEYS if any(p.result.key == k for p in pairs)]
    rows: dict[tuple[str, str, str], dict[str, compare.PairedResult]] = {}
    for p in pairs:
        rows.setdefault((p.backend, p.sensor, p.baseline_sensor), {})[p.result.key] = p.result
    body = [
        [backend, f"`{sensor}`", f"`{base}`", *_verdict_cells(res, keys)]
        for (backend, sensor, base), res in rows.items()
    ]
    head = ["backend", "sensor", "baseline", *_verdict_head("sensor - baseline", keys)]
    return (
        "Paired (exploratory: each sensor's run against the same backend's under the first "
        "sensor, on the items both scored; 95% bootstrap intervals that resample items; "
        f"*better* / *worse* when the interval excludes 0, {UNCORRECTED_NOTE}):\n\n"
        + markdown_table(head, body, "lllr" + "rl" * len(keys))
    )


# -- the pages -----------------------------------------------------------------------------------
def _newest(rows: list[Row]) -> tuple[int, list[Row], dict[int, int]]:
    """The newest suite version, its runs, and how many runs each older version has."""
    newest = max(int(r.summary["suite_version"]) for r in rows)
    older: dict[int, int] = {}
    for r in rows:
        v = int(r.summary["suite_version"])
        if v != newest:
            older[v] = older.get(v, 0) + 1
    return newest, [r for r in rows if r.summary["suite_version"] == newest], older


def _prefix(suite: str, track: str | None, sensor: str | None = None) -> str:
    where = f"{suite}_{sensor}" if sensor else suite
    return f"{where}_{track}" if track else where


def _heading(suite: str, track: str | None, sensor: str | None = None) -> str:
    where = f"{suite}, {track} track" if track else suite
    return f"{where}, sensor {sensor}" if sensor else where


def _partial_note(suite: str, tracks: dict[str | None, list[Section]]) -> str:
    """The line under a suite's title (its page's and the README's) when the sections shown
    first (the README's) cover fewer items than the suite's size, else ``""``."""
    parts = {t: secs[0].partial for t, secs in tracks.items() if secs and secs[0].partial}
    if not parts:
        return ""
    if len(set(parts.values())) == 1 and len(parts) == len(tracks):
        covered = next(iter(parts.values()))
    else:
        covered = "; ".join(f"{_heading(suite, t)}: {p}" for t, p in parts.items())
    return f"**Partial**: the runs shown first cover {covered}."


@dataclass
class _Page:
    """What a suite's page collects while it is built."""

    md: list[str]
    index: list[str]
    plots: list[str]
    verdicts: list[Verdict]
    shown: dict[int, dict[str, Any]]
    sensor_ablations: list[tuple[str, ablations.AblationResult]] = field(default_factory=list)
    """The ablations of the parts of sensors other than the suite's own (with the sensor)."""
    robustness: list[SensorPair] = field(default_factory=list)
    ablations: list[ablations.AblationResult] = field(default_factory=list)
    comparisons: list[MethodComparison] = field(default_factory=list)
    """A pick page's method comparisons (:func:`pick_comparisons`), every sensor's part."""


def _track_part(
    page: _Page,
    out: Path,
    suite: str,
    track: str | None,
    secs: list[Section],
    firsts: dict[tuple[str, str | None, str | None], Section],
    sensor: str | None = None,
) -> None:
    """A track's part of the suite page: its sections, the first with the extra tables.
    ``sensor``: the part of a sensor other than the suite's own (its headings one level
    down, under the sensor's)."""
    top = "###" if sensor else "##"
    level = top + "#" if track else top
    if track:
        page.md += [f"{top} {track} track", "", TRACK_NOTES.get(track, ""), ""]
    for i, sec in enumerate(secs):
        table = suite_table(sec.rows)
        page.md += [f"{level} {sec.title}", "", table, ""]
        for r in sec.rows:
            page.shown.setdefault(id(r.summary), r.summary)
        if i:
            continue
        verdicts = paired_verdicts(sec, sensor)
        page.verdicts += verdicts
        vt = verdict_table(verdicts)
        # ablations pair runs across this seed's sections (a variant may cover a prefix)
        same_seed = [r for s in secs if s.seed == sec.seed for r in s.rows]
        abl = ablations.ablation_results(
            track, same_seed, label, by_category=suite in PER_CATEGORY_SUITES
        )
        if sensor is None:
            page.ablations += abl
        else:
            page.sensor_ablations += [(sensor, a) for a in abl]
        at = ablations.ablation_table(abl)
        # the learned rows' training-seed spread (issue 47), under the suite's own sensor
        st = ablations.seed_table(ablations.seed_spreads(sec.rows, label)) if not sensor else ""
        picks = pick_comparisons(sec, sensor) if is_pick_suite(suite) else []
        page.comparisons += picks
        # the suite's own sensor shows these pairs once, as the page's primary comparisons
        # (Holm-corrected); under another sensor they are exploratory
        mt = pick_comparison_table(picks) if sensor is not None else ""
        vt = "\n\n".join(t for t in (vt, at, st, mt) if t)
        if sensor is None:  # the index shows the suite's own sensor (and the robustness)
            page.index += [f"### {_heading(suite, track)}: {sec.title}", "", table, ""]
            page.index += [vt, ""] if vt else []
        summaries = [r.summary for r in sec.rows]
        gap = gap_table(summaries)
        base = suite.removesuffix(OOD_SUFFIX)
        twin = firsts.get((base, track, sensor)) if base != suite else None
        extra = [vt, gap] + ([degradation_table(base, twin.rows, suite, sec.rows)] if twin else [])
        page.md += [t + "\n" for t in extra if t]
        page.md += [_per_category(suite, sec.rows), ""]  # there, empty or not
        for _, draw in SECTION_TABLES:
            extra_table = draw(suite, sec.rows)
            page.md += [extra_table, ""] if extra_table else []
        plots = _plots(out, _prefix(suite, track, sensor), _heading(suite, track, sensor), sec.rows)
        page.plots += plots
        page.md += [*[f"![{p}]({p})" for p in plots], ""]


def _per_category(suite: str, rows: list[Row]) -> str:
    """A section's per-category table (a pick suite's counts episodes)."""
    return pick_category_table(rows) if is_pick_suite(suite) else category_table(suite, rows)


SectionTable = Callable[[str, list[Row]], str]
"""A table a track's first section shows after its per-category table, drawn from the suite
and the section's rows; ``""`` where it does not apply (the table is then left out)."""
SECTION_TABLES: tuple[tuple[str, SectionTable], ...] = (
    ("Tables 5.1/5.2", lambda suite, rows: table_5_1(rows) if suite in TABLE_5_1_SUITES else ""),
    ("the field's figures", lambda _, rows: field_table(rows)),
    ("NOCS per class", lambda _, rows: nocs_class_tables(rows)),
    ("Tables 3.1/4.1", modelnet10_table),
    ("confusions", lambda _, rows: confused_pairs_table(rows)),
    ("confusion matrices", confusion_counts),
)
"""The first section's further tables, in page order: a table added here is on every page
it applies to."""


MARKER_NAME = ".beo-bench-leaderboards"
LOCK_NAME = ".beo-bench-leaderboards.lock"
"""What a regeneration holds (an exclusive ``flock``, its PID in it) while it writes."""
MARKER_TEXT = (
    "This directory is a leaderboard directory of beo-bench (`beo-bench leaderboard`, "
    "`beo-bench all`).\n"
    "Regenerating rewrites its files only while this file marks the directory as its own.\n"
)
"""The file marking a directory :func:`regenerate` made. Without it a non-empty directory is
refused, even one holding only names a leaderboard writes (``README.md``, ``<suite>.md``):
those could be the user's own, and regenerating replaces and removes files."""


def check_out(out: Path | str) -> None:
    """A :class:`~beo_bench.errors.UsageError` unless ``out`` may take a leaderboard: it
    does not exist, is empty or carries :data:`MARKER_NAME` (``beo-bench all`` asks before
    its runs, so a refusal costs no hours of scoring)."""
    from beo_bench import outdir

    out = Path(out)
    if not out.is_dir():
        return  # created by regenerate (or a file there: mkdir says so)
    try:
        held = outdir.foreign_files(out, MARKER_NAME)
    except OSError as e:
        raise UsageError(f"--out {out} cannot be read ({e}): choose another --out") from e
    if held:
        raise UsageError(
            f"--out {out} is a non-empty directory that beo-bench did not create (it holds "
            f"{outdir.shown(held)} and no {MARKER_NAME}): give --out a new or empty "
            "directory; nothing in this one is touched"
        )


def _mark_out(out: Path) -> None:
    from beo_bench import outdir

    if not (out / MARKER_NAME).is_file():
        outdir.mark(out, MARKER_NAME, MARKER_TEXT)


@dataclass
class _Kept:
    """A suite page ``regenerate(update=True)`` keeps as it is: its files and its part of
    the index, as the last regeneration wrote them."""

    files: set[str]
    index: list[str]


_INDEX_HEAD = "## ["


def _index_parts(readme: Path) -> dict[str, list[str]]:
    """The index's part of each suite (from its ``## [suite](suite.md)`` heading to the
    next), by suite name; empty when there is no index."""
    if not readme.is_file():
        return {}
    parts: dict[str, list[str]] = {}
    current: list[str] | None = None
    for line in readme.read_text().splitlines():
        if line.startswith(_INDEX_HEAD) and "](" in line:
            current = parts.setdefault(line[len(_INDEX_HEAD) : line.index("](")], [])
        elif line.startswith("## "):  # another part of the index (the suites not yet run)
            current = None
        if current is not None:
            current.append(line)
    return parts


def _kept_pages(out: Path, fresh: set[str]) -> dict[str, tuple[_Kept, list[Row]]]:
    """The pages in ``out`` of registered suites that have no runs now (``fresh`` are those
    that do) and whose every row is of the suite's current version, with their rows. A page
    of an older version is not kept: it goes, as its runs are no longer comparable."""
    from beo_bench.bench.suites import UnknownSuiteError, get_suite

    parts = _index_parts(out / "README.md")
    kept = {}
    for path in sorted(out.glob("*.json")):
        suite = path.stem
        if suite.endswith("_paired") or suite in fresh or suite not in parts:
            continue
        try:
            version = get_suite(suite).version
        except UnknownSuiteError:
            continue
        rows = [Row(s) for s in json.loads(path.read_text())]
        if not rows or any(int(r.summary["suite_version"]) != version for r in rows):
            continue
        md = out / f"{suite}.md"
        text = md.read_text() if md.is_file() else ""
        plots = {ln[ln.index("](") + 2 : -1] for ln in text.splitlines() if ln.startswith("![")}
        files = {md.name, path.name, f"{suite}_paired.json", *plots}
        kept[suite] = (_Kept(files, parts[suite]), rows)
    return kept


ABLATION_NOTE = (
    "An ablation page (`beo-bench leaderboard --ablation`): the rows of one study, variants "
    "of a backend and the baseline they pair with, on {suite}'s items, made from those runs "
    "alone. The suite's own page (`leaderboards/{suite}.md`) holds every row, its primary "
    "comparisons and its sensors; the verdicts here are exploratory and uncorrected."
)
"""What an ablation page says first (:func:`regenerate`'s ``ablation``)."""


def regenerate(
    runs: Path | str = "runs",
    out: Path | str = "leaderboards",
    update: bool = False,
    ablation: bool = False,
) -> list[Path]:
    """Rewrite ``out`` from the summaries under ``runs``; returns the suites' Markdown files.
    Its own files (named after a suite) that no run produces any more are removed. ``out``
    must be new, empty or marked as a leaderboard directory (:func:`check_out`).

    ``update`` (``--update``): a suite with no runs under ``runs`` keeps its page, files and
    index part as they are in ``out``, if every row there is of the suite's current
    version, so that a campaign too long for one machine's session can be run suite by
    suite. Each page is still made from one regeneration's runs: its rows, paired verdicts
    and plots always come from the same runs.

    ``ablation`` (``--ablation``): the runs are one study's variant rows and their baseline,
    not a suite's every row (``leaderboards/ablations/``): its pages carry no primary
    comparisons (a family of a page's few rows would be corrected over the wrong family)
    and say where the suite's full page is."""
    from beo_bench import outdir

    out = Path(out)
    check_out(out)
    out.mkdir(parents=True, exist_ok=True)
    _mark_out(out)

    def busy(pid: str) -> Exception:
        return RunError(
            f"--out {out} is being regenerated by another process (PID {pid}, holding "
            f"{out / LOCK_NAME}): wait for it, or give --out another directory"
        )

    with outdir.locked(out / LOCK_NAME, busy):  # one writer per leaderboard directory
        return _regenerate(Path(runs), out, update, ablation)


def _regenerate(runs: Path, out: Path, update: bool, ablation: bool) -> list[Path]:
    by_suite: dict[str, list[Row]] = {}
    for r in load_rows(Path(runs)):
        by_suite.setdefault(r.summary["suite"], []).append(r)
    kept = _kept_pages(out, set(by_suite)) if update else {}
    # every suite's sections first: an -ood suite's page compares with its base's first one
    # (under the same sensor)
    plan: dict[str, tuple[int, dict[int, int], dict[str | None, dict[str | None, list[Section]]]]]
    plan = {}
    firsts: dict[tuple[str, str | None, str | None], Section] = {}
    for suite, (_, kept_rows) in kept.items():
        version, newest, _older = _newest(kept_rows)
        for tag, kept_tracks in _parts(suite, version, newest).items():
            firsts.update({(suite, t, tag): secs[0] for t, secs in kept_tracks.items()})
    for suite, rows in sorted(by_suite.items()):
        version, newest, older = _newest(rows)
        if is_pick_suite(suite):  # the page's JSON holds every pick run's episodes
            attach_episodes(newest)
        parts = _parts(suite, version, newest)
        plan[suite] = (version, older, parts)
        for tag, tracks in parts.items():
            firsts.update({(suite, t, tag): secs[0] for t, secs in tracks.items()})
    keep: set[str] = {"README.md"}
    index_parts: dict[str, list[str]] = {}
    for suite, (k, _) in kept.items():
        keep |= k.files
        index_parts[suite] = k.index + ([""] if k.index and k.index[-1] else [])
    written = []
    index = [
        "# Leaderboards",
        "",
        # RUNS, not the path given: a page names no machine's directories
        "Generated by `beo-bench leaderboard --runs RUNS` (RUNS: the run directories) "
        "from the run summaries (each "
        "suite's JSON holds them, with provenance: git commit, package versions, machine, "
        "seeds). Means over every view, a failed view counted at its worst case, with "
        "bootstrap 95% intervals (items resampled) in brackets. Pose suites have two "
        "tracks: *class-given* (every backend that can use the true class is told it; those "
        "that cannot are listed from their class-free run, marked *(hint not used)*) and "
        "*class-free*. Runs of other seeds or item counts are in separate sections of each "
        "page; *partial* marks fewer items than the suite's size. `model` is the first "
        f"{DIGEST_CHARS} hex digits of the backend's model digest. *Bounds* are not methods: "
        "`oracle` returns the truth, `random` guesses, and a backend marked *privileged* was "
        "handed the truth (listed with the bounds, never ranked or paired). `class acc.` "
        "reads *given* where the "
        "backend was told the class. F-score@1%: tau = 1% of the canonical cube's side. "
        "`BOP AR`: the mean of BOP 2019's average recalls (AR_VSD, AR_MSSD, AR_MSPD), which "
        "each pose section's page lists beside the NOCS report (docs/bop.md); runs made "
        "before these were scored show `-`.",
        "",
    ]
    for suite, (version, older, parts) in plan.items():
        page = _Page([], [], [], [], {})
        tracks = parts.get(None, {})  # the suite's own sensor
        desc = _description([t for p in parts.values() for t in p.values()])
        page.md = [f"# {suite} (suite version {version})", "", desc, ""]
        partial = _partial_note(suite, tracks)
        page.md += [partial, ""] if partial else []
        if ablation:
            page.md += [ABLATION_NOTE.format(suite=suite), ""]
        if older:
            left = ", ".join(f"v{v}: {n} run(s)" for v, n in sorted(older.items()))
            page.md += [f"Runs of older suite versions are left out ({left}): not comparable.", ""]
        # the comparisons the page exists to make, Holm-corrected as one family, apart from
        # the exploratory verdicts of the tracks' sections (issue 47)
        primary = [] if ablation else primary_results(suite, tracks)
        if any(x.result is not None for x in primary):
            page.md += ["## Primary comparisons", "", primary_table(primary), ""]
            page.index += [f"### {suite}: primary comparisons", "", primary_table(primary), ""]
        for track, secs in tracks.items():
            _track_part(page, out, suite, track, secs, firsts)
        robust = robustness(suite, parts)
        page.robustness = robust.pairs
        if robust.tracks:
            page.md += ["## Robustness across sensors", "", robust.markdown("###"), ""]
            page.index += [
                f"### {suite}: robustness across sensors",
                "",
                robust.markdown("####"),
                "",
            ]
        own = rundir.default_sensor_of(suite)
        for tag, sensor_tracks in parts.items():
            if tag is None:
                continue
            page.md += [f"## sensor {tag}", "", SENSOR_NOTE.format(sensor=tag, own=own), ""]
            for track, secs in sensor_tracks.items():
                _track_part(page, out, suite, track, secs, firsts, sensor=tag)
        path = out / f"{suite}.md"
        atomic_write_bytes(path, "\n".join(page.md))
        shown = list(page.shown.values())
        atomic_write_bytes(out / f"{suite}.json", page_json(shown))
        paired_json = [_verdict_json(v) for v in page.verdicts]
        paired_json += [ablations.ablation_json(x) for x in page.ablations]
        paired_json += [
            {**ablations.ablation_json(x), "sensor": t} for t, x in page.sensor_ablations
        ]
        paired_json += [_sensor_json(p) for p in page.robustness]
        paired_json += [_primary_json(x) for x in primary if x.result is not None]
        paired_json += [pick_comparison_json(c) for c in page.comparisons]
        atomic_write_bytes(
            out / f"{suite}_paired.json", json.dumps(paired_json, indent=2, sort_keys=True) + "\n"
        )
        keep |= {path.name, f"{suite}.json", f"{suite}_paired.json", *page.plots}
        written.append(path)
        mark = " *(partial)*" if partial else ""
        part = [f"## [{suite}]({suite}.md){mark}", "", desc, ""]
        index_parts[suite] = [*part, *([partial, ""] if partial else []), *page.index]
    for suite in sorted(index_parts):
        index += index_parts[suite]
    from beo_bench.bench.suites import get_suite, list_suites

    ours = tuple(list_suites())
    pending = [s for s in ours if s not in index_parts]
    if pending and not ablation:
        index += [
            "## Not yet run at their current suite version",
            "",
            ", ".join(f"`{s}` (v{get_suite(s).version})" for s in pending)
            + ": `beo-bench all --update --suites SUITE` makes their pages.",
            "",
        ]
    atomic_write_bytes(out / "README.md", "\n".join(index))
    for stale in out.iterdir():  # our files of suites or backends no longer in the runs
        if stale.is_file() and stale.name.startswith(ours) and stale.name not in keep:
            stale.unlink()
    return written


def _parts(
    suite: str, version: int, rows: list[Row]
) -> dict[str | None, dict[str | None, list[Section]]]:
    """The page's parts: per sensor (None: the suite's own, first), its tracks' sections."""
    return {
        tag: {t: sections(suite, version, t, trs) for t, trs in track_rows(srows).items()}
        for tag, srows in sensor_rows(rows).items()
    }


def _description(all_sections: list[list[Section]]) -> str:
    for secs in all_sections:
        for sec in secs:
            for r in sec.rows:
                d = r.summary.get("provenance", {}).get("suite", {}).get("description")
                if d:
                    return str(d)
    return ""
