"""``beo-bench run``: score a backend on a suite, in parallel, resumable.

Results go to ``OUT/results.jsonl`` (one line per scored view or episode) and
``OUT/summary.json``. Each finished *item* (a view, a scene's views, an episode) is
appended as whole lines in one ``write`` on a file opened with ``O_APPEND`` (fsynced
about once a second), so a run killed at any moment leaves only complete items plus at
most one torn line; resuming
drops the torn line, skips the items already present and runs the rest. The summary is
computed from the rows sorted by (item, view), so it does not depend on the number of
workers, the order in which they finish, or interruptions.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import platform
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from beo_bench.bench.suites import Suite
from beo_bench.errors import BeoBenchError


class RunError(BeoBenchError, ValueError):
    """A run that cannot start or resume as asked."""


@dataclass(frozen=True)
class RunConfig:
    """Everything that determines a run's results (recorded in its summary)."""

    suite: Suite
    backend: str
    backend_kwargs: dict[str, Any] = field(default_factory=dict)


# -- results file ----------------------------------------------------------------------------
def read_rows(path: Path, repair: bool = False) -> list[dict[str, Any]]:
    """The complete rows of a results file. A torn last line (a killed writer) is ignored,
    and cut off the file when ``repair``."""
    if not path.exists():
        return []
    data = path.read_bytes()
    end = data.rfind(b"\n") + 1
    if repair and end < len(data):
        with open(path, "r+b") as f:
            f.truncate(end)
    rows = []
    for line in data[:end].splitlines():
        if line.strip():
            rows.append(json.loads(line))
    return rows


class ResultsWriter:
    """Appends each item's rows as whole lines in one ``write`` to a file opened with
    ``O_APPEND``. Once written, the lines survive the process being killed (they are in the
    kernel's page cache); ``fsync`` (against power loss) runs at most every
    ``sync_every_s`` and on close, because one fsync per item (~20 ms here) capped the
    runner at ~50 items/s."""

    def __init__(self, path: Path, sync_every_s: float = 1.0) -> None:
        self.fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        self.sync_every_s = sync_every_s
        self._last_sync = time.monotonic()

    def append(self, rows: list[dict[str, Any]]) -> None:
        payload = "".join(json.dumps(r, sort_keys=True) + "\n" for r in rows).encode()
        os.write(self.fd, payload)
        if time.monotonic() - self._last_sync > self.sync_every_s:
            os.fsync(self.fd)
            self._last_sync = time.monotonic()

    def close(self) -> None:
        if self.fd >= 0:
            os.fsync(self.fd)
            os.close(self.fd)
            self.fd = -1

    def __enter__(self) -> ResultsWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_atomic(path: Path, data: str | bytes) -> None:
    """Write a whole file through a temporary one and a rename: readers (and a resumed
    run) see the old file or the new one, never half of one."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data if isinstance(data, bytes) else data.encode())
    os.replace(tmp, path)


def write_json_atomic(path: Path, obj: Any) -> None:
    write_atomic(path, json.dumps(obj, indent=2, sort_keys=True, default=_jsonable) + "\n")


def _jsonable(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    raise TypeError(f"not JSON-serialisable: {type(o).__name__}")


def _clean(row: dict[str, Any]) -> dict[str, Any]:
    return {
        k: _jsonable(v) if isinstance(v, np.generic | np.ndarray) else v for k, v in row.items()
    }


# -- workers ---------------------------------------------------------------------------------
WORKER_THREADS = 1
"""BLAS / OpenMP / torch threads per worker. Workers run one per core, and pinning every
path (in-process, local processes, Ray actors, which Ray already pins to 1) to the same count
makes reductions identical, so results do not depend on how a run was spread out."""

_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
_WORKER: Any = None
_WORKER_CFG: Any = None
_INIT_ERROR = ""


def default_workers() -> int:
    """One worker per available core."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _pin_threads() -> Any:
    """Limit this process's thread pools to ``WORKER_THREADS``: the already loaded ones
    through threadpoolctl, the ones loaded later (torch in a backend) through the
    environment. Returns the limiter (keep it alive; ``restore_original_limits`` undoes)."""
    from threadpoolctl import threadpool_limits

    for var in _THREAD_VARS:
        os.environ[var] = str(WORKER_THREADS)
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(WORKER_THREADS)
    return threadpool_limits(limits=WORKER_THREADS)


