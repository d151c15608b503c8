"""The runner and the backends it drives: a failing backend is recorded and the run goes
on, and ``prepare`` runs once, before the items, with the suite's classes."""

from __future__ import annotations

import numpy as np
import pytest

from beo_bench import backend as B
from beo_bench.bench.rows import read_rows
from beo_bench.bench.runner import RunError
from tests.bench.runs import FAST_RANDOM, short_run


def test_a_failing_backend_is_recorded_and_the_run_goes_on(tmp_path) -> None:
    class Boom(B.Backend):
        name = "test-boom"

        def predict(self, view):
            if int(np.count_nonzero(view.mask)) % 2:
                raise RuntimeError("odd mask")
            return B.get_backend("random", **FAST_RANDOM).predict(view)

    B.register(Boom)
    try:
        # registered here, so it exists only in this process: one in-process worker
        s = short_run(tmp_path, "pose-3dof", "test-boom", 12, workers=1)
        # worker processes cannot build it: a clear error, not a pool restarting forever
        with pytest.raises(RunError, match="could not set up the backend"):
            short_run(tmp_path / "two", "pose-3dof", "test-boom", 4, workers=2)
    finally:
        B.unregister_backend("test-boom")
    rows = read_rows(tmp_path / "pose-3dof-test-boom-12" / "results.jsonl")
    failed = [r for r in rows if r["failure"]]
    assert s["n"] == 12 and s["failures"] == len(failed) > 0
    assert all("odd mask" in r["failure"] for r in failed)
    assert not any(r["correct"] for r in failed)


def test_prepare_runs_once_before_the_items_with_the_suite_classes(tmp_path) -> None:
    calls: list[tuple[str, ...]] = []

    class Prepared(B.Backend):
        name = "test-prepared"

        def __init__(self, options=None) -> None:
            super().__init__(options)
            self.inner = B.get_backend("random", **FAST_RANDOM)

        def prepare(self, ctx) -> None:
            calls.append(tuple(ctx.categories))

        def predict(self, view):
            return self.inner.predict(view)

    B.register(Prepared)
    try:
        short_run(tmp_path, "pick", "test-prepared", 1, workers=1)
        short_run(tmp_path, "pick", "test-prepared", 1, workers=1, resume=True)  # nothing to do
    finally:
        B.unregister_backend("test-prepared")
    from beo_bench.scenes.pickconfig import default_categories

    assert calls == [default_categories()]
