"""The regression gate: runs against a baseline, item by item (``beo-bench gate``), and the
baseline file it reads (``beo-bench baseline``); docs/benchmark.md, "A regression gate".

**What is compared.** Each run is paired with the baseline run of the same suite label
(suite, track and, when it is not the suite's own, sensor: ``pose-1dof@class-free``,
``tabletop~ideal``). The two must have scored the same items the same way: the same suite,
suite version, seed, track, sensor, object library version and suite record (image size,
field of view, classes, dataset identity, sensor model version...; the record's ``size``,
``description`` and ``item_timeout_s`` change no score and are not compared), and exactly
the same items. Anything else is refused (:class:`GateUsageError`, exit status 2) with the
flag that fixes it. The baseline is a run directory, a directory of runs (``all --runs``), or
a baseline file: the per-view values of every pairable metric of one or more runs (format
:data:`BASELINE_FORMAT` version :data:`BASELINE_VERSION`, :func:`baseline_json`), small
enough to commit.

**The test.** A gate makes one test per metric and backend, **pooled over every suite** it
gates that measures the metric: per metric, the per-view values as the summary counts them
(failures at their worst case, :func:`beo_bench.bench.compare.view_values`), paired on the
views both runs scored and summed per **unit**, an item of a suite (:func:`pool`: the runs
of one suite's tracks or sensors score the same items, so their views of an item are one
unit, and the sign-flip test's units are independent). The statistic is the mean over the
pooled views of B - A (the baseline is A). A metric is a **regression** when the run is
worse than the baseline by more than the metric's **margin** (:data:`MARGINS`: 5 deg of
mean rotation error, 1 cm of mean translation error, 5 points of class accuracy, 10 of pick
success...; a difference a practitioner would call a regression), tested by a one-sided
paired **sign-flip permutation test** over units of the differences less the margin
(:func:`beo_bench.stats.sign_flip_p`): under "worse by exactly the margin" each unit's
shifted difference is as likely negated; exact over every sign pattern up to
:data:`~beo_bench.stats.EXACT_MAX_ITEMS` units that differ, else
:data:`~beo_bench.stats.DEFAULT_PERMUTATIONS` seeded random patterns. The p-values of every
test one gate makes are corrected together by **Holm's** step-down method
(:func:`beo_bench.stats.holm`), so a
gate over unchanged code fails with probability at most ``alpha`` however many metrics it
tests. The direction is the metric's (``MetricSpec.higher_is_better``,
:mod:`beo_bench.bench.columns`): an improvement never fails the gate. The report also gives
the difference's 95% paired bootstrap interval over units (the figure ``beo-bench compare``
prints for one run) and, per suite, its own difference (not tested: what a failure points
at).

By default the gate tests the declared primary metrics (:data:`PRIMARY_METRICS`), for each
thing a backend gets wrong: rotation (the mean rotation error and the > 15 deg rate),
translation (the mean translation error), class (the class accuracy) and pick (pick
success); a suite joins each test whose metric it measures. Five tests rather than one per
suite: pooled, the smoke set's 126 items that score a pose (166 a class) count together,
and Holm divides alpha by five at most, not by the number of runs (issue 47 saw a 90 deg
turn of every estimate pass, its p of 0.065 made 1 by 16 tests; docs/ci.md, "What the
default gate catches", has what the gate catches now).
``--metrics`` tests others instead, pooled the same way; a suite that does not measure one
is left out of that test and listed in the report as skipped.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np

from beo_bench.atomic import atomic_write_bytes
from beo_bench.bench import compare
from beo_bench.bench.columns import BY_KEY, METRICS, MetricSpec, value_range
from beo_bench.bench.rows import scan_rows, span
from beo_bench.bench.rundir import (
    RESULTS_NAME,
    SUMMARY_NAME,
    ItemsIdentity,
    load_summary,
    sensor_tag_of,
    summary_size,
    track_of,
)
from beo_bench.errors import CorruptDataError, ThresholdError, UsageError
from beo_bench.stats import (
    DEFAULT_PERMUTATIONS,
    EXACT_MAX_ITEMS,
    ViewKey,
    holm,
    item_sums,
    ratio_interval,
    sign_flip_p,
    smallest_p,
)

BASELINE_FORMAT = "beo-bench-baseline"
BASELINE_VERSION = 1
"""The baseline file's ``format`` and ``version``: a reader refuses any other (a file of a
newer version may hold values this version would misread)."""
REPORT_FORMAT = "beo-bench-gate"
REPORT_VERSION = 2
"""2: a verdict per (backend, metric) pooled over suites, with its margin, suites and
skipped metrics (1: a verdict per suite and metric)."""
DEFAULT_ALPHA = 0.05
REGRESSION = "regression"
"""Worse than the baseline by more than the metric's margin (adjusted p at most alpha)."""
IMPROVEMENT = "improvement"
"""The difference's interval lies on the better side (shown; never fails, not corrected)."""
WORSE_WITHIN_MARGIN = "worse, within the margin"
"""The interval lies on the worse side, but the test does not find it beyond the margin."""
NO_DIFFERENCE = "no difference"


class GateUsageError(UsageError):
    """A gate asked for in a way that cannot work: runs that do not pair with the baseline,
    an unknown metric or none that a run measures, a damaged baseline file (exit status
    2)."""


class GateFailure(ThresholdError):
    """The gate found a regression (exit status 3); the reports are written first."""


class FailureRateError(ThresholdError):
    """A finished run whose share of failed views is above ``--max-failure-rate`` (exit
    status 3); its results are written first."""


# -- the metrics ----------------------------------------------------------------------------
@dataclass(frozen=True)
class GateMetric:
    """A metric the gate tests by default, and what it covers."""

    key: str
    """Its key in ``summary["metrics"]`` (a :class:`~beo_bench.bench.columns.MetricSpec`)."""
    covers: str
    """What a backend gets wrong that it sees: ``rotation``, ``translation``, ``class``,
    ``pick``."""


