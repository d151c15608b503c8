"""Resuming a run: existing results need ``--resume``, a killed run resumes to the same
summary, and a resume with more or fewer items extends or summarises a prefix."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from beo_bench.bench.rows import read_rows
from beo_bench.bench.runner import RunConfig, RunError, WorkerPool, run
from beo_bench.bench.suites import get_suite
from tests.bench.runs import FAST_RANDOM, metrics_without_time, short_run


def test_existing_results_need_resume(tmp_path) -> None:
    short_run(tmp_path, "pose-1dof", "oracle", 2)
    with pytest.raises(RunError, match="--resume"):
        short_run(tmp_path, "pose-1dof", "oracle", 2)


@pytest.mark.slow  # three runs, two of them a fresh CLI process each: ~45 s on 2 loaded cores
def test_killed_run_resumes_to_the_same_summary(tmp_path) -> None:
    """With a backend whose scores differ item by item (``random``; the oracle's are constants,
    so a lost or doubled item would not show), the resumed run's metric values equal an
    uninterrupted run's."""
    n = 32
    ref = short_run(tmp_path / "ref", "pose-3dof", "random", n, opts=FAST_RANDOM)
    assert len(set(ref["metrics"]["rot_err_deg"])) == n  # every item scores differently
    out = tmp_path / "killed"
    cmd = [
        sys.executable,
        "-m",
        "beo_bench.cli",
        "run",
        "--suite",
        "pose-3dof",
        "--backend",
        "random",
        "--opt",
        "mean_instances=4",
        "--episodes",
        str(n),
        "--out",
        str(out),
    ]
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=os.environ | {"PYTHONUNBUFFERED": "1"},
    )
    results = out / "results.jsonl"
    deadline = time.time() + 120
    while time.time() < deadline:
        if results.exists() and len(read_rows(results)) >= 4:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    partial = len(read_rows(results))
    assert 4 <= partial < n, "kill the run mid-way"
    with open(results, "ab") as f:
        f.write(b'{"item": 999, "torn')  # a torn last line, as a kill during write leaves
    assert subprocess.run([*cmd, "--resume"], capture_output=True).returncode == 0
    rows = read_rows(results)
    items = sorted(r["item"] for r in rows)
    assert items == list(range(n))  # none missing, none doubled
    s = json.loads((out / "summary.json").read_text())
    assert metrics_without_time(s) == metrics_without_time(ref)


def test_a_run_extends_or_summarises_a_prefix(tmp_path) -> None:
    """Item i depends only on (seed, i): resuming with more items adds the rest, with fewer
    summarises the first ones, and a different suite seed is refused."""
    out = tmp_path / "b"
    cfg = get_suite("pose-3dof")

    def rnd(size: int, seed: int | None = None) -> RunConfig:
        return RunConfig(cfg.with_overrides(size=size, seed=seed), "random", FAST_RANDOM)

    with WorkerPool(1) as pool:  # one worker process for every run here
        full = run(rnd(8), tmp_path / "a", progress=False, pool=pool)
        first = run(rnd(3), tmp_path / "c", progress=False, pool=pool)
        assert metrics_without_time(first) != metrics_without_time(full)  # differ by item
        run(rnd(3), out, progress=False, pool=pool)
        grown = run(rnd(8), out, resume=True, progress=False, pool=pool)
        assert metrics_without_time(grown) == metrics_without_time(full)
        assert len(read_rows(out / "results.jsonl")) == 8
        prefix = run(rnd(3), out, resume=True, progress=False, pool=pool)
        assert prefix["n"] == 3 and metrics_without_time(prefix) == metrics_without_time(first)
        with pytest.raises(RunError, match="different run"):
            run(rnd(3, seed=1), out, resume=True, pool=pool)
