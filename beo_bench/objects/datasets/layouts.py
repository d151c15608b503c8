"""Dataset layouts: what differs between ShapeNetCore v2, ModelNet10/40 and a folder of
meshes, as one small protocol (:class:`Layout`) with one section per layout, and the
layout-independent scanning and loading that dispatch through it (:func:`load_objects`,
:func:`resolve_key`).

A layout says which top-level folders hold its models and which category each is
(:meth:`Layout.holds_models`, :meth:`Layout.category_name`), which model files a folder
has and their splits (:meth:`Layout.entries`), what its keys look like
(:attr:`Layout.key_form`, :meth:`Layout.key_ok`) and its files' axes
(:meth:`Layout.rotation`). Reading, repairing and scaling files and the loading options are
shared (:mod:`~beo_bench.objects.datasets.meshfile`, :mod:`~beo_bench.objects.datasets.load`).
A new layout is one more class here, added to :data:`LAYOUTS`.
"""

from __future__ import annotations

import functools
import hashlib
import re
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol
from urllib.parse import quote, unquote

import numpy as np

from beo_bench.errors import (
    DatasetLayoutError,
    InvalidKeyError,
    UnknownCategoryError,
    UnknownSplitError,
)
from beo_bench.objects.datasets.load import LoadOptions, Manifest, build_mesh
from beo_bench.objects.datasets.meshfile import MESH_SUFFIXES, axes_rotation
from beo_bench.objects.datasets.walk import (
    DatasetScanWarning,
    inside,
    subdirs,
    valid_name,
    walk_files,
    warn_outside,
)
from beo_bench.objects.instance import ObjectInstance
from beo_bench.objects.objectset import ObjectSet
from beo_bench.objects.registry import categories as registered_categories
from beo_bench.objects.registry import check_split, get_category
from beo_bench.types import Mat3

HASH_SPLITS: tuple[tuple[str, float], ...] = (("train", 0.80), ("val", 0.05), ("test", 0.15))
"""Shares of the hash-based splits of ShapeNet and folders."""


@dataclass(frozen=True)
class Entry:
    """One model file of a dataset."""

    ident: str
    """The key without its source prefix and options, e.g. ``03001627/1a2b``."""
    category: str
    split: str
    path: Path


def unit_hash(text: str) -> float:
    """A stable hash of ``text`` in [0, 1) (sha256: unlike ``hash()``, the same in every
    process and run)."""
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "big") / 2.0**64


def hash_split(text: str) -> str:
    """The split (:data:`HASH_SPLITS`) a model id falls in: adding models never moves
    the others."""
    u, acc = unit_hash(text), 0.0
    for name, share in HASH_SPLITS:
        acc += share
        if u < acc:
            return name
    return HASH_SPLITS[-1][0]


class Layout(Protocol):
    """What one dataset layout defines (the layouts are :data:`LAYOUTS`). Layouts are
    hashable (``__hash__``): the scans are cached per layout and root."""

    name: str
    """The layout's name: ``Dataset.layout``, the keys' prefix, the ``source`` of its
    instances (``shapenet``)."""
    title: str
    """The dataset's name in messages (``ShapeNetCore v2``)."""
    pattern: str
    """Where its model files are, for messages (``<root>/<class>/...``)."""
    root_env: str
    """The environment variable naming its root, for keys resolved without a dataset."""
    default_units: str
    """The ``units`` option's default (``normalised``, ``auto``, ...)."""
    axes_option: bool
    """Whether the files' axes are an option (``up``, ``front``); else they are the
    layout's (:meth:`rotation` ignores the option)."""
    key_form: str
    """What its keys look like, for the error about a malformed one."""

    def holds_models(self, folder: Path) -> bool:
        """Whether a top-level folder of a root holds models of this layout (a cheap check
        of a few entries, not a full scan)."""
        ...

    def category_name(self, dirname: str) -> str:
        """Our category name for a top-level folder (a synset, a ModelNet class, ...)."""
        ...

    def entries(self, root: Path, dirname: str) -> list[Entry]:
        """Every model file under the top-level folder ``dirname`` of ``root``, with its
        id (the key without prefix and options), category and split."""
        ...

    def key_ok(self, parts: Sequence[str]) -> bool:
        """Whether a key's id, split at ``/``, has this layout's form."""
        ...

    def rotation(self, opts: LoadOptions) -> Mat3:
        """The rotation taking the files' axes into ours (+z up, +x front)."""
        ...

    def __hash__(self) -> int: ...


