"""``beo-bench score``: score a BOP results CSV on a suite as a run (docs/bop.md)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from beo_bench.bench.bopscore import method_name, score_results
from beo_bench.bench.runs import run_name
from beo_bench.cli.common import format_runs, run_suite
from beo_bench.cli.options import bop_suite_parents, out_parent


def add(sub: Any, help: str) -> None:
    sc = sub.add_parser(
        "score",
        help=help,
        description="Score a BOP results file (scene_id,im_id,obj_id,score,R,t,time) written "
        "for `beo-bench export` of the same suite into a run directory: a leaderboard row "
        "that compare and gate pair with any other run of the suite.",
        parents=[
            *bop_suite_parents("score on"),
            out_parent(None, "default: runs/SUITE[@TRACK][~SENSOR]__METHOD"),
        ],
    )
    sc.add_argument("--suite", required=True)
    sc.add_argument("--bop-results", required=True, metavar="FILE.csv", help="the BOP results CSV")
    sc.add_argument(
        "--method",
        default=None,
        help="the name of the method's row (default: the file name up to its first _, as "
        "BOP names results files METHOD_DATASET-SPLIT.csv)",
    )


def run(args: argparse.Namespace) -> int:
    suite, _ = run_suite(args)
    results = Path(args.bop_results)
    method = args.method or method_name(results)
    track = "class-given" if suite.class_hint else None
    name = run_name(suite.name, method, {}, args.seed, track, suite.sensor_tag)
    out = Path(args.out) if args.out else Path("runs") / name
    summary = score_results(suite, results, out, method=method, progress=True)
    print(format_runs([summary]))
    print(f"\nresults: {out / 'results.jsonl'}\nsummary: {out / 'summary.json'}")
    return 0
