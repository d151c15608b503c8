"""Runner figures (issue 4): the oracle on ``pose-3dof`` with 1000 views and 2 workers,
beside the raw render rate and the same work done in one process without the runner; and
the ``icp`` backend's time per view and pose errors on ``pose-1dof`` and ``pose-3dof``."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
from beo_bench.scenes import OBJECT_RIG
from harness import report

from beo_bench.backend import list_backends
from beo_bench.bench.evaluate import Evaluator
from beo_bench.bench.runner import RunConfig, run
from beo_bench.bench.suites import get_suite

VIEWS = 1000


def main() -> None:
    suite = get_suite("pose-3dof").with_overrides(size=VIEWS)

    # raw render rate of the suite's views (128x128 depth + mask), one process
    ev = Evaluator(suite, "oracle")
    for i in range(VIEWS):  # warm: every instance's mesh and voxels (disk cache)
        ev.run_item(i)
    r = ev._isolated()
    objs = ev._objects
    insts = [objs.get(c, 0) for c in objs.categories]
    rng = np.random.default_rng(0)
    cams = [OBJECT_RIG.sample(rng, np.zeros(3)) for _ in range(50)]
    t0 = time.perf_counter()
    for k in range(500):
        r.render(insts[k % len(insts)], cams[k % len(cams)])
    render_rate = 500 / (time.perf_counter() - t0)
    report("raw isolated render 128x128, one process", render_rate, "views/s")

    # the same items without the runner, one process (render + oracle + scoring)
    t0 = time.perf_counter()
    for i in range(VIEWS):
        ev.run_item(i)
    direct = VIEWS / (time.perf_counter() - t0)
    ev.close()
    report("oracle items without the runner, one process (warm)", direct, "views/s")

    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        run(RunConfig(suite, "oracle"), Path(d) / "o", workers=2, progress=False)
        wall = time.perf_counter() - t0
    rate = VIEWS / wall
    # the runner's own cost: what 2 workers lose against twice the one-process rate
    # (process start-up, each worker's own warm-up, result transfer, appends with fsync)
    overhead = max(0.0, 1.0 - rate / (2 * direct))
    report(f"runner, oracle on pose-3dof, {VIEWS} views, 2 workers", rate, "views/s")
    report(
        "  runner's own cost (1 - rate / (2 x one-process rate))",
        100 * overhead,
        "%",
        "< 10%",
        overhead < 0.10,
    )

    if "icp" in list_backends():
        for name in ("pose-1dof", "pose-3dof"):
            s = get_suite(name).with_overrides(size=110)
            with tempfile.TemporaryDirectory() as d:
                summ = run(RunConfig(s, "icp"), Path(d) / "i", workers=1, progress=False)
            m = summ["metrics"]
            report(
                f"icp on {name} (110 views): median ms/view",
                m["ms_per_view_median"],
                "ms",
                "< 50 ms",
                m["ms_per_view_median"] < 50,
            )
            report(f"  icp on {name}: rotation error mean", m["rot_err_deg_mean"], "deg")
            report(f"  icp on {name}: rotation error median", m["rot_err_deg_median"], "deg")
            report(f"  icp on {name}: > 15 deg rate", 100 * m["gross_err_rate"], "%")
            report(f"  icp on {name}: class accuracy", 100 * m["class_acc"], "%")
