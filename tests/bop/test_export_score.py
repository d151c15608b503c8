"""``beo-bench export --format bop`` and ``beo-bench score --bop-results``, end to end: an
export read back with the BOP reader agrees with the suite's items (poses, depth, intrinsics,
models, targets, ids); a results file scores as BOP's figures say it must (the true poses
perfectly, known perturbations at the recalls worked out here by hand, a missing estimate
as a failure, the higher score winning); a broken results file is refused with its line;
the scored run pairs with in-tree runs in ``compare`` and ``gate``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from beo_bench.bench import compare
from beo_bench.bench.bopscore import NO_ESTIMATE, method_name, score_results
from beo_bench.bench.export import export_bop, open_items, training_suite
from beo_bench.bench.rows import read_rows
from beo_bench.bench.suites import get_suite
from beo_bench.bench.tally import recall_values
from beo_bench.bop.files import (
    model_path,
    read_category_map,
    read_model_ply,
    read_models_info,
    read_targets,
)
from beo_bench.bop.results import HEADER, BopEstimate, write_results
from beo_bench.bop.scenes import read_scene, scene_ids
from beo_bench.cli import main
from beo_bench.objects import instance_from_key

ISOLATED_DEPTH_SCALE_MM = 0.1
"""mm per unit of an isolated suite's exported depth PNGs (0.1 mm steps)."""
SHAPE_METRICS = (
    "class_acc",
    "confusion",
    "iou_mean",
    "iou_cam_mean",
    "edt_err_mean",
    "fscore_mean",
    "chamfer_l1_mean",
)
"""What a pose-only run cannot measure: left out of its summary, not faked."""
MSSD_FRACTIONS = np.arange(1, 11) / 20.0
"""BOP's MSSD thresholds: 0.05, 0.10, ..., 0.50 of the diameter."""
MSPD_PX_128 = np.arange(1, 11) * 1.0
"""BOP's MSPD thresholds, 5 ... 50 px of a 640-px-wide image, in a 128-px-wide one."""


def pose3(n: int):
    return get_suite("pose-3dof").with_overrides(size=n)


def tabletop(n: int):
    return get_suite("tabletop").with_overrides(size=n)


