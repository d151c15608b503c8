"""A run directory: its files, what identifies its run, its lock, the checks a resume
makes and its summary; its rows and results file are :mod:`beo_bench.bench.rows`.

A run directory holds :data:`RECORD_NAME` (``run.json``: the run's identity with its
model and code digests), :data:`RESULTS_NAME` (``results.jsonl``: one
:class:`~beo_bench.bench.rows.Row` a line), :data:`SUMMARY_NAME` (``summary.json``: a
:class:`Summary`), :data:`LOCK_NAME` and :data:`MARKER_NAME` (and :data:`REPORT_NAME` when
asked for). ``beo-bench run`` and ``beo-bench score`` write one; ``compare``, ``gate`` and
the leaderboards read them.

**One definition of "same run".** What fixes a run's items and their scores is its suite
record without :data:`UNSCORED_SUITE_KEYS` (:func:`scored_suite`: name, version, seed,
track, protocol, sensor and its model's version, dataset) and the object library version.
A resume also needs the same backend and options (:func:`run_identity`, recorded in
``run.json`` and checked by :func:`check_same_run`); two runs of different backends pair
(``compare``, ``gate``) when their :class:`ItemsIdentity` agree
(:meth:`ItemsIdentity.differences`).

Integrity (see the "Failure behaviour" doc):

- one run at a time per directory: :func:`lock_run_dir` holds an exclusive ``flock`` on
  ``OUT/run.lock`` (with its PID in it); a second run gets a :class:`RunError` naming the
  holder. The kernel drops the lock when the holder dies, so a stale lock file blocks
  nothing (and is never deleted: the next run reuses it);
- each finished item is appended as whole lines to a file opened with ``O_APPEND``
  (:class:`~beo_bench.bench.rows.ResultsWriter`); a failed write (a full disk) cuts the
  file back to its last complete item and stops the run with a :class:`RunError`;
- reading (:func:`~beo_bench.bench.rows.scan_rows`) skips and reports (a
  :class:`~beo_bench.bench.rows.ResultsWarning`) any line that is not a result row, an
  item's rows that are incomplete and a second set of rows of an item; a torn last line is
  cut off (when repairing, under the lock);
- JSON files (record, summary) are written atomically (:func:`write_json_atomic`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import json
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from beo_bench.atomic import atomic_write_bytes
from beo_bench.bench.pool import jsonable
from beo_bench.bench.rows import io_error
from beo_bench.bench.runs import (
    CorruptRunError,
    RunConfig,
    RunContext,
    RunError,
    RunUsageError,
)
from beo_bench.errors import CorruptDataError, UsageError

LOCK_NAME = "run.lock"
RESULTS_NAME = "results.jsonl"
RECORD_NAME = "run.json"
SUMMARY_NAME = "summary.json"
REPORT_NAME = "report.html"
"""The run's offline report of its worst views (:mod:`beo_bench.bench.worstviews`)."""
MARKER_NAME = ".beo-bench-run"
MARKER_TEXT = (
    "This directory is a run directory of beo-bench (`beo-bench run --out`, `beo-bench all`).\n"
    "A run writes and resumes here only while this file marks the directory as its own.\n"
)
"""The file marking a directory a run made: a run writes only into an empty directory or
one carrying it, so nothing the user keeps in a folder given as ``--out`` is replaced."""
FORCE_RERUN_FLAG = "--force-rerun"
"""The flag of ``run`` and ``all`` that discards results scored by other plugin code."""


def json_text(obj: Any, indent: int | None = 2, allow_nan: bool = True) -> str:
    """``obj`` as the JSON text a run directory holds (keys sorted; numpy values as
    numbers); ``allow_nan=False``: a NaN or infinity is a ValueError."""
    return json.dumps(obj, indent=indent, sort_keys=True, default=jsonable, allow_nan=allow_nan)


def write_json_atomic(path: Path, obj: Any) -> None:
    """``obj`` as a JSON file, written atomically (:func:`beo_bench.atomic.atomic_write_bytes`):
    readers (and a resumed run) see the old file or the new one, never half of one."""
    atomic_write_bytes(path, json_text(obj) + "\n")


