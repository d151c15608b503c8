"""The ObjectSet API, instance keys, cached processing and bad input."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from beo_bench.errors import (
    BeoBenchError,
    InstanceIndexError,
    InvalidKeyError,
    UnknownCategoryError,
    UnknownSplitError,
)
from beo_bench.objects import (
    DEFAULT_SPLIT_SIZES,
    ObjectInstance,
    ObjectSet,
    cache,
    categories,
    instance_from_key,
)
from beo_bench.objects.processing import voxelize


def test_object_set_api() -> None:
    s = ObjectSet("val")
    assert s.categories == categories()
    assert len(s) == DEFAULT_SPLIT_SIZES["val"] * len(s.categories)
    inst = s.get("mug", 2)
    assert isinstance(inst, ObjectInstance)
    assert (inst.category, inst.split, inst.index) == ("mug", "val", 2)
    assert inst.key == "proc/v2/mug/val/2"
    assert instance_from_key(inst.key).content_hash == inst.content_hash
    keys = [i.key for i in ObjectSet("test", ["bowl", "mug"], per_category=3)]
    assert keys == [f"proc/v2/{c}/test/{i}" for c in ("bowl", "mug") for i in range(3)]
    assert set(inst.params) and inst.symmetry.keys() == {"continuous", "discrete"}
    np.testing.assert_allclose(inst.size, inst.mesh.extents)


def test_keys_unique_across_splits() -> None:
    keys = {
        i.key
        for split in ("train", "val", "test", "ood")
        for i in ObjectSet(split, ["can"], per_category=5)
    }
    assert len(keys) == 20


def test_voxels_match_the_mesh() -> None:
    inst = ObjectSet("test").get("box", 0)
    v = inst.voxels(32)
    assert v.shape == (32, 32, 32) and v.dtype == bool
    # occupied volume agrees with the mesh volume within a few percent
    cell = (inst.size.max() / 32) ** 3
    assert abs(v.sum() * cell - inst.mesh.volume) / inst.mesh.volume < 0.1
    # the largest extent spans the grid: filled cells touch both faces on that axis
    axis = int(np.argmax(inst.size))
    profile = v.any(axis=tuple(a for a in range(3) if a != axis))
    assert profile[0] and profile[-1]
    # cached: a second call returns the same grid from disk
    np.testing.assert_array_equal(inst.voxels(32), v)
    assert inst.voxels(16).shape == (16, 16, 16)


def test_quarter_turn_symmetries_hold_on_the_voxel_grid() -> None:
    """Quarter turns about z are exact index permutations of the grid: a declared one keeps
    the grid (IoU > 0.95), an undeclared one changes it."""
    checked = 0
    for c in categories():
        for inst in ObjectSet("test", [c], per_category=4):
            v = inst.voxels(32)
            for k in (1, 2):
                angle = np.pi / 2 * k
                T = np.eye(4)
                T[:2, :2] = [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]
                declared = bool(inst.symmetry["continuous"]) or any(
                    np.allclose(np.asarray(D)[:3, :3], T[:3, :3], atol=1e-6)
                    for D in inst.symmetry["discrete"]
                )
                r = np.rot90(v, k, axes=(0, 1))
                iou = (r & v).sum() / (r | v).sum()
                if declared:
                    assert iou > 0.95, (inst.key, k, iou)
                    checked += 1
                elif k == 1:
                    assert iou < 0.95, (inst.key, k, iou)
    assert checked > 0


def test_voxelize_handmade_cube() -> None:
    import trimesh

    cube = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    assert voxelize(cube, 8).all()
    half = voxelize(cube, 8, extent=2.0)
    assert half.sum() == 4**3 and half[2:6, 2:6, 2:6].all()


def test_surface_points_on_surface() -> None:
    inst = ObjectSet("test").get("bottle", 1)
    p, n = inst.surface_points(512)
    assert p.shape == (512, 3) and n.shape == (512, 3)
    _, dist, _ = inst.mesh.nearest.on_surface(p)
    assert dist.max() < 1e-5  # 10 um: closest-point error on sliver faces
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)


@pytest.mark.parametrize(
    ("call", "exc", "words"),
    [
        (lambda: ObjectSet("test", ["teapot"]), UnknownCategoryError, "teapot"),
        (lambda: ObjectSet("test").get("mugg", 0), UnknownCategoryError, "mugg"),
        (lambda: ObjectSet("test").get("mug", 50), InstanceIndexError, "0..49"),
        (lambda: ObjectSet("test").get("mug", -1), InstanceIndexError, "-1"),
        (lambda: ObjectSet("testing"), UnknownSplitError, "testing"),
        (lambda: instance_from_key("mug-3"), InvalidKeyError, "mug-3"),
        (lambda: instance_from_key("proc/v0/mug/test/3"), InvalidKeyError, "v0"),
        (lambda: instance_from_key("proc/v2/mug/test/x"), InvalidKeyError, "proc/v2"),
        (lambda: instance_from_key("proc/v1/mug/test/3"), InvalidKeyError, "from library v1"),
        (lambda: instance_from_key("nosuch/abc"), InvalidKeyError, "nosuch"),
    ],
)
def test_bad_input_raises_specific_errors(call, exc, words) -> None:
    with pytest.raises(exc) as info:
        call()
    assert isinstance(info.value, BeoBenchError)
    assert words in str(info.value)


def test_cache_write_is_atomic_on_failure(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BEO_BENCH_CACHE", str(tmp_path))

    def boom() -> dict[str, np.ndarray]:
        raise RuntimeError("processing failed")

    with pytest.raises(RuntimeError):
        cache.cached("voxels", "ab" * 16, {"D": 4}, boom)
    assert not [f for f in tmp_path.rglob("*") if f.is_file()]
    # a corrupt entry is recomputed, not trusted
    path = cache.entry_path("voxels", "ab" * 16, {"D": 4})
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"not an npz")
    out = cache.cached("voxels", "ab" * 16, {"D": 4}, lambda: {"x": np.arange(3)})
    np.testing.assert_array_equal(out["x"], np.arange(3))


def test_killed_writer_leaves_no_entry(tmp_path: Path) -> None:
    """SIGKILL while an entry is being written: no readable-but-partial entry remains, and
    the next run computes it normally."""
    script = textwrap.dedent("""
        import sys, numpy as np
        from beo_bench.objects import cache
        def slow():
            print("computing", flush=True)
            import time; time.sleep(30)
            return {"x": np.zeros(10)}
        cache.cached("voxels", "cd" * 16, {"D": 4}, slow)
    """)
    env = {**os.environ, "BEO_BENCH_CACHE": str(tmp_path)}
    proc = subprocess.Popen(
        [sys.executable, "-c", script], env=env, stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None and proc.stdout.readline().strip() == "computing"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not list(tmp_path.rglob("*.npz"))
    out = cache.cached("voxels", "cd" * 16, {"D": 4}, lambda: {"x": np.ones(2)})
    assert out["x"].sum() == 2


def test_cache_info_and_clear(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BEO_BENCH_CACHE", str(tmp_path))
    ObjectSet("test").get("can", 0).voxels(8)
    info = cache.info()
    assert info["kinds"]["voxels"]["entries"] == 1 and info["bytes"] > 0
    assert cache.clear() > 0
    assert cache.info()["kinds"] == {}


def test_inside_tests_release_their_embree_scene() -> None:
    """A process holding ~1000 meshes that each kept an Embree scene segfaulted in Embree;
    the inside test must leave none behind (and still be exact)."""
    import trimesh

    from beo_bench.objects.processing import voxelize
    from beo_bench.objects.solid import contains

    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    inside = contains(box, np.array([[0.0, 0.0, 0.0], [0.9, 0.0, 0.0]]))
    assert inside.tolist() == [True, False]
    voxelize(box, 8)
    assert len(box.ray._cache.cache) == 0


def test_a_contact_sheet_wraps_a_category_onto_rows_of_its_columns(tmp_path) -> None:
    """docs/objects.md's one-class sheets: 4 instances at 2 columns take two rows (about
    twice the height of one row of 4, half the width)."""
    from PIL import Image

    from beo_bench.objects.sheet import contact_sheet

    objects = ObjectSet("test", categories=["bowl"], per_category=4)
    wide = Image.open(contact_sheet(tmp_path / "wide.png", objects, per_category=4)).size
    tall = Image.open(contact_sheet(tmp_path / "tall.png", objects, per_category=4, columns=2)).size
    assert tall[1] == pytest.approx(2 * wide[1], rel=0.01)
    assert tall[0] < 0.6 * wide[0]
