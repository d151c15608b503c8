"""Real-world mesh defects, built with trimesh at test time (no downloads): textured OBJs
with UV seams, STLs with zero-area faces, overlapping convex-hull sets (VHACD output),
open scans, truncated files and NaN coordinates. Each test asserts what a user relies on:
the file loads as a watertight solid, its ground-truth voxels match an exact reference, or
it is refused at load time with an error that names the file."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

from beo_bench.errors import MeshLoadError, NonFiniteMeshError, TruncatedMeshError
from beo_bench.objects.datasets import open_dataset
from beo_bench.objects.datasets.meshfile import read_mesh
from beo_bench.objects.instance import ObjectInstance
from beo_bench.objects.processing import (
    MAX_FACES,
    _clean,
    _voxel_remesh,
    repair,
    simplify,
    voxelize,
)

MODES = ("basic", "solid", "voxel")


pytestmark = pytest.mark.usefixtures("isolated_loaders")


def _load_one(path: Path, root: Path, **kw: object) -> ObjectInstance:
    """The instance of ``path`` from a folder dataset at ``root``, whatever its split."""
    for split in ("train", "val", "test"):
        for inst in open_dataset(root, **kw).objects(split):
            if inst.path == path:
                return inst
    raise AssertionError(f"{path} not found under {root}")


def _closed_mesh_obj(path: Path) -> trimesh.Trimesh:
    """Write a closed sphere as OBJ (trimesh's exporter) and return it."""
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(trimesh.exchange.obj.export_obj(sphere, include_normals=True))
    return sphere


# --------------------------------------------------------------------- loads and is closed


def test_textured_obj_with_uv_seams_loads_watertight(tmp_path: Path) -> None:
    # Every corner has its own UV (a texture atlas): the OBJ repeats each position once per
    # face, and only a merge that ignores UVs and normals closes the surface.
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    corners = sphere.vertices[sphere.faces.reshape(-1)]
    uv = np.random.default_rng(0).uniform(size=(len(corners), 2))
    textured = trimesh.Trimesh(
        corners,
        np.arange(len(corners)).reshape(-1, 3),
        visual=trimesh.visual.TextureVisuals(uv=uv, image=Image.new("RGB", (4, 4))),
        process=False,
    )
    path = tmp_path / "data" / "fruit" / "seams.obj"
    path.parent.mkdir(parents=True)
    textured.export(path)
    raw = trimesh.load(path, force="mesh")
    raw.merge_vertices()
    assert not raw.is_watertight  # the defect is real: a plain merge keeps the seams

    mesh = _load_one(path, tmp_path / "data", size="native").mesh
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx(sphere.volume, rel=1e-6)


def _t_junction_box() -> trimesh.Trimesh:
    """A closed box whose edge (a, b) is split at its midpoint m on one side only, closed by
    the zero-area face (a, b, m): what CAD exporters leave at T-junctions."""
    box = trimesh.creation.box((0.1, 0.2, 0.3))
    verts, faces = box.vertices.tolist(), box.faces.tolist()
    a, b, c = faces[0]
    verts.append(((np.asarray(verts[a]) + np.asarray(verts[b])) / 2).tolist())
    m = len(verts) - 1
    faces[0] = [a, m, c]
    faces += [[m, b, c], [a, b, m]]
    return trimesh.Trimesh(np.asarray(verts), np.asarray(faces), process=False)


def test_stl_with_zero_area_faces_stays_closed(tmp_path: Path) -> None:
    box = _t_junction_box()
    path = tmp_path / "data" / "carton" / "cad.stl"
    path.parent.mkdir(parents=True)
    box.export(path)
    raw = trimesh.load(path, force="mesh")
    degenerate = ~raw.nondegenerate_faces()
    assert raw.is_watertight and degenerate.any()
    opened = raw.copy()
    opened.update_faces(~degenerate)
    assert not opened.is_watertight  # the defect is real: dropping the face opens the box

    mesh = _load_one(path, tmp_path / "data", size="native").mesh
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx(0.1 * 0.2 * 0.3, rel=1e-6)


# ----------------------------------------------------------- overlapping convex hull sets


def _hull_set(seed: int, n: int = 12) -> list[trimesh.Trimesh]:
    """``n`` overlapping convex hulls, like a VHACD decomposition stored as one mesh."""
    rng = np.random.default_rng(seed)
    return [
        trimesh.convex.convex_hull(rng.uniform(-0.04, 0.04, 3) + rng.normal(0, 0.025, (40, 3)))
        for _ in range(n)
    ]


@pytest.mark.parametrize("seed", [0, 1])
def test_overlapping_hulls_voxels_count_overlaps_once(seed: int) -> None:
    parts = _hull_set(seed)
    soup = trimesh.util.concatenate(parts)
    exact = trimesh.boolean.union(parts, engine="manifold")  # one body: parity is exact
    centre = soup.bounds.mean(axis=0)
    soup.apply_translation(-centre)
    exact.apply_translation(-centre)
    extent = float(soup.extents.max())
    assert soup.is_watertight and soup.body_count == len(parts)
    for D in (32, 64):
        truth = voxelize(exact, D, extent)
        got = voxelize(soup, D, extent)
        assert np.sum(got != truth) / truth.sum() < 0.01, D
    # the defect is real: a parity test drops the overlaps
    pts = np.random.default_rng(seed).uniform(-extent / 2, extent / 2, (20000, 3))
    inside = exact.contains(pts)
    assert np.sum(inside & ~soup.contains(pts)) / inside.sum() > 0.1


def test_hull_set_file_loads_as_one_solid(tmp_path: Path) -> None:
    parts = _hull_set(2)
    exact = trimesh.boolean.union(parts, engine="manifold")
    path = tmp_path / "data" / "toy" / "vhacd.obj"
    path.parent.mkdir(parents=True)
    path.write_text(trimesh.exchange.obj.export_obj(trimesh.util.concatenate(parts)))
    root = tmp_path / "data"

    united = _load_one(path, root, size="native")
    assert united.mesh.is_watertight and united.mesh.body_count == 1
    assert united.mesh.volume == pytest.approx(exact.volume, rel=1e-4)

    # unrepaired, the parts stay separate, and the voxels still count their overlaps once
    kept = _load_one(path, root, size="native", repair="none")
    assert kept.mesh.body_count == len(parts)
    exact.apply_translation(-exact.bounds.mean(axis=0))
    truth = voxelize(exact, 32, float(kept.mesh.extents.max()))
    assert np.sum(kept.voxels(32) != truth) / truth.sum() < 0.01


# -------------------------------------------------------------- solidifying open meshes


def test_solid_repair_closes_large_holes_with_few_faces() -> None:
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.05)
    # a scan that missed the top: a 30-degree cap is gone, far beyond hole filling
    capless = trimesh.Trimesh(sphere.vertices, sphere.faces[sphere.triangles_center[:, 2] < 0.043])
    # a cylinder without its caps
    cyl = trimesh.creation.cylinder(0.03, 0.1, sections=24)
    tube = trimesh.Trimesh(cyl.vertices, cyl.faces[np.abs(cyl.face_normals[:, 2]) < 0.5])
    for name, mesh, closed in (("capless", capless, sphere), ("tube", tube, cyl)):
        solid = repair(mesh, name, mode="solid")
        assert solid.is_watertight and solid.body_count == 1, name
        assert len(solid.faces) <= MAX_FACES, name
        # the open shape bounds at most its closed counterpart's volume, and loses little
        assert 0.9 * closed.volume < solid.volume < 1.02 * closed.volume, name
    # repair='voxel' keeps its behaviour: a thin shell around the open tube; simplified, as
    # CoACD's input always was: a fraction of marching cubes' faces, the same solid
    shell = repair(tube, "tube", mode="voxel")
    assert shell.is_watertight and shell.volume < 0.5 * cyl.volume
    cubes = _voxel_remesh(_clean(tube), 96)
    assert len(shell.faces) < len(cubes.faces) / 4
    assert shell.volume == pytest.approx(cubes.volume, rel=0.01)
    extent = float(cubes.extents.max())
    centre = cubes.bounds.mean(axis=0)
    assert np.array_equal(
        voxelize(shell.copy().apply_translation(-centre), 32, extent),
        voxelize(cubes.copy().apply_translation(-centre), 32, extent),
    )


