"""Dataset layouts: what differs between ShapeNetCore v2, ModelNet10/40 and a folder of
meshes, as one small protocol (:class:`Layout`) with one module per layout, and the
layout-independent loading that dispatches through it (:func:`load_objects`,
:func:`resolve_key`).

A layout says which top-level folders hold its models and which category each is
(:meth:`Layout.holds_models`, :meth:`Layout.category_name`), which model files a folder
has and their splits (:meth:`Layout.entries`), what its keys look like
(:attr:`Layout.key_form`, :meth:`Layout.key_ok`) and its files' axes
(:meth:`Layout.rotation`). Reading, repairing and scaling files, the loading options and
the hash split are shared (:mod:`beo_bench.objects.meshfile`,
:mod:`beo_bench.objects.dataset_load`).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol
from urllib.parse import unquote

from beo_bench.errors import (
    DatasetLayoutError,
    InvalidKeyError,
    UnknownCategoryError,
    UnknownSplitError,
)
from beo_bench.objects.dataset_load import Entry, LoadOptions, make_instance, subdirs
from beo_bench.objects.instance import ObjectInstance
from beo_bench.objects.layouts.folder import FOLDER
from beo_bench.objects.layouts.modelnet import MODELNET
from beo_bench.objects.layouts.shapenet import SHAPENET
from beo_bench.objects.objectset import ObjectSet
from beo_bench.objects.registry import check_split
from beo_bench.objects.walk import inside, warn_outside
from beo_bench.types import Mat3


class Layout(Protocol):
    """What one dataset layout defines (the layouts are :data:`LAYOUTS`)."""

    @property
    def name(self) -> str:
        """The layout's name: ``Dataset.layout``, the keys' prefix, the ``source`` of its
        instances (``shapenet``)."""
        ...

    @property
    def title(self) -> str:
        """The dataset's name in messages (``ShapeNetCore v2``)."""
        ...

    @property
    def pattern(self) -> str:
        """Where its model files are, for messages (``<root>/<class>/...``)."""
        ...

    @property
    def root_env(self) -> str:
        """The environment variable naming its root, for keys resolved without a dataset."""
        ...

    @property
    def default_units(self) -> str:
        """The ``units`` option's default (``normalised``, ``auto``, ...)."""
        ...

    @property
    def axes_option(self) -> bool:
        """Whether the files' axes are an option (``up``, ``front``); else they are the
        layout's (:meth:`rotation` ignores the option)."""
        ...

    @property
    def key_form(self) -> str:
        """What its keys look like, for the error about a malformed one."""
        ...

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

    def __hash__(self) -> int:
        """Layouts are hashable: the scans are cached per layout and root."""
        ...


LAYOUTS: dict[str, Layout] = {layout.name: layout for layout in (SHAPENET, MODELNET, FOLDER)}
"""Every layout by name, in the order :func:`detect_layout` tries them."""

SOURCES: tuple[str, ...] = tuple(LAYOUTS)
"""The layouts' names: the sources of dataset instances and the prefixes of their keys."""

ROOT_ENV: dict[str, str] = {name: layout.root_env for name, layout in LAYOUTS.items()}
"""Environment variables naming each layout's dataset root (used for keys resolved without
a dataset)."""

DEFAULT_UNITS: dict[str, str] = {name: layout.default_units for name, layout in LAYOUTS.items()}
"""Each layout's default ``units``: ShapeNetCore normalises every model to a unit diagonal
and ModelNet's units are arbitrary; folders hold scans and assets in real units."""

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
) -> ObjectSet:
    """The models of ``split`` (or every model: ``"all"``) of the ``layout`` dataset at
    ``root``, of ``categories`` (default: all; our names or the layout's folder names) and
    at most ``per_category`` each, as lazily built instances loaded with ``opts``; the files
    in ``exclude`` (paths relative to the root: what ``--skip-bad`` skips) are left out
    before instances are numbered."""
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
        hint = f" (it looks like a {found} dataset: use load_{found})" if found else ""
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
            instances[c] = [_instance(layout, e, i, opts) for i, e in enumerate(entries)]
    return ObjectSet.from_instances(split, instances, source)


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


def _instance(layout: Layout, entry: Entry, index: int, opts: LoadOptions) -> ObjectInstance:
    return make_instance(
        layout.name, entry, index, opts, layout.rotation(opts), layout.default_units
    )


@functools.lru_cache(maxsize=1024)
def resolve_key(layout: Layout, rest: str, root: str) -> ObjectInstance:
    """The instance the key ``<layout name>/<rest>`` names in the dataset at ``root`` (an
    absolute path); one instance object per key and root in a process, so that its loaded
    mesh is shared. An :class:`~beo_bench.errors.InvalidKeyError` for a malformed key or
    one of a model the dataset does not have."""
    key = f"{layout.name}/{rest}"
    quoted, _, query = rest.partition("?")
    ident = unquote(quoted)
    parts = ident.split("/")
    if not layout.key_ok(parts) or not all(parts):
        raise InvalidKeyError(f"key {key!r} is not {layout.key_form}")
    opts = LoadOptions.from_query(key, query, layout.default_units)
    found = category_index(layout, root, layout.category_name(parts[0])).get(ident)
    if found is not None:
        return _instance(layout, found[0], found[1], opts)
    raise InvalidKeyError(
        f"key {key!r}: no such model under the {layout.name} root {root} (pass the dataset "
        f"the key came from, or set {layout.root_env} to its root)"
    )
