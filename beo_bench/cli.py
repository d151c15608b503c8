"""The ``beo-bench`` command.

Exit status: 0 on success, 1 on a failure (a run that cannot finish, a corrupt model, a
full or read-only disk), 2 on a usage error (an argument, option or setting out of range;
runs that do not pair with a gate's baseline) or a problem with your data or set-up (a bad
mesh file, a missing dataset folder, an unusable asset cache), 3 when results cross a limit
you set (`gate` found a regression, a run's failures exceed --max-failure-rate; the results
and reports are written first), 130 when interrupted. An error is one line on stderr,
``beo-bench: error: ...``, saying what was wrong and what to do; no traceback.
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

from beo_bench.argparsing import SuggestingParser
from beo_bench.bench.columns import brief_columns
from beo_bench.errors import BeoBenchError, ThresholdError, UsageError

if TYPE_CHECKING:
    from beo_bench.bench.runs import RunContext, Summary
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


def rate(text: str) -> float:
    """An argparse ``type``: a share in [0, 1] (``--max-failure-rate 0``: no failure)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0 <= value <= 1:
        raise argparse.ArgumentTypeError(f"{text} is out of range: give a share in [0, 1]")
    return value


def open_fraction(text: str) -> float:
    """An argparse ``type``: a number in (0, 1) (a significance level)."""
    value = positive_float(text)
    if value >= 1:
        raise argparse.ArgumentTypeError(f"{text} is out of range: give a number in (0, 1)")
    return value


def gate_metric(text: str) -> str:
    """An argparse ``type`` for ``gate --metrics``: a metric that is a mean over views."""
    from beo_bench.bench.gate import GateUsageError, metric_spec

    try:
        return metric_spec(text).key
    except GateUsageError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


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


SENSOR_NAMES = "ideal, kinect-v1 or d435"
"""How ``--sensor``'s help names the sensors (``beo_bench.scenes.sensors.SENSORS``; spelt
out so that building the parser imports no renderer: tests/bench/test_sensor_axis.py checks
that it names every one)."""


def sensor_name(text: str) -> str:
    """An argparse ``type`` for ``--sensor``: a registered sensor's name, in any case
    (``D435``); another name is a usage error (exit 2) naming the closest ones."""
    from beo_bench.scenes.sensors import SENSORS, SensorError, check_sensor_name

    by_lower = {s.lower(): s for s in SENSORS}
    try:
        return check_sensor_name(by_lower.get(text.strip().lower(), text))
    except SensorError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


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


def dataset_parent(
    size_flags: tuple[str, ...] = ("--size", "--object-size"),
) -> argparse.ArgumentParser:
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
    _add_check_options(g)
    return p


def _add_check_options(g: Any) -> None:
    """``--units``, ``--skip-bad`` and ``--max-faces``: how a dataset's files are read and
    what its check (``objects.checks``, before the command uses it) does with bad ones."""
    from beo_bench.objects.meshfile import MAX_INPUT_FACES, UNIT_MODES

    g.add_argument(
        "--units",
        choices=list(UNIT_MODES),
        default=None,
        help="with --objects: the files' units (in: inches); default: auto (detected) for "
        "folders, normalised (the class's size) for ShapeNet and ModelNet",
    )
    g.add_argument(
        "--skip-bad",
        action="store_true",
        help="with --objects: leave out the files that cannot be used (each is named with "
        "why) and run on the rest; the summary lists them",
    )
    g.add_argument(
        "--max-faces",
        type=positive_int,
        default=MAX_INPUT_FACES,
        metavar="N",
        help=f"with --objects: refuse mesh files of more faces (default {MAX_INPUT_FACES:,}: "
        "beyond it, loading takes minutes and gigabytes)",
    )


SPLITS_ALL = ["train", "val", "test", "all"]
"""Splits of a user's dataset (``all``: every model, whatever its hash split)."""


def _dataset(args: argparse.Namespace) -> Any:
    """The :class:`~beo_bench.objects.dataset.Dataset` that ``--objects`` names (None
    without it; loading options given without it are a usage error)."""
    from beo_bench.objects.loaders import DEFAULT_REPAIR
    from beo_bench.objects.meshfile import MAX_INPUT_FACES

    root = getattr(args, "objects", None)
    if root is None:
        given = [
            f"--{k}"
            for k, default in (
                ("repair", DEFAULT_REPAIR),
                ("up", "z"),
                ("object-size", None),
                ("units", None),
                ("skip-bad", False),
                ("max-faces", MAX_INPUT_FACES),
            )
            if getattr(args, k.replace("-", "_"), default) != default
        ]
        if given or getattr(args, "split", None) == "all":
            given += ["--split all"] if getattr(args, "split", None) == "all" else []
            raise UsageError(f"{', '.join(given)} apply to a user dataset only: add --objects ROOT")
        return None
    from beo_bench.objects.checks import vet
    from beo_bench.objects.dataset import open_dataset

    dataset = open_dataset(root, args.repair, args.up, args.object_size, args.units, args.max_faces)
    # every file is built once, here in the driver, before anything uses the dataset: a bad
    # one is named now with the flag that fixes it, not found by a worker mid-run
    return vet(dataset, args.skip_bad, getattr(args, "workers", None), args.command == "objects")


def cmd_objects(args: argparse.Namespace) -> int:
    from beo_bench import inspection

    if args.objects is not None and args.root is not None:
        raise UsageError("give the dataset once: --objects ROOT (--root is its older spelling)")
    args.objects, args.root = args.objects or args.root, None  # checked as --objects is
    dataset = _dataset(args)
    if dataset is not None:
        print(f"dataset {dataset.root}: {dataset.layout} layout, digest {dataset.digest}")
    objects, counts = inspection.select_objects(
        args.split, _categories(args), args.per_category, dataset=dataset, root=args.root
    )
    report = inspection.summarise_objects(
        objects,
        args.split,
        resolution=args.resolution,
        workers=args.workers,
        sheet=args.sheet,
        sheet_per_category=args.per_category or 6,  # the sheet shows what --per-category asks
        split_counts=counts,
    )
    print()
    print(report.text())
    _print_skipped(dataset)
    return 0


def _print_skipped(dataset: Any) -> None:
    """The files ``--skip-bad`` left out, at the end of a command's output."""
    from beo_bench.objects.checks import skipped_text

    if text := skipped_text(dataset):
        print(f"\n{text}")


