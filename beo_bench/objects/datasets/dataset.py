"""A user's dataset as a benchmark input: its root, layout, loading options and content
digest (``beo-bench ... --objects ROOT``).

Results on a dataset are only comparable with results on the same files loaded the same
way, so a :class:`Dataset` is identified by the digest of its mesh files' content (not
their path: a copied dataset is the same dataset, an edited one is another) and by the
loading options. Suites on a dataset carry it (``Suite.dataset``) and are named
``<suite>.<digest8>``, so run directories and leaderboard pages never mix datasets.

The digest hashes every file once; per-file hashes are cached on disk by path, size and
modification time, so a later call on an unchanged ShapeNet-size dataset costs a ``stat``
per file, not a re-read.

:func:`open_dataset` is the one entry point for opening a dataset; :meth:`Dataset.objects`
gives its object sets and :func:`instance_from_key` (:meth:`Dataset.instance`) turns any
instance key back into its instance, given the dataset it came from.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from beo_bench.atomic import atomic_write_bytes
from beo_bench.errors import InvalidKeyError, UsageError
from beo_bench.objects.cache import cache_root
from beo_bench.objects.datasets.layouts import (
    LAYOUTS,
    Layout,
    category_dirs,
    dataset_entries,
    detect_layout,
    existing_dir,
    get_layout,
    load_objects,
    resolve_key,
)
from beo_bench.objects.datasets.load import (
    DEFAULT_REPAIR,
    REPAIR_MODES,
    LoadOptions,
    Manifest,
    read_manifest,
)
from beo_bench.objects.datasets.meshfile import MAX_INPUT_FACES, UNIT_MODES, axes_rotation
from beo_bench.objects.instance import ObjectInstance
from beo_bench.objects.objectset import PROCEDURAL_PREFIX, ObjectSet, resolve_procedural_key

DIGEST_CHARS = 16
"""Hex characters of a dataset digest kept (64 bits: collisions are not a concern for the
handful of datasets one machine sees)."""
SHORT_CHARS = 8
"""Hex characters of the digest in suite, run and leaderboard names."""
DIGEST_CACHE_VERSION = 1
RACY_NS = 3_000_000_000
"""Files modified less than this long (ns) before they are hashed are not cached (their
time stamp may not tell a later edit apart: some file systems keep whole seconds)."""
ALL_SPLIT = "all"
"""The split holding every model of a dataset (a small folder's hash split puts only a few
files in ``test``; ``--split all`` evaluates on all of them)."""


@dataclass(frozen=True)
class Dataset:
    """A dataset folder and how it is loaded; what ``--objects`` and its options make
    (:func:`open_dataset`). Frozen and picklable: pass it to whatever (a worker process)
    needs the dataset's objects or must resolve its keys."""

    root: str
    """Absolute path of the dataset's root folder (not part of its identity)."""
    layout: str
    """``shapenet``, ``modelnet`` or ``folder``: a name of
    :data:`~beo_bench.objects.datasets.layouts.LAYOUTS` (see
    :func:`~beo_bench.objects.datasets.layouts.detect_layout`)."""
    digest: str
    """Content digest of its mesh files (:func:`dataset_digest`)."""
    repair: str = DEFAULT_REPAIR
    up: str = "z"
    size: float | str | tuple[tuple[str, float], ...] | None = None
    """Largest extent in metres, ``"native"``, per category (sorted ``(category, size)``
    pairs, from a mapping), or None for the category size."""
    units: str | None = None
    """The files' units (``--units``: one of :data:`~.meshfile.UNIT_MODES`),
    or None for the layout's default (folders ``auto``, ShapeNet and ModelNet
    ``normalised``)."""
    skipped: tuple[tuple[str, str], ...] = ()
    """Files left out (``--skip-bad``): (path relative to the root, what is wrong), sorted;
    the paths are part of the identity, the reasons are not (their wording may change)."""
    max_faces: int = MAX_INPUT_FACES
    """The face budget the dataset was checked with (``--max-faces``); not part of the
    identity: it decides only which files are refused, and those are :attr:`skipped`."""
    manifest: Manifest | None = None
    """The per-class and per-file options of the root's ``beo-bench.toml``
    (:class:`~beo_bench.objects.datasets.load.Manifest`), or None without one; part of the
    identity when present."""

    @property
    def short(self) -> str:
        """What suite names carry (``pose-3dof.<short>``): the content digest's first
        characters with the default loading options; with others (``--repair``, ``--up``,
        ``--size``, ``--units``, files skipped) a digest of content and options, so that the
        same files loaded two ways never share a run directory or a leaderboard page."""
        if (self.repair, self.up, self.size, self.units, self.skipped, self.manifest) == (
            DEFAULT_REPAIR,
            "z",
            None,
            None,
            (),
            None,
        ):
            return self.digest[:SHORT_CHARS]
        blob = json.dumps(self.identity(), sort_keys=True).encode()
        return hashlib.sha256(blob).hexdigest()[:SHORT_CHARS]

    def identity(self) -> dict[str, object]:
        """What fixes the objects (the root is where they are, not what they are). The
        newer options appear only when set, so that a dataset loaded as before keeps its
        identity (and its suites, runs and models their names)."""
        out: dict[str, object] = {
            "layout": self.layout,
            "digest": self.digest,
            "repair": self.repair,
            "up": self.up,
            "size": self.size,
        }
        if self.units is not None:
            out["units"] = self.units
        if self.skipped:
            out["skipped"] = [rel for rel, _ in self.skipped]
        if self.manifest is not None:
            out["manifest"] = self.manifest.identity()
        return out

    @property
    def layout_spec(self) -> Layout:
        """The :class:`~beo_bench.objects.datasets.layouts.Layout` named by :attr:`layout`."""
        return get_layout(self.layout)

    def options(self) -> LoadOptions:
        """The loading options its instances are built with (the files' up axis only
        where the layout has that option: folders; their front axis is +x). Raises
        ``ValueError`` or :class:`~beo_bench.errors.ImplausibleSizeError` for a size no
        object has."""
        spec = self.layout_spec
        up = self.up if spec.axes_option else "z"
        size = dict(self.size) if isinstance(self.size, tuple) else self.size
        return LoadOptions.make(self.repair, size, up, "x", self.units, spec.default_units)

    def objects(
        self,
        split: str,
        categories: Sequence[str] | None = None,
        per_category: int | None = None,
        cache_root: Path | None = None,
    ) -> ObjectSet:
        """The dataset's ``split`` (or every model: :data:`ALL_SPLIT`) as an object set,
        without the :attr:`skipped` files, its instances kept in the cache at ``cache_root``
        (None: the environment's)."""
        exclude = frozenset(rel for rel, _ in self.skipped)
        return load_objects(
            self.layout_spec,
            self.root,
            split,
            categories,
            per_category,
            self.options(),
            exclude,
            cache_root,
            self.manifest,
        )

    def instance(self, key: str) -> ObjectInstance:
        """The instance a key names: one of this dataset's, or a procedural one
        (:func:`instance_from_key` with this dataset)."""
        return instance_from_key(key, self)

    def categories(self) -> tuple[str, ...]:
        """Every class of the dataset (in any split), sorted."""
        return self.objects(ALL_SPLIT).categories


