"""Asset processing: solid checks and repair, voxel occupancy, surface samples, and convex
decomposition (CoACD) for meshes that do not bring their own convex parts.

Everything here is a pure function of a mesh plus settings; :mod:`beo_bench.objects.instance`
wraps it with the on-disk cache.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import trimesh

from beo_bench.errors import EmptyMeshError, NonFiniteMeshError
from beo_bench.objects.solid import check_solid, contains, release_ray_scene
from beo_bench.types import BoolGrid

if TYPE_CHECKING:
    import manifold3d

DEFAULT_RESOLUTION = 32
"""Voxel grid size D (docs/design.md: D^3, default 32)."""


REPAIR_MODES: tuple[str, ...] = ("basic", "solid", "voxel", "none")
"""What :func:`repair` can do to a mesh, from most to least faithful (``none``: check only)."""

SOLID_RESOLUTION = 64
"""Grid size of :func:`solidify` (cells along the largest extent)."""

MAX_FACES = 5000
"""Face budget of solidified meshes and of CoACD's input (:func:`simplify`): marching
cubes gives 20k-200k faces, on which CoACD takes minutes instead of seconds."""

RAY_DIRECTIONS = 15
"""Rays per grid point in :func:`solidify`'s inside vote (odd: no fraction is exactly the
level 0.5, where marching cubes would make zero-length edges and non-manifold merges)."""


def repair(
    mesh: trimesh.Trimesh, what: str, mode: str = "basic", resolution: int = 96
) -> trimesh.Trimesh:
    """Make ``mesh`` a usable solid or raise.

    ``basic`` merges duplicate vertices (across UV and normal seams), drops duplicate faces,
    collapses zero-area faces without opening the surface, fills small holes, fixes winding
    and unites overlapping closed parts (e.g. a VHACD hull set) into one solid. ``solid``
    additionally rebuilds a mesh that is still open or not a valid manifold with
    :func:`solidify` (an inside vote that tolerates holes and self-intersections, then
    :data:`MAX_FACES` faces at most). ``voxel`` instead remeshes a mesh that is still open
    by voxelising its surface at ``resolution``, filling the inside and running marching
    cubes (loses detail below one voxel), then :func:`simplify` towards :data:`MAX_FACES`
    faces, as CoACD's input always was: marching cubes gives 20k-60k faces, which made
    every later step (symmetry, voxels, samples) slower for no detail (the simplified can of
    robosuite has the same 64^3 voxels as the 64k-face one). ``none`` only checks.
    """
    if mode not in REPAIR_MODES:
        raise ValueError(f"repair mode {mode!r}: use one of {', '.join(map(repr, REPAIR_MODES))}")
    if len(mesh.faces) == 0:
        raise EmptyMeshError(f"{what}: the mesh has no faces; use a mesh with geometry")
    check_finite(mesh, what)
    if mode != "none":
        mesh = _clean(mesh)
        united = _unite(mesh) if mesh.is_watertight else None
        if united is not None:
            mesh = united
        elif mode == "solid":
            # still open, or closed but not a manifold that manifold3d accepts
            # (self-intersecting parts that share edges, non-manifold edges)
            mesh = solidify(mesh, what)
    if mode == "voxel" and not mesh.is_watertight:
        mesh = simplify(_voxel_remesh(mesh, resolution), MAX_FACES)
    check_solid(mesh, what)
    return mesh


def check_finite(mesh: trimesh.Trimesh, what: str) -> None:
    """Raise :class:`~beo_bench.errors.NonFiniteMeshError` for NaN or infinite vertices."""
    bad = ~np.isfinite(np.asarray(mesh.vertices)).all(axis=1)
    if bad.any():
        raise NonFiniteMeshError(
            f"{what}: {int(bad.sum())} of {len(bad)} vertices have NaN or infinite "
            f"coordinates (first: vertex {int(np.flatnonzero(bad)[0])}); the file is corrupt: "
            f"re-export it from its source"
        )


def _clean(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    mesh = mesh.copy()
    # Textured OBJs repeat a vertex on each side of a UV or normal seam; merging by position
    # only is what makes such a closed surface watertight (the texture is never used).
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    mesh.update_faces(mesh.unique_faces())
    if not mesh.is_watertight:
        # In a closed mesh a zero-area face can be the only face on an edge (a T-junction
        # of CAD exports): deleting it opens the surface, so closed meshes keep theirs
        # until _unite lets manifold3d collapse them; in open meshes they only get in the
        # way of hole filling.
        mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    if not mesh.is_watertight:
        trimesh.repair.fill_holes(mesh)
    trimesh.repair.fix_normals(mesh)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def _to_manifold(mesh: trimesh.Trimesh) -> manifold3d.Manifold | None:
    import manifold3d

    m = manifold3d.Manifold(
        manifold3d.Mesh64(
            vert_properties=np.asarray(mesh.vertices, dtype=np.float64),
            tri_verts=np.asarray(mesh.faces, dtype=np.uint32),
        )
    )
    return None if m.status() != manifold3d.Error.NoError or m.is_empty() else m


def _from_manifold(m: manifold3d.Manifold) -> trimesh.Trimesh:
    out = m.to_mesh64()
    # contiguous copies: a strided view of the property table reaches C extensions (CoACD
    # segfaulted on one) that assume packed rows
    return trimesh.Trimesh(
        np.ascontiguousarray(np.asarray(out.vert_properties)[:, :3], dtype=np.float64),
        np.ascontiguousarray(out.tri_verts, dtype=np.int64),
    )


def _unite(mesh: trimesh.Trimesh) -> trimesh.Trimesh | None:
    """A closed mesh as a clean manifold: zero-area faces collapsed and overlapping parts
    united (their overlap would otherwise be counted twice by volumes and CoACD, and as
    outside by a parity inside test). ``mesh`` itself when there is nothing to do; None
    when manifold3d rejects it (e.g. non-manifold edges)."""
    import manifold3d

    if mesh.body_count <= 1 and mesh.nondegenerate_faces().all():
        return mesh
    m = _to_manifold(mesh)
    if m is None:
        return None
    parts = m.decompose()
    # a part with negative volume is a cavity (an inward-facing inner shell): a union
    # would fill it, and the parts are then already a valid solid as they are
    if len(parts) > 1 and all(p.volume() > 0 for p in parts):
        m = manifold3d.Manifold.batch_boolean(parts, manifold3d.OpType.Add)
    return _from_manifold(m)


def solidify(
    mesh: trimesh.Trimesh,
    what: str,
    resolution: int = SOLID_RESOLUTION,
    max_faces: int = MAX_FACES,
) -> trimesh.Trimesh:
    """A closed manifold approximating the solid bounded by an open or self-intersecting
    mesh, with at most about ``max_faces`` faces.

    Each point of a grid (``resolution`` cells along the largest extent) casts
    :data:`RAY_DIRECTIONS` rays; a ray votes "inside" when the first face it hits faces away
    from the point (the point is behind the surface). The fraction of inside votes is,
    for an oriented surface, an estimate of the sign of its generalised winding number
    (Jacobson et al., SIGGRAPH 2013) that needs no parity: a hole only loses the few rays
    that leave through it, and a self-intersection does not flip anything. Marching cubes
    at 0.5 of that fraction gives the surface, which manifold3d simplifies.
    """
    from scipy import ndimage
    from skimage.measure import marching_cubes

    lo, hi = mesh.bounds
    # an even cell count, so the coarse grid below has exactly every other fine point
    pitch = float((hi - lo).max()) / resolution
    shape = 2 * (np.ceil((hi - lo) / pitch / 2).astype(int) + 2)  # 2+ cells of margin
    origin = (lo + hi) / 2 - pitch * (shape - 1) / 2
    axes = [origin[i] + pitch * np.arange(shape[i]) for i in range(3)]

    def points(step: int) -> np.ndarray:
        g = np.meshgrid(*(ax[::step] for ax in axes), indexing="ij")
        return np.stack(g, axis=-1).reshape(-1, 3)

    # Coarse to fine: the vote is only needed at full resolution near the surface, which
    # cuts the rays (the cost of this function) by about three.
    coarse = _inside_votes(mesh, points(2)).reshape([len(ax[::2]) for ax in axes])
    frac = np.repeat(np.repeat(np.repeat(coarse, 2, 0), 2, 1), 2, 2)[tuple(map(slice, shape))]
    inside = coarse > 0.5
    mixed = ndimage.maximum_filter(inside, 3) != ndimage.minimum_filter(inside, 3)
    near = np.repeat(np.repeat(np.repeat(mixed, 2, 0), 2, 1), 2, 2)[tuple(map(slice, shape))]
    fine = points(1).reshape(*shape, 3)[near]
    frac[near] = _inside_votes(mesh, fine)
    if not (frac > 0.5).any():
        raise EmptyMeshError(
            f"{what}: the surface encloses no volume that can be solidified (a single sheet "
            f"or fragments?); use a closed or nearly closed mesh"
        )
    # a little smoothing takes the voxel staircase off the surface, so that simplification
    # reaches a few thousand faces at a quarter of a cell of tolerance (measured: a sphere
    # with an open cap keeps 99 % of its volume)
    frac = ndimage.gaussian_filter(frac, 0.7)
    verts, faces, _, _ = marching_cubes(frac.astype(np.float32), 0.5)
    # process=False: marching cubes already shares vertices, and merging nearby ones by
    # tolerance can pinch the surface into non-manifold edges
    out = trimesh.Trimesh(verts * pitch + origin, faces[:, ::-1], process=False)
    trimesh.repair.fix_normals(out)
    return simplify(out, max_faces, start=0.25 * pitch)


def _inside_votes(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Fraction of :data:`RAY_DIRECTIONS` rays from each point whose first hit is a face
    seen from behind (see :func:`solidify`); misses count as outside."""
    k = np.arange(RAY_DIRECTIONS) + 0.5
    # a Fibonacci sphere, tilted off the axes so that rays rarely graze axis-aligned faces
    z = 1.0 - 2.0 * k / RAY_DIRECTIONS
    phi = np.pi * (1.0 + 5.0**0.5) * k + 0.1
    r = np.sqrt(1.0 - z**2)
    dirs = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    normals = np.asarray(mesh.face_normals)
    votes = np.zeros(len(points))
    try:
        for d in dirs:
            tri = mesh.ray.intersects_first(points, np.broadcast_to(d, points.shape))
            hit = tri >= 0
            votes[hit] += normals[tri[hit]] @ d > 0
    finally:
        release_ray_scene(mesh)
    return votes / RAY_DIRECTIONS


