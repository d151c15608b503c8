"""One mesh file into one canonical mesh: reading it safely (:func:`read_mesh` and its
checks), its axes (:func:`axes_rotation`), its units and size (:func:`detect_units`,
:func:`default_size`, :data:`CATEGORY_SIZES`) and the plausibility check of the result
(:func:`check_plausible_size`).

Shared by every dataset layout (:mod:`beo_bench.objects.datasets.layouts`); what differs between
layouts is not here. The module docstring of :mod:`beo_bench.objects.datasets` describes the
rules ("Units and size").
"""

from __future__ import annotations

import functools
import io
import re
import warnings
from collections.abc import Iterable
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
import trimesh

from beo_bench.errors import (
    EmptyMeshError,
    ImplausibleSizeError,
    MeshLoadError,
    TooManyFacesError,
    TruncatedMeshError,
)
from beo_bench.objects import processing
from beo_bench.objects.objectset import procedural_instance
from beo_bench.objects.registry import categories as registered_categories
from beo_bench.types import Mat3

MESH_SUFFIXES: tuple[str, ...] = (".obj", ".off", ".ply", ".stl", ".glb", ".gltf")
"""File types a folder dataset's scan picks up (matched case-insensitively)."""


DEFAULT_SIZE = 0.15
"""Largest extent (m) of a normalised mesh whose category is neither in
:data:`CATEGORY_SIZES` nor registered (a :class:`UnknownSizeWarning` says so), and the
reference size :func:`detect_units` aims at for such categories: about the geometric mean of
the plausible range, 2 cm to 1 m."""


MIN_EXTENT = 0.01
"""Smallest plausible largest extent (m) of a loaded object: below 1 cm an object is half a
finger pad (2 cm wide) and a few pixels at the cameras' 0.7-1.1 m, neither graspable nor
seen; a millimetre value read as centimetres usually lands here."""


MAX_DIAGONAL = 0.70
"""Largest plausible bounding-box diagonal (m): the table's depth (``TableConfig``:
2 x 0.35 m). An object within it lies on the table in every pose (its footprint radius is
at most half the diagonal), so placement can never push it off; beyond it, objects were
placed hanging over the edge, fell off and gave episodes with no visible target."""


FILE_EXTENT_LIMITS = (1e-6, 1e6)
"""The largest extent, in file units, that a file is repaired and scaled at as it is: every
reading of ``--units`` that can give a tabletop object lies far inside it (0.01 units read
as metres to 700 read as millimetres), and the repair's geometry (voxel pitch, manifold
tolerances) breaks down far outside it (a mesh scaled by 1e30 failed inside trimesh). A file
outside it, or with an extent that is not finite, is an
:class:`~beo_bench.errors.ImplausibleSizeError` before the repair, naming ``--units`` and
``--size``; with ``size`` given it is first scaled to a unit extent, so ``--size`` loads
it."""

UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
"""Metres per file unit of the units a file may be stated to be in (``in``: inches, common in
CAD exports)."""

DETECTED_UNITS: tuple[str, ...] = ("m", "cm", "mm")
"""The units :func:`detect_units` chooses among. Inches are never detected: 2.54 cm lies
between the metric readings, so with them any extent would have a plausible reading near
every reference size, and detection would no longer tell a millimetre file from a
centimetre one."""


UNIT_MODES: tuple[str, ...] = ("auto", *UNITS, "normalised")
"""Values of the ``units`` option: ``auto`` (detect, :func:`detect_units`), ``m``, ``cm``,
``mm``, ``in`` (keep the file's scale, in these units), ``normalised`` (the file has no
meaningful scale: scale the largest extent to the category's size, :func:`default_size`)."""


MAX_INPUT_FACES = 500_000
"""Face budget of the dataset check (``--max-faces``): a file with more faces is refused
before it is parsed (:func:`read_mesh` with ``max_faces``). A 5.2M-face scan took 209 s and
5 GB to load and repair, for an object that is simplified to 5,000 faces anyway
(:data:`~beo_bench.objects.processing.MAX_FACES`); at 500k faces loading takes a few
seconds, and real object scans (YCB's, robotics packages') have 10k-300k."""