def object_set(
    dataset: Dataset | None,
    split: str,
    categories: Sequence[str] | None = None,
    per_category: int | None = None,
    cache_root: Path | None = None,
) -> ObjectSet:
    """The objects of ``split``: the procedural library's (``dataset`` None) or a user's
    dataset's, of ``categories`` (default: all) and at most ``per_category`` each, kept in
    the cache at ``cache_root`` (None: the environment's)."""
    if dataset is None:
        return ObjectSet(split, categories, per_category=per_category, cache_root=cache_root)
    return dataset.objects(split, categories, per_category, cache_root)


def open_dataset(
    root: str | Path,
    repair: str = DEFAULT_REPAIR,
    up: str = "z",
    size: float | str | Mapping[str, float] | None = None,
    units: str | None = None,
    max_faces: int = MAX_INPUT_FACES,
    *,
    layout: str | None = None,
) -> Dataset:
    """The dataset at ``root`` (its ``layout``, by default detected; content digested): the
    one way to a user's dataset, from the CLI's ``--objects`` and from Python alike. The
    options are those of :class:`~beo_bench.objects.datasets.load.LoadOptions` (``size``
    also a ``{category: metres}`` mapping; ``up``: a folder's files' up axis);
    a :class:`~beo_bench.errors.UsageError` for options that do not apply (``ValueError``
    or :class:`~beo_bench.errors.ImplausibleSizeError` for a size). No file is read yet:
    :func:`~beo_bench.objects.datasets.checks.check_dataset` builds every file."""
    if layout is None:
        layout = detect_layout(root)
    else:
        get_layout(layout)  # a DatasetLayoutError for an unknown name
        existing_dir(root)
    path = str(Path(root).expanduser().resolve())
    # a size no tabletop object has is refused here, before any file is read
    LoadOptions.make(DEFAULT_REPAIR, size)
    # a mapping is kept as sorted pairs: a Dataset is frozen and hashable
    sizes = (
        tuple(sorted((str(k), v) for k, v in size.items())) if isinstance(size, Mapping) else size
    )
    if up != "z" and not get_layout(layout).axes_option:
        raise UsageError(
            f"--up applies to folder datasets only; {path} is a {layout} dataset, whose axes "
            "are known (drop --up)"
        )
    if repair not in REPAIR_MODES:
        raise UsageError(f"--repair {repair!r}: use one of {', '.join(REPAIR_MODES)}")
    try:
        axes_rotation(up, "x")  # a folder's front axis is +x
    except ValueError as e:
        raise UsageError(f"--up {up!r}: {e}") from None
    default_units = get_layout(layout).default_units
    try:  # the layout's own default becomes None: one identity whether it was passed or not
        units = LoadOptions.make(repair, None, "z", "x", units, default_units).units
    except ValueError:
        raise UsageError(f"--units {units!r}: use one of {', '.join(UNIT_MODES)}") from None
    if int(max_faces) < 1:
        raise UsageError(f"--max-faces {max_faces}: give a whole number of faces >= 1")
    digest = dataset_digest(path, layout)
    spec = get_layout(layout)
    manifest = read_manifest(
        path,
        category_dirs(spec, path),
        [rel for rel, _ in dataset_files(path, layout)],
        spec.axes_option,
    )
    return Dataset(path, layout, digest, repair, up, sizes, units, (), int(max_faces), manifest)


