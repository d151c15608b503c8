"""The processes that score a run's items: :class:`WorkerPool`, with a deadline per item.

Each worker is a ``spawn``ed process with a pipe of its own; the driver hands it one item
at a time and it answers in up to three messages:

- ``("setup", error)`` after (re)building its evaluator for a new run ("" when it worked);
- ``("begin", index, rows)`` once the item's views exist and *before* the backend sees
  them: the item's rows as far as they are known without the backend (keys, classes). If
  the backend then kills or hangs the worker, the driver records these rows as failures,
  without needing the backend or the worker again;
- ``("done", index, rows)``, or ``("error", index, traceback)`` when the package's own code
  raised (a backend's exception is a recorded failure, not an error), or
  ``("data-error", index, exception)`` when the user's data or set-up did (a
  :class:`~beo_bench.errors.UserDataError`: a bad mesh file, an unwritable cache), which
  the driver raises as it is: it is not a bug in beo-bench, and its message says what to fix.

A worker that dies (a signal, ``os.abort``, ``sys.exit``) or overruns its item's deadline is
killed and replaced; its item is recorded as failed with the reason (``timeout after 60 s``,
``worker died: signal 6``, ``worker exited with status 3``) and the run goes on. Workers
exit by themselves when the driver dies, even ``kill -9``ed: they get ``SIGKILL`` from the
kernel (``PR_SET_PDEATHSIG``, Linux), and a thread polls the parent PID as a fallback.

A worker that dies or times out while setting up (building the backend, ``SETUP_TIMEOUT_S``)
or before its item's ``begin`` (generating the item's scene: the package's own code) has no
item to blame, and the run stops with a :class:`RunError` saying so; complete items are kept.

The same deadlines apply on Ray (:func:`ray_results`); :func:`in_process_results`, for a
backend that only this process knows, has none.
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
import traceback
from collections import deque
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from multiprocessing.connection import wait
from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench.bench.runs import RunContext, RunError
from beo_bench.errors import UserDataError

if TYPE_CHECKING:
    from beo_bench.backend import Backend
    from beo_bench.bench.evaluate import Evaluator

__all__ = ["WORKER_THREADS", "RunError", "WorkerPool", "default_workers", "pin_threads"]

Rows = list[dict[str, Any]]

WORKER_THREADS = 1
"""BLAS / OpenMP / torch threads per worker. Workers run one per core, and pinning every
path (in-process, local processes, Ray actors, which Ray already pins to 1) to the same count
makes reductions identical, so results do not depend on how a run was spread out."""

SETUP_TIMEOUT_S = 300.0
"""How long a worker may take to start and set up a run's backend (imports, loading a
model) before its first item's deadline starts; a worker still setting up after that (or
after the item timeout, if longer) stops the run with a RunError."""

PARENT_POLL_S = 0.5
"""How often a worker checks that the driver is still alive (the fallback to the kernel's
parent-death signal, e.g. for a pool started from a thread other than the main one)."""

_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
_PR_SET_PDEATHSIG = 1


def default_workers() -> int:
    """One worker per available core."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def jsonable(o: Any) -> Any:
    """``json.dumps``'s ``default``: numpy scalars and arrays, tuples."""
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    raise TypeError(f"not JSON-serialisable: {type(o).__name__}")


def clean_row(row: dict[str, Any]) -> dict[str, Any]:
    return {k: jsonable(v) if isinstance(v, np.generic | np.ndarray) else v for k, v in row.items()}


# -- worker side -----------------------------------------------------------------------------
def pin_threads() -> Any:
    """Limit this process's thread pools to ``WORKER_THREADS``: the already loaded ones
    through threadpoolctl, the ones loaded later (torch in a backend) through the
    environment. Returns the limiter (keep it alive; ``restore_original_limits`` undoes)."""
    from threadpoolctl import threadpool_limits

    for var in _THREAD_VARS:
        os.environ[var] = str(WORKER_THREADS)
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(WORKER_THREADS)
    return threadpool_limits(limits=WORKER_THREADS)


