"""What a run is: its configuration, its context, its name, its errors.

A user asks for a run with a :class:`RunConfig` (suite, backend name, options as given,
``--allow-privileged``). The driver resolves it once into a :class:`RunContext`: the suite
and its item kind, the dataset, the backend's spec reference with its parsed options and
capabilities, the class list the views carry, whether the class hint is given and whether
the backend is handed the truth, and the asset cache it keeps derived data in (read from
``$BEO_BENCH_CACHE`` here, once). The context is frozen and picklable; it is the only thing
that workers, the evaluator and ``Backend.prepare(ctx)`` receive (no per-process state
carries a run's configuration, its cache root included).

A run directory's default name is :func:`run_name`; its files, identity, lock, rows and
summary are :mod:`beo_bench.bench.rundir`'s.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from beo_bench.backend import Capabilities, check_privileged, get_spec, load_plugins
from beo_bench.bench.suites import Suite, check_track
from beo_bench.errors import BeoBenchError, CorruptDataError, UsageError
from beo_bench.objects import cache

if TYPE_CHECKING:
    from beo_bench.backend import Backend, BackendSpec
    from beo_bench.objects.datasets import Dataset


class RunError(BeoBenchError, ValueError):
    """A run that cannot start, resume or go on as asked."""


class RunUsageError(RunError, UsageError):
    """A run asked for in a way that cannot work (``--out`` is a file, results there need
    ``--resume``, they belong to another run or model); exit status 2."""


class CorruptRunError(RunError, CorruptDataError):
    """A run directory's ``run.json`` or ``results.jsonl`` that is damaged beyond skipping a
    line: nothing is overwritten, the message says what to do."""


REPORT_VIEWS = 8
"""The worst views a run's report shows unless ``--report-views`` says otherwise."""


# -- names -----------------------------------------------------------------------------------
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
    sensor: str | None = None,
) -> str:
    """The run directory's name: ``known-pose__icp``, ``pose-3dof@class-given__icp``,
    ``pose-3dof@class-free__icp__starts=48``, or with a replaced base seed
    ``pose-3dof@class-free__icp__suite_seed=7`` (the track is part of what identifies a
    run, so two tracks never share a directory). ``sensor``: a sensor other than the
    suite's own (``Suite.sensor_tag``), which follows the suite and track as in
    ``Suite.label``: ``pose-3dof@class-free~d435__icp``, ``tabletop~ideal__icp``; None
    (the suite's own sensor) keeps the name as it always was."""
    opts = dict(sorted(kwargs.items()))
    if seed is not None:
        opts["suite_seed"] = seed
    slug = "_".join(f"{k}={v}" for k, v in opts.items())
    safe = "".join(ch if ch.isalnum() or ch in "=.-_" else "-" for ch in slug)
    where = f"{suite}@{track}" if track else suite
    if sensor:
        where += f"~{sensor}"
    return f"{where}__{backend}" + (f"__{safe}" if safe else "")


def parse_option_pairs(pairs: list[str]) -> dict[str, Any]:
    """``["samples=25", "point_to_plane=false"]`` -> ``{"samples": 25, "point_to_plane":
    False}`` (values are JSON when they parse, else strings; the backend's options dataclass
    then converts them by type)."""
    out: dict[str, Any] = {}
    for pair in pairs:
        if "=" not in pair:
            raise UsageError(f"option {pair!r}: use KEY=VALUE (e.g. samples=25)")
        k, v = pair.split("=", 1)
        try:
            out[k] = json.loads(v)
        except json.JSONDecodeError:
            out[k] = v  # a plain string
        if isinstance(out[k], float) and not math.isfinite(out[k]):
            # NaN never equals itself: a run's context would never match its own copy
            raise UsageError(f"option {pair!r}: give a finite number")
    return out


def parse_backend_spec(spec: str) -> tuple[str, dict[str, Any]]:
    """``"icp"`` or ``"hbeo-mdn-posterior:samples=25,seed=1"`` -> (name, options)."""
    name, _, opts = spec.partition(":")
    return name, parse_option_pairs([o for o in opts.split(",") if o])


