"""A gate's options and its findings: the units pooled over suites, the verdict per backend and
metric, what was skipped and what could not fail.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from beo_bench.bench.columns import BY_KEY, MetricSpec
from beo_bench.bench.gate.baseline import ScoredRun
from beo_bench.bench.gate.spec import (
    DEFAULT_ALPHA,
    REGRESSION,
    GateUsageError,
    metric_spec,
    primary_keys,
)
from beo_bench.stats import (
    DEFAULT_PERMUTATIONS,
    item_sums,
)


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
