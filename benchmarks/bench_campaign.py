"""The whole campaign's figure: the predict CPU-hours of the committed leaderboards by suite
and backend (:func:`beo_bench.bench.campaign.campaign_cost`), the campaign's wall time on 2
cores, and the projection of the same rows with each backend's time per view divided by its
speed-up measured in this run (old path against new, where the code keeps the old one
callable). Target: half of today's.

A projection, not a campaign (8+ CPU-hours): ``committed ms per view / measured speed-up``
for each row, summed. The leaderboards record predict time only (the median per view or
per pick decision, times the items): rendering, scoring and physics are not in them, so
the figure is the backends' share of a campaign."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from harness import report

from beo_bench.bench.campaign import campaign_cost

LEADERBOARDS = Path(__file__).resolve().parents[1] / "leaderboards"


def _beo_speedup() -> float:
    # the one old path BEO keeps callable: its fine step with every Gram matrix gathered
    # afresh (the other changes of issue 52 are bit-identical rewrites, not kept), so this
    # is a lower bound of its speed-up over the committed code (2.2x measured old against
    # new on 12 views when it landed)
    import bench_beo

    return bench_beo.one_core("pose-3dof", 6, quiet=True)


SPEEDUPS: dict[str, Callable[[], float]] = {"beo": _beo_speedup}
"""backend -> a measurement of its speed-up per view (old time / new time, the two paths
timed alternately on the same views in this run); a backend not named keeps its committed
time."""


def main() -> None:
    today = campaign_cost(LEADERBOARDS)
    print(today.text())
    report("campaign: predict CPU-hours (committed leaderboards)", today.cpu_hours, "h")
    report("campaign: predict wall time on 2 cores", today.wall_hours(2), "h")
    measured = {b: f() for b, f in SPEEDUPS.items()}
    for b, x in sorted(measured.items()):
        report(f"campaign: {b}'s speed-up per view (old / new, this run)", x, "x")
    after = today.projected(measured)
    half = today.cpu_hours / 2
    report(
        "campaign: projected predict CPU-hours (same rows)",
        after.cpu_hours,
        "h",
        f"<= {half:.2f} (half of today's)",
        after.cpu_hours <= half,
        "projection: committed ms/view / measured speed-up"
        + ("" if measured else "; no faster path measured on this branch"),
    )
