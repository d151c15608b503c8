"""``beo-bench run``: score a backend on a suite, in parallel, resumable.

Results go to ``OUT/results.jsonl`` (one line per scored view or episode) and
``OUT/summary.json``; ``OUT/run.json`` records what the run is (suite with its track,
backend, options, the backend's model digest, a plugin's code digest, the object library
version, whether the backend can use the class hint), and a resume must match it (a
plugin's changed code is refused, or run again with ``force_rerun``). The summary carries
the track (``"track"``: ``class-given``, ``class-free`` or null for a suite without
tracks), ``"uses_class_hint"`` and ``"model_digest"`` at its top level, for the
leaderboard.

A run is resolved once into its :class:`~beo_bench.bench.runs.RunContext` (the backend's
options parsed and capabilities read without building it); the driver then builds the
backend once and prepares it, and each worker gets that context alone.

Integrity (see the "Failure behaviour" doc):

- one run at a time per directory: the run holds an exclusive ``flock`` on ``OUT/run.lock``
  (with its PID in it) from start to end; a second run or resume gets a :class:`RunError`
  naming the holder. The kernel drops the lock when the holder dies, so a stale lock file
  blocks nothing (and is never deleted: the next run reuses it);
- each finished *item* (a view, a scene's views, an episode) is appended as whole lines to
  a file opened with ``O_APPEND``, looping until every byte is written; a failed write (a
  full disk) cuts the file back to its last complete item and stops the run with a
  :class:`RunError` (resume after freeing space). Lines are fsynced about once a second;
- reading skips and reports (a :class:`ResultsWarning`) any line that is not a result row,
  anywhere in the file, an item's rows that are incomplete (it is run again) and a second
  set of rows of an item (the first complete set is kept); a torn last line is cut off;
- every item runs in a worker process with a deadline (``Suite.item_timeout_s``,
  ``item_timeout``): a worker that hangs, crashes or exits is replaced and its item recorded
  as failed (:mod:`.pool`); only a backend registered at run time in this process (which
  workers cannot build) runs in-process, without those protections.

The summary is computed from the rows sorted by (item, view), so it does not depend on the
number of workers, the order in which they finish, or interruptions.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import math
import os
import platform
import subprocess
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from beo_bench.atomic import atomic_write_bytes
from beo_bench.backend import Backend
from beo_bench.bench.pool import (
    WORKER_THREADS,
    WorkerPool,
    default_workers,
    in_process_results,
    jsonable,
    ray_results,
)
from beo_bench.bench.runs import (
    LOCK_NAME,
    MARKER_NAME,
    MARKER_TEXT,
    RECORD_NAME,
    REPORT_NAME,
    RESULTS_NAME,
    SUMMARY_NAME,
    CorruptRunError,
    RunConfig,
    RunContext,
    RunError,
    RunUsageError,
    Summary,
)
from beo_bench.bench.suites import Suite
from beo_bench.errors import UsageError

if TYPE_CHECKING:
    from beo_bench.bench.failures import RunEnd

__all__ = [
    "WORKER_THREADS",
    "CorruptRunError",
    "ResultsWarning",
    "RunConfig",
    "RunError",
    "RunUsageError",
    "WorkerPool",
    "default_workers",
    "item_timeout_s",
    "lock_run_dir",
    "read_rows",
    "run",
    "run_end",
    "scan_rows",
]


class ResultsWarning(UserWarning):
    """Lines of a results file that were skipped (damaged, incomplete, duplicated)."""


# -- errors from the file system -------------------------------------------------------------
def io_error(e: OSError, path: Path, doing: str) -> RunError:
    """A :class:`RunError` saying what failed on ``path`` and what to do about it."""
    if e.errno in (errno.ENOSPC, errno.EDQUOT):
        return RunError(
            f"no space left on the device of {path} while {doing}: the complete items "
            "written so far are kept; free some space, then run again with --resume"
        )
    if e.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        return RunError(
            f"cannot write {path} while {doing} ({e.strerror}): a run needs a writable "
            "directory; choose another --out or make this one writable"
        )
    return RunError(f"{path}: {e.strerror or e} while {doing}")


# -- results file ----------------------------------------------------------------------------
@dataclass
class RowScan:
    """What :func:`scan_rows` found in a results file."""

    rows: list[dict[str, Any]] = field(default_factory=list)
    """Each item's first complete set of rows, in file order."""
    damaged: list[int] = field(default_factory=list)
    """Line numbers (1-based) that are not result rows (torn, corrupt)."""
    torn_tail: bool = False
    """The file ended in an unfinished line (cut off when repairing)."""
    incomplete: list[int] = field(default_factory=list)
    """Items with a set of rows that misses some (a damaged line): that set is ignored."""
    duplicates: list[int] = field(default_factory=list)
    """Items with more than one complete set of rows (two runs into one directory): all
    but the first are ignored."""

    def report(self, path: Path) -> str:
        """One sentence per kind of damage ("" when the file is clean)."""
        parts = []
        if self.damaged:
            n = len(self.damaged)
            parts.append(f"skipped {n} damaged line(s) (lines {_items(self.damaged)})")
        if self.torn_tail:
            parts.append("cut off a torn last line (a run stopped mid-write)")
        if self.incomplete:
            parts.append(
                f"ignored incomplete rows of {len(self.incomplete)} item(s) "
                f"{_items(self.incomplete)} (an item without a complete set is run again)"
            )
        if self.duplicates:
            parts.append(
                f"dropped a second set of rows of {len(self.duplicates)} item(s) "
                f"{_items(self.duplicates)}, keeping the first (two runs wrote into one "
                "directory?)"
            )
        return f"{path}: " + "; ".join(parts) if parts else ""


