"""The toilet category: solid, deterministic, tabletop-sized, facing +x with its tank,
panel or pipe at -x, no rotational symmetry, and every sub-style drawn."""

from __future__ import annotations

import numpy as np
import pytest

import beo_bench.objects.toilet  # noqa: F401  (registers the category)
from beo_bench.geometry import axis_angle
from beo_bench.objects import DEFAULT_SPLIT_SIZES, SPLITS, ObjectSet, instance_from_key
from beo_bench.objects.cache import mesh_hash
from beo_bench.objects.processing import rotation_iou
from beo_bench.objects.registry import generate, instance_params

CATEGORY = "toilet"
SIZE_RANGE = (0.06, 0.10)  # largest extent, metres


@pytest.fixture(scope="module")
def test_set() -> list:
    return list(ObjectSet("test", [CATEGORY], per_category=50))


def test_watertight_one_body_and_sized(test_set: list) -> None:
    for inst in test_set:
        m = inst.mesh
        assert m.is_watertight, inst.key
        assert m.body_count == 1, (inst.key, "one connected solid, no closed cavities")
        assert SIZE_RANGE[0] <= m.extents.max() <= SIZE_RANGE[1], (inst.key, m.extents)
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
    for inst in test_set[:3]:
        again = instance_from_key(inst.key)
        assert again.content_hash == inst.content_hash
        rebuilt = generate(CATEGORY, instance_params(CATEGORY, "test", inst.index))
        assert mesh_hash(rebuilt.mesh) == inst.content_hash
    assert test_set[0].content_hash != test_set[1].content_hash


def test_no_rotational_symmetry(test_set: list) -> None:
    """Declared without symmetry, and indeed no half or quarter turn about z keeps the
    solid (IoU < 0.95)."""
    probes = [axis_angle([0.0, 0.0, 1.0], a) for a in (np.pi, np.pi / 2)]
    for inst in test_set:
        assert not inst.symmetry["continuous"] and not inst.symmetry["discrete"], inst.key
        for R in probes:
            assert rotation_iou(inst.mesh, R) < 0.95, (inst.key, R.round(3))


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
    seen: dict[str, str] = {}
    for split in SPLITS:
        for i in range(DEFAULT_SPLIT_SIZES[split]):
            sig = repr(sorted(instance_params(CATEGORY, split, i).items()))
            assert sig not in seen, f"{split}/{i} repeats {seen.get(sig)}"
            seen[sig] = f"{split}/{i}"
