"""A run directory's typed records read and write its JSON unchanged, and one identity says
which runs scored the same items (the sensor included)."""

from __future__ import annotations

import json

from beo_bench.bench.rows import Row, row_line, scan_rows
from beo_bench.bench.rundir import ItemsIdentity, Summary
from beo_bench.bench.suites import get_suite


def test_a_row_writes_back_the_line_it_was_read_from(tmp_path) -> None:
    first = {"item": 3, "view": 0, "item_rows": 2, "category": "mug", "true_class": 1,
             "failure": None, "ms": 12.5, "rot_err_deg": 0.1 + 0.2,
             "viewpoint_gt": [0.0, 30.0]}  # fmt: skip
    second = {"item": 3, "view": 1, "category": "mug", "true_class": 1,
              "failure": "boom", "ms": None}  # fmt: skip
    text = row_line(first) + row_line(second)
    path = tmp_path / "results.jsonl"
    path.write_text(text)
    rows = scan_rows(path).rows
    assert "".join(row_line(r.to_json()) for r in rows) == text  # keys, floats, absent keys
    a, b = rows
    assert (a.item, a.view, a.item_rows, a.category, a.true_class) == (3, 0, 2, "mug", 1)
    assert (a.failure, a.ms) == (None, 12.5) and (b.failure, b.ms, b.item_rows) == (
        "boom",
        None,
        None,
    )
    assert Row.parse(b'{"item": -1, "view": 0}') is None and Row.parse(b"[1]") is None


def test_a_summary_reads_and_writes_its_json_unchanged() -> None:
    obj = {"suite": "pose-1dof", "suite_version": 3, "track": None, "backend": "icp", "n": 2,
           "failures": 0, "failure_kinds": {}, "metrics": {"iou_mean": 0.1 + 0.2}, "ci95": {},
           "categories": ["mug"], "per_category": {}, "scoring": {}, "seed": 2000,
           "uses_class_hint": False, "model_digest": None, "privileged": False,
           "provenance": {"suite": {"name": "pose-1dof"}}, "sensor": "ideal"}  # fmt: skip
    assert json.dumps(Summary.from_json(obj).to_json()) == json.dumps(obj)


def _summary(suite: str, sensor: str | None = None, **over: object) -> dict[str, object]:
    s = get_suite(suite).with_sensor(sensor)
    return {"suite": s.name, "suite_version": s.version, "seed": s.seed, "track": s.track,
            "sensor": s.sensor, "provenance": {"suite": s.record(), "library_version": 1},
            **over}  # fmt: skip


def test_the_items_identity_includes_the_sensor_unless_asked_to_pair_across_sensors() -> None:
    ideal = ItemsIdentity.of(_summary("pose-1dof"))
    kinect = ItemsIdentity.of(_summary("pose-1dof", "kinect-v1"))
    assert ideal.differences(ItemsIdentity.of(_summary("pose-1dof", size=7))) == []
    diffs = ideal.differences(kinect)
    assert ("sensor", "ideal", "kinect-v1") in diffs
    assert any(what == "suite record sensor_version" for what, _, _ in diffs)
    assert ideal.differences(kinect, sensor=False) == []  # the sensor's model version too
    other_seed = ItemsIdentity.of(_summary("pose-1dof", seed=7))
    assert [w for w, _, _ in ideal.differences(other_seed)] == ["seed"]
