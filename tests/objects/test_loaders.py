"""Dataset loaders (ShapeNet, ModelNet, folder) on tiny fixture datasets written to tmp_path,
symmetry estimation, and the CoACD cache of loaded meshes."""

from __future__ import annotations

import pickle
import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh

from beo_bench.errors import (
    DatasetLayoutError,
    EmptyMeshError,
    InvalidKeyError,
    MeshLoadError,
    NonWatertightMeshError,
    UnknownCategoryError,
    UnknownSplitError,
)
from beo_bench.geometry import axis_angle, rigid
from beo_bench.objects import ObjectSet, instance_from_key
from beo_bench.objects.cache import entry_path
from beo_bench.objects.datasets import DatasetScanWarning, object_set, open_dataset
from beo_bench.objects.datasets import instance_from_key as resolve
from beo_bench.objects.datasets.layouts import (
    FOLDER,
    LAYOUTS,
    MODELNET,
    SHAPENET,
    SHAPENET_TO_CANONICAL,
    Layout,
    dataset_entries,
    detect_layout,
    get_layout,
    hash_split,
    modelnet_split,
)
from beo_bench.objects.datasets.load import SYMMETRY_CACHE_PARAMS
from beo_bench.objects.datasets.meshfile import DEFAULT_SIZE, axes_rotation, default_size
from beo_bench.objects.instance import COACD_CACHE_PARAMS, ObjectInstance
from beo_bench.objects.prepare import prepare
from beo_bench.objects.symmetry import estimate_symmetry, rotation_iou

REAL_SPLITS = ("train", "val", "test")
CHAIR, MUG, UNKNOWN = "03001627", "03797390", "09999999"


pytestmark = pytest.mark.usefixtures("isolated_loaders")


# ----------------------------------------------------------------------------- fixtures