def test_simplify_reaches_the_face_budget() -> None:
    dense = trimesh.creation.icosphere(subdivisions=6, radius=0.05)  # 81920 faces
    small = simplify(dense, MAX_FACES)
    assert len(small.faces) <= MAX_FACES and small.is_watertight
    assert small.volume == pytest.approx(dense.volume, rel=0.01)
    assert simplify(small, MAX_FACES) is small  # within budget: untouched


# ---------------------------------------------------------------- corrupt input refused


def _with_nan(obj: bytes) -> bytes:
    """The OBJ with its first vertex's x coordinate replaced by NaN."""
    return re.sub(rb"(?m)^v \S+", b"v nan", obj, count=1)


def test_nan_vertex_is_refused_with_a_specific_error(tmp_path: Path) -> None:
    folder = tmp_path / "data" / "thing"
    good = _closed_mesh_obj(folder / "nan.obj")
    (folder / "nan.obj").write_bytes(_with_nan((folder / "nan.obj").read_bytes()))
    bad = good.copy()
    bad.vertices[3] = [np.inf, 0.0, 0.0]
    bad.export(folder / "inf.stl")
    for name in ("nan.obj", "inf.stl"):
        for mode in (*MODES, "none"):
            inst = _load_one(folder / name, tmp_path / "data", repair=mode)
            with pytest.raises(NonFiniteMeshError, match=re.escape(name) + ".*NaN or infinite"):
                _ = inst.mesh


