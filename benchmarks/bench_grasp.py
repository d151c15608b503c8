"""Grasp planning figures (``pick``): what planning over the MDN's pose samples costs.

- Per pick decision of ``hbeo-mdn-likelihood`` and ``hbeo-mdn-posterior`` with
  ``grasp=robust`` (N = 25 samples): the CPU time of the single-estimate planner
  (``plan_grasps`` on the best sample's surface) and of the robust re-ranking
  (``robust_order``) on the same decision; their ratio, (plan + re-rank) / plan, has a
  target of at most 2. Paired in one process, so load on the machine cancels.

``python benchmarks/run.py grasp`` runs it (about a minute on 2 cores).
"""

from __future__ import annotations

import statistics
import time

from harness import report

from beo_bench.bench import evaluate as E
from beo_bench.bench.kinds import pick as P
from beo_bench.bench.suites import get_suite

EPISODES = 30


def main() -> None:
    suite = get_suite("pick").with_overrides(size=EPISODES)
    plan, rerank = P.plan_grasps, P.robust_order
    for backend in ("hbeo-mdn-likelihood", "hbeo-mdn-posterior"):
        times: dict[str, list[float]] = {"plan": [], "rerank": []}

        def timed(fn, key):
            def inner(*a, **k):
                t0 = time.process_time()
                out = fn(*a, **k)
                times[key].append(1000 * (time.process_time() - t0))  # noqa: B023
                return out

            return inner

        P.plan_grasps, P.robust_order = timed(plan, "plan"), timed(rerank, "rerank")
        try:
            ev = E.Evaluator.of(suite, backend, {"grasp": "robust"})
            for i in range(EPISODES):
                ev.run_item(i)
            ev.close()
        finally:
            P.plan_grasps, P.robust_order = plan, rerank
        pairs = list(zip(times["plan"], times["rerank"], strict=False))
        ratio = statistics.median((p + r) / p for p, r in pairs)
        report(f"{backend}: single-estimate planning (ms CPU, median)",
               statistics.median(times["plan"]), "ms")  # fmt: skip
        report(f"{backend}: robust re-ranking over 25 samples (ms CPU)",
               statistics.median(times["rerank"]), "ms")  # fmt: skip
        report(f"{backend}: robust / single planning time per decision", ratio, "x",
               "<= 2", ratio <= 2.0, note=f"{len(pairs)} decisions")  # fmt: skip


if __name__ == "__main__":
    main()
