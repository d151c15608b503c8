"""What a campaign costs (``make bench``'s campaign figure): the predict time of the rows
on the leaderboard pages, each run once, and its projection under measured speed-ups."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from beo_bench.bench.campaign import campaign_cost


def _row(suite: str, backend: str, n: int, metrics: dict, track: str | None = None) -> dict:
    prov = {"backend_kwargs": {}}
    return {"suite": suite, "backend": backend, "track": track, "sensor": "ideal", "seed": 0,
            "n": n, "metrics": metrics, "provenance": prov}  # fmt: skip


def test_cost_is_items_times_the_median_each_run_once(tmp_path: Path) -> None:
    a = _row("pose-3dof", "beo", 1000, {"ms_per_view_median": 1800.0})
    b = _row("pose-3dof", "beo", 1000, {"ms_per_view_median": 900.0}, track="class-free")
    # a pick row is timed per decision (an episode's views and its grasp choice)
    p = _row("pick", "icp", 500, {"ms_per_view_median": 10.0, "ms_per_decision_median": 72.0})
    failed = _row("pose-3dof", "random", 10, {"ms_per_view_median": float("nan")})
    (tmp_path / "pose-3dof.json").write_text(json.dumps([a, b, failed]))
    (tmp_path / "pose-3dof_paired.json").write_text(json.dumps([{"not": "a row"}]))
    (tmp_path / "pick.json").write_text(json.dumps([p]))
    (tmp_path / "ablations").mkdir()
    (tmp_path / "ablations" / "pose-3dof.json").write_text(json.dumps([a]))  # the same run
    cost = campaign_cost(tmp_path)
    assert len(cost.rows) == 3
    assert cost.hours_by() == {
        ("pose-3dof", "beo"): pytest.approx((1800.0 + 900.0) / 3600),
        ("pick", "icp"): pytest.approx(500 * 0.072 / 3600),
    }
    assert cost.cpu_hours == pytest.approx((2700.0 + 36.0) / 3600)
    assert cost.wall_hours(2) == pytest.approx(cost.cpu_hours / 2)
    # the projection divides each named backend's times by its speed-up, the rest stay
    after = cost.projected({"beo": 4.0})
    assert after.hours_by()[("pose-3dof", "beo")] == pytest.approx(2700.0 / 4 / 3600)
    assert after.hours_by()[("pick", "icp")] == cost.hours_by()[("pick", "icp")]
    text = cost.text()
    assert "3 runs" in text and "pose-3dof" in text and "not recorded" in text
