"""Depth images of an object model at a pose: the renderings VSD compares
(:func:`beo_bench.bop.protocol.vsd_errors`).

The BOP toolkit renders them with OpenGL (``bop_toolkit_lib/renderer_vispy.py``,
``render_object(...)["depth"]``); here they are ray cast on the CPU with trimesh and Embree
(``trimesh.ray.ray_pyembree``, through the ``embreex`` package), which needs no display or
GPU and gives the exact first surface along each pixel's ray. The camera is a pinhole with
intrinsics ``K`` and OpenCV / BOP conventions: x right, y down, z forward; pixel ``(u, v)``
(column, row) has its centre at integer coordinates, so its ray passes through
``K^-1 (u, v, 1)``. A rasteriser samples pixel centres the same way, so the two agree except on
silhouette edges, where a triangle covering a pixel centre is a matter of rounding.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import trimesh
from numpy.typing import ArrayLike, NDArray
from trimesh.intersections import planes_lines

__all__ = ["ModelRenderer", "render_depth"]


def _intersector(mesh: trimesh.Trimesh) -> Any:
    """Embree's intersector when ``embreex`` is installed (milliseconds per image), else
    trimesh's pure-numpy one (same answers, far slower)."""
    try:
        from trimesh.ray import ray_pyembree
    except ImportError:  # pragma: no cover - embreex ships with the package's dependencies
        from trimesh.ray import ray_triangle

        return ray_triangle.RayMeshIntersector(mesh)
    return ray_pyembree.RayMeshIntersector(mesh)


class ModelRenderer:
    """Renders depth images of one mesh at any pose, building its ray-casting structure once.

    The mesh stays in its own (model) frame; for each pose the camera's rays are moved into
    that frame instead (origin ``-R^T t``, directions ``R^T K^-1 (u, v, 1)``), so nothing is
    rebuilt per pose. ``vertices`` (N, 3) are in the length unit the translations will use.
    """

    def __init__(self, vertices: ArrayLike, faces: ArrayLike) -> None:
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0 or not np.isfinite(v).all():
            raise ValueError(f"vertices must be a finite non-empty (N, 3) array, got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or not np.issubdtype(f.dtype, np.integer):
            raise ValueError(f"faces must be a non-empty (M, 3) integer array, got {f.shape}")
        if f.min() < 0 or f.max() >= len(v):
            raise ValueError(f"faces must index the {len(v)} vertices (0..{len(v) - 1})")
        self.mesh = trimesh.Trimesh(vertices=v, faces=f, process=False)
        self._rays = _intersector(self.mesh)
        self._plane_points = np.asarray(self.mesh.triangles[:, 0, :], dtype=np.float64)
        self._plane_normals = np.asarray(self.mesh.face_normals, dtype=np.float64)

    def depth(
        self, R: ArrayLike, t: ArrayLike, K: ArrayLike, width: int, height: int
    ) -> NDArray[np.float64]:
        """The (height, width) z-depth of the mesh posed by ``x -> R x + t`` (model to camera)
        seen through intrinsics ``K`` (3, 3); 0 where a pixel's ray misses the mesh. Only
        surfaces in front of the camera centre are seen (a ray starts there)."""
        Rm = np.asarray(R, dtype=np.float64)
        tv = np.asarray(t, dtype=np.float64).reshape(-1)
        Km = np.asarray(K, dtype=np.float64)
        if Rm.shape != (3, 3) or not np.isfinite(Rm).all():
            raise ValueError(f"R must be a finite (3, 3) rotation matrix, got shape {Rm.shape}")
        if not np.allclose(Rm.T @ Rm, np.eye(3), atol=1e-6) or np.linalg.det(Rm) < 0:
            raise ValueError("R must be a proper rotation matrix (R^T R = I, det R = +1)")
        if tv.shape != (3,) or not np.isfinite(tv).all():
            raise ValueError(f"t must be a finite 3-vector, got shape {np.shape(t)}")
        if (
            Km.shape != (3, 3)
            or not np.isfinite(Km).all()
            or abs(np.linalg.det(Km)) == 0
            or not np.array_equal(Km[2], [0.0, 0.0, 1.0])
        ):
            raise ValueError("K must be a finite invertible (3, 3) pinhole matrix, last row 0 0 1")
        if int(width) != width or int(height) != height or width < 1 or height < 1:
            raise ValueError(f"width and height must be positive integers, got {width}, {height}")
        w, h = int(width), int(height)
        depth = np.zeros((h, w))
        window = self._window(Rm, tv, Km, w, h)
        if window is None:
            return depth
        (u0, u1), (v0, v1) = window
        u, v = np.meshgrid(np.arange(u0, u1, dtype=np.float64), np.arange(v0, v1, dtype=np.float64))
        pixels = np.stack([u.ravel(), v.ravel(), np.ones(u.size)], axis=1)
        dirs = pixels @ (Rm.T @ np.linalg.inv(Km)).T  # R^T K^-1 (u, v, 1) per pixel
        origins = np.broadcast_to(-Rm.T @ tv, dirs.shape)
        # Embree finds the first triangle along each ray (in float32); the hit point is then
        # that triangle's plane met by the ray, in float64 (as trimesh's intersects_location
        # does, without its bookkeeping for multiple hits).
        tri = np.asarray(self._rays.intersects_first(origins, dirs))
        hit = np.flatnonzero(tri >= 0)
        points, valid = planes_lines(
            self._plane_points[tri[hit]], self._plane_normals[tri[hit]], origins[hit], dirs[hit]
        )
        sub = np.zeros(u.size)
        sub[hit[valid]] = np.asarray(points, dtype=np.float64).reshape(-1, 3) @ Rm[2] + tv[2]
        depth[v0:v1, u0:u1] = sub.reshape(u.shape)
        return depth

    def _window(
        self, R: NDArray[np.float64], t: NDArray[np.float64], K: NDArray[np.float64], w: int, h: int
    ) -> tuple[tuple[int, int], tuple[int, int]] | None:
        """The pixel columns and rows ``((u0, u1), (v0, v1))`` (half-open) whose rays can hit
        the mesh: the mesh lies in its bounding box, whose image (all corners in front of the
        camera) is the convex hull of its corners' projections; a pixel centre outside their
        bounding rectangle (widened by a pixel against rounding) sees nothing. The whole
        image when a corner is not in front of the camera; None when the window is empty."""
        lo, hi = self.mesh.bounds
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                            for z in (lo[2], hi[2])])  # fmt: skip
        cam = corners @ R.T + t
        if not (cam[:, 2] > 0).all():
            return (0, w), (0, h)
        uv = cam @ K.T
        uv = uv[:, :2] / uv[:, 2:3]
        u0, v0 = np.maximum(np.floor(uv.min(axis=0)) - 1, 0).astype(int)
        u1, v1 = (np.minimum(np.ceil(uv.max(axis=0)) + 1, (w - 1, h - 1)) + 1).astype(int)
        if u0 >= u1 or v0 >= v1:
            return None
        return (int(u0), int(u1)), (int(v0), int(v1))


def render_depth(
    mesh_vertices: ArrayLike,
    mesh_faces: ArrayLike,
    R: ArrayLike,
    t: ArrayLike,
    K: ArrayLike,
    width: int,
    height: int,
) -> NDArray[np.float64]:
    """One depth image (:meth:`ModelRenderer.depth`); build a :class:`ModelRenderer` instead
    when rendering one mesh at several poses."""
    return ModelRenderer(mesh_vertices, mesh_faces).depth(R, t, K, width, height)
