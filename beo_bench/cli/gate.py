"""``beo-bench gate``: fail (exit 3) when runs got worse than a baseline, item by item."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from beo_bench.argparsing import open_fraction, positive_int, seed_int
from beo_bench.bench.gate.baseline import load_baseline, load_runs
from beo_bench.bench.gate.check import gate
from beo_bench.bench.gate.report import write_reports
from beo_bench.bench.gate.spec import (
    DEFAULT_ALPHA,
    GateFailure,
    GateUsageError,
    metric_spec,
    primary_keys,
)
from beo_bench.bench.gate.verdicts import GateOptions
from beo_bench.cli import show_warning
from beo_bench.stats import DEFAULT_PERMUTATIONS


def gate_metric(text: str) -> str:
    """An argparse ``type`` for ``gate --metrics``: a metric that is a mean over views."""
    try:
        return metric_spec(text).key
    except GateUsageError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def add(sub: Any, help: str) -> None:
    g = sub.add_parser(
        "gate",
        help=help,
        description="Each run against the baseline run of the same suite, track and sensor, "
        "on the same items: per metric, pooled over the suites that measure it, a one-sided "
        "paired sign-flip permutation test over items of the worsening less the metric's "
        "margin, Holm-corrected over every test; a regression is a metric worse than the "
        "baseline by more than its margin with adjusted p at most --alpha (docs/benchmark.md, "
        "'A regression gate').",
        epilog="exit status: 0 no regression (a test or suite with too few items to fail "
        "after the correction is a warning line, 'gate cannot fail', and CANNOT FAIL in every "
        "report), 3 a regression (the reports are written "
        "first), 2 a usage error (runs that do not pair with the baseline: another suite, "
        "version, seed, track, sensor or items), 1 a failure (a damaged results file)",
    )
    g.add_argument(
        "runs",
        nargs="+",
        metavar="RUN",
        help="run directories, their summary.json, or a directory of runs (all --runs)",
    )
    g.add_argument(
        "--baseline",
        required=True,
        metavar="FILE|RUN",
        help="a baseline file (`beo-bench baseline`), a run directory or a directory of runs",
    )
    g.add_argument(
        "--metrics",
        type=gate_metric,
        nargs="+",
        default=None,
        metavar="METRIC",
        help="summary metrics to gate, each pooled over the suites that measure it (a suite "
        "that does not is skipped, and the reports say so), e.g. gross_err_rate iou_mean "
        f"(default: {' '.join(primary_keys())})",
    )
    g.add_argument(
        "--alpha",
        type=open_fraction,
        default=DEFAULT_ALPHA,
        help=f"the gate's family-wise error rate (default {DEFAULT_ALPHA})",
    )
    g.add_argument(
        "--permutations",
        type=positive_int,
        default=DEFAULT_PERMUTATIONS,
        help="random sign patterns when more than 16 items differ (default "
        f"{DEFAULT_PERMUTATIONS}; fewer are enumerated exactly)",
    )
    g.add_argument(
        "--seed", type=seed_int, default=0, help="seeds the permutations and the bootstrap"
    )
    g.add_argument("--json", type=Path, default=None, metavar="FILE", help="the verdicts as JSON")
    g.add_argument(
        "--junit",
        type=Path,
        default=None,
        metavar="FILE",
        help="JUnit XML: a test suite per backend, a test case per metric",
    )
    g.add_argument(
        "--markdown",
        type=Path,
        default=None,
        metavar="FILE",
        help="a Markdown summary (also appended to $GITHUB_STEP_SUMMARY when it is set)",
    )


def run(args: argparse.Namespace) -> int:
    """Each run against its baseline run; the reports; exit 3 on a regression."""
    options = GateOptions(
        metrics=tuple(args.metrics) if args.metrics else None,
        alpha=args.alpha,
        permutations=args.permutations,
        seed=args.seed,
    )
    baseline = load_baseline(args.baseline)  # refused before the runs are read
    report = gate(load_runs(args.runs), baseline, options, str(args.baseline))
    print(report.text())
    written = write_reports(report, args.json, args.junit, args.markdown)
    for path in written:
        print(f"wrote {path}")
    for blind in report.cannot_fail:  # loud, also where stdout is not read: a pass of these
        show_warning(f"gate cannot fail: {blind.line()}", UserWarning, "", 0)  # means nothing
    if not report.passed:
        worst = "; ".join(v.line() for v in report.regressions)
        raise GateFailure(f"gate failed: regression in {worst}")
    return 0
