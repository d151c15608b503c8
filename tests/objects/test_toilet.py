"""The toilet category: solid, deterministic, tabletop-sized, facing +x with its tank,
panel or pipe at -x, no rotational symmetry, and every sub-style drawn."""

from __future__ import annotations

import beo_bench.objects.toilet  # noqa: F401  (registers the category)
from beo_bench.objects.registry import instance_params
from tests.objects.category_checks import (
    deterministic_per_key,
    module_test_set,
    no_turn_about_z_keeps,
    solid_and_sized,
    splits_disjoint,
)

CATEGORY = "toilet"
SIZE_RANGE = (0.06, 0.10)  # largest extent, metres
test_set = module_test_set(CATEGORY)  # module-scoped: the first 50 test instances


def test_watertight_one_body_and_sized(test_set: list) -> None:
    solid_and_sized(test_set, SIZE_RANGE)
    for inst in test_set:
        m = inst.mesh
        # deeper (x) than wide (y)
        assert m.extents[0] > 1.2 * m.extents[1], (inst.key, m.extents)


def test_front_at_plus_x(test_set: list) -> None:
    """The bowl's front is the foremost point and the tank, panel or pipe stands behind:
    the highest points are in the rear half (with the lid down or off), the floor contact
    of a wall-hung toilet is all behind the bowl."""
    for inst in test_set:
        p = instance_params(CATEGORY, "test", inst.index)
        v = inst.mesh.vertices
        lo, hi = inst.mesh.bounds
        if p["lid"] != "up":
            top = v[v[:, 2] > hi[2] - 1e-4]
            assert top[:, 0].max() < 0.0, inst.key
        if p["tank"] == "panel" and p["wall_hung"]:
            floor = v[v[:, 2] < lo[2] + 1e-4]
            assert floor[:, 0].max() < lo[0] + 0.4 * inst.mesh.extents[0], inst.key


def test_deterministic_per_key(test_set: list) -> None:
    deterministic_per_key(CATEGORY, test_set)


def test_no_rotational_symmetry(test_set: list) -> None:
    """Declared without symmetry, and indeed no half or quarter turn about z keeps the
    solid (IoU < 0.95)."""
    no_turn_about_z_keeps(test_set)


def test_every_sub_style_occurs() -> None:
    ps = [instance_params(CATEGORY, "train", i) for i in range(200)]
    assert {p["tank"] for p in ps} == {"close_coupled", "panel", "none"}
    assert {p["wall_hung"] for p in ps if p["tank"] == "panel"} == {True, False}
    assert {p["lid"] for p in ps} == {"down", "up", "none"}
    assert {p["seat"] for p in ps} == {"closed", "open_front"}
    assert {p["flush"] for p in ps if p["tank"] == "close_coupled"} == {"button", "lever"}
    # round and elongated bowls
    assert min(p["bowl_length"] for p in ps) < 0.44 and max(p["bowl_length"] for p in ps) > 0.5


def test_splits_disjoint() -> None:
    splits_disjoint(CATEGORY)
