"""The protocol enum is the table of docs/benchmark.md ("What a backend is told"), and the
views each protocol builds carry exactly the hints its fields say."""

from __future__ import annotations

from pathlib import Path

import pytest

from beo_bench.bench.evaluate import ItemViews
from beo_bench.bench.suites import SUITES, Kind, Protocol, get_suite

TABLE = Path(__file__).resolve().parents[2] / "docs" / "benchmark.md"


def _rows() -> dict[str, list[str]]:
    rows = {}
    for line in TABLE.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if (
            len(cells) == 4
            and cells[0].startswith("`")
            and cells[0].strip("`") in {p.value for p in Protocol}
        ):
            rows[cells[0].strip("`")] = cells
    return rows


@pytest.mark.parametrize("protocol", list(Protocol), ids=lambda p: p.value)
def test_the_docs_table_row_is_the_enums(protocol: Protocol) -> None:
    row = _rows()[protocol.value]
    suites = sorted(n for n, s in SUITES.items() if s.protocol is protocol)
    assert row[1] == ", ".join(f"`{n}`" for n in suites)
    assert row[2].startswith(protocol.reveals)
    assert row[3] == protocol.hides


@pytest.mark.parametrize(
    ("name", "pose", "up"),
    [("known-pose", True, False), ("pose-1dof", False, True), ("pose-3dof", False, False)],
)
def test_isolated_views_carry_the_protocols_hints_and_nothing_else(
    name: str, pose: bool, up: bool
) -> None:
    suite = get_suite(name).with_overrides(size=2)
    assert (suite.protocol.pose_hint, suite.protocol.up_hint) == (pose, up)
    assert suite.kind is Kind.ISOLATED
    items = ItemViews(suite)
    try:
        view = items.views(0)[0]
    finally:
        items.close()
    assert (view.pose_hint is not None) == suite.protocol.pose_hint
    assert (view.up_hint is not None) == suite.protocol.up_hint
    assert view.class_hint is None and view.ground_truth is None


def test_a_protocol_is_named_by_its_value() -> None:
    assert Protocol.of("1dof") is Protocol.ONE_DOF
    assert get_suite("pose-1dof").protocol == "1dof"  # a str enum: records stay strings
    with pytest.raises(ValueError, match="use one of known-pose, 1dof, 3dof, free"):
        Protocol.of("6dof")