def cmd_cache(args: argparse.Namespace) -> int:
    from beo_bench import inspection
    from beo_bench.objects import cache

    # a cache that is a file is an error, not an empty cache (info needs no write access)
    cache.check_root(writable=args.action == "clear", min_free=0)
    if args.action == "clear":
        freed = cache.clear(args.kind)
        print(f"cleared {inspection.format_bytes(freed)} from {cache.cache_root()}")
        return 0
    print(inspection.cache_report().text())
    return 0


def cmd_view(args: argparse.Namespace) -> int:
    from beo_bench.sceneview import view_scene

    dataset = _dataset(args)
    r = view_scene(
        args.seed,
        args.out,
        rrd=not args.no_rrd,
        split=args.split,
        image_size=tuple(args.image_size),
        num_objects=args.num_objects,
        objects=dataset.objects(args.split) if dataset is not None else None,
    )
    print(r.text())
    return 0


def cmd_pick_check(args: argparse.Namespace) -> int:
    from beo_bench import inspection

    report = inspection.pick_check(args.episodes, args.seed, args.split)
    print()
    print(report.text())
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from beo_bench.bench.runner import run
    from beo_bench.bench.runs import RunConfig, RunContext, parse_option_pairs, run_name

    suite, dataset = _run_suite(args, args.track)
    kwargs = parse_option_pairs(args.opt)
    cfg = RunConfig(suite, args.backend, kwargs, args.allow_privileged)
    # resolved once: a bad option, a privileged plugin without leave or a track the backend
    # cannot run in fails here, before any directory is made
    ctx = RunContext.of(cfg, progress=True)
    name = run_name(suite.name, args.backend, kwargs, args.seed, suite.track, suite.sensor_tag)
    out = Path(args.out) if args.out else Path("runs") / name
    summary = run(
        ctx,
        out,
        workers=args.workers,
        resume=args.resume,
        use_ray=args.ray,
        item_timeout=args.item_timeout,
        report_views=args.report_views,
        force_rerun=args.force_rerun,
    )
    print(format_runs([summary]))
    print(f"\nresults: {out / 'results.jsonl'}\nsummary: {out / 'summary.json'}")
    _print_skipped(dataset)
    if args.rerun:
        from beo_bench.bench.recording import log_run

        path = log_run(ctx, args.rerun)
        print(f"recording of the first views: {path}  (open with `rerun {path}`)")
    _print_run_end(ctx, out, label=False)
    if args.max_failure_rate is not None:
        from beo_bench.bench.gate import check_failure_rate

        check_failure_rate([(out, summary)], args.max_failure_rate)
    return 0


def _print_run_end(ctx: RunContext, out: Path, label: bool = True) -> None:
    """A run's last lines: its failures by exception, its pick reasons, its report (a run
    in which every view failed also warns on stderr); ``label``: name the run (``all``)."""
    from beo_bench.bench.runner import run_end
    from beo_bench.bench.runs import backend_label

    who = f"{ctx.suite.label} / {backend_label(ctx.backend.name, ctx.backend.kwargs)}"
    end = run_end(out, ctx.suite.size, who if label else "")
    print(f"\n{end.text()}")
    end.warn()


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
    from beo_bench.bench.suites import Kind as SuiteKind

    return [
        n
        for n, s in sorted(SUITES.items())
        if s.kind is SuiteKind.ISOLATED and s.categories is None and s.split != "ood"
    ]


def _suite(name: str) -> Any:
    """The suite ``name``; an unknown name is a usage error (exit 2), listing the suites."""
    from beo_bench.bench.suites import UnknownSuiteError, get_suite

    try:
        return get_suite(name)
    except UnknownSuiteError as e:
        raise UsageError(str(e)) from e


COLUMNS = brief_columns()
"""The plain-text table's metric columns (``bench.columns``: one list for every table)."""


def format_runs(runs: Sequence[Summary | dict[str, Any]]) -> str:
    """A plain table of runs: one row per run (its suite and track, backend and options),
    the columns that any of them measured."""
    from beo_bench.bench.compare import sensor_tag_of, track_of
    from beo_bench.bench.runs import Summary, backend_label

    summaries = [s.to_json() if isinstance(s, Summary) else s for s in runs]

    def where(s: dict) -> str:
        track = track_of(s)
        text = f"{s['suite']}@{track}" if track else str(s["suite"])
        tag = sensor_tag_of(s)
        return text + (f"~{tag}" if tag else "")

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
    from beo_bench.bench.failures import reasons_text, summary_pick_reasons

    for s in summaries:  # a pick run's episodes by reason (docs/env.md, "Why a pick fails")
        if reasons := summary_pick_reasons(s):
            lines.append(f"pick reasons, {where(s)} {who(s)}: {reasons_text(reasons)}")
    return "\n".join(lines)


def cmd_compare(args: argparse.Namespace) -> int:
    """The runs' table; then, unless ``--table``, each run paired with the first on the
    items both scored (B - A with a bootstrap interval over items, and a verdict), and a
    footnote that the verdicts are uncorrected and ``gate`` is the pass/fail check."""
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
    print(compare.UNCORRECTED_NOTE)  # under the last verdict table: these are not a gate
    return 0


def cmd_gate(args: argparse.Namespace) -> int:
    """Each run against its baseline run; the reports; exit 3 on a regression."""
    from beo_bench.bench import gate

    options = gate.GateOptions(
        metrics=tuple(args.metrics) if args.metrics else None,
        alpha=args.alpha,
        permutations=args.permutations,
        seed=args.seed,
    )
    baseline = gate.load_baseline(args.baseline)  # refused before the runs are read
    report = gate.gate(gate.load_runs(args.runs), baseline, options, str(args.baseline))
    print(report.text())
    written = gate.write_reports(report, args.json, args.junit, args.markdown)
    for path in written:
        print(f"wrote {path}")
    for blind in report.cannot_fail:  # loud, also where stdout is not read: a pass of these
        _show_warning(f"gate cannot fail: {blind.line()}", UserWarning, "", 0)  # means nothing
    if not report.passed:
        worst = "; ".join(v.line() for v in report.regressions)
        raise gate.GateFailure(f"gate failed: regression in {worst}")
    return 0


