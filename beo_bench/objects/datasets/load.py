"""How a dataset's files are loaded: the loading options (:class:`LoadOptions`, which a
key's ``?option=value`` part spells) and building one file into a lazily built instance's
mesh (:func:`build_mesh`: read, rotate, repair, centre, scale, check; symmetry estimated on
first use).

The layouts (:mod:`~beo_bench.objects.datasets.layouts`) say what differs between datasets:
where the models are, what their categories and splits are, what their axes are.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl, urlencode

import numpy as np
import trimesh

from beo_bench.errors import ImplausibleSizeError, InvalidKeyError
from beo_bench.objects import cache, processing, symmetry
from beo_bench.objects.datasets.meshfile import (
    FILE_EXTENT_LIMITS,
    MAX_DIAGONAL,
    MIN_EXTENT,
    UNIT_MODES,
    axes_rotation,
    check_plausible_size,
    detected_units,
    how_scaled,
    read_mesh,
    scale_factor,
)
from beo_bench.objects.registry import Generated
from beo_bench.objects.symmetry import DEFAULT_MARGIN, ESTIMATOR_VERSION
from beo_bench.types import Symmetry

REPAIR_MODES: tuple[str, ...] = processing.REPAIR_MODES
"""See :func:`~beo_bench.objects.processing.repair`."""

DEFAULT_REPAIR = "solid"
"""The default: ``basic``'s clean-up for a mesh that is already a solid, and a
watertight rebuild (:func:`~beo_bench.objects.processing.solidify`) only for one that is
still open or not a manifold afterwards. With ``basic`` as the default, 4 of 14 real meshes
from public robotics packages loaded; real files are rarely clean solids."""

SYMMETRY_THRESHOLD = 0.95
"""Volume IoU below which no candidate rotation counts as a symmetry of a loaded mesh (the
floor of :mod:`beo_bench.objects.symmetry`'s acceptance rule, which also asks for a score
within its margin of the mesh's best candidate)."""

SYMMETRY_CACHE_PARAMS = {
    "threshold": SYMMETRY_THRESHOLD,
    "margin": DEFAULT_MARGIN,
    "v": ESTIMATOR_VERSION,
}
"""Cache key of estimated symmetries: the estimator's version, so groups found by an older
estimator (z-only search, hard threshold, offsets at the centre of mass) are recomputed."""

OPTION_NAMES = ("repair", "size", "up", "front", "units")
"""The options a key's query may carry."""


# --------------------------------------------------------------------------------------
# options


@dataclass(frozen=True)
class LoadOptions:
    """Processing options of a load call (hashable: they go into build partials)."""

    repair: str = DEFAULT_REPAIR
    size: float | str | tuple[tuple[str, float | str], ...] | None = None
    """Largest extent in metres, ``"native"``, per category (sorted ``(category, size)``
    pairs), or None (the category's size)."""
    up: str = "z"
    front: str = "x"
    units: str | None = None
    """One of :data:`~beo_bench.objects.datasets.meshfile.UNIT_MODES`; None: the layout's default
    (``Layout.default_units``), so that an object has one key whether its default was
    passed explicitly or not."""

    @classmethod
    def make(
        cls,
        repair: str,
        size: float | Mapping[str, float] | str | None = None,
        up: str = "z",
        front: str = "x",
        units: str | None = None,
        default_units: str | None = None,
    ) -> LoadOptions:
        """Checked options; ``units`` equal to ``default_units`` (the layout's) become None.
        Raises ``ValueError`` for an unknown option value and
        :class:`~beo_bench.errors.ImplausibleSizeError` for a size no tabletop object has."""
        if repair not in REPAIR_MODES:
            raise ValueError(f"repair={repair!r}: use one of {', '.join(REPAIR_MODES)}")
        axes_rotation(up, front)  # validates
        if isinstance(size, Mapping):
            sz: float | str | tuple[tuple[str, float | str], ...] | None = tuple(
                sorted((str(k), check_size(v)) for k, v in size.items())
            )
        else:
            sz = None if size is None else check_size(size)
        if units is not None:
            units = "normalised" if units == "normalized" else units
            if units not in UNIT_MODES:
                raise ValueError(f"units={units!r}: use one of {', '.join(UNIT_MODES)}")
            if units == default_units:
                units = None
        return cls(repair, sz, up, front, units)

    def size_for(self, category: str) -> float | str | None:
        """The size option that applies to ``category`` (None: the category default)."""
        if isinstance(self.size, tuple):
            return dict(self.size).get(category)
        return self.size

    def key_query(self, category: str) -> str:
        """``?k=v`` of the options that differ from the defaults ('' if none)."""
        q: dict[str, str] = {}
        if self.repair != DEFAULT_REPAIR:
            q["repair"] = self.repair
        size = self.size_for(category)
        if size is not None:
            q["size"] = size if isinstance(size, str) else repr(float(size))
        elif self.units is not None:  # an explicit size makes the units irrelevant
            q["units"] = self.units
        if self.up != "z":
            q["up"] = self.up
        if self.front != "x":
            q["front"] = self.front
        return "?" + urlencode(sorted(q.items())) if q else ""

    @classmethod
    def from_query(cls, key: str, query: str, default_units: str | None = None) -> LoadOptions:
        """The options a key's query spells (:meth:`key_query`'s inverse); an
        :class:`~beo_bench.errors.InvalidKeyError` naming ``key`` for a bad one."""
        try:
            q = dict(parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query)))
        except ValueError:
            raise InvalidKeyError(f"key {key!r}: malformed options {query!r}") from None
        unknown = set(q) - set(OPTION_NAMES)
        if unknown:
            raise InvalidKeyError(f"key {key!r}: unknown option(s) {sorted(unknown)}")
        size: float | str | None = q.get("size")
        if size is not None and size != "native":
            try:
                size = float(size)
            except ValueError:
                raise InvalidKeyError(f"key {key!r}: size {size!r} is not a number") from None
        try:
            return cls.make(
                q.get("repair", DEFAULT_REPAIR),
                size,
                q.get("up", "z"),
                q.get("front", "x"),
                q.get("units"),
                default_units,
            )
        except ValueError as e:
            raise InvalidKeyError(f"key {key!r}: {e}") from None


