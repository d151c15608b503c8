"""``beo-bench leaderboard``: regenerate ``leaderboards/`` from run summaries.

Per suite: ``<suite>.md`` (rows are backends, methods first and the bounds last; means with
bootstrap 95% intervals; then a per-category table and the plots), ``<suite>.json`` (the
summaries behind the table, with their provenance), ``<suite>_rot_cdf.png`` (rotation-error
CDF per backend) and ``<suite>_confusion_<backend>.png``; ``README.md`` indexes them. A row
is a backend with its options (``icp (starts=48)``); when one appears in several runs, the
largest run is shown. Only the newest suite version present is tabulated.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from beo_bench.bench.campaign import backend_label
from beo_bench.bench.runner import write_atomic

BOUNDS = {"oracle": "upper bound", "random": "lower bound"}
Column = tuple[str, str, float, str]
COLUMNS: tuple[Column, ...] = (
    ("rot_err_deg_mean", "rot. error mean (deg)", 1.0, "{:.1f}"),
    ("rot_err_deg_median", "median (deg)", 1.0, "{:.1f}"),
    ("gross_err_rate", "> 15 deg", 100.0, "{:.1f}%"),
    ("acc_10deg5cm", "10deg5cm", 100.0, "{:.1f}%"),
    ("trans_err_cm_mean", "transl. (cm)", 1.0, "{:.2f}"),
    ("class_acc", "class acc.", 100.0, "{:.1f}%"),
    ("iou_mean", "IoU", 1.0, "{:.3f}"),
    ("iou_cam_mean", "posed IoU", 1.0, "{:.3f}"),
    ("edt_err_mean", "EDT error", 1.0, "{:.1f}"),
    ("fscore_mean", "F-score@1%", 1.0, "{:.3f}"),
    ("pick_success", "pick success", 100.0, "{:.1f}%"),
    ("target_found_rate", "target found", 100.0, "{:.1f}%"),
    ("ms_per_view_median", "ms/view", 1.0, "{:.1f}"),
)
PER_CATEGORY: dict[str, tuple[Column, ...]] = {
    "pick": (("pick_success", "pick success", 100.0, "{:.0f}%"),),
    "known-pose": (("class_acc", "class accuracy", 100.0, "{:.0f}%"),),
}
"""The per-category tables' metrics per suite (default: mean rotation error and the gross
error rate, as the dissertation's Tables 5.1 and 5.2)."""
PER_CATEGORY_DEFAULT: tuple[Column, ...] = (
    ("rot_err_deg_mean", "mean rotation error (deg)", 1.0, "{:.1f}"),
    ("gross_err_rate", "rotation errors > 15 deg", 100.0, "{:.1f}%"),
)


def load_summaries(runs: Path) -> list[dict[str, Any]]:
    """Every ``summary.json`` under ``runs``."""
    return [json.loads(p.read_text()) for p in sorted(Path(runs).rglob("summary.json"))]


def label(s: dict[str, Any]) -> str:
    """A summary's row name: the backend and its options."""
    return backend_label(s["backend"], s.get("provenance", {}).get("backend_kwargs") or {})


def _fmt(v: float | None, scale: float, fmt: str) -> str:
    return "-" if v is None or not np.isfinite(v) else fmt.format(v * scale)


def _cell(s: dict[str, Any], key: str, scale: float, fmt: str) -> str:
    if key == "class_acc" and s["metrics"].get("class_given"):
        return "given"
    v = s["metrics"].get(key)
    if v is None:
        return "-"
    text = _fmt(v, scale, fmt)
    ci = s.get("ci95", {}).get(key)
    if ci and all(c is not None and np.isfinite(c) for c in ci):
        lo, hi = (fmt.format(c * scale).rstrip("%") for c in ci)
        text += f" [{lo}, {hi}]"
    return text


