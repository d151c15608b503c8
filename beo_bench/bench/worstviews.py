"""``report.html``: a run's worst views, in one offline page (``beo-bench run --report-views N``).

The page is self-contained: its images are PNG data URIs, its style is inline, it has no
script and names no address, so it opens from a CI job's artifacts or a laptop without a
network. It shows the run's failures grouped by exception (:mod:`.failures`), a pick run's
reasons, then the N worst rows by the suite's primary error (the item kind's
``rank_rows``: rotation error for pose suites, the class for the others, failed episodes
for pick). Each shows the view's depth, its mask, and the estimate's silhouette over the
truth's, with the row's errors; a pick episode shows its reason.

Views are rebuilt from their item index (items are deterministic: the same view as the
run scored), and the estimate is predicted again by the run's backend (the one the driver
built, when there is one) for the rows that did not fail: a failed row is never predicted
again (a backend that hung would hang the report), and predicting stops once
:data:`PREDICT_BUDGET_S` seconds would be spent. A silhouette is the shape's occupied
voxels (``>= 0.5``) placed by the pose and the largest extent, as the camera-frame IoU
places them (:func:`beo_bench.metrics.posed_iou`), and projected with the view's
intrinsics.
"""

from __future__ import annotations

import base64
import contextlib
import html
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench.atomic import atomic_write_bytes
from beo_bench.bench.failures import FailureSummary, summarise_failures
from beo_bench.bench.kinds import get_kind
from beo_bench.bench.kinds.common import ReportCase
from beo_bench.bench.rundir import REPORT_NAME, RESULTS_NAME
from beo_bench.bench.runs import REPORT_VIEWS, RunContext, backend_label

if TYPE_CHECKING:
    from beo_bench.backend import Backend
    from beo_bench.bench.evaluate import Evaluator
    from beo_bench.bench.scoring import Answer
    from beo_bench.types import View

DEFAULT_VIEWS = REPORT_VIEWS
"""Rows a report shows unless ``--report-views`` says otherwise."""
PREDICT_BUDGET_S = 4.0
"""The most seconds a report spends predicting again (a row is predicted when its
recorded time still fits); later rows are shown without the estimate, so a slow backend
adds a few seconds to a run, not minutes (``icp`` takes about 0.75 s a view on a loaded
2-core machine: 5 or 6 of 8 views are redrawn)."""
MAX_SIDE = 256
"""A panel's largest side in pixels: a view is cropped around the object, then thinned by a
whole stride (a 640x480 scene's panels would otherwise make the page megabytes)."""
ROTATION_AGREES_DEG = 0.5
"""A re-predicted estimate whose rotation error differs from the row's by more than this is
flagged: the backend did not answer the same way twice."""

# the colours of beo_bench.bench.recording's meshes: the truth green, the estimate red
TRUTH_RGB = np.array([60, 180, 75], dtype=np.uint8)
ESTIMATE_RGB = np.array([230, 25, 75], dtype=np.uint8)
BOTH_RGB = np.array([255, 225, 25], dtype=np.uint8)
_VIRIDIS = np.array(
    [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], dtype=np.float64
)


class ReportWarning(UserWarning):
    """A run's report that could not be written (the run's results stand)."""


@dataclass(frozen=True)
class Report:
    """What :func:`write_report` wrote."""

    path: Path
    views: int
    """Rows shown."""
    predicted: int
    """Of them, the rows whose estimate was predicted again (and drawn)."""
    criterion: str
    seconds: float