# Typical largest extent (m) of each category, for normalised datasets. Values are for the
# object as it sits on a table and is grasped:
# - the library's 18 classes: the median of its procedural test instances (SIZE_SAMPLES; a
#   test checks they agree), toy-scale for the furniture (ModelNet10's classes), car and
#   airplane, since the real objects cannot be picked up;
# - household and YCB objects: real sizes (YCB's published dimensions where it has them);
# - ShapeNet and ModelNet classes whose real object does not fit on a table (furniture,
#   vehicles, buildings, people): toy models, like the library's, at 10-25 cm;
# - nothing above 0.40 m, so that any normalised shape (diagonal <= sqrt(3) x extent) stays
#   within MAX_DIAGONAL.
CATEGORY_SIZES: dict[str, float] = {
    # the library's classes
    "airplane": 0.129, "bathtub": 0.150, "bed": 0.149, "bottle": 0.234, "bowl": 0.171,
    "box": 0.113, "can": 0.101, "car": 0.132, "chair": 0.102, "desk": 0.141, "dresser": 0.116,
    "lamp": 0.308, "monitor": 0.123, "mug": 0.096, "night_stand": 0.071, "sofa": 0.133,
    "table": 0.115, "toilet": 0.077,
    # food (YCB)
    "apple": 0.075, "banana": 0.19, "lemon": 0.068, "orange": 0.073, "peach": 0.059,
    "pear": 0.10, "plum": 0.052, "strawberry": 0.05,
    # kitchen and household (YCB where listed)
    "cup": 0.09, "glass": 0.12, "jar": 0.15, "pitcher": 0.24, "plate": 0.26, "pot": 0.25,
    "flower_pot": 0.20, "vase": 0.25, "plant": 0.30, "spoon": 0.16, "fork": 0.20,
    "knife": 0.22, "spatula": 0.35, "scissors": 0.20, "hammer": 0.33, "power_drill": 0.18,
    "screwdriver": 0.20, "wrench": 0.20, "cracker_box": 0.21, "sugar_box": 0.175,
    "mustard_bottle": 0.19, "bleach_cleanser": 0.25, "tomato_soup_can": 0.10,
    "tuna_fish_can": 0.085, "sponge": 0.11, "basket": 0.30, "bag": 0.35, "cap": 0.25,
    "helmet": 0.28, "pillow": 0.40, "clock": 0.25, "trash_bin": 0.30, "birdhouse": 0.25,
    "faucet": 0.25, "cone": 0.20, "glass_box": 0.20, "book": 0.24,
    # electronics
    "camera": 0.12, "cellphone": 0.15, "telephone": 0.20, "remote_control": 0.18,
    "earphone": 0.18, "microphone": 0.20, "keyboard": 0.40, "laptop": 0.35,
    "display": 0.40, "loudspeaker": 0.25, "radio": 0.25, "printer": 0.40,
    "microwave": 0.40, "xbox": 0.30, "pistol": 0.20,
    # toy models of things that do not fit on a table
    "bench": 0.15, "bookshelf": 0.15, "cabinet": 0.12,
    "dishwasher": 0.10, "file_cabinet": 0.12, "piano": 0.15, "washer": 0.10, "stove": 0.10,
    "wardrobe": 0.15, "tv_stand": 0.15, "stool": 0.10, "sink": 0.12, "bus": 0.20, "train": 0.25,
    "motorcycle": 0.15, "bicycle": 0.17, "skateboard": 0.20, "vessel": 0.20, "rocket": 0.20,
    "tower": 0.25, "mailbox": 0.12, "guitar": 0.25, "rifle": 0.25, "person": 0.20,
    "tent": 0.15, "stairs": 0.15, "door": 0.20, "curtain": 0.20, "mantel": 0.15,
    "range_hood": 0.12,
}  # fmt: skip
"""Typical largest extent (m) per category for normalised datasets (see the comment above
for where the values come from); ``size={category: metres}`` overrides an entry."""