# --------------------------------------------------------------------------------------
# ShapeNetCore v2: <root>/<8-digit synset>/<model id>/models/model_normalized.obj. Synsets
# map to category names through the registry (``shapenet_synsets``), else SHAPENET_SYNSETS,
# else the synset id itself. Models are +y up, -z front and normalised to a unit diagonal
# (default units ``normalised``). Splits: a stable hash of ``<synset>/<model id>``.

# ShapeNetCore v2 README (shapenet.org download page, mirrored e.g. at
# https://www.graviti.cn/open-datasets/ShapeNet): "The OBJ files are now pre-aligned so that
# the up direction is the +Y axis, and the front is the -Z axis (this fixes the mirroring
# issue in ShapeNetCore v1)". Our canonical frame is +z up, +x front, so the rotation maps
# +y -> +z and -z -> +x (hence +z -> -x and, right-handed, +x -> -y): (x, y, z) -> (-z, -x, y).
SHAPENET_TO_CANONICAL: Mat3 = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


# The 55 ShapeNetCore v2 synsets (WordNet 3.0 offsets) with short snake_case names, used
# when no registered category claims a synset through ``shapenet_synsets``.
SHAPENET_SYNSETS: dict[str, str] = {
    "02691156": "airplane", "02747177": "trash_bin", "02773838": "bag", "02801938": "basket",
    "02808440": "bathtub", "02818832": "bed", "02828884": "bench", "02834778": "bicycle",
    "02843684": "birdhouse", "02871439": "bookshelf", "02876657": "bottle", "02880940": "bowl",
    "02924116": "bus", "02933112": "cabinet", "02942699": "camera", "02946921": "can",
    "02954340": "cap", "02958343": "car", "02992529": "cellphone", "03001627": "chair",
    "03046257": "clock", "03085013": "keyboard", "03207941": "dishwasher", "03211117": "display",
    "03261776": "earphone", "03325088": "faucet", "03337140": "file_cabinet", "03467517": "guitar",
    "03513137": "helmet", "03593526": "jar", "03624134": "knife", "03636649": "lamp",
    "03642806": "laptop", "03691459": "loudspeaker", "03710193": "mailbox",
    "03759954": "microphone", "03761084": "microwave", "03790512": "motorcycle", "03797390": "mug",
    "03928116": "piano", "03938244": "pillow", "03948459": "pistol", "03991062": "pot",
    "04004475": "printer", "04074963": "remote_control", "04090263": "rifle", "04099429": "rocket",
    "04225987": "skateboard", "04256520": "sofa", "04330267": "stove", "04379243": "table",
    "04401088": "telephone", "04460130": "tower", "04468005": "train", "04530566": "vessel",
    "04554684": "washer",
}  # fmt: skip


_SYNSET_RE = re.compile(r"^\d{8}$")

MODEL_FILE = Path("models") / "model_normalized.obj"
"""Where a model's mesh is, relative to its folder ``<root>/<synset>/<model id>``."""


