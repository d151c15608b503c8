"""Asset processing: solid checks and repair, voxel occupancy, surface samples, and convex
decomposition (CoACD) for meshes that do not bring their own convex parts.

Everything here is a pure function of a mesh plus settings; :mod:`beo_bench.objects.instance`
wraps it with the on-disk cache.
"""

from __future__ import annotations

import numpy as np
import trimesh

from beo_bench.errors import EmptyMeshError, NonWatertightMeshError
from beo_bench.types import BoolGrid, Symmetry

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


def rotation_iou(mesh: trimesh.Trimesh, T: np.ndarray, n: int = 40000, seed: int = 0) -> float:
    """Volume IoU between ``mesh`` and ``mesh`` moved by the 4x4 (or 3x3) transform ``T``.

    Estimated on ``n`` seeded random points in the bounding cube with the exact inside test,
    so thin walls do not alias the way a coarse voxel grid would.
    """
    T4 = np.eye(4)
    if T.shape == (3, 3):
        T4[:3, :3] = T
    else:
        T4[:] = T
    rng = np.random.default_rng(seed)
    half = float(np.abs(mesh.bounds).max()) * 1.05
    p = rng.uniform(-half, half, size=(n, 3))
    inv = np.linalg.inv(T4)
    a = contains(mesh, p)
    b = contains(mesh, p @ inv[:3, :3].T + inv[:3, 3])  # p in T(mesh) iff T^-1 p in mesh
    union = int((a | b).sum())
    return float((a & b).sum() / union) if union else 1.0


SYMMETRY_PROBE_ANGLES_DEG = (20.0, 45.0, 90.0, 137.0)
"""Rotations about z that must all map a mesh onto itself for continuous z symmetry; 137
degrees is no multiple of any small n-fold angle, so an n-fold object fails at least one."""


def estimate_symmetry(
    mesh: trimesh.Trimesh, threshold: float = 0.95, n: int = 2500, seed: int = 0
) -> Symmetry:
    """Estimate the rotational symmetry group of a watertight mesh (for meshes from files,
    which carry no symmetry annotation).

    Candidates, all about the centre of mass (every symmetry fixes it, unlike the
    bounding-box centre of, e.g., a triangular prism): continuous rotation about z (passes
    if the rotations by :data:`SYMMETRY_PROBE_ANGLES_DEG` all do), n-fold rotation about z
    for n in 6, 4, 3, 2, and 180-degree flips about x and y. A transform passes when the
    volume IoU of the mesh and its moved copy is at least ``threshold``. The result is the
    largest group generated by passing candidates whose *every* element passes (so, e.g.,
    two flips are only kept together when their product, the half turn about z, passes).
    Symmetries about other axes (a box that is square in x-z) are not searched: objects are
    in the canonical z-up frame.

    The IoU is the quantity :func:`rotation_iou` measures, estimated here from ``n`` seeded
    points uniform *inside* the mesh: with |A| = |T(A)|, IoU = x / (2 - x) where x is the
    fraction of inside points p whose preimage T^-1 p is inside too. The inside test of the
    mesh's own points is done once, and no sample is wasted outside the mesh, so a mesh
    takes ~15-20 inside tests of ``n`` points (well under 0.3 s for 10k-face meshes).
    Returns BOP's form (continuous axes plus discrete 4x4 transforms, identity dropped).
    """
    from beo_bench.geometry import (
        axis_angle,
        close_group,
        continuous_symmetry,
        discrete_symmetry,
        no_symmetry,
    )

    check_solid(mesh, "symmetry estimation")
    scale = float(mesh.extents.max())
    centre = np.asarray(mesh.center_mass, dtype=np.float64)
    # snap round-off so a symmetric, centred object gets offsets of exactly 0
    centre = np.where(np.abs(centre) < 1e-7 * scale, 0.0, np.round(centre, 9))
    inside = _inside_samples(mesh, n, seed)
    if len(inside) < 50:  # a degenerate sliver: nothing can be measured
        return no_symmetry()
    rel = inside - centre
    memo: dict[bytes, bool] = {}

    def passes(R: np.ndarray) -> bool:
        k = np.round(R, 6).tobytes()
        if k not in memo:
            # row-vector form of T^-1 p = R^T (p - c) + c
            x = float(contains(mesh, rel @ R + centre).mean())
            memo[k] = x / (2.0 - x) >= threshold
        return memo[k]

    z, x_axis, y_axis = [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]
    flip_x, flip_y = axis_angle(x_axis, np.pi), axis_angle(y_axis, np.pi)
    offset = tuple(float(v) for v in centre)
    if all(passes(axis_angle(z, np.deg2rad(a))) for a in SYMMETRY_PROBE_ANGLES_DEG):
        # with continuous z, one horizontal flip implies all of them
        return continuous_symmetry(offset=offset, flips=[flip_x] if passes(flip_x) else None)

    folds = [k for k in (6, 4, 3, 2) if passes(axis_angle(z, 2 * np.pi / k))] + [1]
    flips = [f for f in (flip_x, flip_y) if passes(f)]
    flip_sets = [flips, *([[f] for f in flips] if len(flips) == 2 else []), []]
    best: list[np.ndarray] = []
    best_size = 1
    for k in folds:
        for fs in flip_sets:
            gens = ([axis_angle(z, 2 * np.pi / k)] if k > 1 else []) + list(fs)
            group = close_group(gens) if gens else [np.eye(3)]
            if len(group) > best_size and all(passes(R) for R in group[1:]):
                best, best_size = gens, len(group)
    return discrete_symmetry(best, offset=offset) if best else no_symmetry()


def _inside_samples(mesh: trimesh.Trimesh, n: int, seed: int) -> np.ndarray:
    """About ``n`` seeded points uniform inside a watertight mesh (rejection sampling from
    its bounding box, one batch sized by the mesh's fill ratio)."""
    rng = np.random.default_rng(seed)
    lo, hi = mesh.bounds
    fill = float(mesh.volume) / float(np.prod(np.maximum(hi - lo, 1e-12)))
    m = int(min(n / max(fill, 0.01) * 1.2, 60_000))
    p = rng.uniform(lo, hi, size=(m, 3))
    return p[contains(mesh, p)][:n]


def pack_symmetry(symmetry: Symmetry) -> dict[str, np.ndarray]:
    """A symmetry group as arrays for the cache: ``continuous`` (k, 6) axis and offset rows,
    ``discrete`` (m, 4, 4)."""
    cont = [list(c["axis"]) + list(c["offset"]) for c in symmetry["continuous"]]
    return {
        "continuous": np.asarray(cont, dtype=np.float64).reshape(-1, 6),
        "discrete": np.asarray(symmetry["discrete"], dtype=np.float64).reshape(-1, 4, 4),
    }


def unpack_symmetry(arrays: dict[str, np.ndarray]) -> Symmetry:
    """Inverse of :func:`pack_symmetry`."""
    return {
        "continuous": [
            {"axis": row[:3].tolist(), "offset": row[3:].tolist()}
            for row in np.asarray(arrays["continuous"]).reshape(-1, 6)
        ],
        "discrete": np.asarray(arrays["discrete"]).reshape(-1, 4, 4).tolist(),
    }