class WorkerState:
    """What one worker process (or Ray actor) holds: the evaluator of the run it is set up
    for, or why setting it up failed. Local to the worker's loop (no module state)."""

    def __init__(self, import_error: str = "") -> None:
        self.ctx: RunContext | None = None
        self.evaluator: Evaluator | None = None
        self.import_error = import_error
        self.error = ""
        self.data_error: UserDataError | None = None
        """Set-up's error when the user's data caused it (passed on as it is)."""

    def setup(self, ctx: RunContext) -> None:
        """Set up the evaluator for ``ctx`` (closing one set up for another run). An error
        is kept (``error``) rather than raised: the caller reports it."""
        from beo_bench.backend import load_plugins
        from beo_bench.bench.evaluate import Evaluator

        if self.evaluator is not None:
            self.evaluator.close()
        self.ctx, self.evaluator, self.error = ctx, None, self.import_error
        self.data_error = None
        if self.import_error:
            return
        try:
            load_plugins()
            self.evaluator = Evaluator(ctx)
        except Exception as e:
            self.error = f"{type(e).__name__}: {e}"
            if isinstance(e, UserDataError):
                self.data_error = e
            return
        if "torch" in sys.modules:  # loaded by the backend: the environment came too late
            sys.modules["torch"].set_num_threads(WORKER_THREADS)

    def work(self, index: int) -> tuple[int, Rows]:
        """Item ``index`` of the run set up by :meth:`setup`."""
        if self.evaluator is None:
            assert self.ctx is not None
            if self.data_error is not None:
                raise self.data_error
            raise setup_error(self.ctx, self.error)
        return index, [clean_row(r) for r in self.evaluator.run_item(index)]


def setup_error(ctx: RunContext, why: str, imports: tuple[str, ...] = ()) -> RunError:
    """A worker's failed set-up; with the hint about backends registered at run time only
    for such a backend (``imports``: the modules the workers import)."""
    from beo_bench.backend import buildable_in_fresh_process

    hint = ""
    if not buildable_in_fresh_process(ctx.backend.name, imports):
        hint = (
            " (a backend registered at run time, not by an import or an entry point, exists "
            "only in its own process: use workers=1, or WorkerPool(imports=[its module]))"
        )
    return RunError(f"a worker could not set up the backend {ctx.backend.name!r}: {why}{hint}")


def _import_all(modules: Iterable[str]) -> str:
    """Import the modules that register backends outside the tree; the first failure, as
    the set-up error to report ("" when all imported)."""
    for name in modules:
        try:
            importlib.import_module(name)
        except Exception as e:  # reported by the first set-up, as the driver's error
            return f"importing {name}: {type(e).__name__}: {e}"
    return ""


def _die_with_parent(parent: int, deathsig: bool) -> None:
    """Exit when the driver does. The kernel's parent-death signal acts even while this
    process hangs in C code holding the GIL; it is tied to the *thread* that started the
    worker, so it is only asked for when that was the main thread (``deathsig``). The
    polling thread covers every case a few tenths of a second later."""
    if deathsig and sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent:  # the driver died before prctl took effect
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="beo-bench-parent-watch", daemon=True).start()


def worker_main(conn: Any, parent: int, imports: tuple[str, ...], deathsig: bool) -> None:
    """A worker process: items in, messages out (see the module docstring), until the
    driver closes the pipe."""
    _die_with_parent(parent, deathsig)
    # Ctrl-C reaches the whole process group: the driver handles it and stops the workers
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    quiet_dataset_warnings()
    pin_threads()
    state = WorkerState(_import_all(imports))
    while True:
        try:
            ctx, index = conn.recv()
        except (EOFError, OSError):  # the driver closed the pipe (or died)
            return
        if state.ctx != ctx:
            state.setup(ctx)
            if state.data_error is not None:
                _send_data_error(conn, "setup", state.data_error, state.error)
            else:
                error = "" if state.evaluator is not None else state.error or "unknown"
                conn.send(("setup", error))
        if state.evaluator is None:
            continue

        def begin(rows: Rows, i: int = index) -> None:
            conn.send(("begin", i, [clean_row(r) for r in rows]))

        try:
            rows = state.evaluator.run_item(index, announce=begin)
            conn.send(("done", index, [clean_row(r) for r in rows]))
        except UserDataError as e:
            _send_data_error(conn, index, e, traceback.format_exc()[-4000:])
        except Exception:
            conn.send(("error", index, traceback.format_exc()[-4000:]))