class ShapeNetLayout:
    """The ShapeNetCore v2 layout (:data:`SHAPENET`)."""

    name = "shapenet"
    title = "ShapeNetCore v2"
    pattern = "<root>/<8-digit synset>/<model id>/models/model_normalized.obj"
    root_env = "BEO_BENCH_SHAPENET"
    default_units = "normalised"
    axes_option = False
    key_form = "shapenet/<8-digit synset>/<model id>"

    def holds_models(self, folder: Path) -> bool:
        """A synset folder with a model among its first 20 entries."""
        return bool(_SYNSET_RE.match(folder.name)) and any(
            (folder / m / MODEL_FILE).is_file() for m in subdirs(folder)[:20]
        )

    def category_name(self, dirname: str) -> str:
        for c in registered_categories():
            if dirname in get_category(c).shapenet_synsets:
                return c
        return SHAPENET_SYNSETS.get(dirname, dirname)

    def entries(self, root: Path, dirname: str) -> list[Entry]:
        cat = self.category_name(dirname)
        if cat == dirname:  # (scanned once per process: dir_entries is cached)
            warnings.warn(
                f"{root / dirname}: synset {dirname} is none of ShapeNetCore v2's 55 (nor a "
                f"registered class's), so its models form a class named {dirname!r}; check "
                f"the folder's name if it should be a known class (e.g. 03797390 is mug)",
                DatasetScanWarning,
                stacklevel=2,
            )
        out = []
        for m in subdirs(root / dirname):
            ident = f"{dirname}/{m}"
            out.append(Entry(ident, cat, hash_split(ident), root / dirname / m / MODEL_FILE))
        return out

    def key_ok(self, parts: Sequence[str]) -> bool:
        return len(parts) == 2 and bool(_SYNSET_RE.match(parts[0]))

    def rotation(self, opts: LoadOptions) -> Mat3:
        return SHAPENET_TO_CANONICAL

    def __repr__(self) -> str:
        return "SHAPENET"


SHAPENET = ShapeNetLayout()


# --------------------------------------------------------------------------------------
# ModelNet10 / ModelNet40: <root>/<class>/{train,test}/<name>.off. Classes map to category
# names through the registry (``modelnet_names``, e.g. ModelNet ``cup`` is our ``mug``), else
# keep the class folder's name. ModelNet is +z up, as we are; its front direction is not
# consistent within a class, so its axes are kept as they are. Its units are arbitrary
# (default units ``normalised``). Splits: ``test`` is ModelNet's test folder; its train
# folder is split by a hash of the file name into ``val`` (MODELNET_VAL_SHARE) and ``train``.

MODELNET_VAL_SHARE = 0.10
"""Share of ModelNet's train folder that becomes our ``val`` split."""

FOLDERS = ("train", "test")
"""ModelNet's split folders in each class folder."""


def modelnet_split(folder: str, name: str) -> str:
    """Our split of the file ``name`` (its stem) in ModelNet's ``folder`` (train or test)."""
    if folder == "test":
        return "test"
    return "val" if unit_hash(name) < MODELNET_VAL_SHARE else "train"


class ModelNetLayout:
    """The ModelNet10/40 layout (:data:`MODELNET`)."""

    name = "modelnet"
    title = "ModelNet10/40"
    pattern = "<root>/<class>/{train,test}/<name>.off"
    root_env = "BEO_BENCH_MODELNET"
    default_units = "normalised"
    axes_option = False
    key_form = "modelnet/<class>/<train|test>/<name>"

    def holds_models(self, folder: Path) -> bool:
        """A class folder with an OFF file in its train or test folder."""
        return any(next((folder / s).glob("*.off"), None) is not None for s in FOLDERS)

    def category_name(self, dirname: str) -> str:
        for c in registered_categories():
            if dirname in get_category(c).modelnet_names:
                return c
        return dirname

    def entries(self, root: Path, dirname: str) -> list[Entry]:
        cat = self.category_name(dirname)
        return [
            Entry(f"{dirname}/{folder}/{f.stem}", cat, modelnet_split(folder, f.stem), f)
            for folder in FOLDERS
            for f in sorted((root / dirname / folder).glob("*.off"))
            if valid_name(f)
        ]

    def key_ok(self, parts: Sequence[str]) -> bool:
        return len(parts) == 3 and parts[1] in FOLDERS

    def rotation(self, opts: LoadOptions) -> Mat3:
        return np.eye(3)

    def __repr__(self) -> str:
        return "MODELNET"


MODELNET = ModelNetLayout()