PRIMARY_METRICS: tuple[GateMetric, ...] = (
    GateMetric("rot_err_deg_mean", "rotation"),
    GateMetric("gross_err_rate", "rotation"),
    GateMetric("trans_err_cm_mean", "translation"),
    GateMetric("class_acc", "class"),
    GateMetric("pick_success", "pick"),
)
"""The gate's default tests, declared here and nowhere else (docs/benchmark.md, "A
regression gate"): each suite joins those whose metric it measures. The rotation has two,
because each misses what the other sees: the mean error, which a turn of views that are
already wrong moves and the > 15 deg rate does not; and the > 15 deg rate, which a small
bias of views that were right moves (a 10 deg turn of every estimate: 19 points of
``hbeo``'s smoke views more over 15 deg) while the mean, led by the views that are far off,
moves by 2 deg. Pooled over a hundred views, one view's 180 deg moves the mean by under 2
deg and the rate by one view: both under their margins."""

MARGINS: dict[str, float] = {
    # degrees: NOCS's tightest rotation threshold (5deg2cm)
    "rot_err_deg_mean": 5.0,
    # centimetres: half of NOCS's tightest translation threshold (2 cm), and an eighth of
    # the gripper's 8 cm opening
    "trans_err_cm_mean": 1.0,
    "mssd_cm_mean": 1.0,
    # rates, in points: one view in twenty; pick, one episode in ten (an episode's outcome
    # is also the physics', noisier than a view's score)
    "class_acc": 0.05,
    "gross_err_rate": 0.05,
    "acc_5deg2cm": 0.05,
    "acc_5deg5cm": 0.05,
    "acc_10deg2cm": 0.05,
    "acc_10deg5cm": 0.05,
    "iou3d_25": 0.05,
    "iou3d_50": 0.05,
    "iou3d_75": 0.05,
    "failure_rate": 0.05,
    "pick_success": 0.10,
    "target_found_rate": 0.10,
    # scores in [0, 1]: 0.05 of the range
    "ar_bop": 0.05,
    "ar_vsd": 0.05,
    "ar_mssd": 0.05,
    "ar_mspd": 0.05,
    "iou_mean": 0.05,
    "iou_cam_mean": 0.05,
    "fscore_mean": 0.05,
    # per cent of the true size
    "size_err_pct_mean": 5.0,
}
"""The margin of each metric, in its own unit (a rate's as a fraction): how much worse
than the baseline a run must be for the gate to call it a regression. A metric without one
(the EDT error, Chamfer distance, MSPD, the samples' diagnostics) is tested against no
margin: any worsening the test finds fails."""


def _check_declared() -> None:
    """Every gated metric has a spec that can be paired (a typo fails on import)."""
    bad = [k for k in (*MARGINS, *(m.key for m in PRIMARY_METRICS)) if not _pairable(k)]
    if bad:
        raise KeyError(f"gate metrics {bad} have no paired MetricSpec in bench.columns")


def _pairable(key: str) -> bool:
    m = BY_KEY.get(key)
    return m is not None and m.paired


def margin(key: str) -> float:
    """The margin of metric ``key`` (:data:`MARGINS`; 0 where none is declared)."""
    return MARGINS.get(key, 0.0)


def primary_keys() -> tuple[str, ...]:
    """The keys of :data:`PRIMARY_METRICS`, the metrics a gate tests by default."""
    return tuple(m.key for m in PRIMARY_METRICS)


def pairable_keys() -> tuple[str, ...]:
    """Every metric the gate can test: the means over views (medians and timings cannot be
    paired item by item)."""
    return tuple(m.key for m in METRICS if m.paired)


def metric_spec(key: str) -> MetricSpec:
    """The spec of a metric the gate can test; another key is a :class:`GateUsageError`."""
    m = BY_KEY.get(key)
    if m is None or not m.paired:
        raise GateUsageError(
            f"metric {key!r} cannot be gated (not a mean over views): give --metrics among "
            f"{', '.join(pairable_keys())}"
        )
    return m


def primary_metric(suite: str) -> str:
    """A suite's headline metric: its item kind's (``ItemKind.primary_metric``), for a
    registered suite or one made from it (a class subset, a user's dataset). The gate no
    longer tests it alone by default (:data:`PRIMARY_METRICS`, pooled over suites)."""
    from beo_bench.bench.kinds import get_kind
    from beo_bench.bench.suites import UnknownSuiteError, base_suite

    try:
        s = base_suite(suite)
    except UnknownSuiteError as e:
        raise GateUsageError(
            f"suite {suite!r} is not one this beo-bench knows ({e}), so it has no primary "
            "metric: give --metrics"
        ) from None
    return get_kind(s.kind).primary_metric(s)


_check_declared()


# -- a run as the gate reads it ---------------------------------------------------------------
@dataclass(frozen=True)
class ScoredRun:
    """A run, from its directory or from a baseline file: what identifies its items and
    their scoring, and each view's value of every pairable metric (NaN: not scored)."""

    source: str
    """Where it was read (a run directory, or ``FILE#label``), for messages."""
    label: str
    """``SUITE[@TRACK][~SENSOR]``: what pairs a run with its baseline."""
    identity: ItemsIdentity
    """What fixed its items and their scoring (a baseline's must be the same)."""
    backend: str
    """The backend and its options, as tables name them (``icp (starts=48)``)."""
    views: tuple[ViewKey, ...]
    """Every scored (item, view), sorted."""
    values: dict[str, dict[ViewKey, float]]
    git_commit: str | None = None

    @property
    def items(self) -> frozenset[int]:
        return frozenset(i for i, _ in self.views)

    @property
    def suite(self) -> str:
        return self.identity.suite


def suite_label(summary: dict[str, Any]) -> str:
    """``SUITE[@TRACK][~SENSOR]`` of a run's summary (the sensor only when it is not the
    suite's own, as the run's directory name has it)."""
    track = track_of(summary)
    text = f"{summary['suite']}@{track}" if track else str(summary["suite"])
    tag = sensor_tag_of(summary)
    return text + (f"~{tag}" if tag else "")


