"""Runner figures: the oracle on ``pose-3dof`` with 1000 views on 1 and on 2 workers (the
speed-up, target >= 1.8x, and the runner's own cost, target < 3%; issue 52), beside the raw
render rate and the same items done in one process without the runner, with
the runner's own cost; and the ``icp`` backend's time per view and pose errors on
``pose-1dof`` and ``pose-3dof``; and a campaign's short runs with a fresh worker pool per run
against one kept pool; and what a backend that crashes its worker costs a run
(the worker is replaced, the item recorded as failed)."""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np
from harness import report

from beo_bench.backend import Backend, Capabilities, list_backends, register
from beo_bench.bench.evaluate import Evaluator
from beo_bench.bench.rows import read_rows
from beo_bench.bench.runner import RunConfig, WorkerPool, run
from beo_bench.bench.suites import get_suite
from beo_bench.objects import ObjectSet
from beo_bench.scenes import OBJECT_RIG
from beo_bench.types import Estimate, View

VIEWS = 1000
WORKERS = 2


def main() -> None:
    suite = get_suite("pose-3dof").with_overrides(size=VIEWS)

    # raw render rate of the suite's views (128x128 depth + mask) of one bound instance
    ev = Evaluator.of(suite, "oracle")
    r = ev.items.renderer
    inst = ObjectSet("test", ["mug"]).get("mug", 0)
    rng = np.random.default_rng(0)
    cams = [OBJECT_RIG.sample(rng, np.zeros(3)) for _ in range(50)]
    r.render(inst, cams[0])
    t0 = time.perf_counter()
    for k in range(500):
        r.render(inst, cams[k % len(cams)])
    report("raw isolated render 128x128, one instance", 500 / (time.perf_counter() - t0), "views/s")

    # the suite's items in one process, without the runner (render a new instance, oracle,
    # score); warm: every instance's mesh and voxels on disk, this process's caches filled
    for i in range(VIEWS):
        ev.run_item(i)
    t0 = time.perf_counter()
    for i in range(VIEWS):
        ev.run_item(i)
    direct = VIEWS / (time.perf_counter() - t0)
    ev.close()
    report("oracle items without the runner, one process (warm)", direct, "views/s")

    walls = {}
    for workers in (1, WORKERS):  # the same items, one worker and then WORKERS
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            run(RunConfig(suite, "oracle"), Path(d) / "o", workers=workers, progress=False)
            wall = time.perf_counter() - t0
            rows = read_rows(Path(d) / "o" / "results.jsonl")
            busy = sum(row.get("item_ms", 0.0) for row in rows)
        walls[workers] = wall
        # the runner's own cost: the share of the workers' time not spent inside items
        # (process start-up, imports, result transfer and writing, the summary, idle
        # workers at the end)
        own = 1.0 - busy / 1000 / (workers * wall)
        report(f"runner, oracle on pose-3dof, {VIEWS} views, {workers} worker(s)",
               VIEWS / wall, "views/s")  # fmt: skip
        report(f"  runner's own cost, {workers} worker(s) (1 - time in items / (workers x wall))",
               100 * own, "%", "< 3%", own < 0.03)  # fmt: skip
    speedup = walls[1] / walls[WORKERS]
    report(f"  speed-up of {WORKERS} workers over 1, the same items", speedup, "x",
           ">= 1.8x", speedup >= 1.8)  # fmt: skip
    report(f"  speed-up over one process without the runner ({WORKERS} cores)",
           VIEWS / walls[WORKERS] / direct, "x")  # fmt: skip

    short_runs()
    crash_recovery()

    if "icp" in list_backends():
        for name in ("pose-1dof", "pose-3dof"):
            s = get_suite(name).with_overrides(size=110)
            with tempfile.TemporaryDirectory() as d:
                summ = run(RunConfig(s, "icp"), Path(d) / "i", workers=1, progress=False)
            m = summ["metrics"]
            report(
                f"icp on {name} (110 views, class given): median ms/view",
                m["ms_per_view_median"],
                "ms",
                "< 50 ms",
                m["ms_per_view_median"] < 50,
            )
            report(f"  icp on {name}: rotation error mean", m["rot_err_deg_mean"], "deg")
            report(f"  icp on {name}: rotation error median", m["rot_err_deg_median"], "deg")
            report(f"  icp on {name}: > 15 deg rate", 100 * m["gross_err_rate"], "%")


def short_runs(n: int = 6, items: int = 44) -> None:
    """``make demo``'s case: many short runs (here ``n`` runs of 44 ``oracle`` items on
    ``known-pose`` with new seeds, so every run scores new items)."""
    suites = [get_suite("known-pose").with_overrides(size=items, seed=9000 + k) for k in range(n)]
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        for k, s in enumerate(suites):
            run(RunConfig(s, "oracle"), Path(d) / f"fresh{k}", workers=WORKERS, progress=False)
        fresh = (time.perf_counter() - t0) / n
        t0 = time.perf_counter()
        with WorkerPool(WORKERS) as pool:
            for k, s in enumerate(suites):
                run(RunConfig(s, "oracle"), Path(d) / f"kept{k}", pool=pool, progress=False)
        kept = (time.perf_counter() - t0) / n
    report(f"{n} short runs ({items} oracle items): s per run, a fresh pool per run", fresh, "s")
    report("  s per run, one kept pool (beo-bench all)", kept, "s", "< fresh", kept < fresh)


CRASH = "bench-crash"


class _Crash(Backend):
    """The oracle, except that it aborts its process on the views of class 0 (runs in the
    workers because they import this module: ``WorkerPool(imports=[__name__])``)."""

    name = CRASH
    capabilities = Capabilities(privileged=True)
    role = "diagnostic"

    def __init__(self, options: object = None) -> None:
        from beo_bench.backend import get_backend

        super().__init__(options)
        self.inner = get_backend("oracle")

    def predict(self, view: View) -> Estimate:
        if view.ground_truth is not None and view.ground_truth.class_index == 0:
            os.abort()
        return self.inner.predict(view)


register(_Crash)


def crash_recovery(items: int = 44) -> None:
    """``items`` views of ``known-pose`` with the oracle, then with a backend that aborts on
    one class (4 of the 44 items: each costs a new worker); both with one kept pool."""
    s = get_suite("known-pose").with_overrides(size=items, seed=9100)
    with tempfile.TemporaryDirectory() as d, WorkerPool(WORKERS, imports=[__name__]) as pool:
        run(RunConfig(s, "oracle"), Path(d) / "warm", pool=pool, progress=False)  # warm caches
        s = s.with_overrides(seed=9200)
        t0 = time.perf_counter()
        run(RunConfig(s, "oracle"), Path(d) / "clean", pool=pool, progress=False)
        clean = time.perf_counter() - t0
        t0 = time.perf_counter()
        summ = run(RunConfig(s, CRASH), Path(d) / "crash", pool=pool, progress=False)
        crashed = time.perf_counter() - t0
    n = summ["failure_kinds"].get("worker died", 0)
    report(f"{items} oracle items, {WORKERS} kept workers: s per run", clean, "s")
    report(
        f"  s per crashed item ({n} items abort their worker: replaced, recorded)",
        (crashed - clean) / max(n, 1),
        "s",
    )