def quiet_dataset_warnings() -> None:
    """Silence, in a worker, the warnings about a dataset that the driver already showed
    (links skipped by the scan, files near the size limits): each worker scans the
    dataset again, and would repeat them once per process, in Python's multi-line form."""
    import warnings

    from beo_bench.objects.datasets import DatasetScanWarning, UnknownSizeWarning

    warnings.simplefilter("ignore", DatasetScanWarning)
    warnings.simplefilter("ignore", UnknownSizeWarning)


def _send_data_error(conn: Any, index: int | str, e: UserDataError, fallback: str) -> None:
    """Send a user-data error to the driver as the exception itself (``index``: the item,
    or ``"setup"``); one that cannot be pickled goes as its text, a plain error."""
    try:
        conn.send(("data-error", index, e))
    except Exception:  # unpicklable arguments: the traceback text, as for any error
        conn.send(("error", index, fallback) if index != "setup" else ("setup", fallback))


# -- driver side -----------------------------------------------------------------------------
@dataclass
class _Slot:
    """One worker process and the item it is busy with."""

    proc: Any = None
    conn: Any = None
    ctx: Any = None
    """The run whose evaluator the worker holds (None: none yet)."""
    index: int | None = None
    phase: str = ""
    """``setup`` (building the evaluator), ``scene`` (the item's views), ``backend``."""
    deadline: float = 0.0
    limit: float = 0.0
    """The seconds the current phase was given (for the timeout's reason)."""
    begun: Rows | None = None

    @property
    def busy(self) -> bool:
        return self.index is not None


def _fmt_s(seconds: float) -> str:
    return f"{seconds:g}"


def exit_reason(exitcode: int | None) -> str:
    """How a worker process ended, as a failure's reason."""
    if exitcode is not None and exitcode < 0:
        return f"worker died: signal {-exitcode}"
    return f"worker exited with status {exitcode}"