def _check_results(where: Path, summary: dict[str, Any]) -> None:
    """Refuse a run whose ``results.jsonl`` is damaged (:class:`CorruptDataError`, exit
    status 1): lines that do not parse, a torn last line, an item's rows incomplete or
    twice, or fewer items than its summary covers. Read past, the lost items would leave
    the test (and could flip its verdict) or read as a run of other items."""
    results = where / RESULTS_NAME
    if not results.is_file():
        return  # compare.run_from says so
    scan = scan_rows(results)
    damage = scan.report(results)
    size = summary_size(summary)
    if not damage and size is not None:
        lost = set(range(size)) - {r.item for r in scan.rows}
        if lost:
            damage = (
                f"{results}: holds no rows of {len(lost)} of the {size} items its summary "
                f"covers (items {span(lost)})"
            )
    if damage:
        raise CorruptDataError(
            f"{damage}: the results file is damaged, so the gate cannot pair its items; run "
            "the same `beo-bench run` command again with --resume (it scores the lost items "
            "again and rewrites the summary), then gate it"
        )


def scored_run(where: Path, summary: dict[str, Any]) -> ScoredRun:
    """The :class:`ScoredRun` of a run directory and its loaded summary (the rows of the
    items the summary covers)."""
    from beo_bench.bench.runs import backend_label

    _check_results(where, summary)
    run = compare.run_from(where, summary)
    values = {k: v for k, v in compare.view_values(run).items() if k in BY_KEY and BY_KEY[k].paired}
    prov = summary.get("provenance", {})
    return ScoredRun(
        source=str(where),
        label=suite_label(summary),
        identity=ItemsIdentity.of(summary),
        backend=backend_label(str(summary["backend"]), prov.get("backend_kwargs") or {}),
        views=tuple(sorted((int(r["item"]), int(r["view"])) for r in run.rows)),
        values=values,
        git_commit=prov.get("git_commit"),
    )


def find_runs(paths: Iterable[Path | str]) -> list[tuple[Path, dict[str, Any]]]:
    """The runs at ``paths``: each a run directory, its ``summary.json``, or a directory of
    run directories (``beo-bench all --runs``: every sub-directory holding a
    ``summary.json``). A path with no run is a :class:`GateUsageError`."""
    out: list[tuple[Path, dict[str, Any]]] = []
    for given in paths:
        p = Path(given)
        if p.is_file() or (p / SUMMARY_NAME).is_file():
            out.append(load_summary(p))
            continue
        if not p.is_dir():
            raise GateUsageError(
                f"{p} does not exist: give run directories, their summary.json, or the --runs "
                "directory of `beo-bench all`"
            )
        subs = sorted(d for d in p.iterdir() if (d / SUMMARY_NAME).is_file())
        if not subs:
            raise GateUsageError(
                f"{p} holds no run (no summary.json in it or in its sub-directories): give run "
                "directories, or the --runs directory of `beo-bench all`"
            )
        out += [load_summary(d) for d in subs]
    return out


def load_runs(paths: Iterable[Path | str]) -> list[ScoredRun]:
    """:func:`find_runs`, each read as a :class:`ScoredRun`."""
    return [scored_run(where, summary) for where, summary in find_runs(paths)]


# -- the baseline file -------------------------------------------------------------------------
def _number(x: float) -> float | None:
    """A value as the file holds it: NaN (not scored) as null; JSON has no NaN."""
    return float(x) if math.isfinite(x) else None


def baseline_entry(run: ScoredRun) -> dict[str, Any]:
    """One run as a baseline file holds it: its identity, its views per item (``views``:
    item -> view indices) and, per metric, each item's values in that order (``values``:
    metric -> item -> list; null where a view is not scored on it)."""
    per_item: dict[int, list[int]] = {}
    for item, view in run.views:
        per_item.setdefault(item, []).append(view)
    return {
        "label": run.label,
        "suite": run.identity.suite,
        "suite_version": run.identity.suite_version,
        "seed": run.identity.seed,
        "track": run.identity.track,
        "sensor": run.identity.sensor,
        "library_version": run.identity.library_version,
        "suite_record": run.identity.record,
        "backend": run.backend,
        "git_commit": run.git_commit,
        "views": {str(i): vs for i, vs in per_item.items()},
        "values": {
            key: {str(i): [_number(vals[(i, v)]) for v in vs] for i, vs in per_item.items()}
            for key, vals in sorted(run.values.items())
        },
    }


def baseline_json(runs: Sequence[ScoredRun]) -> dict[str, Any]:
    """The baseline file's content for ``runs`` (one entry each). Two runs of one suite
    label by one backend would be ambiguous: :class:`GateUsageError`."""
    seen: dict[tuple[str, str], str] = {}
    for r in runs:
        first = seen.setdefault((r.label, r.backend), r.source)
        if first != r.source:
            raise GateUsageError(
                f"{first} and {r.source} are both runs of {r.label} by {r.backend}: give one "
                "of them to `beo-bench baseline`"
            )
    return {
        "format": BASELINE_FORMAT,
        "version": BASELINE_VERSION,
        "runs": [baseline_entry(r) for r in runs],
    }


def write_baseline(runs: Sequence[ScoredRun], path: Path | str) -> Path:
    """Write the baseline file of ``runs`` at ``path`` (atomically: a CI job reading it
    sees the old file or the new one)."""
    path = Path(path)
    text = json.dumps(baseline_json(runs), separators=(",", ":"), sort_keys=False)
    path.parent.mkdir(parents=True, exist_ok=True)  # ci/baseline.json in a fresh checkout
    atomic_write_bytes(path, text + "\n")
    return path


def _bad_file(path: Path, why: str) -> GateUsageError:
    return GateUsageError(
        f"{path} is not a readable beo-bench baseline ({why}): write it again with "
        f"`beo-bench baseline RUN ... --out {path}`"
    )


def _item_order(i: str) -> tuple[int, str]:
    return (int(i), i) if i.lstrip("-").isdigit() else (0, i)