def cmd_baseline(args: argparse.Namespace) -> int:
    """Write the baseline file of the runs given."""
    from beo_bench.bench import gate

    runs = gate.load_runs(args.runs)
    path = gate.write_baseline(runs, args.out)
    held = ", ".join(f"{r.label} ({r.backend})" for r in runs)
    print(f"wrote {path} ({path.stat().st_size / 1024:.1f} kB): {held}")
    return 0


def _run_suite(args: argparse.Namespace, track: str | None = None) -> tuple[Any, Any]:
    """The suite a ``run``, ``export`` or ``score`` command means, and the user's dataset
    (None: the library): ``--suite`` with ``--episodes``, ``--seed``, ``track``,
    ``--categories``, ``--objects`` and ``--sensor``."""
    # --track on a suite without tracks is a usage error here
    suite = _suite(args.suite).with_overrides(size=args.episodes, seed=args.seed, track=track)
    if args.categories:
        # a class subset is its own suite (pose-3dof+modelnet10): its own runs and page
        suite = suite.with_categories(args.categories)
    dataset = _dataset(args)
    _split_needs_dataset(args, dataset)
    if dataset is not None:
        suite = suite.with_dataset(dataset, args.split)
    return suite.with_sensor(args.sensor), dataset  # None: the suite's own sensor


def cmd_export(args: argparse.Namespace) -> int:
    from beo_bench.bench.export import export_bop

    suite, _ = _run_suite(args)
    train = suite.size if args.train_items is None else args.train_items
    done = export_bop(
        suite, Path(args.dir), train_items=train, progress=True, withhold_gt=args.withhold_gt
    )
    shown = ", ".join(
        f"{n} {split} image{'' if n == 1 else 's'}" for split, n in done.images.items()
    )
    print(
        f"{done.root}: BOP dataset of {suite.name}"
        f"{'' if suite.sensor_tag is None else '~' + suite.sensor_tag} ({shown}, "
        f"{done.objects} object models, "
        f"{done.targets} targets in test_targets_bop19.json"
        f"{'; test ground truth withheld' if args.withhold_gt else ''})"
    )
    if done.removed:
        print(f"removed {done.removed} file(s) of the earlier export that this one replaced")
    if done.kept:
        print(
            f"beo-bench: warning: kept {len(done.kept)} file(s) of the earlier export that "
            f"changed since it wrote them ({', '.join(done.kept[:3])}"
            f"{', ...' if len(done.kept) > 3 else ''}): remove them yourself if unwanted",
            file=sys.stderr,
        )
    return 0


def cmd_score(args: argparse.Namespace) -> int:
    from beo_bench.bench.bopscore import method_name, score_results
    from beo_bench.bench.runs import run_name

    suite, _ = _run_suite(args)
    results = Path(args.bop_results)
    method = args.method or method_name(results)
    track = "class-given" if suite.class_hint else None
    name = run_name(suite.name, method, {}, args.seed, track, suite.sensor_tag)
    out = Path(args.out) if args.out else Path("runs") / name
    summary = score_results(suite, results, out, method=method, progress=True)
    print(format_runs([summary]))
    print(f"\nresults: {out / 'results.jsonl'}\nsummary: {out / 'summary.json'}")
    return 0


def cmd_leaderboard(args: argparse.Namespace) -> int:
    from beo_bench.bench.leaderboard import regenerate

    if not Path(args.runs).is_dir():  # a mistyped --runs is a usage error, not an empty one
        raise UsageError(
            f"--runs {args.runs} is not a directory: give the directory the runs are in "
            "(where `beo-bench run --out` or `all --runs` wrote them)"
        )
    written = regenerate(args.runs, args.out, update=args.update, ablation=args.ablation)
    if not written and not args.update:  # --update alone prunes pages of older versions
        raise BeoBenchError(f"no summary.json under {args.runs}: run `beo-bench run` first")
    for p in written:
        print(p.read_text())
    print(f"wrote {len(written)} suite tables to {args.out}/")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from beo_bench.demo import run_demo

    run_demo(args.out, per_category=args.per_category, workers=args.workers)
    return 0


def cmd_all(args: argparse.Namespace) -> int:
    from beo_bench.bench.campaign import Campaign, run_campaign
    from beo_bench.bench.leaderboard import check_out
    from beo_bench.bench.runs import parse_backend_spec
    from beo_bench.bench.suites import UnknownSuiteError, expand_suites, list_suites
    from beo_bench.inspection import every_backend, leaderboard_text

    dataset = _dataset(args)
    _split_needs_dataset(args, dataset)
    # suite sets (smoke) name each suite with its size; --episodes, when given, wins
    try:
        sizes = expand_suites(
            args.suites or (list_suites() if dataset is None else dataset_suites())
        )
    except UnknownSuiteError as e:
        raise UsageError(str(e)) from e
    for s in sizes:
        suite = _suite(s)  # an unknown name fails before any run starts
        if dataset is not None:
            suite.with_dataset(dataset, args.split)  # so does a scene suite on a dataset
    specs = args.backends or every_backend()
    check_out(args.out)  # a refused --out fails now, not after every run
    c = Campaign(
        {s: n if args.episodes is None else args.episodes for s, n in sizes.items()},
        [parse_backend_spec(b) for b in specs],
        runs=Path(args.runs),
        leaderboards=Path(args.out),
        workers=args.workers,
        use_ray=args.ray,
        seed=args.seed,
        dataset=dataset,
        split=args.split,
        allow_privileged=args.allow_privileged,
        item_timeout=args.item_timeout,
        update=args.update,
        sensors=tuple(dict.fromkeys(args.sensor)) if args.sensor else (None,),
        max_failure_rate=args.max_failure_rate,
        report_views=args.report_views,
        force_rerun=args.force_rerun,
        after_run=_print_run_end,
    )
    print(leaderboard_text(run_campaign(c), c.leaderboards))
    _print_skipped(dataset)
    return 0