def _items(items: list[int]) -> str:
    shown = sorted(set(items))
    return str(shown[:10])[:-1] + (", ...]" if len(shown) > 10 else "]")


def _row(line: bytes) -> dict[str, Any] | None:
    """The result row a line holds, or None if it holds none."""
    try:
        row = json.loads(line)
    except (ValueError, UnicodeDecodeError):
        return None
    ok = isinstance(row, dict) and all(
        isinstance(row.get(k), int) and not isinstance(row.get(k), bool) and row[k] >= 0
        for k in ("item", "view")
    )
    return row if ok else None


def _blocks(rows: list[dict[str, Any]]) -> list[list[dict[str, Any]]]:
    """Rows cut into the sets that items were written as: one item's consecutive views."""
    out: list[list[dict[str, Any]]] = []
    for r in rows:
        last = out[-1][-1] if out else None
        if (
            last is None
            or r["view"] == 0
            or r["item"] != last["item"]
            or r["view"] != last["view"] + 1
        ):
            out.append([r])
        else:
            out[-1].append(r)
    return out


def _complete(block: list[dict[str, Any]]) -> bool:
    """Views 0..n-1 of one item, n as its first row says (``item_rows``; rows written before
    it was recorded count as complete when their views start at 0)."""
    n = block[0].get("item_rows", len(block))
    return block[0]["view"] == 0 and len(block) == n


def scan_rows(path: Path, repair: bool = False) -> RowScan:
    """Read a results file: keep each item's first complete set of rows, skip the rest and
    say what was skipped. ``repair`` cuts a torn last line off the file (only when this
    process holds the run's lock: the next append would be glued to it)."""
    scan = RowScan()
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return scan
    end = data.rfind(b"\n") + 1
    if end < len(data):
        scan.torn_tail = True
        if repair:
            with open(path, "r+b") as f:
                f.truncate(end)
    rows = []
    for n, line in enumerate(data[:end].split(b"\n")[:-1], start=1):
        if not line.strip():
            continue
        row = _row(line)
        if row is None:
            scan.damaged.append(n)
        else:
            rows.append(row)
    kept: set[int] = set()
    for block in _blocks(rows):
        item = block[0]["item"]
        if not _complete(block):
            if item not in scan.incomplete:
                scan.incomplete.append(item)
        elif item in kept:
            if item not in scan.duplicates:
                scan.duplicates.append(item)
        else:
            kept.add(item)
            scan.rows.extend(block)
    return scan


