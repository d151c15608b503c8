"""The bathtub category: solid, deterministic, tabletop-sized, long along y with its taps
at +y, 2-fold about z exactly for a double-ended shell without taps, and every sub-style
drawn."""

from __future__ import annotations

import numpy as np

import beo_bench.objects.bathtub  # noqa: F401  (registers the category)
from beo_bench.geometry import symmetry_transformations
from beo_bench.objects.registry import instance_params
from tests.objects.category_checks import (
    declared_group_fits,
    deterministic_per_key,
    module_test_set,
    solid_and_sized,
    splits_disjoint,
)

CATEGORY = "bathtub"
SIZE_RANGE = (0.095, 0.17)  # largest extent, metres
test_set = module_test_set(CATEGORY)  # module-scoped: the first 50 test instances


def _two_fold(p: dict) -> bool:
    """A shell with two equal ends and no taps."""
    return p["style"] in ("freestanding", "clawfoot") and p["ends"] == "double" and not p["taps"]


def test_watertight_one_body_sized_and_long_along_y(test_set: list) -> None:
    solid_and_sized(test_set, SIZE_RANGE)
    for inst in test_set:
        m = inst.mesh
        p = instance_params(CATEGORY, "test", inst.index)
        # long along y (a corner tub a little less so), and low
        ratio = 1.05 if p["style"] == "corner" else 1.6
        assert m.extents[1] > ratio * m.extents[0], (inst.key, m.extents)
        assert m.extents[2] < 0.6 * m.extents[1], (inst.key, m.extents)


def test_open_basin(test_set: list) -> None:
    """A basin is open at the top: some vertical line down through the middle of the plan
    first meets the solid (the basin's floor) in the lower half of the tub's height."""
    for inst in test_set:
        m = inst.mesh
        u = np.linspace(-0.3, 0.3, 7)
        xy = np.array([(a * m.extents[0], b * m.extents[1]) for a in u for b in u])
        origins = np.column_stack([xy, np.full(len(xy), 1.0)])
        dirs = np.tile([0.0, 0.0, -1.0], (len(xy), 1))
        hits, _, _ = m.ray.intersects_location(origins, dirs, multiple_hits=False)
        assert len(hits), inst.key
        assert hits[:, 2].min() < m.bounds[0][2] + 0.5 * m.extents[2], inst.key


def test_taps_at_plus_y(test_set: list) -> None:
    """A mixer is the highest part of a tub without a swept-up backrest, at its +y end."""
    for inst in test_set:
        p = instance_params(CATEGORY, "test", inst.index)
        if not p["taps"] or p["ends"] == "single" or p["style"] == "clawfoot":
            continue
        v = inst.mesh.vertices
        top = v[v[:, 2] > v[:, 2].max() - 1e-4]
        assert top[:, 1].min() > 0.0, inst.key


def test_deterministic_per_key(test_set: list) -> None:
    deterministic_per_key(CATEGORY, test_set)


def test_symmetry_as_declared(test_set: list) -> None:
    """Declared 2-fold exactly for a double-ended shell without taps; every declared
    rotation keeps the solid (IoU > 0.95), and the quarter and half turns about z outside
    the group do not."""
    for inst in test_set:
        p = instance_params(CATEGORY, "test", inst.index)
        group = symmetry_transformations(inst.symmetry)
        assert not inst.symmetry["continuous"], inst.key
        assert len(group) == (2 if _two_fold(p) else 1), inst.key
    declared_group_fits(test_set)


def test_every_sub_style_occurs() -> None:
    ps = [instance_params(CATEGORY, "train", i) for i in range(200)]
    assert {p["style"] for p in ps} == {"built_in", "corner", "freestanding", "clawfoot"}
    for style in ("built_in", "corner", "freestanding", "clawfoot"):
        of = [p for p in ps if p["style"] == style]
        assert {p["ends"] for p in of} == {"double", "single"}, style
        assert {p["taps"] for p in of} == {True, False}, style
    assert {p["plinth"] for p in ps if p["style"] == "freestanding"} == {True, False}
    assert {p["apron_panel"] for p in ps if p["style"] == "built_in"} == {True, False}
    assert any(_two_fold(p) for p in ps)
    # oval and rounded-rectangle plans
    assert min(p["squareness"] for p in ps) < 2.3 and max(p["squareness"] for p in ps) > 4.0


def test_splits_disjoint() -> None:
    splits_disjoint(CATEGORY)
