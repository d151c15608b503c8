"""The ``beo-bench`` command.

Exit status: 0 on success, 1 on a failure (a run that cannot finish, a corrupt model, a
full or read-only disk), 2 on a usage error (an argument, option or setting out of range),
130 when interrupted. An error is one line on stderr, ``beo-bench: error: ...``, saying what
was wrong and what to do; no traceback.
"""

from __future__ import annotations

import argparse
import errno
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench.bench.columns import brief_columns
from beo_bench.errors import BeoBenchError, UsageError

if TYPE_CHECKING:
    from beo_bench.perception.hbeo_train import HBEOConfig, Kind


# -- argument types: an out-of-range number is a usage error (exit 2) before anything runs --
def bounded_int(lo: int, hi: int | None = None, why: str = "") -> Callable[[str], int]:
    """An argparse ``type`` accepting whole numbers in ``lo..hi`` (no upper bound when
    ``hi`` is None); ``why`` ends the message when a value is refused."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if value < lo or (hi is not None and value > hi):
            wanted = f">= {lo}" if hi is None else f"from {lo} to {hi}"
            wanted = f"a whole number {wanted}"
            raise argparse.ArgumentTypeError(f"{value} is out of range: give {wanted}{why}")
        return value

    parse.__name__ = "int"  # argparse names the type in some of its messages
    return parse


positive_int = bounded_int(1)
nonneg_int = bounded_int(0)
seed_int = bounded_int(0, why=" (numpy seeds are non-negative)")
# Voxel grids hold D^3 cells per instance (and training stacks thousands of them): 128^3
# is 2 M cells, 8 MB per float32 grid; beyond it memory, not the method, is the limit. Below
# 8 cells per edge a shape is no longer recognisable.
resolution_int = bounded_int(8, 128, why=" voxels per edge (memory grows as D^3)")


def _image_side(text: str) -> int:
    from beo_bench.scenes.camera import MAX_IMAGE_SIDE

    return bounded_int(1, MAX_IMAGE_SIDE, why=" pixels (the off-screen GL buffer's limit)")(text)


def positive_float(text: str) -> float:
    """An argparse ``type``: a finite number > 0 (``nan`` and ``inf`` refused)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"{text} is out of range: give a number > 0")
    return value


def fraction(text: str) -> float:
    """An argparse ``type``: a number in (0, 1]."""
    value = positive_float(text)
    if value > 1:
        raise argparse.ArgumentTypeError(f"{text} is out of range: give a number in (0, 1]")
    return value


def key_value(text: str) -> str:
    """An argparse ``type`` for ``--opt``: ``KEY=VALUE`` with a non-empty key."""
    if "=" not in text or not text.split("=", 1)[0].strip():
        raise argparse.ArgumentTypeError(f"{text!r}: use KEY=VALUE (e.g. samples=25)")
    return text


def backend_spec(text: str) -> str:
    """An argparse ``type`` for ``all --backends``: ``NAME`` or ``NAME:K=V,K=V``."""
    name, _, opts = text.partition(":")
    if not name:
        raise argparse.ArgumentTypeError(f"{text!r}: give NAME or NAME:KEY=VALUE,...")
    for pair in (o for o in opts.split(",") if o):
        try:
            key_value(pair)
        except argparse.ArgumentTypeError as e:
            raise argparse.ArgumentTypeError(f"backend {text!r}: option {e}") from None
    return text


def model_name(text: str) -> str:
    """An argparse ``type`` for ``train --name``: a plain name, never a path (the model is
    stored under the cache's models directory, and training may replace a checkpoint
    there)."""
    from beo_bench.errors import InvalidNameError
    from beo_bench.names import check_name

    try:
        return check_name(text, "model name")
    except InvalidNameError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def size_option(text: str) -> float | str:
    """An argparse ``type`` for ``--size``: metres (a number > 0) or ``native``."""
    return "native" if text == "native" else positive_float(text)


def dataset_parent(size_flags: tuple[str, ...] = ("--size", "--object-size")) -> Any:
    """The options that point a command at a user's dataset (``--objects`` and how its
    files are loaded), shared by every command that reads objects. ``size_flags``: the
    spellings of the object-size option (``train`` has its own ``--size``, the network's,
    so there it is ``--object-size`` only)."""
    from beo_bench.objects.loaders import DEFAULT_REPAIR, REPAIR_MODES

    p = argparse.ArgumentParser(add_help=False)
    g = p.add_argument_group("your own dataset")
    g.add_argument(
        "--objects",
        metavar="ROOT",
        default=None,
        help="a dataset instead of the built-in library: ShapeNetCore.v2, ModelNet10/40 or "
        "a folder with one sub-folder of meshes per category (the layout is detected)",
    )
    g.add_argument(
        "--repair",
        choices=list(REPAIR_MODES),
        default=DEFAULT_REPAIR,
        help="with --objects: how meshes are made watertight (default solid: a clean-up, "
        "and a watertight rebuild of what stays open; basic: the clean-up only)",
    )
    g.add_argument(
        "--up",
        default="z",
        help="with --objects (folders): the files' up axis, e.g. y or -z (default z)",
    )
    g.add_argument(
        *size_flags,
        dest="object_size",
        type=size_option,
        default=None,
        metavar="M|native",
        help="with --objects: largest extent in metres, or native (the files' units); "
        "default: the category's size",
    )
    return p


