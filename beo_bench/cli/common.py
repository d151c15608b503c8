"""What several commands do with their parsed options: the user's dataset, the suite a run
means, and the lines a run ends with."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

from beo_bench.bench.columns import brief_columns
from beo_bench.bench.failures import reasons_text, summary_pick_reasons
from beo_bench.bench.rundir import Summary, sensor_tag_of, track_of
from beo_bench.bench.runner import run_end
from beo_bench.bench.runs import RunContext, backend_label
from beo_bench.bench.suites import SUITES, UnknownSuiteError, get_suite
from beo_bench.bench.suites import Kind as SuiteKind
from beo_bench.cli.options import DATASET_DEFAULTS
from beo_bench.errors import UsageError
from beo_bench.objects.datasets import open_dataset, skipped_text, vet
from beo_bench.objects.sets import resolve_categories


def dataset_of(args: argparse.Namespace) -> Any:
    """The :class:`~beo_bench.objects.datasets.Dataset` that ``--objects`` names (None
    without it; loading options given without it are a usage error)."""
    root = getattr(args, "objects", None)
    if root is None:
        given = [
            f"--{k}"
            for k, default in DATASET_DEFAULTS
            if getattr(args, k.replace("-", "_"), default) != default
        ]
        if given or getattr(args, "split", None) == "all":
            given += ["--split all"] if getattr(args, "split", None) == "all" else []
            raise UsageError(f"{', '.join(given)} apply to a user dataset only: add --objects ROOT")
        return None
    dataset = open_dataset(root, args.repair, args.up, args.object_size, args.units, args.max_faces)
    # every file is built once, here in the driver, before anything uses the dataset: a bad
    # one is named now with the flag that fixes it, not found by a worker mid-run
    return vet(dataset, args.skip_bad, getattr(args, "workers", None), args.command == "objects")


def print_skipped(dataset: Any) -> None:
    """The files ``--skip-bad`` left out, at the end of a command's output."""
    if text := skipped_text(dataset):
        print(f"\n{text}")


def categories_of(args: argparse.Namespace) -> tuple[str, ...] | None:
    """``--categories`` with set names expanded (None: not given)."""
    return resolve_categories(args.categories) if args.categories else None


def split_needs_dataset(args: argparse.Namespace, dataset: Any) -> None:
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
    return [
        n
        for n, s in sorted(SUITES.items())
        if s.kind is SuiteKind.ISOLATED and s.categories is None and s.split != "ood"
    ]


def suite_named(name: str) -> Any:
    """The suite ``name``; an unknown name is a usage error (exit 2), listing the suites."""
    try:
        return get_suite(name)
    except UnknownSuiteError as e:
        raise UsageError(str(e)) from e


def run_suite(args: argparse.Namespace, track: str | None = None) -> tuple[Any, Any]:
    """The suite a ``run``, ``export`` or ``score`` command means, and the user's dataset
    (None: the library): ``--suite`` with ``--episodes``, ``--seed``, ``track``,
    ``--categories``, ``--objects`` and ``--sensor``."""
    # --track on a suite without tracks is a usage error here
    suite = suite_named(args.suite).with_overrides(size=args.episodes, seed=args.seed, track=track)
    if args.categories:
        # a class subset is its own suite (pose-3dof+modelnet10): its own runs and page
        suite = suite.with_categories(args.categories)
    dataset = dataset_of(args)
    split_needs_dataset(args, dataset)
    if dataset is not None:
        suite = suite.with_dataset(dataset, args.split)
    return suite.with_sensor(args.sensor), dataset  # None: the suite's own sensor


def print_run_end(ctx: RunContext, out: Any, label: bool = True) -> None:
    """A run's last lines: its failures by exception, its pick reasons, its report (a run
    in which every view failed also warns on stderr); ``label``: name the run (``all``)."""
    who = f"{ctx.suite.label} / {backend_label(ctx.backend.name, ctx.backend.kwargs)}"
    end = run_end(out, ctx.suite.size, who if label else "")
    print(f"\n{end.text()}")
    end.warn()


COLUMNS = brief_columns()
"""The plain-text table's metric columns (``bench.columns``: one list for every table)."""


def format_runs(runs: Sequence[Summary | dict[str, Any]]) -> str:
    """A plain table of runs: one row per run (its suite and track, backend and options),
    the columns that any of them measured."""
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
    for s in summaries:  # a pick run's episodes by reason (docs/env.md, "Why a pick fails")
        if reasons := summary_pick_reasons(s):
            lines.append(f"pick reasons, {where(s)} {who(s)}: {reasons_text(reasons)}")
    return "\n".join(lines)