class WorkerPool:
    """Worker processes kept across runs (``with WorkerPool(2) as pool: run(..., pool=pool)``).

    A campaign's runs are often short (``make demo``: 35 runs of 6-44 items), and a fresh
    pool per run pays process start-up, imports (mujoco, torch) and model loading each time:
    about 3 s a run, more than the 44 oracle items cost. Here a worker rebuilds only its
    evaluator when the run changes. Results do not depend on which process scores an item
    (tested), so they equal a fresh pool's.

    ``imports``: modules each worker imports at start, for backends registered by a module
    that is neither in-tree nor an entry point (a spawned worker knows only those).
    ``restarts`` counts the workers replaced after a death or a timeout.
    """

    def __init__(self, workers: int | None = None, imports: Iterable[str] = ()) -> None:
        self.workers = default_workers() if workers is None else max(1, int(workers))
        self.imports = tuple(imports)
        self.restarts = 0
        self._slots = [_Slot() for _ in range(self.workers)]

    # -- processes -------------------------------------------------------------------------
    def _start(self, slot: _Slot) -> None:
        # spawn: workers start clean (no inherited GL state, torch threads or open files)
        ctx = mp.get_context("spawn")
        here, there = ctx.Pipe(duplex=True)
        main = threading.current_thread() is threading.main_thread()
        proc = ctx.Process(
            target=worker_main,
            args=(there, os.getpid(), self.imports, main),
            name="beo-bench-worker",
            daemon=True,
        )
        try:
            proc.start()
        except OSError as e:  # out of processes or memory
            here.close()
            there.close()
            raise RunError(f"could not start a worker process: {e}") from e
        there.close()  # the worker's end: with it closed here, its death reads as EOF
        slot.proc, slot.conn, slot.ctx = proc, here, None

    def _kill(self, slot: _Slot, grace: float = 0.0) -> int | None:
        """Stop the slot's process: wait up to ``grace`` s for it to end by itself (a dying
        worker, so its own exit status is read), then SIGKILL it. Returns the exit code."""
        code = None
        if slot.proc is not None:
            slot.proc.join(grace)
            if slot.proc.exitcode is None:
                slot.proc.kill()
                slot.proc.join(5)
            code = slot.proc.exitcode
        if slot.conn is not None:
            slot.conn.close()
        slot.proc = slot.conn = slot.ctx = None
        slot.index, slot.begun = None, None
        return code

    def close(self) -> None:
        """Stop every worker (they hold nothing worth a graceful exit)."""
        for slot in self._slots:
            if slot.proc is not None and slot.proc.exitcode is None:
                slot.proc.terminate()
        for slot in self._slots:
            self._kill(slot, grace=5.0)

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- items -----------------------------------------------------------------------------
    def results(
        self, ctx: RunContext, todo: list[int], item_timeout: float | None = None
    ) -> Iterator[tuple[int, Rows]]:
        """``(index, rows)`` of each item of ``todo`` as it finishes, failed items included.
        ``item_timeout``: seconds per item (default: the suite's ``item_timeout_s``)."""
        if not todo:  # a finished run (resumed) starts no processes
            return
        timeout = ctx.suite.item_timeout_s if item_timeout is None else float(item_timeout)
        queue = deque(todo)
        try:
            while queue or any(s.busy for s in self._slots):
                self._refill(ctx, queue, timeout)
                finished = list(self._collect(ctx, timeout))
                # idle workers get their next item before the caller writes these results
                self._refill(ctx, queue, timeout)
                yield from finished
        finally:
            # abandoned mid-run (an error, Ctrl-C): a busy worker's answer would otherwise
            # reach the pool's next run as if it were that run's
            for slot in self._slots:
                if slot.busy:
                    self._kill(slot)

    def _refill(self, ctx: RunContext, queue: deque[int], timeout: float) -> None:
        for slot in self._slots:
            if queue and not slot.busy:
                self._assign(slot, ctx, queue.popleft(), timeout)

    def _assign(self, slot: _Slot, ctx: RunContext, index: int, timeout: float) -> None:
        if slot.proc is not None and slot.proc.exitcode is not None:
            self._kill(slot)  # it died while idle
            self.restarts += 1
        if slot.proc is None:
            self._start(slot)
        if slot.ctx != ctx:
            self._phase(slot, "setup", max(SETUP_TIMEOUT_S, timeout))
        else:
            self._phase(slot, "scene", timeout)
        slot.ctx, slot.index, slot.begun = ctx, index, None
        try:
            slot.conn.send((ctx, index))
        except OSError:  # it died while idle: its item starts on a new worker
            self._kill(slot)
            self.restarts += 1
            self._assign(slot, ctx, index, timeout)

    @staticmethod
    def _phase(slot: _Slot, phase: str, limit: float) -> None:
        slot.phase, slot.limit, slot.deadline = phase, limit, time.monotonic() + limit

    def _collect(self, ctx: RunContext, timeout: float) -> Iterator[tuple[int, Rows]]:
        """Wait until a worker answers, dies, or passes its deadline; handle that."""
        busy = [s for s in self._slots if s.busy]
        left = max(0.0, min(s.deadline for s in busy) - time.monotonic())
        ready = set(wait([s.conn for s in busy] + [s.proc.sentinel for s in busy], left))
        for slot in busy:
            dead = slot.proc.sentinel in ready
            if dead or slot.conn in ready:
                yield from self._read(slot, ctx, timeout)
            if slot.busy and dead:  # ended without closing the pipe (a child holds it)
                yield from self._failed(slot, ctx, None)
            if slot.busy and time.monotonic() > slot.deadline:
                yield from self._failed(slot, ctx, f"timeout after {_fmt_s(slot.limit)} s")

    def _read(self, slot: _Slot, ctx: RunContext, timeout: float) -> Iterator[tuple[int, Rows]]:
        """Every message the slot's worker has sent; its death when the pipe is closed."""
        while slot.busy:
            try:
                if not slot.conn.poll():
                    return
                msg = slot.conn.recv()
            except (EOFError, OSError):
                yield from self._failed(slot, ctx, None)
                return
            kind, *rest = msg
            if kind == "data-error":  # the user's data or set-up: raised as it is, no "bug"
                if rest[0] == "setup":
                    self._kill(slot)  # as for any failed set-up: it holds no evaluator
                slot.index, slot.begun = None, None
                raise rest[1]
            if kind == "setup":
                if rest[0]:
                    self._kill(slot)
                    raise setup_error(ctx, rest[0], self.imports)
                self._phase(slot, "scene", timeout)
            elif kind == "begin":
                slot.phase, slot.begun = "backend", rest[1]
            elif kind == "done":
                slot.index, slot.begun = None, None
                yield rest[0], rest[1]
            else:  # "error": the package's own code raised; a bug to report
                index = slot.index
                slot.index = None
                raise RunError(
                    f"item {index} of {ctx.suite.name} raised in a worker outside the backend "
                    f"(a bug in beo-bench; please report it with this traceback):\n{rest[1]}"
                )

    def _failed(
        self, slot: _Slot, ctx: RunContext, reason: str | None
    ) -> Iterator[tuple[int, Rows]]:
        """The slot's worker died (``reason`` None) or timed out: kill it (a new one starts
        with the next item) and record its item as failed, or stop the run if the backend
        was not yet running."""
        from beo_bench.bench.evaluate import failed_rows

        index, phase, begun = slot.index, slot.phase, slot.begun
        code = self._kill(slot, grace=0.0 if reason else 5.0)
        self.restarts += 1
        why = reason or exit_reason(code)
        if phase == "setup":
            raise setup_error(ctx, why, self.imports)
        if phase == "scene" or begun is None:
            raise RunError(
                f"item {index} of suite {ctx.suite.name}: {why} while its views were "
                "generated, before the backend saw them (if a timeout: raise --item-timeout; "
                "else a bug in beo-bench or its renderer, please report it)"
            )
        assert index is not None
        yield index, failed_rows(ctx.suite, begun, why)


