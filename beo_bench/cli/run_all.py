"""``beo-bench all``: run every suite with every backend (resuming), then regenerate
leaderboards/."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from beo_bench.argparsing import rate
from beo_bench.bench import campaign
from beo_bench.bench.pages.leaderboard import check_out
from beo_bench.bench.runs import parse_backend_spec, suite_categories
from beo_bench.bench.suites import Kind as SuiteKind
from beo_bench.bench.suites import UnknownSuiteError, expand_suites, list_suites
from beo_bench.cli.common import (
    dataset_of,
    dataset_suites,
    print_run_end,
    print_skipped,
    split_needs_dataset,
    suite_named,
)
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
    runs_parent,
    seed_parent,
    sensor_parent,
    split_parent,
    update_parent,
    workers_parent,
)
from beo_bench.errors import UsageError
from beo_bench.inspection import every_backend, leaderboard_text


def backend_spec(text: str) -> str:
    """An argparse ``type`` for ``all --backends``: ``NAME`` or ``NAME:K=V,K=V``."""
    name, _, opts = text.partition(":")
    if not name:
        raise argparse.ArgumentTypeError(f"{text!r}: give NAME or NAME:KEY=VALUE,...")
    for pair in (o for o in opts.split(",") if o):
        try:
            key_value(pair)
        except argparse.ArgumentTypeError as e:
            raise argparse.ArgumentTypeError(f"backend {text!r}: option {e}") from None
    return text


def add(sub: Any, help: str) -> None:
    al = sub.add_parser(
        "all",
        help=help,
        parents=[
            dataset_parent(),
            split_parent(
                SPLITS_ALL,
                None,
                "with --objects: the dataset's split to score on (default: the suites', test)",
            ),
            episodes_parent(None, "items per suite (default: its own)"),
            seed_parent(None, "replace the suites' base seeds"),
            categories_parent(
                "isolated suites: only these classes or sets (modelnet10, shapenet-ch5, "
                "library), as `run --categories`; each run is then suite SUITE+SET "
                "(default suites: the isolated ones of every class)"
            ),
            workers_parent(),
            item_timeout_parent(),
            ray_parent(),
            runs_parent("where the runs go (resumed when present)"),
            out_parent("leaderboards"),
            privileged_parent(),
            update_parent(),
            report_views_parent(),
            sensor_parent(
                f"run every suite under each of these depth sensors ({SENSOR_NAMES}; "
                "docs/sensors.md; default: each suite's own); the leaderboard pairs them in "
                "a robustness table",
                many=True,
            ),
        ],
    )
    al.add_argument(
        "--suites",
        nargs="+",
        default=None,
        help="suites, or suite sets (smoke: every suite at a few items; --episodes still "
        "wins); default: every suite (with --objects: every isolated suite that a dataset has)",
    )
    al.add_argument(
        "--max-failure-rate",
        type=rate,
        default=None,
        metavar="X",
        help=MAX_FAILURE_HELP.replace("the run", "any run"),
    )
    al.add_argument(
        "--backends",
        type=backend_spec,
        nargs="+",
        default=None,
        metavar="NAME[:K=V,...]",
        help="default: every registered backend; options after a colon",
    )
    al.add_argument("--force-rerun", action="store_true", help=FORCE_RERUN_HELP)


def run(args: argparse.Namespace) -> int:
    dataset = dataset_of(args)
    split_needs_dataset(args, dataset)
    # suite sets (smoke) name each suite with its size; --episodes, when given, wins
    default = list_suites() if dataset is None else dataset_suites()
    if args.categories and not args.suites:
        # a class subset is for isolated suites (as on `run`): by default, those that draw
        # from every class (a suite of fixed classes holds few of those asked for)
        default = [
            n
            for n in default
            if suite_named(n).kind is SuiteKind.ISOLATED and suite_named(n).categories is None
        ]
    try:
        sizes = expand_suites(args.suites or default)
    except UnknownSuiteError as e:
        raise UsageError(str(e)) from e
    if args.categories:
        # each suite on the class subset is its own suite (SUITE+SET), as `run` names it;
        # a scene suite or classes a suite does not hold fail here, before any run starts
        sizes = {suite_named(s).with_categories(args.categories).name: n for s, n in sizes.items()}
    for s in sizes:
        suite = suite_named(s)  # an unknown name fails before any run starts
        if dataset is not None:
            # so does a scene suite on a dataset
            suite = suite.with_dataset(dataset, args.split)
        if args.categories:
            suite_categories(suite)  # and an unknown class, as `run` refuses it
    specs = args.backends or every_backend()
    check_out(args.out)  # a refused --out fails now, not after every run
    c = campaign.Campaign(
        {s: n if args.episodes is None else args.episodes for s, n in sizes.items()},
        [parse_backend_spec(b) for b in specs],
        runs=Path(args.runs),
        leaderboards=Path(args.out),
        workers=args.workers,
        use_ray=args.ray,
        seed=args.seed,
        dataset=dataset,
        split=args.split,
        allow_privileged=args.allow_privileged,
        item_timeout=args.item_timeout,
        update=args.update,
        sensors=tuple(dict.fromkeys(args.sensor)) if args.sensor else (None,),
        max_failure_rate=args.max_failure_rate,
        report_views=args.report_views,
        force_rerun=args.force_rerun,
        after_run=print_run_end,
    )
    print(leaderboard_text(campaign.run_campaign(c), c.leaderboards))
    print_skipped(dataset)
    return 0
