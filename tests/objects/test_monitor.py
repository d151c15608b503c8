"""The monitor category: every test instance one watertight solid of tabletop size,
deterministic per key, without rotational symmetry (a quarter and a half turn about z
change it visibly), its sub-styles all drawn, its splits disjoint."""

from __future__ import annotations

import beo_bench.objects.monitor  # noqa: F401  (registers monitor before CATEGORY_MODULES lists it)
from beo_bench.objects.registry import DEFAULT_SPLIT_SIZES, instance_params
from tests.objects.category_checks import (
    deterministic_per_key,
    module_test_set,
    no_turn_about_z_keeps,
    solid_and_sized,
    splits_disjoint,
)

CATEGORY = "monitor"
SIZE_RANGE = (0.07, 0.16)  # largest extent, metres: the panel's width (0.08-0.15 m aimed at)
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
        crt = p["back"] == "crt"
        seen.setdefault("back", set()).add(p["back"])
        seen.setdefault("aspect", set()).add(p["aspect"])
        if not crt:  # a CRT stands on its swivel foot, flat (whatever was drawn)
            seen.setdefault("stand", set()).add(p["stand"])
            seen.setdefault("curved", set()).add(bool(p["curved"]))
    assert seen["back"] == {"flat", "housing", "crt"}
    assert seen["aspect"] == {"4:3", "16:10", "16:9", "21:9"}
    assert seen["stand"] == {
        "post_round",
        "post_rect",
        "v_foot",
        "two_leg",
        "arm_clamp",
        "kickstand",
    }
    assert seen["curved"] == {True, False}


def test_splits_disjoint() -> None:
    splits_disjoint(CATEGORY)