# -- images ------------------------------------------------------------------------------------
def silhouette(
    grid: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    size: np.ndarray,
    K: np.ndarray,
    shape: tuple[int, int],
) -> np.ndarray:
    """The (H, W) pixels that a canonical occupancy ``grid`` covers, placed by (R, t) in
    the camera frame with the cube's edge the largest of ``size`` (as ``posed_iou`` places
    it) and projected by ``K``. Each occupied voxel is drawn as a square a little wider than
    its projected side, so neighbours leave no gaps (the outline grows by a quarter voxel);
    voxels behind the camera are dropped."""
    h, w = shape
    out = np.zeros((h, w), dtype=bool)
    edge = float(np.max(size)) if np.size(size) else 0.0
    occ = np.argwhere(np.asarray(grid) >= 0.5)
    if not len(occ) or not math.isfinite(edge) or edge <= 0:
        return out
    D = np.asarray(grid).shape[0]
    cam = (((occ + 0.5) / D - 0.5) * edge) @ np.asarray(R, dtype=np.float64).T + np.asarray(t)
    cam = cam[cam[:, 2] > 1e-3]
    if not len(cam):
        return out
    K = np.asarray(K, dtype=np.float64)
    uv = cam @ K.T
    u, v = uv[:, 0] / uv[:, 2], uv[:, 1] / uv[:, 2]
    # three quarters of the voxel's projected side: diagonal neighbours (a thin wall's
    # voxels touch only at edges) project sqrt(2) sides apart, and leave no gap between them
    r = 0.75 * (edge / D) * max(K[0, 0], K[1, 1]) / cam[:, 2]
    keep = (u + r >= 0) & (u - r < w) & (v + r >= 0) & (v - r < h)
    u, v, r = u[keep], v[keep], np.maximum(r[keep], 0.5)
    reach = int(min(np.ceil(r.max()), 64)) if len(r) else 0
    for dx in range(-reach, reach + 1):
        for dy in range(-reach, reach + 1):
            sel = (abs(dx) <= r) & (abs(dy) <= r)
            x = np.floor(u[sel] + dx + 0.5).astype(np.int64)
            y = np.floor(v[sel] + dy + 0.5).astype(np.int64)
            ok = (x >= 0) & (x < w) & (y >= 0) & (y < h)
            out[y[ok], x[ok]] = True
    return out


def depth_rgb(depth: np.ndarray) -> np.ndarray:
    """Depth as colours (viridis: near dark blue, far yellow; black where there is no
    reading), scaled over the valid readings shown."""
    d = np.asarray(depth, dtype=np.float64)
    valid = np.isfinite(d) & (d > 0)
    out = np.zeros((*d.shape, 3), dtype=np.uint8)
    if not valid.any():
        return out
    lo, hi = np.percentile(d[valid], [1, 99])
    x = np.clip((d[valid] - lo) / max(hi - lo, 1e-9), 0, 1) * (len(_VIRIDIS) - 1)
    stops = np.arange(len(_VIRIDIS))
    for c in range(3):
        out[..., c][valid] = np.round(np.interp(x, stops, _VIRIDIS[:, c])).astype(np.uint8)
    return out


def _grey(depth: np.ndarray) -> np.ndarray:
    """The depth as a dim grey backdrop for the masks and silhouettes."""
    g = depth_rgb(depth).mean(axis=2, keepdims=True) * 0.45
    return np.repeat(g, 3, axis=2).astype(np.uint8)


