"""Synthetic run directories for the comparison and leaderboard tests: ``results.jsonl``
rows written by hand and the summary the package computes from them (``summarise``), with
the keys the runner adds (track, hint use, model digest, provenance). Nothing is rendered,
so these tests take milliseconds."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

from beo_bench.bench.rows import rows_of
from beo_bench.bench.suites import Suite, get_suite
from beo_bench.bench.summary import summarise

CATEGORIES = ("bottle", "bowl", "mug")


def pose_row(item: int, view: int = 0, **values: Any) -> dict[str, Any]:
    """One scored view of a pose suite; ``values`` override the scores (``rot_err_deg``,
    ``iou``, ...). ``failure="..."`` makes it a failed view without scores."""
    c = item % len(CATEGORIES)
    row: dict[str, Any] = {
        "item": item,
        "view": view,
        "key": f"{CATEGORIES[c]}/test/{item}",
        "category": CATEGORIES[c],
        "true_class": c,
        "class_given": False,
        "pred_class": c,
        "correct": True,
        "rot_err_deg": 10.0,
        "trans_err_cm": 1.0,
        "size_err_pct": 5.0,
        "iou": 0.5,
        "iou_cam": 0.5,
        "edt_err": 100.0,
        "fscore": 0.5,
        "chamfer_l1": 0.02,
        "viewpoint_est": [0.0, 30.0],
        "viewpoint_gt": [0.0, 30.0],
        "ms": 5.0,
        "failure": None,
    }
    if values.get("failure"):
        for k in ("pred_class", "correct", "rot_err_deg", "trans_err_cm", "size_err_pct", "iou",
                  "iou_cam", "edt_err", "fscore", "chamfer_l1", "viewpoint_est", "ms"):  # fmt: skip
            row.pop(k)
    row.update(values)
    return row


def write_run(
    out: Path,
    backend: str,
    rows: list[dict[str, Any]],
    suite: str = "pose-1dof",
    track: str | None = "class-given",
    seed: int | None = None,
    size: int | None = None,
    version: int | None = None,
    kwargs: dict[str, Any] | None = None,
    digest: str | None = None,
    uses_hint: bool = True,
    privileged: bool = False,
    sensor: str | None = None,
) -> dict[str, Any]:
    """Write ``out/results.jsonl`` and ``out/summary.json`` of a finished run; returns the
    summary. ``size`` defaults to the number of items in ``rows``; ``sensor``: the depth
    sensor (None: the suite's own)."""
    base = get_suite(suite)
    size = size if size is not None else len({r["item"] for r in rows})
    s: Suite = base.with_overrides(size=size, seed=seed).with_sensor(sensor)
    if track is not None and s.class_hint:
        s = s.with_overrides(track=track)
    if version is not None:
        s = replace(s, version=version)
    if track == "class-given" and uses_hint:
        rows = [{**r, "class_given": True} for r in rows]
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    summary = summarise(
        s,
        backend,
        rows_of(sorted(rows, key=lambda r: (r["item"], r["view"]))),
        uses_class_hint=uses_hint,
        model_digest=digest,
        privileged=privileged,
        provenance={
            "suite": s.record(),
            "backend_kwargs": kwargs or {},
            "model_digest": digest,
            "library_version": 1,
        },
    ).to_json()
    (out / "summary.json").write_text(json.dumps(summary))
    return summary