def _init_worker(cfg: RunConfig, pin: bool = True) -> None:
    """Set up this process's evaluator for ``cfg`` (closing one set up for another run).
    An error is kept and raised by the first item: a pool whose initializer raises would
    only start new workers, forever."""
    global _WORKER, _WORKER_CFG, _INIT_ERROR
    from beo_bench.backend import load_plugins
    from beo_bench.bench.evaluate import Evaluator

    if pin:
        _pin_threads()
    if _WORKER is not None:
        _WORKER.close()
    _WORKER, _WORKER_CFG = None, cfg
    try:
        load_plugins()
        _WORKER = Evaluator(cfg.suite, cfg.backend, cfg.backend_kwargs)
    except Exception as e:
        _INIT_ERROR = f"{type(e).__name__}: {e}"
        return
    if "torch" in sys.modules:  # loaded by the backend: the environment came too late
        sys.modules["torch"].set_num_threads(WORKER_THREADS)


def _work(index: int) -> tuple[int, list[dict[str, Any]]]:
    if _WORKER is None:
        raise RunError(
            f"a worker could not set up the backend: {_INIT_ERROR} (a backend registered at "
            "run time, not by an import or an entry point, exists only in its own process: "
            "use workers=1)"
        )
    return index, [_clean(r) for r in _WORKER.run_item(index)]


def _work_for(cfg: RunConfig, index: int) -> tuple[int, list[dict[str, Any]]]:
    """One item of ``cfg`` in a :class:`WorkerPool` process, which sets ``cfg`` up the first
    time it sees it (the items of one run arrive together, so that is once per run)."""
    if _WORKER_CFG != cfg:
        _init_worker(cfg, pin=False)
    return _work(index)


class WorkerPool:
    """Worker processes kept across runs (``with WorkerPool(2) as pool: run(..., pool=pool)``).

    A campaign's runs are often short (``make demo``: 35 runs of 6-44 items), and a fresh
    pool per run pays process start-up, imports (mujoco, torch) and model loading each time:
    about 3 s a run, more than the 44 oracle items cost. Here a worker rebuilds only its
    evaluator when the run changes. Results do not depend on which process scores an item
    (tested), so they equal a fresh pool's.
    """

    def __init__(self, workers: int | None = None) -> None:
        self.workers = default_workers() if workers is None else max(1, int(workers))
        self._pool: Any = None

    def results(self, cfg: RunConfig, todo: list[int]) -> Iterator[tuple[int, list]]:
        if not todo:  # a finished run (resumed) starts no processes
            return
        if self._pool is None:
            # spawn: workers start clean (no inherited GL state or torch threads)
            ctx = mp.get_context("spawn")
            self._pool = ctx.Pool(self.workers, initializer=_pin_threads)
        yield from self._pool.imap_unordered(partial(_work_for, cfg), todo, chunksize=1)

    def close(self) -> None:
        if self._pool is not None:
            self._pool.terminate()
            self._pool.join()
            self._pool = None

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _results(cfg: RunConfig, todo: list[int], workers: int) -> Iterator[tuple[int, list]]:
    global _WORKER, _WORKER_CFG
    if workers <= 1:
        # in this process: pin its threads for the run, as a worker's, then restore them
        saved = {v: os.environ.get(v) for v in _THREAD_VARS}
        had_torch = "torch" in sys.modules
        torch_threads = sys.modules["torch"].get_num_threads() if had_torch else None
        limiter = _pin_threads()
        _init_worker(cfg, pin=False)
        if _WORKER is None:
            limiter.restore_original_limits()
            raise RunError(f"could not set up backend {cfg.backend!r}: {_INIT_ERROR}")
        try:
            for i in todo:
                yield _work(i)
        finally:
            _WORKER.close()
            _WORKER = _WORKER_CFG = None
            limiter.restore_original_limits()
            for var, value in saved.items():
                if value is None:
                    os.environ.pop(var, None)
                else:
                    os.environ[var] = value
            if "torch" in sys.modules:
                sys.modules["torch"].set_num_threads(torch_threads or default_workers())
        return
    with WorkerPool(workers) as pool:
        yield from pool.results(cfg, todo)


def _ray_results(cfg: RunConfig, todo: list[int], workers: int) -> Iterator[tuple[int, list]]:
    try:
        import ray
    except ImportError as e:
        raise RunError("--ray needs the ray extra: pip install 'beo-bench[ray]'") from e
    if not ray.is_initialized():
        ray.init(
            address=os.environ.get("RAY_ADDRESS"),
            num_cpus=None if os.environ.get("RAY_ADDRESS") else workers,
            include_dashboard=False,
            log_to_driver=False,
        )

    @ray.remote(num_cpus=1)
    class Actor:
        def __init__(self, c: RunConfig) -> None:
            _init_worker(c)

        def work(self, i: int) -> tuple[int, list]:
            return _work(i)

    actors = [Actor.remote(cfg) for _ in range(max(1, workers))]
    pool = ray.util.ActorPool(actors)
    yield from pool.map_unordered(lambda a, i: a.work.remote(i), todo)


