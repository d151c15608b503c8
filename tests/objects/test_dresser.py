"""The dresser category: solid, deterministic, tabletop-sized, no rotational symmetry
(its front differs visibly from its back), and every sub-style drawn."""

from __future__ import annotations

import numpy as np
import pytest

import beo_bench.objects.dresser  # noqa: F401  (registers the category)
from beo_bench.geometry import axis_angle
from beo_bench.objects import DEFAULT_SPLIT_SIZES, SPLITS, ObjectSet, instance_from_key
from beo_bench.objects.cache import mesh_hash
from beo_bench.objects.dresser import MAX_COLUMNS, plan
from beo_bench.objects.processing import rotation_iou
from beo_bench.objects.registry import generate, instance_params

CATEGORY = "dresser"
SIZE_RANGE = (0.078, 0.16)  # largest extent, metres


@pytest.fixture(scope="module")
def test_set() -> list:
    return list(ObjectSet("test", [CATEGORY], per_category=50))


def test_watertight_one_body_and_sized(test_set: list) -> None:
    for inst in test_set:
        m = inst.mesh
        assert m.is_watertight, inst.key
        assert m.body_count == 1, (inst.key, "one connected solid, no closed cavities")
        assert SIZE_RANGE[0] <= m.extents.max() <= SIZE_RANGE[1], (inst.key, m.extents)
        # wider than deep (at least 1.3 x), under 7.5 cm deep: picked across the depth
        assert m.extents[1] > 1.3 * m.extents[0] and m.extents[0] < 0.075, (inst.key, m.extents)


def test_deterministic_per_key(test_set: list) -> None:
    for inst in test_set[:3]:
        again = instance_from_key(inst.key)
        assert again.content_hash == inst.content_hash
        rebuilt = generate(CATEGORY, instance_params(CATEGORY, "test", inst.index))
        assert mesh_hash(rebuilt.mesh) == inst.content_hash
    assert test_set[0].content_hash != test_set[1].content_hash


def test_no_rotational_symmetry(test_set: list) -> None:
    """Declared without symmetry, and indeed no half or quarter turn about z (nor the
    other probes of tests/objects/test_categories.py) keeps the solid: IoU < 0.95."""
    probes = [axis_angle([0.0, 0.0, 1.0], a) for a in (np.pi, np.pi / 2)]
    for inst in test_set:
        assert not inst.symmetry["continuous"] and not inst.symmetry["discrete"], inst.key
        for R in probes:
            assert rotation_iou(inst.mesh, R) < 0.95, (inst.key, R.round(3))
    others = [axis_angle([1.0, 0.0, 0.0], np.pi / 2), axis_angle([0.0, 1.0, 0.0], np.pi / 2)]
    for inst in test_set[:10]:
        for R in others:
            assert rotation_iou(inst.mesh, R) < 0.95, (inst.key, R.round(3))


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
    seen: dict[str, str] = {}
    for split in SPLITS:
        for i in range(DEFAULT_SPLIT_SIZES[split]):
            sig = repr(sorted(instance_params(CATEGORY, split, i).items()))
            assert sig not in seen, f"{split}/{i} repeats {seen.get(sig)}"
            seen[sig] = f"{split}/{i}"
