"""``beo-bench baseline``: write a baseline file for ``gate`` from runs."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from beo_bench.bench.gate.baseline import load_runs, write_baseline


def add(sub: Any, help: str) -> None:
    b = sub.add_parser(
        "baseline",
        help=help,
        description="A small versioned JSON file holding each run's suite identity, backend "
        "and per-view values of every pairable metric, keyed by item: what `beo-bench gate "
        "--baseline FILE` pairs later runs with.",
    )
    b.add_argument(
        "runs",
        nargs="+",
        metavar="RUN",
        help="run directories, their summary.json, or a directory of runs (all --runs)",
    )
    b.add_argument("--out", type=Path, required=True, metavar="FILE", help="the file to write")


def run(args: argparse.Namespace) -> int:
    """Write the baseline file of the runs given."""
    runs = load_runs(args.runs)
    path = write_baseline(runs, args.out)
    held = ", ".join(f"{r.label} ({r.backend})" for r in runs)
    print(f"wrote {path} ({path.stat().st_size / 1024:.1f} kB): {held}")
    return 0
