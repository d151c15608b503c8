"""The pose tables: the headline, the class-given track, the prior and shape-selection ablations,
the component swaps and the rest prior.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from beo_bench.bench.columns import spec
from beo_bench.bench.doctables.boards import (
    METHODS,
    Boards,
    Cell,
    Fig,
    MissingFigureError,
    Pair,
    PendingSuiteError,
    Row,
    Table,
    _diff,
    _table,
    backends,
    deg,
    fmt_unit,
    num,
    pct,
)
from beo_bench.bench.pages.verdicts import (
    Primary,
)
from beo_bench.bench.runs import backend_label

# -- the tables ------------------------------------------------------------------------------
_POSE = ("rot_err_deg_mean", "gross_err_rate")
HEADLINE_CELLS: tuple[tuple[str, str | None, tuple[str, ...]], ...] = (
    ("known-pose", None, ("class_acc",)),
    ("pose-1dof", "class-free", _POSE),
    ("pose-3dof", "class-free", (*_POSE, "class_acc")),
    ("tabletop", None, (*_POSE, "class_acc")),
    ("pick", None, ("pick_success",)),
)
"""The headline's figures, by (suite, track, metrics), which its note pairs."""
# the headline's cells: those figures, the IoU beside the class at a known pose (not paired)
_HEADLINE_COLS = tuple(
    Cell(tuple(Fig(k, suite=s) for k in keys + ("iou_mean",) * (s == "known-pose")))
    for s, _, keys in HEADLINE_CELLS
)


def modes_note(b: Boards) -> str:
    """What the headline says of its two MDN rows, which differ by a little everywhere:
    per figure, the posterior against the likelihood paired on the same views, as a finding
    only where the page's Holm-corrected primary comparison says so; an uncorrected interval
    that excludes 0 is named as such, not as a finding (issue 47)."""
    post, lik = "hbeo-mdn-posterior", "hbeo-mdn-likelihood"
    same, found, loose = 0, [], []
    for suite, track, keys in HEADLINE_CELLS:
        for key in keys:
            try:
                got = b.primary(suite, Primary(post, lik, key, track, ""))
                p = got if got is not None else b.pair(suite, post, lik, key, track)
            except MissingFigureError:  # the page, or the pair on it, is not there (yet)
                continue
            what = f"`{suite}` {spec(key).label}"
            diff = _diff(p, fmt_unit(key)[1])
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


headline = Table(
    ("backend", "`known-pose` class acc., IoU", "`pose-1dof` mean, > 15 deg",
     "`pose-3dof` mean, > 15 deg, class acc.", "`tabletop` mean, > 15 deg, class acc.",
     "`pick` success"),
    (*backends((*METHODS, "random"), cells=_HEADLINE_COLS),
     Row("`oracle`", "oracle", cells=(*_HEADLINE_COLS[:-1], Cell(
         (*_HEADLINE_COLS[-1].figs, Fig("pick_success", suite="pick", name="oracle (mesh=false)")),
         "{} ({} planning on its voxels)")))),
    note=modes_note,
)  # fmt: skip
"""Every backend on every suite (the pose suites' class-free track)."""

# the dissertation's own protocol first (chapter 3's top-down views at 1-DOF, Figure 3.6; its
# ModelNet10 classes at 3-DOF, Figure 4.3), then ours
_CLASS_GIVEN = ("modelnet10-1dof", "modelnet10-3dof", "pose-1dof", "pose-1dof+modelnet10",
                "pose-3dof", "pose-3dof-ood")  # fmt: skip
class_given = Table(
    ("suite, class given", "`beo` mean, > 15 deg", "`icp-plain`", "`icp`",
     "`beo` - `icp-plain`: mean; > 15 deg", "`beo` - `icp`: mean; > 15 deg"),
    tuple(Row(Cell((Fig("n"),), f"`{s}` ({{}} views)"), "beo", s, "class-given",
              when=(Fig("n"),)) for s in _CLASS_GIVEN),
    cols=(*(Cell(tuple(Fig(k, name=n) for k in _POSE)) for n in ("beo", "icp-plain", "icp")),
          *(Cell(tuple(Pair(k, baseline=n) for k in _POSE), "{}; {}")
            for n in ("icp-plain", "icp"))),
    empty=f"none of {', '.join(_CLASS_GIVEN)} has a class-given `beo` row",
)  # fmt: skip
"""BEO against the dissertation's plain ICP and ours, the class given (Figures 3.6, 4.3);
the suites not in this version's leaderboards left out (docs/reference-models.md)."""


def _uniform_prior(track: str, *keys: str) -> Row:
    """``beo`` with a uniform P(r) against with the prior: both, and the paired difference."""
    pairs = [Pair(k, track=track, baseline="beo") for k in keys]
    return Row(Cell((replace(pairs[0], value="items", fmt=str),), f"{track} ({{}} views)"),
               "beo (pose_prior=false)", "pose-3dof",
               cells=tuple(Cell(tuple(replace(p, value=v) for p in pairs))
                           for v in ("baseline_value", "method_value", "diff")))  # fmt: skip


