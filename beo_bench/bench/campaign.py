"""Many runs at once: every (suite, backend) pair, then the leaderboard (``beo-bench all``,
and ``make demo`` on short suites).

Each pair runs into ``RUNS/<suite>[@<track>]__<backend>[__<options>]`` and resumes what is
already there, so a killed campaign continues where it stopped and a finished one costs
nothing to re-run; the leaderboard is then regenerated from every summary under ``RUNS``.
On a suite with tracks (``Suite.class_hint``) a backend that can use the class hint is run
in both tracks, ``class-given`` and ``class-free``, and any other backend in ``class-free``
only (see :func:`~beo_bench.bench.suites.backend_tracks`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from beo_bench.errors import BeoBenchError

if TYPE_CHECKING:
    from beo_bench.objects.dataset import Dataset


def options_label(kwargs: dict[str, Any]) -> str:
    """``k=v, k=v`` (sorted), or "" without options."""
    return ", ".join(f"{k}={json.dumps(v)}" for k, v in sorted(kwargs.items()))


def backend_label(backend: str, kwargs: dict[str, Any]) -> str:
    """How a leaderboard row names a backend run: ``icp`` or ``icp (starts=48)``."""
    opts = options_label(kwargs)
    return f"{backend} ({opts})" if opts else backend


def run_name(
    suite: str,
    backend: str,
    kwargs: dict[str, Any],
    seed: int | None = None,
    track: str | None = None,
) -> str:
    """The run directory's name: ``known-pose__icp``, ``pose-3dof@class-given__icp``,
    ``pose-3dof@class-free__icp__starts=48``, or with a replaced base seed
    ``pose-3dof@class-free__icp__suite_seed=7`` (the track is part of what identifies a
    run, so two tracks never share a directory)."""
    opts = dict(sorted(kwargs.items()))
    if seed is not None:
        opts["suite_seed"] = seed
    slug = "_".join(f"{k}={v}" for k, v in opts.items())
    safe = "".join(ch if ch.isalnum() or ch in "=.-_" else "-" for ch in slug)
    where = f"{suite}@{track}" if track else suite
    return f"{where}__{backend}" + (f"__{safe}" if safe else "")


def parse_options(pairs: list[str]) -> dict[str, Any]:
    """``["samples=25", "point_to_plane=false"]`` -> ``{"samples": 25, "point_to_plane":
    False}`` (values are JSON when they parse, else strings)."""
    out: dict[str, Any] = {}
    for pair in pairs:
        if "=" not in pair:
            raise BeoBenchError(f"option {pair!r}: use KEY=VALUE (e.g. samples=25)")
        k, v = pair.split("=", 1)
        try:
            out[k] = json.loads(v)
        except json.JSONDecodeError:
            out[k] = v  # a plain string
    return out


def parse_backend_spec(spec: str) -> tuple[str, dict[str, Any]]:
    """``"icp"`` or ``"hbeo-mdn-posterior:samples=25,seed=1"`` -> (name, options)."""
    name, _, opts = spec.partition(":")
    return name, parse_options([o for o in opts.split(",") if o])


@dataclass
class Campaign:
    """Which suites (name -> items, None for the suite's own size) and backends (name,
    options) to run, where, and how. ``item_timeout``: seconds per item in every run (None:
    each suite's ``item_timeout_s``). ``dataset``: run the suites on a user's dataset
    (:meth:`~beo_bench.bench.suites.Suite.with_dataset`; ``split`` replaces their split)."""

    suites: dict[str, int | None]
    backends: list[tuple[str, dict[str, Any]]]
    runs: Path = Path("runs")
    leaderboards: Path = Path("leaderboards")
    workers: int | None = None
    use_ray: bool = False
    seed: int | None = None
    progress: bool = True
    item_timeout: float | None = None
    dataset: Dataset | None = None
    split: str | None = None
    allow_privileged: bool = False
    """``--allow-privileged``: plugins that declare ``privileged`` may run (as bounds)."""


def run_campaign(c: Campaign) -> list[Path]:
    """Run every pair (resuming) in each of its tracks, then regenerate the leaderboard;
    returns its Markdown files. A backend whose construction fails stops the campaign before
    anything runs."""
    from beo_bench.backend import check_privileged, get_backend, load_plugins
    from beo_bench.bench.leaderboard import regenerate
    from beo_bench.bench.runner import RunConfig, WorkerPool, item_timeout_s, run
    from beo_bench.bench.suites import backend_tracks, get_suite

    load_plugins()
    suites = [get_suite(s).with_overrides(size=n, seed=c.seed) for s, n in c.suites.items()]
    if c.dataset is not None:
        suites = [s.with_dataset(c.dataset, c.split) for s in suites]
    for suite in suites:
        item_timeout_s(suite, c.item_timeout)  # a bad value fails here, before any run
    # build each backend here: a bad option fails with its message, not in a worker
    built = [get_backend(n, **kw) for n, kw in c.backends]
    for (n, _), b in zip(c.backends, built, strict=True):
        check_privileged(n, b, c.allow_privileged)  # before any run starts
    hints = [
        (bool(getattr(b, "wants_class_hint", False)), bool(getattr(b, "needs_class_hint", False)))
        for b in built
    ]
    # one set of worker processes for every run (see WorkerPool: start-up once, not per run)
    with WorkerPool(c.workers) as pool:
        for suite in suites:
            for (name, kwargs), hint in zip(c.backends, hints, strict=True):
                for track in backend_tracks(suite, *hint):
                    tracked = suite.with_overrides(track=track)
                    out = c.runs / run_name(suite.name, name, kwargs, c.seed, track)
                    run(
                        RunConfig(tracked, name, kwargs, c.allow_privileged),
                        out,
                        resume=True,
                        use_ray=c.use_ray,
                        progress=c.progress,
                        pool=pool,
                        item_timeout=c.item_timeout,
                    )
    return regenerate(c.runs, c.leaderboards)
