"""Asset processing: solid checks and repair, voxel occupancy, surface samples, and convex
decomposition (CoACD) for meshes that do not bring their own convex parts.

Everything here is a pure function of a mesh plus settings; :mod:`beo_bench.objects.instance`
wraps it with the on-disk cache.
"""

from __future__ import annotations

import numpy as np
import trimesh

from beo_bench.errors import EmptyMeshError, NonWatertightMeshError

# symmetry estimation lives in its own module; re-exported here, where it used to be
from beo_bench.objects.symmetry import estimate_symmetry as estimate_symmetry
from beo_bench.objects.symmetry import pack_symmetry as pack_symmetry
from beo_bench.objects.symmetry import rotation_iou as rotation_iou
from beo_bench.objects.symmetry import unpack_symmetry as unpack_symmetry
from beo_bench.types import BoolGrid

DEFAULT_RESOLUTION = 32
"""Voxel grid size D (docs/design.md: D^3, default 32)."""


def check_solid(mesh: trimesh.Trimesh, what: str) -> None:
    """Raise if ``mesh`` is empty, not watertight, or encloses no volume."""
    if mesh is None or len(mesh.faces) == 0:
        raise EmptyMeshError(f"{what}: the mesh has no faces; use a mesh with geometry")
    if not mesh.is_watertight:
        raise NonWatertightMeshError(
            f"{what}: the mesh is not watertight; close its holes (e.g. with "
            f"repair='voxel', or a tool such as ManifoldPlus) before using it as an object"
        )
    if not mesh.volume > 0:
        raise EmptyMeshError(
            f"{what}: the mesh encloses no volume "
            f"(volume {mesh.volume:.3g} m^3); check its face orientation"
        )


def repair(
    mesh: trimesh.Trimesh, what: str, mode: str = "basic", resolution: int = 96
) -> trimesh.Trimesh:
    """Make ``mesh`` a usable solid or raise.

    ``basic`` merges duplicate vertices, drops degenerate and duplicate faces, fills small
    holes and fixes winding. ``voxel`` additionally remeshes a mesh that is still open: its
    surface is voxelised at ``resolution``, the inside filled, and marching cubes gives a
    closed surface (loses detail below one voxel). ``none`` only checks.
    """
    if mode not in ("basic", "voxel", "none"):
        raise ValueError(f"repair mode {mode!r}: use 'basic', 'voxel' or 'none'")
    if len(mesh.faces) == 0:
        raise EmptyMeshError(f"{what}: the mesh has no faces; use a mesh with geometry")
    if mode != "none":
        mesh = mesh.copy()
        mesh.merge_vertices()
        mesh.update_faces(mesh.nondegenerate_faces())
        mesh.update_faces(mesh.unique_faces())
        mesh.remove_unreferenced_vertices()
        if not mesh.is_watertight:
            trimesh.repair.fill_holes(mesh)
        trimesh.repair.fix_normals(mesh)
        if mesh.volume < 0:
            mesh.invert()
    if mode == "voxel" and not mesh.is_watertight:
        mesh = _voxel_remesh(mesh, resolution)
    check_solid(mesh, what)
    return mesh


def _voxel_remesh(mesh: trimesh.Trimesh, resolution: int) -> trimesh.Trimesh:
    from scipy import ndimage
    from skimage.measure import marching_cubes

    pitch = float(mesh.extents.max()) / resolution
    vox = mesh.voxelized(pitch)
    grid = np.pad(ndimage.binary_fill_holes(vox.matrix), 1)
    verts, faces, _, _ = marching_cubes(grid.astype(np.float32), 0.5)
    verts = (verts - 1) @ vox.transform[:3, :3].T + vox.transform[:3, 3]
    out = trimesh.Trimesh(verts, faces[:, ::-1], process=True)
    trimesh.repair.fix_normals(out)
    return out