def read_rows(path: Path, repair: bool = False, report: bool = True) -> list[dict[str, Any]]:
    """The rows of a results file: each item's first complete set (see :func:`scan_rows`).
    Whatever was skipped is reported as a :class:`ResultsWarning` when ``report``."""
    scan = scan_rows(Path(path), repair)
    message = scan.report(Path(path))
    if report and message:
        warnings.warn(message, ResultsWarning, stacklevel=2)
    return scan.rows


def _write_all(fd: int, data: bytes) -> None:
    """``os.write`` until every byte is written (a write may take fewer bytes than asked)."""
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        if n <= 0:  # no progress and no error: treat as a failed write
            raise OSError(errno.EIO, "write made no progress")
        view = view[n:]


class ResultsWriter:
    """Appends each item's rows as whole lines to a file opened with ``O_APPEND`` (this run
    holds the directory's lock, so it is the only writer). Once written, the lines survive
    the process being killed (they are in the kernel's page cache); ``fsync`` (against power
    loss) runs at most every ``sync_every_s`` and on close, because one fsync per item
    (~20 ms here) capped the runner at ~50 items/s. A write that fails part-way (a full
    disk) is cut back off, so the file never holds a torn line before complete ones."""

    def __init__(self, path: Path, sync_every_s: float = 1.0) -> None:
        self.path = path
        flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC
        try:
            self.fd = os.open(path, flags, 0o644)
            self._size = os.fstat(self.fd).st_size
        except OSError as e:
            raise io_error(e, path, "opening the results file") from e
        self.sync_every_s = sync_every_s
        self._last_sync = time.monotonic()

    def append(self, rows: list[dict[str, Any]]) -> None:
        payload = "".join(json.dumps(r, sort_keys=True) + "\n" for r in rows).encode()
        try:
            _write_all(self.fd, payload)
        except OSError as e:
            self._cut_back()
            raise io_error(e, self.path, "writing results") from e
        self._size += len(payload)
        if time.monotonic() - self._last_sync > self.sync_every_s:
            self._sync()
            self._last_sync = time.monotonic()

    def _cut_back(self) -> None:
        """Remove the part of an item that a failed write left (best effort: a reader skips
        a damaged line anyway)."""
        with contextlib.suppress(OSError):
            os.ftruncate(self.fd, self._size)

    def _sync(self) -> None:
        try:
            os.fsync(self.fd)
        except OSError as e:  # a full disk can surface here, on delayed allocation
            raise io_error(e, self.path, "flushing results to disk") from e

    def close(self) -> None:
        if self.fd >= 0:
            fd, self.fd = self.fd, -1
            try:
                os.fsync(fd)
            except OSError as e:
                raise io_error(e, self.path, "flushing results to disk") from e
            finally:
                os.close(fd)

    def __enter__(self) -> ResultsWriter:
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        if exc_type is None:
            self.close()
        else:  # do not hide the error that stopped the run behind one of closing
            with contextlib.suppress(RunError):
                self.close()


def write_json_atomic(path: Path, obj: Any) -> None:
    """``obj`` as a JSON file, written atomically (:func:`beo_bench.atomic.atomic_write_bytes`):
    readers (and a resumed run) see the old file or the new one, never half of one."""
    atomic_write_bytes(path, json.dumps(obj, indent=2, sort_keys=True, default=jsonable) + "\n")


# -- the run directory -----------------------------------------------------------------------
def _run_dir(out: Path) -> Path:
    """``out``, created if needed; a clear error when it cannot be a run directory."""
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
            legacy = RECORD_NAME in held and _read_record(out / RECORD_NAME) is not None
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