def _ordered(summaries: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return sorted(summaries, key=lambda s: (s["backend"] in BOUNDS, label(s)))


def _name(s: dict[str, Any]) -> str:
    bound = BOUNDS.get(s["backend"])
    return f"{label(s)} *({bound})*" if bound else label(s)


def suite_table(summaries: list[dict[str, Any]]) -> str:
    """The Markdown table of one suite: a row per backend, the columns any of them has."""
    has = {k for s in summaries for k in s["metrics"]}
    if any(s["metrics"].get("class_given") for s in summaries):
        has.add("class_acc")
    cols = [c for c in COLUMNS if c[0] in has]
    lines = [
        "| backend | n | failures | " + " | ".join(c[1] for c in cols) + " |",
        "|---|---:|---:|" + "---:|" * len(cols),
    ]
    for s in _ordered(summaries):
        cells = [_cell(s, k, sc, f) for k, _, sc, f in cols]
        lines.append(f"| {_name(s)} | {s['n']} | {s['failures']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def category_table(suite: str, summaries: list[dict[str, Any]]) -> str:
    """Per metric of ``PER_CATEGORY``: categories as rows, backends as columns."""
    rows = _ordered(summaries)
    tables = []
    for key, title, scale, fmt in PER_CATEGORY.get(suite, PER_CATEGORY_DEFAULT):
        if any(key in d for s in rows for d in s.get("per_category", {}).values()):
            tables.append(_category_table(rows, key, title, scale, fmt))
    if not tables:
        tables.append(_category_table(rows, "iou_mean", "mean IoU", 1.0, "{:.3f}"))
    return "\n\n".join(tables)


def _category_table(
    rows: list[dict[str, Any]], key: str, title: str, scale: float, fmt: str
) -> str:
    cats = sorted({c for s in rows for c in s.get("per_category", {})})
    lines = [
        f"{title} per category:",
        "",
        "| category | n | " + " | ".join(label(s) for s in rows) + " |",
        "|---|---:|" + "---:|" * len(rows),
    ]
    for c in cats:
        n = max(s.get("per_category", {}).get(c, {}).get("n", 0) for s in rows)
        cells = [_fmt(s.get("per_category", {}).get(c, {}).get(key), scale, fmt) for s in rows]
        lines.append(f"| {c} | {n} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _savefig(fig: Any, path: Path) -> None:
    import io

    buf = io.BytesIO()
    fig.savefig(buf, dpi=100, format="png", metadata={"Software": None})
    write_atomic(path, buf.getvalue())


def _slug(text: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in text).strip("_")


def _plots(out: Path, suite: str, summaries: list[dict[str, Any]]) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    with_rot = [s for s in _ordered(summaries) if s["metrics"].get("rot_err_deg")]
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
        ax.set_title(f"{suite}: rotation-error CDF")
        name = f"{suite}_rot_cdf.png"
        _savefig(fig, out / name)
        plt.close(fig)
        written.append(name)
    sampled = [s for s in with_rot if "samples" in _kwargs(s)]
    if sampled:
        written.append(_error_vs_samples(out, suite, with_rot, sampled))
    for s in _ordered(summaries):
        conf = s["metrics"].get("confusion")
        if not conf:
            continue
        c = np.asarray(conf, dtype=float)
        fig, ax = plt.subplots(figsize=(5, 4.5), constrained_layout=True)
        norm = c / np.maximum(c.sum(axis=1, keepdims=True), 1)
        im = ax.imshow(norm, vmin=0, vmax=1, cmap="Blues")
        ax.set_xlabel("predicted class")
        ax.set_ylabel("true class")
        cats = s.get("categories")
        if cats and len(cats) == len(c):
            ax.set_xticks(range(len(cats)), cats, rotation=90)
            ax.set_yticks(range(len(cats)), cats)
        fig.colorbar(im, ax=ax, shrink=0.8)
        ax.set_title(f"{suite} / {label(s)}", fontsize="small")
        name = f"{suite}_confusion_{_slug(label(s))}.png"
        _savefig(fig, out / name)
        plt.close(fig)
        written.append(name)
    return written


def _kwargs(s: dict[str, Any]) -> dict[str, Any]:
    return s.get("provenance", {}).get("backend_kwargs") or {}


def _error_vs_samples(
    out: Path, suite: str, with_rot: list[dict[str, Any]], sampled: list[dict[str, Any]]
) -> str:
    """Mean rotation error against N, the samples drawn (dissertation Figure 5.3): a line
    per sampling backend; the other backends as horizontal references."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4), constrained_layout=True)
    lines: dict[str, list[tuple[int, float, Any]]] = {}
    for s in sampled:
        ci = s.get("ci95", {}).get("rot_err_deg_mean")
        n = int(_kwargs(s)["samples"])
        lines.setdefault(s["backend"], []).append((n, s["metrics"]["rot_err_deg_mean"], ci))
    for backend, pts in sorted(lines.items()):
        pts.sort(key=lambda p: p[0])
        x = [p[0] for p in pts]
        y = [p[1] for p in pts]
        ax.plot(x, y, marker="o", label=backend)
        lo = [p[2][0] if p[2] else p[1] for p in pts]
        hi = [p[2][1] if p[2] else p[1] for p in pts]
        ax.fill_between(x, lo, hi, alpha=0.15)
    # the other methods as references, those within twice the sampled errors' range (a
    # far-off baseline would squash the curves this plot is about)
    top = 2 * max(s["metrics"]["rot_err_deg_mean"] for s in sampled)
    others = [s for s in with_rot if "samples" not in _kwargs(s) and s["backend"] not in BOUNDS]
    styles = iter(["--", ":", "-.", (0, (5, 1)), (0, (1, 3))] * 4)
    for i, s in enumerate(o for o in others if o["metrics"]["rot_err_deg_mean"] <= top):
        ax.axhline(
            s["metrics"]["rot_err_deg_mean"],
            ls=next(styles),
            lw=1,
            label=label(s),
            color=f"C{i + 2}",
        )
    ax.set_ylim(0, top)
    ax.set_xscale("log")
    ax.set_xlabel("N, rotation samples drawn")
    ax.set_ylabel("mean rotation error (deg)")
    ax.legend(fontsize="small")
    ax.set_title(f"{suite}: error against N (cf. Figure 5.3)")
    name = f"{suite}_error_vs_samples.png"
    _savefig(fig, out / name)
    plt.close(fig)
    return name


def _newest_rows(ss: list[dict[str, Any]]) -> tuple[int, list[dict[str, Any]]]:
    """The newest suite version present and its rows: one per backend and options (the
    largest run)."""
    newest = max(s["suite_version"] for s in ss)
    best: dict[str, dict[str, Any]] = {}
    for s in ss:
        if s["suite_version"] == newest and s["n"] > best.get(label(s), {}).get("n", -1):
            best[label(s)] = s
    return newest, _ordered(list(best.values()))


OOD_SUFFIX = "-ood"
DEGRADATION: tuple[Column, ...] = (
    ("rot_err_deg_mean", "rot. error mean (deg)", 1.0, "{:.1f}"),
    ("gross_err_rate", "> 15 deg", 100.0, "{:.1f}%"),
    ("class_acc", "class acc.", 100.0, "{:.1f}%"),
    ("iou_mean", "IoU", 1.0, "{:.3f}"),
)


def degradation_table(
    base: str, base_rows: list[dict[str, Any]], suite: str, rows: list[dict[str, Any]]
) -> str:
    """Each backend on ``base`` (in-distribution) and on ``suite`` (its ``-ood`` twin),
    metric by metric: ``in -> out``."""
    by_label = {label(s): s for s in base_rows}
    both = [s for s in rows if label(s) in by_label]
    lines = [
        f"In distribution (`{base}`) -> out of distribution (`{suite}`):",
        "",
        "| backend | " + " | ".join(c[1] for c in DEGRADATION) + " |",
        "|---|" + "---:|" * len(DEGRADATION),
    ]
    for s in both:
        cells = []
        for key, _, scale, fmt in DEGRADATION:
            pair = []
            for row in (by_label[label(s)], s):
                if key == "class_acc" and row["metrics"].get("class_given"):
                    pair.append("given")
                else:
                    pair.append(_fmt(row["metrics"].get(key), scale, fmt))
            cells.append(" -> ".join(pair))
        lines.append(f"| {_name(s)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


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
    lines = [
        "Where the gap to the oracle comes from (`swap`: the backend's estimate with one "
        "component replaced by the truth; shape swaps plan on the true voxels):",
        "",
        "| backend | pick success | true class | true pose (and size) | true shape | oracle "
        "(voxels) | oracle |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for base, got in sorted(swaps.items()):
        cells = [_fmt(plain.get(base), 100.0, "{:.0f}%")]
        cells += [_fmt(got.get(p), 100.0, "{:.0f}%") for p in parts]
        cells += [_fmt(plain.get("oracle (mesh=false)"), 100.0, "{:.0f}%")]
        cells += [_fmt(oracle, 100.0, "{:.0f}%")]
        lines.append(f"| {base} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def regenerate(runs: Path | str = "runs", out: Path | str = "leaderboards") -> list[Path]:
    """Rewrite ``out`` from the summaries under ``runs``; returns the suites' Markdown files.
    Its own files (named after a suite) that no run produces any more are removed."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    by_suite: dict[str, list[dict[str, Any]]] = {}
    for s in load_summaries(Path(runs)):
        by_suite.setdefault(s["suite"], []).append(s)
    keep: set[str] = {"README.md"}
    written = []
    index = [
        "# Leaderboards",
        "",
        f"Generated by `beo-bench leaderboard --runs {runs}` from the run summaries (each "
        "suite's JSON holds them, with provenance: git commit, package versions, machine, "
        "seeds). Means with bootstrap 95% intervals in brackets. *Bounds* are not methods: "
        "`oracle` returns the truth, `random` guesses. `class acc.` reads *given* where the "
        "backend was told the class (the dissertation's ICP protocol).",
        "",
    ]
    chosen = {suite: _newest_rows(ss) for suite, ss in by_suite.items()}
    for suite, (newest, rows) in sorted(chosen.items()):
        plots = _plots(out, suite, rows)
        desc = rows[0].get("provenance", {}).get("suite", {}).get("description", "")
        md = [f"# {suite} (suite version {newest})", "", desc, "", suite_table(rows), ""]
        gap = gap_table(rows)
        if gap:
            md += [gap, ""]
        base = suite.removesuffix(OOD_SUFFIX)
        if base != suite and base in chosen:
            md += [degradation_table(base, chosen[base][1], suite, rows), ""]
        md += [category_table(suite, rows), ""]
        md += [*[f"![{p}]({p})" for p in plots], ""]
        path = out / f"{suite}.md"
        write_atomic(path, "\n".join(md))
        write_atomic(out / f"{suite}.json", json.dumps(rows, indent=2, sort_keys=True) + "\n")
        keep |= {path.name, f"{suite}.json", *plots}
        written.append(path)
        index += [f"## [{suite}]({suite}.md)", "", desc, "", suite_table(rows), ""]
    write_atomic(out / "README.md", "\n".join(index))
    from beo_bench.bench.suites import list_suites

    ours = tuple(list_suites())
    for stale in out.iterdir():  # our files of suites or backends no longer in the runs
        if stale.is_file() and stale.name.startswith(ours) and stale.name not in keep:
            stale.unlink()
    return written