def test_truncated_obj_is_refused_in_every_repair_mode(tmp_path: Path) -> None:
    folder = tmp_path / "data" / "thing"
    _closed_mesh_obj(folder / "whole.obj")
    data = (folder / "whole.obj").read_bytes()
    face_line = data.index(b"\nf ", len(data) // 2)
    cuts = {
        "in_vertices.obj": data.index(b"\nv ", len(data) // 4) + 8,  # "v 0.0..." cut short
        "in_a_face.obj": face_line + 5,  # "f 12" : too few vertices
        # "f 117//117 99//99 11" of "... 119//119": well-formed, but the surface is open
        "in_the_last_index.obj": data.rstrip().rindex(b"//") - 1,
    }
    for name, cut in cuts.items():
        (folder / name).write_bytes(data[:cut])
    # a complete closed file that lacks only its final line break (folders are scanned once)
    (folder / "no_newline.obj").write_bytes(data.rstrip(b"\n"))
    for name in cuts:
        for mode in MODES:
            inst = _load_one(folder / name, tmp_path / "data", repair=mode)
            with pytest.raises(TruncatedMeshError, match=re.escape(name) + ".*truncated"):
                _ = inst.mesh
    assert _load_one(folder / "no_newline.obj", tmp_path / "data").mesh.is_watertight


def test_truncated_stl_is_named_truncated_not_a_parse_or_module_error(tmp_path: Path) -> None:
    """A cut binary STL was read as text and refused as having no faces (or, without
    charset-normalizer, as a missing module); a cut text STL lacks its endsolid line."""
    folder = tmp_path / "data" / "thing"
    folder.mkdir(parents=True)
    ball = trimesh.creation.icosphere(radius=0.05)
    binary = ball.export(file_type="stl")
    text = trimesh.exchange.stl.export_stl_ascii(ball).encode()
    (folder / "cut.stl").write_bytes(binary[: len(binary) // 2 + 7])
    (folder / "header.stl").write_bytes(binary[:40])
    (folder / "cut_text.stl").write_bytes(text[: len(text) // 2])
    (folder / "whole.stl").write_bytes(binary)
    (folder / "whole_text.stl").write_bytes(text)
    n = len(ball.faces)
    expected = {
        "cut.stl": f"declares {n:,} triangles ({84 + 50 * n:,} bytes) but it has "
        f"{len(binary) // 2 + 7:,} bytes",
        "header.stl": "84-byte header and this file has 40 bytes",
        "cut_text.stl": "a text STL ends with an endsolid line",
    }
    for name, why in expected.items():
        with pytest.raises(TruncatedMeshError, match=re.escape(name) + ": the file is trunc"):
            read_mesh(folder / name)
        with pytest.raises(TruncatedMeshError, match=re.escape(why)):
            read_mesh(folder / name)
    for name in ("whole.stl", "whole_text.stl"):
        assert len(read_mesh(folder / name).faces) == n


def test_objectset_check_reports_every_bad_file_at_load_time(tmp_path: Path) -> None:
    root = tmp_path / "data"
    folder = root / "thing"
    _closed_mesh_obj(folder / "fine.obj")
    data = (folder / "fine.obj").read_bytes()
    (folder / "cut.obj").write_bytes(data[: len(data) // 2])
    (folder / "nan.obj").write_bytes(_with_nan(data))
    seen: list[str] = []
    for split in ("train", "val", "test"):
        objects = open_dataset(root).objects(split)
        bad = sorted(i.path.name for i in objects if i.path.name != "fine.obj")
        if bad:
            with pytest.raises(MeshLoadError) as err:
                objects.check()
            assert all(name in str(err.value) for name in bad)
            seen += bad
        else:
            assert objects.check() is objects
    assert sorted(seen) == ["cut.obj", "nan.obj"]