class UnknownSizeWarning(UserWarning):
    """A normalised mesh of a category with no known size: it gets :data:`DEFAULT_SIZE`.

    Made from the category alone (so that it pickles from a worker process as it is);
    ``str()`` gives the advice in Python terms, :meth:`cli_text` in the command line's (the
    CLI prints that one: a user of ``beo-bench`` has no ``size=`` argument to pass)."""

    def __init__(self, category: str) -> None:
        super().__init__(category)
        self.category = category

    def _text(self, fix: str) -> str:
        return (
            f"category {self.category!r} has no known size (not in CATEGORY_SIZES nor "
            f"registered): its normalised meshes get {DEFAULT_SIZE} m; for its real size "
            f"{fix}"
        )

    def __str__(self) -> str:
        return self._text(
            f"pass size={{{self.category!r}: <metres>}} to open_dataset, or set "
            f"size = <metres> under [classes.{toml_key(self.category)}] in the dataset's "
            f"{MANIFEST}"
        )

    def cli_text(self) -> str:
        """The warning for a command-line user: the manifest key and ``--size``."""
        return self._text(
            f"set size = <metres> under [classes.{toml_key(self.category)}] in the "
            f"dataset's {MANIFEST} (or pass --size M for every object's largest extent)"
        )


MANIFEST = "beo-bench.toml"
"""The name of a dataset's per-class and per-file options file (read by
:func:`~beo_bench.objects.datasets.load.read_manifest`)."""

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def toml_key(name: str) -> str:
    """``name`` as a TOML key: bare when it may be, else quoted."""
    if _BARE_KEY.match(name):
        return name
    return '"' + name.replace("\\", "\\\\").replace('"', '\\"') + '"'


SIZE_SAMPLES = 7
"""Procedural ``test`` instances whose median largest extent is a category's size."""


@functools.cache
def default_size(category: str) -> float:
    """The largest extent (m) a normalised mesh of ``category`` is scaled to: its entry in
    :data:`CATEGORY_SIZES`; else, for a category registered after import (a user's own
    procedural class), the median over :data:`SIZE_SAMPLES` of its procedural ``test``
    instances; else :data:`DEFAULT_SIZE`."""
    if category in CATEGORY_SIZES:
        return CATEGORY_SIZES[category]
    if category in registered_categories():
        return procedural_size(category)
    return DEFAULT_SIZE


def procedural_size(category: str) -> float:
    """The median largest extent (m) of :data:`SIZE_SAMPLES` procedural ``test`` instances of
    a registered category."""
    ext = [
        float(procedural_instance(category, "test", i).mesh.extents.max())
        for i in range(SIZE_SAMPLES)
    ]
    return round(float(np.median(ext)), 6)


_SAID: set[str] = set()
"""The categories whose :class:`UnknownSizeWarning` this process has given."""


def warn_unknown_size(category: str) -> None:
    """The :class:`UnknownSizeWarning` of ``category``, once per process (one line per
    mesh would bury the advice; the dataset check and the parent of worker processes
    re-emit what they recorded through here, so the driver says it once)."""
    if category not in _SAID:
        _SAID.add(category)
        warnings.warn(UnknownSizeWarning(category), stacklevel=3)


def recorded_unknown_sizes(caught: Iterable[warnings.WarningMessage]) -> list[str]:
    """The categories of the :class:`UnknownSizeWarning` among warnings that were recorded
    (``catch_warnings(record=True)``), not shown: forgotten as given, so that re-emitting
    them (:func:`warn_unknown_size`) shows them."""
    cats = [w.message.category for w in caught if isinstance(w.message, UnknownSizeWarning)]
    _SAID.difference_update(cats)
    return cats


def _size_of(category: str) -> float:
    if category not in CATEGORY_SIZES and category not in registered_categories():
        warn_unknown_size(category)
    return default_size(category)


