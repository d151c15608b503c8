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

Integrity (see the "Failure behaviour" doc): the run directory's lock, its appends,
reading and resume checks are :mod:`.rundir`'s; the run holds the lock from start to end.
Every item runs in a worker process with a deadline (``Suite.item_timeout_s``,
``item_timeout``): a worker that hangs, crashes or exits is replaced and its item recorded
as failed (:mod:`.pool`); only a backend registered at run time in this process (which
workers cannot build) runs in-process, without those protections.

The summary is computed from the rows sorted by (item, view), so it does not depend on the
number of workers, the order in which they finish, or interruptions.
"""

from __future__ import annotations

import math
import os
import platform
import subprocess
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from beo_bench.backend import Backend
from beo_bench.bench import rundir
from beo_bench.bench.pool import (
    WORKER_THREADS,
    WorkerPool,
    default_workers,
    in_process_results,
    ray_results,
)
from beo_bench.bench.rows import ResultsWriter, io_error, json_rows, scan_rows, scan_run
from beo_bench.bench.rundir import (
    RECORD_NAME,
    REPORT_NAME,
    RESULTS_NAME,
    SUMMARY_NAME,
    Summary,
    write_json,
)
from beo_bench.bench.runs import RunConfig, RunContext, RunError, RunUsageError
from beo_bench.bench.suites import Suite
from beo_bench.errors import UsageError

if TYPE_CHECKING:
    from beo_bench.bench.failures import RunEnd

__all__ = [
    "WORKER_THREADS",
    "RunConfig",
    "RunError",
    "WorkerPool",
    "default_workers",
    "item_timeout_s",
    "run",
    "run_end",
]


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
    out = rundir.open_run_dir(Path(out))
    with rundir.lock_run_dir(out):
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
    from beo_bench.bench.worstviews import ReportWarning, write_report

    rows = json_rows(scan_run(out / RESULTS_NAME, False, False).rows)  # skips were reported
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
        disable=None if progress else True,
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
    rows = scan_rows(out / RESULTS_NAME).rows  # damage was reported by the run
    if size is not None:
        rows = [r for r in rows if r.item < size]
    report = out / REPORT_NAME
    try:  # a report older than the results is an earlier session's: not this run's
        fresh = report.stat().st_mtime >= (out / RESULTS_NAME).stat().st_mtime
    except OSError:
        fresh = False
    return RunEnd(summarise_failures(json_rows(rows), label), report if fresh else None)


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
    meta = rundir.run_identity(ctx)
    old = rundir.read_record(record_path)
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
        rundir.check_same_run(old, meta, out)
        assert old is not None  # check_same_run refuses results without a record
        # checked before "nothing left to do": a finished run of other code is not reused
        if rundir.code_changed(old, code, out, force_rerun):
            rundir.discard_results(out)
            has_results = False
    scan = scan_run(results, repair=has_results)
    done = {r.item for r in scan.rows if r.item < ctx.suite.size}
    todo = [i for i in range(ctx.suite.size) if i not in done]
    if not todo:
        return old, done, todo, None
    prepared = _prepare(ctx)
    if has_results:
        assert old is not None
        rundir.check_same_model(old, prepared.model_digest, out)
    else:  # a new run: record it before its first result
        old = {
            **meta,
            "model_digest": prepared.model_digest,
            "code_digest": code,
            "library_version": LIBRARY_VERSION,
            "uses_class_hint": ctx.backend.capabilities.wants_class_hint,
            "privileged": ctx.privileged,
        }
        write_json(record_path, old, "writing the run record")
    return old, done, todo, prepared


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
    rows = [r for r in scan_run(out / RESULTS_NAME, False, False).rows if r.item < suite.size]
    rows.sort(key=lambda r: (r.item, r.view))
    caps = ctx.backend.capabilities
    digest = (record or {}).get("model_digest")
    # a bound is marked by what it was given, not by its name (leaderboard.is_bound)
    privileged = rundir.recorded_flag(record, "privileged", ctx.privileged)
    summary = summarise(
        suite,
        ctx.backend.name,
        rows,
        # what a leaderboard groups and labels rows by: whether the backend can use the
        # class hint at all, the model it scored, whether it was handed the truth
        uses_class_hint=rundir.recorded_flag(record, "uses_class_hint", caps.wants_class_hint),
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
    write_json(out / SUMMARY_NAME, summary.to_json(), "writing the summary")
    return summary
