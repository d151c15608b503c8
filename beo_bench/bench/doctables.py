"""The results tables of the README and docs/results.md, made from ``leaderboards/*.json``.

A page marks each generated table with ``<!-- table: NAME -->`` ... ``<!-- /table -->``;
``python -m beo_bench.bench.doctables README.md docs/results.md`` rewrites what lies between
the marks (and nothing else), and ``tests/test_doc_figures.py`` checks that every marked
table equals what the committed leaderboards give, so no figure in them can go stale. The
dissertation's own figures are citations (chapter and table), written here once.
"""

from __future__ import annotations

import functools
import json
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from beo_bench.bench.columns import markdown_table, spec, verdict_cell
from beo_bench.bench.pages.pick import ROBUST_PAIRS
from beo_bench.bench.pages.plots import ERROR_BINS, error_bins, found_target_episodes
from beo_bench.bench.pages.rows import BOUNDS, DISSERTATION_MODELNET10
from beo_bench.bench.pages.tables import confused_pairs
from beo_bench.bench.pages.verdicts import (
    DISSERTATION_PROTOCOL,
    NOT_RUN,
    PRIMARY_COMPARISONS,
    Primary,
    ordering_verdict,
    primary_comparisons,
)
from beo_bench.bench.rundir import sensor_tag_of
from beo_bench.bench.runs import backend_label
from beo_bench.bench.suites import get_suite

MARK = re.compile(r"(<!-- table: ([a-z0-9-]+) -->\n)(.*?)(<!-- /table -->)", re.S)
PRIMARY = "primary"
"""The ``pairing`` of a page's primary comparisons in ``<suite>_paired.json``."""


class MissingFigureError(LookupError):
    """A table asks for a row or metric the leaderboards do not have."""


class PendingSuiteError(MissingFigureError):
    """A table asks for a suite the leaderboards do not hold yet (a campaign run suite by
    suite, ``all --update``): the table says so instead of failing. A row missing from a
    suite that is there stays an error."""


@dataclass(frozen=True)
class Boards:
    """The committed leaderboards: each suite's run summaries and paired results."""

    root: Path

    def rows(self, suite: str) -> list[dict[str, Any]]:
        path = self.root / f"{suite}.json"
        if not path.is_file():
            raise PendingSuiteError(f"leaderboards/{suite}.json is not there")
        return json.loads(path.read_text())

    def paired(self, suite: str) -> list[dict[str, Any]]:
        if not (self.root / f"{suite}.json").is_file():
            raise PendingSuiteError(f"leaderboards/{suite}.json is not there")
        path = self.root / f"{suite}_paired.json"
        return json.loads(path.read_text()) if path.exists() else []

    def row(self, suite: str, name: str, track: str | None = None) -> dict[str, Any]:
        """The row labelled ``name`` (``hbeo``, ``beo (pose_prior=false)``) of the suite's own
        seed and track (default: ``class-free`` where the suite has tracks), with the most
        items."""
        s = get_suite(suite)
        if track is None and s.class_hint:
            track = "class-free"
        found = [
            r
            for r in self.rows(suite)
            if backend_label(r["backend"], r["provenance"].get("backend_kwargs") or {}) == name
            and r.get("track") == track
            and r.get("seed") == s.seed
            and sensor_tag_of(r) is None  # the suite's own sensor: its robustness is apart
        ]
        if not found:
            raise MissingFigureError(f"leaderboards/{suite}.json has no row {name!r} ({track})")
        return max(found, key=lambda r: r["n"])

    def has(self, suite: str, name: str, track: str | None = None) -> bool:
        """Whether the leaderboards have the row (tables leave out rows of runs this
        version's leaderboards do not hold)."""
        try:
            self.row(suite, name, track)
        except MissingFigureError:
            return False
        return True

    def metric(self, suite: str, name: str, key: str, track: str | None = None) -> float:
        v = self.row(suite, name, track)["metrics"].get(key)
        if v is None:
            raise MissingFigureError(f"leaderboards/{suite}.json: {name!r} has no {key}")
        return float(v)

    def pair(
        self,
        suite: str,
        method: str,
        baseline: str,
        metric: str,
        track: str | None,
        sensor: str | None = None,
    ) -> dict[str, Any]:
        """The paired entry of ``method`` against ``baseline``; ``sensor``: in the part of
        that sensor (not the suite's own), else the suite's own sensor's."""
        for p in self.paired(suite):
            if p.get("sensor") != sensor:  # another sensor's part, or a pair across sensors
                continue
            if p.get("pairing") == "sensor":
                continue
            if p.get("pairing") == PRIMARY:  # the same pair, Holm-corrected: self.primary
                continue
            if (p["method"], p["baseline"], p["metric"], p["track"]) == (
                method,
                baseline,
                metric,
                track,
            ):
                return p
        raise MissingFigureError(
            f"leaderboards/{suite}_paired.json has no {method} - {baseline} on {metric} ({track})"
        )

    def primary(self, suite: str, pc: Primary) -> dict[str, Any] | None:
        """The page's primary comparison ``pc``, Holm-corrected over the page's family
        (``"pairing": "primary"``, :func:`beo_bench.bench.pages.verdicts.primary_results`);
        None on a page made before pages carried them."""
        for p in self.paired(suite):
            if p.get("pairing") == PRIMARY and "sensor" not in p:
                key = (p["method"], p["baseline"], p["metric"], p["track"])
                if key == (pc.method, pc.baseline, pc.metric, pc.track):
                    return p
        return None


# -- formats ---------------------------------------------------------------------------------
def pct(v: float) -> str:
    return f"{100 * v:.1f}%"


def deg(v: float) -> str:
    return f"{v:.1f} deg"


def num(v: float, digits: int = 3) -> str:
    return f"{v:.{digits}f}"


def _diff(p: dict[str, Any], unit: str, digits: int = 1) -> str:
    """A paired difference with its interval and verdict; ``unit`` `` pts`` for a rate
    (shown in percentage points), else the value's own unit (`` deg``, or ``""``)."""
    scale = 100.0 if unit == " pts" else 1.0
    d, lo, hi = (f"{scale * x:+.{digits}f}" for x in (p["diff"], *p["ci95"]))
    return f"{d}{unit} [{lo}, {hi}] {verdict_cell(p['verdict'])}"


def _table(head: list[str], rows: list[list[str]]) -> str:
    """A doc table: every column left-aligned, a line break after it."""
    return markdown_table(head, rows, "l") + "\n"


METHODS = ("beo", "hbeo", "hbeo-mdn-likelihood", "hbeo-mdn-posterior", "icp", "icp-plain")


# -- the tables ------------------------------------------------------------------------------
def headline(b: Boards) -> str:
    """Every backend on every suite (the pose suites' class-free track)."""
    head = [
        "backend",
        "`known-pose` class acc., IoU",
        "`pose-1dof` mean, > 15 deg",
        "`pose-3dof` mean, > 15 deg, class acc.",
        "`tabletop` mean, > 15 deg, class acc.",
        "`pick` success",
    ]
    rows = []
    for name in (*METHODS, "random", "oracle"):

        def m(suite: str, key: str, name: str = name) -> float:
            return b.metric(suite, name, key)

        pick = pct(m("pick", "pick_success"))
        if name == "oracle":
            voxels = b.metric("pick", "oracle (mesh=false)", "pick_success")
            pick += f" ({pct(voxels)} planning on its voxels)"
        rows.append(
            [
                f"`{name}`",
                f"{pct(m('known-pose', 'class_acc'))}, {num(m('known-pose', 'iou_mean'))}",
                _pose_cell(b, "pose-1dof", name, False),
                _pose_cell(b, "pose-3dof", name, True),
                _pose_cell(b, "tabletop", name, True),
                pick,
            ]
        )
    return _table(head, rows) + "\n" + modes_note(b) + "\n"


HEADLINE_CELLS: tuple[tuple[str, str | None, tuple[str, ...]], ...] = (
    ("known-pose", None, ("class_acc",)),
    ("pose-1dof", "class-free", ("rot_err_deg_mean", "gross_err_rate")),
    ("pose-3dof", "class-free", ("rot_err_deg_mean", "gross_err_rate", "class_acc")),
    ("tabletop", None, ("rot_err_deg_mean", "gross_err_rate", "class_acc")),
    ("pick", None, ("pick_success",)),
)
"""The headline's figures, by (suite, track, metrics)."""


def modes_note(b: Boards) -> str:
    """What the headline says of its two MDN rows, which differ by a little everywhere:
    per figure, the posterior against the likelihood paired on the same views, as a finding
    only where the page's Holm-corrected primary comparison says so; an uncorrected interval
    that excludes 0 is named as such, not as a finding (issue 47)."""
    post, lik = "hbeo-mdn-posterior", "hbeo-mdn-likelihood"
    same, found, loose = 0, [], []
    for suite, track, keys in HEADLINE_CELLS:
        for key in keys:
            fmt_unit = _DIFF_FORMATS.get(key)
            try:
                got = b.primary(suite, Primary(post, lik, key, track, ""))
                p = got if got is not None else b.pair(suite, post, lik, key, track)
            except MissingFigureError:  # the page, or the pair on it, is not there (yet)
                continue
            what = f"`{suite}` {spec(key).label}"
            diff = _diff(p, fmt_unit[1]) if fmt_unit else p["verdict"]
            if p["verdict"] == "no difference":
                same += 1
            elif got is not None:
                found.append(f"{what} {diff} after Holm's correction")
            else:
                loose.append(f"{what} {diff.replace('**', '')} uncorrected")
    paired = same + len(found) + len(loose)
    text = (
        f"`{post}` against `{lik}`, paired on the same views: no difference on {same} of "
        f"the {paired} figures above that the pages pair"
    )
    if found:
        text += "; a finding after Holm's correction over the page's primary comparisons: "
        text += "; ".join(found)
    if loose:
        text += (
            "; " + "; ".join(loose) + ": one of the many paired cells of the pages, not "
            "corrected for them, so not a finding (docs/results.md, the orderings)"
        )
    return text + "."


