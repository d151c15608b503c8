"""A leaderboard page's plots: rotation-error CDFs, pick error bins, confusion matrices and error
against MDN samples.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from beo_bench.atomic import atomic_write_bytes
from beo_bench.bench.pages.entries import DIAGNOSTIC, Row, _kwargs, is_bound, label
from beo_bench.bench.pages.pick import episodes
from beo_bench.bench.pages.tables import _ordered
from beo_bench.bench.runs import backend_label


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
