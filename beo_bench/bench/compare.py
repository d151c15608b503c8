"""Paired comparisons of two runs over the same items (``beo-bench compare A B``).

Two runs of one suite (same version, track and seed) score the same items, so the fair
question is not whether their intervals overlap but how B's score differs from A's *on the
same items*: :func:`paired` takes, per headline metric, the difference B - A of the means
over the views both runs scored, and a percentile bootstrap 95% interval of it that
resamples **items** (the unit the suite draws: a tabletop item is a scene with several
views, which are not independent), each resample keeping A's and B's views of an item
together. The verdict is ``better`` or ``worse`` (for B, in the metric's direction, see
:mod:`beo_bench.bench.columns`) when the interval excludes 0, else ``no difference``.

The per-view values are the summary's: a failed view counts at its worst case (rotation
180 deg, so a gross error and a NOCS miss; translation, MSSD, EDT, Chamfer at their caps;
IoU, F-score, class and pick 0: :func:`beo_bench.bench.summary.view_values`, the one
definition), so a backend that fails on hard views cannot look better for it.
Medians and timings are not paired (a median of differences is not a difference of
medians, and timings depend on the machine).

Each verdict is one metric's own, **not corrected for multiple comparisons**: of the dozen
or so metrics a compare pairs, one may say ``worse`` by chance. The pass/fail check for CI is
``beo-bench gate`` (:mod:`beo_bench.bench.gate`: Holm-corrected over every metric it tests,
exit status 3 on a regression); ``beo-bench compare`` prints :data:`UNCORRECTED_NOTE` under
its verdicts to say so.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from beo_bench.bench.columns import METRICS, MetricSpec, spec
from beo_bench.bench.rows import read_rows, span
from beo_bench.bench.rundir import RESULTS_NAME, ItemsIdentity, load_summary, summary_size, track_of
from beo_bench.errors import UsageError
from beo_bench.stats import per_item_sums, ratio_interval

CLASS_FREE = "class-free"
VERDICTS = ("better", "worse", "no difference")
UNCORRECTED_NOTE = (
    "note: each verdict is per metric and NOT corrected for multiple comparisons (with many "
    "metrics, one may say worse by chance); the pass/fail check for CI is `beo-bench gate` "
    "(Holm-corrected, exit status 3 on a regression)"
)


class ComparisonWarning(UserWarning):
    """Two compared runs that hold different items: only the common ones are paired."""


# -- loading runs ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Run:
    """A finished run: its directory, summary and result rows (the items it summarised)."""

    path: Path
    summary: dict[str, Any]
    rows: tuple[dict[str, Any], ...]

    @property
    def items(self) -> set[int]:
        return {int(r["item"]) for r in self.rows}


def load_run(path: Path | str) -> Run:
    """The run at ``path`` (a run directory or its ``summary.json``), with the rows of the
    items its summary covers (results files may hold more: a run summarised over a prefix).
    A summary without its ``results.jsonl`` cannot be paired: :class:`UsageError`."""
    return run_from(*load_summary(path))


def run_from(where: Path, summary: dict[str, Any]) -> Run:
    """A :class:`Run` from a directory and its already loaded summary."""
    results = where / RESULTS_NAME
    if not results.is_file():
        raise UsageError(
            f"{where} has no {RESULTS_NAME}, so its items cannot be paired with another run's: "
            "give the run directory that holds it (or `compare --table` for the summaries alone)"
        )
    size = summary_size(summary)
    rows = [r for r in read_rows(results) if size is None or r["item"] < size]
    rows.sort(key=lambda r: (r["item"], r["view"]))
    return Run(where, summary, tuple(rows))


# -- what may be compared ------------------------------------------------------------------------
def hint_unused(summary: dict[str, Any]) -> bool:
    """A class-free run of a backend that cannot use the class hint: it would score the
    same in the class-given track, so it stands in that track too."""
    return track_of(summary) == CLASS_FREE and summary.get("uses_class_hint") is False


def mismatch(a: dict[str, Any], b: dict[str, Any], across_sensors: bool = False) -> str:
    """Why two runs cannot be paired ("" when they can): their items' identities differ
    (:class:`~beo_bench.bench.rundir.ItemsIdentity`: suite, version, seed, track, sensor,
    object library, suite record). A run that does not use the class hint matches either
    track (see :func:`hint_unused`); ``across_sensors``: runs of the same items under two
    sensors pair (a robustness comparison)."""
    ta, tb = track_of(a), track_of(b)
    either = None not in (ta, tb) and (hint_unused(a) or hint_unused(b))
    diffs = ItemsIdentity.of(a).differences(
        ItemsIdentity.of(b), track=not either, sensor=not across_sensors
    )
    return "; ".join(f"{what} {x!r} vs {y!r}" for what, x, y in diffs)


def check_comparable(
    a: Run | dict[str, Any],
    b: Run | dict[str, Any],
    names: str = "",
    across_sensors: bool = False,
) -> None:
    """Raise :class:`UsageError` unless the two runs can be paired (:func:`mismatch`)."""
    sa = a.summary if isinstance(a, Run) else a
    sb = b.summary if isinstance(b, Run) else b
    why = mismatch(sa, sb, across_sensors)
    if why:
        raise UsageError(
            f"cannot pair {names or 'these runs'}: {why}. A paired comparison needs runs of "
            "one suite, suite version, track, sensor and seed (the same items, scored the same "
            "way); use `beo-bench compare --table` to list runs side by side"
        )


# -- per-view values -------------------------------------------------------------------------
def view_values(run: Run) -> dict[str, dict[tuple[int, int], float]]:
    """Per summary metric that is a mean over views, each (item, view)'s value as the
    summary counts it (:func:`beo_bench.bench.summary.view_values`: failures at their worst
    case; NaN where a view is not scored on it)."""
    from beo_bench.bench.suites import base_suite
    from beo_bench.bench.summary import view_values as summary_values

    rows = list(run.rows)
    keys = [(int(r["item"]), int(r["view"])) for r in rows]
    per_metric = summary_values(base_suite(run.summary["suite"]), rows)
    return {m: dict(zip(keys, (float(x) for x in v), strict=True)) for m, v in per_metric.items()}


def pairable(a: dict[str, Any], b: dict[str, Any]) -> list[MetricSpec]:
    """The headline metrics both summaries have that can be paired, in table order."""
    both = set(a.get("metrics", {})) & set(b.get("metrics", {}))
    return [m for m in METRICS if m.key in both and m.paired]


# -- the paired bootstrap ------------------------------------------------------------------------
@dataclass(frozen=True)
class PairedResult:
    """B - A on one metric, over the items both runs scored."""

    key: str
    label: str
    a: float
    """A's mean over the paired views."""
    b: float
    """B's mean over the same views."""
    diff: float
    """``b - a``."""
    lo: float
    hi: float
    """The bootstrap interval of ``diff`` (items resampled)."""
    verdict: str
    """For B against A: ``better``, ``worse`` or ``no difference`` (the interval holds 0)."""
    n_items: int
    """Items with a view that both runs scored on this metric."""
    n_views: int
    """Views that both runs scored on this metric."""
    confidence: float = 0.95

    @property
    def spec(self) -> MetricSpec:
        return spec(self.key)