def write_text(path: Path, text: str) -> None:
    """A whole file of a run directory, written atomically (a results file made at once,
    as ``beo-bench score`` makes it, rather than appended item by item)."""
    atomic_write_bytes(path, text)


def write_json(path: Path, obj: Any, doing: str) -> None:
    """:func:`write_json_atomic`, a failure a :class:`RunError` saying what was being done."""
    try:
        write_json_atomic(path, obj)
    except OSError as e:
        raise io_error(e, path, doing) from e


# -- the directory and its lock --------------------------------------------------------------
def open_run_dir(out: Path) -> Path:
    """``out``, created if needed and claimed as a run directory (:data:`MARKER_NAME`); a
    clear error when it cannot be one."""
    try:
        blocker = next((p for p in (out, *out.parents) if p.exists() and not p.is_dir()), None)
    except OSError as e:
        raise io_error(e, out, "looking up the run directory") from e
    if blocker is not None:
        raise RunUsageError(
            f"--out {out}: {blocker} is a file, not a directory: give a directory (a run "
            f"writes {RESULTS_NAME}, {RECORD_NAME}, summary.json and {LOCK_NAME} into it)"
        )
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise io_error(e, out, "creating the run directory") from e
    _claim_run_dir(out)
    return out


def _claim_run_dir(out: Path) -> None:
    """Mark ``out`` as a run directory when it is empty, or written by an earlier version
    (a valid run record: its marker is added); a :class:`RunUsageError` for a non-empty
    directory this package did not make, left untouched."""
    from beo_bench import outdir

    try:
        held = outdir.foreign_files(out, MARKER_NAME)
    except OSError as e:
        raise io_error(e, out, "looking into the run directory") from e
    if held is None:
        return
    if held:
        try:  # a run of a version before the marker: its record shows it is ours
            legacy = RECORD_NAME in held and read_record(out / RECORD_NAME) is not None
        except RunError:
            legacy = False
        if not legacy:
            raise RunUsageError(
                f"--out {out} is a non-empty directory that beo-bench did not create (it "
                f"holds {outdir.shown(held)} and no {MARKER_NAME}): give --out a new or "
                "empty directory; nothing in this one is touched"
            )
    try:
        outdir.mark(out, MARKER_NAME, MARKER_TEXT)
    except OSError as e:
        raise io_error(e, out / MARKER_NAME, "marking the run directory") from e


@contextlib.contextmanager
def lock_run_dir(out: Path) -> Iterator[None]:
    """Hold the run directory's exclusive lock (``OUT/run.lock``, with this PID in it) for
    the ``with`` block; a :class:`RunError` naming the holder when another process has it.
    The kernel releases it when the holder exits, however it exits."""
    path = Path(out) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except OSError as e:
        raise io_error(e, path, "opening the run's lock file") from e
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = (os.pread(fd, 64, 0).decode(errors="replace").split() or ["unknown"])[0]
            raise RunError(
                f"{out} is in use by another run (PID {holder}, holding {path}): wait for it "
                "to finish or stop it, or choose another --out (two runs into one directory "
                "would score every item twice)"
            ) from None
        try:  # write, then cut: a reader never finds the file empty
            pid = f"{os.getpid()}\n".encode()
            os.pwrite(fd, pid, 0)
            os.ftruncate(fd, len(pid))
        except OSError as e:
            raise io_error(e, path, "writing the run's lock file") from e
        yield
    finally:
        os.close(fd)  # releases the lock


# -- identity --------------------------------------------------------------------------------
UNSCORED_SUITE_KEYS = ("size", "description", "item_timeout_s")
"""Suite record fields that change no score: item i depends only on (seed, i), so a run can
be extended or summarised over its first items (runs are compared item by item instead);
the item timeout and the description change no score either."""


def scored_suite(record: Mapping[str, Any]) -> dict[str, Any]:
    """A suite record (``Suite.record()``, a summary's ``provenance["suite"]``) without
    :data:`UNSCORED_SUITE_KEYS`: what fixes the items and how they are scored (the sensor
    and its model's version included)."""
    return {k: v for k, v in record.items() if k not in UNSCORED_SUITE_KEYS}