def _train_request(args: argparse.Namespace) -> Any:
    """The ``train`` command's options as a :class:`~beo_bench.training.TrainRequest`."""
    from beo_bench.training import TrainRequest

    dataset = _dataset(args)
    _split_needs_dataset(args, dataset)
    return TrainRequest(
        dataset=dataset,
        split=args.split,
        categories=_categories(args),
        per_category=args.per_category,
        resolution=getattr(args, "resolution", 32),
        variance_fraction=getattr(args, "variance_fraction", 0.6),
        images=getattr(args, "images", None),
        val_images=getattr(args, "val_images", None),
        epochs=getattr(args, "epochs", None),
        recipe=getattr(args, "recipe", None),
        seed=getattr(args, "seed", None),
        crop=getattr(args, "crop", None),
        size=getattr(args, "size", None),
        rotation=getattr(args, "rotation", None),
        batch_size=getattr(args, "batch_size", None),
        projection_weighting=getattr(args, "projection_weighting", None),
        sensor=getattr(args, "sensor", None),
    )


def cmd_train(args: argparse.Namespace) -> int:
    """Train a model and store it under its name (the default name is the one the backend
    looks for, so training it ahead of time only saves the first run the wait)."""
    if args.model != "beo":
        return _train_hbeo(args)
    if args.sensor is not None:
        raise UsageError(
            "--sensor applies to hbeo and hbeo-mdn (the depth sensor their training crops "
            "are captured by); beo trains on voxels, nothing is rendered"
        )
    from beo_bench.perception.beo_model import default_name, model_path, train_beo
    from beo_bench.training import beo_config

    req = _train_request(args)
    cfg = beo_config(req)
    cats = cfg.categories
    name = args.name or default_name(cats, args.resolution, args.per_category, req.dataset)
    t0 = time.perf_counter()
    model = train_beo(cfg, progress=True, dataset=req.dataset, split=req.train_split)
    path = model.save(model_path(name))
    print(
        f"BEO model {name!r}: {len(cats)} classes at {args.resolution}^3, subspace k={model.k} "
        f"(per class {dict(zip(cats, model.components.tolist(), strict=True))}), "
        f"trained in {time.perf_counter() - t0:.1f} s -> {path}"
    )
    return 0


def _hbeo_config(args: argparse.Namespace, kind: Kind) -> HBEOConfig:
    """The HBEO training set-up the options describe (:func:`beo_bench.training.hbeo_config`)."""
    from beo_bench.training import hbeo_config

    return hbeo_config(_train_request(args), kind)


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
    if args.model == "rest-prior":  # fitted here: a minute of the training split's scenes
        from beo_bench.perception.means import publish_rest_prior

        sha = publish_rest_prior(out, progress=True)
    elif args.model == "beo":
        from beo_bench.perception.beo_model import BEOModel, model_dir
        from beo_bench.training import library_categories

        cats = library_categories(_categories(args))
        path = model_dir(args.name, cats, 32)
        sha = published.publish_beo(BEOModel.load(path), out)
    else:
        from beo_bench.perception.hbeo_train import (
            HBEOModel,
            default_config,
            default_name,
            is_per_category_default,
            model_path,
        )

        name = args.name
        cats = tuple(args.categories or ())
        if name is None and len(cats) == 1 and cats[0] in published.PER_CATEGORY:
            # chapter 5's network of that class: the per-category recipe's default model
            name = default_name(default_config(args.model, cats, recipe="per-category"))
        if name is None:
            raise UsageError(
                f"publish {args.model} needs --name (the trained model's name), or "
                "--categories C for the per-category network of C "
                f"({', '.join(published.PER_CATEGORY)})"
            )
        model = HBEOModel.load(model_path(name))
        if model.config.kind != args.model:
            raise UsageError(f"{args.name!r} is a {model.config.kind} model, not {args.model}")
        one = len(model.categories) == 1 and is_per_category_default(model.config)
        sha = published.publish_hbeo(model, out, storage=args.storage, per_category=one)
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


# -- shared options: one parent parser per option that several commands declare alike ------
# Each factory takes what differs between commands (the default and the help text), so a
# command's `--help` reads as before while the option's flag, type and checks live here once.
def _option_parent(*flags: str, title: str | None = None, **kwargs: Any) -> argparse.ArgumentParser:
    """A parent parser (``parents=[...]``) holding one option; in argument group ``title``
    when given (parents whose groups share a title fill one group of the command)."""
    p = argparse.ArgumentParser(add_help=False)
    (p.add_argument_group(title) if title else p).add_argument(*flags, **kwargs)
    return p


def seed_parent(
    default: int | None = None, help: str | None = None, title: str | None = None
) -> argparse.ArgumentParser:
    """``--seed``: a non-negative numpy seed."""
    return _option_parent("--seed", type=seed_int, default=default, help=help, title=title)


def workers_parent(
    default: int | None = None, help: str | None = "default: one per core", title: str | None = None
) -> argparse.ArgumentParser:
    """``--workers``: processes, at least one."""
    return _option_parent("--workers", type=positive_int, default=default, help=help, title=title)


def privileged_parent() -> argparse.ArgumentParser:
    """``--allow-privileged``: a plugin that declares ``privileged`` may be handed the truth."""
    return _option_parent(
        "--allow-privileged",
        action="store_true",
        help="let a plugin whose spec declares it privileged be handed the ground truth (its "
        "rows are listed with the bounds, never ranked)",
    )


def episodes_parent(default: int | None = None, help: str | None = None) -> argparse.ArgumentParser:
    """``--episodes``: items or episodes, at least one."""
    return _option_parent("--episodes", type=positive_int, default=default, help=help)


def per_category_parent(
    default: int | None = None, help: str | None = None
) -> argparse.ArgumentParser:
    """``--per-category``: instances per class, at least one."""
    return _option_parent("--per-category", type=positive_int, default=default, help=help)


def split_parent(
    choices: Sequence[str], default: str | None, help: str | None = None
) -> argparse.ArgumentParser:
    """``--split``: one of ``choices``."""
    return _option_parent("--split", choices=list(choices), default=default, help=help)


def update_parent() -> argparse.ArgumentParser:
    """``--update``: keep the current pages of suites that have no runs."""
    return _option_parent(
        "--update",
        action="store_true",
        help="keep the pages of suites with no runs under --runs (when of the current suite "
        "version): run a long campaign suite by suite",
    )


def categories_parent(help: str | None = None) -> argparse.ArgumentParser:
    """``--categories C [C ...]``: class and set names (checked where they are used)."""
    return _option_parent(
        "--categories",
        nargs="+",
        default=None,
        help=help or "classes or sets (modelnet10, shapenet-ch5, library)",
    )


