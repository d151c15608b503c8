"""The dresser category: solid, deterministic, tabletop-sized, no rotational symmetry
(its front differs visibly from its back), and every sub-style drawn."""

from __future__ import annotations

import beo_bench.objects.dresser  # noqa: F401  (registers the category)
from beo_bench.objects.dresser import MAX_COLUMNS, plan
from beo_bench.objects.registry import instance_params
from tests.objects.category_checks import (
    deterministic_per_key,
    module_test_set,
    no_turn_about_z_keeps,
    solid_and_sized,
    splits_disjoint,
)

CATEGORY = "dresser"
SIZE_RANGE = (0.078, 0.16)  # largest extent, metres
test_set = module_test_set(CATEGORY)  # module-scoped: the first 50 test instances


def test_watertight_one_body_and_sized(test_set: list) -> None:
    solid_and_sized(test_set, SIZE_RANGE)
    for inst in test_set:
        m = inst.mesh
        # wider than deep (at least 1.3 x), under 7.5 cm deep: picked across the depth
        assert m.extents[1] > 1.3 * m.extents[0] and m.extents[0] < 0.075, (inst.key, m.extents)


def test_deterministic_per_key(test_set: list) -> None:
    deterministic_per_key(CATEGORY, test_set)


def test_no_rotational_symmetry(test_set: list) -> None:
    """Declared without symmetry, and indeed no half or quarter turn about z (nor the
    other probes of tests/objects/test_categories.py) keeps the solid: IoU < 0.95."""
    no_turn_about_z_keeps(test_set, quarter_xy_on=10)


def test_every_sub_style_occurs() -> None:
    ps = [instance_params(CATEGORY, "train", i) for i in range(200)]
    assert {p["form"] for p in ps} == {"low", "chest", "tall"}
    assert {p["support"] for p in ps} == {"plinth", "legs", "bracket"}
    assert {p["handle"] for p in ps} == {"knob", "bar", "recessed"}
    assert {p["front_style"] for p in ps} == {"overlay", "framed"}
    assert {p["leg_style"] for p in ps if p["support"] == "legs"} == {"square", "tapered", "round"}
    assert {p["mirror_shape"] for p in ps if p["mirror"] and p["form"] == "low"} == {
        "rect",
        "arched",
    }
    assert {min(int(p["columns"]), MAX_COLUMNS[str(p["form"])]) for p in ps} == {1, 2, 3}
    assert any(
        p["top_split"] and min(int(p["columns"]), MAX_COLUMNS[str(p["form"])]) == 1 for p in ps
    )
    assert {p["top_edge"] for p in ps} == {"square", "bevel"}


def test_drawer_counts_span_two_to_twelve() -> None:
    counts = {plan(instance_params(CATEGORY, "train", i)).drawers for i in range(200)}
    assert min(counts) == 2 and max(counts) == 12, counts


def test_splits_disjoint() -> None:
    splits_disjoint(CATEGORY)