# -- configuration and context ---------------------------------------------------------------
@dataclass(frozen=True)
class RunConfig:
    """What a user asks for: everything that determines a run's results (recorded in its
    summary)."""

    suite: Suite
    backend: str
    backend_kwargs: dict[str, Any] = field(default_factory=dict)
    """The options as given (``--opt``): they name the run and identify it on resume."""
    allow_privileged: bool = False
    """Let a plugin that declares ``privileged`` be handed the truth (``--allow-privileged``);
    in-tree bounds need no leave. Whether the backend *was* privileged is recorded in the run
    record, summary and provenance."""


@dataclass(frozen=True)
class BackendRef:
    """A backend as a run uses it: its registered name, the options as given and as parsed
    into its options dataclass, and its capabilities at those options. Picklable: a worker
    finds the spec again by name (:meth:`spec`)."""

    name: str
    kwargs: dict[str, Any]
    options: Any
    capabilities: Capabilities

    def spec(self) -> BackendSpec:
        return get_spec(self.name)

    def build(self) -> Backend:
        """A new backend with these options (one per process)."""
        return self.spec().make(self.options)


@dataclass(frozen=True)
class RunContext:
    """One run, resolved once by the driver (:meth:`of`) and handed to workers, the
    evaluator and ``Backend.prepare``. The track, seed and sensor settings are the suite's
    (:attr:`track`, :attr:`seed`, ``suite.sensor``, ``suite.image_size``, ``suite.fovy_deg``)."""

    suite: Suite
    backend: BackendRef
    categories: tuple[str, ...]
    """The class list the views carry (``View.categories``)."""
    cache_root: Path = field(default_factory=cache.cache_root)
    """The asset cache the run's objects, scenes and models are kept in (resolved from the
    environment when the context is made: a worker is handed it, never reads its own)."""
    privileged: bool = False
    """The backend is handed each view's ground truth (a bound)."""
    class_given: bool = False
    """Views carry the true class (the ``class-given`` track, a backend that can use it)."""
    allow_privileged: bool = False
    progress: bool = False
    """Whether ``prepare`` may show progress bars (the driver's; workers get False)."""

    @property
    def dataset(self) -> Dataset | None:
        """The user's dataset the objects come from (None: the procedural library)."""
        return self.suite.dataset

    @property
    def track(self) -> str | None:
        return self.suite.track

    @property
    def seed(self) -> int:
        return self.suite.seed

    @property
    def sensor(self) -> str:
        """The depth sensor the views are captured by (``Suite.sensor``)."""
        return self.suite.sensor

    @property
    def config(self) -> RunConfig:
        """The configuration this context was resolved from."""
        return RunConfig(self.suite, self.backend.name, self.backend.kwargs, self.allow_privileged)

    @classmethod
    def of(
        cls, cfg: RunConfig, progress: bool = False, cache_root: Path | None = None
    ) -> RunContext:
        """Resolve ``cfg``: find the backend's spec (plugins loaded), parse its options,
        read its capabilities (without building it), refuse a privileged plugin without
        leave and a track the backend cannot run in, and find the views' class list and the
        asset cache (``cache_root``, default: the environment's, read here). Every refusal
        is a usage error raised here, before any run starts."""
        load_plugins()
        spec = get_spec(cfg.backend)
        options = spec.parse(cfg.backend_kwargs)
        caps = spec.capabilities_of(options)
        privileged = check_privileged(cfg.backend, caps, cfg.allow_privileged)
        check_track(cfg.suite, cfg.backend, caps.wants_class_hint, caps.needs_class_hint)
        return cls(
            suite=cfg.suite,
            backend=BackendRef(cfg.backend, dict(cfg.backend_kwargs), options, caps),
            categories=suite_categories(cfg.suite),
            cache_root=cache.cache_root() if cache_root is None else Path(cache_root),
            privileged=privileged,
            class_given=cfg.suite.gives_class and caps.wants_class_hint,
            allow_privileged=cfg.allow_privileged,
            progress=progress,
        )

    def for_workers(self) -> RunContext:
        """The context workers get (no progress bars)."""
        return dataclasses.replace(self, progress=False)


def suite_categories(suite: Suite) -> tuple[str, ...]:
    """The class list a suite's views carry (``View.categories``)."""
    from beo_bench.bench.kinds import get_kind

    return get_kind(suite.kind).categories(suite)