def in_process_results(
    ctx: RunContext, todo: list[int], backend: Backend | None = None
) -> Iterator[tuple[int, Rows]]:
    """The items scored in this process, for backends registered at run time, which exist
    only here (``backend``: the one the driver built and prepared, so it is not built
    twice). Limits: no item timeout, and a backend that crashes or exits takes the run
    with it (resume continues after the last complete item)."""
    from beo_bench.bench.evaluate import Evaluator

    if not todo:  # a finished run (resumed) builds nothing
        return
    # pin this process's threads for the run, as a worker's, then restore them
    with pinned_threads():
        try:
            ev = Evaluator(ctx, backend)
        except Exception as e:
            why = f"{type(e).__name__}: {e}"
            raise RunError(f"could not set up backend {ctx.backend.name!r}: {why}") from e
        try:
            for i in todo:
                yield i, [clean_row(r) for r in ev.run_item(i)]
        finally:
            ev.close()


@contextlib.contextmanager
def pinned_threads() -> Iterator[None]:
    """This process's threads pinned as a worker's (:func:`pin_threads`) for the ``with``
    block, then restored: a backend called here (in-process runs, the run's report) computes
    as it does in a worker, with the same reductions."""
    saved = {v: os.environ.get(v) for v in _THREAD_VARS}
    had_torch = "torch" in sys.modules
    torch_threads = sys.modules["torch"].get_num_threads() if had_torch else None
    limiter = pin_threads()
    try:
        yield
    finally:
        limiter.restore_original_limits()
        for var, value in saved.items():
            if value is None:
                os.environ.pop(var, None)
            else:
                os.environ[var] = value
        if "torch" in sys.modules:
            sys.modules["torch"].set_num_threads(torch_threads or default_workers())