def paired_json(
    r: PairedResult, pairing: str, track: str | None, method: str, baseline: str
) -> dict[str, Any]:
    """One paired result as ``<suite>_paired.json`` holds it (verdicts and ablations)."""
    return {
        "pairing": pairing,
        "track": track,
        "method": method,
        "baseline": baseline,
        "metric": r.key,
        "baseline_value": r.a,
        "method_value": r.b,
        "diff": r.diff,
        "ci95": [r.lo, r.hi],
        "verdict": r.verdict,
        "items": r.n_items,
        "views": r.n_views,
    }


def verdict(lo: float, hi: float, higher_is_better: bool) -> str:
    """``better`` / ``worse`` when the interval ``[lo, hi]`` of B - A excludes 0."""
    if lo > 0:
        return "better" if higher_is_better else "worse"
    if hi < 0:
        return "worse" if higher_is_better else "better"
    return "no difference"


def paired_metric(
    a_values: dict[tuple[int, int], float],
    b_values: dict[tuple[int, int], float],
    key: str,
    n_resamples: int = 1000,
    confidence: float = 0.95,
    seed: int = 0,
) -> PairedResult | None:
    """B - A on metric ``key`` from each run's per-view values of it (:func:`view_values`),
    None when no view has it in both. The mean is over views (as the summary's), the
    resampling over items: each resample draws items with replacement and takes the ratio
    of the drawn items' summed differences to their view count (the cluster bootstrap of a
    mean over views)."""
    sa, sb, n = per_item_sums(a_values, b_values)
    if not len(n):
        return None
    d = sb - sa
    diff = float(d.sum() / n.sum())
    lo, hi = ratio_interval(d, n, n_resamples, seed, tail=100 * (1 - confidence) / 2)
    m = spec(key)
    return PairedResult(
        key=key,
        label=m.label,
        a=float(sa.sum() / n.sum()),
        b=float(sb.sum() / n.sum()),
        diff=diff,
        lo=lo,
        hi=hi,
        verdict=verdict(lo, hi, m.higher_is_better),
        n_items=len(n),
        n_views=int(n.sum()),
        confidence=confidence,
    )