def _pose_cell(b: Boards, suite: str, name: str, with_class: bool) -> str:
    """``mean, > 15 deg`` (and the class accuracy) of one row."""
    cells = [
        deg(b.metric(suite, name, "rot_err_deg_mean")),
        pct(b.metric(suite, name, "gross_err_rate")),
    ]
    if with_class:
        cells.append(pct(b.metric(suite, name, "class_acc")))
    return ", ".join(cells)


def class_given(b: Boards) -> str:
    """BEO against the dissertation's plain ICP and ours, the class given (Figures 3.6, 4.3)."""
    head = [
        "suite, class given",
        "`beo` mean, > 15 deg",
        "`icp-plain`",
        "`icp`",
        "`beo` - `icp-plain`: mean; > 15 deg",
        "`beo` - `icp`: mean; > 15 deg",
    ]
    rows = []
    # the dissertation's own protocol first (chapter 3's top-down views at 1-DOF, Figure
    # 3.6; its ModelNet10 classes at 3-DOF, Figure 4.3), then ours
    suites = ("modelnet10-1dof", "modelnet10-3dof", "pose-1dof", "pose-1dof+modelnet10",
              "pose-3dof", "pose-3dof-ood")  # fmt: skip
    for suite in suites:
        t = "class-given"
        if not (b.root / f"{suite}.json").is_file() or not b.has(suite, "beo", t):
            continue  # not in this version's leaderboards (docs/reference-models.md)

        def cell(name: str, suite: str = suite, t: str = t) -> str:
            mean = b.metric(suite, name, "rot_err_deg_mean", t)
            return f"{deg(mean)}, {pct(b.metric(suite, name, 'gross_err_rate', t))}"

        diffs = []
        for base in ("icp-plain", "icp"):
            mean = b.pair(suite, "beo", base, "rot_err_deg_mean", t)
            gross = b.pair(suite, "beo", base, "gross_err_rate", t)
            diffs.append(f"{_diff(mean, ' deg')}; {_diff(gross, ' pts')}")
        n = b.row(suite, "beo", t)["n"]
        rows.append([f"`{suite}` ({n} views)", cell("beo"), cell("icp-plain"), cell("icp"), *diffs])
    if not rows:  # a table of headers alone would read as a broken page
        raise PendingSuiteError(f"none of {', '.join(suites)} has a class-given `beo` row")
    return _table(head, rows)


def _ablation_rows(
    b: Boards, suite: str, method: str, baseline: str, tracks: list[str], keys: list[str]
) -> list[list[str]]:
    rows = []
    for t in tracks:
        cells: list[list[str]] = [[], [], []]
        for k in keys:
            p = b.pair(suite, method, baseline, k, t)
            fmt = deg if k == "rot_err_deg_mean" else pct
            cells[0].append(fmt(p["baseline_value"]))
            cells[1].append(fmt(p["method_value"]))
            cells[2].append(_diff(p, " deg" if k == "rot_err_deg_mean" else " pts"))
        items = b.pair(suite, method, baseline, keys[0], t)["items"]
        rows.append([f"{t} ({items} views)", *(", ".join(c) for c in cells)])
    return rows


def beo_prior(b: Boards) -> str:
    """BEO with the suites' viewpoint prior against a uniform P(r) (eq. 3.22)."""
    head = ["`pose-3dof`", "with the prior", "uniform P(r)", "uniform - prior [95%]"]
    rows = _ablation_rows(
        b, "pose-3dof", "beo (pose_prior=false)", "beo", ["class-given"],
        ["rot_err_deg_mean", "gross_err_rate"],
    )  # fmt: skip
    rows += _ablation_rows(
        b, "pose-3dof", "beo (pose_prior=false)", "beo", ["class-free"],
        ["rot_err_deg_mean", "gross_err_rate", "class_acc"],
    )  # fmt: skip
    return _table(head, rows)


def mdn_prior_table(suite: str) -> Callable[[Boards], str]:
    """The table of HBEO-MDN's posterior (with eq. 5.6's silhouette prior) against its
    likelihood on ``suite``, class-free, paired on the same views (the same samples: both
    modes seed them by the crop)."""

    def table(b: Boards) -> str:
        head = [f"`{suite}`, class-free", "likelihood", "posterior",
                "posterior - likelihood [95%]"]  # fmt: skip
        rows = []
        rank: Callable[[float], str] = functools.partial(num, digits=1)
        for n in (25, 100):
            opt = "" if n == 25 else " (samples=100)"
            method, base = f"hbeo-mdn-posterior{opt}", f"hbeo-mdn-likelihood{opt}"
            if n != 25 and not b.has(suite, method):
                continue  # N = 100 where the campaign runs it (pose-3dof)
            for label, key, fmt, unit in (
                ("mean error", "rot_err_deg_mean", deg, " deg"),
                ("> 15 deg", "gross_err_rate", pct, " pts"),
                ("rank of the best sample (0: first)", "sample_best_rank_mean", rank, ""),
            ):
                p = b.pair(suite, method, base, key, "class-free")
                rows.append([f"N = {n}, {label}", fmt(p["baseline_value"]),
                             fmt(p["method_value"]), _diff(p, unit)])  # fmt: skip
            # the samples themselves are the same in both modes: what the best one errs
            best = b.metric(suite, method, "sample_best_err_deg_mean")
            rows.append([f"N = {n}, best sample's error", deg(best), deg(best), "-"])
            ms = [b.row(suite, x)["metrics"] for x in (base, method)]
            # how far the samples lie from the estimate each mode picks (median angle)
            key = "sample_spread_deg_mean"
            if all(m.get(key) is not None for m in ms):
                rows.append([f"N = {n}, samples' spread (median angle to the estimate)",
                             deg(ms[0][key]), deg(ms[1][key]), "-"])  # fmt: skip
            # the views the pick got wrong (> 15 deg) alone: what the samples held there
            for label, key, fmt in (
                ("gross errors: rank of the best sample", "sample_best_rank_gross_mean", rank),
                ("gross errors with a sample within 15 deg", "sample_near_true_gross_rate", pct),
                ("gross errors that are half turns", "half_turn_gross_rate", pct),
            ):
                if all(m.get(key) is not None for m in ms):
                    rows.append([f"N = {n}, {label}", fmt(ms[0][key]), fmt(ms[1][key]), "-"])
        return _table(head, rows)

    return table


ABLATION_DIR = "ablations"
"""``leaderboards/ablations/``: pages of a suite's few variant rows, for an ablation its full
page cannot carry without re-running every row (``pose-3dof``'s prior steps: its ``beo``
rows take hours); ``beo-bench leaderboard --ablation --runs RUNS --out
leaderboards/ablations`` makes them from the variants' runs and their baseline's."""


def _ablation_pair(
    b: Boards, suite: str, method: str, baseline: str, key: str, track: str | None,
    category: str | None = None, sensor: str | None = None,
) -> dict[str, Any] | None:  # fmt: skip
    """The ablation entry of ``method`` against ``baseline`` under ``sensor`` (None: the
    suite's own), on every item (``category`` None) or on one category's; None when the
    page lacks it."""
    try:
        paired = b.paired(suite)
    except PendingSuiteError:
        return None
    for p in paired:
        if p.get("pairing") != "ablation" or p.get("sensor") != sensor:
            continue
        if (p["method"], p["baseline"], p["metric"], p["track"]) != (method, baseline, key, track):
            continue
        if p.get("category") == category:
            return p
    return None


def prior_ablation(per_category: bool) -> Callable[[Boards], str]:
    """Chapter 5's ablation (issue 48): each step of ``hbeo-mdn-posterior``'s prior options
    (:data:`~beo_bench.bench.ablations.PRIOR_STEPS`) minus the likelihood on the same
    samples, mean rotation error, paired: on ``pose-3dof`` (its ablation page), on
    ``pose-3dof-percat`` whole and per category (Tables 5.1/5.2's), on ``tabletop``; with
    ``per_category``, the per-category networks' steps (class-given)."""
    from beo_bench.bench.ablations import PER_CATEGORY, PRIOR_STEPS

    def table(b: Boards) -> str:
        track = "class-given" if per_category else "class-free"
        Col = tuple[str, Boards, str, str | None, str | None, str | None]
        cols: list[Col] = []
        if not per_category:
            ab = Boards(b.root / ABLATION_DIR)
            cols.append(("`pose-3dof`", ab, "pose-3dof", track, None, None))
        cols += [
            (f"`pose-3dof-percat`{f', {c}' if c else ''}", b, "pose-3dof-percat", track, c, None)
            for c in (None, "car", "airplane", "sofa")
        ]
        if not per_category:  # its steps run under the ideal sensor: occlusion alone
            cols.append(("`tabletop` (ideal sensor)", b, "tabletop", None, None, "ideal"))
        opts0 = PER_CATEGORY if per_category else {}
        base = backend_label("hbeo-mdn-likelihood", opts0)
        steps = [({}, "the prior as published (eq. 5.6, 32^3, the crop)"), *PRIOR_STEPS]
        rows: list[list[str]] = []
        found: list[list[dict[str, Any] | None]] = []
        for opts, what in steps:
            method = backend_label("hbeo-mdn-posterior", {**opts0, **opts})
            pairs = [
                _ablation_pair(bb, suite, method, base, "rot_err_deg_mean", tr, c, se)
                for _, bb, suite, tr, c, se in cols
            ]
            if all(p is None for p in pairs):
                continue
            found.append(pairs)
            label = f"{what} (`{options_of(opts)}`)" if opts else what
            rows.append([label, *("-" if p is None else _diff(p, "") for p in pairs)])
        if not rows:
            raise PendingSuiteError("no prior step is on the pages")
        # each column's likelihood (the baseline of every step there), for scale
        scale = [
            next((deg(ps[j]["baseline_value"]) for ps in found if ps[j] is not None), "-")  # type: ignore[index]
            for j in range(len(cols))
        ]
        head = ["posterior - likelihood, mean error (deg) [95%]", *(c[0] for c in cols)]
        return _table(head, [["the likelihood's own mean error", *scale], *rows])

    return table


