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

**The test.** Per metric: the per-view values as the summary counts them (failures at their
worst case, :func:`beo_bench.bench.compare.view_values`), paired on the views both runs
scored and summed per item (:func:`beo_bench.bench.compare.per_item_sums`). The statistic
is the mean over views of B - A (the baseline is A). Its two-sided p-value is a paired
**sign-flip permutation test** over items (:func:`sign_flip_p`): under "no difference" the
two runs' values of an item are exchangeable, so each item's summed difference is as likely
negated; exact over every sign pattern up to :data:`EXACT_MAX_ITEMS` items that differ,
else :data:`DEFAULT_PERMUTATIONS` seeded random patterns. The p-values of every test one
gate makes (each suite's metrics) are corrected together by **Holm's** step-down method
(:func:`holm`), so a gate over unchanged code fails with probability at most ``alpha``
however many suites and metrics it tests. A metric is a **regression** when its adjusted
p-value is at most ``alpha`` and its difference goes the wrong way for the metric's
direction (``MetricSpec.higher_is_better``, :mod:`beo_bench.bench.columns`): an
improvement never fails the gate. The report also gives the difference's 95% paired
bootstrap interval (:func:`beo_bench.bench.compare.paired_metric`, items resampled), the
same figure ``beo-bench compare`` prints.

By default each suite is judged on one metric, its item kind's primary one
(:func:`primary_metric`): the class accuracy where the pose is given (``known-pose``) and in
``tabletop``, the > 15 deg rate in the other pose suites, pick success in ``pick``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from statistics import NormalDist
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np

from beo_bench.atomic import atomic_write_bytes
from beo_bench.bench import compare
from beo_bench.bench.columns import BY_KEY, METRICS, MetricSpec
from beo_bench.errors import ThresholdError, UsageError

BASELINE_FORMAT = "beo-bench-baseline"
BASELINE_VERSION = 1
"""The baseline file's ``format`` and ``version``: a reader refuses any other (a file of a
newer version may hold values this version would misread)."""
REPORT_FORMAT = "beo-bench-gate"
REPORT_VERSION = 1
UNSCORED_RECORD_KEYS = ("size", "description", "item_timeout_s")
"""Suite record fields that change no score (the number of items is compared item by item
instead)."""
EXACT_MAX_ITEMS = 16
"""Up to this many items with a non-zero difference the sign-flip test enumerates every
pattern (2^16 = 65,536: milliseconds); above it, random patterns."""
DEFAULT_PERMUTATIONS = 10_000
"""Random sign patterns above :data:`EXACT_MAX_ITEMS` items: the p-value's Monte Carlo
error is then at most 0.005 (at p = 0.5; 0.002 near p = 0.05)."""
DEFAULT_ALPHA = 0.05
REGRESSION = "regression"
IMPROVEMENT = "improvement"
NO_DIFFERENCE = "no difference"

ViewKey = tuple[int, int]


class GateUsageError(UsageError):
    """A gate asked for in a way that cannot work: runs that do not pair with the baseline,
    a metric a suite does not measure, a damaged baseline file (exit status 2)."""


class GateFailure(ThresholdError):
    """The gate found a regression (exit status 3); the reports are written first."""


class FailureRateError(ThresholdError):
    """A finished run whose share of failed views is above ``--max-failure-rate`` (exit
    status 3); its results are written first."""


# -- the metrics ----------------------------------------------------------------------------
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
    """The metric a suite is gated on by default: its item kind's
    (``ItemKind.primary_metric``), for a registered suite or one made from it (a class
    subset, a user's dataset)."""
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


# -- a run as the gate reads it ---------------------------------------------------------------
@dataclass(frozen=True)
class ScoredRun:
    """A run, from its directory or from a baseline file: what identifies its items and
    their scoring, and each view's value of every pairable metric (NaN: not scored)."""

    source: str
    """Where it was read (a run directory, or ``FILE#label``), for messages."""
    label: str
    """``SUITE[@TRACK][~SENSOR]``: what pairs a run with its baseline."""
    suite: str
    suite_version: int | None
    seed: int | None
    track: str | None
    sensor: str
    library_version: int | None
    record: dict[str, Any]
    """The suite record (``provenance["suite"]``) without :data:`UNSCORED_RECORD_KEYS`."""
    backend: str
    """The backend and its options, as tables name them (``icp (starts=48)``)."""
    views: tuple[ViewKey, ...]
    """Every scored (item, view), sorted."""
    values: dict[str, dict[ViewKey, float]]
    git_commit: str | None = None

    @property
    def items(self) -> frozenset[int]:
        return frozenset(i for i, _ in self.views)


def suite_label(summary: dict[str, Any]) -> str:
    """``SUITE[@TRACK][~SENSOR]`` of a run's summary (the sensor only when it is not the
    suite's own, as the run's directory name has it)."""
    track = compare.track_of(summary)
    text = f"{summary['suite']}@{track}" if track else str(summary["suite"])
    tag = compare.sensor_tag_of(summary)
    return text + (f"~{tag}" if tag else "")


def _comparable_record(record: dict[str, Any]) -> dict[str, Any]:
    from beo_bench.bench.suites import upgrade_record

    return {k: v for k, v in upgrade_record(record).items() if k not in UNSCORED_RECORD_KEYS}


def scored_run(where: Path, summary: dict[str, Any]) -> ScoredRun:
    """The :class:`ScoredRun` of a run directory and its loaded summary (the rows of the
    items the summary covers)."""
    from beo_bench.bench.runs import backend_label

    run = compare.run_from(where, summary)
    values = {k: v for k, v in compare.view_values(run).items() if k in BY_KEY and BY_KEY[k].paired}
    prov = summary.get("provenance", {})
    version = summary.get("suite_version")
    return ScoredRun(
        source=str(where),
        label=suite_label(summary),
        suite=str(summary["suite"]),
        suite_version=int(version) if isinstance(version, int) else None,
        seed=summary.get("seed"),
        track=compare.track_of(summary),
        sensor=compare.sensor_of(summary),
        library_version=prov.get("library_version"),
        record=_comparable_record(prov.get("suite", {})),
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
        if p.is_file() or (p / compare.SUMMARY_NAME).is_file():
            out.append(compare.load_summary(p))
            continue
        if not p.is_dir():
            raise GateUsageError(
                f"{p} does not exist: give run directories, their summary.json, or the --runs "
                "directory of `beo-bench all`"
            )
        subs = sorted(d for d in p.iterdir() if (d / compare.SUMMARY_NAME).is_file())
        if not subs:
            raise GateUsageError(
                f"{p} holds no run (no summary.json in it or in its sub-directories): give run "
                "directories, or the --runs directory of `beo-bench all`"
            )
        out += [compare.load_summary(d) for d in subs]
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
        "suite": run.suite,
        "suite_version": run.suite_version,
        "seed": run.seed,
        "track": run.track,
        "sensor": run.sensor,
        "library_version": run.library_version,
        "suite_record": run.record,
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


def _entry_run(path: Path, k: int, e: Any) -> ScoredRun:
    """Entry ``k`` of the baseline file ``path`` as a :class:`ScoredRun`."""
    if not isinstance(e, dict):
        raise _bad_file(path, f"run {k} is not an object")
    try:
        views = sorted((int(i), int(v)) for i, vs in e["views"].items() for v in vs)
        values: dict[str, dict[ViewKey, float]] = {}
        for key, per_item in e["values"].items():
            vals: dict[ViewKey, float] = {}
            for i, xs in per_item.items():
                order = e["views"][i]
                if len(xs) != len(order):
                    raise ValueError(
                        f"{key} of item {i} has {len(xs)} values for {len(order)} views"
                    )
                for v, x in zip(order, xs, strict=True):
                    vals[(int(i), int(v))] = math.nan if x is None else float(x)
            values[str(key)] = vals
        return ScoredRun(
            source=f"{path}#{e['label']}",
            label=str(e["label"]),
            suite=str(e["suite"]),
            suite_version=e["suite_version"],
            seed=e["seed"],
            track=e["track"],
            sensor=str(e["sensor"]),
            library_version=e["library_version"],
            record=dict(e["suite_record"]),
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
    return p.is_file() and p.name != compare.SUMMARY_NAME


def load_baseline(path: Path | str) -> list[ScoredRun]:
    """The baseline runs at ``path``: a baseline file, or runs (:func:`find_runs`)."""
    if not Path(path).exists():
        raise GateUsageError(
            f"--baseline {path} does not exist: give a baseline file (write one with "
            "`beo-bench baseline RUN ... --out FILE`), a run directory or a directory of runs"
        )
    return read_baseline_file(path) if is_baseline_file(path) else load_runs([path])


# -- pairing runs with their baselines --------------------------------------------------------
def _span(items: frozenset[int]) -> str:
    return f"{min(items)}..{max(items)}" if items else "none"


def mismatch(run: ScoredRun, base: ScoredRun) -> str:
    """Why ``run`` cannot be gated against ``base`` ("" when it can), baseline's value
    first."""
    diffs = [
        f"{what} {b!r} (baseline) vs {a!r}"
        for what, a, b in (
            ("suite", run.suite, base.suite),
            ("suite version", run.suite_version, base.suite_version),
            ("seed", run.seed, base.seed),
            ("track", run.track, base.track),
            ("sensor", run.sensor, base.sensor),
        )
        if a != b
    ]
    if None not in (run.library_version, base.library_version) and (
        run.library_version != base.library_version
    ):
        diffs.append(f"object library version {base.library_version!r} vs {run.library_version!r}")
    said = {"name", "version", "seed", "track", "sensor"}
    keys = sorted((run.record.keys() | base.record.keys()) - said)
    diffs += [
        f"suite record {k} {base.record.get(k)!r} vs {run.record.get(k)!r}"
        for k in keys
        if run.record.get(k) != base.record.get(k)
    ]
    return "; ".join(diffs)


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
            f"{_span(run.items)} ({len(run.items)}) and the baseline {_span(base.items)} "
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
def sign_flip_p(
    diffs: np.ndarray, permutations: int = DEFAULT_PERMUTATIONS, seed: int = 0
) -> float:
    """The two-sided p-value of the paired sign-flip permutation test that the items'
    summed differences ``diffs`` (B - A per item) have mean 0: the share of sign patterns
    whose |sum| is at least the observed one. Items whose difference is exactly 0 are the
    same under a flip, so only the others are flipped; up to :data:`EXACT_MAX_ITEMS` of them
    every pattern is enumerated (an exact test), beyond that ``permutations`` random
    patterns drawn from ``seed`` and the observed one ((1 + hits) / (1 + permutations), a
    valid p-value)."""
    d = np.asarray(diffs, dtype=np.float64)
    d = d[d != 0]
    if not len(d):
        return 1.0
    observed = abs(float(d.sum()))
    # the same terms summed in another order differ in the last bits: a pattern that gives
    # the observed |sum| must count as reaching it
    tol = 1e-9 * float(np.abs(d).sum())
    k = len(d)
    if k <= EXACT_MAX_ITEMS:
        patterns = np.arange(2**k, dtype=np.int64)[:, None] >> np.arange(k) & 1
        sums = np.abs((1 - 2 * patterns) @ d)
        return float(np.mean(sums >= observed - tol))
    rng = np.random.default_rng(seed)
    hits, left = 0, int(permutations)
    while left:  # in blocks: 10,000 patterns of 1,000 items would be 80 MB at once
        n = min(left, 1000)
        signs = rng.integers(0, 2, size=(n, k)) * 2 - 1
        hits += int(np.count_nonzero(np.abs(signs @ d) >= observed - tol))
        left -= n
    return (1 + hits) / (1 + int(permutations))


def holm(pvalues: Sequence[float]) -> list[float]:
    """Holm's step-down adjusted p-values: the k-th smallest (from 0) times ``m - k``, made
    non-decreasing in that order and capped at 1. Rejecting where the adjusted value is at
    most alpha keeps the family-wise error rate at most alpha, under any dependence
    between the tests."""
    m = len(pvalues)
    out = [1.0] * m
    running = 0.0
    for rank, i in enumerate(sorted(range(m), key=lambda j: pvalues[j])):
        running = max(running, min(1.0, (m - rank) * float(pvalues[i])))
        out[i] = running
    return out


@dataclass(frozen=True)
class GateOptions:
    """How the gate tests (``beo-bench gate`` flags)."""

    metrics: tuple[str, ...] | None = None
    """``--metrics``: the metrics of every suite (None: each suite's primary metric)."""
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


@dataclass(frozen=True)
class Verdict:
    """One metric of one suite: the run (B) against its baseline (A)."""

    suite: str
    """The suite label (``pose-1dof@class-free``)."""
    metric: str
    label: str
    higher_is_better: bool
    backend: str
    baseline_backend: str
    baseline: float
    value: float
    diff: float
    """``value - baseline``: the mean over the views both scored."""
    lo: float
    hi: float
    """The 95% paired bootstrap interval of ``diff``."""
    p: float
    """The sign-flip test's two-sided p-value."""
    p_holm: float
    """``p`` adjusted by Holm over every test of the gate."""
    outcome: str
    """:data:`REGRESSION`, :data:`IMPROVEMENT` or :data:`NO_DIFFERENCE`."""
    n_items: int
    n_views: int

    @property
    def regression(self) -> bool:
        return self.outcome == REGRESSION

    @property
    def spec(self) -> MetricSpec:
        return BY_KEY[self.metric]

    def to_json(self) -> dict[str, Any]:
        return {
            "suite": self.suite,
            "metric": self.metric,
            "label": self.label,
            "higher_is_better": self.higher_is_better,
            "backend": self.backend,
            "baseline_backend": self.baseline_backend,
            "baseline": self.baseline,
            "value": self.value,
            "diff": self.diff,
            "ci95": [self.lo, self.hi],
            "p": self.p,
            "p_holm": self.p_holm,
            "outcome": self.outcome,
            "items": self.n_items,
            "views": self.n_views,
        }

    def line(self) -> str:
        """One line of it, as the failure message and the terminal say it."""
        m = self.spec
        return (
            f"{self.suite} {m.label}: {m.format(self.baseline)} -> {m.format(self.value)} "
            f"({m.format_diff(self.diff)}, 95% [{m.format_diff(self.lo)}, "
            f"{m.format_diff(self.hi)}], p = {self.p_holm:.3g} after Holm, {self.n_items} items)"
        )


@dataclass(frozen=True)
class GateReport:
    """What a gate found: a verdict per (suite, metric), in the order tested."""

    verdicts: tuple[Verdict, ...]
    options: GateOptions
    baseline: str
    """Where the baseline was read."""
    not_run: tuple[str, ...] = field(default=())
    """Labels of the baseline's runs that no run was gated against (skipped, not failed)."""

    @property
    def regressions(self) -> tuple[Verdict, ...]:
        return tuple(v for v in self.verdicts if v.regression)

    @property
    def passed(self) -> bool:
        return not self.regressions

    def method(self) -> str:
        o = self.options
        return (
            "paired sign-flip permutation test over items (exact up to "
            f"{EXACT_MAX_ITEMS} differing items, else {o.permutations} seeded patterns), "
            f"Holm-corrected over {len(self.verdicts)} tests at alpha {o.alpha:g}; "
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
            "not_run": list(self.not_run),
        }

    def junit_xml(self) -> str:
        """JUnit XML: a ``testsuite`` per suite label, a ``testcase`` per metric (a
        ``failure`` element on a regression); the baseline's runs that were not gated as
        skipped test cases, so a job page shows that they were not tested."""
        root = ET.Element("testsuites", name="beo-bench gate")
        by_suite: dict[str, list[Verdict]] = {}
        for v in self.verdicts:
            by_suite.setdefault(v.suite, []).append(v)
        for suite, vs in by_suite.items():
            fails = sum(v.regression for v in vs)
            ts = ET.SubElement(
                root,
                "testsuite",
                name=suite,
                tests=str(len(vs)),
                failures=str(fails),
                errors="0",
                skipped="0",
            )
            props = ET.SubElement(ts, "properties")
            ET.SubElement(props, "property", name="backend", value=vs[0].backend)
            ET.SubElement(props, "property", name="baseline", value=vs[0].baseline_backend)
            for v in vs:
                tc = ET.SubElement(
                    ts, "testcase", classname=f"beo-bench.gate.{suite}", name=v.metric, time="0"
                )
                if v.regression:
                    f = ET.SubElement(
                        tc, "failure", type=REGRESSION, message=f"regression: {v.line()}"
                    )
                    f.text = self.method()
                else:
                    ET.SubElement(tc, "system-out").text = f"{v.outcome}: {v.line()}"
        for label in self.not_run:
            ts = ET.SubElement(
                root, "testsuite", name=label, tests="1", failures="0", errors="0", skipped="1"
            )
            tc = ET.SubElement(ts, "testcase", classname=f"beo-bench.gate.{label}", name="run")
            ET.SubElement(
                tc, "skipped", message="the baseline has this suite; no run of it was gated"
            )
        total = len(self.verdicts) + len(self.not_run)
        root.set("tests", str(total))
        root.set("failures", str(len(self.regressions)))
        root.set("skipped", str(len(self.not_run)))
        ET.indent(root)
        return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, "unicode") + "\n"

    def markdown(self) -> str:
        """A Markdown summary for a CI job's page (GitHub's step summary, a merge request
        note)."""
        n = len(self.regressions)
        head = "pass" if self.passed else f"{n} regression{'s' * (n != 1)}"
        lines = [
            f"### beo-bench gate: {head}",
            "",
            f"Against the baseline `{self.baseline}`: {self.method()}. A regression is a "
            "metric whose adjusted p is at most alpha and whose difference goes the wrong way.",
            "",
            "| suite | backend (baseline) | metric | baseline | run | run - baseline | 95% "
            "interval | p (Holm) | verdict |",
            "|---|---|---|---:|---:|---:|---|---:|---|",
        ]
        for v in self.verdicts:
            m = v.spec
            verdict = f"**{v.outcome}**" if v.regression else v.outcome
            lines.append(
                f"| {v.suite} | {v.backend} ({v.baseline_backend}) | {m.label} | "
                f"{m.format(v.baseline)} | {m.format(v.value)} | {m.format_diff(v.diff)} | "
                f"[{m.format_diff(v.lo)}, {m.format_diff(v.hi)}] | {v.p_holm:.3g} | {verdict} |"
            )
        if self.not_run:
            lines += ["", f"Not gated (in the baseline, no run given): {', '.join(self.not_run)}."]
        return "\n".join(lines) + "\n"

    def text(self) -> str:
        """The terminal's report: a line per verdict, then the outcome."""
        lines = [f"gate against {self.baseline}: {self.method()}"]
        lines += [f"  {v.outcome:<13} {v.line()}" for v in self.verdicts]
        if self.not_run:
            lines.append(f"  not gated (no run given): {', '.join(self.not_run)}")
        n = len(self.regressions)
        lines.append(
            f"gate: pass ({len(self.verdicts)} tests, no regression)"
            if self.passed
            else f"gate: {n} regression{'s' * (n != 1)} in {len(self.verdicts)} tests"
        )
        return "\n".join(lines)


def _outcome(diff: float, p_holm: float, alpha: float, higher_is_better: bool) -> str:
    if p_holm > alpha or diff == 0:
        return NO_DIFFERENCE
    return IMPROVEMENT if (diff > 0) == higher_is_better else REGRESSION


def gate(
    runs: Sequence[ScoredRun],
    baseline: Sequence[ScoredRun],
    options: GateOptions | None = None,
    baseline_source: str = "",
) -> GateReport:
    """Gate ``runs`` against ``baseline``: pair them (:func:`pair_runs`), test each suite's
    metrics (``options.metrics``, default its primary one), correct the p-values by Holm
    and give each its verdict. Nothing is raised for a regression: see
    :attr:`GateReport.passed`."""
    o = options or GateOptions()
    pairs, not_run = pair_runs(runs, baseline)
    tests: list[tuple[ScoredRun, ScoredRun, compare.PairedResult, float]] = []
    for run, base in pairs:
        keys = o.metrics or (primary_metric(run.suite),)
        for key in keys:
            metric_spec(key)
            missing = [r.source for r in (base, run) if key not in r.values]
            if missing:
                have = sorted(set(run.values) & set(base.values))
                raise GateUsageError(
                    f"{' and '.join(missing)} has no metric {key!r} (suite {run.label}): give "
                    f"--metrics among {', '.join(have)}"
                )
            a, b = base.values[key], run.values[key]
            r = compare.paired_metric(a, b, key, o.resamples, 0.95, o.seed)
            if r is None:
                raise GateUsageError(
                    f"{run.label}: no view scored on {key!r} in both {base.source} and "
                    f"{run.source} (the class of a class-given run is not scored): choose "
                    "other --metrics"
                )
            sa, sb, _ = compare.per_item_sums(a, b)
            tests.append((run, base, r, sign_flip_p(sb - sa, o.permutations, o.seed)))
    adjusted = holm([p for *_, p in tests])
    verdicts = []
    for (run, base, r, p), p_adj in zip(tests, adjusted, strict=True):
        m = BY_KEY[r.key]
        verdicts.append(
            Verdict(
                suite=run.label,
                metric=r.key,
                label=m.label,
                higher_is_better=m.higher_is_better,
                backend=run.backend,
                baseline_backend=base.backend,
                baseline=r.a,
                value=r.b,
                diff=r.diff,
                lo=r.lo,
                hi=r.hi,
                p=p,
                p_holm=p_adj,
                outcome=_outcome(r.diff, p_adj, o.alpha, m.higher_is_better),
                n_items=r.n_items,
                n_views=r.n_views,
            )
        )
    return GateReport(tuple(verdicts), o, baseline_source, tuple(b.label for b in not_run))


# -- what n items can tell -----------------------------------------------------------------------
Z95 = NormalDist().inv_cdf(0.975)
"""The two-sided 95% normal quantile (1.96)."""


def rate_half_width(rate: float, n: int) -> float:
    """The half-width of the 95% interval of a rate (a class accuracy, a > 15 deg rate, pick
    success) measured on ``n`` items: ``1.96 sqrt(rate (1 - rate) / n)``, what the
    summary's bootstrap over items approaches for one view an item."""
    return Z95 * math.sqrt(rate * (1 - rate) / n)


def paired_half_width(discordant: float, n: int) -> float:
    """The half-width of the 95% interval of the paired difference of two rates on ``n``
    items when a share ``discordant`` of the items is right in one run and wrong in the
    other, and no difference on the whole: each item's difference is then +-1 on that share,
    0 elsewhere, of variance ``discordant``, so ``1.96 sqrt(discordant / n)``. Items both
    runs get right or both get wrong cost nothing: pairing is why a gate needs fewer items
    than two intervals that must not overlap."""
    return Z95 * math.sqrt(discordant / n)


def detectable_difference(discordant: float, n: int, power: float = 0.8) -> float:
    """The smallest paired difference of two rates that a two-sided 5% test on ``n`` items
    finds with probability ``power`` when a share ``discordant`` of the items differ
    (normal approximation): the test rejects past ``1.96 sqrt(discordant / n)`` (the null's
    spread), and a difference ``delta`` spreads as ``sqrt((discordant - delta^2) / n)``, so
    ``delta`` solves ``delta - 1.96 sqrt(q / n) = z_power sqrt((q - delta^2) / n)``, found by
    bisection in ``[0, discordant]`` (no difference can exceed the share that differs)."""
    z = NormalDist().inv_cdf(power)
    q = discordant

    def short(delta: float) -> float:  # < 0 while delta is found with less than `power`
        return delta - Z95 * math.sqrt(q / n) - z * math.sqrt(max(q - delta * delta, 0.0) / n)

    lo, hi = 0.0, q
    if short(hi) < 0:
        return math.inf  # not even every differing item going one way is found
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if short(mid) < 0 else (lo, mid)
    return hi


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
