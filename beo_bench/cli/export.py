"""``beo-bench export``: write a suite's items as a BOP-format dataset (docs/bop.md)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from beo_bench.argparsing import nonneg_int
from beo_bench.bench.export import export_bop
from beo_bench.cli.common import run_suite
from beo_bench.cli.options import bop_suite_parents


def add(sub: Any, help: str) -> None:
    ex = sub.add_parser(
        "export",
        help=help,
        description="Write a suite's items as a BOP dataset (models, test scenes with rgb, "
        "depth, masks and ground truth, test_targets_bop19.json, and training scenes), for "
        "methods that read BOP datasets; `beo-bench score` scores their results file.",
        parents=bop_suite_parents("export"),
    )
    ex.add_argument("--suite", required=True)
    ex.add_argument("--format", choices=["bop"], default="bop", help="the format (bop)")
    ex.add_argument(
        "--train-items",
        type=nonneg_int,
        default=None,
        metavar="N",
        help="training images drawn from the split's training instances (default: as many as "
        "the test images; 0: none)",
    )
    ex.add_argument(
        "--withhold-gt",
        action="store_true",
        help="write the test split as the BOP challenge does: images, cameras and targets, "
        "no scene_gt.json, scene_gt_info.json or masks (`beo-bench score` does not need them)",
    )
    ex.add_argument("dir", metavar="DIR", help="a new or empty folder (or an earlier export's)")


def run(args: argparse.Namespace) -> int:
    suite, _ = run_suite(args)
    train = suite.size if args.train_items is None else args.train_items
    done = export_bop(
        suite, Path(args.dir), train_items=train, progress=True, withhold_gt=args.withhold_gt
    )
    shown = ", ".join(
        f"{n} {split} image{'' if n == 1 else 's'}" for split, n in done.images.items()
    )
    print(
        f"{done.root}: BOP dataset of {suite.name}"
        f"{'' if suite.sensor_tag is None else '~' + suite.sensor_tag} ({shown}, "
        f"{done.objects} object models, "
        f"{done.targets} targets in test_targets_bop19.json"
        f"{'; test ground truth withheld' if args.withhold_gt else ''})"
    )
    if done.removed:
        print(f"removed {done.removed} file(s) of the earlier export that this one replaced")
    if done.kept:
        print(
            f"beo-bench: warning: kept {len(done.kept)} file(s) of the earlier export that "
            f"changed since it wrote them ({', '.join(done.kept[:3])}"
            f"{', ...' if len(done.kept) > 3 else ''}): remove them yourself if unwanted",
            file=sys.stderr,
        )
    return 0