def simplify(
    mesh: trimesh.Trimesh, max_faces: int = MAX_FACES, start: float = 0.0
) -> trimesh.Trimesh:
    """``mesh`` with at most about ``max_faces`` faces, by manifold3d's simplification
    (every surface moves by less than its tolerance, which starts at ``start``, default
    1/1000 of the largest extent, and grows by half until the budget is met).

    A step whose result is no longer watertight or changes the volume by more than 5 % is
    not taken: on thin voxel shells (``repair="voxel"``) manifold3d's collapses pinch the
    surface, and CoACD segfaulted on such a result. So the face budget is a goal, not a
    promise; a mesh within budget, or one manifold3d rejects, is returned as it is."""
    if len(mesh.faces) <= max_faces:
        return mesh
    m = _to_manifold(mesh)
    if m is None:
        return mesh
    volume = float(mesh.volume)
    tol = start or 1e-3 * float(mesh.extents.max())
    best = mesh
    for _ in range(12):
        out = _from_manifold(m.simplify(tol))
        if not out.is_watertight or abs(float(out.volume) - volume) > 0.05 * abs(volume):
            break
        best = out
        if len(out.faces) <= max_faces:
            break
        tol *= 1.5
    return best


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


def voxelize(
    mesh: trimesh.Trimesh, D: int = DEFAULT_RESOLUTION, extent: float | None = None
) -> BoolGrid:
    """Solid occupancy of ``mesh`` on a D^3 grid: a cell is filled when its centre is inside.

    The grid is the cube of edge ``extent`` (default: the mesh's largest bounding-box
    extent) centred at the origin, i.e. the canonical frame scaled uniformly into the unit
    cube, as BEO's voxel space (dissertation section 3.2). The inside test is
    :func:`contains`: exact for watertight meshes, overlapping parts counted once, and fast
    with embree.
    """
    if extent is None:
        extent = float(mesh.extents.max())
    inside = contains(mesh, grid_centres(D, extent))
    return inside.reshape(D, D, D)