def shape_selection(b: Boards) -> str:
    """What selecting the published networks on their shape loss would change (issue 48):
    each network's kept epoch (the lowest total validation loss) against the epoch of its
    lowest validation projection loss (eq. 4.3's shape term), from the training history
    each published model carries (``perception/published/<stem>.json``)."""
    from beo_bench.perception import published

    files = published.manifest()
    stems = ["hbeo", "hbeo-mdn"]
    stems += [published.per_category_stem("hbeo-mdn", c) for c in published.PER_CATEGORY]
    rows = []
    for stem in stems:
        if f"{stem}.json" not in files:
            continue
        meta, _ = published.read(stem)
        hist = meta["info"]["history"]
        kept = int(meta["info"]["epoch_kept"])
        best = min(hist, key=lambda r: r["val_projection"])
        at = hist[kept - 1]
        gain = 1 - best["val_projection"] / at["val_projection"]
        rows.append([
            f"`{stem}`", f"{kept} of {len(hist)}", num(at["val_projection"]),
            f"{best['epoch']}", num(best["val_projection"]), f"{100 * gain:.1f}%",
        ])  # fmt: skip
    head = ["published network", "kept epoch (lowest total loss)", "its shape loss",
            "epoch of the lowest shape loss", "that shape loss", "shape loss saved"]  # fmt: skip
    return _table(head, rows)


