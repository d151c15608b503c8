"""How a dataset's files are loaded: the loading options (:class:`LoadOptions`, which a
key's ``?option=value`` part spells) and building one file into a lazily built instance's
mesh (:func:`build_mesh`: read, rotate, repair, centre, scale, check; symmetry estimated on
first use).

The layouts (:mod:`~beo_bench.objects.datasets.layouts`) say what differs between datasets:
where the models are, what their categories and splits are, what their axes are.
"""

from __future__ import annotations

import functools
import hashlib
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl, urlencode

import numpy as np
import trimesh

from beo_bench.errors import ImplausibleSizeError, InvalidKeyError, ManifestError
from beo_bench.objects import cache, processing, symmetry
from beo_bench.objects.datasets.meshfile import (
    FILE_EXTENT_LIMITS,
    MANIFEST,
    MAX_DIAGONAL,
    MIN_EXTENT,
    UNIT_MODES,
    axes_rotation,
    check_plausible_size,
    detected_units,
    how_scaled,
    read_mesh,
    scale_factor,
    toml_key,
)
from beo_bench.objects.registry import Generated
from beo_bench.objects.symmetry import DEFAULT_MARGIN, ESTIMATOR_VERSION
from beo_bench.types import Symmetry

if sys.version_info >= (3, 11):
    import tomllib
else:  # the same parser, before it joined the standard library
    import tomli as tomllib

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


# --------------------------------------------------------------------------------------
# the manifest: per-class and per-file options beside the meshes

MANIFEST_NAME = MANIFEST
"""The file at a dataset's root that gives classes and files their own ``units``, ``size``
and ``up`` (:class:`Manifest`): a folder mixing millimetre and metre files, or a few Y-up
files, cannot be fixed by the command-wide ``--units``, ``--size`` and ``--up``."""

MANIFEST_KEYS = ("units", "size", "up")
"""What a manifest entry may set (the meaning of the flags of the same names)."""


@dataclass(frozen=True)
class Override:
    """One manifest entry: the options it sets (None: left as the command gives them)."""

    units: str | None = None
    size: float | str | None = None
    up: str | None = None


@dataclass(frozen=True)
class Manifest:
    """A dataset's :data:`MANIFEST_NAME`, parsed and checked (:func:`read_manifest`):
    entries per class (``[classes.<class>]``) and per file (``[files."<path relative to the
    root>"]``). A file's entry beats its class's, and both beat the command's flags for
    their files; an entry's ``units`` also drops a command-wide ``--size`` for them (the
    file says its units, so its size is read from them)."""

    classes: tuple[tuple[str, Override], ...] = ()
    files: tuple[tuple[str, Override], ...] = ()

    def options(
        self, opts: LoadOptions, category: str, rel: str, default_units: str | None
    ) -> LoadOptions:
        """The options the file ``rel`` (relative to the root) of ``category`` loads with:
        ``opts`` (the command's) with this manifest's entries for its class and for it."""
        entries = [dict(self.classes).get(category), dict(self.files).get(rel)]
        if not any(entries):
            return opts
        size, units, up = opts.size_for(category), opts.units, opts.up
        for e in entries:
            if e is None:
                continue
            if e.size is not None:
                size = e.size
            elif e.units is not None:
                size = None
            units = e.units if e.units is not None else units
            up = e.up if e.up is not None else up
        return LoadOptions.make(opts.repair, size, up, opts.front, units, default_units)

    def identity(self) -> dict[str, dict[str, dict[str, object]]]:
        """The entries as plain data (a dataset's identity carries them)."""

        def plain(entries: tuple[tuple[str, Override], ...]) -> dict[str, dict[str, object]]:
            return {
                k: {f: v for f in MANIFEST_KEYS if (v := getattr(o, f)) is not None}
                for k, o in entries
            }

        return {"classes": plain(self.classes), "files": plain(self.files)}


def read_manifest(
    root: str | Path,
    classes: Iterable[str],
    files: Iterable[str],
    axes_option: bool = True,
) -> Manifest | None:
    """The :class:`Manifest` at ``root`` (None: the dataset has none), checked against the
    dataset's ``classes`` and ``files`` (paths relative to the root); ``axes_option``:
    whether the layout's files may name their up axis (folders). A
    :class:`~beo_bench.errors.ManifestError` naming the file and the key for anything wrong."""
    path = Path(root) / MANIFEST_NAME
    if not path.is_file():
        return None
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as e:
        raise ManifestError(f"{path}: cannot read it ({e}); fix or remove the file") from None
    except tomllib.TOMLDecodeError as e:
        raise ManifestError(f"{path}: not valid TOML ({e}); fix or remove the file") from None
    for table in data:
        if table not in ("classes", "files"):
            raise ManifestError(
                f"{path}: unknown table [{toml_key(table)}]; use [classes.<class>] or "
                f'[files."<path relative to the root>"]'
            )
    known = {"classes": set(classes), "files": set(files)}
    out: dict[str, list[tuple[str, Override]]] = {"classes": [], "files": []}
    for table, what, example in (
        ("classes", "class", "mug"),
        ("files", "mesh file", '"mug/a.obj"'),
    ):
        entries = data.get(table, {})
        if not isinstance(entries, dict):
            raise ManifestError(
                f"{path}: {table} = ...: give one table per {what}, e.g. [{table}.{example}]"
            )
        for name, entry in entries.items():
            where = f"[{table}.{toml_key(name)}]"
            if name not in known[table]:
                hint = "paths are relative to the root, with / between folders"
                if table == "classes":
                    hint = f"its classes: {', '.join(sorted(known[table])[:12])}"
                raise ManifestError(f"{path}: {where}: the dataset has no {what} {name!r} ({hint})")
            if not isinstance(entry, dict):
                raise ManifestError(
                    f"{path}: {where} must be a table of {', '.join(MANIFEST_KEYS)}"
                )
            out[table].append((name, _override(path, where, entry, axes_option)))
    return Manifest(tuple(sorted(out["classes"])), tuple(sorted(out["files"])))