def _identity(cfg: RunConfig | RunContext) -> dict[str, Any]:
    """What fixes the items and their scores. The size is left out because item i depends
    only on (seed, i): a run can be extended, or summarised over its first items; the item
    timeout and the description change no score either."""
    if isinstance(cfg, RunContext):
        cfg = cfg.config
    drop = ("size", "description", "item_timeout_s")
    suite = {k: v for k, v in cfg.suite.record().items() if k not in drop}
    record = {"suite": suite, "backend": cfg.backend, "backend_kwargs": cfg.backend_kwargs}
    return json.loads(json.dumps(record, default=jsonable))


def _read_record(path: Path) -> dict[str, Any] | None:
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


def _model_name(digest: str | None) -> str:
    return f"model {digest}" if digest else "no learned model"


def _check_same_run(old: dict[str, Any] | None, meta: dict[str, Any], out: Path) -> None:
    """Refuse to add items to results of another suite, backend, options or library."""
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


FORCE_RERUN_FLAG = "--force-rerun"
"""The flag of ``run`` and ``all`` that discards results scored by other plugin code."""


def _code_changed(old: dict[str, Any], digest: str | None, out: Path, force: bool) -> bool:
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


def _discard_results(out: Path) -> None:
    """Remove a run's results, summary and report (:func:`_code_changed` with force): the
    run then starts again, under the lock the caller holds."""
    for name in (RESULTS_NAME, SUMMARY_NAME, REPORT_NAME):
        try:
            (out / name).unlink(missing_ok=True)
        except OSError as e:
            raise io_error(e, out / name, "discarding the results of other code") from e


def _check_same_model(old: dict[str, Any], digest: str | None, out: Path) -> None:
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


# -- workers ---------------------------------------------------------------------------------
def _results(
    ctx: RunContext,
    todo: list[int],
    workers: int,
    timeout: float,
    pool: WorkerPool | None,
    backend: Backend | None,
) -> Iterator[tuple[int, list[dict[str, Any]]]]:
    from beo_bench.backend import buildable_in_fresh_process

    imports = pool.imports if pool is not None else ()
    if workers <= 1 and not buildable_in_fresh_process(ctx.backend.name, imports):
        yield from in_process_results(ctx, todo, backend)
    elif pool is not None:
        yield from pool.results(ctx.for_workers(), todo, timeout)
    else:
        with WorkerPool(workers) as fresh:
            yield from fresh.results(ctx.for_workers(), todo, timeout)


# -- the run ---------------------------------------------------------------------------------
def git_state(where: Path | None = None) -> dict[str, Any]:
    """The checkout the package runs from (``where``: a directory inside it): its commit,
    whether tracked files differ from it, and then the SHA-256 of ``git diff HEAD --binary``,
    so a row scored on uncommitted code names exactly which code. Empty without git."""
    import hashlib

    cwd = Path(__file__).resolve().parent if where is None else Path(where)

    def git(*args: str) -> subprocess.CompletedProcess[bytes] | None:
        try:
            return subprocess.run(["git", *args], capture_output=True, cwd=cwd, timeout=30)
        except (OSError, subprocess.SubprocessError):
            return None

    head = git("rev-parse", "HEAD")
    if head is None or head.returncode != 0:
        return {"git_commit": None, "git_dirty": None}
    status = git("status", "--porcelain", "--untracked-files=no")
    dirty = status is None or status.returncode != 0 or bool(status.stdout.strip())
    out: dict[str, Any] = {"git_commit": head.stdout.decode().strip(), "git_dirty": dirty}
    diff = git("diff", "HEAD", "--binary") if dirty else None
    if diff is not None and diff.returncode == 0:
        out["git_diff_sha256"] = hashlib.sha256(diff.stdout).hexdigest()
    return out