def _categories(args: argparse.Namespace) -> tuple[str, ...] | None:
    """``--categories`` with set names expanded (None: not given)."""
    from beo_bench.objects.sets import resolve_categories

    return resolve_categories(args.categories) if args.categories else None


def out_parent(
    default: Any, help: str | None = None, type: Callable[[str], Any] | None = None
) -> argparse.ArgumentParser:
    """``--out``: where a command writes (``type``: e.g. ``Path``; default: the string). An
    empty value is a usage error: it would read as "not given" (``run`` then writes under
    ``runs/``) or as the current directory, neither of which the user named."""

    def checked(text: str) -> Any:
        if not text.strip():
            raise argparse.ArgumentTypeError("is empty: give a directory, or leave --out out")
        return text if type is None else type(text)

    return _option_parent("--out", type=checked, default=default, help=help)


def runs_parent(help: str | None = None) -> argparse.ArgumentParser:
    """``--runs``: the directory of run directories."""
    return _option_parent("--runs", default="runs", help=help)


def report_views_parent() -> argparse.ArgumentParser:
    """``--report-views N``: the worst views a run's ``report.html`` shows (0: no report)."""
    from beo_bench.bench.runs import REPORT_VIEWS

    return _option_parent(
        "--report-views",
        type=nonneg_int,
        default=REPORT_VIEWS,
        metavar="N",
        help=f"write OUT/report.html, an offline page of the run's failures and its N worst "
        f"views by the suite's primary error (default {REPORT_VIEWS}; 0: no report)",
    )


def ray_parent() -> argparse.ArgumentParser:
    """``--ray``: items as Ray tasks instead of worker processes."""
    return _option_parent("--ray", action="store_true", help="run the items as Ray tasks")


def item_timeout_parent() -> argparse.ArgumentParser:
    """``--item-timeout``: seconds one item may take (a finite number > 0)."""
    return _option_parent(
        "--item-timeout",
        type=positive_float,
        default=None,
        metavar="S",
        help="seconds one item may take before it is recorded as failed (default: the runner's)",
    )


def sensor_parent(
    help: str, many: bool = False, title: str | None = None
) -> argparse.ArgumentParser:
    """``--sensor NAME`` (``many``: one or more names): the depth sensor, checked
    case-insensitively with the closest names on a typo."""
    return _option_parent(
        "--sensor",
        type=sensor_name,
        nargs="+" if many else None,
        default=None,
        metavar="NAME",
        help=help,
        title=title,
    )


def model_parent() -> argparse.ArgumentParser:
    """The positional ``model``: which kind of perception model."""
    return _option_parent("model", choices=MODELS)


def model_name_parent(help: str) -> argparse.ArgumentParser:
    """``--name``: a trained model's plain name (never a path)."""
    return _option_parent("--name", type=model_name, default=None, help=help)


def render_parents(title: str) -> list[argparse.ArgumentParser]:
    """The options of rendering HBEO's training crops (``train`` and ``render-dataset``),
    in one argument group ``title``."""
    return [
        _option_parent(
            "--images", type=positive_int, default=None, help="training crops", title=title
        ),
        _option_parent(
            "--val-images",
            type=nonneg_int,
            default=None,
            help="validation crops (val split)",
            title=title,
        ),
        seed_parent(help="seeds rendering and training", title=title),
        workers_parent(help="render processes (default: cores)", title=title),
        sensor_parent(
            f"capture the noisy share of the crops by this depth sensor ({SENSOR_NAMES}; "
            "docs/sensors.md) instead of the DepthNoise augmentation (default: the published "
            "recipe's augmentation)",
            title=title,
        ),
    ]


MODELS = ["beo", "hbeo", "hbeo-mdn"]
"""The perception models ``train`` and ``publish`` know."""
SCENE_SPLITS = ["train", "val", "test", "ood", "all"]
"""Splits of a scene's objects: the library's four, or ``all`` of a user's dataset."""
RENDER_GROUP = "rendering the training crops (hbeo and hbeo-mdn)"


# -- what the registries hold, for `beo-bench --help` --------------------------------------
def _fit(name: str, text: str, name_width: int, width: int) -> str:
    """``  NAME  text`` on one line of at most ``width`` characters (cut at a word)."""
    text = " ".join(text.replace("`", "").split())
    line = f"  {name:<{name_width}}  {text}"
    if len(line) <= width:
        return line
    return line[: width - 3].rsplit(" ", 1)[0].rstrip(",;:") + "..."


def registry_listing(width: int | None = None) -> str:
    """The suites, backends (plugins included) and cache kinds, one line each with what it
    is, read from their registries; ``width``: the line length (default: the terminal's,
    as argparse's)."""
    import shutil

    from beo_bench.backend import describe_backend, list_backends, load_plugins
    from beo_bench.bench.suites import SUITE_SETS, SUITES
    from beo_bench.objects.cache import KINDS

    width = width or max(60, shutil.get_terminal_size().columns - 2)
    sets = {
        n: f"{len(sizes)} suites at {min(sizes.values())}-{max(sizes.values())} items each"
        for n, sizes in sorted(SUITE_SETS.items())
    }
    load_plugins()  # a broken plugin is one warning, and is left out
    backends = {n: describe_backend(n) for n in list_backends()}
    sections = [
        ("suites (run --suite NAME)", {n: s.description for n, s in sorted(SUITES.items())}),
        ("suite sets (all --suites NAME)", sets),
        # plugins: packages' entry points in the group ENTRY_POINT_GROUP
        ("backends (run --backend NAME; installed plugins included)", backends),
        ("cache kinds (cache clear --kind KIND)", KINDS),
    ]
    out = []
    for head, entries in sections:
        w = max(map(len, entries))
        out += [f"{head}:", *(_fit(n, d, w, width) for n, d in entries.items()), ""]
    return "\n".join(out).rstrip()


class _MainParser(SuggestingParser):
    """The top-level parser: its help lists the registries (read only when help is shown,
    so that a command never pays for importing every backend)."""

    def format_help(self) -> str:
        self.epilog = registry_listing() + "\n\n" + EXIT_STATUS
        return super().format_help()


EXIT_STATUS = __doc__.split("\n\n", 1)[1]