def _checked(key: str, item: str, x: Any) -> float:
    """A baseline value of metric ``key`` (null is read as NaN before): a number in the
    metric's range (:func:`beo_bench.bench.columns.value_range`), else a ValueError naming
    the item."""
    if isinstance(x, bool) or not isinstance(x, int | float):
        raise ValueError(f"{key} of item {item} is {x!r}, not a number")
    lo, hi = value_range(key)
    value = float(x)
    if not (math.isfinite(value) and lo <= value <= hi):
        raise ValueError(f"{key} of item {item} is {x!r}, outside its range [{lo:g}, {hi:g}]")
    return value


def _entry_run(path: Path, k: int, e: Any) -> ScoredRun:
    """Entry ``k`` of the baseline file ``path`` as a :class:`ScoredRun`."""
    if not isinstance(e, dict):
        raise _bad_file(path, f"run {k} is not an object")
    try:
        views = sorted((int(i), int(v)) for i, vs in e["views"].items() for v in vs)
        values: dict[str, dict[ViewKey, float]] = {}
        for key, per_item in e["values"].items():
            vals: dict[ViewKey, float] = {}
            missing = sorted(e["views"].keys() - per_item.keys(), key=_item_order)
            if missing:  # dropped silently, the item would leave the test and flip it
                raise ValueError(f"{key} has no values for item {missing[0]}, which it scored")
            for i, xs in per_item.items():
                order = e["views"][i]
                if len(xs) != len(order):
                    raise ValueError(
                        f"{key} of item {i} has {len(xs)} values for {len(order)} views"
                    )
                for v, x in zip(order, xs, strict=True):
                    vals[(int(i), int(v))] = math.nan if x is None else _checked(key, i, x)
            values[str(key)] = vals
        return ScoredRun(
            source=f"{path}#{e['label']}",
            label=str(e["label"]),
            identity=ItemsIdentity(
                suite=str(e["suite"]),
                suite_version=e["suite_version"],
                seed=e["seed"],
                track=e["track"],
                sensor=str(e["sensor"]),
                library_version=e["library_version"],
                record=dict(e["suite_record"]),
            ),
            backend=str(e["backend"]),
            views=tuple(views),
            values=values,
            git_commit=e.get("git_commit"),
        )
    except (KeyError, TypeError, ValueError, AttributeError) as err:
        raise _bad_file(path, f"run {k}: {type(err).__name__} {err}") from None


def read_baseline_file(path: Path | str) -> list[ScoredRun]:
    """The runs of a baseline file (:func:`write_baseline`). A file of another format or
    version, or a damaged one, is a :class:`GateUsageError` saying how to write it again."""
    path = Path(path)
    try:
        obj = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise _bad_file(path, f"{type(e).__name__}: {e}") from None
    if not isinstance(obj, dict) or obj.get("format") != BASELINE_FORMAT:
        raise _bad_file(path, f"its format is not {BASELINE_FORMAT!r}")
    if obj.get("version") != BASELINE_VERSION:
        raise GateUsageError(
            f"{path} is a baseline of format version {obj.get('version')!r}; this beo-bench "
            f"reads version {BASELINE_VERSION}: write it again with `beo-bench baseline RUN "
            f"... --out {path}` (or use the beo-bench that wrote it)"
        )
    runs = obj.get("runs")
    if not isinstance(runs, list) or not runs:
        raise _bad_file(path, "it holds no run")
    return [_entry_run(path, k, e) for k, e in enumerate(runs)]


def is_baseline_file(path: Path | str) -> bool:
    """Whether ``path`` is a file that is not a run's ``summary.json`` (so: read as a
    baseline file, which says what is wrong with it if it is not one)."""
    p = Path(path)
    return p.is_file() and p.name != SUMMARY_NAME


def load_baseline(path: Path | str) -> list[ScoredRun]:
    """The baseline runs at ``path``: a baseline file, or runs (:func:`find_runs`)."""
    if not Path(path).exists():
        raise GateUsageError(
            f"--baseline {path} does not exist: give a baseline file (write one with "
            "`beo-bench baseline RUN ... --out FILE`), a run directory or a directory of runs"
        )
    return read_baseline_file(path) if is_baseline_file(path) else load_runs([path])


# -- pairing runs with their baselines --------------------------------------------------------
def mismatch(run: ScoredRun, base: ScoredRun) -> str:
    """Why ``run`` cannot be gated against ``base`` ("" when it can), baseline's value
    first: their items' identities differ (:class:`~beo_bench.bench.rundir.ItemsIdentity`)."""
    diffs = base.identity.differences(run.identity)
    return "; ".join(f"{what} {b!r} (baseline) vs {a!r}" for what, b, a in diffs)


def check_pair(run: ScoredRun, base: ScoredRun) -> None:
    """Refuse a pair that did not score the same items the same way."""
    why = mismatch(run, base)
    if why:
        raise GateUsageError(
            f"cannot gate {run.source} against {base.source}: {why}. The gate needs runs of "
            "one suite, version, seed, track and sensor: run the same command as the "
            "baseline's run (same --suite, --track, --sensor, --seed), or write a new "
            "baseline with `beo-bench baseline`"
        )
    if run.items != base.items:
        raise GateUsageError(
            f"cannot gate {run.source} against {base.source}: the run scored items "
            f"{span(run.items)} ({len(run.items)}) and the baseline {span(base.items)} "
            f"({len(base.items)}): run it with --episodes {len(base.items)} (the baseline's "
            "items), or write a new baseline from a run of these items"
        )