def detect_units(extent: float, category: str | None = None) -> str:
    """The units (``"m"``, ``"cm"`` or ``"mm"``) of a file whose largest extent is
    ``extent`` file units.

    Rule: of the three readings (``extent`` x 1, x 0.01, x 0.001 m), keep those whose
    largest extent lies in [:data:`MIN_EXTENT`, :data:`MAX_DIAGONAL`], and take the one
    nearest, by ratio, to the category's typical size (:func:`default_size`;
    :data:`DEFAULT_SIZE` for categories without one). Ties go to the larger unit. So a
    45-unit file is a 4.5 cm lemon in millimetres but a 45 cm object in centimetres when
    its category is unknown (45 cm is 3.0x the 15 cm reference, 4.5 cm 3.3x). Raises
    :class:`~beo_bench.errors.ImplausibleSizeError` when no reading is plausible.
    """
    ref = DEFAULT_SIZE
    if category is not None and (category in CATEGORY_SIZES or category in registered_categories()):
        ref = default_size(category)
    plausible = [u for u in DETECTED_UNITS if MIN_EXTENT <= extent * UNITS[u] <= MAX_DIAGONAL]
    if not plausible:
        raise ImplausibleSizeError(
            f"a largest extent of {extent:.6g} file units is no tabletop object in metres, "
            f"centimetres or millimetres (each reading is outside {MIN_EXTENT}-{MAX_DIAGONAL} "
            f"m); pass size=<metres> for its largest extent"
        )
    return min(plausible, key=lambda u: abs(np.log(extent * UNITS[u] / ref)))


def check_plausible_size(mesh: trimesh.Trimesh, what: str, how: str) -> None:
    """Raise :class:`~beo_bench.errors.ImplausibleSizeError` (naming ``what``, the file, and
    ``how`` it was scaled) unless the canonical mesh is a plausible tabletop object: largest
    extent >= :data:`MIN_EXTENT` and bounding-box diagonal <= :data:`MAX_DIAGONAL`."""
    ext = np.asarray(mesh.extents, dtype=np.float64)
    largest, diagonal = float(ext.max()), float(np.linalg.norm(ext))
    if largest >= MIN_EXTENT and diagonal <= MAX_DIAGONAL:
        return
    dims = " x ".join(f"{e:.4g}" for e in ext)
    if largest < MIN_EXTENT:
        why = (
            f"its largest extent is below {MIN_EXTENT} m: too small to see or grasp with "
            f"the 2 cm finger pads"
        )
    else:
        why = (
            f"its diagonal {diagonal:.3g} m exceeds {MAX_DIAGONAL} m, the table's depth: it "
            f"cannot lie on the table"
        )
    raise ImplausibleSizeError(
        f"{what}: loaded at {dims} m ({how}); {why}. If the file's units are wrong, pass "
        f"units='mm', 'cm' or 'm' (or 'auto' to detect them); for a normalised model pass "
        f"units='normalised' or size=<metres> (largest extent; typical sizes are in "
        f"CATEGORY_SIZES)"
    )


def scale_factor(
    mesh: trimesh.Trimesh, path: str, category: str, size: float | str | None, units: str
) -> float:
    """The factor from file units to metres of ``mesh`` (the file at ``path``, of
    ``category``); precedence: an explicit ``size`` (metres), ``'native'``, then ``units``."""
    extent = float(mesh.extents.max())
    if isinstance(size, float):
        return size / extent
    if size == "native":
        return 1.0  # older keys: the file's units are metres, as they always were
    if units == "normalised":
        return _size_of(category) / extent
    if units == "auto":
        units = detected_units(mesh, path, category)
    return UNITS[units]


def detected_units(mesh: trimesh.Trimesh, path: str, category: str) -> str:
    """:func:`detect_units` of ``mesh`` (the file at ``path``), whose error names the file."""
    try:
        return detect_units(float(mesh.extents.max()), category)
    except ImplausibleSizeError as e:
        raise ImplausibleSizeError(f"{path}: {e}") from None


def how_scaled(size: float | str | None, units: str, detected: bool = False) -> str:
    """How a mesh got its size (from the ``size`` option and ``units``; ``detected``: the
    units were detected, ``units='auto'``), for the plausibility error."""
    if isinstance(size, float):
        return f"size={size} m"
    if size == "native":
        return "size='native': the file's units taken as metres"
    if units == "normalised":
        return "units='normalised': scaled to the category's size"
    if detected:
        return f"units='auto', detected as {units!r}"
    return f"units={units!r}"


def axes_rotation(up: str = "z", front: str = "x") -> Mat3:
    """The rotation taking a mesh whose up and front axes are ``up`` and ``front`` (``"x"``,
    ``"-y"``, ...) into the canonical frame (+z up, +x front)."""
    u, f = _axis(up), _axis(front)
    if abs(float(u @ f)) > 0.5:
        raise ValueError(f"up={up!r} and front={front!r} must be different axes")
    # rows: front -> x, up x front -> y (right-handed), up -> z
    return np.stack([f, np.cross(u, f), u])


