"""``beo-bench pick-check``: pick success of the ground-truth grasp planner (the ceiling)."""

from __future__ import annotations

import argparse
from typing import Any

from beo_bench import inspection
from beo_bench.cli.options import episodes_parent, seed_parent, split_parent


def add(sub: Any, help: str) -> None:
    sub.add_parser(
        "pick-check",
        help=help,
        parents=[
            episodes_parent(100),
            seed_parent(0, "first episode seed"),
            split_parent(["train", "val", "test", "ood"], "test"),
        ],
    )


def run(args: argparse.Namespace) -> int:
    report = inspection.pick_check(args.episodes, args.seed, args.split)
    print()
    print(report.text())
    return 0
