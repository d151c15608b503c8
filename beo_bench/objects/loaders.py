"""Real-dataset loaders: ShapeNetCore v2, ModelNet10/40, and plain folders of meshes.

Every loader returns an :class:`~beo_bench.objects.ObjectSet` of lazily loaded instances in
the library's canonical frame (+z up, +x front, origin at the bounding-box centre, metres).
The processing of one file is: read (a multi-geometry scene is concatenated), rotate into
our axes, :func:`~beo_bench.objects.processing.repair` (``basic``, ``solid``, ``voxel`` or
``none``), centre on the bounding box and scale (see "Units and size" below), then a plausibility
check of the size (:class:`~beo_bench.errors.ImplausibleSizeError`). Nothing is read until an
instance's ``mesh`` is first used, or :meth:`ObjectSet.check` builds them all; errors then
name the file (:class:`~beo_bench.errors.MeshLoadError` and its
:class:`~beo_bench.errors.NonFiniteMeshError` and
:class:`~beo_bench.errors.TruncatedMeshError`, :class:`~beo_bench.errors.EmptyMeshError`,
:class:`~beo_bench.errors.NonWatertightMeshError`).

Units and size. Normalised datasets (ShapeNetCore's unit-diagonal models, ModelNet's
arbitrary units) carry no scale, so their meshes are scaled so that the largest extent is
the category's typical size (:data:`CATEGORY_SIZES`, :func:`default_size`): their default
``units`` is ``"normalised"``. Folders hold scans and robotics assets (YCB-like) whose files
do carry a scale, so their default is ``units="auto"``: the file's units are detected by
:func:`detect_units`. ``units="m"``, ``"cm"`` or ``"mm"`` states them; ``size=<metres>``
(or a ``{category: metres}`` mapping) sets the largest extent whatever the file says, and
``size="native"`` (older keys) means ``units="m"``. Every loaded mesh must then be a
plausible tabletop object (:func:`check_plausible_size`): largest extent at least
:data:`MIN_EXTENT` and bounding-box diagonal at most :data:`MAX_DIAGONAL`, so that it lies on
the table in any pose and the env can always place it.

Symmetry is estimated (real datasets carry no annotation) on first use and cached on disk;
collision parts come from CoACD (:func:`beo_bench.objects.prepare.prepare` fills the cache in
parallel).

Splits of real datasets (``ood`` exists only for the procedural library):

* ShapeNet and folders: a stable hash of the model id (ShapeNet ``<synset>/<model id>``,
  folder: the path relative to the root) puts 80 % of the models in ``train``, 5 % in
  ``val`` and 15 % in ``test``; adding files never moves the others.
* ModelNet: ``test`` is ModelNet's test folder; ModelNet's train folder is split by a hash
  of the file name into ``val`` (~10 %) and ``train`` (the rest).
* ``all``: every model, whatever its split (``--split all``: a folder of ten files has only
  one or two in ``test``).

Keys have no machine paths: ``shapenet/<synset>/<model id>``,
``modelnet/<class>/<train|test>/<name>``, ``folder/<path relative to the root>``, plus
``?option=value`` for options that differ from the defaults. They are resolved against the
root given to the last loader call of that source, or ``$BEO_BENCH_SHAPENET``,
``$BEO_BENCH_MODELNET``, ``$BEO_BENCH_FOLDER``; ship :func:`dataset_roots` to worker
processes and call :func:`set_dataset_roots` there.
"""

from __future__ import annotations

import functools
import hashlib
import io
import os
import re
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NoReturn
from urllib.parse import parse_qsl, quote, unquote, urlencode

import numpy as np
import trimesh

from beo_bench.errors import (
    DatasetLayoutError,
    EmptyMeshError,
    ImplausibleSizeError,
    InvalidKeyError,
    MeshLoadError,
    TruncatedMeshError,
    UnknownCategoryError,
    UnknownSplitError,
)
from beo_bench.objects import cache, processing
from beo_bench.objects.instance import ObjectInstance
from beo_bench.objects.objectset import (
    KeyResolver,
    ObjectSet,
    procedural_instance,
    register_key_source,
)
from beo_bench.objects.registry import Generated, check_split, get_category
from beo_bench.objects.registry import categories as registered_categories
from beo_bench.objects.symmetry import DEFAULT_MARGIN, ESTIMATOR_VERSION
from beo_bench.types import Mat3, Symmetry

SOURCES: tuple[str, ...] = ("shapenet", "modelnet", "folder")
ROOT_ENV: dict[str, str] = {
    "shapenet": "BEO_BENCH_SHAPENET",
    "modelnet": "BEO_BENCH_MODELNET",
    "folder": "BEO_BENCH_FOLDER",
}
"""Environment variables naming each source's dataset root (used when no loader of that
source was called in the process)."""