SPLITS_ALL = ["train", "val", "test", "all"]
"""Splits of a user's dataset (``all``: every model, whatever its hash split)."""


def _dataset(args: argparse.Namespace) -> Any:
    """The :class:`~beo_bench.objects.dataset.Dataset` that ``--objects`` names (None
    without it; loading options given without it are a usage error)."""
    from beo_bench.objects.loaders import DEFAULT_REPAIR

    root = getattr(args, "objects", None)
    if root is None:
        given = [
            f"--{k}"
            for k, default in (("repair", DEFAULT_REPAIR), ("up", "z"), ("object-size", None))
            if getattr(args, k.replace("-", "_"), default) != default
        ]
        if given or getattr(args, "split", None) == "all":
            given += ["--split all"] if getattr(args, "split", None) == "all" else []
            raise UsageError(f"{', '.join(given)} apply to a user dataset only: add --objects ROOT")
        return None
    from beo_bench.objects.dataset import open_dataset

    return open_dataset(root, repair=args.repair, up=args.up, size=args.object_size)


def _fmt_bytes(n: float) -> str:
    for unit in ("B", "KB", "MB", "GB"):
        if n < 1024 or unit == "GB":
            return f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GB"


def library_table(stats: list, split: str, split_counts: dict[str, str] | None = None) -> str:
    """A plain-text summary of the object library from per-instance statistics.
    ``split_counts``: per category, its models per split (a user's dataset; default: the
    procedural library's split sizes)."""
    from beo_bench.objects import DEFAULT_SPLIT_SIZES, get_category

    by_cat: dict[str, list] = {}
    for s in stats:
        by_cat.setdefault(s.category, []).append(s)
    splits = "train/val/test" if split_counts is not None else "train/val/test/ood"
    head = (
        f"{'category':<10} {splits:>18} {'params':>6} {'pick':>4}  "
        f"{'symmetry (' + split + ' split)':<52} {'largest extent cm':>17} "
        f"{'parts':>5} {'gen ms':>6} {'proc ms':>7}"
    )
    lines = [head, "-" * len(head)]
    sizes = "/".join(str(DEFAULT_SPLIT_SIZES[k]) for k in ("train", "val", "test", "ood"))
    for cat, ss in sorted(by_cat.items()):
        spec = get_category(cat) if cat in _registered() else None
        labels, counts = np.unique([s.symmetry for s in ss], return_counts=True)
        order = np.argsort(-counts)
        sym = ", ".join(f"{labels[i]} {100 * counts[i] / len(ss):.0f}%" for i in order)
        ext = np.array([max(s.extents) for s in ss]) * 100
        counts = split_counts.get(cat, "") if split_counts is not None else sizes
        lines.append(
            f"{cat:<10} {counts:>18} {len(spec.params) if spec else 0:>6} "
            f"{'yes' if spec is None or spec.pickable else 'no':>4}  {sym:<52} "
            f"{f'{ext.min():.1f}-{ext.max():.1f}':>17} "
            f"{np.mean([s.parts for s in ss]):>5.0f} "
            f"{1000 * np.median([s.generate_s for s in ss]):>6.1f} "
            f"{1000 * np.median([s.process_s for s in ss]):>7.1f}"
        )
    return "\n".join(lines)


def _registered() -> tuple[str, ...]:
    from beo_bench.objects import categories

    return categories()


def cmd_objects(args: argparse.Namespace) -> int:
    from beo_bench.objects import ObjectSet
    from beo_bench.objects.prepare import prepare
    from beo_bench.objects.sheet import contact_sheet

    dataset = _dataset(args)
    if dataset is not None and args.root is not None:
        raise UsageError("give the dataset once: --objects ROOT (--root is its older spelling)")
    split_counts = None
    if dataset is not None:
        objects = dataset.objects(args.split, args.categories, args.per_category)
        print(f"dataset {dataset.root}: {dataset.layout} layout, digest {dataset.digest}")
        per_split = [dataset.objects(s, objects.categories) for s in ("train", "val", "test")]
        split_counts = {c: "/".join(str(o.count(c)) for o in per_split) for c in objects.categories}
    else:
        objects = ObjectSet(
            args.split, args.categories, root=args.root, per_category=args.per_category
        )
    t0 = time.perf_counter()
    stats = prepare(objects, D=args.resolution, workers=args.workers)
    wall = time.perf_counter() - t0
    print()
    print(library_table(stats, args.split, split_counts))
    print(
        f"\n{len(stats)} instances processed in {wall:.1f} s with {args.workers} "
        f"workers ({len(stats) / wall:.1f} instances/s; voxels {args.resolution}^3, "
        f"surface samples, collision parts)"
    )
    if args.sheet:
        path = contact_sheet(args.sheet, objects, per_category=6)
        print(f"contact sheet: {path}")
    return 0


def cmd_cache(args: argparse.Namespace) -> int:
    from beo_bench.objects import cache

    if args.action == "clear":
        freed = cache.clear(args.kind)
        print(f"cleared {_fmt_bytes(freed)} from {cache.cache_root()}")
        return 0
    info = cache.info()
    print(f"cache: {info['root']} ({_fmt_bytes(info['bytes'])})")
    for kind, k in info["kinds"].items():
        print(f"  {kind:<10} {k['entries']:>7} entries  {_fmt_bytes(k['bytes']):>10}")
    _print_models(cache.cache_root() / "models")
    return 0