def run_identity(cfg: RunConfig | RunContext) -> dict[str, Any]:
    """What a resume must find unchanged (``run.json`` records it): the scored suite
    (:func:`scored_suite`), the backend and its options as given."""
    if isinstance(cfg, RunContext):
        cfg = cfg.config
    record = {
        "suite": scored_suite(cfg.suite.record()),
        "backend": cfg.backend,
        "backend_kwargs": cfg.backend_kwargs,
    }
    out: dict[str, Any] = json.loads(json.dumps(record, default=jsonable))
    return out


def read_record(path: Path) -> dict[str, Any] | None:
    """The run record (``run.json``), None when there is none; an error when it is not one
    this package wrote (damaged, or another program's file): nothing is overwritten."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return None
    except OSError as e:
        raise io_error(e, path, "reading the run record") from e
    try:
        record = json.loads(text)
    except ValueError:
        record = None
    if not isinstance(record, dict) or not {"suite", "backend", "backend_kwargs"} <= set(record):
        raise CorruptRunError(
            f"{path} is damaged or not a beo-bench run record, so the results beside it "
            "cannot be checked or continued, and it is not overwritten: choose another --out "
            "(or move this directory away)"
        )
    return record


def check_same_run(old: dict[str, Any] | None, meta: dict[str, Any], out: Path) -> None:
    """Refuse to add items to results of another suite, sensor, backend, options or library
    (``meta``: :func:`run_identity`; ``old``: the record in ``out``)."""
    if old is None:
        raise CorruptRunError(
            f"{out} has results but no {RECORD_NAME}, so they cannot be checked against this "
            "run: choose another --out (or move this directory away)"
        )
    held = {k: old.get(k) for k in meta}
    recorded = held.get("suite")
    if isinstance(recorded, dict) and "sensor" not in recorded:
        raise RunUsageError(
            f"{out} was recorded by an older beo-bench, before sensors existed (its suite "
            "record has no sensor), and this version does not resume it: re-run into a new --out"
        )
    if held != meta:
        raise RunUsageError(
            f"{out} holds a different run ({held}); resuming needs the same suite (version, "
            "seed, protocol, sensor), backend and options: choose another --out"
        )
    from beo_bench.objects import LIBRARY_VERSION

    if old.get("library_version", LIBRARY_VERSION) != LIBRARY_VERSION:
        raise RunUsageError(
            f"{out} was scored on object library v{old['library_version']}; this package "
            f"generates v{LIBRARY_VERSION}, so its items differ: choose another --out"
        )


def code_changed(old: dict[str, Any], digest: str | None, out: Path, force: bool) -> bool:
    """Whether the results in ``out`` were scored by other code or options of the backend
    than it has now (``code_digest`` in the run record; :func:`beo_bench.codedigest.code_digest`)
    and are to be discarded (``force``); refused otherwise, naming the flag. A record
    without a digest was written before digests were recorded: for a plugin it cannot be
    checked, so it counts as changed."""
    held = old.get("code_digest")
    if held == digest:
        return False
    if force:
        return True
    raise RunUsageError(
        f"{out} holds results of backend {old.get('backend')!r} scored by other code or "
        f"options (code digest {held or 'not recorded'}, now {digest or 'none'}): resuming "
        f"would mix two versions of it in one score. Pass {FORCE_RERUN_FLAG} to discard them "
        "and run it again, or choose another --out"
    )


def discard_results(out: Path) -> None:
    """Remove a run's results, summary and report (:func:`code_changed` with force): the
    run then starts again, under the lock the caller holds."""
    for name in (RESULTS_NAME, SUMMARY_NAME, REPORT_NAME):
        try:
            (out / name).unlink(missing_ok=True)
        except OSError as e:
            raise io_error(e, out / name, "discarding the results of other code") from e


def _model_name(digest: str | None) -> str:
    return f"model {digest}" if digest else "no learned model"


def check_same_model(old: dict[str, Any], digest: str | None, out: Path) -> None:
    """Refuse to add items scored by another model than the run's first ones."""
    if "model_digest" not in old or "library_version" not in old:
        raise RunUsageError(
            f"{out / RECORD_NAME} was written by an older beo-bench that did not record the "
            "model digest or the object library version, so resuming could mix two models "
            "in one score: choose another --out to run it again (this one is left as it is)"
        )
    if old["model_digest"] != digest:
        raise RunUsageError(
            f"{out} holds results of backend {old['backend']!r} with "
            f"{_model_name(old['model_digest'])}, but it now loads {_model_name(digest)} "
            "(retrained or replaced): resuming would mix two models in one score. Choose "
            "another --out for this model, or restore the one the run used"
        )


