"""The ``smoke`` suite set's wall time (docs/benchmark.md, "A smoke set"): ``beo-bench all
--suites smoke`` as a CI job runs it, one process start-up included, with the ``oracle``
(the target: under 90 s on 2 cores) and with ``hbeo`` (the CI recipe's backend), on a warm
asset cache (what a CI job with a cached ``BEO_BENCH_CACHE`` has) and, for the oracle, on
an empty one. Beside each wall time, the CPU time of every process of it (the command and
its worker processes), which a loaded machine does not inflate."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from harness import report, use_fresh_cache

from beo_bench.bench.suites import SUITE_SETS

TARGET_S = 90.0
WORKERS = 2


def _children_cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def smoke(backend: str) -> tuple[float, float, int]:
    """Wall and CPU seconds of one ``beo-bench all --suites smoke`` into fresh runs, and
    the size in bytes of the baseline file ``beo-bench baseline`` writes from its runs."""
    exe = str(Path(sys.executable).with_name("beo-bench"))
    quiet = {"check": True, "stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    with tempfile.TemporaryDirectory() as d:
        argv = [exe, "all", "--suites", "smoke", "--backends", backend]
        argv += ["--runs", f"{d}/runs", "--out", f"{d}/boards", "--workers", str(WORKERS)]
        cpu0, t0 = _children_cpu_s(), time.perf_counter()
        subprocess.run(argv, **quiet)
        wall, cpu = time.perf_counter() - t0, _children_cpu_s() - cpu0
        subprocess.run([exe, "baseline", f"{d}/runs", "--out", f"{d}/baseline.json"], **quiet)
        return wall, cpu, Path(f"{d}/baseline.json").stat().st_size


def main() -> None:
    items = sum(SUITE_SETS["smoke"].values())
    os.environ.setdefault("MUJOCO_GL", "egl")
    use_fresh_cache()
    wall, cpu, _ = smoke("oracle")
    report(
        f"smoke set ({items} items), oracle, empty cache",
        wall,
        "s",
        note=f"CPU {cpu:.0f} s in all processes",
    )
    for backend in ("oracle", "hbeo"):
        wall, cpu, size = smoke(backend)  # the cache the first run filled
        report(
            f"smoke set ({items} items), {backend}, warm cache",
            wall,
            "s",
            f"< {TARGET_S:.0f} s",
            wall < TARGET_S,
            note=f"CPU {cpu:.0f} s in all processes",
        )
        report(f"its baseline file (beo-bench baseline), {backend}", size / 1024, "kB")