def surface_samples(mesh: trimesh.Trimesh, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``n`` area-uniform surface points and their outward unit normals (seeded)."""
    pts, face = trimesh.sample.sample_surface(mesh, n, seed=seed)
    return np.asarray(pts, dtype=np.float64), mesh.face_normals[face].astype(np.float64)


COACD_SETTINGS = {
    "threshold": 0.1,
    "preprocess_mode": "off",
    "max_convex_hull": 32,
    "seed": 0,
    "resolution": 1000,
    "mcts_max_depth": 2,
}
"""CoACD's fast settings. The concavity threshold (0.1) bounds every part as before; the
search is cheaper than CoACD's defaults (``resolution`` 2000 surface samples per concavity
estimate, ``mcts_max_depth`` 3 cuts looked ahead): on robosuite's 14 object meshes it took
8 s of CPU instead of 18 s (the can 2.5 s instead of 4.1 s), the union of the parts covering
the mesh as closely (voxel IoU 0.971 against 0.957 on the can, 0.996 against 1.000 on the
handles) with as many parts (54 against 55 over the 14); ``benchmarks/bench_real_meshes.py``."""


def convex_decomposition(mesh: trimesh.Trimesh, **settings: object) -> list[trimesh.Trimesh]:
    """Approximate convex decomposition by CoACD (seconds per mesh: cache the result)."""
    import coacd

    opts = {**COACD_SETTINGS, **settings}
    coacd.set_log_level("error")
    # CoACD's time grows with the face count (minutes for a 100k-face scan); collision
    # parts need no detail below a millimetre or so
    mesh = simplify(mesh, MAX_FACES)
    cmesh = coacd.Mesh(
        np.ascontiguousarray(mesh.vertices, dtype=np.float64),
        np.ascontiguousarray(mesh.faces, dtype=np.int32),
    )
    parts = coacd.run_coacd(cmesh, **opts)
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
