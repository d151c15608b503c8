"""docs/benchmark.md's cluster recipe, as written: a real two-node Ray cluster on 127.0.0.1
(a head and a worker node, one CPU each, separate processes, token authentication as Ray
2.52+ expects), a small suite run through ``RAY_ADDRESS``, and the same numbers as local
workers. The cluster is stopped afterwards, also on failure: only the processes this test
started (the two ``ray start --block`` process trees) are killed, never another Ray."""

from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from tests.bench.runs import metrics_without_time, short_run

pytestmark = pytest.mark.slow

# the oracle: nothing to build in the test cache (a backend with class means would have
# every actor build them), while rendering, the views' transport and scoring are all real
RUN = ["run", "--suite", "pose-3dof", "--backend", "oracle", "--episodes", "6"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _ray_cli() -> str:
    ray = Path(sys.executable).with_name("ray")
    if not ray.exists():
        pytest.skip("the ray extra is not installed (make installs it)")
    return str(ray)


def _stop(proc: subprocess.Popen[bytes]) -> None:
    """SIGTERM to the process tree of one ``ray start --block`` (its session), then SIGKILL
    to what is left: the raylet, GCS and workers it started, and nothing else."""
    import psutil

    try:
        tree = [psutil.Process(proc.pid), *psutil.Process(proc.pid).children(recursive=True)]
    except psutil.NoSuchProcess:
        tree = []
    for p in tree:
        try:
            p.send_signal(signal.SIGTERM)
        except psutil.NoSuchProcess:
            pass
    _, alive = psutil.wait_procs(tree, timeout=5)
    for p in alive:
        try:
            p.kill()
        except psutil.NoSuchProcess:
            pass
    proc.wait(timeout=15)


def _wait_for_nodes(env: dict[str, str], n: int, timeout: float = 120.0) -> None:
    probe = (
        "import ray; ray.init(); print(sum(1 for x in ray.nodes() if x['Alive'])); ray.shutdown()"
    )
    deadline = time.monotonic() + timeout
    seen = ""
    while time.monotonic() < deadline:
        out = subprocess.run(
            [sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=60
        )
        seen = out.stdout.strip().splitlines()[-1] if out.stdout.strip() else out.stderr[-300:]
        if seen == str(n):
            return
        time.sleep(2)
    raise AssertionError(f"the cluster did not reach {n} nodes: {seen}")


def test_a_two_node_cluster_gives_the_local_workers_numbers(tmp_path) -> None:
    ray = _ray_cli()
    port = _free_port()
    # Ray's socket paths must stay under 107 characters: a short session directory
    temp = tempfile.mkdtemp(prefix="beo-ray-", dir="/tmp")
    env = {
        **os.environ,
        "RAY_AUTH_MODE": "token",
        "RAY_AUTH_TOKEN": secrets.token_hex(16),
        "RAY_USAGE_STATS_ENABLED": "0",
        "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"),
    }
    common = ["--num-cpus=1", "--node-ip-address=127.0.0.1", "--disable-usage-stats", "--block"]
    nodes: list[subprocess.Popen[bytes]] = []
    try:
        nodes.append(
            subprocess.Popen(
                [ray, "start", "--head", f"--port={port}", "--include-dashboard=false",
                 f"--temp-dir={temp}", *common],
                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                start_new_session=True,
            )
        )  # fmt: skip
        driver_env = {**env, "RAY_ADDRESS": f"127.0.0.1:{port}"}
        _wait_for_nodes(driver_env, 1)
        nodes.append(
            subprocess.Popen(
                [ray, "start", f"--address=127.0.0.1:{port}", *common],
                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                start_new_session=True,
            )
        )  # fmt: skip
        _wait_for_nodes(driver_env, 2)
        cli = [sys.executable, "-m", "beo_bench.cli"]
        on_ray = subprocess.run(
            [*cli, *RUN, "--ray", "--workers", "2", "--out", str(tmp_path / "ray")],
            env=driver_env, capture_output=True, text=True, timeout=300,
        )  # fmt: skip
        assert on_ray.returncode == 0, on_ray.stderr[-2000:]
    finally:
        for proc in reversed(nodes):
            _stop(proc)
        shutil.rmtree(temp, ignore_errors=True)
    local = short_run(tmp_path / "local", "pose-3dof", "oracle", 6, workers=2)
    a = json.loads((tmp_path / "ray" / "summary.json").read_text())
    b = local
    assert a["provenance"]["ray"] is True and b["provenance"]["ray"] is False
    assert a["n"] == b["n"] == 6
    assert metrics_without_time(a) == metrics_without_time(b)
