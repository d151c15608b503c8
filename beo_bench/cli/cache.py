"""``beo-bench cache``: inspect or clear the asset cache."""

from __future__ import annotations

import argparse
from typing import Any

from beo_bench import inspection
from beo_bench.objects import cache


def add(sub: Any, help: str) -> None:
    c = sub.add_parser("cache", help=help)
    c.add_argument("action", choices=["info", "clear"])
    # a kind is a name from a fixed list, never a path: `clear` deletes what it names
    c.add_argument(
        "--kind",
        default=None,
        choices=list(cache.KINDS),
        help="only this kind of entry (with clear): "
        + "; ".join(f"{k}: {v}" for k, v in cache.KINDS.items()),
    )


def run(args: argparse.Namespace) -> int:
    # a cache that is a file is an error, not an empty cache (info needs no write access)
    cache.check_root(writable=args.action == "clear", min_free=0)
    if args.action == "clear":
        freed = cache.clear(args.kind)
        print(f"cleared {inspection.format_bytes(freed)} from {cache.cache_root()}")
        return 0
    print(inspection.cache_report().text())
    return 0
