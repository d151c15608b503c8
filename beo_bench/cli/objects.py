"""``beo-bench objects``: process and summarise an object set."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from beo_bench import inspection
from beo_bench.argparsing import resolution_int
from beo_bench.cli.common import categories_of, dataset_of, print_skipped
from beo_bench.cli.options import (
    SCENE_SPLITS,
    categories_parent,
    dataset_parent,
    per_category_parent,
    split_parent,
    workers_parent,
)


def add(sub: Any, help: str) -> None:
    o = sub.add_parser(
        "objects",
        help=help,
        parents=[
            dataset_parent(),
            split_parent(SCENE_SPLITS, "test", "all: every model of a --objects dataset"),
            categories_parent(),
            per_category_parent(None, "instances per category (default: the split's size)"),
            workers_parent(2, None),
        ],
    )
    # the dataset is --objects ROOT, as on run, all, train and export; --root, its older
    # spelling here alone, stays only to say so (hidden from --help; refused as it is
    # parsed, so the docs test's check of a command refuses it too)
    o.add_argument("--root", type=_root_is_gone, default=None, help=argparse.SUPPRESS)
    o.add_argument(
        "--resolution", type=resolution_int, default=32, help="voxel grid size D (8-128)"
    )
    o.add_argument("--sheet", type=Path, default=None, help="write a contact sheet PNG")


def _root_is_gone(text: str) -> str:
    raise argparse.ArgumentTypeError(
        f"`objects` takes the dataset as every command does: --objects {text} (--root was "
        "its older spelling)"
    )


def run(args: argparse.Namespace) -> int:
    dataset = dataset_of(args)
    if dataset is not None:
        print(f"dataset {dataset.root}: {dataset.layout} layout, digest {dataset.digest}")
    objects, counts = inspection.select_objects(
        args.split, categories_of(args), args.per_category, dataset=dataset
    )
    report = inspection.summarise_objects(
        objects,
        args.split,
        resolution=args.resolution,
        workers=args.workers,
        sheet=args.sheet,
        sheet_per_category=args.per_category or 6,  # the sheet shows what --per-category asks
        split_counts=counts,
    )
    print()
    print(report.text())
    print_skipped(dataset)
    return 0
