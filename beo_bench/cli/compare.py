"""``beo-bench compare``: runs side by side; each run paired with the first on their
common items."""

from __future__ import annotations

import argparse
from typing import Any

from beo_bench.bench import compare, rundir
from beo_bench.cli.common import format_runs


def add(sub: Any, help: str) -> None:
    cp = sub.add_parser(
        "compare",
        help=help,
        description="A table of the runs; then, for two or more runs of one suite, version, "
        "track and seed, each run B against the first run A: per headline metric, B - A on "
        "the items both scored, a 95% bootstrap interval that resamples items, and a "
        "verdict (better / worse / no difference for B). The verdicts are per metric and "
        "not corrected for multiple comparisons, so with many metrics one may say worse by "
        "chance: they are for reading, not for failing a build.",
        epilog="for a pass/fail check in CI use `beo-bench gate` (Holm-corrected over every "
        "metric it tests; exit status 3 on a regression): compare's exit status does not "
        "depend on its verdicts",
    )
    cp.add_argument("runs", nargs="+", help="run directories or summary.json files")
    cp.add_argument(
        "--table",
        action="store_true",
        help="only the table (runs of any suites; no pairing, no results.jsonl needed)",
    )


def run(args: argparse.Namespace) -> int:
    """The runs' table; then, unless ``--table``, each run paired with the first on the
    items both scored (B - A with a bootstrap interval over items, and a verdict), and a
    footnote that the verdicts are uncorrected and ``gate`` is the pass/fail check."""
    loaded = [rundir.load_summary(p) for p in args.runs]
    if args.table or len(loaded) < 2:
        print(format_runs([s for _, s in loaded]))
        return 0
    (a_dir, a_sum), rest = loaded[0], loaded[1:]
    for b_dir, b_sum in rest:  # refuse before printing anything
        compare.check_comparable(a_sum, b_sum, f"{a_dir} and {b_dir}")
    first = compare.run_from(a_dir, a_sum)
    others = [compare.run_from(d, s) for d, s in rest]
    print(format_runs([s for _, s in loaded]))
    for b in others:
        print()
        print(compare.format_paired(first, b, compare.paired_runs(first, b)))
    print(compare.UNCORRECTED_NOTE)  # under the last verdict table: these are not a gate
    return 0
