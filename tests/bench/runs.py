"""Short runs of the runner for its tests: one suite and backend, a few items."""

from __future__ import annotations

from pathlib import Path

from beo_bench.bench.runner import RunConfig, run
from beo_bench.bench.suites import get_suite
from beo_bench.bench.summary import TIMING_KEYS

FAST_RANDOM = {"mean_instances": 4}
"""The ``random`` backend's option that keeps its class means quick to build."""


def short_run(tmp_path: Path, suite: str, backend: str, n: int, **kw) -> dict:
    """Run ``n`` items of ``suite`` with ``backend`` into a directory of ``tmp_path`` named
    after them; returns the summary."""
    s = get_suite(suite).with_overrides(size=n, track=kw.pop("track", None))
    cfg = RunConfig(s, backend, kw.pop("opts", {}), kw.pop("allow_privileged", False))
    return run(cfg, tmp_path / f"{suite}-{backend}-{n}", progress=False, **kw)


def metrics_without_time(s: dict) -> dict:
    """A summary's metrics without the timings, which differ from run to run."""
    return {k: v for k, v in s["metrics"].items() if k not in TIMING_KEYS}
