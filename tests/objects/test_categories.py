"""Every registered procedural category: solid, deterministic, canonical, symmetric as
declared, and graspable where meant to be picked."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from beo_bench.geometry import axis_angle, symmetry_transformations
from beo_bench.objects import (
    DEFAULT_SPLIT_SIZES,
    SPLITS,
    ObjectSet,
    categories,
    get_category,
    instance_from_key,
)
from beo_bench.objects.registry import instance_params
from beo_bench.objects.symmetry import rotation_iou

CATEGORIES = categories()
GRIPPER_OPENING = 0.08


def test_at_least_ten_categories() -> None:
    required = {"mug", "bowl", "bottle", "can", "box", "chair", "table", "sofa", "car", "airplane"}
    assert required <= set(CATEGORIES)


@pytest.mark.parametrize("category", CATEGORIES)
def test_most_categories_have_six_parameters(category: str) -> None:
    assert len(get_category(category).params) >= 6


@pytest.mark.parametrize("split", SPLITS)
@pytest.mark.parametrize("category", CATEGORIES)
def test_solid_centred_and_sized(category: str, split: str) -> None:
    for inst in ObjectSet(split, [category], per_category=6):
        m = inst.mesh
        assert m.is_watertight, inst.key
        assert m.volume > 1e-7, inst.key
        assert m.body_count == 1, (inst.key, "one connected solid")
        # canonical frame: bounding-box centre at the origin, tabletop size in metres
        np.testing.assert_allclose(m.bounds.mean(axis=0), 0.0, atol=1e-9)
        assert 0.01 < m.extents.max() < 0.45, (inst.key, m.extents)
        # collision parts are convex and cover the mesh (their union is the mesh)
        parts = inst.collision_parts()
        assert parts and all(p.is_convex for p in parts)
        np.testing.assert_allclose(sum(p.volume for p in parts) >= m.volume * 0.999, True)


@pytest.mark.parametrize("category", CATEGORIES)
def test_deterministic_and_distinct(category: str) -> None:
    a = instance_from_key(f"proc/v2/{category}/test/3")
    b = ObjectSet("test", [category]).get(category, 3)
    c = ObjectSet("test", [category]).get(category, 4)
    assert a.content_hash == b.content_hash
    assert a.content_hash != c.content_hash


@pytest.mark.parametrize("category", CATEGORIES)
def test_splits_disjoint(category: str) -> None:
    """No two instances in any splits, at their default sizes, draw the same parameters: a
    test or OOD object is never a training object under another name."""
    seen: dict[str, str] = {}
    for split in SPLITS:
        for i in range(DEFAULT_SPLIT_SIZES[split]):
            p = instance_params(category, split, i)
            sig = repr(sorted(p.items()))
            assert sig not in seen, f"{split}/{i} repeats {seen.get(sig)}"
            seen[sig] = f"{split}/{i}"


@pytest.mark.parametrize("category", CATEGORIES)
def test_ood_outside_nominal_ranges(category: str) -> None:
    specs = get_category(category).params
    for i in range(10):
        p = instance_params(category, "ood", i)
        assert not all(spec.nominal(p[k]) for k, spec in specs.items())


def _group_samples(sym: dict) -> list[np.ndarray]:
    out = symmetry_transformations(sym, max_step_deg=37.0)[1:]
    return out[:6]


# Rotations that are symmetries of no category in our library unless declared.
_PROBES = [axis_angle([0, 0, 1], np.deg2rad(a)) for a in (90.0, 60.0, 135.0)] + [
    axis_angle([1, 0, 0], np.pi / 2),
    axis_angle([0, 1, 0], np.pi / 2),
    axis_angle([1, 1, 0], np.pi),
]


def _in_group(R: np.ndarray, group: list[np.ndarray], tol_deg: float = 2.0) -> bool:
    for T in group:
        c = np.clip((np.trace(T[:3, :3].T @ R) - 1) / 2, -1, 1)
        if np.degrees(np.arccos(c)) < tol_deg:
            return True
    return False


@pytest.mark.parametrize("category", CATEGORIES)
def test_symmetry_group_matches_geometry(category: str) -> None:
    """A rotation in the declared group leaves the solid nearly unchanged (IoU > 0.95); the
    probe rotations outside it do not."""
    for inst in ObjectSet("test", [category], per_category=8):
        group = symmetry_transformations(inst.symmetry, max_step_deg=1.0)
        for T in _group_samples(inst.symmetry):
            assert rotation_iou(inst.mesh, T) > 0.95, (inst.key, T.round(3))
        for R in _PROBES:
            if not _in_group(R, group):
                assert rotation_iou(inst.mesh, R) < 0.95, (inst.key, R.round(3))


def pinch_widths(mesh: trimesh.Trimesh, finger: float = 0.012) -> list[float]:
    """Thicknesses of material chunks a parallel gripper could close on: along horizontal
    and vertical lines through the object, each solid interval whose free space on both
    sides is at least a finger's width (or open to the outside)."""
    widths = []
    lo, hi = mesh.bounds
    ctr = (lo + hi) / 2
    rng = np.random.default_rng(0)
    origins, dirs = [], []
    for _ in range(400):
        d = rng.normal(size=3)
        d[2] *= 0.3 if rng.random() < 0.7 else 3.0
        d /= np.linalg.norm(d)
        p = ctr + rng.uniform(lo - ctr, hi - ctr)
        origins.append(p - d * 1.0)
        dirs.append(d)
    locs, ray_idx, _ = mesh.ray.intersects_location(
        np.array(origins), np.array(dirs), multiple_hits=True
    )
    for r in range(len(origins)):
        pts = locs[ray_idx == r]
        if len(pts) < 2 or len(pts) % 2:
            continue
        s = np.sort((pts - origins[r]) @ dirs[r])
        for k in range(0, len(s), 2):
            before = s[k] - s[k - 1] if k > 0 else np.inf
            after = s[k + 2] - s[k + 1] if k + 2 < len(s) else np.inf
            if before >= finger and after >= finger:
                widths.append(float(s[k + 1] - s[k]))
    return widths


@pytest.mark.parametrize("category", CATEGORIES)
def test_pickable_fit_the_gripper(category: str) -> None:
    if not get_category(category).pickable:
        pytest.skip(f"{category} is not meant to be picked")
    for inst in ObjectSet("test", [category], per_category=8):
        w = pinch_widths(inst.mesh)
        assert w and min(w) < GRIPPER_OPENING - 0.01, (inst.key, min(w, default=None))
