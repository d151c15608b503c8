"""The sensor tables: robustness of each backend across depth sensors, and the BOP figures per
sensor.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from beo_bench.bench.doctables.boards import (
    METHODS,
    Boards,
    MissingFigureError,
    PendingSuiteError,
    _table,
    num,
    pct,
)
from beo_bench.bench.pages.entries import BOUNDS

RobustnessCell = tuple[str, str | None, str, str]
"""One column of a robustness headline: (suite, track, metric, header)."""
ROBUSTNESS_CELLS: tuple[RobustnessCell, ...] = (
    ("known-pose", None, "class_acc", "`known-pose` class acc."),
    ("pose-1dof", "class-free", "gross_err_rate", "`pose-1dof` > 15 deg (class-free)"),
    ("pose-3dof", "class-free", "gross_err_rate", "`pose-3dof` > 15 deg (class-free)"),
    ("tabletop", None, "class_acc", "`tabletop` class acc."),
    ("pick", None, "pick_success", "`pick` success"),
)
"""The robustness headline's columns: the main suites."""
ROBUSTNESS_MORE_CELLS: tuple[RobustnessCell, ...] = (
    ("pose-3dof-ood", "class-free", "gross_err_rate", "`pose-3dof-ood` > 15 deg (class-free)"),
    ("modelnet10-known-pose", None, "class_acc", "`modelnet10-known-pose` class acc."),
    ("modelnet10-1dof", "class-free", "gross_err_rate", "`modelnet10-1dof` > 15 deg (class-free)"),
    (
        "pose-1dof+modelnet10",
        "class-free",
        "gross_err_rate",
        "`pose-1dof+modelnet10` > 15 deg (class-free)",
    ),
    ("modelnet10-3dof", "class-free", "gross_err_rate", "`modelnet10-3dof` > 15 deg (class-free)"),
)
"""The second robustness table's columns: the out-of-distribution and ModelNet10 suites."""
SENSOR_ORDER = ("kinect-v1", "d435")


def _sensor_pairs(
    b: Boards, suite: str, track: str | None, metric: str
) -> dict[tuple[str, str], dict[str, Any]]:
    """``{(backend, sensor): entry}`` of the page's robustness pairs (each sensor's run
    against the backend's ``ideal`` run, paired on the same items) for one metric."""
    out = {}
    for p in b.paired(suite):
        if p.get("baseline_sensor") == "ideal" and p["metric"] == metric:
            if p.get("track") == track:
                out[(p["method"], p["sensor"])] = p
    return out


NOT_RUN_SENSORS = "ideal only at this version"
"""A robustness cell of a page whose runs under the other sensors are not made yet."""


def robustness_table(cells: tuple[RobustnessCell, ...]) -> Callable[[Boards], str]:
    """docs/sensors.md's robustness tables: each backend's figure ideal -> kinect-v1 -> d435
    on suites run under all three, each step in bold where its paired interval (on the same
    items) excludes 0 the worse way."""

    def table(b: Boards) -> str:
        head = ["backend", *(h for *_, h in cells)]
        # one lookup per column: two columns may share a suite and metric on two tracks
        pairs = [_sensor_pairs(b, s, t, m) for s, t, m, _ in cells]
        rows = []
        for name in (*METHODS, *BOUNDS):
            row = [f"`{name}`"]
            for found, (suite, _, metric, _) in zip(pairs, cells, strict=True):
                if not found:
                    # the page holds no sensor section at its version (a campaign made the
                    # suite's own sensor first): the column says so, the others stand
                    b.rows(suite)  # the page itself must be there (else the table waits)
                    row.append(NOT_RUN_SENSORS)
                    continue
                if any((name, tag) not in found for tag in SENSOR_ORDER):
                    raise MissingFigureError(
                        f"leaderboards/{suite}_paired.json has no {name} {metric} under "
                        "every sensor"
                    )
                got = [found[(name, tag)] for tag in SENSOR_ORDER]
                steps = [pct(got[0]["baseline_value"])]
                for g in got:
                    v = pct(g["method_value"])
                    steps.append(f"**{v}**" if g["verdict"] == "worse" else v)
                row.append(" -> ".join(steps))
            rows.append(row)
        return _table(head, rows)

    return table


BOP_SUITE = "pose-1dof"
BOP_SENSORS = ("ideal", "kinect-v1", "d435")


def bop_figures(b: Boards) -> str:
    """docs/bop.md's table: BOP 2019's AR and its parts, and NOCS's 10deg5cm and IoU50, of
    every backend on ``pose-1dof`` (class-free) under each sensor."""
    rows_by = {
        (r["backend"], r.get("sensor") or "ideal", r.get("track")): r
        for r in b.rows(BOP_SUITE)
        if not r.get("provenance", {}).get("backend_kwargs")
    }
    head = ["backend", *(f"BOP AR `{t}`" for t in BOP_SENSORS), "AR_VSD / AR_MSSD / AR_MSPD "
            "`ideal`", "10deg5cm, 3D IoU50 `ideal`"]  # fmt: skip
    rows = []
    for name in (*METHODS, *BOUNDS):
        keys = [(name, t, "class-free") for t in BOP_SENSORS]
        if any(k not in rows_by or "ar_bop" not in rows_by[k]["metrics"] for k in keys):
            raise PendingSuiteError(
                f"leaderboards/{BOP_SUITE}.json has no BOP figures of {name} under every sensor"
            )
        got = [rows_by[k] for k in keys]
        m = got[0]["metrics"]
        parts = " / ".join(num(m[k]) for k in ("ar_vsd", "ar_mssd", "ar_mspd"))
        nocs = f"{pct(m['acc_10deg5cm'])}, {pct(m['iou3d_50'])}"
        rows.append([f"`{name}`", *(num(g["metrics"]["ar_bop"]) for g in got), parts, nocs])
    return _table(head, rows)