def _print_models(root: Path) -> None:
    """Each trained model with its content digest (equal digests: bitwise-equal models)."""
    from beo_bench.errors import CheckpointError
    from beo_bench.perception.digest import model_digest

    # hidden siblings are a save in progress (.NAME.*.tmp) or a replaced model (.old)
    dirs = (
        sorted(d for d in root.glob("*/*") if d.is_dir() and not d.name.startswith("."))
        if root.exists()
        else []
    )
    if dirs:
        print("models (content digest):")
    for d in dirs:
        try:
            digest = model_digest(d)
        except CheckpointError as e:
            digest = f"unusable: {e}"
        print(f"  {d.parent.name}/{d.name}  {digest}")


def cmd_view(args: argparse.Namespace) -> int:
    from beo_bench.view import view_scene

    kwargs: dict[str, Any] = {"split": args.split, "image_size": tuple(args.image_size)}
    dataset = _dataset(args)
    if dataset is not None:
        kwargs["objects"] = objects = dataset.objects(args.split)
        # scenes hold distinct classes: a small dataset caps the default 1-4
        kwargs["num_objects"] = (1, min(4, len(objects.categories)))
    if args.num_objects is not None:
        kwargs["num_objects"] = args.num_objects
    r = view_scene(args.seed, args.out, rrd=not args.no_rrd, **kwargs)
    print(
        f"seed {args.seed}: objects {', '.join(r.objects)}; target {r.target}; "
        f"{r.grasps} ground-truth grasps of the target"
    )
    print(f"image:     {r.png}")
    if r.rrd is not None:
        print(f"recording: {r.rrd}  (open with `rerun {r.rrd}`)")
    return 0


def cmd_pick_check(args: argparse.Namespace) -> int:
    from beo_bench.envs.pickcheck import ground_truth_pick_check

    t0 = time.perf_counter()
    r = ground_truth_pick_check(
        episodes=args.episodes, seed=args.seed, progress=True, split=args.split
    )
    wall = time.perf_counter() - t0
    print(
        f"\nBEOPick-v0, split {args.split}, seeds {args.seed}..{args.seed + args.episodes - 1}: "
        "the ground-truth planner's best grasp of the target, executed once\n"
    )
    print(r.table())
    reasons = ", ".join(f"{k} {v}" for k, v in sorted(r.failure_reasons().items()))
    per = 1000 * wall / max(args.episodes, 1)
    print(f"\nfailures: {reasons or 'none'}; {wall:.0f} s ({per:.0f} ms per episode)")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from beo_bench.backend import get_backend, load_plugins
    from beo_bench.bench.campaign import parse_options, run_name
    from beo_bench.bench.runner import RunConfig, run
    from beo_bench.bench.suites import check_track

    load_plugins()
    suite = _suite(args.suite).with_overrides(
        size=args.episodes, seed=args.seed, track=args.track
    )  # --track on a suite without tracks is a usage error here
    dataset = _dataset(args)
    _split_needs_dataset(args, dataset)
    if dataset is not None:
        suite = suite.with_dataset(dataset, args.split)
    kwargs = parse_options(args.opt)
    backend = get_backend(args.backend, **kwargs)  # fail here, not in a worker
    check_track(
        suite,
        args.backend,
        bool(getattr(backend, "wants_class_hint", False)),
        bool(getattr(backend, "needs_class_hint", False)),
    )
    name = run_name(suite.name, args.backend, kwargs, args.seed, suite.track)
    out = Path(args.out) if args.out else Path("runs") / name
    summary = run(
        RunConfig(suite, args.backend, kwargs),
        out,
        workers=args.workers,
        resume=args.resume,
        use_ray=args.ray,
        **_timeout(args),
    )
    print(format_runs([summary]))
    print(f"\nresults: {out / 'results.jsonl'}\nsummary: {out / 'summary.json'}")
    if args.rerun:
        from beo_bench.bench.recording import log_run

        path = log_run(RunConfig(suite, args.backend, kwargs), args.rerun)
        print(f"recording of the first views: {path}  (open with `rerun {path}`)")
    return 0


def _split_needs_dataset(args: argparse.Namespace, dataset: Any) -> None:
    """``--split`` replaces the suites' split on a user's dataset only (a built-in suite's
    split is part of its definition)."""
    if args.split is not None and dataset is None:
        raise UsageError(
            f"--split {args.split} applies to a user dataset only (add --objects ROOT); the "
            "built-in suites fix their split"
        )


def dataset_suites() -> list[str]:
    """The suites ``all --objects`` runs by default: the isolated ones that draw from every
    class of a split (not a fixed class subset, not the procedural ``ood`` split)."""
    from beo_bench.bench.suites import SUITES

    return [
        n
        for n, s in sorted(SUITES.items())
        if s.kind == "isolated" and s.categories is None and s.split != "ood"
    ]


def _suite(name: str) -> Any:
    """The suite ``name``; an unknown name is a usage error (exit 2), listing the suites."""
    from beo_bench.bench.suites import UnknownSuiteError, get_suite

    try:
        return get_suite(name)
    except UnknownSuiteError as e:
        raise UsageError(str(e)) from e