def pair_runs(
    runs: Sequence[ScoredRun], baseline: Sequence[ScoredRun]
) -> tuple[list[tuple[ScoredRun, ScoredRun]], list[ScoredRun]]:
    """Each run with its baseline run (the one of its suite label; of those, the one by the
    same backend), checked (:func:`check_pair`), and the baseline runs no run was paired
    with. One run against one baseline run pairs them whatever their labels (so the
    refusal says what differs)."""
    if not runs:
        raise GateUsageError("no run to gate: give run directories or a --runs directory")
    if len(runs) == 1 and len(baseline) == 1:
        pairs = [(runs[0], baseline[0])]
    else:
        pairs = []
        for r in runs:
            found = [b for b in baseline if b.label == r.label]
            if len(found) > 1:
                found = [b for b in found if b.backend == r.backend]
            if len(found) != 1:
                held = ", ".join(sorted({f"{b.label} ({b.backend})" for b in baseline}))
                why = "no baseline run" if not found else "several baseline runs"
                raise GateUsageError(
                    f"{r.source}: {why} of {r.label} by {r.backend} (the baseline holds {held}): "
                    "gate the baseline's suites, or add this run to it with `beo-bench baseline`"
                )
            pairs.append((r, found[0]))
    used: dict[int, str] = {}
    for r, b in pairs:
        first = used.setdefault(id(b), r.source)
        if first != r.source:
            raise GateUsageError(
                f"{first} and {r.source} are both gated against {b.source}: give one run of "
                f"{b.label}"
            )
        check_pair(r, b)
    not_run = [b for b in baseline if id(b) not in used]
    return pairs, not_run


# -- the test -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class GateOptions:
    """How the gate tests (``beo-bench gate`` flags)."""

    metrics: tuple[str, ...] | None = None
    """``--metrics``: the metrics to test, each pooled over the suites that measure it
    (None: :data:`PRIMARY_METRICS`)."""
    alpha: float = DEFAULT_ALPHA
    """``--alpha``: the family-wise error rate of the whole gate (Holm)."""
    permutations: int = DEFAULT_PERMUTATIONS
    resamples: int = 1000
    """Bootstrap resamples of the reported interval (as ``compare``)."""
    seed: int = 0
    """Seeds the random sign patterns and the bootstrap: the same inputs give the same
    report."""

    def __post_init__(self) -> None:
        if not 0 < self.alpha < 1:
            raise GateUsageError(f"alpha {self.alpha}: give --alpha in (0, 1), e.g. 0.05")
        for key in self.metrics or ():
            metric_spec(key)

    def keys(self) -> tuple[str, ...]:
        """The metrics tested: ``metrics``, else the primary ones."""
        return self.metrics or primary_keys()


UnitKey = tuple[str, str, int]
"""A test's unit: (suite, its seed, item). The runs of one suite in its tracks or under its
sensors score the same items (item i depends on the seed and i alone), so their views of an
item are one unit: summed, the units are independent, as the sign-flip test needs."""


@dataclass(frozen=True)
class SuiteDiff:
    """One run's part of a pooled test: its own means and difference (shown, not tested:
    what a failure points at)."""

    suite: str
    """The run's suite label (``pose-1dof@class-free``)."""
    baseline: float
    value: float
    diff: float
    n_items: int
    n_views: int

    def to_json(self) -> dict[str, Any]:
        return {
            "suite": self.suite,
            "baseline": self.baseline,
            "value": self.value,
            "diff": self.diff,
            "items": self.n_items,
            "views": self.n_views,
        }


@dataclass(frozen=True)
class Skipped:
    """A metric the gate was asked for (``--metrics``) that a run's suite does not measure:
    left out of that metric's test, and said so in every report."""

    suite: str
    metric: str
    why: str

    def to_json(self) -> dict[str, Any]:
        return {"suite": self.suite, "metric": self.metric, "why": self.why}


@dataclass(frozen=True)
class Pool:
    """One metric over one backend's runs: per unit (:data:`UnitKey`), the sums of the
    baseline's (``a``) and the run's (``b``) values over the views both scored, and how many
    views that is (``n``); and each run's part."""

    a: np.ndarray
    b: np.ndarray
    n: np.ndarray
    parts: tuple[SuiteDiff, ...]


def pool(
    pairs: Sequence[tuple[ScoredRun, ScoredRun]], key: str
) -> tuple[Pool | None, list[Skipped]]:
    """Metric ``key`` over the (run, baseline) ``pairs``, summed per unit (None when no pair
    measures it), and the runs left out, with why."""
    units: dict[UnitKey, list[float]] = {}
    parts, skipped = [], []
    for run, base in pairs:
        missing = [r.source for r in (base, run) if key not in r.values]
        if missing:
            skipped.append(Skipped(run.label, key, f"{' and '.join(missing)} has no {key}"))
            continue
        sums = item_sums(base.values[key], run.values[key])
        if not sums:
            why = "no view scored on it in both runs (the class of a class-given run is not)"
            skipped.append(Skipped(run.label, key, why))
            continue
        for item, (x, y, k) in sums.items():
            u = units.setdefault((run.suite, str(run.identity.seed), item), [0.0, 0.0, 0.0])
            u[0], u[1], u[2] = u[0] + x, u[1] + y, u[2] + k
        xa, xb, views = (sum(s[j] for s in sums.values()) for j in range(3))
        parts.append(SuiteDiff(run.label, xa / views, xb / views, (xb - xa) / views,
                               len(sums), int(views)))  # fmt: skip
    if not units:
        return None, skipped
    arr = np.array([units[u] for u in sorted(units)], dtype=np.float64)
    return Pool(arr[:, 0], arr[:, 1], arr[:, 2], tuple(parts)), skipped


