"""``beo-bench view``: write a BEOPick-v0 scene to a rerun .rrd and a PNG."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from beo_bench.argparsing import bounded_int, positive_int
from beo_bench.cli.common import dataset_of
from beo_bench.cli.options import (
    SCENE_SPLITS,
    dataset_parent,
    out_parent,
    seed_parent,
    split_parent,
)
from beo_bench.scenes.camera import MAX_IMAGE_SIDE
from beo_bench.sceneview import view_scene

image_side = bounded_int(1, MAX_IMAGE_SIDE, why=" pixels (the off-screen GL buffer's limit)")


def add(sub: Any, help: str) -> None:
    v = sub.add_parser(
        "view",
        help=help,
        parents=[
            dataset_parent(),
            seed_parent(0),
            out_parent(Path("out/view"), type=Path),
            split_parent(SCENE_SPLITS, "test", "all: every model of a --objects dataset"),
        ],
    )
    v.add_argument("--num-objects", type=positive_int, default=None, help="default: 1-4")
    v.add_argument("--image-size", type=image_side, nargs=2, default=[640, 480], metavar=("W", "H"))
    v.add_argument("--no-rrd", action="store_true", help="only the PNG")


def run(args: argparse.Namespace) -> int:
    dataset = dataset_of(args)
    r = view_scene(
        args.seed,
        args.out,
        rrd=not args.no_rrd,
        split=args.split,
        image_size=tuple(args.image_size),
        num_objects=args.num_objects,
        objects=dataset.objects(args.split) if dataset is not None else None,
    )
    print(r.text())
    return 0