def dataset_files(root: str, layout: str) -> list[tuple[str, Path]]:
    """Every mesh file of the dataset (all splits), as (path relative to the root, path),
    sorted."""
    entries = dataset_entries(get_layout(layout), root)
    return sorted((e.path.relative_to(root).as_posix(), e.path) for e in entries)


def dataset_digest(root: str | Path, layout: str) -> str:
    """SHA-256 over the sorted (relative path, file SHA-256) pairs of the dataset's mesh
    files, :data:`DIGEST_CHARS` hex characters (the files' hashes: :func:`file_hashes`)."""
    h = hashlib.sha256(layout.encode())
    for rel, file_hash in file_hashes(root, layout).items():
        h.update(f"{rel}\0{file_hash}\n".encode())
    return h.hexdigest()[:DIGEST_CHARS]


def file_hashes(root: str | Path, layout: str) -> dict[str, str]:
    """SHA-256 of each mesh file of the dataset, by path relative to the root, sorted.
    They are cached (see the module docstring); a file whose size or modification time
    changed is hashed again."""
    root = str(Path(root).resolve())
    memo_path = memo_file(root, f"v{DIGEST_CACHE_VERSION}")
    try:
        memo: dict[str, list] = json.loads(memo_path.read_text())
    except (OSError, ValueError):
        memo = {}
    fresh: dict[str, list] = {}
    out: dict[str, str] = {}
    now_ns = time.time_ns()
    for rel, path in dataset_files(root, layout):
        try:
            st = path.stat()
            old = memo.get(rel)
            if old is not None and old[2] is not None and old[:2] == [st.st_size, st.st_mtime_ns]:
                file_hash = str(old[2])
            else:
                file_hash = _file_sha256(path)
        except OSError as e:
            # a missing or unreadable model file is the dataset check's to report (with the
            # flag that skips it), not a reason to refuse the whole dataset here; not cached
            out[rel] = f"unreadable:{e.errno}"
            continue
        # a file modified just now may change again within the file system's timestamp
        # granularity without its size or time changing: hash it again next time
        recent = now_ns - st.st_mtime_ns < RACY_NS
        fresh[rel] = [st.st_size, st.st_mtime_ns, None if recent else file_hash]
        out[rel] = file_hash
    if fresh != memo:
        try:
            memo_path.parent.mkdir(parents=True, exist_ok=True)
            # not fsync-ed: losing it in a crash only costs re-hashing, and it is rewritten
            # whenever a dataset file changes
            atomic_write_bytes(memo_path, json.dumps(fresh), durable=False)
        except OSError:
            pass  # a read-only cache only costs re-hashing next time
    return out