@dataclass(frozen=True)
class Verdict:
    """One test: a metric of one backend's runs, pooled over the suites that measure it;
    the runs (B) against their baselines (A)."""

    metric: str
    label: str
    higher_is_better: bool
    margin: float
    """How much worse B must be to be a regression (:data:`MARGINS`), in the metric's
    unit."""
    backend: str
    baseline_backend: str
    baseline: float
    value: float
    diff: float
    """``value - baseline``: the mean over the views both scored, every suite's together."""
    lo: float
    hi: float
    """The 95% paired bootstrap interval of ``diff`` (units resampled)."""
    p: float
    """The one-sided sign-flip test's p-value that B is worse by more than the margin."""
    p_holm: float
    """``p`` adjusted by Holm over every test of the gate."""
    outcome: str
    """:data:`REGRESSION`, :data:`IMPROVEMENT`, :data:`WORSE_WITHIN_MARGIN` or
    :data:`NO_DIFFERENCE`."""
    n_items: int
    """Units: items of a suite (a suite's tracks and sensors score the same items)."""
    n_views: int
    parts: tuple[SuiteDiff, ...] = ()
    """Each run's own difference, in the order gated."""

    @property
    def regression(self) -> bool:
        return self.outcome == REGRESSION

    @property
    def spec(self) -> MetricSpec:
        return BY_KEY[self.metric]

    @property
    def suites(self) -> tuple[str, ...]:
        """The suite labels pooled."""
        return tuple(p.suite for p in self.parts)

    def where(self) -> str:
        """What was pooled, in words: the suite label of one run, else how many runs."""
        return self.parts[0].suite if len(self.parts) == 1 else f"{len(self.parts)} runs"

    def to_json(self) -> dict[str, Any]:
        return {
            "metric": self.metric,
            "label": self.label,
            "higher_is_better": self.higher_is_better,
            "margin": self.margin,
            "backend": self.backend,
            "baseline_backend": self.baseline_backend,
            "suites": list(self.suites),
            "baseline": self.baseline,
            "value": self.value,
            "diff": self.diff,
            "ci95": [self.lo, self.hi],
            "p": self.p,
            "p_holm": self.p_holm,
            "outcome": self.outcome,
            "items": self.n_items,
            "views": self.n_views,
            "by_suite": [p.to_json() for p in self.parts],
        }

    def line(self) -> str:
        """One line of it, as the failure message and the terminal say it."""
        m = self.spec
        return (
            f"{self.backend} {m.label} over {self.where()}: {m.format(self.baseline)} -> "
            f"{m.format(self.value)} ({m.format_diff(self.diff)}, 95% [{m.format_diff(self.lo)}"
            f", {m.format_diff(self.hi)}], margin {m.format(self.margin)}, p = "
            f"{self.p_holm:.3g} after Holm, {self.n_items} items)"
        )


@dataclass(frozen=True)
class CannotFail:
    """A test, or a suite in it, too small to fail the gate: the smallest p its items allow
    (:func:`smallest_p`) is above the smallest threshold Holm's correction gives a test
    (``alpha / tests``), so a regression of it alone, however large, passes."""

    backend: str
    metric: str
    suite: str
    """The suite label, or ``... (the whole test)`` when the whole pooled test cannot fail."""
    n_items: int
    p_min: float
    threshold: float

    def line(self) -> str:
        return (
            f"{self.backend} {BY_KEY[self.metric].label} of {self.suite}: {self.n_items} items "
            f"allow p >= {self.p_min:.3g}, above the corrected threshold {self.threshold:.3g} "
            "(alpha / tests): a regression confined to it cannot fail the gate; gate it alone "
            "(fewer --metrics) or with more items (--episodes)"
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "backend": self.backend,
            "metric": self.metric,
            "suite": self.suite,
            "items": self.n_items,
            "p_min": self.p_min,
            "threshold": self.threshold,
        }