def _box(extents: tuple[float, float, float], centre=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    return trimesh.creation.box(
        extents, transform=trimesh.transformations.translation_matrix(centre)
    )


def _union(*parts: trimesh.Trimesh) -> trimesh.Trimesh:
    return trimesh.boolean.union(list(parts), engine="manifold")


def _shapenet_model(k: int) -> trimesh.Trimesh:
    """ShapeNet axes (+y up, -z front): a body tallest in y, a bump on the front (-z) and
    one on the +x side near the top."""
    body = _box((0.2, 0.5 + 0.05 * k, 0.3))
    front = _box((0.05, 0.05, 0.1), (0.0, 0.0, -0.2))
    side = _box((0.1, 0.05, 0.05), (0.15, 0.2, 0.0))
    m = _union(body, front, side)
    m.apply_scale(1.0 / np.linalg.norm(m.extents))  # ShapeNet: unit diagonal
    return m


def _write(mesh: trimesh.Trimesh, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix == ".obj":
        path.write_text(trimesh.exchange.obj.export_obj(mesh, include_normals=False))
    else:
        mesh.export(path)
    return path


@pytest.fixture
def shapenet_root(tmp_path: Path) -> Path:
    root = tmp_path / "ShapeNetCore.v2"
    models = {CHAIR: ["c0", "c1", "c2", "c3"], MUG: ["m0", "m1", "m2"], UNKNOWN: ["u0"]}
    for synset, ids in models.items():
        for k, mid in enumerate(ids):
            _write(_shapenet_model(k), root / synset / mid / "models" / "model_normalized.obj")
    (root / "taxonomy.json").write_text("[]")  # a file at the top: ignored
    return root


def _modelnet_names(prefix: str, want: dict[str, int]) -> list[str]:
    """File stems of ModelNet's train folder giving at least ``want`` of each split."""
    got: dict[str, list[str]] = {"train": [], "val": []}
    i = 0
    while any(len(got[s]) < n for s, n in want.items()):
        i += 1
        name = f"{prefix}_{i:04d}"
        split = modelnet_split("train", name)
        if len(got[split]) < want[split]:
            got[split].append(name)
    return sorted(got["train"] + got["val"])


GLUED_OFF = """OFF8 6 0
-0.1 -0.2 -0.3
0.1 -0.2 -0.3
0.1 0.2 -0.3
-0.1 0.2 -0.3
-0.1 -0.2 0.3
0.1 -0.2 0.3
0.1 0.2 0.3
-0.1 0.2 0.3
4 0 3 2 1
4 4 5 6 7
4 0 1 5 4
4 1 2 6 5
4 2 3 7 6
4 3 0 4 7
"""


@pytest.fixture
def modelnet_root(tmp_path: Path) -> Path:
    root = tmp_path / "ModelNet40"
    cyl = trimesh.creation.cylinder(4.0, 9.0, sections=24)  # ModelNet units are arbitrary
    for name in _modelnet_names("cup", {"train": 3, "val": 1}):
        _write(cyl, root / "cup" / "train" / f"{name}.off")
    _write(cyl, root / "cup" / "test" / "cup_0100.off")
    (root / "chair" / "test").mkdir(parents=True)
    (root / "chair" / "test" / "chair_0001.off").write_text(GLUED_OFF)
    _write(_box((30.0, 20.0, 50.0)), root / "chair" / "test" / "chair_0002.off")
    return root


@pytest.fixture
def folder_root(tmp_path: Path) -> Path:
    root = tmp_path / "meshes"
    box = _box((0.04, 0.06, 0.12))
    _write(box, root / "mug" / "a.obj")
    _write(box, root / "mug" / "sub" / "b.ply")
    _write(box, root / "widget" / "c.stl")
    _write(box, root / "widget" / "d.glb")
    _write(box, root / "widget" / "e.off")
    (root / "widget" / "notes.txt").write_text("not a mesh")
    return root


def _objects(
    root: Path,
    split: str = "test",
    categories: list[str] | None = None,
    per_category: int | None = None,
    **opts: Any,
) -> ObjectSet:
    """A split of the dataset at ``root``, opened the one way there is (:func:`open_dataset`)."""
    return open_dataset(root, **opts).objects(split, categories, per_category)


def _all(loader: Callable[..., ObjectSet], root: Path, **kw: object) -> list[ObjectInstance]:
    return [inst for s in REAL_SPLITS for inst in loader(root, s, **kw)]


def _find(loader: Callable[..., ObjectSet], root: Path, name: str, **kw: object) -> ObjectInstance:
    for inst in _all(loader, root, **kw):
        if inst.path is not None and inst.path.name == name:
            return inst
    raise AssertionError(f"{name} not loaded")


# ------------------------------------------------------------------------------ ShapeNet


def test_shapenet_rotation_is_the_documented_convention() -> None:
    # ShapeNetCore v2: +y up, -z front -> ours +z up, +x front; a proper rotation
    np.testing.assert_allclose(SHAPENET_TO_CANONICAL, axes_rotation("y", "-z"))
    np.testing.assert_allclose(SHAPENET_TO_CANONICAL @ [0, 1, 0], [0, 0, 1])
    np.testing.assert_allclose(SHAPENET_TO_CANONICAL @ [0, 0, -1], [1, 0, 0])
    assert np.linalg.det(SHAPENET_TO_CANONICAL) == pytest.approx(1.0)


def test_shapenet_categories_and_round_trip(shapenet_root: Path) -> None:
    insts = _all(_objects, shapenet_root)
    assert len(insts) == 8
    by_cat: dict[str, int] = {}
    for inst in insts:
        by_cat[inst.category] = by_cat.get(inst.category, 0) + 1
    assert by_cat == {"chair": 4, "mug": 3, UNKNOWN: 1}  # unknown synset keeps its id
    dataset = open_dataset(shapenet_root)
    for inst in insts:
        assert inst.source == "shapenet"
        assert inst.key.startswith("shapenet/") and str(shapenet_root) not in inst.key
        again = instance_from_key(inst.key, dataset)
        assert (again.category, again.split, again.index) == (inst.category, inst.split, inst.index)
        assert again.content_hash == inst.content_hash


def test_an_unknown_synset_keeps_its_id_and_says_so(shapenet_root: Path) -> None:
    """A synset none of the 55 (nor a registered class's) is a class named by its id,
    with one warning naming the folder; known synsets say nothing."""
    with pytest.warns(DatasetScanWarning) as said:
        dataset_entries(SHAPENET, str(shapenet_root))
    lines = [str(w.message) for w in said if issubclass(w.category, DatasetScanWarning)]
    assert len(lines) == 1 and lines[0].startswith(f"{shapenet_root / UNKNOWN}: synset {UNKNOWN}")
    assert f"a class named {UNKNOWN!r}" in lines[0]


def test_shapenet_set_api(shapenet_root: Path) -> None:
    for split in REAL_SPLITS:
        s = _objects(shapenet_root, split)
        assert len(s) == sum(s.count(c) for c in s.categories) == len(list(s))
        for c in s.categories:
            for i in range(s.count(c)):
                assert s.get(c, i).index == i and s.get(c, i).split == split
    # splits are disjoint and cover the dataset
    keys = [i.key for i in _all(_objects, shapenet_root)]
    assert len(set(keys)) == len(keys) == 8
    one = _objects(shapenet_root, "train", categories=[MUG], per_category=1)
    assert one.categories == ("mug",) and len(one) <= 1


def test_shapenet_canonical_frame(shapenet_root: Path) -> None:
    for inst in _all(_objects, shapenet_root):
        m = inst.mesh
        assert m.is_watertight
        np.testing.assert_allclose(m.bounds.mean(axis=0), 0.0, atol=1e-9)
        assert m.extents.max() == pytest.approx(default_size(inst.category), rel=1e-6)
        assert int(np.argmax(m.extents)) == 2  # ShapeNet's tall y is our z
        v, eps = m.vertices, 1e-6 * m.extents.max()
        # the front bump (ShapeNet -z) is our +x end: narrow there, the full body at -x
        front = v[v[:, 0] > v[:, 0].max() - eps]
        back = v[v[:, 0] < v[:, 0].min() + eps]
        assert np.ptp(front[:, 1]) < 0.5 * np.ptp(back[:, 1])
        # the side bump (ShapeNet +x, upper half) is our -y end, above the centre
        side = v[v[:, 1] < v[:, 1].min() + eps]
        assert (side[:, 2] > 0).all()


def test_real_world_size_option(shapenet_root: Path) -> None:
    inst = _objects(shapenet_root, "train", size=0.3).instances("chair")[0]
    assert inst.mesh.extents.max() == pytest.approx(0.3)
    assert "size=0.3" in inst.key
    assert (
        instance_from_key(inst.key, open_dataset(shapenet_root)).content_hash == inst.content_hash
    )
    per_cat = _all(_objects, shapenet_root, size={"mug": 0.09})
    for inst in per_cat:
        want = 0.09 if inst.category == "mug" else default_size(inst.category)
        assert inst.mesh.extents.max() == pytest.approx(want)


def test_default_size_of_registered_category_is_procedural_median() -> None:
    assert 0.05 < default_size("mug") < 0.2
    assert default_size("no_such_category") == DEFAULT_SIZE


def test_categories_by_synset_and_unknown(shapenet_root: Path) -> None:
    s = _objects(shapenet_root, "train", categories=[MUG, "chair"])
    assert set(s.categories) == {"mug", "chair"}
    with pytest.raises(UnknownCategoryError, match="sofa"):
        _objects(shapenet_root, "test", categories=["sofa"])


# ------------------------------------------------------------------------------ ModelNet


def test_modelnet_splits_and_names(modelnet_root: Path) -> None:
    test = _objects(modelnet_root, "test")
    assert test.categories == ("chair", "mug")  # ModelNet cup is our mug
    assert test.count("chair") == 2 and test.count("mug") == 1
    train = {i.key for i in _objects(modelnet_root, "train")}
    val = {i.key for i in _objects(modelnet_root, "val")}
    assert train and val and not train & val
    files = {f"modelnet/cup/train/{p.stem}" for p in (modelnet_root / "cup/train").iterdir()}
    assert train | val == files
    dataset = open_dataset(modelnet_root)
    for inst in _objects(modelnet_root, "val"):
        assert inst.split == "val" and dataset.instance(inst.key).split == "val"
    with pytest.raises(UnknownSplitError, match="ood"):
        _objects(modelnet_root, "ood")
    with pytest.raises(UnknownSplitError, match="ood"):
        object_set(dataset, "ood")
    with pytest.raises(UnknownSplitError):
        _objects(modelnet_root, "holdout")


def test_modelnet_glued_off_header_and_frame(modelnet_root: Path) -> None:
    inst = _find(_objects, modelnet_root, "chair_0001.off")
    m = inst.mesh
    assert m.is_watertight and len(m.faces) == 12
    # ModelNet is z-up like us: the axes are kept, only centred and scaled
    np.testing.assert_allclose(m.extents / m.extents.max(), [1 / 3, 2 / 3, 1], atol=1e-9)
    np.testing.assert_allclose(m.bounds.mean(axis=0), 0.0, atol=1e-9)
    assert m.extents.max() == pytest.approx(default_size("chair"))
    assert open_dataset(modelnet_root).instance(inst.key).content_hash == inst.content_hash


# -------------------------------------------------------------------------------- folder


def test_folder_round_trip_and_splits(folder_root: Path) -> None:
    insts = _all(_objects, folder_root)
    assert sorted(i.path.name for i in insts) == ["a.obj", "b.ply", "c.stl", "d.glb", "e.off"]
    dataset = open_dataset(folder_root)
    for inst in insts:
        rel = inst.path.relative_to(folder_root).as_posix()
        assert inst.key == f"folder/{rel}"
        assert inst.split == hash_split(rel)
        assert inst.mesh.is_watertight
        assert instance_from_key(inst.key, dataset).content_hash == inst.content_hash
    with pytest.raises(UnknownSplitError):
        _objects(folder_root, "ood")


def test_a_loaded_set_pickles_for_worker_processes(folder_root: Path) -> None:
    # an env drawing from a loaded dataset is pickled when it goes to a subprocess vector env
    s = _objects(folder_root, "all")
    back = pickle.loads(pickle.dumps(s))
    assert back.categories == s.categories
    c = s.categories[0]
    assert back.get(c, 0).key == s.get(c, 0).key
    assert back.get(c, 0).content_hash == s.get(c, 0).content_hash


def test_folder_axes_option(folder_root: Path) -> None:
    # the box is 0.04 x 0.06 x 0.12 in file axes; file +y up -> our z, file +z front ->
    # our x, and right-handedness leaves file x as our y
    inst = _find(_objects, folder_root, "a.obj", up="y", size="native")
    np.testing.assert_allclose(inst.mesh.extents, [0.04, 0.12, 0.06], atol=1e-9)
    assert "up=y" in inst.key and "size=native" in inst.key
    # the key carries the options: the dataset opened with the defaults resolves it, and a
    # key may name the files' front axis too (file +z front -> our x, file x -> our y)
    default = open_dataset(folder_root)
    assert instance_from_key(inst.key, default).content_hash == inst.content_hash
    fronted = instance_from_key(inst.key.replace("up=y", "front=z&up=y"), default)
    np.testing.assert_allclose(fronted.mesh.extents, [0.12, 0.04, 0.06], atol=1e-9)
    with pytest.raises(ValueError, match="different axes"):
        _objects(folder_root, up="x")


def test_detect_layout_and_open_dataset(
    shapenet_root: Path, modelnet_root: Path, folder_root: Path
) -> None:
    assert detect_layout(shapenet_root) == "shapenet"
    assert detect_layout(modelnet_root) == "modelnet"
    assert detect_layout(folder_root) == "folder"
    dataset = open_dataset(modelnet_root)
    assert dataset.layout == "modelnet" and dataset.layout_spec is get_layout("modelnet")
    assert dataset.objects("test").source == "modelnet"
    s = object_set(dataset, "test", ["mug"])
    assert s.source == "modelnet" and s.categories == ("mug",) and len(s) == 1
    # a layout given rather than detected gives the same instances
    forced = _objects(modelnet_root, "test", ["mug"], layout="modelnet")
    assert [i.key for i in s] == [i.key for i in forced]


def test_each_layout_is_a_layout() -> None:
    assert list(LAYOUTS) == ["shapenet", "modelnet", "folder"]
    for name, layout in LAYOUTS.items():
        typed: Layout = layout
        assert typed.name == name and get_layout(name) is layout
        assert layout.root_env == f"BEO_BENCH_{name.upper()}"
        assert layout.key_form.startswith(f"{name}/")
    assert (SHAPENET.default_units, MODELNET.default_units, FOLDER.default_units) == (
        "normalised",
        "normalised",
        "auto",
    )
    assert [layout.axes_option for layout in LAYOUTS.values()] == [False, False, True]
    with pytest.raises(DatasetLayoutError, match="unknown dataset layout 'obj'"):
        get_layout("obj")


# ------------------------------------------------------------------------------- keys


def test_keys_resolve_given_their_dataset_or_the_environment(
    shapenet_root: Path, modelnet_root: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    inst = _objects(shapenet_root, "train").instances("chair")[0]
    # a process knows no dataset roots, not even of a dataset it loaded: no global state
    with pytest.raises(InvalidKeyError, match="BEO_BENCH_SHAPENET"):
        instance_from_key(inst.key)
    dataset = open_dataset(shapenet_root)
    assert instance_from_key(inst.key, dataset).content_hash == inst.content_hash
    assert resolve(inst.key, dataset) is dataset.instance(inst.key)  # one instance per key
    # what a worker process is given: the (picklable) dataset
    shipped = pickle.loads(pickle.dumps(dataset))
    assert shipped == dataset
    assert shipped.instance(inst.key).content_hash == inst.content_hash
    # a procedural key needs no dataset, and ignores one
    assert dataset.instance("proc/v2/mug/test/3").key == "proc/v2/mug/test/3"
    # the dataset must be the key's
    with pytest.raises(InvalidKeyError, match="is a shapenet key, but the dataset"):
        instance_from_key(inst.key, open_dataset(modelnet_root))
    monkeypatch.setenv("BEO_BENCH_SHAPENET", str(shapenet_root))
    assert instance_from_key(inst.key).content_hash == inst.content_hash


def test_bad_keys(shapenet_root: Path, modelnet_root: Path) -> None:
    shapenet, modelnet = open_dataset(shapenet_root), open_dataset(modelnet_root)
    for key, dataset, why in (
        ("shapenet/0300/abc", shapenet, "is not shapenet/<8-digit synset>/<model id>"),
        ("shapenet/03001627/nope", shapenet, "no such model"),
        ("shapenet/03001627/c0?x=1", shapenet, "unknown option"),
        ("modelnet/cup/x", modelnet, "is not modelnet/<class>/<train|test>/<name>"),
        ("modelnet/cup/x", None, "BEO_BENCH_MODELNET"),
        ("mesh/cup/x", shapenet, "unknown source 'mesh'; known: folder, modelnet, proc"),
    ):
        with pytest.raises(InvalidKeyError, match=re.escape(why)):
            instance_from_key(key, dataset)


# ------------------------------------------------------------------------ bad input


@pytest.fixture
def bad_root(tmp_path: Path) -> Path:
    root = tmp_path / "bad"
    d = root / "thing"
    d.mkdir(parents=True)
    (d / "garbage.obj").write_bytes(np.random.default_rng(0).bytes(2000))
    (d / "empty.obj").write_text("# exported nothing\n")
    (d / "glitch.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")  # truncated
    box = _box((0.1, 0.2, 0.3))
    _write(
        trimesh.Trimesh(box.vertices, box.faces[box.face_normals[:, 2] < 0.5]), d / "open_box.obj"
    )
    cyl = trimesh.creation.cylinder(0.03, 0.1, sections=24)
    _write(
        trimesh.Trimesh(cyl.vertices, cyl.faces[np.abs(cyl.face_normals[:, 2]) < 0.5]),
        d / "open_tube.obj",
    )
    return root


def test_corrupt_files_raise_mesh_load_error(bad_root: Path) -> None:
    for name in ("garbage.obj", "glitch.off"):
        inst = _find(_objects, bad_root, name)
        with pytest.raises(MeshLoadError, match=re.escape(name)):
            _ = inst.mesh


def test_missing_file_raises_mesh_load_error(bad_root: Path) -> None:
    inst = _find(_objects, bad_root, "open_box.obj")
    inst.path.unlink()
    with pytest.raises(MeshLoadError, match=re.escape("open_box.obj")):
        _ = inst.mesh


def test_empty_mesh_raises(bad_root: Path) -> None:
    inst = _find(_objects, bad_root, "empty.obj")
    with pytest.raises(EmptyMeshError, match=re.escape("empty.obj")):
        _ = inst.mesh


def test_repair_modes(bad_root: Path) -> None:
    with pytest.raises(NonWatertightMeshError, match=re.escape("open_box.obj")):
        _ = _find(_objects, bad_root, "open_box.obj", repair="none").mesh
    assert _find(_objects, bad_root, "open_box.obj", repair="basic").mesh.is_watertight
    with pytest.raises(NonWatertightMeshError, match=re.escape("open_tube.obj")):
        _ = _find(_objects, bad_root, "open_tube.obj", repair="basic").mesh  # a 24-gon
    # the default rebuilds what basic cannot close, and keeps the default out of the key
    tube = _find(_objects, bad_root, "open_tube.obj")
    assert tube.mesh.is_watertight and tube.mesh.volume > 0 and "repair=" not in tube.key
    fixed = _find(_objects, bad_root, "open_tube.obj", repair="voxel")
    assert fixed.mesh.is_watertight and fixed.mesh.volume > 0
    assert "repair=voxel" in fixed.key
    with pytest.raises(ValueError, match="repair"):
        _objects(bad_root, repair="magic")


def test_layout_errors(tmp_path: Path, shapenet_root: Path, modelnet_root: Path) -> None:
    missing = tmp_path / "nowhere"
    for call in (
        lambda: open_dataset(missing),
        lambda: _objects(missing, layout="shapenet"),
        lambda: detect_layout(missing),
    ):
        with pytest.raises(DatasetLayoutError, match="nowhere"):
            call()
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DatasetLayoutError, match="ShapeNetCore v2"):
        open_dataset(empty)
    with pytest.raises(
        DatasetLayoutError, match="it looks like a modelnet dataset: layout='modelnet'"
    ):
        _objects(modelnet_root, layout="shapenet")
    with pytest.raises(DatasetLayoutError, match="no modelnet data"):
        _objects(shapenet_root, layout="modelnet")


# ----------------------------------------------------------------------------- symmetry


def _sym_size(sym: dict) -> tuple[int, int]:
    return len(sym["continuous"]), len(sym["discrete"])


def test_estimate_symmetry_simple_shapes() -> None:
    cyl = trimesh.creation.cylinder(0.04, 0.1, sections=48)
    assert _sym_size(estimate_symmetry(cyl)) == (1, 1)  # continuous z plus a flip
    assert _sym_size(estimate_symmetry(_box((0.1, 0.2, 0.3)))) == (0, 3)  # three half turns
    assert _sym_size(estimate_symmetry(_box((0.1, 0.1, 0.3)))) == (0, 7)  # 4-fold z + flips
    ell = _union(_box((0.2, 0.05, 0.05)), _box((0.05, 0.12, 0.05), (0.075, 0.06, 0.0)))
    assert _sym_size(estimate_symmetry(ell)) == (0, 0)
    # a box turned 30 degrees about z keeps all three half turns: the search runs over its
    # principal axes, not only the canonical ones (tests/objects/test_symmetry.py: any frame)
    box = _box((0.1, 0.2, 0.3))
    box.apply_transform(rigid(axis_angle([0, 0, 1], np.pi / 6)))
    assert _sym_size(estimate_symmetry(box)) == (0, 3)


def test_estimate_symmetry_about_centre_of_mass() -> None:
    # a triangular prism: its bounding-box centre is not on the 3-fold axis
    tri = trimesh.creation.cylinder(0.04, 0.1, sections=3)
    tri.apply_translation(-tri.bounds.mean(axis=0))
    sym = estimate_symmetry(tri)
    assert _sym_size(sym) == (0, 5)  # D3
    for T in sym["discrete"]:
        assert rotation_iou(tri, np.asarray(T), n=20000) > 0.95


def test_loaded_symmetry_is_lazy_and_cached(modelnet_root: Path, tmp_path: Path) -> None:
    inst = _find(_objects, modelnet_root, "cup_0100.off")
    assert inst.mesh.is_watertight
    assert not (tmp_path / "cache" / "symmetry").exists()  # not computed by loading
    sym = inst.symmetry
    assert _sym_size(sym) == (1, 1)
    assert entry_path("symmetry", inst.content_hash, SYMMETRY_CACHE_PARAMS).exists()
    assert open_dataset(modelnet_root).instance(inst.key).symmetry == sym


# ------------------------------------------------------------------------- collision


def _mug_like() -> trimesh.Trimesh:
    wall = trimesh.creation.annulus(r_min=0.03, r_max=0.035, height=0.1, sections=32)
    bottom = trimesh.creation.cylinder(
        radius=0.035,
        height=0.01,
        sections=32,
        transform=trimesh.transformations.translation_matrix((0.0, 0.0, -0.045)),
    )
    return _union(wall, bottom)


@pytest.mark.slow
def test_coacd_collision_parts_are_cached(tmp_path: Path) -> None:
    _write(_mug_like(), tmp_path / "mugs" / "mug" / "m.obj")
    inst = _all(_objects, tmp_path / "mugs", size="native")[0]
    path = entry_path("coacd", inst.content_hash, COACD_CACHE_PARAMS)
    assert not path.exists()
    t = time.perf_counter()
    parts = inst.collision_parts()
    first = time.perf_counter() - t
    assert path.exists() and len(parts) >= 2 and all(p.is_convex for p in parts)
    t = time.perf_counter()
    again = open_dataset(tmp_path / "mugs").instance(inst.key).collision_parts()
    second = time.perf_counter() - t
    assert len(again) == len(parts)
    assert second < first / 5
    print(f"CoACD: {first:.2f} s, {len(parts)} parts; cached: {second:.3f} s")


@pytest.mark.slow
def test_prepare_collision_in_workers(folder_root: Path) -> None:
    insts = [i for i in _all(_objects, folder_root) if i.category == "widget"]
    stats = prepare(insts, workers=2, progress=False)
    assert [s.key for s in stats] == [i.key for i in insts] and all(s.parts >= 1 for s in stats)
    for inst in insts:  # filled the cache this process reads
        assert entry_path("coacd", inst.content_hash, COACD_CACHE_PARAMS).exists()
