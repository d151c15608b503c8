"""``beo-bench run``: score a backend on a suite."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from beo_bench.argparsing import rate
from beo_bench.bench import recording, runner
from beo_bench.bench.gate.check import check_failure_rate
from beo_bench.bench.runs import RunConfig, RunContext, parse_option_pairs, run_name
from beo_bench.bench.suites import TRACKS
from beo_bench.cli.common import format_runs, print_run_end, print_skipped, run_suite
from beo_bench.cli.options import (
    FORCE_RERUN_HELP,
    MAX_FAILURE_HELP,
    SENSOR_NAMES,
    SPLITS_ALL,
    categories_parent,
    dataset_parent,
    episodes_parent,
    item_timeout_parent,
    key_value,
    out_parent,
    privileged_parent,
    ray_parent,
    report_views_parent,
    seed_parent,
    sensor_parent,
    split_parent,
    workers_parent,
)


def add(sub: Any, help: str) -> None:
    r = sub.add_parser(
        "run",
        help=help,
        parents=[
            dataset_parent(),
            split_parent(
                SPLITS_ALL,
                None,
                "with --objects: the dataset's split to score on (default: the suite's, test)",
            ),
            episodes_parent(None, "items (default: the suite's)"),
            seed_parent(None, "replace the suite's base seed"),
            categories_parent(
                "isolated suites: only these classes or sets (modelnet10, shapenet-ch5, "
                "library); the run is then suite SUITE+SET"
            ),
            workers_parent(None, "worker processes (default: one per core)"),
            out_parent(None, "default: runs/SUITE[@TRACK][~SENSOR]__BACKEND"),
            ray_parent(),
            item_timeout_parent(),
            privileged_parent(),
            report_views_parent(),
            sensor_parent(
                f"the depth sensor the views are captured by ({SENSOR_NAMES}; "
                "docs/sensors.md; default: the suite's own, kinect-v1 for tabletop, ideal "
                "for the others); another than the suite's own names the run SUITE~SENSOR"
            ),
        ],
    )
    r.add_argument("--suite", required=True)
    r.add_argument("--backend", required=True)
    r.add_argument(
        "--track",
        choices=list(TRACKS),
        default=None,
        help="pose suites: whether backends that can use the true class are given it "
        "(default: class-free; suites without tracks refuse it)",
    )
    r.add_argument("--resume", action="store_true", help="continue a killed run in --out")
    r.add_argument("--force-rerun", action="store_true", help=FORCE_RERUN_HELP)
    r.add_argument(
        "--max-failure-rate",
        type=rate,
        default=None,
        metavar="X",
        help=MAX_FAILURE_HELP,
    )
    r.add_argument("--rerun", default=None, help="also write a rerun .rrd of the first views")
    r.add_argument(
        "--opt",
        type=key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="backend option",
    )


def run(args: argparse.Namespace) -> int:
    suite, dataset = run_suite(args, args.track)
    kwargs = parse_option_pairs(args.opt)
    cfg = RunConfig(suite, args.backend, kwargs, args.allow_privileged)
    # resolved once: a bad option, a privileged plugin without leave or a track the backend
    # cannot run in fails here, before any directory is made
    ctx = RunContext.of(cfg, progress=True)
    name = run_name(suite.name, args.backend, kwargs, args.seed, suite.track, suite.sensor_tag)
    out = Path(args.out) if args.out else Path("runs") / name
    summary = runner.run(
        ctx,
        out,
        workers=args.workers,
        resume=args.resume,
        use_ray=args.ray,
        item_timeout=args.item_timeout,
        report_views=args.report_views,
        force_rerun=args.force_rerun,
    )
    print(format_runs([summary]))
    print(f"\nresults: {out / 'results.jsonl'}\nsummary: {out / 'summary.json'}")
    print_skipped(dataset)
    if args.rerun:
        path = recording.log_run(ctx, args.rerun)
        print(f"recording of the first views: {path}  (open with `rerun {path}`)")
    print_run_end(ctx, out, label=False)
    if args.max_failure_rate is not None:
        check_failure_rate([(out, summary)], args.max_failure_rate)
    return 0