def mask_rgb(depth: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The view's mask in white over the dim depth."""
    out = _grey(depth)
    out[np.asarray(mask, dtype=bool)] = 255
    return out


def overlay_rgb(depth: np.ndarray, truth: np.ndarray, estimate: np.ndarray | None) -> np.ndarray:
    """The truth's silhouette (green), the estimate's (red) and where both cover (yellow),
    over the dim depth."""
    out = _grey(depth)
    est = np.zeros_like(truth) if estimate is None else estimate
    out[truth & ~est] = TRUTH_RGB
    out[est & ~truth] = ESTIMATE_RGB
    out[truth & est] = BOTH_RGB
    return out


def crop_window(masks: Sequence[np.ndarray], shape: tuple[int, int]) -> tuple[slice, slice]:
    """(rows, columns) of the part of an image a panel shows: a square around ``masks``
    with a margin (an isolated object fills a fifth of its view, a scene's a tenth), thinned
    by the whole stride that brings it to at most :data:`MAX_SIDE` pixels a side; the whole
    image when the masks are empty."""
    h, w = shape
    ys, xs = np.nonzero(np.any(np.stack(masks), axis=0)) if masks else ((), ())
    if len(ys):
        side = max(int(max(ys)) - int(min(ys)), int(max(xs)) - int(min(xs))) + 1
        half = max(int(0.75 * side), 16)  # the object's box and as much again around it
        cy, cx = (int(min(ys)) + int(max(ys))) // 2, (int(min(xs)) + int(max(xs))) // 2
        y0, y1 = max(0, cy - half), min(h, cy + half)
        x0, x1 = max(0, cx - half), min(w, cx + half)
    else:
        y0, y1, x0, x1 = 0, h, 0, w
    stride = max(1, math.ceil(max(y1 - y0, x1 - x0) / MAX_SIDE))
    return slice(y0, y1, stride), slice(x0, x1, stride)


def png(rgb: np.ndarray) -> bytes:
    """``rgb`` (H, W, 3) uint8 as PNG bytes."""
    import cv2

    # level 6: a scene's noisy depth halves against cv2's default (1), in milliseconds
    params = [cv2.IMWRITE_PNG_COMPRESSION, 6]
    ok, data = cv2.imencode(".png", np.ascontiguousarray(rgb[..., ::-1]), params)
    if not ok:  # cv2 reports a failed encode by its flag alone
        raise ValueError(f"could not encode a {rgb.shape} image as PNG")
    return bytes(data)


def data_uri(png_bytes: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png_bytes).decode("ascii")


# -- one row -----------------------------------------------------------------------------------
_ERRORS: tuple[tuple[str, str, str], ...] = (
    # (row field, label, format)
    ("rot_err_deg", "rotation error", "{:.1f} deg"),
    ("trans_err_cm", "translation error", "{:.2f} cm"),
    ("size_err_pct", "size error", "{:.1f}%"),
    ("mssd_cm", "MSSD", "{:.2f} cm"),
    ("mspd_px", "MSPD", "{:.1f} px"),
    ("iou", "voxel IoU", "{:.3f}"),
    ("iou_cam", "camera-frame IoU", "{:.3f}"),
    ("fscore", "F@1%", "{:.3f}"),
    ("chamfer_l1", "Chamfer-L1", "{:.4f}"),
    ("edt_err", "EDT error", "{:.1f}"),
    ("pixels", "mask pixels", "{}"),
    ("ms", "time", "{:.0f} ms"),
)


def row_errors(row: dict[str, Any], categories: Sequence[str]) -> list[tuple[str, str]]:
    """(label, value) of what a row recorded: a pick episode's reason first, or a view's
    class, then its errors, its failure last."""
    out: list[tuple[str, str]] = []

    def name(i: Any) -> str:
        return categories[i] if isinstance(i, int) and 0 <= i < len(categories) else "none"

    if "reason" in row:  # a pick episode
        out.append(("reason", str(row.get("reason"))))
        out.append(("picked", "yes" if row.get("success") else "no"))
        out.append(("asked class", str(row.get("category"))))
        if "chosen_category" in row:
            chosen = str(row["chosen_category"])
            aim = "the target" if row.get("chosen_is_target") else "not the target"
            out.append(("chosen object", f"{chosen} ({aim})"))
        out.append(("objects seen", str(row.get("views"))))
        if row.get("ms_decision") is not None:
            out.append(("decision time", f"{float(row['ms_decision']):.0f} ms"))
        if row.get("force_closure") is not None:  # the grasp audit (pick's AUDIT_FIELDS)
            from beo_bench.grasping import AUDIT_FRICTION

            mu = row.get("fc_mu")
            need = "none" if mu is None else f"mu >= {float(mu):.2f}"
            out.append(("lifted what it aimed at", "yes" if row.get("lifted_chosen") else "no"))
            closure = "yes" if row["force_closure"] else "no"
            out.append((f"force closure at mu {AUDIT_FRICTION:g}", f"{closure} ({need})"))
        if row.get("shake_held") is not None:
            held = "held" if row["shake_held"] else "dropped"
            out.append(("after the shake", f"{held}, slipped {float(row['slip_cm']):.1f} cm"))
    else:
        truth = str(row.get("category"))
        if row.get("class_given"):
            out.append(("class", f"{truth} (given)"))
        else:
            pred = name(row.get("pred_class"))
            prob = row.get("class_prob_true")
            p = f", p(true) = {float(prob):.2f}" if prob is not None else ""
            mark = "right" if row.get("correct") else "wrong"
            out.append(("class", f"{truth} -> {pred} ({mark}{p})"))
        for key, label, fmt in _ERRORS:
            if row.get(key) is not None:
                out.append((label, fmt.format(row[key])))
    if row.get("failure"):
        out.append(("failure", str(row["failure"])))
    return out


@dataclass(frozen=True)
class Card:
    """One row as the page shows it."""

    title: str
    panels: tuple[tuple[str, bytes], ...]
    """(caption, PNG)."""
    errors: tuple[tuple[str, str], ...]
    notes: tuple[str, ...]
    failed: bool


def _agreement(case: ReportCase) -> str:
    """A note when the estimate predicted again is not the one the row scored."""
    est, row = case.estimate, case.row
    if est is None or "pred_class" not in row:
        return ""
    if int(est.class_index) != int(row["pred_class"]):
        return "predicted again, the backend chose another class than in the run"
    if row.get("rot_err_deg") is not None:
        from beo_bench.metrics import rotation_error

        now = rotation_error(est.rotation, case.truth.R_cam, case.truth.symmetry)
        if abs(now - float(row["rot_err_deg"])) > ROTATION_AGREES_DEG:
            return (
                f"predicted again, the rotation error is {now:.1f} deg (the run scored "
                f"{float(row['rot_err_deg']):.1f}): the backend does not answer the same twice"
            )
    return ""


def card(case: ReportCase, ctx: RunContext, predicted: bool) -> Card:
    """The panels, errors and notes of one case."""
    from beo_bench.bench.scoring import truth_shape

    view, gt, est = case.view, case.truth, case.estimate
    shape = view.depth.shape
    true_voxels = truth_shape(gt.key, ctx.suite.resolution, ctx.dataset, ctx.cache_root).voxels
    truth = silhouette(true_voxels, gt.R_cam, gt.t_cam, gt.size, view.K, shape)
    mine = (
        silhouette(est.shape, est.rotation, est.translation, est.size, view.K, shape)
        if est is not None
        else None
    )
    mask = np.asarray(view.mask, dtype=bool)
    rows, cols = crop_window([mask, truth, *([mine] if mine is not None else [])], shape)
    depth = np.asarray(view.depth)[rows, cols]
    panels = (
        ("depth", png(depth_rgb(depth))),
        ("mask", png(mask_rgb(depth, mask[rows, cols]))),
        (
            "voxel silhouettes: truth green, estimate red, both yellow",
            png(overlay_rgb(depth, truth[rows, cols], None if mine is None else mine[rows, cols])),
        ),
    )
    row = case.row
    notes = [n for n in (case.note, _agreement(case)) if n]
    if row.get("failure"):
        notes.append("the backend gave no estimate for this row (its failure is below)")
    elif est is None and not case.note:
        notes.append(
            "not predicted again: the report's budget for predicting again "
            f"({PREDICT_BUDGET_S:g} s) was spent"
            if not predicted
            else "no estimate to draw"
        )
    what = f"episode {row['item']}" if "reason" in row else f"item {row['item']} view {row['view']}"
    title = f"{what}: {gt.category} ({gt.key})"
    failed = bool(row.get("failure")) or ("reason" in row and not row.get("success"))
    return Card(title, panels, tuple(row_errors(row, view.categories)), tuple(notes), failed)


# -- the page ----------------------------------------------------------------------------------
_STYLE = """
body { font-family: sans-serif; margin: 1.5em; color: #222; max-width: 1100px; }
h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 1.5em; }
.alarm { background: #fde2e2; border: 2px solid #c00; padding: 0.6em 1em; font-weight: bold; }
.card { border: 1px solid #ccc; border-radius: 6px; padding: 0.6em 1em; margin: 1em 0; }
.card.failed { border-color: #c00; }
.card h3 { font-size: 1em; margin: 0.2em 0 0.6em; }
.panels { display: flex; gap: 12px; flex-wrap: wrap; }
figure { margin: 0; } figcaption { font-size: 0.8em; color: #555; max-width: 224px; }
img { width: 224px; image-rendering: pixelated; background: #000; }
table { border-collapse: collapse; font-size: 0.9em; margin-top: 0.6em; }
td { padding: 1px 10px 1px 0; vertical-align: top; } td.k { color: #555; }
.note { font-size: 0.85em; color: #8a4b00; }
code { background: #f3f3f3; padding: 0 3px; }
"""


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def page(
    ctx: RunContext,
    failures: FailureSummary,
    criterion: str,
    cards: Sequence[Card],
    seconds: float,
) -> str:
    """The report's HTML (no script, no address: only inline style and data URIs)."""
    label = f"{ctx.suite.label} / {backend_label(ctx.backend.name, ctx.backend.kwargs)}"
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>beo-bench report: {_e(label)}</title>",
        f"<style>{_STYLE}</style></head><body>",
        f"<h1>beo-bench report: {_e(label)}</h1>",
    ]
    alarm = failures.warning()
    if alarm:
        parts.append(f'<p class="alarm">{_e(alarm)}</p>')
    parts.append("<h2>Failures</h2>")
    parts += [f"<p>{_e(line.strip())}</p>" for line in failures.lines()[:1]]
    if failures.groups:
        items = "".join(f"<li>{_e(g.text())}</li>" for g in failures.groups)
        parts.append(f"<ul>{items}</ul>")
    if failures.pick_reasons:
        parts.append("<h2>Pick reasons</h2><table>")
        parts += [
            f'<tr><td class="k"><code>{_e(why)}</code></td><td>{n}</td></tr>'
            for why, n in failures.pick_reasons
        ]
        parts.append("</table><p>What each reason means: docs/env.md, “Why a pick fails”.</p>")
    unit = "episodes" if failures.pick_reasons else "views"
    parts.append(f"<h2>The {len(cards)} worst {unit}</h2><p>By {_e(criterion)}.</p>")
    for c in cards:
        parts.append(f'<div class="card{" failed" if c.failed else ""}"><h3>{_e(c.title)}</h3>')
        parts.append('<div class="panels">')
        parts += [
            f'<figure><img alt="{_e(cap)}" src="{data_uri(data)}"><figcaption>{_e(cap)}'
            "</figcaption></figure>"
            for cap, data in c.panels
        ]
        parts.append("</div><table>")
        parts += [f'<tr><td class="k">{_e(k)}</td><td>{_e(v)}</td></tr>' for k, v in c.errors]
        parts.append("</table>")
        parts += [f'<p class="note">{_e(n)}</p>' for n in c.notes]
        parts.append("</div>")
    parts.append(
        f"<p class='note'>Made in {seconds:.1f} s from {_e(RESULTS_NAME)}: each view rebuilt "
        "from its item index, each estimate predicted again by the run's backend.</p>"
    )
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def write_report(
    ctx: RunContext,
    out: Path | str,
    rows: Sequence[dict[str, Any]],
    views: int = DEFAULT_VIEWS,
    backend: Backend | None = None,
    budget_s: float = PREDICT_BUDGET_S,
) -> Report:
    """Write ``OUT/report.html`` for the run ``ctx`` in ``out`` from its result ``rows``
    (``results.jsonl``'s): its failures and its ``views`` worst rows (module docstring).
    ``backend``: the run's backend, built and prepared (default: built here, once, when a
    row is predicted again: a run whose every row failed never builds one). Atomic: a
    reader sees the old page or the new one."""
    from beo_bench.bench.evaluate import Evaluator
    from beo_bench.bench.pool import pinned_threads

    t0 = time.perf_counter()
    out = Path(out)
    rows = sorted(
        (r for r in rows if r["item"] < ctx.suite.size), key=lambda r: (r["item"], r["view"])
    )
    kind = get_kind(ctx.suite.kind)
    ranking = kind.rank_rows(ctx.suite, rows)
    chosen = [rows[i] for i in ranking.order[: max(0, int(views))]]
    cards: list[Card] = []
    predicted = 0
    items = kind.open(ctx.suite, ctx.class_given, ctx.cache_root)
    ev: Evaluator | None = None  # built at the first row predicted again

    def predict(index: int, j: int, view: View) -> Answer:
        nonlocal ev
        if ev is None:
            ev = Evaluator(ctx, backend, items)
        return ev.predict(index, j, view)

    spent = 0.0
    # threads pinned as a worker's: the backend computes as it did in the run
    with pinned_threads(), contextlib.closing(items):
        for row in chosen:
            # what predicting it took in the run, against what predicting took here so far
            cost = float(row.get("ms_decision") or row.get("ms") or 0.0) / 1000.0
            again = not row.get("failure") and spent + cost <= budget_s
            t = time.perf_counter()
            case = kind.report_case(items, row, predict if again else None)
            spent += time.perf_counter() - t if again else 0.0
            predicted += case.estimate is not None
            cards.append(card(case, ctx, bool(again)))
    fs = summarise_failures(rows)
    seconds = time.perf_counter() - t0
    path = out / REPORT_NAME
    atomic_write_bytes(path, page(ctx, fs, ranking.criterion, cards, seconds))
    return Report(path, len(cards), predicted, ranking.criterion, seconds)


__all__ = [
    "DEFAULT_VIEWS",
    "REPORT_NAME",
    "Report",
    "ReportWarning",
    "silhouette",
    "write_report",
]