def rot_z(deg: float) -> np.ndarray:
    a = np.deg2rad(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def max_pairwise_distance(v: np.ndarray) -> float:
    """The largest distance between two of the points ``v`` (N, 3), over every pair."""
    best = 0.0
    for i in range(0, len(v), 512):
        d = np.linalg.norm(v[i : i + 512, None, :] - v[None, :, :], axis=-1)
        best = max(best, float(d.max()))
    return best


def project(K: np.ndarray, P: np.ndarray) -> np.ndarray:
    x = P @ K.T
    return x[:, :2] / x[:, 2:3]


def assert_depth(depth_mm: np.ndarray, view_depth_m, scale: float) -> None:
    """The exported depth (mm) is the view's (metres) to half a depth unit where the view
    has depth, 0 where it has none."""
    want = 1000.0 * np.asarray(view_depth_m, dtype=np.float64)
    valid = want > 0
    assert valid.sum() > 100
    assert (depth_mm[~valid] == 0).all()
    assert np.abs(depth_mm[valid] - want[valid]).max() <= scale / 2 + 1e-9


def oracle_estimates(root: Path, time: float = 0.25) -> list[BopEstimate]:
    """Every test target's true pose, read back from ``scene_gt.json``."""
    out = []
    targets = {(t.scene_id, t.im_id, t.obj_id) for t in read_targets(root)}
    for sid in scene_ids(root, "test"):
        scene = read_scene(root, "test", sid)
        for im_id, img in scene.images.items():
            for g in img.gt:
                if (sid, im_id, g.obj_id) in targets:
                    out.append(BopEstimate(sid, im_id, g.obj_id, 1.0, g.R_m2c, g.t_m2c_mm, time))
    return out


@pytest.fixture(scope="module")
def pose_export(tmp_path_factory):
    """pose-3dof, 4 test items and 2 training items."""
    root = tmp_path_factory.mktemp("pose3dof") / "bop"
    suite = pose3(4)
    done = export_bop(suite, root, train_items=2)
    assert done.images == {"test": 4, "train": 2} and done.targets == 4
    return suite, root


@pytest.fixture(scope="module")
def three(tmp_path_factory):
    """pose-3dof, 3 items (objects without symmetry), exported; with what the hand
    computations need per image: the true pose (mm), K, the model's vertices (mm) and
    diameter (mm)."""
    root = tmp_path_factory.mktemp("three") / "bop"
    suite = pose3(3)
    export_bop(suite, root)
    scene = read_scene(root, "test", 0)
    cmap = read_category_map(root)
    per_image = []
    for im_id in range(3):
        img = scene.images[im_id]
        (g,) = img.gt
        inst = instance_from_key(cmap[g.obj_id].key)
        assert not inst.symmetry.get("discrete") and not inst.symmetry.get("continuous")
        V = 1000.0 * np.asarray(inst.mesh.vertices, dtype=np.float64)
        per_image.append(
            {
                "obj_id": g.obj_id,
                "R": g.R_m2c,
                "t": g.t_m2c_mm,
                "K": img.camera.K,
                "V": V,
                "diameter": max_pairwise_distance(V),
            }
        )
    return suite, root, per_image


def score(suite, ests: list[BopEstimate], tmp_path: Path, name: str = "m"):
    """Score ``ests`` on ``suite``; the summary (as JSON) and the rows by item."""
    csv = tmp_path / f"{name}_beo-pose-test.csv"
    write_results(csv, ests)
    out = tmp_path / f"run-{name}"
    summary = score_results(suite, csv, out).to_json()
    rows = sorted(read_rows(out / "results.jsonl"), key=lambda r: (r["item"], r["view"]))
    return summary, rows


# -- 1. the export read back -------------------------------------------------------------------
def test_export_round_trip_isolated(pose_export) -> None:
    suite, root = pose_export
    scene = read_scene(root, "test", 0)
    assert scene_ids(root, "test") == [0] and sorted(scene.images) == [0, 1, 2, 3]
    cmap = read_category_map(root)
    infos = read_models_info(root)
    targets = read_targets(root)
    record = json.loads((root / "beo_bench_export.json").read_text())
    assert record["depth_scale"] == ISOLATED_DEPTH_SCALE_MM
    assert record["items"] == {"test": 4, "train": 2}
    items = open_items(suite)
    want_targets = []
    try:
        for i in range(4):
            truth = items.isolated_truth(i)
            view = items.isolated_view_only(i)
            img = scene.images[i]
            (g,) = img.gt
            # the pose: R as it is, t in mm
            np.testing.assert_allclose(g.R_m2c, truth.R_cam, rtol=0, atol=1e-9)
            np.testing.assert_allclose(g.t_m2c_mm, 1000.0 * truth.t_cam, rtol=1e-12, atol=1e-9)
            np.testing.assert_array_equal(img.camera.K, view.K)
            assert img.camera.depth_scale == ISOLATED_DEPTH_SCALE_MM
            # the depth: the view's, in 0.1 mm steps; 0 where the view has none
            assert_depth(scene.depth_mm(i), view.depth, ISOLATED_DEPTH_SCALE_MM)
            # the masks: an isolated view is never occluded (ideal sensor: the view's mask)
            np.testing.assert_array_equal(scene.mask_visib(i, 0), np.asarray(view.mask))
            assert not (scene.mask_visib(i, 0) & ~scene.mask(i, 0)).any()
            assert img.gt_info[0].visib_fract == 1.0
            # the object it is
            entry = cmap[g.obj_id]
            assert (entry.key, entry.category, entry.split) == (truth.key, truth.category, "test")
            want_targets.append((0, i, g.obj_id, 1))
    finally:
        items.close()
    assert [(t.scene_id, t.im_id, t.obj_id, t.inst_count) for t in targets] == want_targets
    # every model: the instance's mesh in mm, its diameter the largest vertex distance
    assert sorted(infos) == sorted(cmap) == list(range(1, len(cmap) + 1))
    for obj_id, entry in cmap.items():
        mesh = instance_from_key(entry.key).mesh
        V = 1000.0 * np.asarray(mesh.vertices, dtype=np.float64)
        v, f = read_model_ply(model_path(root, obj_id))
        np.testing.assert_allclose(v, V, rtol=0, atol=1e-5)  # written with 6 decimals
        np.testing.assert_array_equal(f, np.asarray(mesh.faces))
        assert infos[obj_id].diameter_mm == pytest.approx(max_pairwise_distance(V), rel=1e-9)
        np.testing.assert_allclose(infos[obj_id].min_mm, V.min(axis=0), rtol=1e-12)
        np.testing.assert_allclose(infos[obj_id].size_mm, np.ptp(V, axis=0), rtol=1e-9)


def test_export_training_split(pose_export) -> None:
    suite, root = pose_export
    train = read_scene(root, "train", 0)
    assert sorted(train.images) == [0, 1]
    cmap = read_category_map(root)
    test_ids = {g.obj_id for img in read_scene(root, "test", 0).images.values() for g in img.gt}
    items = open_items(training_suite(suite, 2))
    try:
        for i, img in train.images.items():
            (g,) = img.gt
            truth = items.isolated_truth(i)
            assert cmap[g.obj_id].split == "train" and cmap[g.obj_id].key == truth.key
            assert cmap[g.obj_id].category == truth.category
            assert g.obj_id not in test_ids  # the training instances are other objects
            np.testing.assert_allclose(g.R_m2c, truth.R_cam, rtol=0, atol=1e-9)
            np.testing.assert_allclose(g.t_m2c_mm, 1000.0 * truth.t_cam, rtol=1e-12)
            assert (root / "train" / "000000" / "rgb" / f"{i:06d}.png").is_file()
    finally:
        items.close()
    # the ids: test objects first, then the training ones
    assert max(test_ids) < min(g.obj_id for img in train.images.values() for g in img.gt)


def test_export_round_trip_tabletop(tmp_path) -> None:
    suite = tabletop(1)
    root = tmp_path / "bop"
    export_bop(suite, root)
    scene = read_scene(root, "test", 0)
    assert sorted(scene.images) == [0]
    img = scene.images[0]
    cmap = read_category_map(root)
    items = open_items(suite)
    try:
        views = items.views(0)
        truths = items.truths(0, views)
        assert len(views) >= 1 and len(img.gt) >= len(views)
        for j, truth in enumerate(truths):  # ground truth j is scored view j
            g = img.gt[j]
            np.testing.assert_allclose(g.R_m2c, truth.R_cam, rtol=0, atol=1e-9)
            np.testing.assert_allclose(g.t_m2c_mm, 1000.0 * truth.t_cam, rtol=1e-12)
            entry = cmap[g.obj_id]
            assert (entry.key, entry.category, entry.split) == (truth.key, truth.category, "test")
        view = views[0]
        np.testing.assert_array_equal(img.camera.K, view.K)
        scale = img.camera.depth_scale
        assert json.loads((root / "beo_bench_export.json").read_text())["depth_scale"] == scale
        assert_depth(scene.depth_mm(0), view.depth, scale)
        want_targets = sorted({(0, 0, img.gt[j].obj_id, 1) for j in range(len(views))})
    finally:
        items.close()
    got = sorted((t.scene_id, t.im_id, t.obj_id, t.inst_count) for t in read_targets(root))
    assert got == want_targets  # one per scored view: the others are no targets
    infos = read_models_info(root)
    for obj_id, entry in cmap.items():
        V = 1000.0 * np.asarray(instance_from_key(entry.key).mesh.vertices, dtype=np.float64)
        assert infos[obj_id].diameter_mm == pytest.approx(max_pairwise_distance(V), rel=1e-9)


def test_a_shorter_export_has_the_same_ids(pose_export, tmp_path) -> None:
    _, big = pose_export
    small = tmp_path / "bop"
    export_bop(pose3(2), small, train_items=0)
    big_map, small_map = read_category_map(big), read_category_map(small)
    assert sorted(small_map) == [1, 2]
    for obj_id, entry in small_map.items():
        assert big_map[obj_id] == entry
    big_gt = read_scene(big, "test", 0).images
    for im_id, img in read_scene(small, "test", 0).images.items():
        assert [g.obj_id for g in img.gt] == [g.obj_id for g in big_gt[im_id].gt]


def test_export_under_another_sensor(pose_export, tmp_path) -> None:
    _, ideal_root = pose_export
    suite = pose3(2).with_sensor("kinect-v1")
    root = tmp_path / "kinect"
    export_bop(suite, root, train_items=0)
    assert json.loads((root / "beo_bench_export.json").read_text())["sensor"] == "kinect-v1"
    kinect, ideal = read_scene(root, "test", 0), read_scene(ideal_root, "test", 0)
    items = open_items(suite)
    try:
        for i in range(2):
            (gk,), (gi,) = kinect.images[i].gt, ideal.images[i].gt
            assert gk.obj_id == gi.obj_id
            np.testing.assert_array_equal(gk.R_m2c, gi.R_m2c)
            np.testing.assert_array_equal(gk.t_m2c_mm, gi.t_m2c_mm)
            dk, di = kinect.depth_mm(i), ideal.depth_mm(i)
            assert np.abs(dk - di).max() > 1.0  # the sensor's noise and holes: not ideal
            scale = kinect.images[i].camera.depth_scale
            assert_depth(dk, items.isolated_view_only(i).depth, scale)
    finally:
        items.close()


def test_export_refuses_a_folder_it_did_not_create(tmp_path, capsys) -> None:
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("my notes\n")
    rc = main(["export", "--suite", "pose-3dof", "--episodes", "1", "--train-items", "0", str(out)])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("beo-bench: error:") and str(out) in err[0]
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    assert (out / "notes.txt").read_text() == "my notes\n"


# -- 2. the true poses score perfectly ----------------------------------------------------------
def _assert_perfect(summary: dict, rows: list[dict], n_views: int) -> None:
    m = summary["metrics"]
    assert summary["n"] == n_views == len(rows) and summary["failures"] == 0
    for key in ("ar_vsd", "ar_mssd", "ar_mspd", "ar_bop"):
        assert m[key] == 1.0, key
    assert m["rot_err_deg_mean"] == pytest.approx(0.0, abs=1e-6)
    assert m["trans_err_cm_mean"] == pytest.approx(0.0, abs=1e-9)
    assert m["failure_rate"] == 0.0
    assert m["class_given"] is True
    left_in = [k for k in SHAPE_METRICS if k in m]
    assert not left_in, f"a pose-only run reports {left_in}"
    for r in rows:
        assert r["failure"] is None and r["pose_only"] is True and r["class_given"] is True
        assert r["bop_recall"] == {"vsd": 1.0, "mssd": 1.0, "mspd": 1.0}
        assert "iou" not in r and "fscore" not in r and "size_err_pct" not in r


def test_oracle_results_score_perfectly_on_pose_3dof(pose_export, tmp_path) -> None:
    suite, root = pose_export
    summary, rows = score(suite, oracle_estimates(root), tmp_path, "truth")
    _assert_perfect(summary, rows, 4)
    assert summary["track"] == "class-given" and summary["backend"] == "truth"
    assert [r["ms"] for r in rows] == [250.0] * 4  # 0.25 s per image of one view


def test_oracle_results_score_perfectly_on_tabletop(tmp_path) -> None:
    suite = tabletop(2)
    root = tmp_path / "bop"
    export_bop(suite, root, train_items=0)
    ests = oracle_estimates(root)
    targets = read_targets(root)
    assert len(ests) == len(targets) >= 2
    summary, rows = score(suite, ests, tmp_path, "truth")
    _assert_perfect(summary, rows, len(targets))
    assert summary["track"] is None  # tabletop has no tracks
    assert {r["item"] for r in rows} == {0, 1}
    for r in rows:  # the image's 0.25 s shared among its targets
        share = sum(q["item"] == r["item"] for q in rows)
        assert r["ms"] == pytest.approx(250.0 / share)
    assert any(sum(q["item"] == i for q in rows) > 1 for i in (0, 1))


# -- 3. known perturbations, by hand -------------------------------------------------------------
def _mspd_by_hand(K, R_est, t_est, R_gt, t_gt, V) -> float:
    return float(
        np.linalg.norm(
            project(K, V @ R_est.T + t_est) - project(K, V @ R_gt.T + t_gt), axis=1
        ).max()
    )


def test_translation_along_the_camera_axis(three, tmp_path) -> None:
    """Every estimate 0.3 diameters too far along the camera's z: every vertex moves by
    that, so MSSD = 0.3 d, found at 0.35 ... 0.50 of the diameter (0.30 is a miss: strict
    <; 0.3 d is nudged by 1e-6 so rounding cannot put it on either side of 0.30)."""
    suite, _, per = three
    ests, mspd, offsets = [], [], []
    for im_id, p in enumerate(per):
        dz = np.array([0.0, 0.0, 0.3 * p["diameter"] * (1 + 1e-6)])
        offsets.append(dz[2])
        t_est = p["t"] + dz
        ests.append(BopEstimate(0, im_id, p["obj_id"], 1.0, p["R"], t_est))
        mspd.append(_mspd_by_hand(p["K"], p["R"], t_est, p["R"], p["t"], p["V"]))
    summary, rows = score(suite, ests, tmp_path)
    mspd_recall = [float(np.mean(px < MSPD_PX_128)) for px in mspd]
    for r, dz, px, rec in zip(rows, offsets, mspd, mspd_recall, strict=True):
        assert r["failure"] is None
        assert r["bop_mssd_mm"] == pytest.approx(dz, rel=1e-9)
        assert r["mssd_cm"] == pytest.approx(dz / 10.0, rel=1e-9)
        assert r["trans_err_cm"] == pytest.approx(dz / 10.0, rel=1e-9)
        assert r["rot_err_deg"] == pytest.approx(0.0, abs=1e-6)
        assert r["bop_mspd_px"] == pytest.approx(px, rel=1e-9)
        assert r["bop_recall"]["mssd"] == pytest.approx(0.4)
        assert r["bop_recall"]["mspd"] == pytest.approx(rec)
    m = summary["metrics"]
    assert m["ar_mssd"] == pytest.approx(0.4)
    assert m["ar_mspd"] == pytest.approx(np.mean(mspd_recall))
    assert 0.0 <= m["ar_vsd"] < 1.0
    assert m["ar_bop"] == pytest.approx((m["ar_vsd"] + m["ar_mssd"] + m["ar_mspd"]) / 3)


def test_quarter_turn_about_the_model_z_axis(three, tmp_path) -> None:
    """R_est = R_gt Rz(90 deg): MSSD = max |R_est x - R_gt x| over the vertices."""
    suite, _, per = three
    Rz = rot_z(90.0)
    ests, mssd, mspd = [], [], []
    for im_id, p in enumerate(per):
        R_est = p["R"] @ Rz
        ests.append(BopEstimate(0, im_id, p["obj_id"], 1.0, R_est, p["t"]))
        V = p["V"]
        mssd.append(float(np.linalg.norm(V @ R_est.T - V @ p["R"].T, axis=1).max()))
        mspd.append(_mspd_by_hand(p["K"], R_est, p["t"], p["R"], p["t"], V))
    summary, rows = score(suite, ests, tmp_path)
    mssd_rec = [
        float(np.mean(e / p["diameter"] < MSSD_FRACTIONS)) for e, p in zip(mssd, per, strict=True)
    ]
    mspd_rec = [float(np.mean(px < MSPD_PX_128)) for px in mspd]
    for r, e, px, a, b in zip(rows, mssd, mspd, mssd_rec, mspd_rec, strict=True):
        assert r["rot_err_deg"] == pytest.approx(90.0, abs=1e-6)
        assert r["trans_err_cm"] == pytest.approx(0.0, abs=1e-9)
        assert r["bop_mssd_mm"] == pytest.approx(e, rel=1e-9)
        assert r["bop_mspd_px"] == pytest.approx(px, rel=1e-9)
        assert r["bop_recall"]["mssd"] == pytest.approx(a)
        assert r["bop_recall"]["mspd"] == pytest.approx(b)
    m = summary["metrics"]
    assert m["ar_mssd"] == pytest.approx(np.mean(mssd_rec))
    assert m["ar_mspd"] == pytest.approx(np.mean(mspd_rec))
    assert m["rot_err_deg_mean"] == pytest.approx(90.0, abs=1e-6)


def test_an_estimate_of_another_images_object_is_no_estimate(three, tmp_path) -> None:
    """Image 0 gets an estimate of image 1's object (an obj_id that exists): image 0's
    target has no estimate, a failed view that is a miss in every recall."""
    suite, _, per = three
    ests = [BopEstimate(0, 0, per[1]["obj_id"], 1.0, per[0]["R"], per[0]["t"])]
    ests += [BopEstimate(0, i, per[i]["obj_id"], 1.0, per[i]["R"], per[i]["t"]) for i in (1, 2)]
    summary, rows = score(suite, ests, tmp_path)
    assert rows[0]["failure"] == NO_ESTIMATE and "bop_recall" not in rows[0]
    assert rows[0]["pose_only"] is True and "rot_err_deg" not in rows[0]
    assert [r["failure"] for r in rows[1:]] == [None, None]
    per_view = recall_values(rows, 128)
    assert per_view["ar_bop"].tolist() == [0.0, 1.0, 1.0]
    m = summary["metrics"]
    assert summary["failures"] == 1 and m["failure_rate"] == pytest.approx(1 / 3)
    for key in ("ar_vsd", "ar_mssd", "ar_mspd", "ar_bop"):
        assert m[key] == pytest.approx(2 / 3), key
    assert m["rot_err_deg_mean"] == pytest.approx(60.0)  # the failure at 180 deg
    left_in = [k for k in SHAPE_METRICS if k in m]
    assert not left_in, f"a failed pose-only view faked {left_in}"


def test_a_missing_estimate_fakes_no_size_error(three, tmp_path) -> None:
    suite, _, per = three
    ests = [BopEstimate(0, i, per[i]["obj_id"], 1.0, per[i]["R"], per[i]["t"]) for i in (1, 2)]
    summary, _ = score(suite, ests, tmp_path)
    assert summary["failures"] == 1
    assert "size_err_pct_mean" not in summary["metrics"]


def test_the_higher_score_is_the_estimate_scored(three, tmp_path) -> None:
    """Two estimates for one target: the higher-scored one counts (written second, so
    file order alone would not pick it)."""
    suite, _, per = three
    Rz = rot_z(90.0)
    p0, p1, p2 = per
    ests = [
        BopEstimate(0, 0, p0["obj_id"], 0.1, p0["R"] @ Rz, p0["t"], 0.5),  # wrong, low score
        BopEstimate(0, 0, p0["obj_id"], 0.9, p0["R"], p0["t"], 0.5),  # right, high score
        BopEstimate(0, 1, p1["obj_id"], 0.2, p1["R"], p1["t"], 0.5),  # right, low score
        BopEstimate(0, 1, p1["obj_id"], 0.8, p1["R"] @ Rz, p1["t"], 0.5),  # wrong, high score
        BopEstimate(0, 2, p2["obj_id"], 0.5, p2["R"], p2["t"], 0.5),
    ]
    summary, rows = score(suite, ests, tmp_path)
    assert rows[0]["rot_err_deg"] == pytest.approx(0.0, abs=1e-6)
    assert rows[0]["bop_recall"] == {"vsd": 1.0, "mssd": 1.0, "mspd": 1.0}
    assert rows[1]["rot_err_deg"] == pytest.approx(90.0, abs=1e-6)
    V = p1["V"]
    mssd = float(np.linalg.norm(V @ (p1["R"] @ Rz).T - V @ p1["R"].T, axis=1).max())
    assert rows[1]["bop_mssd_mm"] == pytest.approx(mssd, rel=1e-9)
    want = float(np.mean(mssd / p1["diameter"] < MSSD_FRACTIONS))
    assert rows[1]["bop_recall"]["mssd"] == pytest.approx(want)
    assert want < 1.0
    assert all(r["ms"] == 500.0 for r in rows)  # 0.5 s per image of one target
    assert summary["failures"] == 0


# -- 4. broken results files ---------------------------------------------------------------------
def _line(e: BopEstimate, **change) -> str:
    R = np.asarray(change.get("R", e.R)).reshape(-1)
    t = np.asarray(change.get("t", e.t_mm))
    ids = [
        change.get("scene_id", e.scene_id),
        change.get("im_id", e.im_id),
        change.get("obj_id", e.obj_id),
    ]
    return ",".join(
        [
            *map(str, ids),
            "1.0",
            " ".join(map(repr, map(float, R))),
            " ".join(map(repr, map(float, t))),
            "-1",
        ]
    )


def _cases(root: Path) -> dict[str, tuple[str, int]]:
    """name -> (file text, the line the error must name)."""
    good = oracle_estimates(root)
    lines = [_line(e) for e in good]
    e = good[1]
    return {
        "wrong header": ("scene_id,im_id,obj_id,score,R,t\n" + "\n".join(lines) + "\n", 1),
        "unknown obj_id": ("\n".join([HEADER, lines[0], _line(e, obj_id=999), lines[2]]) + "\n", 3),
        "missing image": ("\n".join([HEADER, lines[0], lines[1], _line(e, im_id=3)]) + "\n", 4),
        "not a rotation": ("\n".join([HEADER, lines[0], _line(e, R=1.01 * e.R)]) + "\n", 3),
        "duplicate row": ("\n".join([HEADER, lines[0], lines[1], lines[2], lines[1]]) + "\n", 5),
    }


def _score(csv: Path, out: Path) -> int:
    """``beo-bench score`` of ``csv`` on pose-3dof's first 3 items into ``out``."""
    argv = ["score", "--suite", "pose-3dof", "--episodes", "3", "--bop-results", str(csv)]
    return main([*argv, "--out", str(out)])


@pytest.mark.parametrize(
    "case", ["wrong header", "unknown obj_id", "missing image", "not a rotation", "duplicate row"]
)
def test_a_broken_results_file_is_refused_with_its_line(three, tmp_path, capsys, case) -> None:
    """Exit 2: a results file that breaks the format is the user's data (BopFormatError is a
    UserDataError; docs/failure-behaviour.md: 2 for a usage error or the user's data)."""
    _, root, _ = three
    text, line = _cases(root)[case]
    csv = tmp_path / "m_beo-pose-3dof-test.csv"
    csv.write_text(text)
    out = tmp_path / "run"
    capsys.readouterr()
    rc = _score(csv, out)
    err = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert rc == 2, err
    assert len(err) == 1, err
    assert err[0].startswith("beo-bench: error:") and f"{csv}:{line}:" in err[0], err[0]
    if case == "duplicate row":
        assert "line 3" in err[0]  # the earlier line is named too
    if case in ("missing image", "unknown obj_id"):  # the flags that make them agree
        assert "first 3 items" in err[0] and "--episodes" in err[0], err[0]
    assert not out.exists()


@pytest.mark.parametrize("suite", ["pick", "known-pose"])
def test_a_suite_that_scores_no_pose_is_refused(suite, tmp_path, capsys) -> None:
    csv = tmp_path / "m_x.csv"
    write_results(csv, [])
    out = tmp_path / "run"
    rc = main(["score", "--suite", suite, "--bop-results", str(csv), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "does not score poses" in err[0], err
    assert not out.exists()


def test_a_missing_results_file_is_a_usage_error(tmp_path, capsys) -> None:
    out = tmp_path / "run"
    csv = tmp_path / "nothing_here.csv"
    rc = _score(csv, out)
    err = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert rc == 2 and len(err) == 1 and err[0].startswith("beo-bench: error:")
    assert str(csv) in err[0]
    assert not out.exists()


# -- 5. the scored run pairs with in-tree runs ----------------------------------------------------
@pytest.mark.slow  # icp builds its class means (a cold asset cache: ~15 s)
def test_a_scored_run_pairs_with_an_icp_run(three, tmp_path, capsys) -> None:
    _, root, _ = three
    csv = tmp_path / "truth_beo-pose-3dof-test.csv"
    write_results(csv, oracle_estimates(root))
    bop, icp = tmp_path / "bop", tmp_path / "icp"
    rc = _score(csv, bop)
    assert rc == 0
    rc = main(
        [
            "run",
            "--suite",
            "pose-3dof",
            "--backend",
            "icp",
            "--track",
            "class-given",
            "--episodes",
            "3",
            "--workers",
            "1",
            "--opt",
            "mean_instances=4",
            "--out",
            str(icp),
        ]
    )
    assert rc == 0
    a, b = compare.load_run(icp), compare.load_run(bop)
    assert a.items == b.items == {0, 1, 2}
    results = {r.key: r for r in compare.paired_runs(a, b)}
    assert {"rot_err_deg_mean", "ar_bop", "ar_mssd"} <= set(results)
    assert results["ar_bop"].n_items == 3 and results["ar_bop"].b == 1.0
    assert results["rot_err_deg_mean"].b == pytest.approx(0.0, abs=1e-6)
    assert "iou_mean" not in results  # the scored run has none: nothing to pair
    capsys.readouterr()
    assert main(["compare", str(icp), str(bop)]) == 0
    assert "3 items in common" in capsys.readouterr().out
    assert main(["gate", str(bop), "--baseline", str(icp)]) in (0, 3)
    assert main(["gate", str(bop), "--baseline", str(icp), "--metrics", "ar_bop"]) in (0, 3)


# -- 6. the method's name ---------------------------------------------------------------------
def test_method_name_is_the_file_name_up_to_its_first_underscore() -> None:
    assert method_name(Path("mymethod_beo-pose-3dof-test.csv")) == "mymethod"
    assert method_name(Path("/x/y/mymethod_a_b.csv")) == "mymethod"
    assert method_name(Path("plain.csv")) == "plain"


def test_score_compares_with_the_depth_as_exported() -> None:
    """VSD in ``score`` reads the depth as the export's PNG holds it (the method's, and the
    toolkit's, depth): rounded to the PNG's step, 0 kept."""
    from beo_bench.bench.bopscore import as_exported
    from beo_bench.bench.export import DEPTH_SCALES

    suite = get_suite("tabletop").with_overrides(size=1)
    items = open_items(suite)
    try:
        view = items.views(0)[0]
    finally:
        items.close()
    q = np.asarray(as_exported(view, suite).depth, dtype=np.float64)
    d = np.asarray(view.depth, dtype=np.float64)
    step = DEPTH_SCALES[suite.kind] / 1000.0
    assert q.dtype == np.float64 and q.shape == d.shape
    np.testing.assert_allclose(q / step, np.round(q / step), atol=1e-3)
    assert np.abs(q - d).max() <= step / 2 + 1e-6 and ((q == 0) == (d <= 0)).all()
    assert (q != d).any()


def test_score_leaves_a_barely_visible_instance_out_of_bops_matching(monkeypatch) -> None:
    """Two views of one object in an image, one below visib_gt_min (10%): BOP's matching
    never gives an estimate to it (``match_poses``' valid instances), so an estimate that
    fits only it finds nothing, and the visible view's share is 0; our own metrics still
    score the hidden view with that estimate (nearest by MSSD)."""
    from beo_bench.bench import bopscore

    # (VSD per tau, MSSD / diameter, MSPD at 640 px) of estimate 0 against views 0 and 1
    errors = {0: (np.full(10, 0.01), 0.01, 1.0), 1: (np.full(10, 0.9), 0.9, 90.0)}
    monkeypatch.setattr(bopscore, "_errors", lambda e, view, gt, suite: errors[view])
    est = BopEstimate(0, 0, 7, 1.0, np.eye(3), np.zeros(3))
    hidden = bopscore._Target(0, None, 7, 0.05)  # type: ignore[arg-type]
    seen = bopscore._Target(1, None, 7, 0.9)  # type: ignore[arg-type]
    bopscore._match([hidden, seen], [est], get_suite("tabletop"), 0, 0)
    assert seen.shares == {"vsd": 0.0, "mssd": 0.0, "mspd": 0.0}
    assert hidden.best is est and seen.best is None
    # with the hidden view visible, the same estimate is found at every threshold
    hidden = bopscore._Target(0, None, 7, 0.5)  # type: ignore[arg-type]
    seen = bopscore._Target(1, None, 7, 0.9)  # type: ignore[arg-type]
    bopscore._match([hidden, seen], [est], get_suite("tabletop"), 0, 0)
    assert hidden.shares == {"vsd": 0.5, "mssd": 0.5, "mspd": 0.5}  # 1 of 2 targets found


# -- 7. attacks on `score` (issue 50) ----------------------------------------------------------
def _one_line_error(capsys) -> str:
    lines = capsys.readouterr().err.splitlines()
    err = [x for x in lines if x.strip() and "it/s]" not in x]  # not the progress bar's
    assert len(err) == 1 and err[0].startswith("beo-bench: error:"), err
    return err[0]


def test_a_rotation_printed_to_4_decimals_is_scored(three, tmp_path, capsys) -> None:
    """R to 4 decimals is within ROTATION_TOL (1e-3) but not the renderer's 1e-6: it scores
    (as its nearest rotation), where it once ended in a ValueError traceback."""
    _, root, _ = three
    lines = [HEADER]
    for e in oracle_estimates(root):
        R = " ".join(f"{x:.4f}" for x in np.asarray(e.R).reshape(-1))
        t = " ".join(f"{x:.4f}" for x in np.asarray(e.t_mm))
        lines.append(f"{e.scene_id},{e.im_id},{e.obj_id},1.0,{R},{t},0.25")
    csv = tmp_path / "rounded_beo-pose-3dof-test.csv"
    csv.write_text("\n".join(lines) + "\n")
    out = tmp_path / "run"
    assert _score(csv, out) == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["failures"] == 0
    assert summary["metrics"]["rot_err_deg_mean"] < 0.05


def test_score_refuses_a_run_directory(three, tmp_path, capsys) -> None:
    """--out at a `run` directory (the same marker) was silently replaced; now refused with
    one line naming --out, and nothing in it touched."""
    from beo_bench.bench.rundir import open_run_dir

    _, root, _ = three
    out = open_run_dir(tmp_path / "icp-run")  # a run's directory: marked, with its files
    (out / "run.json").write_text(
        json.dumps({"suite": {"name": "pose-3dof"}, "backend": "icp", "backend_kwargs": {}})
    )
    for name in ("results.jsonl", "summary.json", "report.html"):
        (out / name).write_text(f"the run's {name}\n")
    before = {p.name: p.read_bytes() for p in out.iterdir()}  # (run.lock: the lock's own)
    csv = tmp_path / "mine_beo-pose-3dof-test.csv"
    write_results(csv, oracle_estimates(root))
    capsys.readouterr()
    assert _score(csv, out) == 2
    err = _one_line_error(capsys)
    assert f"--out {out}" in err and "run of backend 'icp'" in err, err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.name != "run.lock"} == before


def test_score_refuses_another_methods_score_and_rewrites_its_own(three, tmp_path, capsys) -> None:
    _, root, _ = three
    ests = oracle_estimates(root)
    mine, other = tmp_path / "mine_x.csv", tmp_path / "other_x.csv"
    write_results(mine, ests)
    write_results(other, ests)
    out = tmp_path / "run"
    assert _score(mine, out) == 0
    (out / "report.html").write_text("an earlier report")
    assert _score(mine, out) == 0  # an earlier score of its own: rewritten, the report gone
    assert not (out / "report.html").exists()
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()
    assert _score(other, out) == 2
    err = _one_line_error(capsys)
    assert f"--out {out}" in err and "method 'mine'" in err, err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.name != "run.lock"} == {
        k: v for k, v in before.items() if k != "run.lock"
    }


def test_a_second_score_into_a_locked_directory_is_refused(three, tmp_path, capsys) -> None:
    from beo_bench.bench.rundir import lock_run_dir, open_run_dir

    _, root, _ = three
    csv = tmp_path / "mine_x.csv"
    write_results(csv, oracle_estimates(root))
    out = open_run_dir(tmp_path / "run")
    with lock_run_dir(out):  # another score (or run) holds it
        capsys.readouterr()
        assert _score(csv, out) == 1
        err = _one_line_error(capsys)
        assert "in use by another run" in err and str(out) in err, err
    assert not (out / "summary.json").exists()


@pytest.mark.parametrize("method", ["icp", "oracle"])
def test_a_scored_file_cannot_take_a_backends_name(three, tmp_path, capsys, method) -> None:
    """`--method icp` (or a file named icp_...) stood on the leaderboard as the baseline,
    `oracle` as the upper bound: refused, with a name to use instead."""
    _, root, _ = three
    csv = tmp_path / "mine_x.csv"
    write_results(csv, oracle_estimates(root))
    out = tmp_path / "run"
    capsys.readouterr()
    argv = ["score", "--suite", "pose-3dof", "--episodes", "3", "--bop-results", str(csv)]
    assert main([*argv, "--method", method, "--out", str(out)]) == 2
    err = _one_line_error(capsys)
    assert f"--method {method}" in err and f"--method {method}-bop" in err, err
    assert not out.exists()
    named = tmp_path / f"{method}_beo-pose-3dof-test.csv"
    write_results(named, oracle_estimates(root))
    assert _score(named, out) == 2
    assert "is the name of a beo-bench backend" in _one_line_error(capsys)


def test_no_infinity_is_ever_written(three, tmp_path, capsys, monkeypatch) -> None:
    """A time of 0 once wrote views_per_s: Infinity into summary.json (not JSON). The reader
    now refuses it (test_results.py); with that bound lifted, the writer still refuses any
    non-finite number, in one line, with nothing written."""
    from beo_bench.bop import results as br

    _, root, _ = three
    csv = tmp_path / "mine_x.csv"
    write_results(csv, oracle_estimates(root, time=0.5))
    csv.write_text(csv.read_text().replace(",0.5\n", ",0\n"))
    capsys.readouterr()
    out = tmp_path / "run"
    assert _score(csv, out) == 2
    assert ":2: time 0: must be seconds within" in _one_line_error(capsys)
    monkeypatch.setattr(br, "MIN_TIME_S", 0.0)
    assert _score(csv, out) == 1
    assert "NaN or infinite" in _one_line_error(capsys)
    assert not {"run.json", "results.jsonl", "summary.json"} & {p.name for p in out.iterdir()}
