"""One object instance: its mesh in the canonical frame, symmetry, and cached derived data.

The canonical frame (all categories, all sources): +z up, +x front, origin at the centre of
the axis-aligned bounding box, metres. ``voxels(D)`` scales that frame uniformly into the
unit cube (see :func:`beo_bench.objects.processing.voxelize`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from beo_bench.objects import cache
from beo_bench.objects.params import Params
from beo_bench.objects.processing import (
    COACD_SETTINGS,
    DEFAULT_RESOLUTION,
    MAX_FACES,
    convex_decomposition,
    pack_parts,
    surface_samples,
    unpack_parts,
    voxelize,
)
from beo_bench.objects.registry import Generated
from beo_bench.types import BoolGrid, Symmetry

COACD_CACHE_PARAMS = {"v": 3, "max_faces": MAX_FACES, **COACD_SETTINGS}
"""Cache key of CoACD results: format version and the settings that shape them (v3: the
input is simplified to ``max_faces`` first)."""
SURFACE_SAMPLES = 4096
"""Default number of cached surface samples per instance."""


@dataclass(eq=False)
class ObjectInstance:
    """An object of the library. Build it through :class:`~beo_bench.objects.ObjectSet`,
    a loader, or :func:`~beo_bench.objects.instance_from_key`; the mesh is built on first
    use and kept."""

    key: str
    """Unique across sets and sources; :func:`instance_from_key` turns it back into this."""
    category: str
    split: str
    index: int
    source: str
    """``procedural``, ``shapenet``, ``modelnet`` or ``folder``."""
    build: Callable[[Path | None], Generated] = field(repr=False)
    """Produces the canonical mesh, its convex parts (None: decompose with CoACD) and the
    symmetry group, given the cache root to keep what it derives in (:attr:`cache_dir`)."""
    params: Params = field(default_factory=dict)
    """Shape parameters of a procedural instance (empty for meshes from files)."""
    pickable: bool = True
    path: Path | None = None
    """The source file of a loaded mesh."""
    cache_dir: Path | None = field(default=None, repr=False)
    """The asset cache this instance's derived data (mesh, voxels, samples, parts, rest pose)
    is kept in, as its maker was given it (a run's ``RunContext.cache_root``); None: the
    environment's (:func:`beo_bench.objects.cache.cache_root`, read at each use)."""

    @functools.cached_property
    def _generated(self) -> Generated:
        return self.build(self.cache_dir)

    @property
    def mesh(self) -> trimesh.Trimesh:
        """The watertight mesh in the canonical frame (metres)."""
        return self._generated.mesh

    @property
    def symmetry(self) -> Symmetry:
        """Symmetry group in BOP's form (continuous axes, discrete 4x4 transforms)."""
        return self._generated.symmetry

    @property
    def size(self) -> np.ndarray:
        """Bounding-box extents (x, y, z) in metres."""
        return np.asarray(self.mesh.extents, dtype=np.float64)

    @functools.cached_property
    def content_hash(self) -> str:
        return cache.mesh_hash(self.mesh)

    def voxels(self, D: int = DEFAULT_RESOLUTION) -> BoolGrid:
        """Solid occupancy on a D^3 grid over the unit cube that the canonical frame is
        scaled into (edge = the largest extent), indexed [x, y, z]. Cached on disk."""
        out = cache.cached(
            "voxels",
            self.content_hash,
            # v2: overlapping parts count once (processing.contains)
            {"D": int(D), "v": 2},
            lambda: {"occ": np.packbits(voxelize(self.mesh, D))},
            self.cache_dir,
        )
        return np.unpackbits(out["occ"], count=D**3).astype(bool).reshape(D, D, D)

    def surface_points(self, n: int = SURFACE_SAMPLES) -> tuple[np.ndarray, np.ndarray]:
        """``n`` area-uniform surface points and outward normals (canonical frame, cached)."""
        out = cache.cached(
            "surface",
            self.content_hash,
            {"n": int(n), "seed": 0, "v": 1},
            lambda: dict(
                zip(("points", "normals"), surface_samples(self.mesh, n, seed=0), strict=True)
            ),
            self.cache_dir,
        )
        return out["points"], out["normals"]

    @property
    def exact_parts(self) -> bool:
        """True when :meth:`collision_parts` are exact (their union is the mesh), as for
        procedural instances; False when they are CoACD's approximation."""
        return self._generated.parts is not None

    def collision_parts(self) -> list[trimesh.Trimesh]:
        """Convex collision parts in the canonical frame: the exact primitives of a
        procedural instance, or CoACD's decomposition of a loaded mesh (cached)."""
        if self._generated.parts is not None:
            return self._generated.parts
        out = cache.cached(
            "coacd",
            self.content_hash,
            COACD_CACHE_PARAMS,
            lambda: pack_parts(convex_decomposition(self.mesh)),
            self.cache_dir,
        )
        return unpack_parts(out)

    def __repr__(self) -> str:
        return f"ObjectInstance({self.key!r})"