beo_prior = Table(
    ("`pose-3dof`", "with the prior", "uniform P(r)", "uniform - prior [95%]"),
    (_uniform_prior("class-given", *_POSE), _uniform_prior("class-free", *_POSE, "class_acc")),
)
"""BEO with the suites' viewpoint prior against a uniform P(r) (eq. 3.22)."""


def mdn_prior_table(suite: str) -> Table:
    """The table of HBEO-MDN's posterior (with eq. 5.6's silhouette prior) against its
    likelihood on ``suite``, class-free, paired on the same views (the same samples: both
    modes seed them by the crop); N = 100 where the campaign runs it (pose-3dof)."""
    rank = functools.partial(num, digits=1)
    rows: list[Row] = []
    for n in (25, 100):
        opt = "" if n == 25 else " (samples=100)"
        post, lik = f"hbeo-mdn-posterior{opt}", f"hbeo-mdn-likelihood{opt}"
        at = () if n == 25 else (Fig("n", name=post),)
        rows += [
            Row(f"N = {n}, {label}", post, track="class-free", when=at, cells=tuple(
                replace(p, value=v) for v in ("baseline_value", "method_value", "diff")))
            for label, p in (("mean error", Pair("rot_err_deg_mean", baseline=lik)),
                             ("> 15 deg", Pair("gross_err_rate", baseline=lik)),
                             ("rank of the best sample (0: first)",
                              Pair("sample_best_rank_mean", rank, baseline=lik)))
        ]  # fmt: skip
        # the samples themselves are the same in both modes: what the best one errs
        best = Fig("sample_best_err_deg_mean", name=post)
        rows.append(Row(f"N = {n}, best sample's error", when=at, cells=(best, best, "-")))
        # how far the samples lie from the estimate each mode picks (median angle), then
        # on the views the pick got wrong (> 15 deg) alone: what the samples held there
        for label, key, fmt in (
            ("samples' spread (median angle to the estimate)", "sample_spread_deg_mean", deg),
            ("gross errors: rank of the best sample", "sample_best_rank_gross_mean", rank),
            ("gross errors with a sample within 15 deg", "sample_near_true_gross_rate", pct),
            ("gross errors that are half turns", "half_turn_gross_rate", pct),
        ):
            both = (Fig(key, fmt, name=lik), Fig(key, fmt, name=post))
            rows.append(Row(f"N = {n}, {label}", when=(*at, *both), cells=(*both, "-")))
    head = (f"`{suite}`, class-free", "likelihood", "posterior", "posterior - likelihood [95%]")
    return Table(head, tuple(rows), suite=suite)


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


_SWAP_BASES = ("hbeo", "hbeo-mdn-posterior", "icp")
swap = Table(
    ("backend", "pick success", "true class", "true pose and size", "true shape",
     "oracle on voxels"),
    tuple(Row(f"`{base}`", base, cells=(
        Fig("pick_success"),
        # a swap not run at this suite version (the backend's own row is): "-", as the page
        # has no row of it; the prose beside the table says which
        *(Cell((Fig("pick_success", name=sw), Pair("pick_success", name=sw, baseline=base,
                                                   value="shift")), "{} ({})", (Fig("n", name=sw),))
          for sw in (f'swap (base="{base}", truth="{t}")' for t in ("class", "pose", "shape"))),
        Fig("pick_success", name="oracle (mesh=false)"))) for base in _SWAP_BASES),
    suite="pick",
)  # fmt: skip
"""Where each backend's pick gap comes from: one estimated component swapped for the truth."""


REST_PRIOR_SENSOR = "ideal"
"""The sensor the rest prior's tabletop controls ran under (the campaign block's line)."""


_REST = tuple(
    Row(f"`{n}`", f"{n} (pose_prior=false)", cells=(
        Pair("rot_err_deg_mean", str, baseline=n, value="items", sensor=REST_PRIOR_SENSOR),
        *(Cell(tuple(Pair(k, baseline=n, value=v, sensor=REST_PRIOR_SENSOR)
                     for v in ("baseline_value", "method_value")), "{} -> {}")
          for k in ("rot_err_deg_mean", "gross_err_rate", "class_acc")),
        # the table's direction is with - without: the ablation's, negated
        Pair("rot_err_deg_mean", baseline=n, sign=-1, sensor=REST_PRIOR_SENSOR)))
    for n in ("beo", "icp", "icp-plain")
)  # fmt: skip
rest_prior = Table(
    ("backend", "scenes", "rot. error mean, with -> without", "> 15 deg", "class acc.",
     "with - without, mean [95%]"), _REST, suite="tabletop",
)  # fmt: skip
"""``tabletop``: each method that takes the rest prior against itself without it
(``pose_prior=false``), paired on the scenes both scored, under :data:`REST_PRIOR_SENSOR`."""
