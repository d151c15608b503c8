"""``beo-bench leaderboard``: the page assembly (a part per track and sensor, sections, the
index) and the regeneration of ``leaderboards/`` from run summaries into a marked folder.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from beo_bench.atomic import atomic_write_bytes
from beo_bench.bench import ablations, rundir
from beo_bench.bench.pages.entries import (
    DIGEST_CHARS,
    OOD_SUFFIX,
    PER_CATEGORY_SUITES,
    TABLE_5_1_SUITES,
    TRACK_NOTES,
    Row,
    label,
    load_rows,
)
from beo_bench.bench.pages.pick import (
    MethodComparison,
    attach_episodes,
    is_pick_suite,
    page_json,
    pick_category_table,
    pick_comparison_json,
    pick_comparison_table,
    pick_comparisons,
)
from beo_bench.bench.pages.plots import _plots
from beo_bench.bench.pages.sensors import (
    SENSOR_NOTE,
    SensorPair,
    _sensor_json,
    robustness,
    sensor_rows,
)
from beo_bench.bench.pages.tables import (
    category_table,
    confused_pairs_table,
    confusion_counts,
    field_table,
    modelnet10_table,
    nocs_class_tables,
    suite_table,
    table_5_1,
)
from beo_bench.bench.pages.verdicts import (
    Section,
    Verdict,
    _primary_json,
    _verdict_json,
    degradation_table,
    gap_table,
    paired_verdicts,
    primary_results,
    primary_table,
    sections,
    track_rows,
    verdict_table,
)
from beo_bench.bench.runs import RunError
from beo_bench.errors import UsageError


# -- the pages -----------------------------------------------------------------------------------
def _newest(rows: list[Row]) -> tuple[int, list[Row], dict[int, int]]:
    """The newest suite version, its runs, and how many runs each older version has."""
    newest = max(int(r.summary["suite_version"]) for r in rows)
    older: dict[int, int] = {}
    for r in rows:
        v = int(r.summary["suite_version"])
        if v != newest:
            older[v] = older.get(v, 0) + 1
    return newest, [r for r in rows if r.summary["suite_version"] == newest], older


def _prefix(suite: str, track: str | None, sensor: str | None = None) -> str:
    where = f"{suite}_{sensor}" if sensor else suite
    return f"{where}_{track}" if track else where


def _heading(suite: str, track: str | None, sensor: str | None = None) -> str:
    where = f"{suite}, {track} track" if track else suite
    return f"{where}, sensor {sensor}" if sensor else where


def _partial_note(suite: str, tracks: dict[str | None, list[Section]]) -> str:
    """The line under a suite's title (its page's and the README's) when the sections shown
    first (the README's) cover fewer items than the suite's size, else ``""``."""
    parts = {t: secs[0].partial for t, secs in tracks.items() if secs and secs[0].partial}
    if not parts:
        return ""
    if len(set(parts.values())) == 1 and len(parts) == len(tracks):
        covered = next(iter(parts.values()))
    else:
        covered = "; ".join(f"{_heading(suite, t)}: {p}" for t, p in parts.items())
    return f"**Partial**: the runs shown first cover {covered}."


@dataclass
class _Page:
    """What a suite's page collects while it is built."""

    md: list[str]
    index: list[str]
    plots: list[str]
    verdicts: list[Verdict]
    shown: dict[int, dict[str, Any]]
    sensor_ablations: list[tuple[str, ablations.AblationResult]] = field(default_factory=list)
    """The ablations of the parts of sensors other than the suite's own (with the sensor)."""
    robustness: list[SensorPair] = field(default_factory=list)
    ablations: list[ablations.AblationResult] = field(default_factory=list)
    comparisons: list[MethodComparison] = field(default_factory=list)
    """A pick page's method comparisons (:func:`pick_comparisons`), every sensor's part."""


def _track_part(
    page: _Page,
    out: Path,
    suite: str,
    track: str | None,
    secs: list[Section],
    firsts: dict[tuple[str, str | None, str | None], Section],
    sensor: str | None = None,
) -> None:
    """A track's part of the suite page: its sections, the first with the extra tables.
    ``sensor``: the part of a sensor other than the suite's own (its headings one level
    down, under the sensor's)."""
    top = "###" if sensor else "##"
    level = top + "#" if track else top
    if track:
        page.md += [f"{top} {track} track", "", TRACK_NOTES.get(track, ""), ""]
    for i, sec in enumerate(secs):
        table = suite_table(sec.rows)
        page.md += [f"{level} {sec.title}", "", table, ""]
        for r in sec.rows:
            page.shown.setdefault(id(r.summary), r.summary)
        if i:
            continue
        verdicts = paired_verdicts(sec, sensor)
        page.verdicts += verdicts
        vt = verdict_table(verdicts)
        # ablations pair runs across this seed's sections (a variant may cover a prefix)
        same_seed = [r for s in secs if s.seed == sec.seed for r in s.rows]
        abl = ablations.ablation_results(
            track, same_seed, label, by_category=suite in PER_CATEGORY_SUITES
        )
        if sensor is None:
            page.ablations += abl
        else:
            page.sensor_ablations += [(sensor, a) for a in abl]
        at = ablations.ablation_table(abl)
        # the learned rows' training-seed spread (issue 47), under the suite's own sensor
        st = ablations.seed_table(ablations.seed_spreads(sec.rows, label)) if not sensor else ""
        picks = pick_comparisons(sec, sensor) if is_pick_suite(suite) else []
        page.comparisons += picks
        # the suite's own sensor shows these pairs once, as the page's primary comparisons
        # (Holm-corrected); under another sensor they are exploratory
        mt = pick_comparison_table(picks) if sensor is not None else ""
        vt = "\n\n".join(t for t in (vt, at, st, mt) if t)
        if sensor is None:  # the index shows the suite's own sensor (and the robustness)
            page.index += [f"### {_heading(suite, track)}: {sec.title}", "", table, ""]
            page.index += [vt, ""] if vt else []
        summaries = [r.summary for r in sec.rows]
        gap = gap_table(summaries)
        base = suite.removesuffix(OOD_SUFFIX)
        twin = firsts.get((base, track, sensor)) if base != suite else None
        extra = [vt, gap] + ([degradation_table(base, twin.rows, suite, sec.rows)] if twin else [])
        page.md += [t + "\n" for t in extra if t]
        page.md += [_per_category(suite, sec.rows), ""]  # there, empty or not
        for _, draw in SECTION_TABLES:
            extra_table = draw(suite, sec.rows)
            page.md += [extra_table, ""] if extra_table else []
        plots = _plots(out, _prefix(suite, track, sensor), _heading(suite, track, sensor), sec.rows)
        page.plots += plots
        page.md += [*[f"![{p}]({p})" for p in plots], ""]


def _per_category(suite: str, rows: list[Row]) -> str:
    """A section's per-category table (a pick suite's counts episodes)."""
    return pick_category_table(rows) if is_pick_suite(suite) else category_table(suite, rows)


SectionTable = Callable[[str, list[Row]], str]
"""A table a track's first section shows after its per-category table, drawn from the suite
and the section's rows; ``""`` where it does not apply (the table is then left out)."""
SECTION_TABLES: tuple[tuple[str, SectionTable], ...] = (
    ("Tables 5.1/5.2", lambda suite, rows: table_5_1(rows) if suite in TABLE_5_1_SUITES else ""),
    ("the field's figures", lambda _, rows: field_table(rows)),
    ("NOCS per class", lambda _, rows: nocs_class_tables(rows)),
    ("Tables 3.1/4.1", modelnet10_table),
    ("confusions", lambda _, rows: confused_pairs_table(rows)),
    ("confusion matrices", confusion_counts),
)
"""The first section's further tables, in page order: a table added here is on every page
it applies to."""


MARKER_NAME = ".beo-bench-leaderboards"
LOCK_NAME = ".beo-bench-leaderboards.lock"
"""What a regeneration holds (an exclusive ``flock``, its PID in it) while it writes."""
MARKER_TEXT = (
    "This directory is a leaderboard directory of beo-bench (`beo-bench leaderboard`, "
    "`beo-bench all`).\n"
    "Regenerating rewrites its files only while this file marks the directory as its own.\n"
)
"""The file marking a directory :func:`regenerate` made. Without it a non-empty directory is
refused, even one holding only names a leaderboard writes (``README.md``, ``<suite>.md``):
those could be the user's own, and regenerating replaces and removes files."""


def check_out(out: Path | str) -> None:
    """A :class:`~beo_bench.errors.UsageError` unless ``out`` may take a leaderboard: it
    does not exist, is empty or carries :data:`MARKER_NAME` (``beo-bench all`` asks before
    its runs, so a refusal costs no hours of scoring)."""
    from beo_bench import outdir

    out = Path(out)
    if not out.is_dir():
        return  # created by regenerate (or a file there: mkdir says so)
    try:
        held = outdir.foreign_files(out, MARKER_NAME)
    except OSError as e:
        raise UsageError(f"--out {out} cannot be read ({e}): choose another --out") from e
    if held:
        raise UsageError(
            f"--out {out} is a non-empty directory that beo-bench did not create (it holds "
            f"{outdir.shown(held)} and no {MARKER_NAME}): give --out a new or empty "
            "directory; nothing in this one is touched"
        )


def _mark_out(out: Path) -> None:
    from beo_bench import outdir

    if not (out / MARKER_NAME).is_file():
        outdir.mark(out, MARKER_NAME, MARKER_TEXT)


@dataclass
class _Kept:
    """A suite page ``regenerate(update=True)`` keeps as it is: its files and its part of
    the index, as the last regeneration wrote them."""

    files: set[str]
    index: list[str]


_INDEX_HEAD = "## ["


def _index_parts(readme: Path) -> dict[str, list[str]]:
    """The index's part of each suite (from its ``## [suite](suite.md)`` heading to the
    next), by suite name; empty when there is no index."""
    if not readme.is_file():
        return {}
    parts: dict[str, list[str]] = {}
    current: list[str] | None = None
    for line in readme.read_text().splitlines():
        if line.startswith(_INDEX_HEAD) and "](" in line:
            current = parts.setdefault(line[len(_INDEX_HEAD) : line.index("](")], [])
        elif line.startswith("## "):  # another part of the index (the suites not yet run)
            current = None
        if current is not None:
            current.append(line)
    return parts


def _kept_pages(out: Path, fresh: set[str]) -> dict[str, tuple[_Kept, list[Row]]]:
    """The pages in ``out`` of registered suites that have no runs now (``fresh`` are those
    that do) and whose every row is of the suite's current version, with their rows. A page
    of an older version is not kept: it goes, as its runs are no longer comparable."""
    from beo_bench.bench.suites import UnknownSuiteError, get_suite

    parts = _index_parts(out / "README.md")
    kept = {}
    for path in sorted(out.glob("*.json")):
        suite = path.stem
        if suite.endswith("_paired") or suite in fresh or suite not in parts:
            continue
        try:
            version = get_suite(suite).version
        except UnknownSuiteError:
            continue
        rows = [Row(s) for s in json.loads(path.read_text())]
        if not rows or any(int(r.summary["suite_version"]) != version for r in rows):
            continue
        md = out / f"{suite}.md"
        text = md.read_text() if md.is_file() else ""
        plots = {ln[ln.index("](") + 2 : -1] for ln in text.splitlines() if ln.startswith("![")}
        files = {md.name, path.name, f"{suite}_paired.json", *plots}
        kept[suite] = (_Kept(files, parts[suite]), rows)
    return kept


ABLATION_NOTE = (
    "An ablation page (`beo-bench leaderboard --ablation`): the rows of one study, variants "
    "of a backend and the baseline they pair with, on {suite}'s items, made from those runs "
    "alone. The suite's own page (`leaderboards/{suite}.md`) holds every row, its primary "
    "comparisons and its sensors; the verdicts here are exploratory and uncorrected."
)
"""What an ablation page says first (:func:`regenerate`'s ``ablation``)."""


def regenerate(
    runs: Path | str = "runs",
    out: Path | str = "leaderboards",
    update: bool = False,
    ablation: bool = False,
) -> list[Path]:
    """Rewrite ``out`` from the summaries under ``runs``; returns the suites' Markdown files.
    Its own files (named after a suite) that no run produces any more are removed. ``out``
    must be new, empty or marked as a leaderboard directory (:func:`check_out`).

    ``update`` (``--update``): a suite with no runs under ``runs`` keeps its page, files and
    index part as they are in ``out``, if every row there is of the suite's current
    version, so that a campaign too long for one machine's session can be run suite by
    suite. Each page is still made from one regeneration's runs: its rows, paired verdicts
    and plots always come from the same runs.

    ``ablation`` (``--ablation``): the runs are one study's variant rows and their baseline,
    not a suite's every row (``leaderboards/ablations/``): its pages carry no primary
    comparisons (a family of a page's few rows would be corrected over the wrong family)
    and say where the suite's full page is."""
    from beo_bench import outdir

    out = Path(out)
    check_out(out)
    out.mkdir(parents=True, exist_ok=True)
    _mark_out(out)

    def busy(pid: str) -> Exception:
        return RunError(
            f"--out {out} is being regenerated by another process (PID {pid}, holding "
            f"{out / LOCK_NAME}): wait for it, or give --out another directory"
        )

    with outdir.locked(out / LOCK_NAME, busy):  # one writer per leaderboard directory
        return _regenerate(Path(runs), out, update, ablation)


def _regenerate(runs: Path, out: Path, update: bool, ablation: bool) -> list[Path]:
    by_suite: dict[str, list[Row]] = {}
    for r in load_rows(Path(runs)):
        by_suite.setdefault(r.summary["suite"], []).append(r)
    kept = _kept_pages(out, set(by_suite)) if update else {}
    # every suite's sections first: an -ood suite's page compares with its base's first one
    # (under the same sensor)
    plan: dict[str, tuple[int, dict[int, int], dict[str | None, dict[str | None, list[Section]]]]]
    plan = {}
    firsts: dict[tuple[str, str | None, str | None], Section] = {}
    for suite, (_, kept_rows) in kept.items():
        version, newest, _older = _newest(kept_rows)
        for tag, kept_tracks in _parts(suite, version, newest).items():
            firsts.update({(suite, t, tag): secs[0] for t, secs in kept_tracks.items()})
    for suite, rows in sorted(by_suite.items()):
        version, newest, older = _newest(rows)
        if is_pick_suite(suite):  # the page's JSON holds every pick run's episodes
            attach_episodes(newest)
        parts = _parts(suite, version, newest)
        plan[suite] = (version, older, parts)
        for tag, tracks in parts.items():
            firsts.update({(suite, t, tag): secs[0] for t, secs in tracks.items()})
    keep: set[str] = {"README.md"}
    index_parts: dict[str, list[str]] = {}
    for suite, (k, _) in kept.items():
        keep |= k.files
        index_parts[suite] = k.index + ([""] if k.index and k.index[-1] else [])
    written = []
    index = [
        "# Leaderboards",
        "",
        # RUNS, not the path given: a page names no machine's directories
        "Generated by `beo-bench leaderboard --runs RUNS` (RUNS: the run directories) "
        "from the run summaries (each "
        "suite's JSON holds them, with provenance: git commit, package versions, machine, "
        "seeds). Means over every view, a failed view counted at its worst case, with "
        "bootstrap 95% intervals (items resampled) in brackets. Pose suites have two "
        "tracks: *class-given* (every backend that can use the true class is told it; those "
        "that cannot are listed from their class-free run, marked *(hint not used)*) and "
        "*class-free*. Runs of other seeds or item counts are in separate sections of each "
        "page; *partial* marks fewer items than the suite's size. `model` is the first "
        f"{DIGEST_CHARS} hex digits of the backend's model digest. *Bounds* are not methods: "
        "`oracle` returns the truth, `random` guesses, and a backend marked *privileged* was "
        "handed the truth (listed with the bounds, never ranked or paired). `class acc.` "
        "reads *given* where the "
        "backend was told the class. F-score@1%: tau = 1% of the canonical cube's side. "
        "`BOP AR`: the mean of BOP 2019's average recalls (AR_VSD, AR_MSSD, AR_MSPD), which "
        "each pose section's page lists beside the NOCS report (docs/bop.md); runs made "
        "before these were scored show `-`.",
        "",
    ]
    for suite, (version, older, parts) in plan.items():
        page = _Page([], [], [], [], {})
        tracks = parts.get(None, {})  # the suite's own sensor
        desc = _description([t for p in parts.values() for t in p.values()])
        page.md = [f"# {suite} (suite version {version})", "", desc, ""]
        partial = _partial_note(suite, tracks)
        page.md += [partial, ""] if partial else []
        if ablation:
            page.md += [ABLATION_NOTE.format(suite=suite), ""]
        if older:
            left = ", ".join(f"v{v}: {n} run(s)" for v, n in sorted(older.items()))
            page.md += [f"Runs of older suite versions are left out ({left}): not comparable.", ""]
        # the comparisons the page exists to make, Holm-corrected as one family, apart from
        # the exploratory verdicts of the tracks' sections (issue 47)
        primary = [] if ablation else primary_results(suite, tracks)
        if any(x.result is not None for x in primary):
            page.md += ["## Primary comparisons", "", primary_table(primary), ""]
            page.index += [f"### {suite}: primary comparisons", "", primary_table(primary), ""]
        for track, secs in tracks.items():
            _track_part(page, out, suite, track, secs, firsts)
        robust = robustness(suite, parts)
        page.robustness = robust.pairs
        if robust.tracks:
            page.md += ["## Robustness across sensors", "", robust.markdown("###"), ""]
            page.index += [
                f"### {suite}: robustness across sensors",
                "",
                robust.markdown("####"),
                "",
            ]
        own = rundir.default_sensor_of(suite)
        for tag, sensor_tracks in parts.items():
            if tag is None:
                continue
            page.md += [f"## sensor {tag}", "", SENSOR_NOTE.format(sensor=tag, own=own), ""]
            for track, secs in sensor_tracks.items():
                _track_part(page, out, suite, track, secs, firsts, sensor=tag)
        path = out / f"{suite}.md"
        atomic_write_bytes(path, "\n".join(page.md))
        shown = list(page.shown.values())
        atomic_write_bytes(out / f"{suite}.json", page_json(shown))
        paired_json = [_verdict_json(v) for v in page.verdicts]
        paired_json += [ablations.ablation_json(x) for x in page.ablations]
        paired_json += [
            {**ablations.ablation_json(x), "sensor": t} for t, x in page.sensor_ablations
        ]
        paired_json += [_sensor_json(p) for p in page.robustness]
        paired_json += [_primary_json(x) for x in primary if x.result is not None]
        paired_json += [pick_comparison_json(c) for c in page.comparisons]
        atomic_write_bytes(
            out / f"{suite}_paired.json", json.dumps(paired_json, indent=2, sort_keys=True) + "\n"
        )
        keep |= {path.name, f"{suite}.json", f"{suite}_paired.json", *page.plots}
        written.append(path)
        mark = " *(partial)*" if partial else ""
        part = [f"## [{suite}]({suite}.md){mark}", "", desc, ""]
        index_parts[suite] = [*part, *([partial, ""] if partial else []), *page.index]
    for suite in sorted(index_parts):
        index += index_parts[suite]
    from beo_bench.bench.suites import get_suite, list_suites

    ours = tuple(list_suites())
    pending = [s for s in ours if s not in index_parts]
    if pending and not ablation:
        index += [
            "## Not yet run at their current suite version",
            "",
            ", ".join(f"`{s}` (v{get_suite(s).version})" for s in pending)
            + ": `beo-bench all --update --suites SUITE` makes their pages.",
            "",
        ]
    atomic_write_bytes(out / "README.md", "\n".join(index))
    for stale in out.iterdir():  # our files of suites or backends no longer in the runs
        if stale.is_file() and stale.name.startswith(ours) and stale.name not in keep:
            stale.unlink()
    return written


def _parts(
    suite: str, version: int, rows: list[Row]
) -> dict[str | None, dict[str | None, list[Section]]]:
    """The page's parts: per sensor (None: the suite's own, first), its tracks' sections."""
    return {
        tag: {t: sections(suite, version, t, trs) for t, trs in track_rows(srows).items()}
        for tag, srows in sensor_rows(rows).items()
    }


def _description(all_sections: list[list[Section]]) -> str:
    for secs in all_sections:
        for sec in secs:
            for r in sec.rows:
                d = r.summary.get("provenance", {}).get("suite", {}).get("description")
                if d:
                    return str(d)
    return ""