MESH_SUFFIXES: tuple[str, ...] = (".obj", ".off", ".ply", ".stl", ".glb", ".gltf")
"""File types :func:`load_folder` picks up (matched case-insensitively)."""

REPAIR_MODES: tuple[str, ...] = processing.REPAIR_MODES
"""See :func:`~beo_bench.objects.processing.repair`."""

DEFAULT_REPAIR = "solid"
"""The loaders' default: ``basic``'s clean-up for a mesh that is already a solid, and a
watertight rebuild (:func:`~beo_bench.objects.processing.solidify`) only for one that is
still open or not a manifold afterwards. With ``basic`` as the default, 4 of 14 real meshes
from public robotics packages loaded; real files are rarely clean solids."""

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

UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001}
"""Metres per file unit of the units a file may be stated or detected to be in."""

UNIT_MODES: tuple[str, ...] = ("auto", *UNITS, "normalised")
"""Values of the ``units`` option: ``auto`` (detect, :func:`detect_units`), ``m``, ``cm``,
``mm`` (keep the file's scale, in these units), ``normalised`` (the file has no meaningful
scale: scale the largest extent to the category's size, :func:`default_size`)."""

DEFAULT_UNITS: dict[str, str] = {
    "shapenet": "normalised",
    "modelnet": "normalised",
    "folder": "auto",
}
"""Each source's default ``units``: ShapeNetCore normalises every model to a unit diagonal
and ModelNet's units are arbitrary; folders hold scans and assets in real units."""

# Typical largest extent (m) of each category, for normalised datasets. Values are for the
# object as it sits on a table and is grasped:
# - the library's 11 classes: the median of its procedural test instances (SIZE_SAMPLES; a
#   test checks they agree), toy-scale for chair, sofa, table, car and airplane, since the
#   real objects cannot be picked up;
# - household and YCB objects: real sizes (YCB's published dimensions where it has them);
# - ShapeNet and ModelNet classes whose real object does not fit on a table (furniture,
#   vehicles, buildings, people): toy models, like the library's, at 10-25 cm;
# - nothing above 0.40 m, so that any normalised shape (diagonal <= sqrt(3) x extent) stays
#   within MAX_DIAGONAL.
CATEGORY_SIZES: dict[str, float] = {
    # the library's classes
    "airplane": 0.145, "bottle": 0.253, "bowl": 0.158, "box": 0.105, "can": 0.123,
    "car": 0.097, "chair": 0.096, "lamp": 0.254, "mug": 0.106, "sofa": 0.138, "table": 0.126,
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
    "display": 0.40, "monitor": 0.40, "loudspeaker": 0.25, "radio": 0.25, "printer": 0.40,
    "microwave": 0.40, "xbox": 0.30, "pistol": 0.20,
    # toy models of things that do not fit on a table
    "bathtub": 0.15, "bed": 0.15, "bench": 0.15, "bookshelf": 0.15, "cabinet": 0.12,
    "dishwasher": 0.10, "file_cabinet": 0.12, "piano": 0.15, "washer": 0.10, "stove": 0.10,
    "desk": 0.15, "dresser": 0.12, "night_stand": 0.10, "wardrobe": 0.15, "tv_stand": 0.15,
    "stool": 0.10, "sink": 0.12, "toilet": 0.12, "bus": 0.20, "train": 0.25,
    "motorcycle": 0.15, "bicycle": 0.17, "skateboard": 0.20, "vessel": 0.20, "rocket": 0.20,
    "tower": 0.25, "mailbox": 0.12, "guitar": 0.25, "rifle": 0.25, "person": 0.20,
    "tent": 0.15, "stairs": 0.15, "door": 0.20, "curtain": 0.20, "mantel": 0.15,
    "range_hood": 0.12,
}  # fmt: skip
"""Typical largest extent (m) per category for normalised datasets (see the comment above
for where the values come from); ``size={category: metres}`` overrides an entry."""


class UnknownSizeWarning(UserWarning):
    """A normalised mesh of a category with no known size: it gets :data:`DEFAULT_SIZE`."""


SIZE_SAMPLES = 7
"""Procedural ``test`` instances whose median largest extent is a category's size."""

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

HASH_SPLITS: tuple[tuple[str, float], ...] = (("train", 0.80), ("val", 0.05), ("test", 0.15))
"""Shares of the hash-based splits of ShapeNet and folders."""

MODELNET_VAL_SHARE = 0.10
"""Share of ModelNet's train folder that becomes our ``val`` split."""

