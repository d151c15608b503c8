"""``beo-bench demo``'s wall time, cold and warm (docs/performance.md, "The demo"): the command
as ``make demo`` runs it, on an empty asset cache and a new output folder, then again on both
(it resumes the finished runs). The virtualenv is made before ``make bench`` starts, so the
cold figure leaves out the set-up that ``make demo`` on a fresh clone adds (about a minute
from a local package index); ``export BEO_BENCH_CACHE=$(mktemp -d); time make demo`` in a
fresh clone is the figure with it. Beside each wall time, the CPU time of the command and
its worker processes."""

from __future__ import annotations

import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from harness import report, use_fresh_cache

COLD_TARGET_S = 8 * 60.0  # set-up included on a fresh clone: the cold figure here is below it
WARM_TARGET_S = 45.0


def _children_cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def demo(out: Path) -> tuple[float, float]:
    """Wall and CPU seconds of one ``beo-bench demo --out OUT``."""
    exe = str(Path(sys.executable).with_name("beo-bench"))
    quiet = {"check": True, "stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    cpu0, t0 = _children_cpu_s(), time.perf_counter()
    subprocess.run([exe, "demo", "--out", str(out)], **quiet)
    return time.perf_counter() - t0, _children_cpu_s() - cpu0


def main() -> None:
    use_fresh_cache()  # cold: no instance, mesh or model of the demo's built yet
    with tempfile.TemporaryDirectory() as d:
        for what, target in (("cold", COLD_TARGET_S), ("warm", WARM_TARGET_S)):
            wall, cpu = demo(Path(d) / "demo")
            report(
                f"demo {what}, wall (the venv made; CPU of all its processes {cpu:.0f} s)",
                wall,
                "s",
                f"<= {target:.0f} s",
                wall <= target,
            )
