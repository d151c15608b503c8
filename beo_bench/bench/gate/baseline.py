"""The runs a gate reads: run directories (a run's scored per-view values) and the baseline file
(``beo-bench baseline``: the per-view values of one or more runs, small enough to commit).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from beo_bench.atomic import atomic_write_bytes
from beo_bench.bench import compare
from beo_bench.bench.columns import BY_KEY, value_range
from beo_bench.bench.gate.spec import GateUsageError
from beo_bench.bench.rows import scan_rows, span
from beo_bench.bench.rundir import (
    RESULTS_NAME,
    SUMMARY_NAME,
    ItemsIdentity,
    load_summary,
    sensor_tag_of,
    summary_size,
    track_of,
)
from beo_bench.errors import CorruptDataError
from beo_bench.stats import (
    ViewKey,
)

BASELINE_FORMAT = "beo-bench-baseline"
BASELINE_VERSION = 1
"""The baseline file's ``format`` and ``version``: a reader refuses any other (a file of a
newer version may hold values this version would misread)."""


# -- a run as the gate reads it ---------------------------------------------------------------
@dataclass(frozen=True)
class ScoredRun:
    """A run, from its directory or from a baseline file: what identifies its items and
    their scoring, and each view's value of every pairable metric (NaN: not scored)."""

    source: str
    """Where it was read (a run directory, or ``FILE#label``), for messages."""
    label: str
    """``SUITE[@TRACK][~SENSOR]``: what pairs a run with its baseline."""
    identity: ItemsIdentity
    """What fixed its items and their scoring (a baseline's must be the same)."""
    backend: str
    """The backend and its options, as tables name them (``icp (starts=48)``)."""
    views: tuple[ViewKey, ...]
    """Every scored (item, view), sorted."""
    values: dict[str, dict[ViewKey, float]]
    git_commit: str | None = None

    @property
    def items(self) -> frozenset[int]:
        return frozenset(i for i, _ in self.views)

    @property
    def suite(self) -> str:
        return self.identity.suite


def suite_label(summary: dict[str, Any]) -> str:
    """``SUITE[@TRACK][~SENSOR]`` of a run's summary (the sensor only when it is not the
    suite's own, as the run's directory name has it)."""
    track = track_of(summary)
    text = f"{summary['suite']}@{track}" if track else str(summary["suite"])
    tag = sensor_tag_of(summary)
    return text + (f"~{tag}" if tag else "")


def _check_results(where: Path, summary: dict[str, Any]) -> None:
    """Refuse a run whose ``results.jsonl`` is damaged (:class:`CorruptDataError`, exit
    status 1): lines that do not parse, a torn last line, an item's rows incomplete or
    twice, or fewer items than its summary covers. Read past, the lost items would leave
    the test (and could flip its verdict) or read as a run of other items."""
    results = where / RESULTS_NAME
    if not results.is_file():
        return  # compare.run_from says so
    scan = scan_rows(results)
    damage = scan.report(results)
    size = summary_size(summary)
    if not damage and size is not None:
        lost = set(range(size)) - {r.item for r in scan.rows}
        if lost:
            damage = (
                f"{results}: holds no rows of {len(lost)} of the {size} items its summary "
                f"covers (items {span(lost)})"
            )
    if damage:
        raise CorruptDataError(
            f"{damage}: the results file is damaged, so the gate cannot pair its items; run "
            "the same `beo-bench run` command again with --resume (it scores the lost items "
            "again and rewrites the summary), then gate it"
        )


def scored_run(where: Path, summary: dict[str, Any]) -> ScoredRun:
    """The :class:`ScoredRun` of a run directory and its loaded summary (the rows of the
    items the summary covers)."""
    from beo_bench.bench.runs import backend_label

    _check_results(where, summary)
    run = compare.run_from(where, summary)
    values = {k: v for k, v in compare.view_values(run).items() if k in BY_KEY and BY_KEY[k].paired}
    prov = summary.get("provenance", {})
    return ScoredRun(
        source=str(where),
        label=suite_label(summary),
        identity=ItemsIdentity.of(summary),
        backend=backend_label(str(summary["backend"]), prov.get("backend_kwargs") or {}),
        views=tuple(sorted((int(r["item"]), int(r["view"])) for r in run.rows)),
        values=values,
        git_commit=prov.get("git_commit"),
    )