# ShapeNetCore v2 README (shapenet.org download page, mirrored e.g. at
# https://www.graviti.cn/open-datasets/ShapeNet): "The OBJ files are now pre-aligned so that
# the up direction is the +Y axis, and the front is the -Z axis (this fixes the mirroring
# issue in ShapeNetCore v1)". Our canonical frame is +z up, +x front, so the rotation maps
# +y -> +z and -z -> +x (hence +z -> -x and, right-handed, +x -> -y): (x, y, z) -> (-z, -x, y).
SHAPENET_TO_CANONICAL: Mat3 = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

# The 55 ShapeNetCore v2 synsets (WordNet 3.0 offsets) with short snake_case names, used
# when no registered category claims a synset through ``shapenet_synsets``.
SHAPENET_SYNSETS: dict[str, str] = {
    "02691156": "airplane",
    "02747177": "trash_bin",
    "02773838": "bag",
    "02801938": "basket",
    "02808440": "bathtub",
    "02818832": "bed",
    "02828884": "bench",
    "02834778": "bicycle",
    "02843684": "birdhouse",
    "02871439": "bookshelf",
    "02876657": "bottle",
    "02880940": "bowl",
    "02924116": "bus",
    "02933112": "cabinet",
    "02942699": "camera",
    "02946921": "can",
    "02954340": "cap",
    "02958343": "car",
    "02992529": "cellphone",
    "03001627": "chair",
    "03046257": "clock",
    "03085013": "keyboard",
    "03207941": "dishwasher",
    "03211117": "display",
    "03261776": "earphone",
    "03325088": "faucet",
    "03337140": "file_cabinet",
    "03467517": "guitar",
    "03513137": "helmet",
    "03593526": "jar",
    "03624134": "knife",
    "03636649": "lamp",
    "03642806": "laptop",
    "03691459": "loudspeaker",
    "03710193": "mailbox",
    "03759954": "microphone",
    "03761084": "microwave",
    "03790512": "motorcycle",
    "03797390": "mug",
    "03928116": "piano",
    "03938244": "pillow",
    "03948459": "pistol",
    "03991062": "pot",
    "04004475": "printer",
    "04074963": "remote_control",
    "04090263": "rifle",
    "04099429": "rocket",
    "04225987": "skateboard",
    "04256520": "sofa",
    "04330267": "stove",
    "04379243": "table",
    "04401088": "telephone",
    "04460130": "tower",
    "04468005": "train",
    "04530566": "vessel",
    "04554684": "washer",
}

_SYNSET_RE = re.compile(r"^\d{8}$")
_EXPECTED_LAYOUTS = (
    "expected one of:\n"
    "  ShapeNetCore v2: <root>/<8-digit synset>/<model id>/models/model_normalized.obj\n"
    "  ModelNet10/40:   <root>/<class>/{train,test}/<name>.off\n"
    "  folder:          <root>/<category>/**/<name>.{obj,off,ply,stl,glb,gltf}"
)

_ROOTS: dict[str, str] = {}
"""Dataset roots registered in this process (by loader calls or set_dataset_roots)."""


# --------------------------------------------------------------------------------------
# public loaders


def load_shapenet(
    path: str | Path,
    split: str = "test",
    categories: Sequence[str] | None = None,
    per_category: int | None = None,
    repair: str = DEFAULT_REPAIR,
    *,
    size: float | Mapping[str, float] | str | None = None,
    units: str | None = None,
) -> ObjectSet:
    """ShapeNetCore v2 (``<root>/<synset>/<model id>/models/model_normalized.obj``).

    Synsets map to category names through the registry (``shapenet_synsets``), else
    :data:`SHAPENET_SYNSETS`, else the synset id itself; ``categories`` takes those names
    (or synset ids). Meshes are rotated from ShapeNet's +y up / -z front into our frame
    (:data:`SHAPENET_TO_CANONICAL`) and, since ShapeNet normalises every model to unit
    size, scaled to a real-world largest extent: :func:`default_size` of the category, or
    ``size`` (metres for all, a ``{category: metres}`` mapping, or ``"native"`` to keep the
    file's units as metres); ``units`` (default ``"normalised"``; ``"auto"``, ``"m"``,
    ``"cm"``, ``"mm"``) keeps the file's scale instead (see the module docstring). Every
    mesh must pass :func:`check_plausible_size`. Many ShapeNet models are open surfaces
    that ``repair="basic"`` cannot close; the default ``repair="solid"`` rebuilds those
    watertight (at most :data:`~beo_bench.objects.processing.MAX_FACES` faces; ``"voxel"``
    is the older voxel-shell remesh, with 20k-200k faces). Splits: see the
    module docstring (``ood`` raises :class:`~beo_bench.errors.UnknownSplitError`).
    """
    opts = _Options.make(repair, size, units=units, source="shapenet")
    return _load("shapenet", path, split, categories, per_category, opts)


