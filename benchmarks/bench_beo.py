"""BEO figures (issue 5), the dissertation's values beside ours: training the default model,
and the median time per view of known-pose classification + completion, 1-DOF and 3-DOF
joint pose + class + completion (one process, torch on both cores). Accuracy is in the
leaderboards (``beo-bench all --suites known-pose pose-1dof pose-3dof --backends beo``)."""

from __future__ import annotations

import statistics
import time

from beo_bench.envs.pick import default_categories
from harness import report

from beo_bench.backend import get_backend
from beo_bench.bench.evaluate import Evaluator
from beo_bench.bench.suites import get_suite

# (suite, views timed, target ms, dissertation's time per view)
CASES = (
    ("known-pose", 40, 100.0, "1.13 s (Table 4.2)"),
    ("pose-1dof", 20, 1000.0, "672.97 s (Table 4.2)"),
    ("pose-3dof", 6, 10000.0, "3529.88 s (Table 4.2)"),
)


def main() -> None:
    from beo_bench.perception.beo_model import BEOConfig, load_model, train_beo

    cats = default_categories()
    load_model(None, cats, 32, progress=True)  # the default model (voxels cached after)
    t0 = time.perf_counter()
    model = train_beo(BEOConfig(categories=cats))
    train_s = time.perf_counter() - t0
    report(
        f"train the default BEO model ({len(cats)} classes, 32^3, voxels cached)",
        train_s,
        "s",
        "< 180 s",
        train_s < 180,
        f"k={model.k}; voxels loaded in {model.info['data_s']} s",
    )
    backend = get_backend("beo")
    backend.prepare(cats)
    for name, n, target_ms, theirs in CASES:
        ev = Evaluator(get_suite(name), "beo")
        views = [ev.isolated_view(i)[0] for i in range(n)]
        ev.close()
        backend.predict(views[0])
        times = []
        for v in views:
            t0 = time.perf_counter()
            backend.predict(v)
            times.append(1000 * (time.perf_counter() - t0))
        ms = statistics.median(times)
        report(
            f"beo {name}: median per view ({n} views)",
            ms,
            "ms",
            f"< {target_ms:.0f} ms",
            ms < target_ms,
            f"dissertation: {theirs}",
        )


if __name__ == "__main__":
    main()
