"""The desk category: every test instance one watertight solid of tabletop size,
deterministic per key, without rotational symmetry (a quarter and a half turn about z
change it visibly), its sub-styles all drawn, its splits disjoint."""

from __future__ import annotations

import beo_bench.objects.desk  # noqa: F401  (registers desk before CATEGORY_MODULES lists it)
from beo_bench.objects.registry import DEFAULT_SPLIT_SIZES, instance_params
from tests.objects.category_checks import (
    deterministic_per_key,
    module_test_set,
    no_turn_about_z_keeps,
    solid_and_sized,
    splits_disjoint,
)

CATEGORY = "desk"
SIZE_RANGE = (0.07, 0.18)  # largest extent, metres (table.py's tops are 0.09-0.16 m)
test_set = module_test_set(CATEGORY)  # module-scoped: the first 50 test instances


def test_solid_one_body_and_sized(test_set: list) -> None:
    solid_and_sized(test_set, SIZE_RANGE)


def test_deterministic_per_key(test_set: list) -> None:
    deterministic_per_key(CATEGORY, test_set, (0, 7, 31))


def test_no_symmetry_and_turns_about_z_change_it(test_set: list) -> None:
    """Declared asymmetric, so quarter and half turns about z must score below 0.95."""
    no_turn_about_z_keeps(test_set)


def test_sub_styles_occur() -> None:
    seen: dict[str, set] = {}
    for i in range(DEFAULT_SPLIT_SIZES["train"]):
        p = instance_params(CATEGORY, "train", i)
        style = str(p["style"])
        seen.setdefault("style", set()).add(style)
        seen.setdefault("handle", set()).add(p["handle"])
        if style == "one_pedestal":
            seen.setdefault("end_support", set()).add(p["end_support"])
        # a two-pedestal desk builds no wing
        seen.setdefault("wing", set()).add(bool(p["wing"]) and style != "two_pedestals")
        seen.setdefault("hutch", set()).add(bool(p["hutch"]))
        if style != "writing":
            seen.setdefault("center_drawer", set()).add(bool(p["center_drawer"]))
        if style == "writing":
            seen.setdefault("writing_back", set()).add(bool(p["modesty"]))
    assert seen["style"] == {"writing", "one_pedestal", "two_pedestals", "panel_ends"}
    assert seen["handle"] == {"knob", "bar", "lip"}
    assert seen["end_support"] == {"legs", "panel"}
    for flag in ("wing", "hutch", "center_drawer", "writing_back"):
        assert seen[flag] == {True, False}, flag


def test_splits_disjoint() -> None:
    splits_disjoint(CATEGORY)