# --------------------------------------------------------------------------------------
# A folder with one sub-folder per category holding mesh files, searched recursively:
# <root>/<category>/**/<name>.{obj,off,ply,stl,glb,gltf} (MESH_SUFFIXES). The sub-folder name
# is the category name. The files' axes are an option (``up``, ``front``; default ours) and
# their units are real (default units ``auto``: detected). Splits: a stable hash of the path
# relative to the root. The search never follows a link out of the root and is bounded
# (:mod:`~beo_bench.objects.datasets.walk`).


def mesh_files(folder: Path, root: Path | None = None) -> Iterator[Path]:
    """The mesh files under ``folder`` (any depth, hidden files and folders skipped),
    sorted; links out of ``root`` (default: ``folder``'s parent, the dataset root of a
    category folder) are skipped (:func:`~beo_bench.objects.datasets.walk.walk_files`)."""
    base = Path(folder).absolute().parent.resolve() if root is None else Path(root).resolve()
    return walk_files(Path(folder), base, MESH_SUFFIXES)


class FolderLayout:
    """The per-category folder layout (:data:`FOLDER`)."""

    name = "folder"
    title = "folder"
    pattern = "<root>/<category>/**/<name>.{obj,off,ply,stl,glb,gltf}"
    root_env = "BEO_BENCH_FOLDER"
    default_units = "auto"
    axes_option = True
    key_form = "folder/<category>/<path of the mesh file>"

    def holds_models(self, folder: Path) -> bool:
        """A folder with a mesh file at any depth."""
        return any(mesh_files(folder))

    def category_name(self, dirname: str) -> str:
        return dirname

    def entries(self, root: Path, dirname: str) -> list[Entry]:
        out = []
        for f in mesh_files(root / dirname, root):
            ident = f.relative_to(root).as_posix()
            out.append(Entry(ident, dirname, hash_split(ident), f))
        return out

    def key_ok(self, parts: Sequence[str]) -> bool:
        return len(parts) >= 2

    def rotation(self, opts: LoadOptions) -> Mat3:
        return axes_rotation(opts.up, opts.front)

    def __repr__(self) -> str:
        return "FOLDER"


FOLDER = FolderLayout()


LAYOUTS: dict[str, Layout] = {layout.name: layout for layout in (SHAPENET, MODELNET, FOLDER)}
"""Every layout by name, in the order :func:`detect_layout` tries them."""

SOURCES: tuple[str, ...] = tuple(LAYOUTS)
"""The layouts' names: the sources of dataset instances and the prefixes of their keys."""

ROOT_ENV: dict[str, str] = {name: layout.root_env for name, layout in LAYOUTS.items()}
"""Environment variables naming each layout's dataset root (used for keys resolved without
a dataset)."""

EXPECTED_LAYOUTS = "expected one of:\n" + "\n".join(
    f"  {layout.title + ':':<17}{layout.pattern}" for layout in LAYOUTS.values()
)
"""The layouts, for the errors about a root that has none."""


def get_layout(name: str) -> Layout:
    """The layout called ``name`` (``shapenet``, ``modelnet`` or ``folder``)."""
    try:
        return LAYOUTS[name]
    except KeyError:
        raise DatasetLayoutError(
            f"unknown dataset layout {name!r}; use one of {', '.join(SOURCES)}"
        ) from None


def existing_dir(root: str | Path) -> Path:
    """``root`` resolved, or a :class:`~beo_bench.errors.DatasetLayoutError` when it is no
    directory."""
    path = Path(root).expanduser()
    if not path.exists():
        raise DatasetLayoutError(
            f"{path}: no such directory; pass the dataset's root folder; {EXPECTED_LAYOUTS}"
        )
    if not path.is_dir():
        raise DatasetLayoutError(
            f"{path}: not a directory; pass the dataset's root folder; {EXPECTED_LAYOUTS}"
        )
    return path.resolve()