def _override(path: Path, where: str, entry: dict[str, object], axes_option: bool) -> Override:
    """One manifest entry's checked values."""
    for key in entry:
        if key not in MANIFEST_KEYS:
            raise ManifestError(
                f"{path}: {where} {key}: unknown key; an entry sets {', '.join(MANIFEST_KEYS)}"
            )
    units, size, up = entry.get("units"), entry.get("size"), entry.get("up")
    if units is not None:
        if units == "normalized":
            units = "normalised"
        if units not in UNIT_MODES:
            raise ManifestError(
                f"{path}: {where} units = {units!r}: use one of {', '.join(UNIT_MODES)}"
            )
    if size is not None:
        if isinstance(size, bool) or not isinstance(size, (int, float, str)):
            raise ManifestError(
                f"{path}: {where} size = {size!r}: give metres (a number) or 'native'"
            )
        try:
            size = check_size(size)
        except (ValueError, ImplausibleSizeError) as e:  # ("size=5: why"): said in TOML
            why = str(e).split(": ", 1)[-1]
            raise ManifestError(f"{path}: {where} size = {size!r}: {why}") from None
    if up is not None:
        if not axes_option:
            raise ManifestError(
                f"{path}: {where} up: this layout's axes are known; only folder datasets take up"
            )
        try:
            axes_rotation(str(up), "x")  # a folder's front axis is +x
        except ValueError as e:
            raise ManifestError(f"{path}: {where} up = {up!r}: {e}") from None
    return Override(
        None if units is None else str(units),
        size,
        None if up is None else str(up),
    )


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


LOADED_VERSION = 1
"""Version of the cached built meshes (cache kind ``loaded``): bump it when reading,
repairing or scaling a file gives another mesh, so that no mesh of an older rule is reused."""


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
    cache it and its symmetry are kept in (the instance's ``cache_dir``). ``max_faces``:
    the face budget (None: none; see :func:`~beo_bench.objects.datasets.meshfile.read_mesh`).
    ``trace``, when given, is filled as the steps go (the dataset check,
    :mod:`beo_bench.objects.datasets.checks`, tells from it where a file failed and what it
    measured): ``stage`` (``read``, ``repair``, ``scale``, ``size``: the step under way),
    ``faces``, ``native_extents`` (file units, our axes), ``units`` (the ones used, detected
    ones resolved; None when ``size`` set the scale) and ``extents`` (metres).

    The mesh is cached by the file's content and these options (kind ``loaded``): the
    dataset check builds every file in the driver before a command starts, and the
    instances, in the driver or in workers, then read what it built instead of repairing
    the file again (a voxel or solid rebuild is seconds a file). With a ``trace`` the file
    is always built (the check wants the steps), and the result stored."""
    content = _file_digest(path)
    if content is None:  # unreadable: building says why
        return _LoadedGenerated(
            _build(path, category, rotation, opts, units, max_faces, trace), root
        )
    settings = {
        "v": LOADED_VERSION,
        "category": category,
        "rotation": rotation,
        "repair": opts.repair,
        "size": opts.size_for(category),
        "units": units,
    }
    built: list[trimesh.Trimesh] = []

    def build() -> dict[str, np.ndarray]:
        built.append(_build(path, category, rotation, opts, units, max_faces, trace))
        return {"vertices": built[0].vertices, "faces": built[0].faces}

    if trace is not None:
        build()
    arrays = cache.cached("loaded", content, settings, build, root)
    if built:  # built here: this very mesh (its cached arrays are the same numbers)
        return _LoadedGenerated(built[0], root)
    mesh = trimesh.Trimesh(arrays["vertices"], arrays["faces"], process=False)
    return _LoadedGenerated(mesh, root)


def _file_digest(path: str) -> str | None:
    """The SHA-256 of a file's bytes (32 hex digits), or None when it cannot be read."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return None
    return h.hexdigest()[:32]


def _build(
    path: str,
    category: str,
    rotation: tuple[tuple[float, ...], ...],
    opts: LoadOptions,
    units: str,
    max_faces: int | None,
    trace: dict[str, Any] | None,
) -> trimesh.Trimesh:
    """:func:`build_mesh`'s steps, uncached."""
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
    return mesh