def _add_demo(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``demo`` command."""
    d = sub.add_parser(
        "demo",
        help="the main job on the embedded defaults",
        parents=[
            out_parent("out/demo", "where images and results go"),
            per_category_parent(20, "test-split instances per category to process and summarise"),
            workers_parent(),
        ],
    )
    d.set_defaults(func=cmd_demo)


def _add_objects(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``objects`` command."""
    o = sub.add_parser(
        "objects",
        help="process and summarise an object set",
        parents=[
            data,
            split_parent(SCENE_SPLITS, "test", "all: every model of a --objects dataset"),
            categories_parent(),
            per_category_parent(None, "instances per category (default: the split's size)"),
            workers_parent(2, None),
        ],
    )
    o.add_argument(
        "--root", default=None, help="a ShapeNetCore v2, ModelNet or per-category mesh folder"
    )
    o.add_argument(
        "--resolution", type=resolution_int, default=32, help="voxel grid size D (8-128)"
    )
    o.add_argument("--sheet", type=Path, default=None, help="write a contact sheet PNG")
    o.set_defaults(func=cmd_objects)


def _add_view(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``view`` command."""
    v = sub.add_parser(
        "view",
        help="write a BEOPick-v0 scene to a rerun .rrd and a PNG",
        parents=[
            data,
            seed_parent(0),
            out_parent(Path("out/view"), type=Path),
            split_parent(SCENE_SPLITS, "test", "all: every model of a --objects dataset"),
        ],
    )
    v.add_argument("--num-objects", type=positive_int, default=None, help="default: 1-4")
    v.add_argument(
        "--image-size", type=_image_side, nargs=2, default=[640, 480], metavar=("W", "H")
    )
    v.add_argument("--no-rrd", action="store_true", help="only the PNG")
    v.set_defaults(func=cmd_view)


def _add_pick_check(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``pick-check`` command."""
    pc = sub.add_parser(
        "pick-check",
        help="pick success of the ground-truth grasp planner (the ceiling)",
        parents=[
            episodes_parent(100),
            seed_parent(0, "first episode seed"),
            split_parent(["train", "val", "test", "ood"], "test"),
        ],
    )
    pc.set_defaults(func=cmd_pick_check)


def _add_run(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``run`` command."""
    from beo_bench.bench.suites import TRACKS

    r = sub.add_parser(
        "run",
        help="score a backend on a suite",
        parents=[
            data,
            split_parent(
                SPLITS_ALL,
                None,
                "with --objects: the dataset's split to score on (default: the suite's, test)",
            ),
            episodes_parent(None, "items (default: the suite's)"),
            seed_parent(None, "replace the suite's base seed"),
            categories_parent(
                "isolated suites: only these classes or sets (modelnet10, shapenet-ch5, "
                "library); the run is then suite SUITE+SET"
            ),
            workers_parent(None, "worker processes (default: one per core)"),
            out_parent(None, "default: runs/SUITE[@TRACK][~SENSOR]__BACKEND"),
            ray_parent(),
            item_timeout_parent(),
            privileged_parent(),
            report_views_parent(),
            sensor_parent(
                f"the depth sensor the views are captured by ({SENSOR_NAMES}; "
                "docs/sensors.md; default: the suite's own, kinect-v1 for tabletop, ideal "
                "for the others); another than the suite's own names the run SUITE~SENSOR"
            ),
        ],
    )
    r.add_argument("--suite", required=True)
    r.add_argument("--backend", required=True)
    r.add_argument(
        "--track",
        choices=list(TRACKS),
        default=None,
        help="pose suites: whether backends that can use the true class are given it "
        "(default: class-free; suites without tracks refuse it)",
    )
    r.add_argument("--resume", action="store_true", help="continue a killed run in --out")
    r.add_argument("--force-rerun", action="store_true", help=FORCE_RERUN_HELP)
    r.add_argument(
        "--max-failure-rate",
        type=rate,
        default=None,
        metavar="X",
        help=MAX_FAILURE_HELP,
    )
    r.add_argument("--rerun", default=None, help="also write a rerun .rrd of the first views")
    r.add_argument(
        "--opt",
        type=key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="backend option",
    )
    r.set_defaults(func=cmd_run)


def _add_all(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``all`` command."""
    al = sub.add_parser(
        "all",
        help="run every suite with every backend (resuming), then regenerate leaderboards/",
        parents=[
            data,
            split_parent(
                SPLITS_ALL,
                None,
                "with --objects: the dataset's split to score on (default: the suites', test)",
            ),
            episodes_parent(None, "items per suite (default: its own)"),
            seed_parent(None, "replace the suites' base seeds"),
            workers_parent(),
            item_timeout_parent(),
            ray_parent(),
            runs_parent("where the runs go (resumed when present)"),
            out_parent("leaderboards"),
            privileged_parent(),
            update_parent(),
            report_views_parent(),
            sensor_parent(
                f"run every suite under each of these depth sensors ({SENSOR_NAMES}; "
                "docs/sensors.md; default: each suite's own); the leaderboard pairs them in "
                "a robustness table",
                many=True,
            ),
        ],
    )
    al.add_argument(
        "--suites",
        nargs="+",
        default=None,
        help="suites, or suite sets (smoke: every suite at a few items; --episodes still "
        "wins); default: every suite (with --objects: every isolated suite that a dataset has)",
    )
    al.add_argument(
        "--max-failure-rate",
        type=rate,
        default=None,
        metavar="X",
        help=MAX_FAILURE_HELP.replace("the run", "any run"),
    )
    al.add_argument(
        "--backends",
        type=backend_spec,
        nargs="+",
        default=None,
        metavar="NAME[:K=V,...]",
        help="default: every registered backend; options after a colon",
    )
    al.add_argument("--force-rerun", action="store_true", help=FORCE_RERUN_HELP)
    al.set_defaults(func=cmd_all)


def _export_parents(data: argparse.ArgumentParser, what: str) -> list[argparse.ArgumentParser]:
    return [
        data,
        split_parent(SPLITS_ALL, None, "with --objects: the dataset's split (default: test)"),
        episodes_parent(None, f"{what} the suite's first N items (default: all of them)"),
        seed_parent(None, "replace the suite's base seed"),
        categories_parent("isolated suites: only these classes or sets (suite SUITE+SET)"),
        sensor_parent(
            f"the depth sensor the depth images are captured by ({SENSOR_NAMES}; "
            "docs/sensors.md; default: the suite's own)"
        ),
    ]


def _add_export(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``export`` command."""
    ex = sub.add_parser(
        "export",
        help="write a suite's items as a BOP-format dataset (docs/bop.md)",
        description="Write a suite's items as a BOP dataset (models, test scenes with rgb, "
        "depth, masks and ground truth, test_targets_bop19.json, and training scenes), for "
        "methods that read BOP datasets; `beo-bench score` scores their results file.",
        parents=_export_parents(data, "export"),
    )
    ex.add_argument("--suite", required=True)
    ex.add_argument("--format", choices=["bop"], default="bop", help="the format (bop)")
    ex.add_argument(
        "--train-items",
        type=nonneg_int,
        default=None,
        metavar="N",
        help="training images drawn from the split's training instances (default: as many as "
        "the test images; 0: none)",
    )
    ex.add_argument(
        "--withhold-gt",
        action="store_true",
        help="write the test split as the BOP challenge does: images, cameras and targets, "
        "no scene_gt.json, scene_gt_info.json or masks (`beo-bench score` does not need them)",
    )
    ex.add_argument("dir", metavar="DIR", help="a new or empty folder (or an earlier export's)")
    ex.set_defaults(func=cmd_export)


def _add_score(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``score`` command."""
    sc = sub.add_parser(
        "score",
        help="score a BOP results CSV on a suite as a run (docs/bop.md)",
        description="Score a BOP results file (scene_id,im_id,obj_id,score,R,t,time) written "
        "for `beo-bench export` of the same suite into a run directory: a leaderboard row "
        "that compare and gate pair with any other run of the suite.",
        parents=[
            *_export_parents(data, "score on"),
            out_parent(None, "default: runs/SUITE[@TRACK][~SENSOR]__METHOD"),
        ],
    )
    sc.add_argument("--suite", required=True)
    sc.add_argument("--bop-results", required=True, metavar="FILE.csv", help="the BOP results CSV")
    sc.add_argument(
        "--method",
        default=None,
        help="the name of the method's row (default: the file name up to its first _, as "
        "BOP names results files METHOD_DATASET-SPLIT.csv)",
    )
    sc.set_defaults(func=cmd_score)


def _add_compare(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``compare`` command."""
    cp = sub.add_parser(
        "compare",
        help="runs side by side; each run paired with the first on their common items",
        description="A table of the runs; then, for two or more runs of one suite, version, "
        "track and seed, each run B against the first run A: per headline metric, B - A on "
        "the items both scored, a 95% bootstrap interval that resamples items, and a "
        "verdict (better / worse / no difference for B). The verdicts are per metric and "
        "not corrected for multiple comparisons, so with many metrics one may say worse by "
        "chance: they are for reading, not for failing a build.",
        epilog="for a pass/fail check in CI use `beo-bench gate` (Holm-corrected over every "
        "metric it tests; exit status 3 on a regression): compare's exit status does not "
        "depend on its verdicts",
    )
    cp.add_argument("runs", nargs="+", help="run directories or summary.json files")
    cp.add_argument(
        "--table",
        action="store_true",
        help="only the table (runs of any suites; no pairing, no results.jsonl needed)",
    )
    cp.set_defaults(func=cmd_compare)


MAX_FAILURE_HELP = (
    "exit with status 3 (after writing the results) when the run's share of failed views is "
    "above X, in [0, 1] (0: any failure)"
)


FORCE_RERUN_HELP = (
    "discard and run again a run whose results a plugin backend scored with other code or "
    "options than it has now (its recorded code digest differs); without it such a run is "
    "refused"
)


def _add_gate(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``gate`` command."""
    from beo_bench.bench.gate import DEFAULT_ALPHA, DEFAULT_PERMUTATIONS, primary_keys

    g = sub.add_parser(
        "gate",
        help="fail (exit 3) when runs got worse than a baseline, item by item",
        description="Each run against the baseline run of the same suite, track and sensor, "
        "on the same items: per metric, pooled over the suites that measure it, a one-sided "
        "paired sign-flip permutation test over items of the worsening less the metric's "
        "margin, Holm-corrected over every test; a regression is a metric worse than the "
        "baseline by more than its margin with adjusted p at most --alpha (docs/benchmark.md, "
        "'A regression gate').",
        epilog="exit status: 0 no regression (a test or suite with too few items to fail "
        "after the correction is a warning line, 'gate cannot fail', and CANNOT FAIL in every "
        "report), 3 a regression (the reports are written "
        "first), 2 a usage error (runs that do not pair with the baseline: another suite, "
        "version, seed, track, sensor or items), 1 a failure (a damaged results file)",
    )
    g.add_argument(
        "runs",
        nargs="+",
        metavar="RUN",
        help="run directories, their summary.json, or a directory of runs (all --runs)",
    )
    g.add_argument(
        "--baseline",
        required=True,
        metavar="FILE|RUN",
        help="a baseline file (`beo-bench baseline`), a run directory or a directory of runs",
    )
    g.add_argument(
        "--metrics",
        type=gate_metric,
        nargs="+",
        default=None,
        metavar="METRIC",
        help="summary metrics to gate, each pooled over the suites that measure it (a suite "
        "that does not is skipped, and the reports say so), e.g. gross_err_rate iou_mean "
        f"(default: {' '.join(primary_keys())})",
    )
    g.add_argument(
        "--alpha",
        type=open_fraction,
        default=DEFAULT_ALPHA,
        help=f"the gate's family-wise error rate (default {DEFAULT_ALPHA})",
    )
    g.add_argument(
        "--permutations",
        type=positive_int,
        default=DEFAULT_PERMUTATIONS,
        help="random sign patterns when more than 16 items differ (default "
        f"{DEFAULT_PERMUTATIONS}; fewer are enumerated exactly)",
    )
    g.add_argument(
        "--seed", type=seed_int, default=0, help="seeds the permutations and the bootstrap"
    )
    g.add_argument("--json", type=Path, default=None, metavar="FILE", help="the verdicts as JSON")
    g.add_argument(
        "--junit",
        type=Path,
        default=None,
        metavar="FILE",
        help="JUnit XML: a test suite per backend, a test case per metric",
    )
    g.add_argument(
        "--markdown",
        type=Path,
        default=None,
        metavar="FILE",
        help="a Markdown summary (also appended to $GITHUB_STEP_SUMMARY when it is set)",
    )
    g.set_defaults(func=cmd_gate)


def _add_baseline(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``baseline`` command."""
    b = sub.add_parser(
        "baseline",
        help="write a baseline file for `gate` from runs (per-item values, to commit)",
        description="A small versioned JSON file holding each run's suite identity, backend "
        "and per-view values of every pairable metric, keyed by item: what `beo-bench gate "
        "--baseline FILE` pairs later runs with.",
    )
    b.add_argument(
        "runs",
        nargs="+",
        metavar="RUN",
        help="run directories, their summary.json, or a directory of runs (all --runs)",
    )
    b.add_argument("--out", type=Path, required=True, metavar="FILE", help="the file to write")
    b.set_defaults(func=cmd_baseline)


def _add_leaderboard(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``leaderboard`` command."""
    lb = sub.add_parser(
        "leaderboard",
        help="regenerate leaderboards/ from run summaries",
        parents=[runs_parent(), out_parent("leaderboards"), update_parent()],
    )
    lb.add_argument(
        "--ablation",
        action="store_true",
        help="the runs are one study's variants and their baseline, not a suite's every row "
        "(leaderboards/ablations/): no primary comparisons, a note naming the full page",
    )
    lb.set_defaults(func=cmd_leaderboard)


def _add_train(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``train`` command."""
    tr = sub.add_parser(
        "train",
        help="train a perception model (beo, hbeo, hbeo-mdn)",
        parents=[
            dataset_parent(("--object-size",)),
            model_parent(),
            split_parent(
                SPLITS_ALL,
                None,
                "with --objects: the dataset's split to train on (default train; all: every "
                "model, for folders too small for a hash split, which then also validates on it)",
            ),
            categories_parent(
                "classes or sets (modelnet10, shapenet-ch5, library; default: library)"
            ),
            model_name_parent("model name, a plain name (default: the default model's name)"),
            per_category_parent(
                None,
                "train instances per class (hbeo: for the crops and the default BEO subspace)",
            ),
            *render_parents(RENDER_GROUP),
        ],
    )
    tb = tr.add_argument_group("beo")
    tb.add_argument("--resolution", type=resolution_int, default=32, help="voxels per edge (D)")
    tb.add_argument("--variance-fraction", type=fraction, default=0.6, help="in (0, 1]")
    th = tr.add_argument_group("hbeo and hbeo-mdn (defaults: the default small model's)")
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


def _add_publish(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``publish`` command."""
    pb = sub.add_parser(
        "publish",
        help="write a trained model into the published models the backends load "
        "(rest-prior: fit the training split's rest prior and publish it)",
        parents=[
            _option_parent("model", choices=[*MODELS, "rest-prior"]),
            model_name_parent("the trained model (beo: default model)"),
            categories_parent("classes or sets (beo default: library)"),
            out_parent(None, "default: the package's perception/published"),
        ],
    )
    from beo_bench.perception.published import STORAGE

    pb.add_argument(
        "--storage",
        choices=STORAGE,
        default="float16",
        help="how the network's weights are stored (int8: per-channel scales, half float16's "
        "bytes; the per-category networks')",
    )
    pb.set_defaults(func=cmd_publish)


def _add_render_dataset(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``render-dataset`` command."""
    rd = sub.add_parser(
        "render-dataset",
        help="render HBEO's training crops (cached shards)",
        parents=[
            data,
            split_parent(
                SPLITS_ALL,
                None,
                "with --objects: the dataset's split to render (default train; all: every model)",
            ),
            categories_parent(
                "classes or sets (modelnet10, shapenet-ch5, library; default: library)"
            ),
            per_category_parent(None, "instances per class"),
            *render_parents(RENDER_GROUP),
        ],
    )
    rd.set_defaults(func=cmd_render_dataset)


def _add_cache(sub: Any, data: argparse.ArgumentParser) -> None:
    """The ``cache`` command."""
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


_COMMANDS = (
    _add_demo,
    _add_objects,
    _add_view,
    _add_pick_check,
    _add_run,
    _add_all,
    _add_export,
    _add_score,
    _add_compare,
    _add_gate,
    _add_baseline,
    _add_leaderboard,
    _add_train,
    _add_publish,
    _add_render_dataset,
    _add_cache,
)
"""Each command's parser, in the order ``--help`` lists them."""


def build_parser() -> argparse.ArgumentParser:
    import beo_bench

    p = _MainParser(
        prog="beo-bench",
        description="Benchmark object-centric perception (class, pose and full 3D shape from\n"
        "one segmented depth image) in simulation, and the grasps planned from it.",
        epilog=EXIT_STATUS,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"beo-bench {beo_bench.__version__}")
    # the commands' parsers take no abbreviations and suggest the closest flag on a typo, as
    # the top-level one does; only the top-level help lists the registries
    sub = p.add_subparsers(dest="command", required=True, parser_class=SuggestingParser)
    data = dataset_parent()

    for add in _COMMANDS:
        add(sub, data)
    return p


RESUME_HINTS = {
    "run": "run the same command with --resume to continue",
    "all": "run the same command again to continue (finished runs are kept)",
    "demo": "run the same command again to continue (finished runs are kept)",
    "train": "run the same command again to continue from the last finished epoch",
    "render-dataset": "run the same command again to continue (finished shards are kept)",
}
"""What to tell a user who pressed Ctrl-C, per command (the others have nothing to resume)."""


CACHE_COMMANDS = ("demo", "objects", "view", "pick-check", "run", "all", "train", "render-dataset")
"""The commands that write the asset cache, whose directory is checked as they start
(``objects.cache.check_root``); ``cache`` checks it itself."""


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line ``argv``; returns the exit status (argparse's own usage errors
    exit 2 through ``SystemExit``)."""
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        # inside: `--help` loads the backend plugins, and a broken one is a warning line
        args = build_parser().parse_args(argv)
        try:
            if args.command in CACHE_COMMANDS:  # once, before anything is computed
                from beo_bench.objects.cache import check_root

                check_root()
            return int(args.func(args))
        except ThresholdError as e:  # not an error of the command: what it found
            return _fail(str(e), e.exit_code, what="")
        except BeoBenchError as e:
            return _fail(str(e), e.exit_code)
        except OSError as e:
            return _fail(_os_error(e), 1)
        except KeyboardInterrupt:
            hint = RESUME_HINTS.get(args.command, "run the command again to start over")
            return _fail(f"interrupted; {hint}", 130, what="")


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