def load_modelnet(
    path: str | Path,
    split: str = "test",
    categories: Sequence[str] | None = None,
    per_category: int | None = None,
    repair: str = DEFAULT_REPAIR,
    *,
    size: float | Mapping[str, float] | str | None = None,
    units: str | None = None,
) -> ObjectSet:
    """ModelNet10 or ModelNet40 (``<root>/<class>/<train|test>/<name>.off``).

    Classes map to category names through the registry (``modelnet_names``, e.g. ModelNet
    ``cup`` is our ``mug``), else keep the class folder's name. ModelNet is +z up, as we
    are; its front direction is not consistent within a class, so x is kept as it is (the
    +x front convention does not hold for ModelNet objects). The ``test`` split is
    ModelNet's test folder; ``train`` and ``val`` divide its train folder (``val`` is a
    stable ~10 % by file name); ``ood`` raises. OFF files with the count line glued to
    the header (``OFF490 518 0``, common in ModelNet) are read correctly. ``repair`` and
    ``size`` and ``units`` are as for :func:`load_shapenet` (ModelNet's units are
    arbitrary, so meshes are scaled to the category size by default).
    """
    opts = _Options.make(repair, size, units=units, source="modelnet")
    return _load("modelnet", path, split, categories, per_category, opts)


def load_folder(
    path: str | Path,
    split: str = "test",
    categories: Sequence[str] | None = None,
    per_category: int | None = None,
    repair: str = DEFAULT_REPAIR,
    *,
    size: float | Mapping[str, float] | str | None = None,
    units: str | None = None,
    up: str = "z",
    front: str = "x",
) -> ObjectSet:
    """A folder with one sub-folder per category holding meshes (searched recursively):
    any of :data:`MESH_SUFFIXES` that trimesh reads.

    The sub-folder name is the category name. ``up`` and ``front`` name the files' axes
    (``"x"``, ``"-y"``, ...; default ours: +z up, +x front). Splits are by a stable hash
    of the path relative to the root: 80 % ``train``, 5 % ``val``, 15 % ``test``; ``ood``
    raises. Files keep their real scale: ``units="auto"`` (the default) detects metres,
    centimetres or millimetres from the largest extent (:func:`detect_units`); pass
    ``units="mm"`` (``"cm"``, ``"m"``) to state them, ``units="normalised"`` to scale
    unit-size models to the category's size (:data:`CATEGORY_SIZES`), or ``size=<metres>``
    (or a ``{category: metres}`` mapping) to set the largest extent. A mesh that is no
    plausible tabletop object raises :class:`~beo_bench.errors.ImplausibleSizeError` when
    it is built (:meth:`ObjectSet.check` builds all).
    """
    opts = _Options.make(repair, size, up, front, units, "folder")
    return _load("folder", path, split, categories, per_category, opts)


def load_any(
    root: str | Path,
    split: str = "test",
    categories: Sequence[str] | None = None,
    per_category: int | None = None,
) -> ObjectSet:
    """Detect the layout of ``root`` (:func:`detect_layout`) and load it with defaults
    (what ``ObjectSet(root=...)`` calls)."""
    loader = {"shapenet": load_shapenet, "modelnet": load_modelnet, "folder": load_folder}[
        detect_layout(root)
    ]
    return loader(root, split=split, categories=categories, per_category=per_category)


def detect_layout(root: str | Path) -> str:
    """``"shapenet"``, ``"modelnet"`` or ``"folder"``; raises
    :class:`~beo_bench.errors.DatasetLayoutError` when ``root`` is none of them."""
    path = _existing_dir(root)
    for source in SOURCES:
        if _top_dirs(source, str(path)):
            return source
    raise DatasetLayoutError(f"{path}: no dataset found; {_EXPECTED_LAYOUTS}")


def dataset_roots() -> dict[str, str]:
    """The dataset root of each source this process knows (registered by a loader call or
    :func:`set_dataset_roots`, else from the environment). Pass it to worker processes."""
    out = {s: os.environ[e] for s, e in ROOT_ENV.items() if os.environ.get(e)}
    out.update(_ROOTS)
    return out


def set_dataset_roots(roots: Mapping[str, str | Path]) -> None:
    """Register dataset roots (e.g. :func:`dataset_roots` of the parent process) so that
    keys of those sources resolve here."""
    for source, root in roots.items():
        if source not in SOURCES:
            raise ValueError(f"unknown dataset source {source!r}; use one of {SOURCES}")
        _ROOTS[source] = str(root)


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


