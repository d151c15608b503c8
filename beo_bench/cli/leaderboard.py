"""``beo-bench leaderboard``: regenerate leaderboards/ from run summaries."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from beo_bench.bench.pages.leaderboard import regenerate
from beo_bench.cli.options import out_parent, runs_parent, update_parent
from beo_bench.errors import BeoBenchError, UsageError


def add(sub: Any, help: str) -> None:
    lb = sub.add_parser(
        "leaderboard",
        help=help,
        parents=[runs_parent(), out_parent("leaderboards"), update_parent()],
    )
    lb.add_argument(
        "--ablation",
        action="store_true",
        help="the runs are one study's variants and their baseline, not a suite's every row "
        "(leaderboards/ablations/): no primary comparisons, a note naming the full page",
    )


def run(args: argparse.Namespace) -> int:
    if not Path(args.runs).is_dir():  # a mistyped --runs is a usage error, not an empty one
        raise UsageError(
            f"--runs {args.runs} is not a directory: give the directory the runs are in "
            "(where `beo-bench run --out` or `all --runs` wrote them)"
        )
    written = regenerate(args.runs, args.out, update=args.update, ablation=args.ablation)
    if not written and not args.update:  # --update alone prunes pages of older versions
        raise BeoBenchError(f"no summary.json under {args.runs}: run `beo-bench run` first")
    for p in written:
        print(p.read_text())
    print(f"wrote {len(written)} suite tables to {args.out}/")
    return 0