FLAT_BASE = 0.4
"""Share of the bounding box's cross-section that the flat faces of a mesh's convex hull
facing one way must cover to count as a base it stands on (:func:`sideways_up`): a
cylinder's end covers 0.79, a mug's bottom about 0.6 (its handle widens the box)."""

NO_BASE = 0.1
"""Share below which a mesh has no flat base facing down at all (a bowl on its side)."""

STANDS = 0.75
"""A mesh whose flat base facing down (-z) covers at least this share of its flat base
facing along y stands as it is (:func:`sideways_up`): a box's faces cover 1.0 each, and a
Y-up hexagonal bottle lies on a side covering 0.54 of the box, its end 0.8."""


def sideways_up(mesh: trimesh.Trimesh) -> bool:
    """Whether a canonical mesh looks modelled with +y up (the glTF and many OBJ
    exporters' convention) rather than +z: its convex hull has a flat base facing along y
    (:data:`FLAT_BASE`) and a much smaller one, or none, facing down (:data:`STANDS`): a
    Y-up bottle, can, mug or bowl, which lies on its side on the table. Only the axis is
    told: an open container's rim makes as large a hull face as its bottom. False for
    shapes with no flat base at all (a lemon) and for boxes, where nothing tells."""
    hull = mesh.convex_hull
    normals, areas = np.asarray(hull.face_normals), np.asarray(hull.area_faces)
    ext = np.asarray(mesh.extents, dtype=np.float64)

    def base(axis: int, sign: float) -> float:
        flat = areas[normals[:, axis] * sign > np.cos(np.radians(8.0))].sum()
        other = [i for i in range(3) if i != axis]
        return float(flat / max(ext[other[0]] * ext[other[1]], 1e-12))

    along_y, down = max(base(1, -1.0), base(1, 1.0)), base(2, -1.0)
    # taller along y than along z, or flat at both y ends and nothing flat below (a bowl: its
    # rim and its foot): a monitor's screen or a night stand's side faces y, but it is not
    # taller that way and stands on its feet
    upright = ext[1] >= ext[2] or (down < NO_BASE and min(base(1, -1.0), base(1, 1.0)) >= FLAT_BASE)
    return bool(along_y >= FLAT_BASE and down < STANDS * along_y and upright)


def _axis(name: str) -> np.ndarray:
    s = name.strip().lower()
    sign = -1.0 if s.startswith("-") else 1.0
    s = s.lstrip("+-")
    if s not in ("x", "y", "z"):
        raise ValueError(f"axis {name!r}: use 'x', 'y', 'z' with an optional sign ('-y')")
    v = np.zeros(3)
    v["xyz".index(s)] = sign
    return v


# ------------------------------------------------------------------------------ reading


_TEXT_SUFFIXES = (".obj", ".off")


# ``OFF490 518 0``: ModelNet's common defect, the count line glued to the header
_GLUED_OFF = re.compile(rb"\A(\s*C?OFF)(?=[ \t]*[-+0-9])")


