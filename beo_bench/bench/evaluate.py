"""Score a backend on a suite's items (one worker's job).

An :class:`Evaluator` is made from a run's :class:`~beo_bench.bench.runs.RunContext`. It
owns what is slow to create (the suite's items: a renderer or an env; the backend, built
and prepared once) and turns item index ``i`` into result rows: plain JSON-serialisable
dicts, one per scored view (isolated, tabletop) or episode (pick), as the suite's item
kind (:mod:`beo_bench.bench.kinds`) defines them. A backend that raises or returns garbage
is recorded as a failure with its reason and scored as wrong; the run goes on. One that
hangs or kills its worker is recorded the same way by the worker pool, from the rows the
evaluator announced before calling it (:func:`failed_rows`).
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from beo_bench.backend import Backend, validate_estimate
from beo_bench.bench.kinds import get_kind
from beo_bench.bench.kinds.common import Announce, Items, no_announce
from beo_bench.bench.runs import RunConfig, RunContext
from beo_bench.bench.scoring import Answer
from beo_bench.bench.suites import Suite
from beo_bench.types import View


def ItemViews(suite: Suite, class_given: bool = False, cache_root: Path | None = None) -> Items:
    """A suite's items without a backend (views, truths, rows before a backend call), as
    its item kind makes them, their objects kept in the cache at ``cache_root`` (None: the
    environment's)."""
    return get_kind(suite.kind).open(suite, class_given, cache_root)


def failed_rows(suite: Suite, templates: list[dict[str, Any]], reason: str) -> list[dict[str, Any]]:
    """The rows of an item of ``suite`` whose backend never answered (``reason``: ``timeout
    after 60 s``, ``worker died: signal 6``), from its rows as known before the backend was
    called: scored as a backend's exception is (its item kind says how)."""
    return get_kind(suite.kind).failed_rows(templates, reason)


class Evaluator:
    """Scores the run's backend on items of its suite. Create one per process; it builds
    the backend once (or takes the one the driver built: ``backend``) and prepares it with
    the context; ``items``: the suite's items to use (default: its own, opened here)."""

    def __init__(
        self, ctx: RunContext, backend: Backend | None = None, items: Items | None = None
    ) -> None:
        self.ctx = ctx
        self.suite = ctx.suite
        self.kind = get_kind(ctx.suite.kind)
        # the items may be the caller's (the report rebuilds views with its own, and the
        # truth a privileged backend is handed must be of the scene those hold)
        self.items: Items = (
            self.kind.open(ctx.suite, ctx.class_given, ctx.cache_root) if items is None else items
        )
        if backend is None:
            backend = ctx.backend.build()
            backend.prepare(ctx)
        self.backend = backend
        # the truth goes to an in-tree bound, or to a plugin run with --allow-privileged
        # (RunContext.of checked); the true class only to a backend that can use it, and
        # only in the class-given track (Suite.track): never a backend option's
        self.privileged = ctx.privileged
        self.class_hint = ctx.class_given
        self.robust = ctx.backend.capabilities.grasp == "robust"

    @classmethod
    def of(
        cls,
        suite: Suite,
        backend: str,
        backend_kwargs: dict[str, Any] | None = None,
        allow_privileged: bool = False,
    ) -> Evaluator:
        """An evaluator of ``backend`` on ``suite`` (its context resolved here: for tests,
        benchmarks and notebooks)."""
        cfg = RunConfig(suite, backend, dict(backend_kwargs or {}), allow_privileged)
        return cls(RunContext.of(cfg))

    def close(self) -> None:
        self.items.close()

    def run_item(self, index: int, announce: Announce = no_announce) -> list[dict[str, Any]]:
        """The result rows of item ``index``. The first row carries ``item_ms`` (the whole
        item's time in this worker: rendering, every prediction, scoring, grasping) and
        ``item_rows`` (how many rows the item has: a reader can tell a complete item from one
        that lost a line). ``announce`` gets the rows known before the backend is called."""
        t0 = time.perf_counter()
        rows = self.kind.run_item(self.items, self.predict, index, announce, robust=self.robust)
        if rows:
            rows[0]["item_ms"] = 1000 * (time.perf_counter() - t0)
            rows[0]["item_rows"] = len(rows)
        return rows

    def predict(self, index: int, j: int, view: View) -> Answer:
        """The backend's answer for view ``j`` of item ``index``. Only a privileged bound
        is handed the truth; the class hint goes only to a backend in the class-given track
        that uses it (both fetched here, for this call alone)."""
        if self.privileged or self.class_hint:
            gt = self.items.truth_of(index, view)
            if self.privileged:
                view = replace(view, ground_truth=gt)
            if self.class_hint:
                view = replace(view, class_hint=gt.class_index)
            del gt
        t0 = time.perf_counter()
        try:
            est = validate_estimate(self.backend.predict(view), view)
            failure = None
        except Exception as e:  # recorded, scored as wrong; the run goes on
            est, failure = None, f"{type(e).__name__}: {e}"[:500]
        return est, time.perf_counter() - t0, failure