def check_size(v: object) -> float | str:
    """A ``size`` option value: metres in the plausible range, or ``"native"``."""
    if v == "native":
        return "native"
    if isinstance(v, str):
        raise ValueError(
            f"size={v!r}: use metres (a number), a mapping, or 'native' (for file units "
            f"other than metres pass units='cm', 'mm' or 'auto' instead)"
        )
    f = float(v)  # type: ignore[arg-type]
    if not (np.isfinite(f) and f > 0):
        raise ValueError(f"size={v!r}: the largest extent must be positive metres")
    # refused here, before any file is read: the plausibility check would refuse every mesh
    if not MIN_EXTENT <= f <= MAX_DIAGONAL:
        raise ImplausibleSizeError(
            f"size={v!r}: a tabletop object's largest extent is {MIN_EXTENT}-{MAX_DIAGONAL} m "
            f"(at most the table's depth); give metres in that range"
        )
    return f


class _LoadedGenerated(Generated):
    """A loaded mesh whose symmetry is estimated on first use (cached on disk), so that
    only callers that need the symmetry pay for it."""

    def __init__(self, mesh: trimesh.Trimesh, root: Path | None) -> None:  # lazy symmetry
        self.mesh = mesh
        self.parts = None
        self.root = root

    @functools.cached_property
    def symmetry(self) -> Symmetry:  # type: ignore[override]
        return loaded_symmetry(self.mesh, self.root)


def loaded_symmetry(mesh: trimesh.Trimesh, root: Path | None = None) -> Symmetry:
    """:func:`~beo_bench.objects.symmetry.estimate_symmetry` of a canonical mesh at
    :data:`SYMMETRY_THRESHOLD`, cached on disk by content hash (in the cache at ``root``;
    default: the environment's)."""
    arrays = cache.cached(
        "symmetry",
        cache.mesh_hash(mesh),
        SYMMETRY_CACHE_PARAMS,
        lambda: symmetry.pack_symmetry(
            symmetry.estimate_symmetry(mesh, threshold=SYMMETRY_THRESHOLD)
        ),
        root,
    )
    return symmetry.unpack_symmetry(arrays)


def build_mesh(
    path: str,
    category: str,
    rotation: tuple[tuple[float, ...], ...],
    opts: LoadOptions,
    units: str = "normalised",
    root: Path | None = None,
    *,
    max_faces: int | None = None,
    trace: dict[str, Any] | None = None,
) -> Generated:
    """Read, rotate, repair, centre, scale and check one file (the lazy part of an
    instance); ``units`` is the option with the layout's default filled in; ``root``: the
    cache its symmetry is kept in (the instance's ``cache_dir``). ``max_faces``:
    the face budget (None: none; see :func:`~beo_bench.objects.datasets.meshfile.read_mesh`).
    ``trace``, when given, is filled as the steps go (the dataset check,
    :mod:`beo_bench.objects.datasets.checks`, tells from it where a file failed and what it
    measured): ``stage`` (``read``, ``repair``, ``scale``, ``size``: the step under way),
    ``faces``, ``native_extents`` (file units, our axes), ``units`` (the ones used, detected
    ones resolved; None when ``size`` set the scale) and ``extents`` (metres)."""
    t: dict[str, Any] = {} if trace is None else trace
    t["stage"] = "read"
    mesh = read_mesh(path, max_faces)
    t["faces"] = len(mesh.faces)
    R = np.asarray(rotation, dtype=np.float64)
    if not np.allclose(R, np.eye(3)):
        T = np.eye(4)
        T[:3, :3] = R
        mesh.apply_transform(T)
    t["native_extents"] = tuple(float(e) for e in mesh.extents)
    size = opts.size_for(category)
    largest = max(t["native_extents"])
    lo, hi = FILE_EXTENT_LIMITS
    if not (np.isfinite(largest) and lo <= largest <= hi):  # before the repair, which fails
        given = isinstance(size, float) or (size is None and units == "normalised")
        if given and np.isfinite(largest) and largest > 0:
            mesh.apply_scale(1.0 / largest)  # the size sets the scale anyway: a unit extent
        else:
            t["stage"] = "scale"
            raise ImplausibleSizeError(
                f"{path}: its largest extent, {largest:.4g} file units, is outside the "
                f"{lo:g} to {hi:g} file units a mesh is read at (no units make it a tabletop "
                "object): pass --size <metres> for its largest extent, or rescale the file"
            )
    t["stage"] = "repair"
    mesh = processing.repair(mesh, what=path, mode=opts.repair)
    # centre and scale after the repair, which may move the bounds (voxel remeshing)
    mesh.apply_translation(-mesh.bounds.mean(axis=0))
    t["stage"] = "scale"
    if size is None and units == "auto":  # resolved here, so that messages say which
        t["detected"] = True
        units = detected_units(mesh, path, category)
    t["units"] = None if isinstance(size, float) else "m" if size == "native" else units
    mesh.apply_scale(scale_factor(mesh, path, category, size, units))
    t["extents"] = tuple(float(e) for e in mesh.extents)
    t["stage"] = "size"
    check_plausible_size(mesh, path, how_scaled(size, units, bool(t.get("detected"))))
    t["stage"] = "done"
    return _LoadedGenerated(mesh, root)
