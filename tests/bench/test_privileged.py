"""Privileged backends are visible: only an in-tree bound, or a plugin run with
``--allow-privileged``, is handed the truth; every run records whether it was; and for any
other backend the truth is not a local of any frame on ``predict``'s call stack."""

from __future__ import annotations

import inspect
import json

import numpy as np
import pytest

from beo_bench import backend as B
from beo_bench.bench.evaluate import Evaluator
from beo_bench.bench.runner import RunConfig, run
from beo_bench.bench.suites import get_suite
from beo_bench.cli import build_parser
from beo_bench.types import Estimate, GroundTruth

FAST = {"mean_instances": 4}
"""The random bound's class means from 4 instances a class (the default uses the split)."""


class Peek(B.Backend):
    """Wraps the oracle and declares ``privileged``: what a cheating plugin would do."""

    name = "test-peek"
    capabilities = B.Capabilities(privileged=True)

    def __init__(self, options=None) -> None:
        super().__init__(options)
        self.inner = B.get_backend("oracle")

    def predict(self, view):
        return self.inner.predict(view)


@pytest.fixture
def peek():
    B.register(Peek)  # what a cheating plugin would declare
    try:
        yield "test-peek"
    finally:
        B.unregister_backend("test-peek")


def _cfg(backend: str, allow: bool = False, n: int = 2, **opts) -> RunConfig:
    return RunConfig(get_suite("pose-1dof").with_overrides(size=n), backend, opts, allow)


def test_a_privileged_plugin_needs_allow_privileged(tmp_path, peek) -> None:
    out = tmp_path / "peek"
    with pytest.raises(B.PrivilegeError, match="--allow-privileged"):
        run(_cfg(peek), out, progress=False, workers=1)
    assert not (out / "results.jsonl").exists()  # refused before anything was scored
    with pytest.raises(B.PrivilegeError):
        Evaluator.of(get_suite("pose-1dof"), peek)  # a worker refuses it too
    s = run(_cfg(peek, allow=True), out, progress=False, workers=1)
    assert s["privileged"] is True and s["provenance"]["privileged"] is True
    assert json.loads((out / "run.json").read_text())["privileged"] is True
    assert s["metrics"]["rot_err_deg_mean"] < 1e-6  # it was handed the answer


def test_every_run_records_whether_it_was_privileged(tmp_path) -> None:
    for backend, privileged, opts in (("oracle", True, {}), ("random", False, FAST)):
        s = run(_cfg(backend, **opts), tmp_path / backend, progress=False, workers=1)
        assert s["privileged"] is privileged and s["provenance"]["privileged"] is privileged


def test_the_cli_has_the_flag_on_run_and_all() -> None:
    p = build_parser()
    assert p.parse_args(["run", "--suite", "pose-1dof", "--backend", "x"]).allow_privileged is False
    args = p.parse_args(["run", "--suite", "pose-1dof", "--backend", "x", "--allow-privileged"])
    assert args.allow_privileged is True
    assert p.parse_args(["all", "--allow-privileged"]).allow_privileged is True


class StackSearch(B.Backend):
    """Looks through every frame above its ``predict`` for a ``GroundTruth`` (or a list or
    tuple holding one) among the frame's locals: the cheat a generic plugin could try."""

    name = "test-stack-search"

    def __init__(self, options=None) -> None:
        super().__init__(options)
        self.found: list[str] = []

    def predict(self, view):
        for info in inspect.stack()[1:]:
            for name, value in info.frame.f_locals.items():
                items = value if isinstance(value, list | tuple) else [value]
                for v in items:
                    inner = v if isinstance(v, list | tuple) else [v]
                    if any(isinstance(x, GroundTruth) for x in inner):
                        self.found.append(f"{info.function}:{name}")
        n = len(view.categories)
        pts = view.points()
        centre = pts.mean(axis=0) if len(pts) else np.array([0.0, 0.0, 0.5])
        return Estimate(np.full(n, 1 / n), np.eye(3), centre, np.full(3, 0.1), np.ones((8, 8, 8)))


@pytest.mark.parametrize("suite", ["pose-3dof", "pose-1dof", "tabletop", "pick"])
def test_the_truth_is_not_on_predicts_call_stack(suite) -> None:
    B.register(StackSearch)
    try:
        ev = Evaluator.of(get_suite(suite).with_overrides(size=2), "test-stack-search")
        rows = ev.run_item(1)
        ev.close()
    finally:
        B.unregister_backend("test-stack-search")
    assert rows and all(r.get("failure") is None for r in rows)
    found = ev.backend.found  # type: ignore[attr-defined]
    assert found == [], f"the truth was on the stack at {found}"
    assert np.isfinite(rows[0]["item_ms"])