# -- the run ---------------------------------------------------------------------------------
def _git(*args: str) -> str:
    """Output of a git command run in the package's checkout ("" when there is none)."""
    try:
        return subprocess.run(
            ["git", *args],
            capture_output=True,
            text=True,
            cwd=Path(__file__).resolve().parent,
            timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def provenance(cfg: RunConfig) -> dict[str, Any]:
    import importlib.metadata as md

    def version(name: str) -> str | None:
        try:
            return md.version(name)
        except md.PackageNotFoundError:
            return None

    commit, dirty = _git("rev-parse", "HEAD"), _git("status", "--porcelain", "--untracked-files=no")
    return {
        "git_commit": commit or None,
        "git_dirty": bool(dirty) if commit else None,
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
        "suite": asdict(cfg.suite),
        "backend_kwargs": cfg.backend_kwargs,
    }


def suite_categories(suite: Suite) -> tuple[str, ...]:
    """The class list a suite's views carry (``View.categories``)."""
    if suite.kind == "isolated":
        from beo_bench.objects import ObjectSet

        return ObjectSet(suite.split).categories
    from beo_bench.envs.pick import default_categories

    return default_categories()


def _prepare(cfg: RunConfig) -> None:
    """The backend's one-time set-up, here, before workers start (they then load it)."""
    from beo_bench.backend import get_backend, load_plugins, prepare_backend

    load_plugins()
    prepare_backend(get_backend(cfg.backend, **cfg.backend_kwargs), suite_categories(cfg.suite))


def run(
    cfg: RunConfig,
    out: Path | str,
    workers: int | None = None,
    resume: bool = False,
    use_ray: bool = False,
    progress: bool = True,
    pool: WorkerPool | None = None,
) -> dict[str, Any]:
    """Run (or resume) ``cfg`` into ``out`` with ``workers`` processes (default: one per
    core), Ray actors, or the processes of ``pool`` (kept across runs; it sets the number
    of workers); returns the summary."""
    from tqdm import tqdm

    from beo_bench.bench.summary import summarise

    if pool is not None:
        workers = pool.workers
    workers = default_workers() if workers is None else max(1, int(workers))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    results, meta_path = out / "results.jsonl", out / "run.json"
    # what fixes the items and their scores; the size is left out because item i depends
    # only on (seed, i): a run can be extended, or summarised over its first items
    suite = {k: v for k, v in asdict(cfg.suite).items() if k not in ("size", "description")}
    meta = json.loads(
        json.dumps(
            {"suite": suite, "backend": cfg.backend, "backend_kwargs": cfg.backend_kwargs},
            default=_jsonable,
        )
    )
    if results.exists() and results.stat().st_size > 0:
        if not resume:
            raise RunError(
                f"{results} already has results: pass --resume to continue that "
                "run, or choose another --out"
            )
        old = json.loads(meta_path.read_text()) if meta_path.exists() else None
        if old != meta:
            raise RunError(
                f"{out} holds a different run ({old}); resuming needs the same suite "
                "(version, seed, protocol), backend and options: choose another --out"
            )
    write_json_atomic(meta_path, meta)
    done = {r["item"] for r in read_rows(results, repair=True) if r["item"] < cfg.suite.size}
    todo = [i for i in range(cfg.suite.size) if i not in done]
    if todo:
        _prepare(cfg)
    t0 = time.perf_counter()
    if use_ray:
        source = _ray_results(cfg, todo, workers)
    elif pool is not None and workers > 1:
        source = pool.results(cfg, todo)
    else:
        source = _results(cfg, todo, workers)
    bar = tqdm(
        total=cfg.suite.size,
        initial=len(done),
        disable=not progress,
        desc=f"{cfg.suite.name} / {cfg.backend}",
        unit="item",
    )
    with bar, ResultsWriter(results) as writer:
        for _, rows in source:
            writer.append(rows)
            bar.update(1)
    wall = time.perf_counter() - t0
    rows = [r for r in read_rows(results) if r["item"] < cfg.suite.size]
    rows.sort(key=lambda r: (r["item"], r["view"]))
    summary = summarise(cfg.suite, cfg.backend, rows)
    summary["provenance"] = provenance(cfg)
    summary["provenance"]["wall_s_last_session"] = wall
    summary["provenance"]["workers"] = workers
    summary["provenance"]["ray"] = use_ray
    write_json_atomic(out / "summary.json", summary)
    return summary