def _timeout(args: argparse.Namespace) -> dict[str, float]:
    """``item_timeout`` for the runner, only when ``--item-timeout`` was given (otherwise
    the runner's own default holds)."""
    return {} if args.item_timeout is None else {"item_timeout": args.item_timeout}


COLUMNS = brief_columns()
"""The plain-text table's metric columns (``bench.columns``: one list for every table)."""


def format_runs(summaries: list[dict]) -> str:
    """A plain table of runs: one row per run (its suite and track, backend and options),
    the columns that any of them measured."""
    from beo_bench.bench.campaign import backend_label
    from beo_bench.bench.compare import track_of

    def where(s: dict) -> str:
        track = track_of(s)
        return f"{s['suite']}@{track}" if track else str(s["suite"])

    def who(s: dict) -> str:
        return backend_label(s["backend"], s.get("provenance", {}).get("backend_kwargs") or {})

    cols = [c for c in COLUMNS if any(c.key in s["metrics"] for s in summaries)]
    w_suite = max([len("suite"), *(len(where(s)) for s in summaries)])
    w_backend = max([len("backend"), *(len(who(s)) for s in summaries)])
    head = f"{'suite':<{w_suite}} {'backend':<{w_backend}} {'n':>5} {'fail':>4} " + " ".join(
        f"{c.short:>9}" for c in cols
    )
    lines = [head, "-" * len(head)]
    for s in summaries:
        cells = [f"{c.format(s['metrics'].get(c.key)):>9}" for c in cols]
        lines.append(
            f"{where(s):<{w_suite}} {who(s):<{w_backend}} {s['n']:>5} {s['failures']:>4} "
            + " ".join(cells)
        )
    return "\n".join(lines)


def cmd_compare(args: argparse.Namespace) -> int:
    """The runs' table; then, unless ``--table``, each run paired with the first on the
    items both scored (B - A with a bootstrap interval over items, and a verdict)."""
    from beo_bench.bench import compare

    loaded = [compare.load_summary(p) for p in args.runs]
    if args.table or len(loaded) < 2:
        print(format_runs([s for _, s in loaded]))
        return 0
    (a_dir, a_sum), rest = loaded[0], loaded[1:]
    for b_dir, b_sum in rest:  # refuse before printing anything
        compare.check_comparable(a_sum, b_sum, f"{a_dir} and {b_dir}")
    first = compare.run_from(a_dir, a_sum)
    others = [compare.run_from(d, s) for d, s in rest]
    print(format_runs([s for _, s in loaded]))
    for b in others:
        print()
        print(compare.format_paired(first, b, compare.paired_runs(first, b)))
    return 0


def cmd_leaderboard(args: argparse.Namespace) -> int:
    from beo_bench.bench.leaderboard import regenerate

    written = regenerate(args.runs, args.out)
    if not written:
        raise BeoBenchError(f"no summary.json under {args.runs}: run `beo-bench run` first")
    for p in written:
        print(p.read_text())
    print(f"wrote {len(written)} suite tables to {args.out}/")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from beo_bench.bench.runner import default_workers

    out = Path(args.out)
    workers = args.workers or default_workers()
    print("beo-bench demo: the object library (test split)\n")
    ns = argparse.Namespace(
        split="test",
        categories=None,
        root=None,
        per_category=args.per_category,
        resolution=32,
        workers=workers,
        sheet=out / "objects.png",
    )
    cmd_objects(ns)
    print("\nbeo-bench demo: one BEOPick-v0 scene\n")
    cmd_view(
        argparse.Namespace(
            seed=0, out=out, split="test", image_size=[640, 480], num_objects=None, no_rrd=False
        )
    )
    print("\nbeo-bench demo: the ground-truth grasp ceiling on 20 episodes\n")
    cmd_pick_check(argparse.Namespace(episodes=20, seed=0, split="test"))
    demo_suites(out, workers)
    return cmd_cache(argparse.Namespace(action="info", kind=None))


DEMO_SIZES = {"known-pose": 44, "pose-1dof": 44, "pose-3dof": 44, "tabletop": 6, "pick": 10}
"""Items per suite in ``make demo`` (a multiple of the 11 categories for isolated suites)."""


def _default_backends() -> list[str]:
    """Every registered backend (in-tree and plugins), bounds included; diagnostic tools
    that wrap another backend (``swap``) are run by name only."""
    from beo_bench.backend import list_backends, load_plugins

    load_plugins()
    return list_backends(diagnostic=False)


def _print_leaderboard(written: list[Path], where: Path) -> None:
    print()
    for p in written:
        print(p.read_text().split("\n![")[0])
    print(f"leaderboards: {where}/ (plots and per-category tables beside the summaries)")


def demo_suites(out: Path, workers: int | None) -> None:
    """Every suite, shortened, with every registered backend; then the leaderboard.
    Re-running resumes the finished runs (nothing is recomputed)."""
    from beo_bench.bench.campaign import Campaign, run_campaign

    backends = _default_backends()
    print(f"\nbeo-bench demo: short suites with {', '.join(backends)}\n")
    c = Campaign(
        dict(DEMO_SIZES),
        [(b, {}) for b in backends],
        runs=out / "runs",
        leaderboards=out / "leaderboards",
        workers=workers,
    )
    _print_leaderboard(run_campaign(c), c.leaderboards)