def provenance(ctx: RunContext) -> dict[str, Any]:
    """Where and from what a run was made (the summary's ``provenance``)."""
    return {
        **machine_provenance(),
        "suite": ctx.suite.record(),
        "backend_kwargs": ctx.backend.kwargs,
        **({"dataset_root": ctx.dataset.root} if ctx.dataset else {}),
        # files --skip-bad left out, with why (the paths are also in the suite's identity)
        **(
            {"dataset_skipped": [{"path": p, "why": w} for p, w in ctx.dataset.skipped]}
            if ctx.dataset and ctx.dataset.skipped
            else {}
        ),
    }


def machine_provenance() -> dict[str, Any]:
    """The git state, package versions, Python and machine a summary was made with."""
    import importlib.metadata as md

    def version(name: str) -> str | None:
        try:
            return md.version(name)
        except md.PackageNotFoundError:
            return None

    return {
        **git_state(),
        "versions": {
            n: version(n)
            for n in ("beo-bench", "mujoco", "numpy", "scipy", "trimesh", "torch", "gymnasium")
        },
        "python": platform.python_version(),
        "machine": {
            "platform": platform.platform(),
            "processor": platform.machine(),
            "cpus": os.cpu_count(),
        },
    }


@dataclass(frozen=True)
class Prepared:
    """The backend the driver built and prepared, and the digest of the model it loaded."""

    backend: Backend
    model_digest: str | None
    """The backend's ``model_digest()`` (None: no learned model)."""


def _prepare(ctx: RunContext) -> Prepared:
    """The backend's one-time set-up, here, before workers start (they then load what it
    cached), and the digest of the model it loaded."""
    backend = ctx.backend.build()
    backend.prepare(ctx)
    return Prepared(backend, backend.model_digest())


def _recorded(record: dict[str, Any] | None, key: str, fallback: bool) -> bool:
    """A flag of the run record, or (a record written before it was recorded) ``fallback``,
    what the backend's capabilities say now."""
    if record is not None and isinstance(record.get(key), bool):
        return bool(record[key])
    return fallback


def item_timeout_s(suite: Suite, item_timeout: float | None) -> float:
    """The seconds an item may take: ``item_timeout``, else the suite's default."""
    t = suite.item_timeout_s if item_timeout is None else item_timeout
    try:
        t = float(t)
    except (TypeError, ValueError):
        t = math.nan
    if not math.isfinite(t) or t <= 0:
        raise UsageError(
            f"item timeout {item_timeout!r}: give a positive number of seconds (--item-timeout "
            f"S; suite {suite.name}'s default is {suite.item_timeout_s:g} s)"
        )
    return t


def run(
    cfg: RunConfig | RunContext,
    out: Path | str,
    workers: int | None = None,
    resume: bool = False,
    use_ray: bool = False,
    progress: bool = True,
    pool: WorkerPool | None = None,
    item_timeout: float | None = None,
    report_views: int = 0,
    force_rerun: bool = False,
) -> Summary:
    """Run (or resume) ``cfg`` into ``out`` with ``workers`` processes (default: one per
    core), Ray actors, or the processes of ``pool`` (kept across runs; it sets the number
    of workers; with ``use_ray`` only its ``imports`` are used); returns the summary.
    ``item_timeout``: seconds an item may take before it is recorded as failed (default:
    the suite's ``item_timeout_s``). ``report_views``: also write ``OUT/report.html`` with
    that many worst views (:mod:`.report`; 0: none), when this call scored items or there
    is none yet. ``force_rerun`` (``--force-rerun``): results in ``out`` scored by other
    code or options of a plugin backend (its ``code_digest``) are discarded and the run made
    again, rather than refused. The directory is locked for the whole run. The run's context
    is resolved here, once (a :class:`RunContext` given is used as it is)."""
    ctx = cfg if isinstance(cfg, RunContext) else RunContext.of(cfg, progress=progress)
    if pool is not None:
        workers = pool.workers
    workers = default_workers() if workers is None else max(1, int(workers))
    timeout = item_timeout_s(ctx.suite, item_timeout)
    out = _run_dir(Path(out))
    with lock_run_dir(out):
        summary, prepared, scored = _run_locked(
            ctx, out, workers, resume, use_ray, progress, pool, timeout, force_rerun
        )
        if report_views > 0 and (scored or not (out / REPORT_NAME).exists()):
            _report(ctx, out, report_views, prepared)
        return summary


