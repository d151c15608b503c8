"""BOP dataset files (beo_bench.bop.files): a small synthetic dataset written and read back,
checked against the units and layout of the toolkit's docs/bop_datasets_format.md."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import trimesh
from scipy.spatial.distance import pdist

from beo_bench.bop import files as bf
from beo_bench.bop import scenes as bs
from beo_bench.bop import store as bst
from beo_bench.errors import BopFormatError
from beo_bench.geometry import axis_angle, continuous_symmetry, discrete_symmetry

H, W = 24, 32
K = np.array([[40.0, 0.0, 15.5], [0.0, 42.0, 11.5], [0.0, 0.0, 1.0]])
BOX_EXTENTS = (0.10, 0.06, 0.04)


def _box() -> trimesh.Trimesh:
    return trimesh.creation.box(extents=BOX_EXTENTS)


def _cylinder() -> trimesh.Trimesh:
    return trimesh.creation.cylinder(radius=0.03, height=0.08, sections=32)


def _rect(y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
    m = np.zeros((H, W), dtype=bool)
    m[y0:y1, x0:x1] = True
    return m


def _image(seed: int) -> dict:
    """One image's inputs: rgb, depth (m, with holes), a pose, three instances (one
    partly occluded, one whose silhouette is empty)."""
    rng = np.random.default_rng(seed)
    rgb = rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8)
    # depths on a 0.1 mm grid, so that depth_scale 0.1 stores them exactly
    depth = rng.integers(3000, 9000, size=(H, W)) * 1e-4
    depth[0, :4] = 0.0  # missing
    depth[1, :4] = np.nan  # missing
    depth[2:5, 3:6] = 0.0  # holes inside instance 0's silhouette
    R1 = axis_angle([0.2, 0.5, 0.8], 0.7 + seed)
    gts = [
        bs.GtInstance(
            1, R1, np.array([0.01, -0.02, 0.5 + seed / 10]), _rect(2, 12, 3, 20), _rect(2, 12, 3, 9)
        ),
        bs.GtInstance(
            2, np.eye(3), np.array([-0.05, 0.03, 0.6]), _rect(10, 20, 15, 30), _rect(10, 20, 15, 30)
        ),
        bs.GtInstance(
            1, R1.T, np.array([0.0, 0.0, 0.7]), np.zeros((H, W), bool), np.zeros((H, W), bool)
        ),
    ]
    R_w2c = axis_angle([1.0, 0.0, 0.3], 2.0 + seed)
    return {
        "rgb": rgb,
        "depth_m": depth,
        "K": K + seed,
        "gts": gts,
        "R_w2c": R_w2c,
        "t_w2c_m": np.array([0.1, 0.2, 0.9 + seed]),
    }


SCENES = {1: (0.1, [0, 1]), 4: (1.0, [3, 7])}
"""scene_id -> (depth_scale, image ids)."""


@pytest.fixture
def dataset(tmp_path: Path) -> Path:
    root = bst.claim_dataset_dir(tmp_path / "bop")
    box, cyl = _box(), _cylinder()
    bf.write_model_ply(bf.model_path(root, 1), box.vertices, box.faces)
    bf.write_model_ply(bf.model_path(root, 2), cyl.vertices, cyl.faces, binary=True)
    sym_box = discrete_symmetry([axis_angle([1, 0, 0], np.pi), axis_angle([0, 0, 1], np.pi)])
    sym_cyl = continuous_symmetry(offset=(0.0, 0.0, 0.01))
    bf.write_models_info(
        root / "models" / "models_info.json",
        {1: bf.model_info(box.vertices, sym_box), 2: bf.model_info(cyl.vertices, sym_cyl)},
    )
    bf.write_category_map(
        root / "models" / bst.CATEGORY_MAP_NAME,
        {1: bf.ObjectEntry("box", "test", "box/abc"), 2: bf.ObjectEntry("can", "val", "can/7")},
    )
    for scene_id, (scale, im_ids) in SCENES.items():
        with bs.SceneWriter(root, "test", scene_id, depth_scale=scale) as sw:
            for im_id in im_ids:
                sw.add_image(im_id, **_image(im_id))
    bf.write_targets(root / bst.TARGETS_NAME, [bf.BopTarget(1, 0, 1, 2), bf.BopTarget(4, 7, 2, 1)])
    return root


# -- layout and JSON conventions --------------------------------------------------------------
def test_layout_and_json_keys(dataset: Path) -> None:
    scene = dataset / "test" / "000001"
    for rel in (
        "rgb/000000.png",
        "depth/000001.png",
        "mask/000001_000002.png",
        "mask_visib/000000_000000.png",
        "scene_camera.json",
        "scene_gt.json",
        "scene_gt_info.json",
    ):
        assert (scene / rel).is_file(), rel
    assert (dataset / "test" / "000004" / "rgb" / "000007.png").is_file()
    assert (dataset / "models" / "obj_000001.ply").is_file()
    for name in ("scene_camera.json", "scene_gt.json", "scene_gt_info.json"):
        assert list(json.loads((scene / name).read_text())) == ["0", "1"]
    assert list(json.loads((dataset / "models" / "models_info.json").read_text())) == ["1", "2"]
    assert not list(dataset.rglob("*.tmp"))


def test_scene_camera_and_gt_units(dataset: Path) -> None:
    for scene_id, (scale, im_ids) in SCENES.items():
        raw_cam = json.loads(
            (bf.scene_path(dataset, "test", scene_id) / "scene_camera.json").read_text()
        )
        raw_gt = json.loads(
            (bf.scene_path(dataset, "test", scene_id) / "scene_gt.json").read_text()
        )
        scene = bs.read_scene(dataset, "test", scene_id)
        assert sorted(scene.images) == im_ids
        for im_id in im_ids:
            src = _image(im_id)
            cam = raw_cam[str(im_id)]
            assert cam["cam_K"] == (K + im_id).reshape(-1).tolist()  # row-wise
            assert cam["depth_scale"] == scale
            assert cam["cam_R_w2c"] == src["R_w2c"].reshape(-1).tolist()
            np.testing.assert_allclose(cam["cam_t_w2c"], src["t_w2c_m"] * 1000.0)  # mm
            img = scene.images[im_id]
            np.testing.assert_array_equal(img.camera.K, K + im_id)
            assert img.camera.depth_scale == scale
            np.testing.assert_array_equal(img.camera.R_w2c, src["R_w2c"])
            np.testing.assert_allclose(img.camera.t_w2c_mm, src["t_w2c_m"] * 1000.0)
            assert [g.obj_id for g in img.gt] == [1, 2, 1]
            for g, s, r in zip(img.gt, src["gts"], raw_gt[str(im_id)], strict=True):
                assert r["cam_R_m2c"] == s.R_m2c.reshape(-1).tolist()  # row-wise
                assert r["obj_id"] == s.obj_id and isinstance(r["obj_id"], int)
                np.testing.assert_allclose(r["cam_t_m2c"], s.t_m2c_m * 1000.0)  # mm
                np.testing.assert_array_equal(g.R_m2c, s.R_m2c)
                np.testing.assert_allclose(g.t_m2c_mm, s.t_m2c_m * 1000.0)


def test_gt_info_from_masks(dataset: Path) -> None:
    scene = bs.read_scene(dataset, "test", 1)
    info = scene.images[0].gt_info
    assert info is not None
    # instance 0: rows 2..11, cols 3..19; visible cols 3..8; depth holes at rows 2-4, cols 3-5
    assert info[0].bbox_obj == (3, 2, 16, 9)  # (x, y, w, h), w = max x - min x (toolkit)
    assert info[0].bbox_visib == (3, 2, 5, 9)
    assert info[0].px_count_all == 10 * 17
    assert info[0].px_count_visib == 10 * 6
    assert info[0].px_count_valid == 10 * 17 - 9
    assert info[0].visib_fract == pytest.approx(60 / 170)
    assert info[1].visib_fract == 1.0
    # an empty silhouette: boxes (-1, -1, -1, -1), counts 0, visib_fract 0
    assert info[2].bbox_obj == (-1, -1, -1, -1) and info[2].bbox_visib == (-1, -1, -1, -1)
    assert (info[2].px_count_all, info[2].px_count_visib, info[2].visib_fract) == (0, 0, 0.0)


def test_images_round_trip(dataset: Path) -> None:
    for scene_id, (scale, im_ids) in SCENES.items():
        scene = bs.read_scene(dataset, "test", scene_id)
        for im_id in im_ids:
            src = _image(im_id)
            np.testing.assert_array_equal(scene.rgb(im_id), src["rgb"])
            raw = cv2.imread(str(scene.path / "depth" / f"{im_id:06d}.png"), cv2.IMREAD_UNCHANGED)
            assert raw.dtype == np.uint16
            d_mm = np.nan_to_num(src["depth_m"]) * 1000.0
            np.testing.assert_array_equal(raw, np.round(d_mm / scale).astype(np.uint16))
            assert (raw[0, :4] == 0).all() and (raw[1, :4] == 0).all()  # missing -> 0
            got = scene.depth_mm(im_id)
            assert got.dtype == np.float64
            np.testing.assert_array_equal(got, raw * scale)
            if scale == 0.1:  # the 0.1 mm grid survives exactly (up to float rounding)
                np.testing.assert_allclose(got, d_mm, rtol=0, atol=1e-9)
            for i, g in enumerate(src["gts"]):
                np.testing.assert_array_equal(scene.mask(im_id, i), g.mask)
                np.testing.assert_array_equal(scene.mask_visib(im_id, i), g.mask_visib)


def test_depth_out_of_range_is_refused(tmp_path: Path) -> None:
    root = bst.claim_dataset_dir(tmp_path)
    sw = bs.SceneWriter(root, "test", 0, depth_scale=0.1)
    with pytest.raises(ValueError, match=r"depth_scale >= 0\.1"):
        sw.depth_png(np.array([[7.0]]))  # 70000 units of 0.1 mm
    assert sw.depth_png(np.array([[6.5535, np.inf, -1.0]])).tolist() == [[65535, 0, 0]]


# -- models -----------------------------------------------------------------------------------
def _ply_header(path: Path) -> list[str]:
    lines = []
    with path.open("rb") as f:
        while (line := f.readline().decode("ascii").strip()) != "end_header":
            lines.append(line)
    return lines


def test_model_ply_header_units_and_normals(dataset: Path) -> None:
    path = dataset / "models" / "obj_000001.ply"
    header = _ply_header(path)
    box = _box()
    assert header[1] == "format ascii 1.0"
    assert f"element vertex {len(box.vertices)}" in header
    props = [h.split()[-1] for h in header if h.startswith("property float")]
    assert props == ["x", "y", "z", "nx", "ny", "nz"]
    assert "property list uchar int vertex_indices" in header
    assert f"element face {len(box.faces)}" in header
    body = path.read_text().split("end_header\n")[1].splitlines()
    verts = np.array([[float(x) for x in r.split()] for r in body[: len(box.vertices)]])
    np.testing.assert_allclose(verts[:, :3], box.vertices * 1000.0, atol=1e-6)  # mm
    np.testing.assert_allclose(np.linalg.norm(verts[:, 3:], axis=1), 1.0, atol=1e-5)
    faces = np.array([[int(x) for x in r.split()] for r in body[len(box.vertices) :]])
    assert (faces[:, 0] == 3).all()
    np.testing.assert_array_equal(faces[:, 1:], box.faces)
    v, _ = bf.read_model_ply(path)
    np.testing.assert_allclose(v, box.vertices * 1000.0, atol=1e-6)


def test_binary_model_ply(dataset: Path) -> None:
    path = dataset / "models" / "obj_000002.ply"
    assert _ply_header(path)[1] == "format binary_little_endian 1.0"
    v, f = bf.read_model_ply(path)
    cyl = _cylinder()
    np.testing.assert_allclose(v, cyl.vertices * 1000.0, atol=1e-3)  # float32 in mm
    np.testing.assert_array_equal(f, cyl.faces)


def test_models_info_box_and_cylinder(dataset: Path) -> None:
    raw = json.loads((dataset / "models" / "models_info.json").read_text())
    box = raw["1"]
    assert box["diameter"] == pytest.approx(np.linalg.norm(BOX_EXTENTS) * 1000.0)
    for i, a in enumerate("xyz"):
        assert box[f"min_{a}"] == pytest.approx(-BOX_EXTENTS[i] * 500.0)
        assert box[f"size_{a}"] == pytest.approx(BOX_EXTENTS[i] * 1000.0)
    # the three 180-degree turns about x, y and z, flattened row-wise
    assert len(box["symmetries_discrete"]) == 3
    for axis in ([1, 0, 0], [0, 1, 0], [0, 0, 1]):
        T = np.eye(4)
        T[:3, :3] = axis_angle(axis, np.pi)
        assert any(np.allclose(f, T.reshape(-1), atol=1e-9) for f in box["symmetries_discrete"])
    assert "symmetries_continuous" not in box
    cyl = raw["2"]
    assert cyl["symmetries_continuous"] == [{"axis": [0.0, 0.0, 1.0], "offset": [0.0, 0.0, 10.0]}]
    assert "symmetries_discrete" not in cyl
    v = _cylinder().vertices * 1000.0
    assert cyl["diameter"] == pytest.approx(pdist(v).max())
    info = bf.read_models_info(dataset)
    assert info[2].diameter_mm == pytest.approx(np.hypot(60.0, 80.0), rel=1e-6)
    np.testing.assert_allclose(info[2].symmetries_continuous[0].offset_mm, [0, 0, 10.0])
    sym = info[2].symmetry()
    assert sym["continuous"] == [{"axis": [0.0, 0.0, 1.0], "offset": [0.0, 0.0, 0.01]}]


def test_discrete_symmetry_translation_in_mm() -> None:
    # a 180-degree turn about x through (0, 0, 0.01) m moves the origin by (0, 0, 0.02) m
    sym = discrete_symmetry([axis_angle([1, 0, 0], np.pi)], offset=(0.0, 0.0, 0.01))
    info = bf.model_info(_box().vertices, sym)
    (T,) = info["symmetries_discrete"]
    T = np.reshape(T, (4, 4))  # row-major: translation in the last column
    np.testing.assert_allclose(T[:3, 3], [0.0, 0.0, 20.0], atol=1e-9)
    np.testing.assert_allclose(T[3], [0, 0, 0, 1])
    m = bf.ModelInfo(1, 1.0, np.zeros(3), np.ones(3), symmetries_discrete=(T,))
    np.testing.assert_allclose(np.asarray(m.symmetry()["discrete"][0]), sym["discrete"][0])


# -- targets, category map, camera ------------------------------------------------------------
def test_targets_category_map_camera(dataset: Path) -> None:
    raw = json.loads((dataset / bst.TARGETS_NAME).read_text())
    assert raw[0] == {"im_id": 0, "inst_count": 2, "obj_id": 1, "scene_id": 1}
    assert bf.read_targets(dataset) == [bf.BopTarget(1, 0, 1, 2), bf.BopTarget(4, 7, 2, 1)]
    assert bf.read_category_map(dataset) == {
        1: bf.ObjectEntry("box", "test", "box/abc"),
        2: bf.ObjectEntry("can", "val", "can/7"),
    }
    raw_map = json.loads((dataset / "models" / bst.CATEGORY_MAP_NAME).read_text())
    assert raw_map["2"] == {"category": "can", "key": "can/7", "split": "val"}
    bf.write_camera(dataset / "camera.json", K, W, H, 0.1)
    cam = json.loads((dataset / "camera.json").read_text())
    assert cam == {
        "cx": 15.5,
        "cy": 11.5,
        "depth_scale": 0.1,
        "fx": 40.0,
        "fy": 42.0,
        "height": H,
        "width": W,
    }


# -- ownership --------------------------------------------------------------------------------
def test_refuses_a_foreign_non_empty_directory(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(bst.ForeignOutputError, match=r"did not create.*notes\.txt"):
        bst.claim_dataset_dir(tmp_path)
    with pytest.raises(bst.ForeignOutputError, match="claim_dataset_dir"):
        bf.write_targets(tmp_path / bst.TARGETS_NAME, [bf.BopTarget(0, 0, 1, 1)])
    with pytest.raises(bst.ForeignOutputError):
        bs.SceneWriter(tmp_path, "test", 0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_claims_new_empty_and_own_directories(tmp_path: Path) -> None:
    root = bst.claim_dataset_dir(tmp_path / "a" / "b")  # created
    assert (root / bst.MARKER_NAME).is_file()
    bf.write_targets(root / bst.TARGETS_NAME, [bf.BopTarget(0, 0, 1, 1)])
    assert bst.claim_dataset_dir(root) == root  # ours: accepted again
    (tmp_path / "empty").mkdir()
    bst.claim_dataset_dir(tmp_path / "empty")
    (tmp_path / "file").write_text("x")
    with pytest.raises(bst.ForeignOutputError, match="is a file"):
        bst.claim_dataset_dir(tmp_path / "file")


# -- reader errors ----------------------------------------------------------------------------
def _edit(path: Path, fn: object) -> None:
    content = json.loads(path.read_text())
    fn(content)  # type: ignore[operator]
    path.write_text(json.dumps(content))


def test_reader_names_file_and_key(dataset: Path) -> None:
    scene = dataset / "test" / "000001"
    _edit(scene / "scene_camera.json", lambda c: c["1"].pop("cam_K"))
    with pytest.raises(BopFormatError, match=r"scene_camera\.json key \['1'\]\['cam_K'\]: missing"):
        bs.read_scene(dataset, "test", 1)
    _edit(scene / "scene_camera.json", lambda c: c["1"].update(cam_K=K.reshape(-1).tolist()))
    _edit(scene / "scene_gt.json", lambda c: c["0"][1].update(cam_R_m2c=[1.0] * 8))
    with pytest.raises(BopFormatError, match=r"scene_gt\.json key \['0'\]\[1\]\['cam_R_m2c'\]"):
        bs.read_scene(dataset, "test", 1)


def test_reader_damaged_and_missing_files(dataset: Path) -> None:
    scene = dataset / "test" / "000004"
    (scene / "scene_gt.json").write_text('{"3": [')
    with pytest.raises(BopFormatError, match=r"scene_gt\.json: not valid JSON"):
        bs.read_scene(dataset, "test", 4)
    (scene / "scene_gt.json").unlink()
    with pytest.raises(BopFormatError, match=r"scene_gt\.json: file missing"):
        bs.read_scene(dataset, "test", 4)
    assert bs.read_scene(dataset, "test", 4, require_gt=False).images[3].gt == ()
    s = bs.read_scene(dataset, "test", 1)
    (s.path / "depth" / "000001.png").unlink()
    with pytest.raises(BopFormatError, match=r"depth/000001\.png: image missing"):
        s.depth_mm(1)
    (s.path / "depth" / "000000.png").write_bytes(b"not a png")
    with pytest.raises(BopFormatError, match=r"depth/000000\.png: not a readable image"):
        s.depth_mm(0)
    with pytest.raises(BopFormatError, match="no instance 3"):
        s.mask(0, 3)
    with pytest.raises(BopFormatError, match=r"models_info\.json: file missing"):
        bf.read_models_info(dataset / "nowhere")


def test_reader_key_sets_must_agree(dataset: Path) -> None:
    scene = dataset / "test" / "000001"
    _edit(scene / "scene_gt_info.json", lambda c: c.pop("1"))
    with pytest.raises(BopFormatError, match=r"scene_gt_info\.json: lacks image ids 1"):
        bs.read_scene(dataset, "test", 1)
    _edit(scene / "scene_gt.json", lambda c: c.update({"00": c["0"]}))
    with pytest.raises(BopFormatError, match=r"key \['00'\]: keys must be ids"):
        bs.read_scene(dataset, "test", 1)


def test_models_info_errors(dataset: Path) -> None:
    path = dataset / "models" / "models_info.json"
    _edit(path, lambda c: c["1"].update(diameter="12"))
    with pytest.raises(BopFormatError, match=r"key \['1'\]\['diameter'\]: must be a number"):
        bf.read_models_info(dataset)
    _edit(path, lambda c: c["1"].update(diameter=1.0, symmetries_discrete=[[1.0] * 15]))
    with pytest.raises(BopFormatError, match=r"\['symmetries_discrete'\]\[0\]: must be 16"):
        bf.read_models_info(dataset)
    path.write_text('{"1": {"diameter": NaN}}')
    with pytest.raises(BopFormatError, match="NaN is not a JSON number"):
        bf.read_models_info(dataset)


def test_targets_errors(dataset: Path) -> None:
    path = dataset / bst.TARGETS_NAME
    _edit(path, lambda c: c[1].pop("inst_count"))
    with pytest.raises(BopFormatError, match=r"\[1\]\['inst_count'\]: missing"):
        bf.read_targets(dataset)


def test_scene_json_written_on_close_only(tmp_path: Path) -> None:
    root = bst.claim_dataset_dir(tmp_path)
    with pytest.raises(RuntimeError), bs.SceneWriter(root, "val", 3) as sw:
        sw.add_image(0, **_image(0))
        raise RuntimeError("interrupted")
    scene = bf.scene_path(root, "val", 3)
    assert (scene / "rgb" / "000000.png").is_file()
    assert not list(scene.glob("*.json"))
    sw2 = bs.SceneWriter(root, "val", 3)
    sw2.add_image(0, **_image(0))
    with pytest.raises(ValueError, match="already added"):
        sw2.add_image(0, **_image(0))
    sw2.close()
    assert sorted(bs.read_scene(root, "val", 3).images) == [0]
