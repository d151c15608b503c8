"""Convex building blocks of the procedural categories.

Every primitive is a convex, watertight ``trimesh.Trimesh``. An object is the union of its
parts (manifold3d booleans), and the parts themselves are its collision geometry: exact
and instant, with no convex decomposition needed (docs/design.md "Object library").

Builders work in any convenient frame (usually resting on z = 0); the library re-centres
the result on its bounding-box centre.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import trimesh
from scipy.spatial import ConvexHull

from beo_bench.geometry import no_symmetry
from beo_bench.types import Mat3, Symmetry

# Neighbouring sectors of a shell overlap by this angle so that their union is one solid
# rather than pieces touching along a face (which booleans may leave as a seam).
_SECTOR_OVERLAP = 1e-3


@dataclass
class Assembly:
    """What a category's builder returns: convex parts and the symmetry group, both in the
    builder's frame (the library shifts both to the bounding-box centre)."""

    parts: list[trimesh.Trimesh]
    symmetry: Symmetry = field(default_factory=no_symmetry)


def hull(points: np.ndarray | Sequence[Sequence[float]]) -> trimesh.Trimesh:
    """The convex hull of ``points`` (the most general primitive).

    Straight from qhull with each triangle wound to agree with its facet's outward normal:
    4x faster than ``trimesh.convex.convex_hull``, whose general repairs a hull never needs.
    """
    pts = np.asarray(points, dtype=np.float64)
    h = ConvexHull(pts)
    faces = h.simplices.copy()
    v = pts[faces]
    normals = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    flip = np.einsum("ij,ij->i", normals, h.equations[:, :3]) < 0
    faces[flip] = faces[flip][:, ::-1]
    used, inverse = np.unique(faces, return_inverse=True)
    return trimesh.Trimesh(pts[used], inverse.reshape(-1, 3), process=False)


def box(
    extents: Sequence[float],
    center: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
    rotation: Mat3 | None = None,
) -> trimesh.Trimesh:
    """An axis-aligned box (optionally rotated about its centre)."""
    ex = np.asarray(extents, dtype=np.float64) / 2
    corners = (
        np.array(
            [[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64
        )
        * ex
    )
    if rotation is not None:
        corners = corners @ np.asarray(rotation).T
    return hull(corners + np.asarray(center, dtype=np.float64))


def _ring(
    r: float,
    z: float,
    sections: int,
    center: Sequence[float] = (0.0, 0.0),
    scale: Sequence[float] = (1.0, 1.0),
) -> np.ndarray:
    a = np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    return np.stack(
        [
            center[0] + scale[0] * r * np.cos(a),
            center[1] + scale[1] * r * np.sin(a),
            np.full_like(a, z),
        ],
        axis=1,
    )


def frustum(
    r0: float,
    r1: float,
    z0: float,
    z1: float,
    sections: int = 48,
    center: Sequence[float] = (0.0, 0.0),
    scale: Sequence[float] = (1.0, 1.0),
) -> trimesh.Trimesh:
    """A solid truncated cone about a vertical axis through ``center`` (x, y): radius r0 at
    z0 and r1 at z1; ``scale`` squashes it to an elliptic cross-section."""
    return hull(
        np.concatenate(
            [
                _ring(max(r0, 1e-5), z0, sections, center, scale),
                _ring(max(r1, 1e-5), z1, sections, center, scale),
            ]
        )
    )


def cylinder(
    r: float, z0: float, z1: float, sections: int = 48, center: Sequence[float] = (0.0, 0.0)
) -> trimesh.Trimesh:
    """A solid vertical cylinder."""
    return frustum(r, r, z0, z1, sections, center)


def revolve_solid(
    profile: Sequence[tuple[float, float]], sections: int = 48, center: Sequence[float] = (0.0, 0.0)
) -> list[trimesh.Trimesh]:
    """A solid of revolution from a profile of (radius, z) with increasing z: one convex
    frustum per profile segment, so a profile that narrows and widens stays exact."""
    return [
        frustum(r0, r1, z0, z1, sections, center)
        for (r0, z0), (r1, z1) in itertools.pairwise(profile)
    ]


def revolve_shell(
    profile: Sequence[tuple[float, float]],
    thickness: float,
    sectors: int = 32,
    center: Sequence[float] = (0.0, 0.0),
) -> list[trimesh.Trimesh]:
    """A thin wall of revolution (a mug's wall, a bowl): the outer profile (radius, z) with
    increasing z, thickened inwards by ``thickness``. Each (profile segment x angular sector)
    is one convex piece, a ring of convex segments as docs/design.md describes. With 32 sectors a
    whole mug or bowl (wall plus base) rotated by half a sector keeps a volume IoU of about
    0.97 with itself (the symmetry test in tests/objects/test_categories.py measures it), so
    such objects may be declared continuously symmetric; a bare thin wall alone scores
    lower, since its faceting is a larger share of its volume."""
    parts = []
    step = 2 * np.pi / sectors
    cos_half = np.cos(step / 2)
    for k in range(sectors):
        a0, a1 = k * step - _SECTOR_OVERLAP, (k + 1) * step + _SECTOR_OVERLAP
        for (r0, z0), (r1, z1) in itertools.pairwise(profile):
            pts = []
            for a in (a0, a1):
                c, s = np.cos(a), np.sin(a)
                # the outer corners sit on a circumscribing polygon so that the flat outer
                # face never cuts inside the nominal radius (the wall never gets thinner)
                for r, z in (
                    (r0 / cos_half, z0),
                    (r1 / cos_half, z1),
                    (r0 - thickness, z0),
                    (r1 - thickness, z1),
                ):
                    pts.append([center[0] + r * c, center[1] + r * s, z])
            parts.append(hull(pts))
    return parts


def tube(
    path: np.ndarray | Sequence[Sequence[float]], radius: float, sections: int = 12
) -> list[trimesh.Trimesh]:
    """A round tube along a polyline (a mug handle, a leg, a strut): one convex hull of two
    discs per segment, the discs normal to the segment and overlapping at the joints."""
    P = np.asarray(path, dtype=np.float64)
    parts = []
    a = np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    for p0, p1 in itertools.pairwise(P):
        d = p1 - p0
        d /= np.linalg.norm(d)
        u = np.cross(d, [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(d, u)
        disc = radius * (np.cos(a)[:, None] * u + np.sin(a)[:, None] * v)
        # extend each segment by a little of the radius so consecutive pieces overlap
        ext = 0.5 * radius * d
        parts.append(hull(np.concatenate([p0 - ext + disc, p1 + ext + disc])))
    return parts


def ellipsoid(
    center: Sequence[float], radii: Sequence[float], subdivisions: int = 2
) -> trimesh.Trimesh:
    """A convex ellipsoid (an icosphere scaled per axis)."""
    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    return hull(s.vertices * np.asarray(radii) + np.asarray(center))


def mirror_y(parts: list[trimesh.Trimesh]) -> list[trimesh.Trimesh]:
    """Copies of ``parts`` mirrored across the xz-plane (left/right pairs)."""
    return [hull(p.vertices * np.array([1.0, -1.0, 1.0])) for p in parts]
