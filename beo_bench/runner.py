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
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from beo_bench.errors import BeoBenchError
from beo_bench.suites import Suite


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


def append_rows(path: Path, rows: list[dict[str, Any]]) -> None:
    """Append one item's rows (one write, then fsync)."""
    with ResultsWriter(path) as w:
        w.append(rows)


def write_json_atomic(path: Path, obj: Any) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(obj, indent=2, sort_keys=True, default=_jsonable) + "\n")
    os.replace(tmp, path)


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
_WORKER: Any = None


def _init_worker(cfg: RunConfig) -> None:
    global _WORKER
    from beo_bench.backend import load_plugins
    from beo_bench.evaluate import Evaluator

    load_plugins()
    _WORKER = Evaluator(cfg.suite, cfg.backend, cfg.backend_kwargs)


def _work(index: int) -> tuple[int, list[dict[str, Any]]]:
    return index, [_clean(r) for r in _WORKER.run_item(index)]


def _results(cfg: RunConfig, todo: list[int], workers: int) -> Iterator[tuple[int, list]]:
    if workers <= 1:
        _init_worker(cfg)
        try:
            for i in todo:
                yield _work(i)
        finally:
            _WORKER.close()
        return
    # spawn: workers start clean (no inherited GL state or torch threads)
    ctx = mp.get_context("spawn")
    with ctx.Pool(workers, initializer=_init_worker, initargs=(cfg,)) as pool:
        yield from pool.imap_unordered(_work, todo, chunksize=1)


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
def provenance(cfg: RunConfig) -> dict[str, Any]:
    import importlib.metadata as md

    def version(name: str) -> str | None:
        try:
            return md.version(name)
        except md.PackageNotFoundError:
            return None

    try:
        commit = (
            subprocess.run(
                ["git", "rev-parse", "HEAD"],
                capture_output=True,
                text=True,
                cwd=Path(__file__).resolve().parent,
                timeout=5,
            ).stdout.strip()
            or None
        )
    except (OSError, subprocess.SubprocessError):
        commit = None
    return {
        "git_commit": commit,
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


def run(
    cfg: RunConfig,
    out: Path | str,
    workers: int = 1,
    resume: bool = False,
    use_ray: bool = False,
    progress: bool = True,
) -> dict[str, Any]:
    """Run (or resume) ``cfg`` into ``out``; returns the summary."""
    from tqdm import tqdm

    from beo_bench.summary import summarise

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    results, meta_path = out / "results.jsonl", out / "run.json"
    meta = {
        "suite": cfg.suite.name,
        "suite_version": cfg.suite.version,
        "backend": cfg.backend,
        "backend_kwargs": cfg.backend_kwargs,
        "seed": cfg.suite.seed,
        "size": cfg.suite.size,
    }
    if results.exists() and results.stat().st_size > 0:
        if not resume:
            raise RunError(
                f"{results} already has results: pass --resume to continue that "
                "run, or choose another --out"
            )
        old = json.loads(meta_path.read_text()) if meta_path.exists() else None
        if old != json.loads(json.dumps(meta, default=_jsonable)):
            raise RunError(
                f"{out} holds a different run ({old}); resume needs the same suite, "
                "backend, options, seed and size"
            )
    write_json_atomic(meta_path, meta)
    done = {r["item"] for r in read_rows(results, repair=True)}
    todo = [i for i in range(cfg.suite.size) if i not in done]
    t0 = time.perf_counter()
    source = _ray_results if use_ray else _results
    bar = tqdm(
        total=cfg.suite.size,
        initial=len(done),
        disable=not progress,
        desc=f"{cfg.suite.name} / {cfg.backend}",
        unit="item",
    )
    with bar, ResultsWriter(results) as writer:
        for _, rows in source(cfg, todo, workers):
            writer.append(rows)
            bar.update(1)
    wall = time.perf_counter() - t0
    rows = sorted(read_rows(results), key=lambda r: (r["item"], r["view"]))
    summary = summarise(cfg.suite, cfg.backend, rows)
    summary["provenance"] = provenance(cfg)
    summary["provenance"]["wall_s_last_session"] = wall
    summary["provenance"]["workers"] = workers
    summary["provenance"]["ray"] = use_ray
    write_json_atomic(out / "summary.json", summary)
    return summary
