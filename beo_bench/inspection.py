"""The work behind ``beo-bench objects``, ``pick-check`` and ``cache info``, as library
functions with typed parameters that return result dataclasses.

The command handlers and ``beo-bench demo`` call these same functions and print the
results' ``text()``; a notebook or script can call them too and read the fields instead.
(``beo-bench view`` is :func:`beo_bench.sceneview.view_scene`.)
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from beo_bench.envs.pickcheck import PickCheck
    from beo_bench.objects import ObjectSet
    from beo_bench.objects.datasets import Dataset
    from beo_bench.objects.prepare import InstanceStats


def format_bytes(n: float) -> str:
    """``1536`` -> ``1.5 KB`` (binary units, up to GB)."""
    for unit in ("B", "KB", "MB", "GB"):
        if n < 1024 or unit == "GB":
            return f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GB"


# -- objects -----------------------------------------------------------------------------------
def library_table(
    stats: Sequence[InstanceStats], split: str, split_counts: dict[str, str] | None = None
) -> str:
    """A plain-text summary of the object library from per-instance statistics.
    ``split_counts``: per category, its models per split (a user's dataset; default: the
    procedural library's split sizes)."""
    from beo_bench.objects import DEFAULT_SPLIT_SIZES, categories, get_category

    registered = categories()
    by_cat: dict[str, list[InstanceStats]] = {}
    for s in stats:
        by_cat.setdefault(s.category, []).append(s)
    splits = "train/val/test" if split_counts is not None else "train/val/test/ood"
    w = max([10, *(len(c) for c in by_cat)])  # a dataset's class names may be long
    head = (
        f"{'category':<{w}} {splits:>18} {'params':>6} {'pick':>4}  "
        f"{'symmetry (' + split + ' split)':<52} {'largest extent cm':>17} "
        f"{'parts':>5} {'gen ms':>6} {'proc ms':>7}"
    )
    lines = [head, "-" * len(head)]
    sizes = "/".join(str(DEFAULT_SPLIT_SIZES[k]) for k in ("train", "val", "test", "ood"))
    for cat, ss in sorted(by_cat.items()):
        spec = get_category(cat) if cat in registered else None
        labels, counts = np.unique([s.symmetry for s in ss], return_counts=True)
        order = np.argsort(-counts)
        sym = ", ".join(f"{labels[i]} {100 * counts[i] / len(ss):.0f}%" for i in order)
        ext = np.array([max(s.extents) for s in ss]) * 100
        per_split = split_counts.get(cat, "") if split_counts is not None else sizes
        lines.append(
            f"{cat:<{w}} {per_split:>18} {len(spec.params) if spec else 0:>6} "
            f"{'yes' if spec is None or spec.pickable else 'no':>4}  {sym:<52} "
            f"{f'{ext.min():.1f}-{ext.max():.1f}':>17} "
            f"{np.mean([s.parts for s in ss]):>5.0f} "
            f"{1000 * np.median([s.generate_s for s in ss]):>6.1f} "
            f"{1000 * np.median([s.process_s for s in ss]):>7.1f}"
        )
    return "\n".join(lines)


@dataclass(frozen=True)
class ObjectsReport:
    """What :func:`summarise_objects` processed and measured."""

    stats: tuple[InstanceStats, ...]
    split: str
    split_counts: dict[str, str] | None
    """Per category, its models per split (a user's dataset); None: the built-in library."""
    wall_s: float
    workers: int
    resolution: int
    sheet: Path | None
    """The contact sheet written, if one was asked for."""

    def text(self) -> str:
        """The table, the throughput line and the contact sheet's path."""
        n = len(self.stats)
        lines = [
            library_table(self.stats, self.split, self.split_counts),
            "",
            f"{n} instances processed in {self.wall_s:.1f} s with {self.workers} workers "
            f"({n / max(self.wall_s, 1e-9):.1f} instances/s; voxels {self.resolution}^3, "
            "surface samples, collision parts)",
        ]
        if self.sheet is not None:
            lines.append(f"contact sheet: {self.sheet}")
        return "\n".join(lines)


def select_objects(
    split: str = "test",
    categories: Sequence[str] | None = None,
    per_category: int | None = None,
    dataset: Dataset | None = None,
    root: str | Path | None = None,
) -> tuple[ObjectSet, dict[str, str] | None]:
    """The object set to summarise (the built-in library, a mesh folder ``root``, or a
    user's ``dataset``) and, for a dataset, per category its models per split."""
    from beo_bench.objects.datasets import object_set, open_dataset

    if dataset is None:
        folder = open_dataset(root) if root is not None else None
        return object_set(folder, split, categories, per_category), None
    objects = dataset.objects(split, categories, per_category)
    per_split = [dataset.objects(s, objects.categories) for s in ("train", "val", "test")]
    counts = {c: "/".join(str(o.count(c)) for o in per_split) for c in objects.categories}
    return objects, counts


def summarise_objects(
    objects: ObjectSet,
    split: str,
    *,
    resolution: int = 32,
    workers: int = 2,
    sheet: Path | None = None,
    sheet_per_category: int = 6,
    split_counts: dict[str, str] | None = None,
) -> ObjectsReport:
    """Process every instance of ``objects`` (meshes, ``resolution``^3 voxels, surface
    samples, collision parts; cached) with ``workers`` processes, and draw a contact sheet
    of ``sheet_per_category`` instances a category to ``sheet`` when given."""
    from beo_bench.objects.prepare import prepare
    from beo_bench.objects.sheet import contact_sheet

    t0 = time.perf_counter()
    stats = prepare(objects, D=resolution, workers=workers)
    wall = time.perf_counter() - t0
    written = None
    if sheet is not None:
        written = contact_sheet(sheet, objects, per_category=sheet_per_category)
    return ObjectsReport(tuple(stats), split, split_counts, wall, workers, resolution, written)


# -- pick-check --------------------------------------------------------------------------------
@dataclass(frozen=True)
class PickCheckReport:
    """The ground-truth planner's pick rate over consecutive seeds."""

    result: PickCheck
    split: str
    seed: int
    episodes: int
    wall_s: float

    def text(self) -> str:
        """A header naming the seeds, the per-category table and the failure reasons."""
        reasons = ", ".join(f"{k} {v}" for k, v in sorted(self.result.failure_reasons().items()))
        per = 1000 * self.wall_s / max(self.episodes, 1)
        return (
            f"BEOPick-v0, split {self.split}, seeds {self.seed}..{self.seed + self.episodes - 1}: "
            "the ground-truth planner's best grasp of the target, executed once\n\n"
            f"{self.result.table()}\n\n"
            f"failures: {reasons or 'none'}; {self.wall_s:.0f} s ({per:.0f} ms per episode)"
        )


def pick_check(
    episodes: int = 100, seed: int = 0, split: str = "test", progress: bool = True
) -> PickCheckReport:
    """Run BEOPick-v0 episodes ``seed, seed + 1, ...`` with the ground-truth planner's best
    grasp (:func:`beo_bench.envs.pickcheck.ground_truth_pick_check`), timed."""
    from beo_bench.envs.pickcheck import ground_truth_pick_check

    t0 = time.perf_counter()
    r = ground_truth_pick_check(episodes=episodes, seed=seed, progress=progress, split=split)
    return PickCheckReport(r, split, seed, episodes, time.perf_counter() - t0)


# -- cache info --------------------------------------------------------------------------------
@dataclass(frozen=True)
class CacheKindInfo:
    """One kind of cache entry (:data:`beo_bench.objects.cache.KINDS`) on disk."""

    kind: str
    entries: int
    bytes: int


@dataclass(frozen=True)
class CacheReport:
    """The asset cache: where it is, what each kind holds, and the trained models."""

    root: Path
    bytes: int
    kinds: tuple[CacheKindInfo, ...]
    models: tuple[tuple[str, str], ...]
    """(``KIND/NAME``, content digest or why the model is unusable), sorted."""

    def text(self) -> str:
        lines = [f"cache: {self.root} ({format_bytes(self.bytes)})"]
        lines += [
            f"  {k.kind:<10} {k.entries:>7} entries  {format_bytes(k.bytes):>10}"
            for k in self.kinds
        ]
        if self.models:
            lines.append("models (content digest):")
        lines += [f"  {name}  {digest}" for name, digest in self.models]
        return "\n".join(lines)


def cache_report() -> CacheReport:
    """Entry counts and sizes per kind, and each trained model with its content digest
    (equal digests: bitwise-equal models)."""
    from beo_bench.errors import CheckpointError
    from beo_bench.objects import cache
    from beo_bench.perception.digest import model_digest

    info = cache.info()
    kinds = tuple(
        CacheKindInfo(kind, int(k["entries"]), int(k["bytes"])) for kind, k in info["kinds"].items()
    )
    root = cache.cache_root() / "models"
    # hidden siblings are a save in progress (.NAME.*.tmp) or a replaced model (.old)
    dirs = (
        sorted(d for d in root.glob("*/*") if d.is_dir() and not d.name.startswith("."))
        if root.exists()
        else []
    )
    models = []
    for d in dirs:
        try:
            digest = model_digest(d)
        except CheckpointError as e:
            digest = f"unusable: {e}"
        models.append((f"{d.parent.name}/{d.name}", digest))
    return CacheReport(Path(info["root"]), int(info["bytes"]), kinds, tuple(models))


# -- campaigns (``beo-bench all`` and the demo) ------------------------------------------------
def every_backend() -> list[str]:
    """Every registered backend (in-tree and plugins), bounds included; diagnostic tools
    that wrap another backend (``swap``) are run by name only."""
    from beo_bench.backend import list_backends, load_plugins

    load_plugins()
    return list_backends(diagnostic=False)


def leaderboard_text(written: Sequence[Path], where: Path) -> str:
    """The suite tables of a regenerated leaderboard (without their plots), then where the
    leaderboard is."""
    tables = [p.read_text().split("\n![")[0] for p in written]
    where_line = f"leaderboards: {where}/ (plots and per-category tables beside the summaries)"
    return "\n".join(["", *tables, where_line])