def find_runs(paths: Iterable[Path | str]) -> list[tuple[Path, dict[str, Any]]]:
    """The runs at ``paths``: each a run directory, its ``summary.json``, or a directory of
    run directories (``beo-bench all --runs``: every sub-directory holding a
    ``summary.json``). A path with no run is a :class:`GateUsageError`."""
    out: list[tuple[Path, dict[str, Any]]] = []
    for given in paths:
        p = Path(given)
        if p.is_file() or (p / SUMMARY_NAME).is_file():
            out.append(load_summary(p))
            continue
        if not p.is_dir():
            raise GateUsageError(
                f"{p} does not exist: give run directories, their summary.json, or the --runs "
                "directory of `beo-bench all`"
            )
        subs = sorted(d for d in p.iterdir() if (d / SUMMARY_NAME).is_file())
        if not subs:
            raise GateUsageError(
                f"{p} holds no run (no summary.json in it or in its sub-directories): give run "
                "directories, or the --runs directory of `beo-bench all`"
            )
        out += [load_summary(d) for d in subs]
    return out


def load_runs(paths: Iterable[Path | str]) -> list[ScoredRun]:
    """:func:`find_runs`, each read as a :class:`ScoredRun`."""
    return [scored_run(where, summary) for where, summary in find_runs(paths)]


# -- the baseline file -------------------------------------------------------------------------
def _number(x: float) -> float | None:
    """A value as the file holds it: NaN (not scored) as null; JSON has no NaN."""
    return float(x) if math.isfinite(x) else None


def baseline_entry(run: ScoredRun) -> dict[str, Any]:
    """One run as a baseline file holds it: its identity, its views per item (``views``:
    item -> view indices) and, per metric, each item's values in that order (``values``:
    metric -> item -> list; null where a view is not scored on it)."""
    per_item: dict[int, list[int]] = {}
    for item, view in run.views:
        per_item.setdefault(item, []).append(view)
    return {
        "label": run.label,
        "suite": run.identity.suite,
        "suite_version": run.identity.suite_version,
        "seed": run.identity.seed,
        "track": run.identity.track,
        "sensor": run.identity.sensor,
        "library_version": run.identity.library_version,
        "suite_record": run.identity.record,
        "backend": run.backend,
        "git_commit": run.git_commit,
        "views": {str(i): vs for i, vs in per_item.items()},
        "values": {
            key: {str(i): [_number(vals[(i, v)]) for v in vs] for i, vs in per_item.items()}
            for key, vals in sorted(run.values.items())
        },
    }


def baseline_json(runs: Sequence[ScoredRun]) -> dict[str, Any]:
    """The baseline file's content for ``runs`` (one entry each). Two runs of one suite
    label by one backend would be ambiguous: :class:`GateUsageError`."""
    seen: dict[tuple[str, str], str] = {}
    for r in runs:
        first = seen.setdefault((r.label, r.backend), r.source)
        if first != r.source:
            raise GateUsageError(
                f"{first} and {r.source} are both runs of {r.label} by {r.backend}: give one "
                "of them to `beo-bench baseline`"
            )
    return {
        "format": BASELINE_FORMAT,
        "version": BASELINE_VERSION,
        "runs": [baseline_entry(r) for r in runs],
    }


def write_baseline(runs: Sequence[ScoredRun], path: Path | str) -> Path:
    """Write the baseline file of ``runs`` at ``path`` (atomically: a CI job reading it
    sees the old file or the new one)."""
    path = Path(path)
    text = json.dumps(baseline_json(runs), separators=(",", ":"), sort_keys=False)
    path.parent.mkdir(parents=True, exist_ok=True)  # ci/baseline.json in a fresh checkout
    atomic_write_bytes(path, text + "\n")
    return path


def _bad_file(path: Path, why: str) -> GateUsageError:
    return GateUsageError(
        f"{path} is not a readable beo-bench baseline ({why}): write it again with "
        f"`beo-bench baseline RUN ... --out {path}`"
    )


def _item_order(i: str) -> tuple[int, str]:
    return (int(i), i) if i.lstrip("-").isdigit() else (0, i)