def recorded_flag(record: Mapping[str, Any] | None, key: str, fallback: bool) -> bool:
    """A flag of the run record, or (a record written before it was recorded) ``fallback``,
    what the backend's capabilities say now."""
    if record is not None and isinstance(record.get(key), bool):
        return bool(record[key])
    return fallback


# -- the summary -----------------------------------------------------------------------------
@dataclass
class Summary:
    """A run's summary (``summary.json``; docs/design.md "Public names"): what the suite
    measured over the run's rows (:func:`beo_bench.bench.summary.summarise`), and what a
    leaderboard groups and labels rows by (the track, whether the backend can use the class
    hint, the model it scored, whether it was handed the truth) with the run's provenance."""

    suite: str
    suite_version: int
    track: str | None
    backend: str
    n: int
    failures: int
    failure_kinds: dict[str, int]
    metrics: dict[str, Any]
    ci95: dict[str, Any]
    categories: list[str]
    per_category: dict[str, dict[str, Any]]
    scoring: dict[str, Any]
    seed: int
    uses_class_hint: bool = False
    model_digest: str | None = None
    privileged: bool = False
    provenance: dict[str, Any] = field(default_factory=dict)
    sensor: str | None = None
    """The depth sensor the views were captured by (``Suite.sensor``); None in a summary
    written before sensors existed (its ``provenance["suite"]`` says ``noise``:
    :func:`sensor_of` reads either)."""

    def to_json(self) -> dict[str, Any]:
        """The summary as the JSON object ``summary.json`` holds."""
        return dataclasses.asdict(self)

    # Read access by key, as to a loaded summary.json: what compares and leaderboards
    # read, from files or from runs just finished, alike.
    def __getitem__(self, key: str) -> Any:
        if key not in _SUMMARY_FIELDS:
            raise KeyError(key)
        return getattr(self, key)

    def __contains__(self, key: object) -> bool:
        return key in _SUMMARY_FIELDS

    def get(self, key: str, default: Any = None) -> Any:
        return getattr(self, key) if key in _SUMMARY_FIELDS else default

    def keys(self) -> list[str]:
        return list(_SUMMARY_FIELDS)

    @classmethod
    def from_json(cls, obj: dict[str, Any]) -> Summary:
        """A summary read back (keys it does not know, from other versions, are dropped;
        missing optional ones take their defaults)."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in obj.items() if k in names})


_SUMMARY_FIELDS = tuple(f.name for f in dataclasses.fields(Summary))

SummaryLike = Summary | Mapping[str, Any]
"""A summary as a run returns it or as ``summary.json`` is loaded."""


def load_summary(path: Path | str) -> tuple[Path, dict[str, Any]]:
    """A run's directory and summary, from the directory or its ``summary.json``.
    Missing: :class:`UsageError`; unreadable: :class:`CorruptDataError`."""
    p = Path(path)
    f = p / SUMMARY_NAME if p.is_dir() else p
    if not f.exists():
        raise UsageError(f"{f} does not exist: give run directories or summary.json files")
    try:
        summary = json.loads(f.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise CorruptDataError(
            f"{f} is not a readable summary ({e}); rerun that run with `beo-bench run "
            "--resume` to rewrite it"
        ) from e
    if not isinstance(summary, dict) or not {"suite", "backend", "metrics"} <= set(summary):
        raise CorruptDataError(
            f"{f} is not a beo-bench run summary (no suite, backend or metrics); give the "
            "summary.json of a run, or rerun that run with `beo-bench run --resume`"
        )
    return f.parent, summary


def summary_size(summary: SummaryLike) -> int | None:
    """How many items the summary covers (its suite's size), None when it does not say."""
    size = summary.get("provenance", {}).get("suite", {}).get("size")
    return int(size) if isinstance(size, int) and not isinstance(size, bool) else None


def track_of(summary: SummaryLike) -> str | None:
    """The run's track (``class-given``, ``class-free``; None for a suite without tracks),
    from the summary or, failing that, the suite its provenance records."""
    track = summary.get("track", summary.get("provenance", {}).get("suite", {}).get("track"))
    return str(track) if track is not None else None


def sensor_of(summary: SummaryLike) -> str:
    """The depth sensor the run's views were captured by: the summary's ``sensor`` or, in
    a summary written before sensors existed, what its suite record says
    (:func:`~beo_bench.bench.suites.record_sensor`: ``noise: false`` is the ideal render)."""
    from beo_bench.bench.suites import record_sensor

    sensor = summary.get("sensor")
    if isinstance(sensor, str):
        return sensor
    return record_sensor(summary.get("provenance", {}).get("suite", {}))


def default_sensor_of(suite: str) -> str:
    """The registered suite's own sensor (``ideal`` for a suite this package does not
    know)."""
    from beo_bench.bench.suites import SUITES, base_name
    from beo_bench.scenes.sensors import DEFAULT_SENSOR

    base = SUITES.get(base_name(suite))
    return base.sensor if base is not None else DEFAULT_SENSOR


def sensor_tag_of(summary: SummaryLike) -> str | None:
    """The run's sensor when it is not its suite's own (what names the run, as
    ``Suite.sensor_tag``), else None. A run recorded before sensors existed was at its
    suite version's own sensor (None)."""
    recorded = summary.get("provenance", {}).get("suite", {})
    if not isinstance(summary.get("sensor"), str) and "sensor" not in recorded:
        return None
    sensor = sensor_of(summary)
    return None if sensor == default_sensor_of(str(summary.get("suite"))) else sensor


@dataclass(frozen=True)
class ItemsIdentity:
    """What fixes a finished run's items and how they were scored, read from its summary
    (or a gate baseline's entry): two runs pair (``compare``, ``gate``) when every field
    agrees (:meth:`differences`)."""

    suite: str
    suite_version: int | None
    seed: int | None
    track: str | None
    sensor: str
    library_version: int | None
    """None: not recorded (matches any)."""
    record: dict[str, Any]
    """The scored suite record (:func:`scored_suite` of ``provenance["suite"]``)."""

    @classmethod
    def of(cls, summary: SummaryLike) -> ItemsIdentity:
        prov = summary.get("provenance", {})
        version = summary.get("suite_version")
        return cls(
            suite=str(summary.get("suite")),
            suite_version=int(version) if isinstance(version, int) else None,
            seed=summary.get("seed"),
            track=track_of(summary),
            sensor=sensor_of(summary),
            library_version=prov.get("library_version"),
            record=scored_suite(prov.get("suite", {})),
        )

    def differences(
        self, other: ItemsIdentity, track: bool = True, sensor: bool = True
    ) -> list[tuple[str, Any, Any]]:
        """(what, this one's, ``other``'s) for each field that differs. ``track=False``
        leaves the track out (a run that cannot use the class hint stands in either);
        ``sensor=False`` the sensor and its model's version (the same scenes captured by
        two sensors: a robustness pairing)."""
        named = [
            ("suite", self.suite, other.suite),
            ("suite version", self.suite_version, other.suite_version),
            ("seed", self.seed, other.seed),
            ("track", self.track, other.track),
            ("sensor", self.sensor, other.sensor),
        ]
        left_out = {w for w, keep in (("track", track), ("sensor", sensor)) if not keep}
        diffs = [(w, a, b) for w, a, b in named if a != b and w not in left_out]
        if None not in (self.library_version, other.library_version) and (
            self.library_version != other.library_version
        ):
            diffs.append(("object library version", self.library_version, other.library_version))
        said = {"name", "version", "seed", "track", "sensor"}
        if not sensor:
            said.add("sensor_version")
        keys = sorted((self.record.keys() | other.record.keys()) - said)
        diffs += [
            (f"suite record {k}", self.record.get(k), other.record.get(k))
            for k in keys
            if self.record.get(k) != other.record.get(k)
        ]
        return diffs