def options_of(opts: dict[str, Any]) -> str:
    """``k=v,k=v``: how ``--opt`` / ``--backends NAME:K=V,...`` spell a step's options."""
    return ",".join(f"{k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in opts.items())


def swap(b: Boards) -> str:
    """Where each backend's pick gap comes from: one estimated component swapped for the truth."""
    head = ["backend", "pick success", "true class", "true pose and size", "true shape",
            "oracle on voxels"]  # fmt: skip
    voxels = pct(b.metric("pick", "oracle (mesh=false)", "pick_success"))
    rows = []
    for base in ("hbeo", "hbeo-mdn-posterior", "icp"):
        cells = [pct(b.metric("pick", base, "pick_success"))]
        for truth in ("class", "pose", "shape"):
            name = f'swap (base="{base}", truth="{truth}")'
            # a swap not run at this suite version (the backend's own row is): "-", as the
            # page has no row of it; the prose beside the table says which
            if not b.has("pick", name):
                cells.append("-")
                continue
            shift = _shift(b.pair("pick", name, base, "pick_success", None))
            cells.append(f"{pct(b.metric('pick', name, 'pick_success'))} ({shift})")
        rows.append([f"`{base}`", *cells, voxels])
    return _table(head, rows)


def _shift(p: dict[str, Any]) -> str:
    """A paired change in a rate, in points with its interval (``+14.4 [+10.2, +18.4]``)."""
    lo, hi = p["ci95"]
    return f"{100 * p['diff']:+.1f} [{100 * lo:+.1f}, {100 * hi:+.1f}]"


REST_PRIOR_SENSOR = "ideal"
"""The sensor the rest prior's tabletop controls ran under (the campaign block's line)."""


def rest_prior(b: Boards) -> str:
    """``tabletop``: each method that takes the rest prior against itself without it
    (``pose_prior=false``), paired on the scenes both scored, under :data:`REST_PRIOR_SENSOR`."""
    head = ["backend", "scenes", "rot. error mean, with -> without", "> 15 deg", "class acc.",
            "with - without, mean [95%]"]  # fmt: skip
    rows = []
    for name in ("beo", "icp", "icp-plain"):
        control = f"{name} (pose_prior=false)"
        pairs = [
            b.pair("tabletop", control, name, k, None, REST_PRIOR_SENSOR)
            for k in ("rot_err_deg_mean", "gross_err_rate", "class_acc")
        ]
        rot, gross, acc = pairs
        lo, hi = rot["ci95"]
        rows.append([
            f"`{name}`", str(rot["items"]),
            f"{deg(rot['baseline_value'])} -> {deg(rot['method_value'])}",
            f"{pct(gross['baseline_value'])} -> {pct(gross['method_value'])}",
            f"{pct(acc['baseline_value'])} -> {pct(acc['method_value'])}",
            # the table's direction is with - without: the ablation's, negated
            f"{-rot['diff']:+.1f} deg [{-hi:+.1f}, {-lo:+.1f}]",
        ])  # fmt: skip
    return _table(head, rows)


PICK_CONTROLS: tuple[tuple[str, str], ...] = (
    ("beo (pose_prior=false)", "beo"),
    ("icp (pose_prior=false)", "icp"),
    ("icp-plain (pose_prior=false)", "icp-plain"),
    ("oracle (mesh=false)", "oracle"),
)
"""The pick page's controls docs/results.md quotes: the rest prior made uniform for each
method that takes it, and the oracle planning on voxels."""


def pick_pairs(b: Boards) -> str:
    """Pick's comparisons on the same episodes: the page's primary ones (Holm-corrected over
    the page's family), then the controls (uncorrected)."""
    head = ["method", "baseline", "episodes", "pick success, method - baseline [95%]",
            "verdict"]  # fmt: skip
    rows = []
    for pc in primary_comparisons("pick"):
        p = b.primary("pick", pc)
        if p is None:
            continue
        verdict = verdict_cell(p["verdict"])
        rows.append([f"`{pc.method}`", f"`{pc.baseline}`", str(p["items"]),
                     f"{_shift(p)} pts", f"{verdict} (Holm)"])  # fmt: skip
    for method, base in PICK_CONTROLS:
        if not b.has("pick", method):
            continue
        p = b.pair("pick", method, base, "pick_success", None)
        rows.append([f"`{method}`", f"`{base}`", str(p["items"]), f"{_shift(p)} pts",
                     f"{p['verdict']} (uncorrected)"])  # fmt: skip
    return _table(head, rows)


def pick_sensitivity(b: Boards) -> str:
    """What pick punishes (issue 49): the oracle with one controlled error of a known size
    (``oracle:rot_deg=D``, ``rot_axis=up``, ``trans_cm=T``, ``shape=class-mean``) against
    the oracle on the same episodes, pick success and its paired change."""
    from beo_bench.bench.ablations import SENSITIVITY_STEPS

    base = b.metric("pick", "oracle", "pick_success")
    rows = [["the truth (`oracle`)", pct(base), "-"]]
    for opts, what in SENSITIVITY_STEPS:
        method = backend_label("oracle", opts)
        if not b.has("pick", method):
            continue
        p = b.pair("pick", method, "oracle", "pick_success", None)
        rows.append([f"{what} (`{options_of(opts)}`)", pct(p["method_value"]), _diff(p, " pts")])
    if len(rows) == 1:
        raise PendingSuiteError("no sensitivity row is on the pick page")
    table = _table(["the oracle's estimate", "pick success", "- the oracle [95%]"], rows)
    # the tolerance of each kind of error: where success falls to half the oracle's
    tol = []
    for what, unit, levels in (
        ("rotation, random axis", "deg", [({"rot_deg": d}, d) for d in ROT_LEVELS]),
        ("rotation about the up axis (yaw)", "deg",
         [({"rot_axis": "up", "rot_deg": d}, d) for d in ROT_LEVELS]),
        ("translation", "cm", [({"trans_cm": t}, t) for t in TRANS_LEVELS]),
    ):  # fmt: skip
        pts = [(0.0, base)] + [
            (float(x), b.metric("pick", backend_label("oracle", o), "pick_success"))
            for o, x in levels
            if b.has("pick", backend_label("oracle", o))
        ]
        if len(pts) > 1:
            t = half_success_tolerance([x for x, _ in pts], [y for _, y in pts])
            tol.append([what, "beyond the largest error" if t is None else f"{t:.3g} {unit}"])
    head = ["error", "tolerance (success at half the oracle's)"]
    return table + "\n" + _table(head, tol) + "\n" + _sensitivity_per_category(b)


def _sensitivity_per_category(b: Boards) -> str:
    """Per category (about 28 episodes a level), the tolerance of each damage of
    :func:`pick_sensitivity`, from the rows' per-category success; ``-`` where the oracle
    itself picks under a third of the category's targets (no curve to halve)."""
    levels: dict[str, list[tuple[dict[str, Any], float]]] = {
        "rotation (deg)": [({"rot_deg": d}, d) for d in ROT_LEVELS],
        "yaw (deg)": [({"rot_axis": "up", "rot_deg": d}, d) for d in ROT_LEVELS],
        "translation (cm)": [({"trans_cm": t}, t) for t in TRANS_LEVELS],
    }
    base = b.row("pick", "oracle").get("per_category", {})
    rows = []
    for cat in sorted(base):
        y0 = base[cat].get("pick_success")
        cells = [cat, str(int(base[cat].get("n", 0))), "-" if y0 is None else pct(y0)]
        for steps in levels.values():
            pts = [(0.0, y0)] if y0 is not None else []
            for o, x in steps:
                name = backend_label("oracle", o)
                if pts and b.has("pick", name):
                    v = b.row("pick", name).get("per_category", {}).get(cat, {})
                    if v.get("pick_success") is not None:
                        pts.append((float(x), float(v["pick_success"])))
            if len(pts) < 2 or pts[0][1] < 1 / 3:
                cells.append("-")
                continue
            t = half_success_tolerance([x for x, _ in pts], [y for _, y in pts])
            cells.append("never halves" if t is None else f"{t:.3g}")
        rows.append(cells)
    return _table(["category", "episodes", "the oracle", *levels], rows)


def _found_target(b: Boards) -> dict[str, list[dict[str, Any]]]:
    """Each perception backend's ideal-sensor pick row (no options, no bounds, nothing
    privileged): its episodes that chose their target and record their errors."""
    per: dict[str, list[dict[str, Any]]] = {}
    for r in b.rows("pick"):
        if sensor_tag_of(r) is not None or r["provenance"].get("backend_kwargs"):
            continue
        if r["backend"] in BOUNDS or r.get("privileged"):
            continue
        eps = found_target_episodes(r)
        if eps:
            per[r["backend"]] = eps
    if not per:
        raise PendingSuiteError("no pick run records its estimates' errors yet")
    return per


def pick_vs_error(b: Boards) -> str:
    """Pick success against each error of the estimate the episode grasped, binned, over
    the episodes that chose their target (the committed per-episode records of
    ``leaderboards/pick.json``): every perception backend with records pooled, then each;
    the bounds and privileged rows left out. A cell is success (episodes)."""
    from itertools import pairwise

    per = _found_target(b)
    out = []
    for key, (what, unit, edges) in ERROR_BINS.items():
        head = [f"{what} ({unit})" if unit else what]
        head += [f"{lo:g}-{hi:g}" if hi < 100 else f">= {lo:g}" for lo, hi in pairwise(edges)]
        lines = []
        for name, eps in [
            ("every backend", [e for v in per.values() for e in v]),
            *sorted(per.items()),
        ]:
            cells = []
            for lo, hi in pairwise(edges):
                top = hi if hi == edges[-1] else np.nextafter(hi, -np.inf)  # last bin: hi in it
                sel = [e for e in eps if e.get(key) is not None and lo <= e[key] <= top]
                ok = sum(bool(e["success"]) for e in sel)
                cells.append(f"{pct(ok / len(sel))} ({len(sel)})" if sel else "-")
            lines.append([name if name == "every backend" else f"`{name}`", *cells])
        out.append(_table(head, lines))
    return "\n".join(out)


def _rate(eps: list[dict[str, Any]], key: str = "success") -> float:
    return sum(bool(e[key]) for e in eps) / len(eps)


def _audited(b: Boards) -> dict[str, list[dict[str, Any]]]:
    """Every ideal-sensor pick row whose episodes record the grasp audit, by row name: the
    episodes (all of them, as dicts)."""
    from beo_bench.bench.pages.pick import episodes

    out: dict[str, list[dict[str, Any]]] = {}
    for r in b.rows("pick"):
        if sensor_tag_of(r) is not None:
            continue
        eps = list(episodes(r).values())
        if any(e.get("force_closure") is not None for e in eps):
            out[backend_label(r["backend"], r["provenance"].get("backend_kwargs") or {})] = eps
    if not out:
        raise PendingSuiteError("no pick run records its grasps' audit yet")
    return dict(sorted(out.items()))


def pick_tolerance(b: Boards) -> str:
    """Each backend's own tolerance (issue 49): from its episodes that chose their target,
    binned by the grasped estimate's error (:data:`ERROR_BINS`), the error at which success
    falls to half its value in the first bin (:func:`half_success_tolerance` over the bins'
    median errors; IoU's bins read from 1 down)."""
    per = _found_target(b)
    head = ["backend", "episodes"]
    head += [f"{what} ({unit})" if unit else what for what, unit, _ in ERROR_BINS.values()]
    rows = []
    for name, eps in [
        ("every backend", [e for v in per.values() for e in v]),
        *sorted(per.items()),
    ]:
        cells = [name if name == "every backend" else f"`{name}`", str(len(eps))]
        for key in ERROR_BINS:
            pts = [(x, y) for x, y, _ in error_bins(eps, key)]
            if key == "iou_cam":  # better is larger: walk the bins from the top
                pts = [(1 - x, y) for x, y in reversed(pts)]
            t = half_success_tolerance([x for x, _ in pts], [y for _, y in pts]) if pts else None
            if t is not None and key == "iou_cam":
                t = 1 - t
            cells.append("never halves" if t is None else f"{t:.3g}")
        rows.append(cells)
    return _table(head, rows)


def _kappa(a: list[bool], b: list[bool]) -> float:
    """Cohen's kappa of two yes/no raters (Cohen 1960): agreement beyond chance."""
    n = len(a)
    po = sum(x == y for x, y in zip(a, b, strict=True)) / n
    pa, pb = sum(a) / n, sum(b) / n
    pe = pa * pb + (1 - pa) * (1 - pb)
    return 0.0 if pe == 1 else (po - pe) / (1 - pe)


def pick_audit(b: Boards) -> str:
    """The simulated grasp check against the analytic one (issue 49), over every executed
    grasp the ideal-sensor pick rows record: the simulator lifted the object the grasp was
    planned on, and the grasp is in force closure at mu = 0.4 on that object's true mesh
    (``closure_friction``); their agreement, Cohen's kappa and the two kinds of
    disagreement; then the shake's effect on each row's success."""
    from beo_bench.grasping import AUDIT_FRICTION
    from beo_bench.scenes.gripper import GRIPPER

    per = _audited(b)
    pads = GRIPPER.pad_friction
    head = ["row", "executed grasps", "lifted", f"force closure (mu {AUDIT_FRICTION:g})",
            "agree", "kappa", "lifted, no closure", "closure, not lifted",
            f"agree at the pads' mu {pads:g}"]  # fmt: skip
    rows = []
    pooled: list[dict[str, Any]] = []
    for name, eps in per.items():
        done = [e for e in eps if e.get("force_closure") is not None]
        pooled += done
        rows.append(_audit_row(f"`{name}`", done, pads))
    rows.insert(0, _audit_row("every row", pooled, pads))
    audit = _table(head, rows)
    head2 = ["row", "pick success", "held after the shake", "lost to the shake",
             "median slip of the held (cm)", "contacts per finger (median)"]  # fmt: skip
    rows2 = []
    for name, eps in per.items():
        won = [e for e in eps if e["success"]]
        held = [e for e in won if e.get("shake_held")]
        slips = [e["slip_cm"] for e in held if e.get("slip_cm") is not None]
        fingers = [
            min(e["contacts_left"], e["contacts_right"])
            for e in won
            if e.get("contacts_left") is not None and e.get("contacts_right") is not None
        ]
        rows2.append([
            f"`{name}`", pct(_rate(eps)), pct(len(held) / len(eps)), str(len(won) - len(held)),
            f"{np.median(slips):.2f}" if slips else "-",
            f"{np.median(fingers):g}" if fingers else "-",
        ])  # fmt: skip
    return audit + "\n" + _table(head2, rows2)


def _audit_row(name: str, done: list[dict[str, Any]], pads: float) -> list[str]:
    sim = [bool(e["lifted_chosen"]) for e in done]
    fc = [bool(e["force_closure"]) for e in done]
    # at the friction the simulated pads have (fc_mu: the least friction that closes)
    at_pads = [e["fc_mu"] is not None and e["fc_mu"] <= pads for e in done]
    n = len(done)
    agree = sum(x == y for x, y in zip(sim, fc, strict=True))
    return [
        name, str(n), pct(sum(sim) / n), pct(sum(fc) / n), pct(agree / n), f"{_kappa(sim, fc):.2f}",
        str(sum(x and not y for x, y in zip(sim, fc, strict=True))),
        str(sum(y and not x for x, y in zip(sim, fc, strict=True))),
        pct(sum(x == y for x, y in zip(sim, at_pads, strict=True)) / n),
    ]  # fmt: skip


def pick_robust(b: Boards) -> str:
    """The grasp planned over the MDN's pose samples against the one planned on its best
    sample, on the same episodes and estimates (issue 49): success, its share of the
    oracle's, the paired change, and the median planning time per decision (from the
    episodes' records: wall time in runs made at different times on a loaded machine, so
    their ratio is not the cost; ``benchmarks/bench_grasp.py`` pairs it)."""
    from beo_bench.bench.pages.pick import episodes

    oracle = b.metric("pick", "oracle", "pick_success")
    head = ["row", "pick success", "of the oracle's", "- best-sample grasp [95%]",
            "planning (ms, median, in the campaign)"]  # fmt: skip
    rows = []
    for base, robust in ROBUST_PAIRS:
        if not b.has("pick", robust):
            continue
        ms: dict[str, float | None] = {}
        for name in (base, robust):
            eps = episodes(b.row("pick", name)).values()
            t = [e["plan_ms"] for e in eps if e.get("plan_ms") is not None]
            ms[name] = float(np.median(t)) if t else None
        for name in (base, robust):
            v = b.metric("pick", name, "pick_success")
            shift = _diff(b.pair("pick", robust, base, "pick_success", None), " pts")
            rows.append([
                f"`{name}`", pct(v), pct(v / oracle) if oracle else "-",
                shift if name == robust else "-",
                f"{ms[name]:.0f}" if ms[name] is not None else "-",
            ])  # fmt: skip
    if not rows:
        raise PendingSuiteError("no grasp=robust row is on the pick page")
    return _table(head, rows)


ROT_LEVELS = (5, 15, 30, 60, 90)
TRANS_LEVELS = (0.5, 1, 2, 4)


def half_success_tolerance(errors: list[float], success: list[float]) -> float | None:
    """The error at which pick success first falls to half its value at the smallest error
    (issue 49's tolerance), linearly interpolated between the measured levels (``errors``
    ascending); None when it never does."""
    half = success[0] / 2
    from itertools import pairwise

    for (x0, y0), (x1, y1) in pairwise(zip(errors, success, strict=True)):
        if y1 <= half:
            return x0 if y0 == y1 else x0 + (x1 - x0) * (y0 - half) / (y0 - y1)
    return None


def ood(b: Boards) -> str:
    """Each backend in (``pose-3dof``) and out of distribution (``pose-3dof-ood``)."""
    head = ["backend", "mean rotation error", "> 15 deg", "class accuracy", "IoU"]
    for suite in ("pose-3dof", "pose-3dof-ood"):
        b.rows(suite)  # both pages, or the table is pending
    rows = []
    for name in METHODS:
        if not b.has("pose-3dof-ood", name):
            continue
        cells = []
        for key, fmt in (
            ("rot_err_deg_mean", lambda v: f"{v:.1f}"),
            ("gross_err_rate", lambda v: f"{100 * v:.1f}"),
            ("class_acc", lambda v: f"{100 * v:.1f}"),
            ("iou_mean", num),
        ):
            a, o = b.metric("pose-3dof", name, key), b.metric("pose-3dof-ood", name, key)
            unit = " deg" if key == "rot_err_deg_mean" else ("" if key == "iou_mean" else "%")
            cells.append(f"{fmt(a)} -> {fmt(o)}{unit}")
        rows.append([f"`{name}`", *cells])
    return _table(head, rows)


def hbeo_detail(b: Boards) -> str:
    """The HBEO family on ``pose-3dof`` (class-free), beside ``icp`` and ``beo``."""
    head = ["`pose-3dof`, class-free", "mean rot. error", "> 15 deg", "class acc.", "IoU",
            "EDT error", "F-score", "ms/view in the runner"]  # fmt: skip
    rows = []
    names = [
        "hbeo",
        *(f"hbeo-mdn-{m}{o}" for m in ("likelihood", "posterior")
          for o in (" (samples=5)", "", " (samples=100)")),
        "icp",
        "beo",
    ]  # fmt: skip
    b.rows("pose-3dof")  # the page, or the table is pending
    for name in names:
        if not b.has("pose-3dof", name):
            continue

        def m(key: str, name: str = name) -> float:
            return b.metric("pose-3dof", name, key)

        rows.append(
            [
                f"`{name}`",
                deg(m("rot_err_deg_mean")),
                pct(m("gross_err_rate")),
                pct(m("class_acc")),
                num(m("iou_mean")),
                f"{m('edt_err_mean'):.0f}",
                num(m("fscore_mean")),
                f"{m('ms_per_view_median'):.1f}",
            ]
        )
    return _table(head, rows)


def dissertation(b: Boards) -> str:
    """Our figures beside the dissertation's (Burchfiel 2019; the tables named)."""
    kp = {n: pct(b.metric("known-pose", n, "class_acc")) for n in METHODS}
    p3 = {n: pct(b.metric("pose-3dof", n, "class_acc")) for n in METHODS}

    def ms(suite: str, name: str) -> float:
        return b.metric(suite, name, "ms_per_view_median")

    def percat(name: str, key: str, fmt: Callable[[float], str], track: str | None = None) -> str:
        per = b.row("pose-3dof-percat", name, track)["per_category"]
        return " / ".join(fmt(per[c][key]).split()[0] for c in ("car", "airplane", "sofa"))

    post100 = "hbeo-mdn-posterior (samples=100)"
    own100 = "hbeo-mdn-posterior (per_category=true, samples=100)"  # chapter 5's networks
    own = b.has("pose-3dof-percat", own100, "class-given")

    def own_cell(key: str, fmt: Callable[[float], str], unit: str) -> str:
        if not own:
            return ""
        return (
            f"; one network per category (published, class given): `hbeo-mdn-posterior` "
            f"N=100 {percat(own100, key, fmt, 'class-given')}{unit}"
        )

    rows = [
        [
            "Table 3.1: class accuracy at a known pose",
            "BEO 76.3% (ModelNet10; 3DShapeNets 54.4%)",
            f"`beo` {kp['beo']}, `icp` (nearest class-mean shape) {kp['icp']}, `icp-plain` "
            f"{kp['icp-plain']}, `hbeo` {kp['hbeo']}, `hbeo-mdn` {kp['hbeo-mdn-likelihood']} "
            "(`known-pose`)",
        ],
        [
            "Table 4.1: class accuracy, 3-DOF",
            "HBEO 81.8%",
            f"`hbeo` {p3['hbeo']}, `hbeo-mdn` {p3['hbeo-mdn-likelihood']}, `beo` {p3['beo']} "
            "(`pose-3dof`, class-free)",
        ],
        [
            "Table 4.2: time per view",
            "BEO 1-DOF 672.97 s, 3-DOF 3529.88 s; HBEO 0.01 s (GTX1070)",
            f"`beo` {ms('pose-1dof', 'beo') / 1000:.2f} s and {ms('pose-3dof', 'beo') / 1000:.2f} "
            f"s; `hbeo` {ms('pose-3dof', 'hbeo'):.1f} ms (median in the runner, one worker per "
            "core on 2 CPU cores)",
        ],
        [
            "Table 5.1: mean rotation error, car / plane / couch",
            "HBEO 9.45 / 13.29 / 18.84 deg; MDN posterior N=100 3.23 / 8.06 / 7.50 deg (one "
            "network per category)",
            f"one network for all 18 classes: `hbeo` {percat('hbeo', 'rot_err_deg_mean', deg)} "
            f"deg; `hbeo-mdn-posterior` N=100 {percat(post100, 'rot_err_deg_mean', deg)} deg"
            f"{own_cell('rot_err_deg_mean', deg, ' deg')} (`pose-3dof-percat`, 200 views a "
            "class)",
        ],
        [
            "Table 5.2: > 15 deg, car / plane / couch",
            "HBEO 6.87 / 13.57 / 31.27%; MDN posterior N=100 0.93 / 5.78 / 5.95% (one network "
            "per category)",
            f"`hbeo` {percat('hbeo', 'gross_err_rate', pct)}; `hbeo-mdn-posterior` N=100 "
            f"{percat(post100, 'gross_err_rate', pct)}{own_cell('gross_err_rate', pct, '')} "
            "(the same)",
        ],
        [
            "Table 5.1: MDN posterior time, N=25 / N=100",
            "0.32 / 1.06 s (1080ti)",
            f"{ms('pose-3dof', 'hbeo-mdn-posterior'):.0f} / {ms('pose-3dof', post100):.0f} ms "
            "(median in the runner, 2 CPU cores)",
        ],
    ]
    return _table(["dissertation figure", "dissertation", "ours"], rows)


# -- ModelNet10 (issue 28: Tables 3.1 and 4.1, chapter 4's confusions, the headroom) ----------
HEADROOM_CAP = 0.97
"""No in-tree method may read the class of more than 97% of ``modelnet10-3dof``'s views: a
suite the reference method aces cannot rank the next one (the bounds aside)."""
CHAPTER4_CLASSES: dict[str, tuple[float, float, float]] = {
    c: (
        DISSERTATION_MODELNET10["modelnet10-known-pose"][2][c],
        DISSERTATION_MODELNET10["modelnet10-1dof"][2][c],
        hbeo,
    )
    for c, hbeo in DISSERTATION_MODELNET10["modelnet10-3dof"][2].items()
}
"""Chapter 4's account of HBEO's gain over BEO on ModelNet10 (Tables 3.1 and 4.1): the
class accuracy of BEO at a known pose and at 1-DOF (Table 3.1's two rows), then HBEO at
3-DOF (Table 4.1), on the classes that ModelNet10 confuses (the dissertation rows'
per-class figures in :data:`beo_bench.bench.pages.rows.DISSERTATION_MODELNET10`)."""


def _acc_ci(b: Boards, suite: str, name: str) -> str:
    row = b.row(suite, name)
    lo, hi = row["ci95"]["class_acc"]
    return f"{pct(row['metrics']['class_acc'])} [{100 * lo:.1f}, {100 * hi:.1f}]"


def _unpaired(b: Boards, a: tuple[str, str], c: tuple[str, str]) -> tuple[str, str]:
    """Class accuracy of run ``a`` against run ``c`` ((suite, backend); other items, or no
    pairing committed: not paired): both, their difference and a 95% interval from the two
    bootstrap intervals as if normal (their half-widths add in quadrature), and whether
    ``a`` above ``c`` holds (``holds``, ``fails``, or ``no difference`` when the interval
    spans 0: an ordering not shown does not hold)."""
    ra, rc = b.row(*a), b.row(*c)
    va, vc = ra["metrics"]["class_acc"], rc["metrics"]["class_acc"]
    half = float(np.hypot(*(np.diff(r["ci95"]["class_acc"])[0] / 2 for r in (ra, rc))))
    d, lo, hi = va - vc, va - vc - half, va - vc + half
    verdict = "holds" if lo > 0 else ("fails" if hi < 0 else "no difference")
    figures = (
        f"{pct(va)} vs {pct(vc)}: {100 * d:+.1f} pts [{100 * lo:+.1f}, {100 * hi:+.1f}] (unpaired)"
    )
    return figures, verdict


def modelnet10(b: Boards) -> str:
    """Class accuracy on the three ModelNet10 protocols beside Tables 3.1 and 4.1 (the pose
    suites' class-free track), with 95% intervals."""
    suites = ("modelnet10-known-pose", "modelnet10-1dof", "modelnet10-3dof")
    head = ["backend", *(f"`{s}`" for s in suites)]
    rows = [["the dissertation", "BEO 76.3% (Table 3.1)", "BEO 54.5% (Table 3.1)",
             "HBEO 81.8% (Table 4.1)"]]  # fmt: skip
    for name in (*METHODS, "random"):
        if not any(b.has(s, name) for s in suites):
            continue
        rows.append(
            [f"`{name}`", *(_acc_ci(b, s, name) if b.has(s, name) else "-" for s in suites)]
        )
    if len(rows) == 1:  # a campaign suite by suite: partial once one of them is there
        raise PendingSuiteError(f"none of {', '.join(suites)} is in leaderboards/")
    # chapter 4's comparison, paired on the same views (the leaderboard's hbeo - beo pair):
    # on class, and on completion (IoU in the object's frame)
    for key, label, unit in (("class_acc", "", " pts"), ("iou_mean", ", IoU", "")):
        cells = []
        for s in suites:
            track = "class-free" if get_suite(s).class_hint else None
            try:
                p = b.pair(s, "hbeo", "beo", key, track)
            except MissingFigureError:  # the suite or one of the two runs is not there yet
                cells.append("-")
                continue
            cells.append(_diff(p, unit, 3 if unit == "" else 1))  # an IoU: 3 decimals
        rows.append([f"`hbeo` - `beo`{label}, paired", *cells])
    return _table(head, rows)


def modelnet10_viewpoints(b: Boards) -> str:
    """Class accuracy on the ModelNet10 set from chapter 3's top-down view (the
    ``modelnet10-*`` suites) beside our viewpoint distribution (the same protocol's suite
    restricted to the set, ``--categories modelnet10``), class-free, with 95% intervals.
    The items differ, so nothing here is paired."""
    pairs = (
        ("modelnet10-known-pose", "known-pose+modelnet10"),
        ("modelnet10-1dof", "pose-1dof+modelnet10"),
    )
    suites = [s for pair in pairs for s in pair]
    missing = [s for s in suites if not (b.root / f"{s}.json").is_file()]
    rows = []
    for name in (*METHODS, "random"):
        cells = [_acc_ci(b, s, name) if b.has(s, name) else "-" for s in suites]
        if any(c != "-" for c in cells):
            rows.append([f"`{name}`", *cells])
    if missing or not rows:
        raise PendingSuiteError(f"{', '.join(missing)} not in leaderboards/")
    return _table(["backend", *(f"`{s}`" for s in suites)], rows)


def modelnet10_headroom(b: Boards) -> str:
    """Issue 28's headroom on ``modelnet10-3dof`` (class-free): every method's class
    accuracy under the cap. The dissertation's orderings on the suite are in the
    ``orderings`` table, which reports each as it comes out rather than requiring it."""
    suite = "modelnet10-3dof"
    head = ["check", "figures", "verdict"]
    rows = []
    for name in METHODS:
        if not b.has(suite, name):
            continue
        acc = b.metric(suite, name, "class_acc")
        ok = "holds" if acc <= HEADROOM_CAP else "**fails**"
        rows.append([f"`{name}` class accuracy <= 97%", _acc_ci(b, suite, name), ok])
    if not rows:
        raise PendingSuiteError(f"leaderboards/{suite}.json has no method's row")
    return _table(head, rows)


def modelnet10_chapter4(b: Boards) -> str:
    """Per class, BEO (known pose, 1-DOF) and HBEO (3-DOF) beside chapter 4's figures for the
    classes it discusses, and each method's most frequent confusions on
    ``modelnet10-3dof``."""
    known, one, three = "modelnet10-known-pose", "modelnet10-1dof", "modelnet10-3dof"
    kp = b.row(known, "beo")["per_category"]
    beo, hbeo = b.row(one, "beo")["per_category"], b.row(three, "hbeo")["per_category"]
    head = ["class", "dissertation: BEO known pose / 1-DOF -> HBEO 3-DOF",
            "ours: `beo` known pose / 1-DOF -> `hbeo` 3-DOF"]  # fmt: skip
    rows = []
    for c in sorted(set(beo) | set(hbeo)):
        theirs = CHAPTER4_CLASSES.get(c)
        ours = (kp[c]["class_acc"], beo[c]["class_acc"], hbeo[c]["class_acc"])
        rows.append(
            [
                c.replace("_", " "),
                f"{pct(theirs[0])} / {pct(theirs[1])} -> {pct(theirs[2])}" if theirs else "-",
                f"{pct(ours[0])} / {pct(ours[1])} -> {pct(ours[2])}",
            ]
        )
    out = _table(head, rows)
    conf_rows = []
    for name in METHODS:
        if not b.has(three, name):
            continue
        r = b.row(three, name)
        top = [f"{t} -> {p} {k}/{n}" for t, p, k, n in confused_pairs(r, 4)]
        conf_rows.append([f"`{name}`", str(r["n"]), "; ".join(top).replace("_", " ") or "none"])
    return (
        out
        + "\n"
        + _table(
            [
                f"`{three}`, class-free",
                "views",
                "most frequent confusions (true -> predicted: views of the true class)",
            ],
            conf_rows,
        )
    )


def beo_figures(b: Boards) -> str:
    """``beo`` and ``icp`` on the isolated suites, with the dissertation's figures."""

    def t(ms: float) -> str:
        return f"{ms / 1000:.2f} s" if ms >= 1000 else f"{ms:.0f} ms"

    def both(suite: str, key: str, fmt: Callable[[float], str]) -> list[str]:
        return [
            " / ".join(fmt(b.metric(suite, n, key, tr)) for tr in ("class-given", "class-free"))
            for n in ("beo", "icp")
        ]

    def pose(suite: str, track: str, with_class: bool) -> list[str]:
        out = []
        for n in ("beo", "icp"):
            m = b.row(suite, n, track)["metrics"]
            cell = f"{m['rot_err_deg_mean']:.1f} / {deg(m['rot_err_deg_median'])}, "
            cell += pct(m["gross_err_rate"])
            if with_class:
                cell += f", {pct(m['class_acc'])}"
            out.append(cell)
        return out

    kp = [
        f"{pct(b.metric('known-pose', n, 'class_acc'))}, "
        f"{num(b.metric('known-pose', n, 'iou_mean'))}"
        for n in ("beo", "icp")
    ]
    rows = [
        ["known-pose: median per view", *(t(b.metric("known-pose", n, "ms_per_view_median"))
                                          for n in ("beo", "icp")), "1.13 s"],
        ["pose-1dof: median per view, class given / class-free",
         *both("pose-1dof", "ms_per_view_median", t), "672.97 s"],
        ["pose-3dof: median per view, class given / class-free",
         *both("pose-3dof", "ms_per_view_median", t), "3529.88 s"],
        ["known-pose: class accuracy, IoU", kp[0], kp[1] + " (mean shape)", "76.3% (ModelNet10)"],
        ["pose-1dof, class given: rotation error mean / median, > 15 deg",
         *pose("pose-1dof", "class-given", False), "n/a"],
        ["pose-1dof, class-free: mean / median, > 15 deg, class accuracy",
         *pose("pose-1dof", "class-free", True), "n/a"],
        ["pose-3dof, class given: mean / median, > 15 deg",
         *pose("pose-3dof", "class-given", False), "n/a"],
        ["pose-3dof, class-free: mean / median, > 15 deg, class accuracy",
         *pose("pose-3dof", "class-free", True), "n/a"],
    ]  # fmt: skip
    return _table(["figure", "`beo`", "`icp`", "dissertation"], rows)


def ref_accuracy(b: Boards) -> str:
    """The published networks on ``pose-3dof`` (class-free) beside the dissertation's car."""
    rows = []
    for name, what in (
        ("hbeo", "`hbeo` (published)"),
        ("hbeo-mdn-likelihood", "`hbeo-mdn-likelihood` N=25 (published)"),
        ("hbeo-mdn-posterior", "`hbeo-mdn-posterior` N=25 (published)"),
    ):
        m = b.row("pose-3dof", name)["metrics"]
        rows.append(
            [what, deg(m["rot_err_deg_mean"]), pct(m["gross_err_rate"]), pct(m["class_acc"]),
             num(m["iou_mean"])]
        )  # fmt: skip
    rows.append(["dissertation, HBEO (car; Tables 4.1, 5.1, 5.2)", "9.45 deg", "6.87%",
                 "81.8% (3-DOF, Table 4.1)", ""])  # fmt: skip
    rows.append(["dissertation, MDN posterior N=100 (car)", "3.23 deg", "0.93%", "", ""])
    return _table(["network", "mean rot. error", "> 15 deg", "class acc.", "IoU"], rows)


def pick_models(b: Boards) -> str:
    """``pick`` success of the published networks, and with one component swapped in."""
    rows = [[f"`{n}`", pct(b.metric("pick", n, "pick_success"))] for n in METHODS[1:4]]
    for base in ("hbeo-mdn-posterior", "hbeo"):
        rates = [
            pct(b.metric("pick", f'swap (base="{base}", truth="{t}")', "pick_success"))
            for t in ("class", "pose", "shape")
        ]
        rows.append([f"`swap:base={base}`, true class / pose / shape", " / ".join(rates)])
    rows.append(["`oracle` (the truth)", pct(b.metric("pick", "oracle", "pick_success"))])
    return _table(["backend", "pick success"], rows)


# -- the dissertation's orderings and the primary comparisons (issue 47) ---------------------
ORDERING_SUITES: tuple[str, ...] = (
    *DISSERTATION_PROTOCOL,
    "known-pose",
    "known-pose+modelnet10",
    "pose-1dof",
    "pose-1dof+modelnet10",
    "pose-3dof",
    "pose-3dof-ood",
    "tabletop",
)
"""The pages whose primary comparisons hold the dissertation's orderings: the suites of its
own protocol first (:data:`~beo_bench.bench.pages.verdicts.DISSERTATION_PROTOCOL`), then ours."""
THE_DISSERTATIONS, OURS = "the dissertation's", "ours"
ORDERINGS_SAID: dict[str, str] = {
    "Table 3.1": "at a known pose BEO reads the class better than 3DShapeNets (here the "
    "nearest class-mean shape, `icp`, stands in)",
    "Figure 3.6": "at 1-DOF, every method told the class, BEO errs less in rotation than plain ICP",
    "Table 4.1": "HBEO reads the class better than BEO",
    "Figure 4.3": "at 3-DOF, every method told the class, BEO errs less in rotation than plain ICP",
    "Table 4.2": "HBEO takes a fraction of BEO's time per view",
    "Table 5.1": "each MDN mode's mean rotation error is below HBEO's",
    "Table 5.2": "each MDN mode errs by more than 15 deg less often than HBEO",
    "Table 5.1 (eq. 5.6's prior)": "the posterior (the silhouette prior) errs less than the "
    "likelihood",
    "Table 5.1 (eq. 5.6's prior, per-category networks)": "with each category's own network, "
    "the posterior errs less than the likelihood",
    "Table 5.2 (eq. 5.6's prior, per-category networks)": "with each category's own network, "
    "the posterior errs by more than 15 deg less often than the likelihood",
}
"""Each ordering of the dissertation that docs/results.md quotes, in its words, in the order
of the dissertation; the key is the ``source`` of its primary comparisons."""
_DIFF_FORMATS: dict[str, tuple[Callable[[float], str], str]] = {
    "rot_err_deg_mean": (deg, " deg"),
    "gross_err_rate": (pct, " pts"),
    "class_acc": (pct, " pts"),
    "pick_success": (pct, " pts"),
}


@dataclass(frozen=True)
class Check:
    """One dissertation ordering on one suite (or pair of suites): what was compared, the
    figures and whether it ``holds``, ``fails`` or shows ``no difference`` (``not run``: a
    run is missing; ``waits``: the page is not in the leaderboards yet)."""

    source: str
    protocol: str
    suite: str
    claim: str
    figures: str
    verdict: str


def _claim(pc: Primary) -> str:
    m = spec(pc.metric)
    side = "above" if m.higher_is_better else "below"
    track = {"class-given": ", class given", "class-free": ", class-free"}.get(pc.track or "", "")
    return f"`{pc.method}` {side} `{pc.baseline}` on {m.label}{track}"


def _paired_check(b: Boards, suite: str, pc: Primary) -> tuple[str, str]:
    """The figures and the verdict of a declared ordering on a page: its Holm-corrected
    primary comparison where the page has it, else the page's paired interval
    (uncorrected), else (class accuracy, no pairing committed) the two rows' intervals,
    unpaired."""
    fmt, unit = _DIFF_FORMATS[pc.metric]
    got = b.primary(suite, pc)
    if got is not None:
        figures = f"{fmt(got['method_value'])} vs {fmt(got['baseline_value'])}: "
        return figures + _diff(got, unit) + " (Holm)", str(got["ordering"])
    try:
        p = b.pair(suite, pc.method, pc.baseline, pc.metric, pc.track)
    except MissingFigureError:
        if pc.metric != "class_acc" or not (b.has(suite, pc.method) and b.has(suite, pc.baseline)):
            return "-", NOT_RUN
        return _unpaired(b, (suite, pc.method), (suite, pc.baseline))
    figures = f"{fmt(p['method_value'])} vs {fmt(p['baseline_value'])}: {_diff(p, unit)}"
    return figures, str(ordering_verdict(pc.expected, p["verdict"]))


def _protocol(suite: str) -> str:
    return THE_DISSERTATIONS if suite in DISSERTATION_PROTOCOL else OURS


def ordering_checks(b: Boards) -> list[Check]:
    """Every ordering of :data:`ORDERINGS_SAID` on every page that tests it: the paired ones
    from the pages' primary comparisons (:data:`~beo_bench.bench.pages.verdicts.
    PRIMARY_COMPARISONS`), HBEO at 3-DOF against BEO at 1-DOF (Table 4.1's two rows, other
    views: unpaired) and the time per view (Table 4.2: medians, not resampled); in the
    order of :data:`ORDERINGS_SAID`, the dissertation's protocol first."""
    checks = []
    for suite in ORDERING_SUITES:
        for pc in primary_comparisons(suite):
            if pc.expected is None:
                continue
            try:
                figures, verdict = _paired_check(b, suite, pc)
            except PendingSuiteError:
                figures, verdict = "-", WAITS
            checks.append(Check(pc.source, _protocol(suite), suite, _claim(pc), figures, verdict))
    claim = "`hbeo` at 3-DOF above `beo` at 1-DOF on class acc., class-free (other views)"
    for three, one in (("modelnet10-3dof", "modelnet10-1dof"), ("pose-3dof", "pose-1dof")):
        try:
            figures, verdict = _unpaired(b, (three, "hbeo"), (one, "beo"))
        except PendingSuiteError:
            figures, verdict = "-", WAITS
        checks.append(Check("Table 4.1", _protocol(three), f"{three} / {one}", claim, figures,
                            verdict))  # fmt: skip
    claim = "`hbeo` below `beo` on the median time per view, class-free (not resampled)"
    for suite in ("modelnet10-1dof", "modelnet10-3dof", "pose-1dof", "pose-3dof"):
        try:
            hbeo, beo = (b.metric(suite, n, "ms_per_view_median") for n in ("hbeo", "beo"))
            figures = f"{hbeo:.1f} ms vs {beo:.1f} ms"
            verdict = "holds" if hbeo < beo else "fails"
        except PendingSuiteError:
            figures, verdict = "-", WAITS
        except MissingFigureError:
            figures, verdict = "-", NOT_RUN
        checks.append(Check("Table 4.2", _protocol(suite), suite, claim, figures, verdict))
    order = list(ORDERINGS_SAID)
    return sorted(checks, key=lambda c: (order.index(c.source), c.protocol != THE_DISSERTATIONS))


WAITS = "waits"
VERDICTS: tuple[str, ...] = ("holds", "fails", "no difference", NOT_RUN, WAITS)


def ordering_counts(checks: list[Check]) -> dict[str, dict[str, int]]:
    """Per protocol (the dissertation's, then ours), how many checks have each verdict."""
    out = {p: dict.fromkeys(VERDICTS, 0) for p in (THE_DISSERTATIONS, OURS)}
    for c in checks:
        out[c.protocol][c.verdict] += 1
    return out


def orderings(b: Boards) -> str:
    """docs/results.md's table of every ordering of the dissertation it quotes, on the
    dissertation's protocol and then on ours, each ``holds``, ``fails`` or ``no
    difference`` (an ordering a paired interval cannot show does not hold), and the counts."""
    checks = ordering_checks(b)
    if all(c.verdict == WAITS for c in checks):
        raise PendingSuiteError(f"none of {', '.join(ORDERING_SUITES)} is in leaderboards/")
    said = _table(["source", "the dissertation's ordering"],
                  [[s, ORDERINGS_SAID[s]] for s in ORDERINGS_SAID])  # fmt: skip
    rows = [
        [c.source, c.protocol, f"`{c.suite}`", c.claim, c.figures,
         "**fails**" if c.verdict == "fails" else c.verdict]
        for c in checks
    ]  # fmt: skip
    head = ["source", "protocol", "suite", "compared", "figures", "verdict"]
    counts = ordering_counts(checks)
    shown = [v for v in VERDICTS if any(n[v] for n in counts.values())]
    tally = [[p, str(sum(n.values())), *(str(n[v]) for v in shown)] for p, n in counts.items()]
    return "\n".join([said, _table(head, rows), _table(["protocol", "checks", *shown], tally)])


def primary_declared(boards: Boards) -> str:
    """docs/benchmark.md's table of the primary comparisons each leaderboard page declares
    (:data:`~beo_bench.bench.pages.verdicts.PRIMARY_COMPARISONS`; ``boards`` is not read: the
    declaration comes before the runs)."""
    head = ["page", "method (B)", "baseline (A)", "metric", "track", "why", "expected"]
    rows = [
        [f"`{suite}`", f"`{pc.method}`", f"`{pc.baseline}`", spec(pc.metric).label,
         pc.track or "-", pc.source, "B better" if pc.expected else "none: a question"]
        for suite, declared in PRIMARY_COMPARISONS.items()
        for pc in declared
    ]  # fmt: skip
    return _table(head, rows)


INTERVAL_ITEMS = (20, 50, 100, 200, 500, 1000)
"""From the smoke set's 20 items an isolated suite (``SMOKE_SIZES``) to a full suite."""
INTERVAL_RATES = (0.5, 0.8, 0.95)
INTERVAL_DISCORDANT = (0.1, 0.3)


def interval_widths(boards: Boards) -> str:
    """docs/benchmark.md's table of what n items can tell: the 95% half-width of a rate
    near 50% (the widest), 80% and 95%, of a paired difference of two rates when 10% or
    30% of the items differ between the runs, and the smallest such difference a gate
    finds with 80% power (:mod:`beo_bench.stats`' formulas; ``boards`` is not
    read: these figures follow from n alone)."""
    from beo_bench.stats import detectable_difference, paired_half_width, rate_half_width

    head = (
        ["items n"]
        + [f"a rate near {r:.0%}" for r in INTERVAL_RATES]
        + [f"paired, {q:.0%} of items differ" for q in INTERVAL_DISCORDANT]
        + [f"smallest difference found, {INTERVAL_DISCORDANT[-1]:.0%} differ"]
    )
    lines = []
    for n in INTERVAL_ITEMS:
        cells = [f"{n}"]
        cells += [f"{100 * rate_half_width(r, n):.1f}" for r in INTERVAL_RATES]
        cells += [f"{100 * paired_half_width(q, n):.1f}" for q in INTERVAL_DISCORDANT]
        found = detectable_difference(INTERVAL_DISCORDANT[-1], n)
        cells.append(f"{100 * found:.1f}" if np.isfinite(found) else "-")
        lines.append(cells)
    return markdown_table(head, lines, "r") + "\n"


RobustnessCell = tuple[str, str | None, str, str]
"""One column of a robustness headline: (suite, track, metric, header)."""
ROBUSTNESS_CELLS: tuple[RobustnessCell, ...] = (
    ("known-pose", None, "class_acc", "`known-pose` class acc."),
    ("pose-1dof", "class-free", "gross_err_rate", "`pose-1dof` > 15 deg (class-free)"),
    ("pose-3dof", "class-free", "gross_err_rate", "`pose-3dof` > 15 deg (class-free)"),
    ("tabletop", None, "class_acc", "`tabletop` class acc."),
    ("pick", None, "pick_success", "`pick` success"),
)
"""The robustness headline's columns: the main suites."""
ROBUSTNESS_MORE_CELLS: tuple[RobustnessCell, ...] = (
    ("pose-3dof-ood", "class-free", "gross_err_rate", "`pose-3dof-ood` > 15 deg (class-free)"),
    ("modelnet10-known-pose", None, "class_acc", "`modelnet10-known-pose` class acc."),
    ("modelnet10-1dof", "class-free", "gross_err_rate", "`modelnet10-1dof` > 15 deg (class-free)"),
    (
        "pose-1dof+modelnet10",
        "class-free",
        "gross_err_rate",
        "`pose-1dof+modelnet10` > 15 deg (class-free)",
    ),
    ("modelnet10-3dof", "class-free", "gross_err_rate", "`modelnet10-3dof` > 15 deg (class-free)"),
)
"""The second robustness table's columns: the out-of-distribution and ModelNet10 suites."""
SENSOR_ORDER = ("kinect-v1", "d435")


def _sensor_pairs(
    b: Boards, suite: str, track: str | None, metric: str
) -> dict[tuple[str, str], dict[str, Any]]:
    """``{(backend, sensor): entry}`` of the page's robustness pairs (each sensor's run
    against the backend's ``ideal`` run, paired on the same items) for one metric."""
    out = {}
    for p in b.paired(suite):
        if p.get("baseline_sensor") == "ideal" and p["metric"] == metric:
            if p.get("track") == track:
                out[(p["method"], p["sensor"])] = p
    return out


NOT_RUN_SENSORS = "ideal only at this version"
"""A robustness cell of a page whose runs under the other sensors are not made yet."""


def robustness_table(cells: tuple[RobustnessCell, ...]) -> Callable[[Boards], str]:
    """docs/sensors.md's robustness tables: each backend's figure ideal -> kinect-v1 -> d435
    on suites run under all three, each step in bold where its paired interval (on the same
    items) excludes 0 the worse way."""

    def table(b: Boards) -> str:
        head = ["backend", *(h for *_, h in cells)]
        # one lookup per column: two columns may share a suite and metric on two tracks
        pairs = [_sensor_pairs(b, s, t, m) for s, t, m, _ in cells]
        rows = []
        for name in (*METHODS, *BOUNDS):
            row = [f"`{name}`"]
            for found, (suite, _, metric, _) in zip(pairs, cells, strict=True):
                if not found:
                    # the page holds no sensor section at its version (a campaign made the
                    # suite's own sensor first): the column says so, the others stand
                    b.rows(suite)  # the page itself must be there (else the table waits)
                    row.append(NOT_RUN_SENSORS)
                    continue
                if any((name, tag) not in found for tag in SENSOR_ORDER):
                    raise MissingFigureError(
                        f"leaderboards/{suite}_paired.json has no {name} {metric} under "
                        "every sensor"
                    )
                got = [found[(name, tag)] for tag in SENSOR_ORDER]
                steps = [pct(got[0]["baseline_value"])]
                for g in got:
                    v = pct(g["method_value"])
                    steps.append(f"**{v}**" if g["verdict"] == "worse" else v)
                row.append(" -> ".join(steps))
            rows.append(row)
        return _table(head, rows)

    return table


BOP_SUITE = "pose-1dof"
BOP_SENSORS = ("ideal", "kinect-v1", "d435")


def bop_figures(b: Boards) -> str:
    """docs/bop.md's table: BOP 2019's AR and its parts, and NOCS's 10deg5cm and IoU50, of
    every backend on ``pose-1dof`` (class-free) under each sensor."""
    rows_by = {
        (r["backend"], r.get("sensor") or "ideal", r.get("track")): r
        for r in b.rows(BOP_SUITE)
        if not r.get("provenance", {}).get("backend_kwargs")
    }
    head = ["backend", *(f"BOP AR `{t}`" for t in BOP_SENSORS), "AR_VSD / AR_MSSD / AR_MSPD "
            "`ideal`", "10deg5cm, 3D IoU50 `ideal`"]  # fmt: skip
    rows = []
    for name in (*METHODS, *BOUNDS):
        keys = [(name, t, "class-free") for t in BOP_SENSORS]
        if any(k not in rows_by or "ar_bop" not in rows_by[k]["metrics"] for k in keys):
            raise PendingSuiteError(
                f"leaderboards/{BOP_SUITE}.json has no BOP figures of {name} under every sensor"
            )
        got = [rows_by[k] for k in keys]
        m = got[0]["metrics"]
        parts = " / ".join(num(m[k]) for k in ("ar_vsd", "ar_mssd", "ar_mspd"))
        nocs = f"{pct(m['acc_10deg5cm'])}, {pct(m['iou3d_50'])}"
        rows.append([f"`{name}`", *(num(g["metrics"]["ar_bop"]) for g in got), parts, nocs])
    return _table(head, rows)


TABLES: dict[str, Callable[[Boards], str]] = {
    "robustness": robustness_table(ROBUSTNESS_CELLS),
    "robustness-more": robustness_table(ROBUSTNESS_MORE_CELLS),
    "bop-figures": bop_figures,
    "ref-accuracy": ref_accuracy,
    "pick-models": pick_models,
    "beo-figures": beo_figures,
    "headline": headline,
    "class-given": class_given,
    "beo-prior": beo_prior,
    "mdn-prior": mdn_prior_table("pose-3dof"),
    "mdn-prior-modelnet10": mdn_prior_table("modelnet10-3dof"),
    "swap": swap,
    "prior-ablation": prior_ablation(per_category=False),
    "prior-ablation-percat": prior_ablation(per_category=True),
    "shape-selection": shape_selection,
    "pick-pairs": pick_pairs,
    "pick-sensitivity": pick_sensitivity,
    "pick-vs-error": pick_vs_error,
    "pick-tolerance": pick_tolerance,
    "pick-audit": pick_audit,
    "pick-robust": pick_robust,
    "rest-prior": rest_prior,
    "ood": ood,
    "hbeo-detail": hbeo_detail,
    "dissertation": dissertation,
    "modelnet10": modelnet10,
    "modelnet10-viewpoints": modelnet10_viewpoints,
    "modelnet10-headroom": modelnet10_headroom,
    "modelnet10-chapter4": modelnet10_chapter4,
    "interval-widths": interval_widths,
    "orderings": orderings,
    "primary-comparisons": primary_declared,
}


def render(text: str, boards: Boards) -> str:
    """``text`` with every marked table regenerated (an unknown name is an error)."""

    def one(m: re.Match[str]) -> str:
        name = m.group(2)
        if name not in TABLES:
            raise MissingFigureError(
                f"no generated table named {name!r}: use one of {sorted(TABLES)}"
            )
        try:
            table = TABLES[name](boards)
        except PendingSuiteError as e:
            # a campaign run suite by suite (`all --update`) fills the leaderboards over
            # several sessions: until the rows are there the table says so, it never shows
            # another version's figures
            table = PENDING.format(reason=e)
        return m.group(1) + table + m.group(4)

    return MARK.sub(one, text)


PENDING = (
    "*Not in this suite version's leaderboards yet ({reason}); `beo-bench all --update "
    "--suites SUITE` makes its runs and this table.*\n"
)
"""What a generated table says while the leaderboards lack a row it needs."""


def main(argv: list[str] | None = None) -> int:
    """Rewrite the marked tables of the files given, from ``leaderboards/``."""
    args = sys.argv[1:] if argv is None else argv
    boards = Boards(Path("leaderboards"))
    for name in args:
        path = Path(name)
        new = render(path.read_text(), boards)
        if new != path.read_text():
            from beo_bench.atomic import atomic_write_bytes

            atomic_write_bytes(path, new.encode())
            print(f"rewrote the tables of {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
