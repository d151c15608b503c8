"""``ObjectSet``: a split of the object library (procedural, or a real dataset), and the
procedural library's keys.

Keys are ``<source>/<rest>``: ``proc/v2/mug/test/7`` for procedural instances
(:func:`resolve_procedural_key`); a dataset's keys (``shapenet``, ``modelnet``, ``folder``)
are resolved by :func:`beo_bench.objects.datasets.instance_from_key`, the one function for
every key.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np
import trimesh

from beo_bench.errors import (
    InstanceIndexError,
    InvalidKeyError,
    MeshError,
    UnknownCategoryError,
)
from beo_bench.objects.instance import ObjectInstance
from beo_bench.objects.params import Params
from beo_bench.objects.registry import (
    DEFAULT_SPLIT_SIZES,
    LIBRARY_VERSION,
    Generated,
    check_split,
    generate,
    get_category,
    instance_params,
)
from beo_bench.objects.registry import (
    categories as registered_categories,
)

PROCEDURAL_PREFIX = "proc"
"""The source prefix of procedural keys."""


def procedural_instance(
    category: str, split: str, index: int, cache_root: Path | None = None
) -> ObjectInstance:
    """Instance ``index`` of a procedural category in ``split`` (cheap: the mesh is lazy),
    kept in the cache at ``cache_root`` (None: the environment's)."""
    spec = get_category(category)
    check_split(split)
    params = instance_params(category, split, index)
    return ObjectInstance(
        key=f"{PROCEDURAL_PREFIX}/v{LIBRARY_VERSION}/{category}/{split}/{index}",
        category=category,
        split=split,
        index=index,
        source="procedural",
        build=functools.partial(_generate_cached, category, params),
        params=params,
        pickable=spec.pickable,
        cache_dir=cache_root,
    )


GENERATED_CACHE_VERSION = 1


def _generate_cached(category: str, params: Params, root: Path | None) -> Generated:
    """``generate`` through the asset cache: building a mesh (booleans, ~25 ms) is paid once
    per machine, not once per process; loading it back takes about a millisecond. Keyed by
    the category, its parameters and the library version, which determine the mesh; kept in
    the cache at ``root`` (None: the environment's)."""
    import hashlib
    import json

    from beo_bench.objects import cache
    from beo_bench.objects.processing import pack_parts, unpack_parts

    blob = json.dumps([category, LIBRARY_VERSION, params], sort_keys=True, default=repr)
    content = hashlib.sha256(blob.encode()).hexdigest()

    def compute() -> dict[str, np.ndarray]:
        g = generate(category, params)
        packed = {f"part_{k}": v for k, v in pack_parts(g.parts or []).items()}
        return {
            "vertices": np.asarray(g.mesh.vertices, dtype=np.float64),
            "faces": np.asarray(g.mesh.faces, dtype=np.int64),
            "symmetry": np.array(json.dumps(g.symmetry, default=lambda o: np.asarray(o).tolist())),
            **packed,
        }

    a = cache.cached("generated", content, {"v": GENERATED_CACHE_VERSION}, compute, root)
    mesh = trimesh.Trimesh(a["vertices"], a["faces"], process=False)
    parts = unpack_parts({k[5:]: v for k, v in a.items() if k.startswith("part_")})
    return Generated(mesh=mesh, parts=parts, symmetry=json.loads(str(a["symmetry"])))


def _is_index(s: str) -> bool:
    """A canonical instance index: ASCII digits, no sign, no leading zero."""
    return s.isascii() and s.isdigit() and (s == "0" or not s.startswith("0"))


def resolve_procedural_key(rest: str, cache_root: Path | None = None) -> ObjectInstance:
    """The procedural instance the key ``proc/<rest>`` names (kept in the cache at
    ``cache_root``; None: the environment's); an
    :class:`~beo_bench.errors.InvalidKeyError` for a malformed key, one of another library
    version, or an index beyond its split."""
    parts = rest.split("/")
    if len(parts) != 4 or not _is_index(parts[3]) or not parts[0].startswith("v"):
        # str.isdigit() alone takes fullwidth and other non-ASCII digits, which int() reads
        # as numbers: '１' would name instance 1 under a second key
        raise InvalidKeyError(
            f"procedural key 'proc/{rest}' is not proc/v<N>/<category>/<split>/<index> "
            "(index: ASCII digits without leading zeros)"
        )
    version, category, split, index = parts
    if version != f"v{LIBRARY_VERSION}":
        raise InvalidKeyError(
            f"key 'proc/{rest}' is from library {version}; this package generates "
            f"v{LIBRARY_VERSION} (install the beo-bench release that made those results)"
        )
    get_category(category)
    check_split(split)
    n = DEFAULT_SPLIT_SIZES[split]
    if int(index) >= n:  # any index would build some object: one the split never has
        raise InvalidKeyError(
            f"key 'proc/{rest}': index {index} is out of range, split {split!r} has {n} "
            f"instances per category (0..{n - 1})"
        )
    # the process-wide instance, so its generated mesh (~25 ms) is built once per process
    return _cached_procedural(category, int(index), split, cache_root)


class _InstanceLists:
    """``(category, index) -> instance`` over given lists: ``ObjectSet.from_instances``'
    lookup."""

    def __init__(self, instances: dict[str, list[ObjectInstance]]) -> None:
        self.instances = instances

    def __call__(self, category: str, index: int) -> ObjectInstance:
        return self.instances[category][index]


class ObjectSet:
    """One split of an object library.

    ``ObjectSet(split="test")`` is the procedural library (every registered category,
    ``DEFAULT_SPLIT_SIZES[split]`` instances each unless ``per_category`` says otherwise).
    A real dataset's sets come from :meth:`beo_bench.objects.datasets.Dataset.objects` (or
    :func:`~beo_bench.objects.datasets.object_set`, which gives either). ``cache_root``:
    the cache its instances keep their derived data in (None: the environment's).
    """

    def __init__(
        self,
        split: str = "test",
        categories: Sequence[str] | None = None,
        *,
        per_category: int | None = None,
        cache_root: Path | None = None,
    ) -> None:
        self.split = check_split(split)
        names = tuple(categories) if categories is not None else registered_categories()
        for c in names:
            get_category(c)
        n = DEFAULT_SPLIT_SIZES[split] if per_category is None else int(per_category)
        if not 0 < n <= DEFAULT_SPLIT_SIZES[split]:
            # the library's splits have fixed sizes (their keys name an index in the split,
            # which instance_from_key refuses beyond it)
            from beo_bench.errors import UsageError

            raise UsageError(
                f"per_category={per_category} for the library's {split!r} split: it holds "
                f"{DEFAULT_SPLIT_SIZES[split]} instances a class; give 1 to "
                f"{DEFAULT_SPLIT_SIZES[split]} (--per-category)"
            )
        self._counts = {c: n for c in names}
        self._get: Callable[[str, int], ObjectInstance] = functools.partial(
            _cached_procedural, split=split, cache_root=cache_root
        )
        self.source = "procedural"

    @classmethod
    def from_instances(
        cls, split: str, instances: dict[str, list[ObjectInstance]], source: str
    ) -> ObjectSet:
        """A set over given instances (what a dataset's layout builds)."""
        self = cls.__new__(cls)
        self.split = split
        self.source = source
        self._counts = {c: len(v) for c, v in sorted(instances.items())}
        # a picklable lookup (not a lambda), so that an env drawing from a loaded dataset
        # can be pickled for worker processes
        self._get = _InstanceLists(instances)
        return self

    @property
    def categories(self) -> tuple[str, ...]:
        """Category names, sorted."""
        return tuple(self._counts)

    def count(self, category: str) -> int:
        """Instances of ``category`` in this set."""
        self._check_category(category)
        return self._counts[category]

    def get(self, category: str, index: int) -> ObjectInstance:
        """Instance ``index`` of ``category``."""
        n = self.count(category)
        if not 0 <= index < n:
            raise InstanceIndexError(
                f"index {index} is out of range for {category!r} in "
                f"split {self.split!r}: it has {n} instances (0..{n - 1})"
            )
        return self._get(category, index)

    def instances(self, category: str) -> list[ObjectInstance]:
        return [self.get(category, i) for i in range(self.count(category))]

    def __len__(self) -> int:
        return sum(self._counts.values())

    def __iter__(self) -> Iterator[ObjectInstance]:
        for c in self.categories:
            yield from self.instances(c)

    def check(self) -> ObjectSet:
        """Build every instance now (read, repair, centre and scale its mesh), so that a file
        that cannot be used fails here, named, instead of at first use deep in an episode or
        a worker process. Raises the first failure's :class:`~beo_bench.errors.MeshError`
        class with every failure listed; returns the set, for chaining."""
        failures: list[MeshError] = []
        for inst in self:
            try:
                _ = inst.mesh
            except MeshError as e:
                failures.append(e)
        if len(failures) == 1:
            raise failures[0]
        if failures:
            listed = "\n".join(f"  {e}" for e in failures)
            raise type(failures[0])(
                f"{len(failures)} of {len(self)} objects cannot be used:\n{listed}"
            ) from failures[0]
        return self

    def __repr__(self) -> str:
        return (
            f"ObjectSet(split={self.split!r}, source={self.source!r}, "
            f"categories={len(self._counts)}, instances={len(self)})"
        )

    def _check_category(self, category: str) -> None:
        if category not in self._counts:
            raise UnknownCategoryError(
                f"unknown category {category!r} in this set; it has: {', '.join(self.categories)}"
            )


def _cached_procedural(
    category: str, index: int, split: str, cache_root: Path | None = None
) -> ObjectInstance:
    """The process's one instance object of a key and cache, so its built mesh, voxels and
    content hash are shared. Its callers pass the arguments by position or by keyword
    (``ObjectSet``'s partial, ``instance_from_key``), which ``lru_cache`` would key apart:
    two objects, each loading the mesh again; the cached function gets them by position."""
    return _procedural_once(category, int(index), split, cache_root)


@functools.lru_cache(maxsize=1024)
def _procedural_once(
    category: str, index: int, split: str, cache_root: Path | None
) -> ObjectInstance:
    return procedural_instance(category, split, index, cache_root)
