"""Tiny harness for the performance benchmarks: each figure is printed with its target.

Benchmarks measure; they never fail the build. ``make bench`` runs them all.
"""

from __future__ import annotations

import contextlib
import os
import statistics
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

RESULTS: list[dict[str, Any]] = []


def use_fresh_cache() -> Path:
    """Point the asset cache at a new, empty temporary folder, for cold-cache figures
    (``run.py`` gives the next benchmark the user's cache back)."""
    root = Path(tempfile.mkdtemp(prefix="beo_bench_bench_"))
    os.environ["BEO_BENCH_CACHE"] = str(root)
    return root


@contextlib.contextmanager
def pinned_one_core() -> Iterator[None]:
    """This process on one core with one BLAS/torch thread, for the figures whose target is
    per core: CPU time summed over threads on two cores is not one core's time."""
    from threadpoolctl import threadpool_limits

    cpus = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(cpus)})
    try:
        import torch

        threads = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            with threadpool_limits(limits=1):
                yield
        finally:
            torch.set_num_threads(threads)
    finally:
        os.sched_setaffinity(0, cpus)


def median_time(
    fn: Callable[[], Any], repeat: int, setup: Callable[[], Any] | None = None
) -> float:
    """Median wall time of ``fn`` over ``repeat`` calls (``setup`` runs untimed before each)."""
    times = []
    for _ in range(repeat):
        if setup is not None:
            setup()
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def paired_median_times(
    fn: Callable[[], Any], ref: Callable[[], Any], repeat: int
) -> tuple[float, float]:
    """Median wall times of ``fn`` and of its reference ``ref``, called alternately
    ``repeat`` times each, so that both see the same machine state (a ratio of two
    back-to-back medians moves by a quarter with the load of a shared machine)."""
    a, b = [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        ref()
        t1 = time.perf_counter()
        fn()
        t2 = time.perf_counter()
        b.append(t1 - t0)
        a.append(t2 - t1)
    return statistics.median(a), statistics.median(b)


def median_ms_per_item(fn: Callable[[Any], Any], items: list[Any]) -> float:
    """Median wall time (ms) of ``fn(item)`` over ``items``, after one untimed warm-up call
    on the first."""
    fn(items[0])
    times = []
    for item in items:
        t0 = time.perf_counter()
        fn(item)
        times.append(1000 * (time.perf_counter() - t0))
    return statistics.median(times)


def report(
    name: str,
    value: float,
    unit: str,
    target: str = "report",
    ok: bool | None = None,
    note: str = "",
) -> None:
    """Print one figure: its value, its target, and whether the target is met."""
    verdict = "" if ok is None else ("  [meets target]" if ok else "  [MISSES target]")
    extra = f"  ({note})" if note else ""
    print(f"  {name:<58} {value:>10.3f} {unit:<10} target: {target}{verdict}{extra}", flush=True)
    RESULTS.append({"name": name, "value": value, "unit": unit, "target": target, "ok": ok})