def cmd_all(args: argparse.Namespace) -> int:
    from beo_bench.bench.campaign import Campaign, parse_backend_spec, run_campaign
    from beo_bench.bench.suites import list_suites

    dataset = _dataset(args)
    _split_needs_dataset(args, dataset)
    suites = args.suites or (list_suites() if dataset is None else dataset_suites())
    for s in suites:
        suite = _suite(s)  # an unknown name fails before any run starts
        if dataset is not None:
            suite.with_dataset(dataset, args.split)  # so does a scene suite on a dataset
    specs = args.backends or _default_backends()
    c = Campaign(
        {s: args.episodes for s in suites},
        [parse_backend_spec(b) for b in specs],
        runs=Path(args.runs),
        leaderboards=Path(args.out),
        workers=args.workers,
        use_ray=args.ray,
        seed=args.seed,
        dataset=dataset,
        split=args.split,
        **_timeout(args),
    )
    _print_leaderboard(run_campaign(c), c.leaderboards)
    return 0


def _categories(args: argparse.Namespace) -> tuple[str, ...]:
    from beo_bench.envs.pick import default_categories
    from beo_bench.objects import registry

    cats = tuple(args.categories) if args.categories else default_categories()
    for c in cats:
        registry.get_category(c)  # an unknown name raises, listing the known ones
    return cats


def _dataset_categories(args: argparse.Namespace, dataset: Any, split: str) -> tuple[str, ...]:
    """The classes to train on a user's dataset: ``--categories`` (each must be in it) or
    every class of the dataset (the class list its suites' views carry); each needs models
    in ``split``."""
    objects = dataset.objects(split, args.categories or dataset.categories(), args.per_category)
    empty = [c for c in objects.categories if objects.count(c) == 0]
    if empty or not objects.categories:
        raise UsageError(
            f"the {split!r} split of {dataset.root} has no models of "
            f"{', '.join(empty) or 'any class'}: use --split all (every model), or add files"
        )
    return objects.categories


def cmd_train(args: argparse.Namespace) -> int:
    """Train a model and store it under its name (the default name is the one the backend
    looks for, so training it ahead of time only saves the first run the wait)."""
    if args.model != "beo":
        return _train_hbeo(args)
    from beo_bench.perception.beo_model import BEOConfig, default_name, model_path, train_beo

    dataset = _dataset(args)
    _split_needs_dataset(args, dataset)
    split = args.split or "train"
    cats = _categories(args) if dataset is None else _dataset_categories(args, dataset, split)
    cfg = BEOConfig(
        categories=cats,
        resolution=args.resolution,
        per_category=args.per_category,
        variance_fraction=args.variance_fraction,
    )
    name = args.name or default_name(cats, args.resolution, args.per_category, dataset)
    t0 = time.perf_counter()
    model = train_beo(cfg, progress=True, dataset=dataset, split=split)
    path = model.save(model_path(name))
    print(
        f"BEO model {name!r}: {len(cats)} classes at {args.resolution}^3, subspace k={model.k} "
        f"(per class {dict(zip(cats, model.components.tolist(), strict=True))}), "
        f"trained in {time.perf_counter() - t0:.1f} s -> {path}"
    )
    return 0


def _hbeo_config(args: argparse.Namespace, kind: Kind) -> HBEOConfig:
    """The HBEO training set-up the options describe; with ``--objects``, rendered from
    that dataset (made this process's active one, so the BEO subspace it regresses is the
    dataset's: ``beo-bench train beo --objects ROOT`` first)."""
    from beo_bench.objects.dataset import activate
    from beo_bench.perception.hbeo_train import default_config, with_overrides

    dataset = _dataset(args)
    _split_needs_dataset(args, dataset)
    activate(dataset)
    split = args.split or "train"
    cats = _categories(args) if dataset is None else _dataset_categories(args, dataset, split)
    # a folder too small for a hash split validates on what it trains on (--split all)
    splits = {} if dataset is None else {"split": split, "val_split": split}
    if dataset is not None and split == "train":
        splits["val_split"] = "val"
    base = default_config(
        kind,
        cats,
        instances=args.per_category,
        images=args.images,
        epochs=getattr(args, "epochs", None),
        recipe=getattr(args, "recipe", None) or "default",
    )
    return with_overrides(
        base,
        val_images=args.val_images,
        seed=args.seed,
        crop=getattr(args, "crop", None),
        size=getattr(args, "size", None),
        rotation=getattr(args, "rotation", None),
        batch_size=getattr(args, "batch_size", None),
        projection_weighting=getattr(args, "projection_weighting", None),
        **splits,
    )


def _train_hbeo(args: argparse.Namespace) -> int:
    from beo_bench.perception.hbeo_train import default_name, model_path, train_hbeo

    cfg = _hbeo_config(args, args.model)
    name = args.name or default_name(cfg)
    path = model_path(name)
    t0 = time.perf_counter()
    model = train_hbeo(
        cfg, path, progress=True, workers=args.workers, resume=args.resume, device=args.device
    )
    last = model.info["history"][model.info["epoch_kept"] - 1]
    speed = model.info["render_images_per_s"]
    rendered = f"rendered at {speed:.0f} images/s" if speed else "rendering cached"
    print(
        f"{args.model} model {name!r}: {model.info['train_images']} crops ({rendered}), "
        f"{len(model.info['history'])} epochs in {time.perf_counter() - t0:.1f} s "
        f"(kept epoch {model.info['epoch_kept']}, on {model.info['device']}); "
        f"validation: class accuracy {last.get('val_class_acc', float('nan')):.1%}, "
        f"rotation median {last.get('val_rot_err_median', float('nan')):.1f} deg -> {path}"
    )
    return 0


