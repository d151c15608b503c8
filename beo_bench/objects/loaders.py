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
``?option=value`` for options that differ from the defaults.
:func:`~beo_bench.objects.dataset.instance_from_key` resolves one given the dataset it came
from (:func:`~beo_bench.objects.dataset.open_dataset`), else under ``$BEO_BENCH_SHAPENET``,
``$BEO_BENCH_MODELNET``, ``$BEO_BENCH_FOLDER``.

This module is the loaders' public face: :func:`load_shapenet`, :func:`load_modelnet` and
:func:`load_folder` (thin wrappers over :func:`beo_bench.objects.layouts.load_objects`) and
the names of :mod:`~beo_bench.objects.meshfile` (reading, units, sizes),
:mod:`~beo_bench.objects.dataset_load` (options, splits, instances) and
:mod:`~beo_bench.objects.layouts` (one module per layout) that callers use.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from beo_bench.objects.dataset_load import (
    DEFAULT_REPAIR,
    HASH_SPLITS,
    REPAIR_MODES,
    SYMMETRY_CACHE_PARAMS,
    SYMMETRY_THRESHOLD,
    LoadOptions,
    loaded_symmetry,
)
from beo_bench.objects.layouts import (
    DEFAULT_UNITS,
    ROOT_ENV,
    SOURCES,
    Layout,
    detect_layout,
    load_objects,
)
from beo_bench.objects.layouts.folder import FOLDER
from beo_bench.objects.layouts.modelnet import MODELNET, MODELNET_VAL_SHARE
from beo_bench.objects.layouts.shapenet import SHAPENET, SHAPENET_SYNSETS, SHAPENET_TO_CANONICAL
from beo_bench.objects.meshfile import (
    CATEGORY_SIZES,
    DEFAULT_SIZE,
    MAX_DIAGONAL,
    MESH_SUFFIXES,
    MIN_EXTENT,
    SIZE_SAMPLES,
    UNIT_MODES,
    UNITS,
    UnknownSizeWarning,
    axes_rotation,
    check_plausible_size,
    default_size,
    detect_units,
    procedural_size,
    read_mesh,
)
from beo_bench.objects.objectset import ObjectSet

__all__ = [
    "CATEGORY_SIZES",
    "DEFAULT_REPAIR",
    "DEFAULT_SIZE",
    "DEFAULT_UNITS",
    "HASH_SPLITS",
    "MAX_DIAGONAL",
    "MESH_SUFFIXES",
    "MIN_EXTENT",
    "MODELNET_VAL_SHARE",
    "REPAIR_MODES",
    "ROOT_ENV",
    "SHAPENET_SYNSETS",
    "SHAPENET_TO_CANONICAL",
    "SIZE_SAMPLES",
    "SOURCES",
    "SYMMETRY_CACHE_PARAMS",
    "SYMMETRY_THRESHOLD",
    "UNITS",
    "UNIT_MODES",
    "UnknownSizeWarning",
    "axes_rotation",
    "check_plausible_size",
    "default_size",
    "detect_layout",
    "detect_units",
    "load_folder",
    "load_modelnet",
    "load_shapenet",
    "loaded_symmetry",
    "procedural_size",
    "read_mesh",
]


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
    return _load(SHAPENET, path, split, categories, per_category, repair, size, units)


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
    return _load(MODELNET, path, split, categories, per_category, repair, size, units)


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
    return _load(FOLDER, path, split, categories, per_category, repair, size, units, up, front)


def _load(
    layout: Layout,
    path: str | Path,
    split: str,
    categories: Sequence[str] | None,
    per_category: int | None,
    repair: str,
    size: float | Mapping[str, float] | str | None,
    units: str | None,
    up: str = "z",
    front: str = "x",
) -> ObjectSet:
    opts = LoadOptions.make(repair, size, up, front, units, layout.default_units)
    return load_objects(layout, path, split, categories, per_category, opts)
