"""Results do not depend on how items are spread: one or two worker processes, a worker
pool kept across runs, or Ray actors give the same numbers."""

from __future__ import annotations

import pytest

from beo_bench.bench.runner import WorkerPool
from tests.bench.runs import FAST_RANDOM, metrics_without_time, short_run


def test_same_numbers_with_one_or_two_workers(tmp_path) -> None:
    a = short_run(tmp_path / "a", "pose-3dof", "random", 10, opts=FAST_RANDOM, workers=1)
    b = short_run(tmp_path / "b", "pose-3dof", "random", 10, opts=FAST_RANDOM, workers=2)
    assert metrics_without_time(a) == metrics_without_time(b)


def test_a_kept_worker_pool_gives_every_run_its_own_numbers(tmp_path) -> None:
    # a campaign's processes serve run after run: each must score as a fresh process would
    runs = [("pose-3dof", "random", 6), ("pose-1dof", "oracle", 4), ("pose-3dof", "random", 7)]
    opts = {"random": FAST_RANDOM, "oracle": {}}
    with WorkerPool(2) as pool:
        kept = [short_run(tmp_path / "kept", s, b, n, opts=opts[b], pool=pool) for s, b, n in runs]
    for (s, b, n), k in zip(runs, kept, strict=True):
        alone = short_run(tmp_path / "alone", s, b, n, opts=opts[b], workers=1)
        assert k["n"] == n and k["provenance"]["workers"] == 2
        assert metrics_without_time(k) == metrics_without_time(alone)


def test_ray_gives_the_same_numbers_as_local_workers(tmp_path) -> None:
    ray = pytest.importorskip("ray", reason="ray is an optional extra (make installs it)")
    try:
        local = short_run(tmp_path / "local", "pick", "oracle", 3, workers=1)
        on_ray = short_run(tmp_path / "ray", "pick", "oracle", 3, workers=2, use_ray=True)
        r_local = short_run(tmp_path / "local", "pose-3dof", "random", 6, opts=FAST_RANDOM)
        r_ray = short_run(
            tmp_path / "ray", "pose-3dof", "random", 6, opts=FAST_RANDOM, workers=2, use_ray=True
        )
    finally:
        ray.shutdown()
    assert on_ray["provenance"]["ray"] is True
    assert metrics_without_time(on_ray) == metrics_without_time(local)
    assert metrics_without_time(r_ray) == metrics_without_time(r_local)
