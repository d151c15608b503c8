"""Solid tests of watertight meshes: :func:`check_solid` (is it a usable solid?) and
:func:`contains` (which points are inside it?).

The lowest layer of the mesh tools: :mod:`beo_bench.objects.processing` (repair, voxels) and
:mod:`beo_bench.objects.symmetry` (which scores rotations by inside tests) both build on it,
and :mod:`~beo_bench.objects.processing` re-exports both functions.
"""

from __future__ import annotations

import numpy as np
import trimesh

from beo_bench.errors import EmptyMeshError, NonWatertightMeshError


def check_solid(mesh: trimesh.Trimesh, what: str) -> None:
    """Raise if ``mesh`` is empty, not watertight, or encloses no volume."""
    if mesh is None or len(mesh.faces) == 0:
        raise EmptyMeshError(f"{what}: the mesh has no faces; use a mesh with geometry")
    if not mesh.is_watertight:
        raise NonWatertightMeshError(
            f"{what}: the mesh is not watertight; close its holes (e.g. with "
            f"repair='solid', or a tool such as ManifoldPlus) before using it as an object"
        )
    if not mesh.volume > 0:
        raise EmptyMeshError(
            f"{what}: the mesh encloses no volume "
            f"(volume {mesh.volume:.3g} m^3); check its face orientation"
        )


def contains(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Whether each point is inside the solid of a watertight ``mesh``, counting a point
    inside overlapping parts once.

    A ray parity test (trimesh's ``contains``) of a mesh made of overlapping closed parts
    (a VHACD hull set, a model of intersecting primitives) calls the overlap outside (two
    crossings), which lost 22-41 % of such solids. So a mesh of several bodies is tested
    per body: the winding number of a closed body is +1 inside it (-1 for an inward-facing
    cavity shell, which therefore cuts its cavity out), 0 outside, and a point is inside
    when the sum is positive. One body, the common case, costs one parity test as before.
    """
    points = np.asarray(points, dtype=np.float64)
    if mesh.body_count <= 1:
        return _parity_contains(mesh, points)
    winding = np.zeros(len(points), dtype=np.int64)
    for body in mesh.split(only_watertight=False):
        lo, hi = body.bounds
        near = np.flatnonzero(np.all((points >= lo) & (points <= hi), axis=1))
        if near.size:
            sign = 1 if body.volume >= 0 else -1
            winding[near] += sign * _parity_contains(body, points[near])
    return winding > 0


def _parity_contains(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """``mesh.contains(points)`` without leaving an Embree scene on the mesh.

    Each trimesh mesh owns a ray intersector that caches an Embree scene on its own Embree
    device. A process that keeps about a thousand instances in memory (a worker processing a
    whole training split) segfaulted inside Embree when creating the next device, so the
    scene is released after every test (rebuilding it costs about a millisecond)."""
    try:
        return np.asarray(mesh.contains(points), dtype=bool)
    finally:
        release_ray_scene(mesh)


def release_ray_scene(mesh: trimesh.Trimesh) -> None:
    """Drop the Embree scene ``mesh``'s ray intersector cached (see :func:`contains`)."""
    cache = getattr(getattr(mesh, "ray", None), "_cache", None)
    if cache is not None:
        cache.clear()