@functools.cache
def _warn_unknown_size(category: str) -> None:
    # once per category and process: one line per mesh would bury the advice
    warnings.warn(
        f"category {category!r} has no known size (not in CATEGORY_SIZES nor registered): its "
        f"normalised meshes get {DEFAULT_SIZE} m; pass size={{{category!r}: <metres>}} to the "
        f"loader for its real size",
        UnknownSizeWarning,
        stacklevel=3,
    )


def _size_of(category: str) -> float:
    if category not in CATEGORY_SIZES and category not in registered_categories():
        _warn_unknown_size(category)
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
    plausible = [u for u, f in UNITS.items() if MIN_EXTENT <= extent * f <= MAX_DIAGONAL]
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


def axes_rotation(up: str = "z", front: str = "x") -> Mat3:
    """The rotation taking a mesh whose up and front axes are ``up`` and ``front`` (``"x"``,
    ``"-y"``, ...) into the canonical frame (+z up, +x front)."""
    u, f = _axis(up), _axis(front)
    if abs(float(u @ f)) > 0.5:
        raise ValueError(f"up={up!r} and front={front!r} must be different axes")
    # rows: front -> x, up x front -> y (right-handed), up -> z
    return np.stack([f, np.cross(u, f), u])


# --------------------------------------------------------------------------------------
# options and keys


@dataclass(frozen=True)
class _Options:
    """Processing options of a load call (hashable: they go into build partials)."""

    repair: str = DEFAULT_REPAIR
    size: float | str | tuple[tuple[str, float], ...] | None = None
    up: str = "z"
    front: str = "x"
    units: str | None = None
    """One of :data:`UNIT_MODES`; None: the source's default (:data:`DEFAULT_UNITS`), so
    that an object has one key whether its default was passed explicitly or not."""

    @classmethod
    def make(
        cls,
        repair: str,
        size: float | Mapping[str, float] | str | None = None,
        up: str = "z",
        front: str = "x",
        units: str | None = None,
        source: str | None = None,
    ) -> _Options:
        if repair not in REPAIR_MODES:
            raise ValueError(f"repair={repair!r}: use one of {', '.join(REPAIR_MODES)}")
        axes_rotation(up, front)  # validates
        if isinstance(size, Mapping):
            sz: float | str | tuple[tuple[str, float], ...] | None = tuple(
                sorted((str(k), _check_size(v)) for k, v in size.items())
            )
        else:
            sz = None if size is None else _check_size(size)
        if units is not None:
            units = "normalised" if units == "normalized" else units
            if units not in UNIT_MODES:
                raise ValueError(f"units={units!r}: use one of {', '.join(UNIT_MODES)}")
            if source is not None and units == DEFAULT_UNITS[source]:
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
    def from_query(cls, key: str, query: str) -> _Options:
        try:
            q = dict(parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query)))
        except ValueError:
            raise InvalidKeyError(f"key {key!r}: malformed options {query!r}") from None
        unknown = set(q) - {"repair", "size", "up", "front", "units"}
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
                key.partition("/")[0],
            )
        except ValueError as e:
            raise InvalidKeyError(f"key {key!r}: {e}") from None


def _check_size(v: object) -> float | str:
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


def _axis(name: str) -> np.ndarray:
    s = name.strip().lower()
    sign = -1.0 if s.startswith("-") else 1.0
    s = s.lstrip("+-")
    if s not in ("x", "y", "z"):
        raise ValueError(f"axis {name!r}: use 'x', 'y', 'z' with an optional sign ('-y')")
    v = np.zeros(3)
    v["xyz".index(s)] = sign
    return v


def _unit_hash(text: str) -> float:
    """A stable hash of ``text`` in [0, 1) (sha256: unlike ``hash()``, the same in every
    process and run)."""
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "big") / 2.0**64


def _hash_split(text: str) -> str:
    u, acc = _unit_hash(text), 0.0
    for name, share in HASH_SPLITS:
        acc += share
        if u < acc:
            return name
    return HASH_SPLITS[-1][0]


def _modelnet_split(folder: str, name: str) -> str:
    if folder == "test":
        return "test"
    return "val" if _unit_hash(name) < MODELNET_VAL_SHARE else "train"


# --------------------------------------------------------------------------------------
# dataset scanning


@dataclass(frozen=True)
class _Entry:
    """One model file of a dataset."""

    ident: str
    """The key without its source prefix and options, e.g. ``03001627/1a2b``."""
    category: str
    split: str
    path: Path