def detect_layout(root: str | Path) -> str:
    """``"shapenet"``, ``"modelnet"`` or ``"folder"``; raises
    :class:`~beo_bench.errors.DatasetLayoutError` when ``root`` is none of them."""
    path = existing_dir(root)
    for name, layout in LAYOUTS.items():
        if top_dirs(layout, str(path)):
            return name
    raise DatasetLayoutError(f"{path}: no dataset found; {EXPECTED_LAYOUTS}")


# --------------------------------------------------------------------------------------
# scanning (cached per layout and root: a process scans a dataset once)


@functools.lru_cache(maxsize=64)
def top_dirs(layout: Layout, root: str) -> tuple[str, ...]:
    """The sub-folders of ``root`` that hold models of ``layout``; a link to a folder
    outside ``root`` is skipped with a warning, before anything under it is looked at."""
    path = Path(root)
    return tuple(
        d for d in subdirs(path) if _within(path / d, path) and layout.holds_models(path / d)
    )


@functools.lru_cache(maxsize=1024)
def dir_entries(layout: Layout, root: str, dirname: str) -> tuple[Entry, ...]:
    """All models under one top-level folder (every split), sorted by id; a model file
    that is (or lies behind) a link out of ``root`` is skipped with a warning, so it is
    never read."""
    base = Path(root)
    entries = [e for e in layout.entries(base, dirname) if _within(e.path, base)]
    return tuple(sorted(entries, key=lambda e: e.ident))


def _within(path: Path, root: Path) -> bool:
    """Whether ``path`` resolves inside ``root``; warns (once) when it does not."""
    if inside(path, root):
        return True
    # name the link itself: the first component of the path that is one
    link = next((p for p in [path, *path.parents] if p.is_symlink()), path)
    warn_outside(str(link), str(root))
    return False


def dataset_entries(layout: Layout, root: str) -> list[Entry]:
    """Every model of the dataset at ``root`` (every split)."""
    return [e for d in top_dirs(layout, root) for e in dir_entries(layout, root, d)]


def category_dirs(layout: Layout, root: str) -> dict[str, list[str]]:
    """Top-level folders of each category (ModelNet or ShapeNet may map several to one)."""
    out: dict[str, list[str]] = {}
    for d in top_dirs(layout, root):
        out.setdefault(layout.category_name(d), []).append(d)
    return out


def category_entries(layout: Layout, root: str, category: str, split: str) -> list[Entry]:
    """The models of ``category`` in ``split``, in instance-index order."""
    dirs = category_dirs(layout, root).get(category, [])
    entries = [e for d in dirs for e in dir_entries(layout, root, d) if split in (e.split, "all")]
    return sorted(entries, key=lambda e: e.ident)


@functools.lru_cache(maxsize=256)
def category_index(layout: Layout, root: str, category: str) -> dict[str, tuple[Entry, int]]:
    """Model id -> (entry, instance index in its split), for resolving keys quickly."""
    return {
        e.ident: (e, i)
        for split in ("train", "val", "test")
        for i, e in enumerate(category_entries(layout, root, category, split))
    }


# --------------------------------------------------------------------------------------
# loading and keys


def load_objects(
    layout: Layout,
    root: str | Path,
    split: str,
    categories: Sequence[str] | None,
    per_category: int | None,
    opts: LoadOptions,
    exclude: frozenset[str] = frozenset(),
    cache_root: Path | None = None,
    manifest: Manifest | None = None,
) -> ObjectSet:
    """The models of ``split`` (or every model: ``"all"``) of the ``layout`` dataset at
    ``root``, of ``categories`` (default: all; our names or the layout's folder names) and
    at most ``per_category`` each, as lazily built instances loaded with ``opts``; the files
    in ``exclude`` (paths relative to the root: what ``--skip-bad`` skips) are left out
    before instances are numbered. ``cache_root``: the cache the instances keep their
    derived data in (None: the environment's). ``manifest``: the dataset's per-class and
    per-file options, which replace ``opts``' for their files (their keys say so)."""
    source = layout.name
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
    path = str(existing_dir(root))
    dirs = category_dirs(layout, path)
    if not dirs:
        found = detect_layout(path) if any(top_dirs(o, path) for o in LAYOUTS.values()) else None
        hint = f" (it looks like a {found} dataset: layout={found!r})" if found else ""
        raise DatasetLayoutError(f"{path}: no {source} data found{hint}; {EXPECTED_LAYOUTS}")
    names = sorted(dirs) if categories is None else _category_names(layout, path, dirs, categories)
    instances: dict[str, list[ObjectInstance]] = {}
    for c in dict.fromkeys(names):
        entries = category_entries(layout, path, c, split)
        if exclude:
            entries = [e for e in entries if e.path.relative_to(path).as_posix() not in exclude]
        if per_category is not None:
            entries = entries[: int(per_category)]
        if entries or categories is not None:
            instances[c] = [
                _instance(layout, e, i, entry_options(layout, path, e, opts, manifest), cache_root)
                for i, e in enumerate(entries)
            ]
    return ObjectSet.from_instances(split, instances, source)


