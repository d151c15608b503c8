"""Checks that every per-category test file (``tests/objects/test_<category>.py``) makes of
its category, written once so that a threshold cannot drift between the files.

Each file keeps what is particular to its category (proportions, which end faces where,
the sub-styles drawn, which instances declare which group) and calls these for the rest.
Where the files' versions of a check differed, the difference is a parameter, so each file
checks exactly what it checked before. Plain functions, not tests: pytest collects nothing
here (the module's name does not start with ``test_``), and no name in it starts with
``test`` either, so that importing one into a test module adds no test there.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pytest

from beo_bench.geometry import axis_angle, symmetry_transformations
from beo_bench.objects import (
    DEFAULT_SPLIT_SIZES,
    LIBRARY_VERSION,
    SPLITS,
    ObjectInstance,
    ObjectSet,
    instance_from_key,
)
from beo_bench.objects.cache import mesh_hash
from beo_bench.objects.registry import generate, instance_params
from beo_bench.objects.symmetry import rotation_iou

IOU_KEEPS = 0.95
"""Volume IoU above which a rotation counts as keeping the solid (a symmetry), below which
as changing it: the threshold of every category file."""

QUARTER_Z = axis_angle([0.0, 0.0, 1.0], np.pi / 2)
HALF_Z = axis_angle([0.0, 0.0, 1.0], np.pi)
QUARTER_X = axis_angle([1.0, 0.0, 0.0], np.pi / 2)
QUARTER_Y = axis_angle([0.0, 1.0, 0.0], np.pi / 2)


def module_test_set(category: str, per_category: int = 50) -> Callable[[], list[ObjectInstance]]:
    """A module-scoped fixture named ``test_set``: the first ``per_category`` instances of
    ``category``'s test split, as a list in index order (``test_set[i].index == i``).

    Module-scoped because building and measuring 50 meshes is the slow part of a category
    file, and every test of the file reads the same instances. Use it as
    ``test_set = module_test_set(CATEGORY)`` at a test module's top level.
    """

    @pytest.fixture(scope="module", name="test_set")
    def _test_set() -> list[ObjectInstance]:
        return list(ObjectSet("test", [category], per_category=per_category))

    return _test_set


def solid_and_sized(insts: Sequence[ObjectInstance], size_range: tuple[float, float]) -> None:
    """Every instance is watertight, one body with faces wound outward (a positive volume),
    and its largest extent lies in ``size_range`` (metres, both ends included).

    Watertight, because volumes, voxels, IoU and the simulator's inside tests need a closed
    surface; one body, because a loose part or a closed cavity inside is no single
    graspable solid; the size range, because the class is meant at tabletop scale, within
    the gripper's reach and apart from (or overlapping by design with) its neighbours.
    """
    lo, hi = size_range
    for inst in insts:
        m = inst.mesh
        assert m.is_watertight, inst.key
        assert m.body_count == 1, (inst.key, "one connected solid, no closed cavities")
        assert m.volume > 0, inst.key
        assert lo <= m.extents.max() <= hi, (inst.key, m.extents)


def deterministic_per_key(
    category: str, insts: Sequence[ObjectInstance], indices: Sequence[int] = (0, 1, 2)
) -> None:
    """An instance's key rebuilds the same mesh, its parameters generate it again, and two
    instances differ: runs, caches and published results name objects by key alone.

    For each of ``insts[i]``, ``i`` in ``indices`` (test-split instances in index order,
    as :func:`module_test_set` gives them): the key the instance carries and the key written
    out as ``proc/v{LIBRARY_VERSION}/{category}/test/{i}`` (which checks the key's form) both
    rebuild an instance of its content hash, and ``generate`` on its parameters gives a
    mesh of that hash. Last, instances 0 and 1 differ (their content hashes).
    """
    for i in indices:
        inst = insts[i]
        spelled = f"proc/v{LIBRARY_VERSION}/{category}/test/{i}"
        for key in (inst.key, spelled):
            assert instance_from_key(key).content_hash == inst.content_hash, key
        rebuilt = generate(category, instance_params(category, "test", inst.index))
        assert mesh_hash(rebuilt.mesh) == inst.content_hash, inst.key
    assert insts[0].content_hash != insts[1].content_hash


def no_turn_about_z_keeps(insts: Sequence[ObjectInstance], *, quarter_xy_on: int = 0) -> None:
    """Every instance is declared without symmetry (exactly ``{"continuous": [],
    "discrete": []}``), and indeed neither a quarter nor a half turn about z keeps its
    solid: volume IoU below :data:`IOU_KEEPS` for both.

    An object that a turn keeps but that declares no symmetry would charge a method
    rotation error for a correct answer. ``quarter_xy_on`` also probes a quarter turn about
    x and one about y on the first that many instances (the other probes of
    tests/objects/test_categories.py).
    """
    for inst in insts:
        assert inst.symmetry == {"continuous": [], "discrete": []}, inst.key
        for R in (QUARTER_Z, HALF_Z):
            assert rotation_iou(inst.mesh, R) < IOU_KEEPS, (inst.key, R.round(3))
    for inst in insts[:quarter_xy_on]:
        for R in (QUARTER_X, QUARTER_Y):
            assert rotation_iou(inst.mesh, R) < IOU_KEEPS, (inst.key, R.round(3))


def in_group(R: np.ndarray, group: Sequence[np.ndarray]) -> bool:
    """Whether the rotation ``R`` (3x3) is the rotation part of an element of ``group``
    (4x4 transforms), to within 1e-6 an entry."""
    return any(np.allclose(T[:3, :3], R, atol=1e-6) for T in group)


def declared_group_fits(insts: Sequence[ObjectInstance]) -> None:
    """Every declared rotation keeps the solid (volume IoU above :data:`IOU_KEEPS`), and
    the quarter and the half turn about z, where the group lacks them, do not (below it).

    The declaration is what rotation error is scored against: a declared element that
    changes the solid forgives real errors, an undeclared turn that keeps it charges for
    correct answers. Which group each instance declares is the category file's to check.
    """
    for inst in insts:
        group = symmetry_transformations(inst.symmetry)
        for T in group[1:]:
            assert rotation_iou(inst.mesh, T) > IOU_KEEPS, (inst.key, T.round(3))
        for R in (QUARTER_Z, HALF_Z):
            if not in_group(R, group):
                assert rotation_iou(inst.mesh, R) < IOU_KEEPS, (inst.key, R.round(3))


def splits_disjoint(category: str) -> None:
    """No two instances of ``category`` in any splits, at their default sizes, draw the
    same parameters: a test or OOD object is never a training object under another name.
    """
    seen: dict[str, str] = {}
    for split in SPLITS:
        for i in range(DEFAULT_SPLIT_SIZES[split]):
            sig = repr(sorted(instance_params(category, split, i).items()))
            assert sig not in seen, f"{split}/{i} repeats {seen.get(sig)}"
            seen[sig] = f"{split}/{i}"
