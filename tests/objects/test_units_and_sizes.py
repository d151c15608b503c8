"""Units and size of loaded meshes: real scale detected from files that
carry it, the category size table for normalised datasets, and the plausibility check that
refuses objects no table or gripper can hold."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh

from beo_bench.errors import ImplausibleSizeError, MeshError
from beo_bench.objects import ObjectSet, instance_from_key
from beo_bench.objects import categories as library_categories
from beo_bench.objects.datasets import LoadOptions, open_dataset
from beo_bench.objects.datasets.layouts import hash_split
from beo_bench.objects.datasets.meshfile import (
    CATEGORY_SIZES,
    DEFAULT_SIZE,
    MAX_DIAGONAL,
    MIN_EXTENT,
    UnknownSizeWarning,
    default_size,
    detect_units,
    procedural_size,
)
from beo_bench.scenes.builder import TableConfig
from beo_bench.scenes.gripper import GRIPPER

# a lemon as YCB measures it: 54 x 54 x 68 mm (an ellipsoid, largest extent along z)
LEMON_MM = (54.0, 54.0, 68.0)


pytestmark = pytest.mark.usefixtures("isolated_loaders")


def _ellipsoid(extents: tuple[float, float, float]) -> trimesh.Trimesh:
    m = trimesh.creation.icosphere(subdivisions=2)
    m.apply_scale(np.asarray(extents) / m.extents)
    return m


def _write(mesh: trimesh.Trimesh, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    mesh.export(path)
    return path


def _objects(root: Path, split: str, **opts: Any) -> ObjectSet:
    return open_dataset(root, **opts).objects(split)


def _one(root: Path, **kw: Any) -> trimesh.Trimesh:
    s = _objects(root, "test", **kw)
    (inst,) = [i for c in s.categories for i in s.instances(c)]
    return inst.mesh


def _folder(tmp_path: Path, category: str, mesh: trimesh.Trimesh, name: str = "m.stl") -> Path:
    """A folder dataset whose one file lands in the test split (the split is a hash of the
    path; the name is varied until it does)."""
    root = tmp_path / "data"
    for k in range(200):
        rel = f"{category}/{k}_{name}"
        if hash_split(rel) == "test":
            _write(mesh, root / rel)
            return root
    raise AssertionError("no test-split name found")


# ------------------------------------------------------------------ files with real units


def test_millimetre_file_loads_at_real_size(tmp_path: Path) -> None:
    root = _folder(tmp_path, "lemon", _ellipsoid(LEMON_MM))
    mesh = _one(root)  # default units="auto"
    np.testing.assert_allclose(np.sort(mesh.extents), np.sort(LEMON_MM) / 1000, rtol=1e-6)
    # stated units give the same object, and the key carries them
    s = _objects(root, "test", units="mm")
    inst = s.instances("lemon")[0]
    assert "units=mm" in inst.key
    np.testing.assert_allclose(inst.mesh.extents, mesh.extents, rtol=1e-9)
    assert instance_from_key(inst.key, open_dataset(root)).content_hash == inst.content_hash
    # the default (auto) has the plain key: one key per object
    assert "units" not in _objects(root, "test", units="auto").instances("lemon")[0].key


def test_centimetre_and_metre_files(tmp_path: Path) -> None:
    mug = (8.0, 11.0, 10.0)  # cm
    np.testing.assert_allclose(
        _one(_folder(tmp_path / "a", "mug", _ellipsoid(mug))).extents.max(), 0.11, rtol=1e-6
    )
    metres = tuple(x / 100 for x in mug)
    np.testing.assert_allclose(
        _one(_folder(tmp_path / "b", "mug", _ellipsoid(metres))).extents.max(), 0.11, rtol=1e-6
    )


@pytest.mark.parametrize(
    ("extent", "category", "want"),
    [
        (45.0, "lemon", "mm"),  # 4.5 cm: nearest the 6.8 cm lemon
        (45.0, None, "cm"),  # unknown: 45 cm is 3.0x the 15 cm reference, 4.5 cm 3.3x
        (0.1, "mug", "m"),
        (10.0, "mug", "cm"),
        (100.0, "mug", "mm"),
        (190.0, "banana", "mm"),
        (0.45, "keyboard", "m"),
    ],
)
def test_detect_units_rule(extent: float, category: str | None, want: str) -> None:
    assert detect_units(extent, category) == want


def test_no_plausible_unit_is_refused_naming_the_file(tmp_path: Path) -> None:
    # 45 m in millimetres is 45,000 units: metres, centimetres and millimetres all fail
    root = _folder(tmp_path, "widget", _ellipsoid((20_000.0, 30_000.0, 45_000.0)))
    with pytest.raises(ImplausibleSizeError, match=r"m\.stl.*45000 file units.*size="):
        _one(root)


# ---------------------------------------------------------------- normalised datasets


def test_unit_diagonal_lemon_gets_the_table_size(tmp_path: Path) -> None:
    # ModelNet layout (normalised by default): a unit-diagonal lemon
    mesh = _ellipsoid(LEMON_MM)
    mesh.apply_scale(1.0 / np.linalg.norm(mesh.extents))
    _write(mesh, tmp_path / "mn" / "lemon" / "test" / "lemon_0001.off")
    (inst,) = _objects(tmp_path / "mn", "test").instances("lemon")
    assert inst.mesh.extents.max() == pytest.approx(CATEGORY_SIZES["lemon"], rel=1e-9)
    assert CATEGORY_SIZES["lemon"] != DEFAULT_SIZE  # not the old 15 cm fallback
    # ShapeNet layout: laptop (03642806) is not a library class but is in the table
    shapenet = tmp_path / "sn" / "03642806" / "l0" / "models" / "model_normalized.obj"
    _write(_ellipsoid((0.9, 0.05, 0.6)), shapenet)
    laptops = [i for split in ("train", "val", "test") for i in _objects(tmp_path / "sn", split)]
    assert laptops[0].category == "laptop"
    assert laptops[0].mesh.extents.max() == pytest.approx(CATEGORY_SIZES["laptop"])
    # a normalised file in a folder: units="normalised" scales it like ShapeNet
    root = _folder(tmp_path / "f", "lemon", mesh)
    assert _one(root, units="normalised").extents.max() == pytest.approx(0.068)


def test_size_table_overridable_and_unknown_rule(tmp_path: Path) -> None:
    mesh = _ellipsoid((1.0, 0.5, 0.5))
    root = _folder(tmp_path, "gizmo", mesh)
    with pytest.warns(UnknownSizeWarning, match="gizmo"):
        assert _one(root, units="normalised").extents.max() == pytest.approx(DEFAULT_SIZE)
    assert _one(root, size={"gizmo": 0.05}).extents.max() == pytest.approx(0.05)


def test_size_table_is_consistent() -> None:
    # normalised shapes of any proportion stay on the table: diagonal <= sqrt(3) x extent
    assert max(CATEGORY_SIZES.values()) * math.sqrt(3) <= MAX_DIAGONAL
    assert min(CATEGORY_SIZES.values()) >= MIN_EXTENT
    # the library's classes: the procedural median, to the millimetre
    for c in library_categories():
        assert default_size(c) == pytest.approx(procedural_size(c), abs=6e-4), c
    # the limits are the table's depth and the gripper's scale
    assert 2 * min(TableConfig().table_half) == pytest.approx(MAX_DIAGONAL)
    assert MIN_EXTENT < GRIPPER.finger_width


# ------------------------------------------------------------------- plausibility check


def test_45_metre_native_object_is_refused(tmp_path: Path) -> None:
    # the lemon in millimetres, read with size="native" (file units taken as metres): 68 m
    root = _folder(tmp_path, "lemon", _ellipsoid(LEMON_MM))
    with pytest.raises(ImplausibleSizeError) as e:
        _one(root, size="native")
    msg = str(e.value)
    assert "m.stl" in msg and "68 m" in msg and "units='mm'" in msg
    assert isinstance(e.value, MeshError)
    with pytest.raises(ImplausibleSizeError, match="68 m"):
        _one(root, units="m")


def test_object_larger_than_the_table_is_refused(tmp_path: Path) -> None:
    root = _folder(tmp_path, "table", _ellipsoid((1.2, 0.6, 0.7)))  # a real table, metres
    with pytest.raises(ImplausibleSizeError, match=r"diagonal 1\.51 m exceeds 0\.7 m"):
        _one(root, units="m")
    with pytest.raises(ImplausibleSizeError, match=r"size=2\.0"):
        _objects(root, "test", size=2.0)
    # a millimetre-sized crumb read as metres is too small
    crumb = _folder(tmp_path / "c", "crumb", _ellipsoid((0.004, 0.003, 0.002)))
    with pytest.raises(ImplausibleSizeError, match="too small"):
        _one(crumb, units="m")


def test_bad_units_option() -> None:
    with pytest.raises(ValueError, match="units='inch'"):
        LoadOptions.make("basic", units="inch")
