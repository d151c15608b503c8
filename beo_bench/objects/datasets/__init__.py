"""A user's dataset (ShapeNetCore v2, ModelNet10/40 or a folder of meshes) as benchmark
objects. The one way in is :func:`open_dataset`::

    dataset = open_dataset(root)              # layout detected, content digested
    dataset = vet(dataset)                    # optional: build every file once, name bad ones
    objects = dataset.objects("test")         # an ObjectSet of lazily loaded instances
    inst = dataset.instance(objects[0].key)   # a key back into its instance

The CLI's ``--objects ROOT`` and its loading options make the same call, and everything
else (suites, backends, reports) takes the :class:`Dataset` it returns. The modules:
:mod:`~beo_bench.objects.datasets.dataset` (identity, opening, keys),
:mod:`~beo_bench.objects.datasets.layouts` (what differs between ShapeNet, ModelNet and a
folder), :mod:`~beo_bench.objects.datasets.load` (loading options, one file into one
instance's mesh), :mod:`~beo_bench.objects.datasets.meshfile` (reading files safely, units,
sizes), :mod:`~beo_bench.objects.datasets.walk` (scans that stay in the root and are
bounded) and :mod:`~beo_bench.objects.datasets.checks` (the check of every file before a
command uses them).

Every instance is in the library's canonical frame (+z up, +x front, origin at the
bounding-box centre, metres). The processing of one file is: read (a multi-geometry scene
is concatenated), rotate into our axes, :func:`~beo_bench.objects.processing.repair`
(``basic``, ``solid``, ``voxel`` or ``none``), centre on the bounding box and scale (see
"Units and size" below), then a plausibility check of the size
(:class:`~beo_bench.errors.ImplausibleSizeError`). Nothing is read until an instance's
``mesh`` is first used, or :func:`check_dataset` builds them all; errors then name the file
(:class:`~beo_bench.errors.MeshLoadError` and its
:class:`~beo_bench.errors.NonFiniteMeshError` and
:class:`~beo_bench.errors.TruncatedMeshError`, :class:`~beo_bench.errors.EmptyMeshError`,
:class:`~beo_bench.errors.NonWatertightMeshError`).

Units and size. Normalised datasets (ShapeNetCore's unit-diagonal models, ModelNet's
arbitrary units) carry no scale, so their meshes are scaled so that the largest extent is
the category's typical size (:data:`CATEGORY_SIZES`, ``default_size``): their default
``units`` is ``"normalised"``. Folders hold scans and robotics assets (YCB-like) whose files
do carry a scale, so their default is ``units="auto"``: the file's units are detected
(``detect_units``). ``units="m"``, ``"cm"``, ``"mm"`` or ``"in"`` states them;
``size=<metres>`` (or a ``{category: metres}`` mapping) sets the largest extent whatever the
file says, and ``size="native"`` (older keys) means ``units="m"``. Every loaded mesh must
then be a plausible tabletop object (``check_plausible_size``): largest extent at least
``MIN_EXTENT`` and bounding-box diagonal at most ``MAX_DIAGONAL``, so that it lies on the
table in any pose and the env can always place it. A folder's files may name their up axis
(``up``: ``"y"``, ``"-z"``, ...); ShapeNet's and ModelNet's axes are known.

Symmetry is estimated (real datasets carry no annotation) on first use and cached on disk;
collision parts come from CoACD (:func:`beo_bench.objects.prepare.prepare` fills the cache in
parallel).

Splits of real datasets (``ood`` exists only for the procedural library):

* ShapeNet and folders: a stable hash of the model id (ShapeNet ``<synset>/<model id>``,
  folder: the path relative to the root) puts 80 % of the models in ``train``, 5 % in
  ``val`` and 15 % in ``test``; adding files never moves the others.
* ModelNet: ``test`` is ModelNet's test folder; ModelNet's train folder is split by a hash
  of the file name into ``val`` (~10 %) and ``train`` (the rest).
* ``all`` (:data:`ALL_SPLIT`): every model, whatever its split (a folder of ten files has
  only one or two in ``test``).

Keys have no machine paths: ``shapenet/<synset>/<model id>``,
``modelnet/<class>/<train|test>/<name>``, ``folder/<path relative to the root>``, plus
``?option=value`` for options that differ from the defaults. :func:`instance_from_key`
resolves one given the dataset it came from, else under ``$BEO_BENCH_SHAPENET``,
``$BEO_BENCH_MODELNET``, ``$BEO_BENCH_FOLDER`` (:data:`ROOT_ENV`).
"""

from __future__ import annotations

from beo_bench.errors import ManifestError
from beo_bench.objects.datasets.checks import (
    DatasetCheck,
    FileCheck,
    SidewaysWarning,
    SizeWarning,
    SkippedFileWarning,
    check_dataset,
    skipped_text,
    vet,
)
from beo_bench.objects.datasets.dataset import (
    ALL_SPLIT,
    SHORT_CHARS,
    Dataset,
    instance_from_key,
    object_set,
    open_dataset,
    reference_split,
    train_command,
)
from beo_bench.objects.datasets.layouts import LAYOUTS, ROOT_ENV
from beo_bench.objects.datasets.load import (
    DEFAULT_REPAIR,
    MANIFEST_NAME,
    REPAIR_MODES,
    LoadOptions,
    Manifest,
)
from beo_bench.objects.datasets.meshfile import (
    CATEGORY_SIZES,
    MAX_INPUT_FACES,
    UNIT_MODES,
    UnknownSizeWarning,
)
from beo_bench.objects.datasets.walk import DatasetScanWarning

__all__ = [
    "ALL_SPLIT",
    "CATEGORY_SIZES",
    "DEFAULT_REPAIR",
    "LAYOUTS",
    "MANIFEST_NAME",
    "MAX_INPUT_FACES",
    "REPAIR_MODES",
    "ROOT_ENV",
    "SHORT_CHARS",
    "UNIT_MODES",
    "Dataset",
    "DatasetCheck",
    "DatasetScanWarning",
    "FileCheck",
    "LoadOptions",
    "Manifest",
    "ManifestError",
    "SidewaysWarning",
    "SizeWarning",
    "SkippedFileWarning",
    "UnknownSizeWarning",
    "check_dataset",
    "instance_from_key",
    "object_set",
    "open_dataset",
    "reference_split",
    "skipped_text",
    "train_command",
    "vet",
]
