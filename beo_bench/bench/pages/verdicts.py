"""A page's sections (one per seed and items within a track) and their paired verdicts: each
method against the baselines, and the preregistered primary comparisons.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from beo_bench.bench import compare, rundir
from beo_bench.bench.columns import (
    DEGRADATION_KEYS,
    VERDICT_KEYS,
    markdown_table,
    spec,
    verdict_cell,
)
from beo_bench.bench.pages.entries import (
    BASELINES,
    DIAGNOSTIC,
    TRACK_ORDER,
    Row,
    _kwargs,
    is_bound,
    is_scored_file,
    items,
    label,
    suite_seed,
    suite_size,
)
from beo_bench.bench.pages.tables import _as_rows, _name, _ordered, _value
from beo_bench.bench.runs import options_label
from beo_bench.errors import UsageError


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