def grid_centres(D: int, extent: float) -> np.ndarray:
    """(D^3, 3) cell centres of the cube of edge ``extent`` centred at the origin, in
    x-major order (reshape to (D, D, D) gives [x, y, z] indexing)."""
    g = ((np.arange(D) + 0.5) / D - 0.5) * extent
    return np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)


def contains(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """``mesh.contains(points)`` without leaving an Embree scene on the mesh.

    Each trimesh mesh owns a ray intersector that caches an Embree scene on its own Embree
    device. A process that keeps about a thousand instances in memory (a worker processing a
    whole training split) segfaulted inside Embree when creating the next device, so the
    scene is released after every test (rebuilding it costs about a millisecond)."""
    try:
        return np.asarray(mesh.contains(points), dtype=bool)
    finally:
        cache = getattr(getattr(mesh, "ray", None), "_cache", None)
        if cache is not None:
            cache.clear()


def voxelize(
    mesh: trimesh.Trimesh, D: int = DEFAULT_RESOLUTION, extent: float | None = None
) -> BoolGrid:
    """Solid occupancy of ``mesh`` on a D^3 grid: a cell is filled when its centre is inside.

    The grid is the cube of edge ``extent`` (default: the mesh's largest bounding-box
    extent) centred at the origin, i.e. the canonical frame scaled uniformly into the unit
    cube, as BEO's voxel space (dissertation section 3.2). The inside test is trimesh's ray
    parity test, exact for watertight meshes and fast with embree.
    """
    if extent is None:
        extent = float(mesh.extents.max())
    inside = contains(mesh, grid_centres(D, extent))
    return inside.reshape(D, D, D)


def surface_samples(mesh: trimesh.Trimesh, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``n`` area-uniform surface points and their outward unit normals (seeded)."""
    pts, face = trimesh.sample.sample_surface(mesh, n, seed=seed)
    return np.asarray(pts, dtype=np.float64), mesh.face_normals[face].astype(np.float64)


COACD_SETTINGS = {"threshold": 0.1, "preprocess_mode": "off", "max_convex_hull": 32, "seed": 0}
"""CoACD's fast settings: about 7 s and a dozen hulls for a mug-like mesh (measured)."""


def convex_decomposition(mesh: trimesh.Trimesh, **settings: object) -> list[trimesh.Trimesh]:
    """Approximate convex decomposition by CoACD (seconds per mesh: cache the result)."""
    import coacd

    opts = {**COACD_SETTINGS, **settings}
    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces)), **opts)
    return [trimesh.convex.convex_hull(np.asarray(v)) for v, _f in parts]


def pack_parts(parts: list[trimesh.Trimesh]) -> dict[str, np.ndarray]:
    """Convex parts as flat arrays for the cache: vertices and faces with per-part counts
    (faces index each part's own vertices), so loading needs no hull computation."""
    verts = [np.asarray(p.vertices, dtype=np.float64) for p in parts]
    faces = [np.asarray(p.faces, dtype=np.int32) for p in parts]
    return {
        "vertices": np.concatenate(verts) if verts else np.zeros((0, 3)),
        "counts": np.array([len(v) for v in verts], dtype=np.int64),
        "faces": np.concatenate(faces) if faces else np.zeros((0, 3), np.int32),
        "face_counts": np.array([len(f) for f in faces], dtype=np.int64),
    }


def unpack_parts(arrays: dict[str, np.ndarray]) -> list[trimesh.Trimesh]:
    """Inverse of :func:`pack_parts`."""
    out = []
    v_end = np.cumsum(arrays["counts"])
    f_end = np.cumsum(arrays["face_counts"])
    for v1, nv, f1, nf in zip(v_end, arrays["counts"], f_end, arrays["face_counts"], strict=True):
        out.append(
            trimesh.Trimesh(
                arrays["vertices"][v1 - nv : v1],
                arrays["faces"][f1 - nf : f1].astype(np.int64),
                process=False,
            )
        )
    return out