def cmd_publish(args: argparse.Namespace) -> int:
    """Write a trained model as a published one (compact, pickle-free, digests in the
    manifest): what the backends load by default."""
    from beo_bench.perception import published

    out = Path(args.out) if args.out else published.PUBLISHED_DIR
    if args.model == "beo":
        from beo_bench.perception.beo_model import BEOModel, model_dir

        cats = _categories(args)
        path = model_dir(args.name, cats, 32) if args.name else model_dir(None, cats, 32)
        sha = published.publish_beo(BEOModel.load(path), out)
    else:
        from beo_bench.perception.hbeo_train import HBEOModel, model_path

        if args.name is None:
            raise UsageError(f"publish {args.model} needs --name (the trained model's name)")
        model = HBEOModel.load(model_path(args.name))
        if model.config.kind != args.model:
            raise UsageError(f"{args.name!r} is a {model.config.kind} model, not {args.model}")
        sha = published.publish_hbeo(model, out, half=not args.float32)
    print(f"published {args.model} -> {out} (SHA-256 {sha})")
    for name, size, digest in published.files_table(out):
        print(f"  {name:<16} {size / 1e6:6.2f} MB  {digest}")
    return 0


def cmd_render_dataset(args: argparse.Namespace) -> int:
    """Render (or complete) HBEO's training set and report its rendering speed."""
    from beo_bench.perception.hbeo_data import render_dataset

    cfg = _hbeo_config(args, "hbeo").dataset
    root, st = render_dataset(cfg, workers=args.workers, progress=True)
    if st["images"]:
        repaired = int(st.get("repaired", 0))
        print(
            f"rendered {st['images']:.0f} crops in {st['seconds']:.1f} s "
            f"({st['images_per_s']:.0f} images/s)"
            + (f", {repaired} damaged shards among them re-rendered" if repaired else "")
            + f" -> {root}"
        )
    else:
        print(f"all {cfg.images} + {cfg.val_images} crops already rendered -> {root}")
    return 0


def _dataset_args(g: Any) -> None:
    g.add_argument("--images", type=positive_int, default=None, help="training crops")
    g.add_argument(
        "--val-images", type=nonneg_int, default=None, help="validation crops (val split)"
    )
    g.add_argument("--seed", type=seed_int, default=None, help="seeds rendering and training")
    g.add_argument(
        "--workers", type=positive_int, default=None, help="render processes (default: cores)"
    )


def _item_timeout_arg(g: Any) -> None:
    g.add_argument(
        "--item-timeout",
        type=positive_float,
        default=None,
        metavar="S",
        help="seconds one item may take before it is recorded as failed (default: the runner's)",
    )


