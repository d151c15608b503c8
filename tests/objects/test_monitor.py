"""The monitor category: every test instance one watertight solid of tabletop size,
deterministic per key, without rotational symmetry (a quarter and a half turn about z
change it visibly), its sub-styles all drawn, its splits disjoint."""

from __future__ import annotations

import numpy as np
import pytest

import beo_bench.objects.monitor  # noqa: F401  (registers monitor before CATEGORY_MODULES lists it)
from beo_bench.geometry import axis_angle
from beo_bench.objects import LIBRARY_VERSION, ObjectSet, instance_from_key
from beo_bench.objects.cache import mesh_hash
from beo_bench.objects.processing import rotation_iou
from beo_bench.objects.registry import DEFAULT_SPLIT_SIZES, SPLITS, generate, instance_params

CATEGORY = "monitor"
SIZE_RANGE = (0.07, 0.16)  # largest extent, metres: the panel's width (0.08-0.15 m aimed at)


@pytest.fixture(scope="module")
def test_set() -> ObjectSet:
    return ObjectSet("test", [CATEGORY], per_category=50)


def test_solid_one_body_and_sized(test_set: ObjectSet) -> None:
    for inst in test_set:
        m = inst.mesh
        assert m.is_watertight, inst.key
        assert m.body_count == 1, inst.key
        assert m.volume > 0, inst.key
        assert SIZE_RANGE[0] <= m.extents.max() <= SIZE_RANGE[1], (inst.key, m.extents)


def test_deterministic_per_key(test_set: ObjectSet) -> None:
    for i in (0, 7, 31):
        fresh = generate(CATEGORY, instance_params(CATEGORY, "test", i)).mesh
        again = generate(CATEGORY, instance_params(CATEGORY, "test", i)).mesh
        assert mesh_hash(fresh) == mesh_hash(again)
        keyed = instance_from_key(f"proc/v{LIBRARY_VERSION}/{CATEGORY}/test/{i}")
        assert keyed.content_hash == test_set.get(CATEGORY, i).content_hash
    assert test_set.get(CATEGORY, 0).content_hash != test_set.get(CATEGORY, 1).content_hash


def test_no_symmetry_and_turns_about_z_change_it(test_set: ObjectSet) -> None:
    """Declared asymmetric, so quarter and half turns about z must score below 0.95."""
    turns = [axis_angle([0.0, 0.0, 1.0], a) for a in (np.pi / 2, np.pi)]
    for inst in test_set:
        assert inst.symmetry == {"continuous": [], "discrete": []}, inst.key
        for R in turns:
            assert rotation_iou(inst.mesh, R) < 0.95, (inst.key, R.round(3))


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
    seen: dict[str, str] = {}
    for split in SPLITS:
        for i in range(DEFAULT_SPLIT_SIZES[split]):
            sig = repr(sorted(instance_params(CATEGORY, split, i).items()))
            assert sig not in seen, f"{split}/{i} repeats {seen.get(sig)}"
            seen[sig] = f"{split}/{i}"