def _report(ctx: RunContext, out: Path, views: int, prepared: Prepared | None) -> None:
    """The run's report, with the backend the driver prepared (if it did). The results
    and summary are written by now: a report that cannot be made is one warning, and the
    run stands."""
    from beo_bench.bench.report import ReportWarning, write_report

    rows = _scan(out / RESULTS_NAME, False, False).rows  # what was skipped was reported
    try:
        backend = prepared.backend if prepared is not None else None
        write_report(ctx, out, rows, views, backend)
    except Exception as e:  # whatever drawing or predicting again raised: the run is done
        warnings.warn(
            f"{out / REPORT_NAME} was not written ({type(e).__name__}: {e}); the results and "
            "summary are complete (--report-views 0 skips the report)",
            ReportWarning,
            stacklevel=3,
        )


def _run_locked(
    ctx: RunContext,
    out: Path,
    workers: int,
    resume: bool,
    use_ray: bool,
    progress: bool,
    pool: WorkerPool | None,
    timeout: float,
    force_rerun: bool = False,
) -> tuple[Summary, Prepared | None, bool]:
    """The run, then its summary; with the backend the driver prepared (None: nothing was
    left to do) and whether any item was scored."""
    from tqdm import tqdm

    record, done, todo, prepared = _open_run(ctx, out, resume, force_rerun)
    t0 = time.perf_counter()
    if use_ray:
        imports = pool.imports if pool is not None else ()
        source = ray_results(ctx.for_workers(), todo, workers, timeout, imports)
    else:
        backend = prepared.backend if prepared is not None else None
        source = _results(ctx, todo, workers, timeout, pool, backend)
    bar = tqdm(
        total=ctx.suite.size,
        initial=len(done),
        disable=not progress,
        desc=f"{ctx.suite.label} / {ctx.backend.name}",
        unit="item",
    )
    with bar, ResultsWriter(out / RESULTS_NAME) as writer:
        for _, rows in source:
            writer.append(rows)
            bar.update(1)
    wall = time.perf_counter() - t0
    summary = _summarise(ctx, out, record, wall, workers, use_ray, timeout)
    return summary, prepared, bool(todo)


def run_end(out: Path | str, size: int | None = None, label: str = "") -> RunEnd:
    """What the run in ``out`` ends by printing (:class:`~beo_bench.bench.failures.RunEnd`):
    its failures grouped by exception, a pick run's reasons, its report if this run wrote
    one. ``size``: the items its summary covers (a resume may ask for fewer)."""
    from beo_bench.bench.failures import RunEnd, summarise_failures

    out = Path(out)
    rows = read_rows(out / RESULTS_NAME, report=False)  # damage was reported by the run
    if size is not None:
        rows = [r for r in rows if r["item"] < size]
    report = out / REPORT_NAME
    try:  # a report older than the results is an earlier session's: not this run's
        fresh = report.stat().st_mtime >= (out / RESULTS_NAME).stat().st_mtime
    except OSError:
        fresh = False
    return RunEnd(summarise_failures(rows, label), report if fresh else None)