def build_parser() -> argparse.ArgumentParser:
    import beo_bench
    from beo_bench.bench.suites import TRACKS

    p = argparse.ArgumentParser(
        prog="beo-bench",
        description="Benchmark object-centric perception (class, pose and full 3D shape from\n"
        "one segmented depth image) in simulation, and the grasps planned from it.",
        epilog=__doc__.split("\n\n", 1)[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"beo-bench {beo_bench.__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    d = sub.add_parser("demo", help="the main job on the embedded defaults")
    d.add_argument("--out", default="out/demo", help="where images and results go")
    d.add_argument(
        "--per-category",
        type=positive_int,
        default=20,
        help="test-split instances per category to process and summarise",
    )
    d.add_argument("--workers", type=positive_int, default=None, help="default: one per core")
    d.set_defaults(func=cmd_demo)

    o = sub.add_parser(
        "objects", help="process and summarise an object set", parents=[dataset_parent()]
    )
    o.add_argument(
        "--split",
        default="test",
        choices=["train", "val", "test", "ood", "all"],
        help="all: every model of a --objects dataset",
    )
    o.add_argument("--categories", nargs="+", default=None)
    o.add_argument(
        "--root", default=None, help="a ShapeNetCore v2, ModelNet or per-category mesh folder"
    )
    o.add_argument(
        "--per-category",
        type=positive_int,
        default=None,
        help="instances per category (default: the split's size)",
    )
    o.add_argument(
        "--resolution", type=resolution_int, default=32, help="voxel grid size D (8-128)"
    )
    o.add_argument("--workers", type=positive_int, default=2)
    o.add_argument("--sheet", type=Path, default=None, help="write a contact sheet PNG")
    o.set_defaults(func=cmd_objects)

    v = sub.add_parser(
        "view",
        help="write a BEOPick-v0 scene to a rerun .rrd and a PNG",
        parents=[dataset_parent()],
    )
    v.add_argument("--seed", type=seed_int, default=0)
    v.add_argument("--out", type=Path, default=Path("out/view"))
    v.add_argument(
        "--split",
        default="test",
        choices=["train", "val", "test", "ood", "all"],
        help="all: every model of a --objects dataset",
    )
    v.add_argument("--num-objects", type=positive_int, default=None, help="default: 1-4")
    v.add_argument(
        "--image-size", type=_image_side, nargs=2, default=[640, 480], metavar=("W", "H")
    )
    v.add_argument("--no-rrd", action="store_true", help="only the PNG")
    v.set_defaults(func=cmd_view)

    pc = sub.add_parser(
        "pick-check", help="pick success of the ground-truth grasp planner (the ceiling)"
    )
    pc.add_argument("--episodes", type=positive_int, default=100)
    pc.add_argument("--seed", type=seed_int, default=0, help="first episode seed")
    pc.add_argument("--split", default="test", choices=["train", "val", "test", "ood"])
    pc.set_defaults(func=cmd_pick_check)

    r = sub.add_parser("run", help="score a backend on a suite", parents=[dataset_parent()])
    r.add_argument(
        "--split",
        choices=SPLITS_ALL,
        default=None,
        help="with --objects: the dataset's split to score on (default: the suite's, test)",
    )
    r.add_argument("--suite", required=True)
    r.add_argument("--backend", required=True)
    r.add_argument(
        "--episodes", type=positive_int, default=None, help="items (default: the suite's)"
    )
    r.add_argument("--seed", type=seed_int, default=None, help="replace the suite's base seed")
    r.add_argument(
        "--track",
        choices=list(TRACKS),
        default=None,
        help="pose suites: whether backends that can use the true class are given it "
        "(default: class-free; suites without tracks refuse it)",
    )
    r.add_argument(
        "--workers",
        type=positive_int,
        default=None,
        help="worker processes (default: one per core)",
    )
    r.add_argument("--out", default=None, help="default: runs/SUITE[@TRACK]__BACKEND")
    r.add_argument("--resume", action="store_true", help="continue a killed run in --out")
    r.add_argument("--ray", action="store_true", help="run the items as Ray tasks")
    r.add_argument("--rerun", default=None, help="also write a rerun .rrd of the first views")
    r.add_argument(
        "--opt",
        type=key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="backend option",
    )
    _item_timeout_arg(r)
    r.set_defaults(func=cmd_run)

    al = sub.add_parser(
        "all",
        help="run every suite with every backend (resuming), then regenerate leaderboards/",
        parents=[dataset_parent()],
    )
    al.add_argument(
        "--suites",
        nargs="+",
        default=None,
        help="default: every suite (with --objects: every isolated suite that a dataset has)",
    )
    al.add_argument(
        "--split",
        choices=SPLITS_ALL,
        default=None,
        help="with --objects: the dataset's split to score on (default: the suites', test)",
    )
    al.add_argument(
        "--backends",
        type=backend_spec,
        nargs="+",
        default=None,
        metavar="NAME[:K=V,...]",
        help="default: every registered backend; options after a colon",
    )
    al.add_argument(
        "--episodes", type=positive_int, default=None, help="items per suite (default: its own)"
    )
    al.add_argument("--seed", type=seed_int, default=None, help="replace the suites' base seeds")
    al.add_argument("--workers", type=positive_int, default=None, help="default: one per core")
    _item_timeout_arg(al)
    al.add_argument("--ray", action="store_true", help="run the items as Ray tasks")
    al.add_argument("--runs", default="runs", help="where the runs go (resumed when present)")
    al.add_argument("--out", default="leaderboards")
    al.set_defaults(func=cmd_all)

    cp = sub.add_parser(
        "compare",
        help="runs side by side; each run paired with the first on their common items",
        description="A table of the runs; then, for two or more runs of one suite, version, "
        "track and seed, each run B against the first run A: per headline metric, B - A on "
        "the items both scored, a 95% bootstrap interval that resamples items, and a "
        "verdict (better / worse / no difference for B).",
    )
    cp.add_argument("runs", nargs="+", help="run directories or summary.json files")
    cp.add_argument(
        "--table",
        action="store_true",
        help="only the table (runs of any suites; no pairing, no results.jsonl needed)",
    )
    cp.set_defaults(func=cmd_compare)

    lb = sub.add_parser("leaderboard", help="regenerate leaderboards/ from run summaries")
    lb.add_argument("--runs", default="runs")
    lb.add_argument("--out", default="leaderboards")
    lb.set_defaults(func=cmd_leaderboard)

    tr = sub.add_parser(
        "train",
        help="train a perception model (beo, hbeo, hbeo-mdn)",
        parents=[dataset_parent(("--object-size",))],
    )
    tr.add_argument("model", choices=["beo", "hbeo", "hbeo-mdn"])
    tr.add_argument(
        "--split",
        choices=SPLITS_ALL,
        default=None,
        help="with --objects: the dataset's split to train on (default train; all: every "
        "model, for folders too small for a hash split, which then also validates on it)",
    )
    tr.add_argument("--categories", nargs="+", default=None, help="default: the 11 built-in")
    tr.add_argument(
        "--name",
        type=model_name,
        default=None,
        help="model name, a plain name (default: the default model's name)",
    )
    tb = tr.add_argument_group("beo")
    tb.add_argument("--resolution", type=resolution_int, default=32, help="voxels per edge (D)")
    tr.add_argument(
        "--per-category",
        type=positive_int,
        default=None,
        help="train instances per class (hbeo: for the crops and the default BEO subspace)",
    )
    tb.add_argument("--variance-fraction", type=fraction, default=0.6, help="in (0, 1]")
    th = tr.add_argument_group("hbeo and hbeo-mdn (defaults: the default small model's)")
    _dataset_args(th)
    th.add_argument("--epochs", type=positive_int, default=None)
    th.add_argument("--batch-size", type=positive_int, default=None)
    th.add_argument("--size", choices=["small", "dissertation"], default=None)
    th.add_argument("--rotation", choices=["axis-angle", "6d"], default=None, help="hbeo only")
    th.add_argument(
        "--recipe",
        choices=["default", "reference", "per-category"],
        default="default",
        help="default: 16k crops x 15 epochs (minutes on CPU); reference: 100k x 20, best "
        "validation epoch (the published models); per-category: one class's network, 30k x "
        "20 (with --categories C, for hbeo's per_category option)",
    )
    th.add_argument(
        "--device",
        choices=["auto", "cpu", "cuda"],
        default="cpu",
        help="where to train (auto: CUDA when available); cpu is bitwise reproducible",
    )
    th.add_argument(
        "--projection-weighting",
        choices=["uniform", "variance"],
        default=None,
        help="eq. 4.3's projection term: uniform (dissertation) or variance-weighted",
    )
    th.add_argument("--crop", type=positive_int, default=None, help="crop side in pixels (64)")
    th.add_argument(
        "--resume",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="continue from the last finished epoch of a killed run (default)",
    )
    tr.set_defaults(func=cmd_train)

    pb = sub.add_parser(
        "publish", help="write a trained model into the published models the backends load"
    )
    pb.add_argument("model", choices=["beo", "hbeo", "hbeo-mdn"])
    pb.add_argument(
        "--name", type=model_name, default=None, help="the trained model (beo: default model)"
    )
    pb.add_argument("--categories", nargs="+", default=None, help="beo: default the 11 built-in")
    pb.add_argument("--out", default=None, help="default: the package's perception/published")
    pb.add_argument("--float32", action="store_true", help="keep float32 weights (default fp16)")
    pb.set_defaults(func=cmd_publish)

    rd = sub.add_parser(
        "render-dataset",
        help="render HBEO's training crops (cached shards)",
        parents=[dataset_parent()],
    )
    rd.add_argument(
        "--split",
        choices=SPLITS_ALL,
        default=None,
        help="with --objects: the dataset's split to render (default train; all: every model)",
    )
    rd.add_argument("--categories", nargs="+", default=None, help="default: the 11 built-in")
    rd.add_argument("--per-category", type=positive_int, default=None, help="instances per class")
    _dataset_args(rd)
    rd.set_defaults(func=cmd_render_dataset)

    from beo_bench.objects.cache import KINDS

    c = sub.add_parser("cache", help="inspect or clear the asset cache")
    c.add_argument("action", choices=["info", "clear"])
    # a kind is a name from a fixed list, never a path: `clear` deletes what it names
    c.add_argument(
        "--kind",
        default=None,
        choices=list(KINDS),
        help="only this kind of entry (with clear): "
        + "; ".join(f"{k}: {v}" for k, v in KINDS.items()),
    )
    c.set_defaults(func=cmd_cache)
    return p


RESUME_HINTS = {
    "run": "run the same command with --resume to continue",
    "all": "run the same command again to continue (finished runs are kept)",
    "demo": "run the same command again to continue (finished runs are kept)",
    "train": "run the same command again to continue from the last finished epoch",
    "render-dataset": "run the same command again to continue (finished shards are kept)",
}
"""What to tell a user who pressed Ctrl-C, per command (the others have nothing to resume)."""


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line ``argv``; returns the exit status (argparse's own usage errors
    exit 2 through ``SystemExit``)."""
    args = build_parser().parse_args(argv)
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        try:
            return int(args.func(args))
        except BeoBenchError as e:
            return _fail(str(e), e.exit_code)
        except OSError as e:
            return _fail(_os_error(e), 1)
        except KeyboardInterrupt:
            hint = RESUME_HINTS.get(args.command, "run the command again to start over")
            return _fail(f"interrupted; {hint}", 130, what="")
        finally:
            # a run on a user's dataset made it this process's (for its backends' models);
            # a later call in the same process (tests, notebooks) starts from the library
            if "beo_bench.objects.dataset" in sys.modules:
                sys.modules["beo_bench.objects.dataset"].activate(None)


def _fail(message: str, code: int, what: str = "error: ") -> int:
    # one line: the message's own line breaks would read as several errors
    print(f"beo-bench: {what}{' '.join(message.split())}", file=sys.stderr)
    return code


def _os_error(e: OSError) -> str:
    """A line naming the path and what to do about a file-system failure."""
    paths = " -> ".join(str(f) for f in (e.filename, e.filename2) if f)
    why = e.strerror or str(e) or type(e).__name__
    if e.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        todo = "choose a writable place (e.g. --out) or fix its permissions"
    elif e.errno in (errno.ENOSPC, errno.EDQUOT):
        todo = "free some disk space or choose another place (e.g. --out), then resume"
    elif e.errno in (errno.ENOTDIR, errno.EISDIR, errno.EEXIST):
        todo = "a file or directory is in the way: choose another place (e.g. --out) or move it"
    elif e.errno == errno.ENOENT:
        todo = "check that the path exists"
    else:
        todo = "check the path and the disk"
    return f"{why}{': ' + paths if paths else ''}; {todo}"


def _show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: Any = None,
    line: str | None = None,
) -> None:
    """Warnings as one line each, like the errors (no source file, no code line)."""
    print(f"beo-bench: warning: {message}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