def entry_options(
    layout: Layout, root: str, entry: Entry, opts: LoadOptions, manifest: Manifest | None
) -> LoadOptions:
    """The options ``entry`` (a model of the dataset at ``root``) loads with: ``opts``, or
    what the dataset's manifest makes of them for its class and file."""
    if manifest is None:
        return opts
    rel = entry.path.relative_to(root).as_posix()
    return manifest.options(opts, entry.category, rel, layout.default_units)


def _category_names(
    layout: Layout, root: str, dirs: dict[str, list[str]], categories: Sequence[str]
) -> list[str]:
    names = []
    for c in categories:
        name = c if c in dirs else layout.category_name(c)
        if name not in dirs:
            raise UnknownCategoryError(
                f"category {c!r} is not in the {layout.name} dataset at {root}; it has: "
                f"{', '.join(sorted(dirs))}"
            )
        names.append(name)
    return names


def _instance(
    layout: Layout, entry: Entry, index: int, opts: LoadOptions, cache_root: Path | None
) -> ObjectInstance:
    """The lazily built instance of ``entry`` (instance ``index`` of its split), loaded with
    ``opts``: its key is the layout's name (the key's prefix), its id and its options."""
    registered = entry.category in registered_categories()
    return ObjectInstance(
        key=f"{layout.name}/{quote(entry.ident, safe='/')}{opts.key_query(entry.category)}",
        category=entry.category,
        split=entry.split,
        index=index,
        source=layout.name,
        build=functools.partial(
            build_mesh,
            str(entry.path),
            entry.category,
            tuple(map(tuple, np.asarray(layout.rotation(opts)).tolist())),
            opts,
            opts.units or layout.default_units,
        ),
        pickable=get_category(entry.category).pickable if registered else True,
        path=entry.path,
        cache_dir=cache_root,
    )


@functools.lru_cache(maxsize=1024)
def resolve_key(
    layout: Layout, rest: str, root: str, cache_root: Path | None = None
) -> ObjectInstance:
    """The instance the key ``<layout name>/<rest>`` names in the dataset at ``root`` (an
    absolute path), kept in the cache at ``cache_root``; one instance object per key, root
    and cache in a process, so that its loaded mesh is shared. An
    :class:`~beo_bench.errors.InvalidKeyError` for a malformed key or one of a model the
    dataset does not have."""
    key = f"{layout.name}/{rest}"
    quoted, _, query = rest.partition("?")
    ident = unquote(quoted)
    parts = ident.split("/")
    if not layout.key_ok(parts) or not all(parts):
        raise InvalidKeyError(f"key {key!r} is not {layout.key_form}")
    opts = LoadOptions.from_query(key, query, layout.default_units)
    found = category_index(layout, root, layout.category_name(parts[0])).get(ident)
    if found is not None:
        return _instance(layout, found[0], found[1], opts, cache_root)
    raise InvalidKeyError(
        f"key {key!r}: no such model under the {layout.name} root {root} (pass the dataset "
        f"the key came from, or set {layout.root_env} to its root)"
    )
