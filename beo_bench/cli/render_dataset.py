"""``beo-bench render-dataset``: render (or complete) HBEO's training crops (cached shards)
and report the rendering speed."""

from __future__ import annotations

import argparse
from typing import Any

from beo_bench.cli.options import (
    RENDER_GROUP,
    SPLITS_ALL,
    categories_parent,
    dataset_parent,
    per_category_parent,
    render_parents,
    split_parent,
)
from beo_bench.cli.train import hbeo_config
from beo_bench.perception.hbeo.data import render_dataset


def add(sub: Any, help: str) -> None:
    sub.add_parser(
        "render-dataset",
        help=help,
        parents=[
            dataset_parent(),
            split_parent(
                SPLITS_ALL,
                None,
                "with --objects: the dataset's split to render (default train; all: every model)",
            ),
            categories_parent(
                "classes or sets (modelnet10, shapenet-ch5, library; default: library)"
            ),
            per_category_parent(None, "instances per class"),
            *render_parents(RENDER_GROUP),
        ],
    )


def run(args: argparse.Namespace) -> int:
    """Render (or complete) HBEO's training set and report its rendering speed."""
    cfg = hbeo_config(args, "hbeo").dataset
    root, st = render_dataset(cfg, workers=args.workers, progress=True)
    if st["images"]:
        repaired = int(st.get("repaired", 0))
        print(
            f"rendered {st['images']:.0f} crops in {st['seconds']:.1f} s "
            f"({st['images_per_s']:.0f} images/s)"
            + (f", {repaired} damaged shards among them re-rendered" if repaired else "")
            + f" -> {root}"
        )
    else:
        print(f"all {cfg.images} + {cfg.val_images} crops already rendered -> {root}")
    return 0