def _existing_dir(root: str | Path) -> Path:
    path = Path(root).expanduser()
    if not path.exists():
        raise DatasetLayoutError(
            f"{path}: no such directory; pass the dataset's root folder; {_EXPECTED_LAYOUTS}"
        )
    if not path.is_dir():
        raise DatasetLayoutError(
            f"{path}: not a directory; pass the dataset's root folder; {_EXPECTED_LAYOUTS}"
        )
    return path.resolve()


def _subdirs(path: Path) -> list[str]:
    try:
        return sorted(e.name for e in os.scandir(path) if e.is_dir() and not e.name.startswith("."))
    except OSError:
        return []


def _category_name(source: str, dirname: str) -> str:
    """Our category name for a synset / ModelNet class / folder name."""
    if source == "folder":
        return dirname
    attr = "shapenet_synsets" if source == "shapenet" else "modelnet_names"
    for c in registered_categories():
        if dirname in getattr(get_category(c), attr):
            return c
    return SHAPENET_SYNSETS.get(dirname, dirname) if source == "shapenet" else dirname


@functools.lru_cache(maxsize=64)
def _top_dirs(source: str, root: str) -> tuple[str, ...]:
    """The sub-folders of ``root`` that hold models of ``source``'s layout (a cheap check
    of a few entries each, not a full scan)."""
    path = Path(root)
    out = []
    for d in _subdirs(path):
        if source == "shapenet":
            ok = bool(_SYNSET_RE.match(d)) and any(
                (path / d / m / "models" / "model_normalized.obj").is_file()
                for m in _subdirs(path / d)[:20]
            )
        elif source == "modelnet":
            ok = any(
                next((path / d / s).glob("*.off"), None) is not None for s in ("train", "test")
            )
        else:
            ok = any(_mesh_files(path / d))
        if ok:
            out.append(d)
    return tuple(out)


def _mesh_files(folder: Path) -> Iterable[Path]:
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder).parts
        if (
            p.suffix.lower() in MESH_SUFFIXES
            and p.is_file()
            and not any(s.startswith(".") for s in rel)
        ):
            yield p


@functools.lru_cache(maxsize=1024)
def _dir_entries(source: str, root: str, dirname: str) -> tuple[_Entry, ...]:
    """All models under one top-level folder (every split), sorted by id."""
    path, cat = Path(root), _category_name(source, dirname)
    out: list[_Entry] = []
    if source == "shapenet":
        for m in _subdirs(path / dirname):
            ident = f"{dirname}/{m}"
            out.append(
                _Entry(
                    ident,
                    cat,
                    _hash_split(ident),
                    path / dirname / m / "models" / "model_normalized.obj",
                )
            )
    elif source == "modelnet":
        for folder in ("train", "test"):
            for f in sorted((path / dirname / folder).glob("*.off")):
                out.append(
                    _Entry(f"{dirname}/{folder}/{f.stem}", cat, _modelnet_split(folder, f.stem), f)
                )
    else:
        for f in _mesh_files(path / dirname):
            ident = f.relative_to(path).as_posix()
            out.append(_Entry(ident, cat, _hash_split(ident), f))
    return tuple(sorted(out, key=lambda e: e.ident))


def _category_dirs(source: str, root: str) -> dict[str, list[str]]:
    """Top-level folders of each category (ModelNet or ShapeNet may map several to one)."""
    out: dict[str, list[str]] = {}
    for d in _top_dirs(source, root):
        out.setdefault(_category_name(source, d), []).append(d)
    return out


def _category_entries(source: str, root: str, category: str, split: str) -> list[_Entry]:
    """The models of ``category`` in ``split``, in instance-index order."""
    dirs = _category_dirs(source, root).get(category, [])
    entries = [e for d in dirs for e in _dir_entries(source, root, d) if split in (e.split, "all")]
    return sorted(entries, key=lambda e: e.ident)


@functools.lru_cache(maxsize=256)
def _category_index(source: str, root: str, category: str) -> dict[str, tuple[_Entry, int]]:
    """Model id -> (entry, instance index in its split), for resolving keys quickly."""
    return {
        e.ident: (e, i)
        for split in ("train", "val", "test")
        for i, e in enumerate(_category_entries(source, root, category, split))
    }


# --------------------------------------------------------------------------------------
# loading


