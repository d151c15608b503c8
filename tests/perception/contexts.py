"""A run's context for calling ``Backend.prepare(ctx)`` directly in tests."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from beo_bench.backend import get_spec
from beo_bench.bench.runs import BackendRef, RunContext
from beo_bench.bench.suites import get_suite


def run_context(
    backend: str, categories: Sequence[str], suite: str = "pose-3dof", **opts: Any
) -> RunContext:
    """The context of a run of ``backend`` with options ``opts`` on ``suite`` whose views
    carry ``categories`` (what ``prepare`` reads: the class list, the dataset, whether it may
    show progress bars), resolved as :meth:`RunContext.of` resolves one, without its track
    checks and with any class list."""
    spec = get_spec(backend)
    options = spec.parse(opts)
    ref = BackendRef(backend, dict(opts), options, spec.capabilities_of(options))
    return RunContext(suite=get_suite(suite), backend=ref, categories=tuple(categories))
