"""The declared doc tables (:class:`beo_bench.bench.doctables.boards.Table`): one renderer
draws a header, rows and cells of figures from a leaderboard directory, leaves out the rows
whose runs it lacks and waits (the pending note) for a page that is not there."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from beo_bench.bench.doctables.boards import (
    Boards,
    Cell,
    Fig,
    MissingFigureError,
    Pair,
    PendingSuiteError,
    Row,
    Table,
    backends,
)
from beo_bench.bench.doctables.render import PENDING, TABLES, render
from beo_bench.bench.suites import get_suite


def _board(root: Path) -> Boards:
    """A ``pick`` page of two rows (``hbeo``, ``icp``) and the pair of the one against the
    other."""
    seed = get_suite("pick").seed
    rows = [
        {"backend": name, "provenance": {"backend_kwargs": {}}, "track": None, "seed": seed,
         "n": n, "metrics": {"pick_success": v, "rot_err_deg_mean": r},
         "ci95": {"pick_success": [v - 0.05, v + 0.04]}}
        for name, n, v, r in (("hbeo", 40, 0.625, 12.25), ("icp", 38, 0.5, 30.0))
    ]  # fmt: skip
    pair = {"method": "hbeo", "baseline": "icp", "metric": "pick_success", "track": None,
            "diff": 0.125, "ci95": [0.02, 0.2], "verdict": "better", "items": 36,
            "baseline_value": 0.5, "method_value": 0.625}  # fmt: skip
    root.mkdir(parents=True, exist_ok=True)
    (root / "pick.json").write_text(json.dumps(rows))
    (root / "pick_paired.json").write_text(json.dumps([pair]))
    return Boards(root)


_VS_ICP = Pair("pick_success", baseline="icp")
TABLE = Table(
    ("backend", "success", "mean, success", "- `icp` [95%]", "`icp` - it", "items"),
    (*backends(("hbeo", "beo", "icp"), Fig("n")),  # no `beo` row on the page: left out
     Row("the dissertation", cells=("80.0%", "-", "-", "-", "-"))),
    cols=(Fig("pick_success", value="ci"),
          Cell((Fig("rot_err_deg_mean"), Fig("pick_success")), "{} / {}"),
          Cell((_VS_ICP,), when=(_VS_ICP,)),  # `icp` against itself: no pair, "-"
          Cell((Pair("pick_success", baseline="icp", sign=-1),
                Pair("pick_success", baseline="icp", value="shift")), when=(_VS_ICP,)),
          Fig("n")),
    suite="pick",
)  # fmt: skip


def test_a_declared_table_is_drawn_cell_by_cell(tmp_path) -> None:
    assert TABLE(_board(tmp_path / "lb")) == (
        "| backend | success | mean, success | - `icp` [95%] | `icp` - it | items |\n"
        "|---|---|---|---|---|---|\n"
        "| `hbeo` | 62.5% [57.5, 66.5] | 12.2 deg / 62.5% | +12.5 pts [+2.0, +20.0] **better** "
        "| -12.5 pts [-20.0, -2.0], +12.5 [+2.0, +20.0] | 40 |\n"
        "| `icp` | 50.0% [45.0, 54.0] | 30.0 deg / 50.0% | - | - | 38 |\n"
        "| the dissertation | 80.0% | - | - | - | - |\n"
    )


def test_a_declared_table_waits_for_its_page_and_a_missing_figure_is_an_error(tmp_path) -> None:
    with pytest.raises(PendingSuiteError, match=r"leaderboards/pick.json is not there"):
        TABLE(Boards(tmp_path))
    # through the page: the pending note in place of the old table
    TABLES["test-spec"] = TABLE
    try:
        out = render("<!-- table: test-spec -->\nold\n<!-- /table -->\n", Boards(tmp_path))
    finally:
        del TABLES["test-spec"]
    assert out == (
        "<!-- table: test-spec -->\n"
        + PENDING.format(reason="leaderboards/pick.json is not there")
        + "<!-- /table -->\n"
    )
    # a row the page has without the figure a cell asks for is not left out: an error
    broken = Table(("backend", "x"), backends(("hbeo",)), cols=(Fig("iou_mean"),), suite="pick")
    with pytest.raises(MissingFigureError, match="'hbeo' has no iou_mean"):
        broken(_board(tmp_path / "lb"))
    # no row at all shown: the table waits, saying why, rather than show bare headers
    empty = Table(("backend",), backends(("beo",), Fig("n")), suite="pick", empty="no `beo`")
    with pytest.raises(PendingSuiteError, match="no `beo`"):
        empty(_board(tmp_path / "lb"))
