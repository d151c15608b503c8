"""The gate itself: runs paired with their baseline, one test per metric and backend pooled over
suites, Holm-corrected, and the failure-rate check (``--max-failure-rate``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from beo_bench.bench import compare
from beo_bench.bench.columns import BY_KEY
from beo_bench.bench.gate.baseline import ScoredRun
from beo_bench.bench.gate.report import GateReport
from beo_bench.bench.gate.spec import (
    IMPROVEMENT,
    NO_DIFFERENCE,
    REGRESSION,
    WORSE_WITHIN_MARGIN,
    FailureRateError,
    GateUsageError,
    margin,
)
from beo_bench.bench.gate.verdicts import GateOptions, Pool, Skipped, Verdict, pool
from beo_bench.bench.rows import span
from beo_bench.stats import (
    holm,
    ratio_interval,
    sign_flip_p,
)


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