@dataclass(frozen=True)
class GateReport:
    """What a gate found: a verdict per (backend, metric), in the order tested."""

    verdicts: tuple[Verdict, ...]
    options: GateOptions
    baseline: str
    """Where the baseline was read."""
    not_run: tuple[str, ...] = field(default=())
    """Labels of the baseline's runs that no run was gated against (skipped, not failed)."""
    skipped: tuple[Skipped, ...] = field(default=())
    """The ``--metrics`` a run's suite does not measure (left out of that test)."""

    @property
    def regressions(self) -> tuple[Verdict, ...]:
        return tuple(v for v in self.verdicts if v.regression)

    @property
    def passed(self) -> bool:
        return not self.regressions

    @property
    def cannot_fail(self) -> tuple[CannotFail, ...]:
        """The tests, and each test's suites, whose item count cannot reach significance
        after the correction (:class:`CannotFail`): a pass says nothing about them."""
        if not self.verdicts:
            return ()
        o = self.options
        threshold = o.alpha / len(self.verdicts)  # Holm's first (smallest) threshold
        out = []
        for v in self.verdicts:
            whole = smallest_p(v.n_items, o.permutations)
            if whole > threshold:
                out.append(CannotFail(v.backend, v.metric, f"{v.where()} (the whole test)",
                                      v.n_items, whole, threshold))  # fmt: skip
                continue
            for part in v.parts:
                p_min = max(whole, smallest_p(part.n_items, o.permutations))
                if p_min > threshold:
                    out.append(CannotFail(v.backend, v.metric, part.suite, part.n_items, p_min,
                                          threshold))  # fmt: skip
        return tuple(out)

    def method(self) -> str:
        o = self.options
        return (
            "one-sided paired sign-flip permutation test over items, each metric pooled over "
            "the suites that measure it, of the run's worsening less the metric's margin "
            f"(exact up to {EXACT_MAX_ITEMS} differing items, else {o.permutations} seeded "
            f"patterns), Holm-corrected over {len(self.verdicts)} tests at alpha {o.alpha:g}; "
            f"intervals: 95% paired bootstrap, {o.resamples} resamples of items"
        )

    def to_json(self) -> dict[str, Any]:
        o = self.options
        return {
            "format": REPORT_FORMAT,
            "version": REPORT_VERSION,
            "passed": self.passed,
            "baseline": self.baseline,
            "method": self.method(),
            "alpha": o.alpha,
            "seed": o.seed,
            "metrics": list(o.metrics) if o.metrics else "primary",
            "regressions": len(self.regressions),
            "verdicts": [v.to_json() for v in self.verdicts],
            "skipped": [s.to_json() for s in self.skipped],
            "not_run": list(self.not_run),
            "cannot_fail": [c.to_json() for c in self.cannot_fail],
        }

    def junit_xml(self) -> str:
        """JUnit XML: a ``testsuite`` per backend, a ``testcase`` per metric (a ``failure``
        element on a regression); the metrics a suite does not measure (``--metrics``) and
        the baseline's runs that were not gated as skipped test cases, so a job page shows
        what was not tested."""
        root = ET.Element("testsuites", name="beo-bench gate")
        by_backend: dict[str, list[Verdict]] = {}
        for v in self.verdicts:
            by_backend.setdefault(v.backend, []).append(v)
        for backend, vs in by_backend.items():
            fails = sum(v.regression for v in vs)
            ts = ET.SubElement(root, "testsuite", name=backend, tests=str(len(vs)),
                               failures=str(fails), errors="0", skipped="0")  # fmt: skip
            props = ET.SubElement(ts, "properties")
            ET.SubElement(props, "property", name="baseline", value=vs[0].baseline_backend)
            for v in vs:
                tc = ET.SubElement(ts, "testcase", classname=f"beo-bench.gate.{backend}",
                                   name=v.metric, time="0")  # fmt: skip
                if v.regression:
                    f = ET.SubElement(
                        tc, "failure", type=REGRESSION, message=f"regression: {v.line()}"
                    )
                    f.text = self.method() + "\n" + "\n".join(_part_lines(v))
                else:
                    ET.SubElement(tc, "system-out").text = f"{v.outcome}: {v.line()}"
        skips = [(s.suite, s.metric, s.why) for s in self.skipped]
        skips += [(label, "run", "the baseline has this suite; no run of it was gated")
                  for label in self.not_run]  # fmt: skip
        skips += [(c.suite, c.metric, f"cannot fail: {c.line()}") for c in self.cannot_fail]
        for suite, name, why in skips:
            ts = ET.SubElement(root, "testsuite", name=suite, tests="1", failures="0",
                               errors="0", skipped="1")  # fmt: skip
            tc = ET.SubElement(ts, "testcase", classname=f"beo-bench.gate.{suite}", name=name)
            ET.SubElement(tc, "skipped", message=why)
        root.set("tests", str(len(self.verdicts) + len(skips)))
        root.set("failures", str(len(self.regressions)))
        root.set("skipped", str(len(skips)))
        ET.indent(root)
        return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, "unicode") + "\n"

    def markdown(self) -> str:
        """A Markdown summary for a CI job's page (GitHub's step summary, a merge request
        note): the tests, then each suite's own difference, then what was not tested."""
        n = len(self.regressions)
        head = "pass" if self.passed else f"{n} regression{'s' * (n != 1)}"
        lines = [
            f"### beo-bench gate: {head}",
            "",
            f"Against the baseline `{self.baseline}`: {self.method()}. A regression is a "
            "metric worse than the baseline by more than its margin, with adjusted p at most "
            "alpha.",
            "",
            "| backend (baseline) | metric | suites | baseline | run | run - baseline | 95% "
            "interval | margin | p (Holm) | verdict |",
            "|---|---|---|---:|---:|---:|---|---:|---:|---|",
        ]
        for v in self.verdicts:
            m = v.spec
            verdict = f"**{v.outcome}**" if v.regression else v.outcome
            lines.append(
                f"| {v.backend} ({v.baseline_backend}) | {m.label} | {v.where()} | "
                f"{m.format(v.baseline)} | {m.format(v.value)} | {m.format_diff(v.diff)} | "
                f"[{m.format_diff(v.lo)}, {m.format_diff(v.hi)}] | {m.format(v.margin)} | "
                f"{v.p_holm:.3g} | {verdict} |"
            )
        lines += [
            "",
            "Each suite's own difference (not tested: the tests above pool them):",
            "",
            "| backend | metric | suite | baseline | run | run - baseline | items |",
            "|---|---|---|---:|---:|---:|---:|",
        ]
        for v in self.verdicts:
            m = v.spec
            lines += [
                f"| {v.backend} | {m.label} | {p.suite} | {m.format(p.baseline)} | "
                f"{m.format(p.value)} | {m.format_diff(p.diff)} | {p.n_items} |"
                for p in v.parts
            ]
        if self.skipped:
            said = "; ".join(f"{s.suite}: {s.metric} ({s.why})" for s in self.skipped)
            lines += ["", f"Skipped (the suite does not measure the metric): {said}."]
        if self.not_run:
            lines += ["", f"Not gated (in the baseline, no run given): {', '.join(self.not_run)}."]
        if self.cannot_fail:
            lines += ["", "**Cannot fail** (too few items for the corrected threshold; a pass "
                      "says nothing about them):", ""]  # fmt: skip
            lines += [f"- {c.line()}" for c in self.cannot_fail]
        return "\n".join(lines) + "\n"

    def text(self) -> str:
        """The terminal's report: a line per verdict (a regression's suites under it),
        what was skipped, then the outcome."""
        lines = [f"gate against {self.baseline}: {self.method()}"]
        for v in self.verdicts:
            lines.append(f"  {v.outcome:<13} {v.line()}")
            if v.regression:
                lines += [f"      {line}" for line in _part_lines(v)]
        lines += [f"  skipped        {s.suite}: {s.metric} ({s.why})" for s in self.skipped]
        if self.not_run:
            lines.append(f"  not gated (no run given): {', '.join(self.not_run)}")
        blind = self.cannot_fail
        lines += [f"  CANNOT FAIL   {c.line()}" for c in blind]
        n = len(self.regressions)
        lines.append(
            f"gate: pass ({len(self.verdicts)} tests, no regression)"
            if self.passed
            else f"gate: {n} regression{'s' * (n != 1)} in {len(self.verdicts)} tests"
        )
        if blind:
            lines[-1] += (
                f"; WARNING: {len(blind)} test{'s' * (len(blind) != 1)} or suite"
                f"{'s' * (len(blind) != 1)} cannot fail it (CANNOT FAIL above)"
            )
        return "\n".join(lines)