def _open_run(
    ctx: RunContext, out: Path, resume: bool, force_rerun: bool = False
) -> tuple[dict[str, Any] | None, set[int], list[int], Prepared | None]:
    """Check that ``out`` may take this run (or its resume), prepare the backend if there
    is work left and record a new run: (the run record, the items done, the items to do,
    what preparing learnt). ``force_rerun``: results scored by other code of the backend
    are discarded rather than refused."""
    from beo_bench.codedigest import code_digest
    from beo_bench.objects import LIBRARY_VERSION

    results, record_path = out / RESULTS_NAME, out / RECORD_NAME
    meta = _identity(ctx)
    old = _read_record(record_path)
    code = code_digest(ctx.backend.name, ctx.backend.options)
    try:
        has_results = results.exists() and results.stat().st_size > 0
    except OSError as e:
        raise io_error(e, results, "reading the results") from e
    if has_results:
        if not resume:
            raise RunUsageError(
                f"{results} already has results: pass --resume to continue that "
                "run, or choose another --out"
            )
        _check_same_run(old, meta, out)
        assert old is not None  # _check_same_run refuses results without a record
        # checked before "nothing left to do": a finished run of other code is not reused
        if _code_changed(old, code, out, force_rerun):
            _discard_results(out)
            has_results = False
    scan = _scan(results, repair=has_results)
    done = {r["item"] for r in scan.rows if r["item"] < ctx.suite.size}
    todo = [i for i in range(ctx.suite.size) if i not in done]
    if not todo:
        return old, done, todo, None
    prepared = _prepare(ctx)
    if has_results:
        assert old is not None
        _check_same_model(old, prepared.model_digest, out)
    else:  # a new run: record it before its first result
        old = {
            **meta,
            "model_digest": prepared.model_digest,
            "code_digest": code,
            "library_version": LIBRARY_VERSION,
            "uses_class_hint": ctx.backend.capabilities.wants_class_hint,
            "privileged": ctx.privileged,
        }
        _write(record_path, old, "writing the run record")
    return old, done, todo, prepared


def _scan(results: Path, repair: bool, report: bool = True) -> RowScan:
    """The results file's rows; what was skipped is reported (once per run: ``report``)."""
    try:
        scan = scan_rows(results, repair)
    except OSError as e:
        raise io_error(e, results, "reading the results") from e
    if scan.damaged and not scan.rows:
        raise CorruptRunError(
            f"{results} holds no result rows ({len(scan.damaged)} damaged lines): it is not "
            "a beo-bench results file or it is destroyed, and it is not appended to: choose "
            "another --out (or move this directory away)"
        )
    message = scan.report(results)
    if report and message:
        warnings.warn(message, ResultsWarning, stacklevel=5)  # run()'s caller
    return scan


def _write(path: Path, obj: Any, doing: str) -> None:
    try:
        write_json_atomic(path, obj)
    except OSError as e:
        raise io_error(e, path, doing) from e


def _summarise(
    ctx: RunContext,
    out: Path,
    record: dict[str, Any] | None,
    wall: float,
    workers: int,
    use_ray: bool,
    timeout: float,
) -> Summary:
    from beo_bench.bench.summary import summarise

    suite = ctx.suite
    # the rows as this run left them (what was skipped was reported when it started)
    rows = [r for r in _scan(out / RESULTS_NAME, False, False).rows if r["item"] < suite.size]
    rows.sort(key=lambda r: (r["item"], r["view"]))
    caps = ctx.backend.capabilities
    digest = (record or {}).get("model_digest")
    # a bound is marked by what it was given, not by its name (leaderboard.is_bound)
    privileged = _recorded(record, "privileged", ctx.privileged)
    summary = summarise(
        suite,
        ctx.backend.name,
        rows,
        # what a leaderboard groups and labels rows by: whether the backend can use the
        # class hint at all, the model it scored, whether it was handed the truth
        uses_class_hint=_recorded(record, "uses_class_hint", caps.wants_class_hint),
        model_digest=digest,
        privileged=privileged,
        provenance={
            **provenance(ctx),
            "privileged": privileged,
            "wall_s_last_session": wall,
            "workers": workers,
            "ray": use_ray,
            "item_timeout_s": timeout,
            "model_digest": digest,
            "code_digest": (record or {}).get("code_digest"),
            "library_version": (record or {}).get("library_version"),
        },
    )
    _write(out / SUMMARY_NAME, summary.to_json(), "writing the summary")
    return summary