def _load(
    source: str,
    path: str | Path,
    split: str,
    categories: Sequence[str] | None,
    per_category: int | None,
    opts: _Options,
) -> ObjectSet:
    if split != "all":  # "all": every model of the dataset, whatever its hash split
        check_split(split)
    if split == "ood":
        raise UnknownSplitError(
            f"split 'ood' does not exist for {source} data: it is the procedural library's "
            f"out-of-range parameters (ObjectSet('ood')); real datasets have train, val, "
            f"test"
        )
    if per_category is not None and int(per_category) < 0:
        raise ValueError(f"per_category={per_category!r} must be >= 0")
    root = str(_existing_dir(path))
    dirs = _category_dirs(source, root)
    if not dirs:
        found = detect_layout(root) if _any_layout(root) else None
        hint = f" (it looks like a {found} dataset: use load_{found})" if found else ""
        raise DatasetLayoutError(f"{root}: no {source} data found{hint}; {_EXPECTED_LAYOUTS}")
    if categories is None:
        names = sorted(dirs)
    else:
        names = []
        for c in categories:
            name = c if c in dirs else _category_name(source, c)
            if name not in dirs:
                raise UnknownCategoryError(
                    f"category {c!r} is not in the {source} dataset at {root}; it has: "
                    f"{', '.join(sorted(dirs))}"
                )
            names.append(name)
    _ROOTS[source] = root
    instances: dict[str, list[ObjectInstance]] = {}
    for c in dict.fromkeys(names):
        entries = _category_entries(source, root, c, split)
        if per_category is not None:
            entries = entries[: int(per_category)]
        if entries or categories is not None:
            instances[c] = [_instance(source, e, i, opts) for i, e in enumerate(entries)]
    return ObjectSet.from_instances(split, instances, source)


def _any_layout(root: str) -> bool:
    return any(_top_dirs(s, root) for s in SOURCES)


def _instance(source: str, entry: _Entry, index: int, opts: _Options) -> ObjectInstance:
    if source == "shapenet":
        rot = SHAPENET_TO_CANONICAL
    elif source == "folder":
        rot = axes_rotation(opts.up, opts.front)
    else:
        rot = np.eye(3)
    registered = entry.category in registered_categories()
    return ObjectInstance(
        key=f"{source}/{quote(entry.ident, safe='/')}{opts.key_query(entry.category)}",
        category=entry.category,
        split=entry.split,
        index=index,
        source=source,
        build=functools.partial(
            _build,
            str(entry.path),
            entry.category,
            tuple(map(tuple, rot.tolist())),
            opts,
            opts.units or DEFAULT_UNITS[source],
        ),
        pickable=get_category(entry.category).pickable if registered else True,
        path=entry.path,
    )


class _LoadedGenerated(Generated):
    """A loaded mesh whose symmetry is estimated on first use (cached on disk), so that
    only callers that need the symmetry pay for it."""

    def __init__(self, mesh: trimesh.Trimesh) -> None:  # no super(): symmetry is lazy
        self.mesh = mesh
        self.parts = None

    @functools.cached_property
    def symmetry(self) -> Symmetry:  # type: ignore[override]
        return loaded_symmetry(self.mesh)


def loaded_symmetry(mesh: trimesh.Trimesh) -> Symmetry:
    """:func:`~beo_bench.objects.symmetry.estimate_symmetry` of a canonical mesh at
    :data:`SYMMETRY_THRESHOLD`, cached on disk by content hash."""
    arrays = cache.cached(
        "symmetry",
        cache.mesh_hash(mesh),
        SYMMETRY_CACHE_PARAMS,
        lambda: processing.pack_symmetry(
            processing.estimate_symmetry(mesh, threshold=SYMMETRY_THRESHOLD)
        ),
    )
    return processing.unpack_symmetry(arrays)


def _build(
    path: str,
    category: str,
    rotation: tuple[tuple[float, ...], ...],
    opts: _Options,
    units: str = "normalised",
) -> Generated:
    """Read, rotate, repair, centre, scale and check one file (the lazy part of an
    instance); ``units`` is the option with the source's default filled in."""
    mesh = read_mesh(path)
    R = np.asarray(rotation, dtype=np.float64)
    if not np.allclose(R, np.eye(3)):
        T = np.eye(4)
        T[:3, :3] = R
        mesh.apply_transform(T)
    mesh = processing.repair(mesh, what=path, mode=opts.repair)
    # centre and scale after the repair, which may move the bounds (voxel remeshing)
    mesh.apply_translation(-mesh.bounds.mean(axis=0))
    mesh.apply_scale(_scale(mesh, path, category, opts.size_for(category), units))
    check_plausible_size(mesh, path, _how_scaled(mesh, opts.size_for(category), units))
    return _LoadedGenerated(mesh)