def _part_lines(v: Verdict) -> list[str]:
    """Each suite's own difference in a test, a line each."""
    m = v.spec
    return [
        f"{p.suite}: {m.format(p.baseline)} -> {m.format(p.value)} ({m.format_diff(p.diff)}, "
        f"{p.n_items} items)"
        for p in v.parts
    ]


def _outcome(v_diff: float, lo: float, hi: float, p_holm: float, alpha: float,
             higher_is_better: bool) -> str:  # fmt: skip
    if p_holm <= alpha and v_diff != 0:
        return REGRESSION
    side = compare.verdict(lo, hi, higher_is_better)  # the interval's side, as compare reads it
    return {"better": IMPROVEMENT, "worse": WORSE_WITHIN_MARGIN}.get(side, NO_DIFFERENCE)


def gate(
    runs: Sequence[ScoredRun],
    baseline: Sequence[ScoredRun],
    options: GateOptions | None = None,
    baseline_source: str = "",
) -> GateReport:
    """Gate ``runs`` against ``baseline``: pair them (:func:`pair_runs`); per backend and
    metric (``options.metrics``, default :data:`PRIMARY_METRICS`), pool the runs that
    measure it (:func:`pool`) and test whether the runs are worse by more than the metric's
    margin; correct the p-values by Holm and give each its verdict. Nothing is raised for
    a regression (see :attr:`GateReport.passed`); a gate that finds nothing to test is a
    :class:`GateUsageError`."""
    o = options or GateOptions()
    pairs, not_run = pair_runs(runs, baseline)
    by_backend: dict[str, list[tuple[ScoredRun, ScoredRun]]] = {}
    for run, base in pairs:
        by_backend.setdefault(run.backend, []).append((run, base))
    tests: list[tuple[str, list[tuple[ScoredRun, ScoredRun]], str, Pool, float]] = []
    skipped: list[Skipped] = []
    for backend, group in by_backend.items():
        for key in o.keys():
            pooled, left_out = pool(group, key)
            if o.metrics:  # asked for by name: say which suites lack it (the primary
                skipped += left_out  # metrics are each suite's that measures them)
            if pooled is None:
                continue
            sign = -1.0 if BY_KEY[key].higher_is_better else 1.0
            worse = sign * (pooled.b - pooled.a) - margin(key) * pooled.n
            p = sign_flip_p(worse, o.permutations, o.seed, alternative="greater")
            tests.append((backend, group, key, pooled, p))
    if not tests:
        have = sorted({k for r, b in pairs for k in r.values.keys() & b.values.keys()})
        said = "; ".join(f"{s.suite}: {s.metric} ({s.why})" for s in skipped)
        raise GateUsageError(
            f"nothing to gate: no run measures {', '.join(o.keys())}"
            + (f" ({said})" if said else "")
            + f": give --metrics among {', '.join(have)}"
        )
    adjusted = holm([p for *_, p in tests])
    verdicts = []
    for (backend, group, key, pooled, p), p_adj in zip(tests, adjusted, strict=True):
        m = BY_KEY[key]
        d = pooled.b - pooled.a
        views = float(pooled.n.sum())
        diff = float(d.sum()) / views
        lo, hi = ratio_interval(d, pooled.n, o.resamples, o.seed, tail=2.5)
        verdicts.append(
            Verdict(
                metric=key,
                label=m.label,
                higher_is_better=m.higher_is_better,
                margin=margin(key),
                backend=backend,
                baseline_backend=", ".join(dict.fromkeys(b.backend for _, b in group)),
                baseline=float(pooled.a.sum()) / views,
                value=float(pooled.b.sum()) / views,
                diff=diff,
                lo=lo,
                hi=hi,
                p=p,
                p_holm=p_adj,
                outcome=_outcome(diff, lo, hi, p_adj, o.alpha, m.higher_is_better),
                n_items=len(pooled.n),
                n_views=int(views),
                parts=pooled.parts,
            )
        )
    return GateReport(
        tuple(verdicts), o, baseline_source, tuple(b.label for b in not_run), tuple(skipped)
    )


# -- writing the reports ------------------------------------------------------------------------
STEP_SUMMARY_ENV = "GITHUB_STEP_SUMMARY"
"""The file GitHub Actions shows on a job's page: the Markdown summary is appended to it."""


def write_reports(
    report: GateReport,
    json_path: Path | str | None = None,
    junit_path: Path | str | None = None,
    markdown_path: Path | str | None = None,
) -> list[Path]:
    """Write the asked-for reports (each atomically) and append the Markdown summary to
    ``$GITHUB_STEP_SUMMARY`` when it is set; returns the files written."""
    written = []
    for path, text in (
        (json_path, lambda: json.dumps(report.to_json(), indent=1) + "\n"),
        (junit_path, report.junit_xml),
        (markdown_path, report.markdown),
    ):
        if path is not None:
            Path(path).parent.mkdir(parents=True, exist_ok=True)  # out/gate.xml: out/ may be new
            atomic_write_bytes(Path(path), text())
            written.append(Path(path))
    summary = os.environ.get(STEP_SUMMARY_ENV)
    if summary:
        # appended, not replaced: the file is the job's, and other steps write to it too
        with open(summary, "a", encoding="utf-8") as f:
            f.write(report.markdown())
        written.append(Path(summary))
    return written


# -- the failure rate of finished runs --------------------------------------------------------
def check_failure_rate(runs: Sequence[tuple[Path, Any]], limit: float) -> None:
    """Raise :class:`FailureRateError` naming every run (directory, summary) whose share of
    failed views (``failures / n``: one view an item in isolated suites and ``pick``) is
    above ``limit``."""
    over = []
    for where, s in runs:
        n, failed = int(s["n"]), int(s["failures"])
        if n and failed / n > limit:
            over.append(f"{where} ({failed} of {n} views failed, {failed / n:.1%})")
    if over:
        raise FailureRateError(
            f"failure rate above --max-failure-rate {limit:g} in {'; '.join(over)}; the results "
            "are written: the reasons are in each run's results.jsonl (`failure`) and "
            "summary.json (`failure_kinds`)"
        )
