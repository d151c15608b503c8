"""The night stand category: solid, deterministic, tabletop-sized, no rotational symmetry
(its front differs visibly from its back, the open table style too), and every sub-style
drawn."""

from __future__ import annotations

import numpy as np
import pytest

import beo_bench.objects.night_stand  # noqa: F401  (registers the category)
from beo_bench.geometry import axis_angle
from beo_bench.objects import DEFAULT_SPLIT_SIZES, SPLITS, ObjectSet, instance_from_key
from beo_bench.objects.cache import mesh_hash
from beo_bench.objects.processing import rotation_iou
from beo_bench.objects.registry import generate, instance_params

CATEGORY = "night_stand"
SIZE_RANGE = (0.06, 0.117)  # largest extent, metres


@pytest.fixture(scope="module")
def test_set() -> list:
    return list(ObjectSet("test", [CATEGORY], per_category=50))


def test_watertight_one_body_and_sized(test_set: list) -> None:
    for inst in test_set:
        m = inst.mesh
        assert m.is_watertight, inst.key
        assert m.body_count == 1, (inst.key, "one connected solid, no closed cavities")
        assert SIZE_RANGE[0] <= m.extents.max() <= SIZE_RANGE[1], (inst.key, m.extents)
        # wider than deep: a quarter turn about z is no symmetry of the plan
        assert m.extents[1] > 1.15 * m.extents[0], (inst.key, m.extents)


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


def test_table_style_front_differs_about_its_centre_of_mass(test_set: list) -> None:
    """The known trap: a table night stand open between its legs could be nearly
    symmetric under a half turn, its drawer front the only difference. Its half turn
    about the vertical axis through the centre of mass (the axis a symmetry would have to
    use) still changes it: IoU < 0.95."""
    tables = [i for i in test_set if i.params["style"] == "table"]
    assert tables
    R = axis_angle([0.0, 0.0, 1.0], np.pi)
    for inst in tables:
        c = inst.mesh.center_mass
        T = np.eye(4)
        T[:3, :3] = R
        T[:2, 3] = (c - R @ c)[:2]
        assert rotation_iou(inst.mesh, T) < 0.95, inst.key


def test_every_sub_style_occurs() -> None:
    ps = [instance_params(CATEGORY, "train", i) for i in range(200)]
    styles = {s: [p for p in ps if p["style"] == s] for s in ("drawers", "table", "cabinet")}
    assert all(styles.values()), {s: len(v) for s, v in styles.items()}
    cases = styles["drawers"] + styles["cabinet"]
    assert {p["support"] for p in cases} == {"plinth", "legs", "bracket"}
    assert {p["handle"] for p in ps} == {"knob", "bar", "recessed"}
    assert {p["front_style"] for p in cases} == {"overlay", "framed"}
    assert {p["drawers"] for p in styles["drawers"]} == {1, 2, 3}
    assert {p["niche"] for p in styles["drawers"]} == {"none", "top", "bottom"}
    # a cabinet's door under a drawer, under a niche, or alone
    assert any(p["drawers"] > 1 for p in styles["cabinet"])
    assert any(p["drawers"] == 1 and p["niche"] != "none" for p in styles["cabinet"])
    assert any(p["drawers"] == 1 and p["niche"] == "none" for p in styles["cabinet"])
    assert {p["shelf_enclosure"] for p in styles["table"]} == {"open", "back", "boxed"}
    assert {p["leg_style"] for p in styles["table"]} == {"square", "tapered", "round"}
    assert {p["hinge"] for p in styles["cabinet"]} == {"left", "right"}


def test_splits_disjoint() -> None:
    seen: dict[str, str] = {}
    for split in SPLITS:
        for i in range(DEFAULT_SPLIT_SIZES[split]):
            sig = repr(sorted(instance_params(CATEGORY, split, i).items()))
            assert sig not in seen, f"{split}/{i} repeats {seen.get(sig)}"
            seen[sig] = f"{split}/{i}"