def ray_results(
    ctx: RunContext,
    todo: list[int],
    workers: int,
    timeout: float,
    imports: tuple[str, ...] = (),
) -> Iterator[tuple[int, list[dict[str, Any]]]]:
    """The items as Ray actor calls, each with a deadline (``ray.wait``): an actor that
    overruns it is killed, one that dies is replaced, and the item is recorded as failed.
    The failed item's rows are generated here, in the driver (Ray gives no word before the
    backend is called): for tabletop and pick suites that renders the scene in this process."""
    try:
        import ray
    except ImportError as e:
        raise RunError("--ray needs the ray extra: pip install 'beo-bench[ray]'") from e
    from beo_bench.bench.evaluate import ItemViews, failed_rows

    if not ray.is_initialized():
        ray.init(
            address=os.environ.get("RAY_ADDRESS"),
            num_cpus=None if os.environ.get("RAY_ADDRESS") else workers,
            include_dashboard=False,
            log_to_driver=False,
        )

    @ray.remote(num_cpus=1)
    class Actor:
        def __init__(self, c: RunContext, modules: tuple[str, ...]) -> None:
            quiet_dataset_warnings()
            pin_threads()
            # a failed import is reported by the first item, as set-up's
            self.state = WorkerState(_import_all(modules))
            self.state.setup(c)

        def work(self, i: int) -> tuple[int, list]:
            return self.state.work(i)

    actors: Any = Actor  # ray.remote gives the class its `remote`, which mypy cannot see

    views = ItemViews(ctx.suite, ctx.class_given, ctx.cache_root)

    def failed(i: int, why: str) -> list[dict[str, Any]]:
        return [clean_row(r) for r in failed_rows(ctx.suite, views.templates(i), why)]

    queue, idle = deque(todo), [actors.remote(ctx, imports) for _ in range(max(1, workers))]
    fresh = set(idle)  # actors whose first call also waits for their set-up
    flight: dict[Any, tuple[Any, int, float]] = {}
    try:
        while queue or flight:
            while idle and queue:
                actor, i = idle.pop(), queue.popleft()
                grace = SETUP_TIMEOUT_S if actor in fresh else 0.0
                flight[actor.work.remote(i)] = (actor, i, time.monotonic() + timeout + grace)
            left = max(0.0, min(d for _, _, d in flight.values()) - time.monotonic())
            ready, _ = ray.wait(list(flight), num_returns=1, timeout=left)
            for ref in ready:
                actor, i, _ = flight.pop(ref)
                fresh.discard(actor)
                try:
                    rows = ray.get(ref)[1]  # cleaned by work()
                except ray.exceptions.RayActorError:
                    rows = failed(i, "worker died: Ray actor lost")
                    fresh.add(actor := actors.remote(ctx, imports))
                except ray.exceptions.RayTaskError as e:
                    cause = getattr(e, "cause", None)
                    if isinstance(cause, UserDataError):  # as a local worker's: as it is
                        raise cause from None
                    raise RunError(f"item {i} failed on a Ray actor: {e}") from e
                idle.append(actor)
                yield i, rows
            for ref, (actor, i, deadline) in list(flight.items()):
                if time.monotonic() > deadline:
                    del flight[ref]
                    ray.kill(actor)
                    yield i, failed(i, f"timeout after {_fmt_s(timeout)} s")
                    fresh.add(actor := actors.remote(ctx, imports))
                    idle.append(actor)
    finally:
        views.close()
        for actor, _, _ in flight.values():
            ray.kill(actor)