def _scale(
    mesh: trimesh.Trimesh, path: str, category: str, size: float | str | None, units: str
) -> float:
    """The factor from file units to metres (precedence: an explicit size, 'native', the
    units option)."""
    extent = float(mesh.extents.max())
    if isinstance(size, float):
        return size / extent
    if size == "native":
        return 1.0  # older keys: the file's units are metres, as they always were
    if units == "normalised":
        return _size_of(category) / extent
    if units == "auto":
        try:
            units = detect_units(extent, category)
        except ImplausibleSizeError as e:
            raise ImplausibleSizeError(f"{path}: {e}") from None
    return UNITS[units]


def _how_scaled(mesh: trimesh.Trimesh, size: float | str | None, units: str) -> str:
    """How a (scaled) mesh got its size, for the plausibility error."""
    if isinstance(size, float):
        return f"size={size} m"
    if size == "native":
        return "size='native': the file's units taken as metres"
    if units == "normalised":
        return "units='normalised': scaled to the category's size"
    return f"units={units!r}"


_TEXT_SUFFIXES = (".obj", ".off")
# ``OFF490 518 0``: ModelNet's common defect, the count line glued to the header
_GLUED_OFF = re.compile(rb"\A(\s*C?OFF)(?=[ \t]*[-+0-9])")


def read_mesh(path: str | Path) -> trimesh.Trimesh:
    """Read one mesh file as a single :class:`trimesh.Trimesh` (scenes are concatenated,
    materials skipped), in the file's own axes and units.

    Raises, each naming the file: :class:`~beo_bench.errors.MeshLoadError` for a missing,
    unreadable or unparseable file; :class:`~beo_bench.errors.NonFiniteMeshError` for NaN
    or infinite coordinates; :class:`~beo_bench.errors.TruncatedMeshError` for an OBJ that
    was cut off (its last line is incomplete, or unterminated while the surface is open);
    :class:`~beo_bench.errors.EmptyMeshError` for one without faces.
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
    # before parsing: a cut file may not parse at all, and a parser error would hide why
    cut = _obj_unterminated_line(data) if suffix == ".obj" else None
    if cut is not None and not _obj_line_ok(cut):
        _raise_truncated(p, cut, "which is incomplete")
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
                kw = {"skip_materials": True} if suffix == ".obj" else {}
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
    processing.check_finite(loaded, str(p))
    if cut is not None:
        closed = loaded.copy()
        closed.merge_vertices(merge_tex=True, merge_norm=True)
        if not closed.is_watertight:
            _raise_truncated(p, cut, "and the surface is open")
    loaded.process()  # what trimesh does by default: merge duplicate vertices
    return loaded


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


# --------------------------------------------------------------------------------------
# keys


def _root_for(source: str, key: str) -> str:
    root = _ROOTS.get(source) or os.environ.get(ROOT_ENV[source])
    if not root:
        raise InvalidKeyError(
            f"key {key!r}: no {source} dataset root is known in this process; set "
            f"{ROOT_ENV[source]}=<dataset root>, or call load_{source}(<root>) first (worker "
            f"processes: set_dataset_roots(dataset_roots() of the parent))"
        )
    return str(Path(root).expanduser().resolve())


def _resolver(source: str) -> KeyResolver:
    def resolve(rest: str) -> ObjectInstance:
        key = f"{source}/{rest}"
        return _resolve(source, rest, _root_for(source, key))

    return resolve


@functools.lru_cache(maxsize=1024)
def _resolve(source: str, rest: str, root: str) -> ObjectInstance:
    # one instance object per key and root in a process, so its loaded mesh is shared
    key = f"{source}/{rest}"
    quoted, _, query = rest.partition("?")
    ident = unquote(quoted)
    parts = ident.split("/")
    shape_ok = {
        "shapenet": len(parts) == 2 and bool(_SYNSET_RE.match(parts[0])),
        "modelnet": len(parts) == 3 and parts[1] in ("train", "test"),
        "folder": len(parts) >= 2,
    }[source]
    if not shape_ok or not all(parts):
        form = {
            "shapenet": "shapenet/<8-digit synset>/<model id>",
            "modelnet": "modelnet/<class>/<train|test>/<name>",
            "folder": "folder/<category>/<path of the mesh file>",
        }[source]
        raise InvalidKeyError(f"key {key!r} is not {form}")
    opts = _Options.from_query(key, query)
    found = _category_index(source, root, _category_name(source, parts[0])).get(ident)
    if found is not None:
        return _instance(source, found[0], found[1], opts)
    raise InvalidKeyError(
        f"key {key!r}: no such model under the {source} root {root} (set "
        f"{ROOT_ENV[source]} or call load_{source} with the dataset the key came from)"
    )


for _source in SOURCES:
    register_key_source(_source, _resolver(_source))