def paired_runs(
    a: Run,
    b: Run,
    keys: Iterable[str] | None = None,
    n_resamples: int = 1000,
    confidence: float = 0.95,
    seed: int = 0,
    across_sensors: bool = False,
) -> list[PairedResult]:
    """B - A per metric (``keys``, default: :func:`pairable`) over the common items.
    Runs that cannot be paired (:func:`check_comparable`; ``across_sensors``: two sensors'
    runs of the same items pair): :class:`UsageError`; runs with different items: a
    :class:`ComparisonWarning`, then the common items are compared."""
    check_comparable(a, b, f"{a.path} and {b.path}", across_sensors)
    common = a.items & b.items
    if not common:
        raise UsageError(
            f"{a.path} and {b.path} have no item in common (items {span(a.items)} and "
            f"{span(b.items)}): run both over the same items (the same --episodes)"
        )
    if a.items != b.items:
        warnings.warn(
            f"{a.path} has {len(a.items)} items and {b.path} {len(b.items)}: comparing the "
            f"{len(common)} they have in common",
            ComparisonWarning,
            stacklevel=2,
        )
    wanted = [m.key for m in pairable(a.summary, b.summary)] if keys is None else list(keys)
    va, vb = view_values(a), view_values(b)
    out = []
    for key in wanted:
        if key not in va or key not in vb:
            continue
        r = paired_metric(va[key], vb[key], key, n_resamples, confidence, seed)
        if r is not None:
            out.append(r)
    return out


def paired(
    a_dir: Path | str,
    b_dir: Path | str,
    keys: Iterable[str] | None = None,
    n_resamples: int = 1000,
    confidence: float = 0.95,
    seed: int = 0,
) -> list[PairedResult]:
    """B - A per headline metric for the runs in ``a_dir`` and ``b_dir`` (directories or
    their ``summary.json``): see :func:`paired_runs`."""
    return paired_runs(load_run(a_dir), load_run(b_dir), keys, n_resamples, confidence, seed)


# -- text --------------------------------------------------------------------------------------
def format_paired(a: Run, b: Run, results: Sequence[PairedResult]) -> str:
    """The plain-text report of :func:`paired_runs`."""
    from beo_bench.bench.runs import backend_label

    def name(r: Run) -> str:
        s = r.summary
        kwargs = s.get("provenance", {}).get("backend_kwargs") or {}
        return f"{backend_label(s['backend'], kwargs)} ({r.path})"

    common = len(a.items & b.items)
    lines = [
        f"paired: B = {name(b)} against A = {name(a)}",
        f"  {common} items in common (A has {len(a.items)}, B {len(b.items)}); B - A with a "
        "95% bootstrap interval that resamples items (rates in percentage points)",
    ]
    head = f"  {'metric':<22} {'A':>9} {'B':>9} {'B - A':>9}  {'95% interval':<22} verdict"
    lines += [head, "  " + "-" * (len(head) - 2)]
    for r in results:
        m = r.spec
        ci = f"[{m.format_diff(r.lo)}, {m.format_diff(r.hi)}]"
        lines.append(
            f"  {m.label:<22} {m.format(r.a):>9} {m.format(r.b):>9} "
            f"{m.format_diff(r.diff):>9}  {ci:<22} {r.verdict}"
        )
    if not results:
        lines.append("  (no metric that both runs measured can be paired)")
    return "\n".join(lines)