def memo_file(root: str, what: str) -> Path:
    """Where what is known about the files of the dataset at ``root`` (an absolute path) is
    cached: ``what`` names the memo (its kind and version)."""
    name = hashlib.sha256(root.encode()).hexdigest()[:16]
    return cache_root() / "datasets" / f"{name}-{what}.json"


def _file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def reference_split(dataset: Dataset, categories: Sequence[str]) -> str:
    """The split a backend derives class statistics from (ICP's mean shapes): ``train``
    when every class has a model there, else :data:`ALL_SPLIT` (a folder of a few files per
    class may have none in ``train``; the means then include the scored models, which the
    user chose by scoring on such a folder)."""
    train = dataset.objects("train")
    if all(c in train.categories and train.count(c) > 0 for c in categories):
        return "train"
    return ALL_SPLIT


def instance_from_key(
    key: str, dataset: Dataset | None = None, cache_root: Path | None = None
) -> ObjectInstance:
    """The instance a key names (keys are unique across sets and sources).

    A procedural key (``proc/...``) needs nothing else. A dataset's key (``shapenet/...``,
    ``modelnet/...``, ``folder/...``: no machine paths) is looked up under ``dataset.root``;
    without a dataset, under the root in the layout's environment variable
    (:data:`~beo_bench.objects.datasets.layouts.ROOT_ENV`: ``$BEO_BENCH_SHAPENET``, ...). Raises
    :class:`~beo_bench.errors.InvalidKeyError` for a malformed key, an unknown source, a
    key of another layout than ``dataset``'s, or one with no root to look it up in.
    ``cache_root``: the cache the instance keeps its derived data in (None: the
    environment's).
    """
    prefix, sep, rest = key.partition("/")
    if not sep:
        raise InvalidKeyError(f"instance key {key!r} has no '<source>/' prefix")
    if prefix == PROCEDURAL_PREFIX:
        return resolve_procedural_key(rest, cache_root)
    layout = LAYOUTS.get(prefix)
    if layout is None:
        raise InvalidKeyError(
            f"instance key {key!r}: unknown source {prefix!r}; known: "
            f"{', '.join(sorted((PROCEDURAL_PREFIX, *LAYOUTS)))}"
        )
    return resolve_key(layout, rest, _key_root(layout, key, dataset), cache_root)


def _key_root(layout: Layout, key: str, dataset: Dataset | None) -> str:
    """The root a key of ``layout`` is looked up under."""
    if dataset is not None:
        if dataset.layout != layout.name:
            raise InvalidKeyError(
                f"key {key!r} is a {layout.name} key, but the dataset at {dataset.root} is a "
                f"{dataset.layout} dataset; pass the dataset the key came from"
            )
        root: str | None = dataset.root
    else:
        root = os.environ.get(layout.root_env)
    if not root:
        raise InvalidKeyError(
            f"key {key!r}: no {layout.name} dataset is given; pass the dataset the key came "
            f"from (instance_from_key(key, dataset), Dataset.instance(key)) or set "
            f"{layout.root_env}=<dataset root>"
        )
    return str(Path(root).expanduser().resolve())


def train_command(
    model: str,
    categories: Sequence[str] = (),
    dataset: Dataset | None = None,
    **flags: object,
) -> str:
    """The ``beo-bench train`` command that makes ``model``'s default model for
    ``categories`` (on a dataset left out when they are all its classes: the command's
    default), on the library or on ``dataset`` (with the loading options it was opened
    with), with ``flags`` (option name -> value, underscores for dashes; None is left out):
    what the errors for a missing model print, so the command trains the model looked for."""
    parts = ["beo-bench", "train", model]
    if dataset is not None:
        parts += ["--objects", dataset.root]
        if dataset.repair != DEFAULT_REPAIR:
            parts += ["--repair", dataset.repair]
        if dataset.up != "z":
            parts += ["--up", dataset.up]
        if dataset.size is not None:
            parts += ["--object-size", str(dataset.size)]  # train's --size is the network's
        if dataset.units is not None:
            parts += ["--units", dataset.units]
        if dataset.max_faces != MAX_INPUT_FACES:
            parts += ["--max-faces", str(dataset.max_faces)]
        if dataset.skipped:  # the same files left out: the same dataset identity
            parts += ["--skip-bad"]
        if set(categories) == set(dataset.categories()):
            categories = ()
    if categories:
        parts += ["--categories", *categories]
    parts += [f"--{k.replace('_', '-')} {v}" for k, v in flags.items() if v is not None]
    return " ".join(parts)