def read_mesh(path: str | Path, max_faces: int | None = None) -> trimesh.Trimesh:
    """Read one mesh file as a single :class:`trimesh.Trimesh` (scenes are concatenated,
    materials skipped), in the file's own axes and units.

    Raises, each naming the file: :class:`~beo_bench.errors.MeshLoadError` for a missing,
    unreadable or unparseable file; :class:`~beo_bench.errors.NonFiniteMeshError` for NaN
    or infinite coordinates; :class:`~beo_bench.errors.TruncatedMeshError` for an OBJ that
    was cut off (its last line is incomplete, or unterminated while the surface is open) or
    an STL (shorter than its header's triangle count, or a text one without ``endsolid``);
    :class:`~beo_bench.errors.EmptyMeshError` for one without faces;
    :class:`~beo_bench.errors.TooManyFacesError` for one with more than ``max_faces``
    faces (None: no budget), counted before parsing where the format allows
    (:func:`count_faces`), so that an oversized file costs a read, not minutes of parsing.
    """
    p = Path(path)
    if not p.is_file():
        raise MeshLoadError(
            f"{p}: mesh file not found; check the dataset root (is the "
            f"download complete?) or remove the model's folder"
        )
    try:
        data = p.read_bytes()
    except OSError as e:
        raise MeshLoadError(f"{p}: cannot read the file ({e}); check its permissions") from e
    suffix = p.suffix.lower()
    if suffix == ".off":
        data = _GLUED_OFF.sub(rb"\1\n", data, count=1)
    if max_faces is not None:
        _check_faces(p, count_faces(data, suffix), max_faces)
    # before parsing: a cut file may not parse at all, and a parser error would hide why
    cut = _obj_unterminated_line(data) if suffix == ".obj" else None
    if cut is not None and not _obj_line_ok(cut):
        _raise_truncated(p, cut, "which is incomplete")
    if suffix == ".stl":
        _check_stl_length(p, data)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # e.g. missing texture images: irrelevant here
            # process=False: processing silently drops NaN vertices with their faces, which
            # turned a corrupt coordinate into a misleading "not watertight" later
            if suffix == ".off":
                loaded = trimesh.load(
                    io.BytesIO(data), file_type="off", force="mesh", process=False
                )
            else:
                kw: dict[str, Any] = {"skip_materials": True} if suffix == ".obj" else {}
                loaded = trimesh.load(str(p), force="mesh", process=False, **kw)
    except Exception as e:
        if cut is not None:
            _raise_truncated(p, cut, "and the file does not parse")
        raise MeshLoadError(
            f"{p}: cannot parse the {suffix or 'mesh'} file ({type(e).__name__}: {e}); it is "
            f"corrupt or not a mesh: re-download or re-export it"
        ) from e
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        if suffix in _TEXT_SUFFIXES and not _looks_like_text(data):
            raise MeshLoadError(
                f"{p}: not a text {suffix} file (binary garbage); it is "
                f"corrupt: re-download or re-export it"
            )
        raise EmptyMeshError(
            f"{p}: the file has no faces; use a mesh with geometry or remove the file"
        )
    if max_faces is not None:  # formats without a cheap count (glTF), and polygons split
        _check_faces(p, len(loaded.faces), max_faces)
    processing.check_finite(loaded, str(p))
    if cut is not None:
        closed = loaded.copy()
        closed.merge_vertices(merge_tex=True, merge_norm=True)
        if not closed.is_watertight:
            _raise_truncated(p, cut, "and the surface is open")
    loaded.process()  # what trimesh does by default: merge duplicate vertices
    return loaded


def _check_faces(p: Path, faces: int | None, max_faces: int) -> None:
    if faces is not None and faces > max_faces:
        e = TooManyFacesError(
            f"{p}: {faces:,} faces, over the face budget of {max_faces:,}; simplify it in a "
            f"mesh tool, or raise the budget (max_faces=N)"
        )
        e.faces = faces
        raise e


_OBJ_FACE = re.compile(rb"^[ \t]*f[ \t]", re.M)
_PLY_FACES = re.compile(rb"^element[ \t]+face[ \t]+(\d+)", re.M)
_OFF_COUNTS = re.compile(rb"\A\s*C?OFF\s+(?:#[^\n]*\n\s*)*(\d+)\s+(\d+)")


def count_faces(data: bytes, suffix: str) -> int | None:
    """The number of faces a mesh file declares, read without parsing it (``suffix``: its
    extension, lower case): an OBJ's ``f`` lines, an STL's triangle count (its header when
    binary, ``endfacet`` when text), a PLY's or an OFF's header count. None for formats
    without one (glTF: its counts are in accessors) or a header that does not say. Polygons
    of more than three sides count once, so a quad mesh has twice the faces once loaded."""
    if suffix == ".obj":
        return len(_OBJ_FACE.findall(data))
    if suffix == ".stl":
        if _stl_is_text(data):
            return data.count(b"endfacet")
        if len(data) >= 84:
            n = int.from_bytes(data[80:84], "little")
            return n if len(data) == 84 + 50 * n else None
        return None
    if suffix == ".ply":
        m = _PLY_FACES.search(data[: data.find(b"end_header") + 1 or 4096])
        return int(m.group(1)) if m else None
    if suffix == ".off":
        m = _OFF_COUNTS.match(data)
        return int(m.group(2)) if m else None
    return None


