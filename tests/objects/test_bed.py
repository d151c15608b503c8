"""The bed category: solid, deterministic, tabletop-sized, long along x with the head at
-x, 2-fold about z exactly when it is a plain mattress on a base, and every sub-style
drawn."""

from __future__ import annotations

import beo_bench.objects.bed  # noqa: F401  (registers the category)
from beo_bench.geometry import symmetry_transformations
from beo_bench.objects.registry import instance_params
from tests.objects.category_checks import (
    declared_group_fits,
    deterministic_per_key,
    module_test_set,
    solid_and_sized,
    splits_disjoint,
)

CATEGORY = "bed"
SIZE_RANGE = (0.10, 0.18)  # largest extent, metres
test_set = module_test_set(CATEGORY)  # module-scoped: the first 50 test instances


def _plain(p: dict) -> bool:
    """A mattress on a base: no boards, no pillows, neither daybed nor bunk."""
    return p["style"] == "standard" and p["headboard"] == "none" and not p["pillows"]


def test_watertight_one_body_sized_and_long_along_x(test_set: list) -> None:
    solid_and_sized(test_set, SIZE_RANGE)
    for inst in test_set:
        m = inst.mesh
        # long and low: the length along x, at least 1.2 times the width
        assert m.extents[0] == m.extents.max() and m.extents[0] > 1.2 * m.extents[1], inst.key


def test_head_at_minus_x(test_set: list) -> None:
    """A headboard is the highest part of a standard bed and stands at its -x end."""
    for inst in test_set:
        p = instance_params(CATEGORY, "test", inst.index)
        if p["style"] != "standard" or p["headboard"] == "none":
            continue
        v = inst.mesh.vertices
        top = v[v[:, 2] > v[:, 2].max() - 1e-4]
        assert top[:, 0].max() < 0.0, inst.key


def test_deterministic_per_key(test_set: list) -> None:
    deterministic_per_key(CATEGORY, test_set)


def test_symmetry_as_declared(test_set: list) -> None:
    """Declared 2-fold exactly for a plain bed; every declared rotation keeps the solid
    (IoU > 0.95), and the quarter and half turns about z outside the group do not."""
    for inst in test_set:
        p = instance_params(CATEGORY, "test", inst.index)
        group = symmetry_transformations(inst.symmetry)
        assert not inst.symmetry["continuous"], inst.key
        assert len(group) == (2 if _plain(p) else 1), inst.key
    declared_group_fits(test_set)


def test_every_sub_style_occurs() -> None:
    ps = [instance_params(CATEGORY, "train", i) for i in range(200)]
    assert {p["style"] for p in ps} == {"standard", "daybed", "bunk"}
    assert {p["base"] for p in ps} == {"legs", "plinth", "box"}
    standard = [p for p in ps if p["style"] == "standard"]
    assert {p["headboard"] for p in standard} == {"none", "panel", "slatted", "upholstered"}
    assert any(p["footboard"] and p["headboard"] != "none" for p in standard)
    assert any(p["pillows"] and p["duvet"] for p in standard)
    assert any(p["headboard"] == "panel" and p["arched"] for p in standard)
    assert any(p["headboard"] == "panel" and p["posts"] for p in standard)
    assert any(_plain(p) for p in ps)  # the 2-fold plain bed


def test_splits_disjoint() -> None:
    splits_disjoint(CATEGORY)