def _checked(key: str, item: str, x: Any) -> float:
    """A baseline value of metric ``key`` (null is read as NaN before): a number in the
    metric's range (:func:`beo_bench.bench.columns.value_range`), else a ValueError naming
    the item."""
    if isinstance(x, bool) or not isinstance(x, int | float):
        raise ValueError(f"{key} of item {item} is {x!r}, not a number")
    lo, hi = value_range(key)
    value = float(x)
    if not (math.isfinite(value) and lo <= value <= hi):
        raise ValueError(f"{key} of item {item} is {x!r}, outside its range [{lo:g}, {hi:g}]")
    return value


def _entry_run(path: Path, k: int, e: Any) -> ScoredRun:
    """Entry ``k`` of the baseline file ``path`` as a :class:`ScoredRun`."""
    if not isinstance(e, dict):
        raise _bad_file(path, f"run {k} is not an object")
    try:
        views = sorted((int(i), int(v)) for i, vs in e["views"].items() for v in vs)
        values: dict[str, dict[ViewKey, float]] = {}
        for key, per_item in e["values"].items():
            vals: dict[ViewKey, float] = {}
            missing = sorted(e["views"].keys() - per_item.keys(), key=_item_order)
            if missing:  # dropped silently, the item would leave the test and flip it
                raise ValueError(f"{key} has no values for item {missing[0]}, which it scored")
            for i, xs in per_item.items():
                order = e["views"][i]
                if len(xs) != len(order):
                    raise ValueError(
                        f"{key} of item {i} has {len(xs)} values for {len(order)} views"
                    )
                for v, x in zip(order, xs, strict=True):
                    vals[(int(i), int(v))] = math.nan if x is None else _checked(key, i, x)
            values[str(key)] = vals
        return ScoredRun(
            source=f"{path}#{e['label']}",
            label=str(e["label"]),
            identity=ItemsIdentity(
                suite=str(e["suite"]),
                suite_version=e["suite_version"],
                seed=e["seed"],
                track=e["track"],
                sensor=str(e["sensor"]),
                library_version=e["library_version"],
                record=dict(e["suite_record"]),
            ),
            backend=str(e["backend"]),
            views=tuple(views),
            values=values,
            git_commit=e.get("git_commit"),
        )
    except (KeyError, TypeError, ValueError, AttributeError) as err:
        raise _bad_file(path, f"run {k}: {type(err).__name__} {err}") from None


def read_baseline_file(path: Path | str) -> list[ScoredRun]:
    """The runs of a baseline file (:func:`write_baseline`). A file of another format or
    version, or a damaged one, is a :class:`GateUsageError` saying how to write it again."""
    path = Path(path)
    try:
        obj = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise _bad_file(path, f"{type(e).__name__}: {e}") from None
    if not isinstance(obj, dict) or obj.get("format") != BASELINE_FORMAT:
        raise _bad_file(path, f"its format is not {BASELINE_FORMAT!r}")
    if obj.get("version") != BASELINE_VERSION:
        raise GateUsageError(
            f"{path} is a baseline of format version {obj.get('version')!r}; this beo-bench "
            f"reads version {BASELINE_VERSION}: write it again with `beo-bench baseline RUN "
            f"... --out {path}` (or use the beo-bench that wrote it)"
        )
    runs = obj.get("runs")
    if not isinstance(runs, list) or not runs:
        raise _bad_file(path, "it holds no run")
    return [_entry_run(path, k, e) for k, e in enumerate(runs)]


def is_baseline_file(path: Path | str) -> bool:
    """Whether ``path`` is a file that is not a run's ``summary.json`` (so: read as a
    baseline file, which says what is wrong with it if it is not one)."""
    p = Path(path)
    return p.is_file() and p.name != SUMMARY_NAME


def load_baseline(path: Path | str) -> list[ScoredRun]:
    """The baseline runs at ``path``: a baseline file, or runs (:func:`find_runs`)."""
    if not Path(path).exists():
        raise GateUsageError(
            f"--baseline {path} does not exist: give a baseline file (write one with "
            "`beo-bench baseline RUN ... --out FILE`), a run directory or a directory of runs"
        )
    return read_baseline_file(path) if is_baseline_file(path) else load_runs([path])