_OBJ_REF = re.compile(rb"^-?\d+(/(-?\d+)?){0,2}$")


_OBJ_MIN_ARGS = {b"v": 3, b"vn": 3, b"vt": 1, b"f": 3, b"l": 2}


def _obj_unterminated_line(data: bytes) -> list[bytes] | None:
    """The tokens of an OBJ's last line if it has no line break (None if it has one).

    Exporters end every line with a line break, so a file cut at an arbitrary byte (an
    interrupted download or copy) almost always ends in an unterminated line. That line is
    proof when it is malformed (``f 12 1``, ``v 0.5 -``); a well-formed one only counts
    when the surface is open, since a few writers omit the final line break. A cut exactly
    at a line break cannot be told from a complete file of an open mesh.
    """
    if not data.strip() or data.endswith((b"\n", b"\r")):
        return None
    return data[data.rfind(b"\n") + 1 :].split()


def _raise_truncated(p: Path, tokens: list[bytes], why: str) -> NoReturn:
    shown = b" ".join(tokens)[:60].decode("utf-8", errors="replace")
    raise TruncatedMeshError(
        f"{p}: the file is truncated: it ends in the middle of a line ({shown!r}, {why}); "
        f"re-download or re-export it (a complete file ends with a line break)"
    )


def _stl_is_text(data: bytes) -> bool:
    """Whether STL bytes are the text form (binary files may also start with ``solid``:
    some exporters write it into the 80-byte header, so a facet must follow)."""
    return data[:5].lower() == b"solid" and b"endfacet" in data[:4096]


def _check_stl_length(p: Path, data: bytes) -> None:
    """A :class:`~beo_bench.errors.TruncatedMeshError` for an STL cut short: a binary one
    holds fewer bytes than the 84 + 50 per triangle its header declares, a text one does not
    end with ``endsolid``. Checked before parsing: a cut binary file was otherwise read as
    text and refused as having no faces (or, without charset-normalizer, as a missing
    module), which sends the user after the wrong problem."""
    if _stl_is_text(data):
        last = data.rstrip().rsplit(b"\n", 1)[-1].strip()
        if not last.lower().startswith(b"endsolid"):
            shown = last[:60].decode("utf-8", errors="replace")
            raise TruncatedMeshError(
                f"{p}: the file is truncated: a text STL ends with an endsolid line and this "
                f"one ends with {shown!r}; re-download or re-export it"
            )
        return
    if len(data) < 84:
        if data.strip():
            raise TruncatedMeshError(
                f"{p}: the file is truncated: a binary STL has an 84-byte header and this "
                f"file has {len(data)} bytes; re-download or re-export it"
            )
        return  # empty: the no-faces error says it
    declared = int.from_bytes(data[80:84], "little")
    if len(data) < 84 + 50 * declared:
        raise TruncatedMeshError(
            f"{p}: the file is truncated: its header declares {declared:,} triangles "
            f"({84 + 50 * declared:,} bytes) but it has {len(data):,} bytes; re-download or "
            f"re-export it"
        )


def _obj_line_ok(tokens: list[bytes]) -> bool:
    """Whether an OBJ statement is complete (statements other than data pass)."""
    if not tokens or tokens[0] not in _OBJ_MIN_ARGS:
        return True
    args = tokens[1:]
    if len(args) < _OBJ_MIN_ARGS[tokens[0]]:
        return False
    if tokens[0] in (b"f", b"l"):
        return all(_OBJ_REF.match(a) for a in args)
    try:
        [float(a) for a in args]
    except ValueError:
        return False
    return True


def _looks_like_text(data: bytes) -> bool:
    """Whether the bytes look like a text file (>= 95 % printable ASCII, no NUL)."""
    sample = np.frombuffer(data[:65536], dtype=np.uint8)
    if sample.size == 0:
        return True
    printable = ((sample >= 32) & (sample < 127)) | np.isin(sample, (9, 10, 13))
    return bool(printable.mean() >= 0.95 and not (sample == 0).any())
