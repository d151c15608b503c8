"""``beo-bench demo``: the main job on the embedded defaults (``beo_bench.demo``)."""

from __future__ import annotations

import argparse
from typing import Any

from beo_bench import demo
from beo_bench.cli.options import out_parent, per_category_parent, workers_parent


def add(sub: Any, help: str) -> None:
    sub.add_parser(
        "demo",
        help=help,
        parents=[
            out_parent("out/demo", "where images and results go"),
            per_category_parent(
                demo.DEMO_PER_CATEGORY, "test-split instances per category to process and summarise"
            ),
            workers_parent(),
        ],
    )


def run(args: argparse.Namespace) -> int:
    demo.run_demo(args.out, per_category=args.per_category, workers=args.workers)
    return 0
