"""Many runs at once: every (suite, backend) pair, then the leaderboard (``beo-bench all``,
and ``make demo`` on short suites).

Each pair runs into ``RUNS/<suite>[@<track>][~<sensor>]__<backend>[__<options>]`` (the
sensor when it is not the suite's own: ``Campaign.sensors``) and resumes what is
already there, so a killed campaign continues where it stopped and a finished one costs
nothing to re-run; the leaderboard is then regenerated from every summary under ``RUNS``.
On a suite with tracks (``Suite.class_hint``) a backend that can use the class hint is run
in both tracks, ``class-given`` and ``class-free``, and any other backend in ``class-free``
only (see :func:`~beo_bench.bench.suites.backend_tracks`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from beo_bench.bench.runs import (
    RunConfig,
    RunContext,
    backend_label,
    options_label,
    parse_backend_spec,
    parse_option_pairs,
    run_name,
)

__all__ = [
    "Campaign",
    "backend_label",
    "options_label",
    "parse_backend_spec",
    "parse_option_pairs",
    "run_campaign",
    "run_name",
]

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset


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
    update: bool = False
    """``--update``: keep the current pages of suites this campaign does not run
    (:func:`~beo_bench.bench.pages.leaderboard.regenerate`)."""
    sensors: tuple[str | None, ...] = (None,)
    """``--sensor``: every suite is run under each of these depth sensors (None: the
    suite's own); the leaderboard pairs a backend's runs across them (its robustness
    table)."""
    max_failure_rate: float | None = None
    """``--max-failure-rate``: after every run and the leaderboard are written, a
    :class:`~beo_bench.bench.gate.spec.FailureRateError` (exit status 3) names each run whose
    share of failed views is above it (None: no limit)."""
    report_views: int = 0
    """``--report-views``: each run's ``report.html`` shows that many worst views (0: no
    report)."""
    force_rerun: bool = False
    """``--force-rerun``: a run whose results a plugin scored with other code or options
    (its code digest) is discarded and run again, rather than refused."""
    after_run: Callable[[RunContext, Path], None] | None = None
    """Called with each run's context and directory when it ends (the CLI prints its
    failures there, so each run of a campaign ends with them as a lone run does)."""


def run_campaign(c: Campaign) -> list[Path]:
    """Run every pair (resuming) in each of its tracks, then regenerate the leaderboard;
    returns its Markdown files. A backend whose construction fails stops the campaign before
    anything runs."""
    from beo_bench.backend import get_spec, load_plugins
    from beo_bench.bench.pages.leaderboard import regenerate
    from beo_bench.bench.runner import WorkerPool, item_timeout_s, run
    from beo_bench.bench.suites import backend_tracks, get_suite

    suites = [get_suite(s).with_overrides(size=n, seed=c.seed) for s, n in c.suites.items()]
    if c.dataset is not None:
        suites = [s.with_dataset(c.dataset, c.split) for s in suites]
    # each suite under each sensor (one suite under its own and under the same one named
    # is one run, not two)
    suites = list(
        {s.with_sensor(x).label: s.with_sensor(x) for s in suites for x in c.sensors}.values()
    )
    for suite in suites:
        item_timeout_s(suite, c.item_timeout)  # a bad value fails here, before any run
    # every run's context, resolved before any run starts: a bad option, a privileged plugin
    # without leave, or a track a backend cannot run in fails with its message here
    load_plugins()
    contexts = []
    for suite in suites:
        for name, kwargs in c.backends:
            spec = get_spec(name)
            caps = spec.capabilities_of(spec.parse(kwargs))  # the tracks it runs in
            for track in backend_tracks(suite, caps.wants_class_hint, caps.needs_class_hint):
                tracked = suite.with_overrides(track=track)
                cfg = RunConfig(tracked, name, kwargs, c.allow_privileged)
                out = c.runs / run_name(suite.name, name, kwargs, c.seed, track, suite.sensor_tag)
                contexts.append((RunContext.of(cfg, progress=c.progress), out))
    # every model and dataset the runs need, looked up before the first run starts: a
    # missing one fails now, all of them named at once, not after hours of other runs
    check_prepared(contexts, c.force_rerun)
    # one set of worker processes for every run (see WorkerPool: start-up once, not per run)
    finished = []
    with WorkerPool(c.workers) as pool:
        for ctx, out in contexts:
            summary = run(
                ctx,
                out,
                resume=True,
                use_ray=c.use_ray,
                progress=c.progress,
                pool=pool,
                item_timeout=c.item_timeout,
                report_views=c.report_views,
                force_rerun=c.force_rerun,
            )
            finished.append((out, summary))
            if c.after_run is not None:
                c.after_run(ctx, out)
    written = regenerate(c.runs, c.leaderboards, update=c.update)
    if c.max_failure_rate is not None:
        from beo_bench.bench.gate.check import check_failure_rate

        # every run finished first: one broken suite does not hide how the others did
        check_failure_rate(finished, c.max_failure_rate)
    return written


def _work_left(ctx: RunContext, out: Path) -> bool:
    """Whether the run in ``out`` has items left to score (a run that finished is resumed
    without preparing its backend, so nothing of it is checked)."""
    from beo_bench.bench.rows import scan_rows
    from beo_bench.bench.rundir import RESULTS_NAME

    done = {r.item for r in scan_rows(out / RESULTS_NAME).rows}
    return any(i not in done for i in range(ctx.suite.size))


def check_prepared(contexts: list[tuple[RunContext, Path]], force_rerun: bool = False) -> None:
    """Prepare each backend that loads a trained model (``Capabilities.model``) once for
    each set of runs that prepare it alike (its options, the class list, the dataset, the
    suite's frame) among those with work left (every run with ``force_rerun``), as its runs
    will: a model, a trained default or a dataset's model that is missing or unusable
    raises one :class:`~beo_bench.errors.CheckpointError` naming every such backend and
    suite with the command that fixes it, before any run starts. A default model trained on
    first use is trained here, in the cache, where the runs then find it."""
    from beo_bench.backend import get_spec
    from beo_bench.errors import CheckpointError, TrainingInRunError, UserDataError

    seen: set[tuple[Any, ...]] = set()
    problems: list[str] = []
    for ctx, out in contexts:
        key = (
            ctx.backend.name,
            repr(sorted(ctx.backend.kwargs.items())),
            ctx.categories,
            None if ctx.dataset is None else ctx.dataset.root,
            ctx.suite.protocol.world_frame,
        )
        if ctx.backend.capabilities.model is None:
            continue  # no trained model to miss (nothing but caches is built in prepare)
        if key in seen or not (force_rerun or _work_left(ctx, out)):
            continue
        seen.add(key)
        backend = get_spec(ctx.backend.name).make(ctx.backend.options)
        try:
            backend.prepare(ctx)
        except (CheckpointError, TrainingInRunError, UserDataError) as e:
            who = backend_label(ctx.backend.name, ctx.backend.kwargs)
            problems.append(f"({len(problems) + 1}) {who} on {ctx.suite.label}: {e}")
    if problems:
        raise CheckpointError(
            f"nothing was run: {len(problems)} of the runs cannot start, each with what it "
            "misses and the command that makes it: " + "; ".join(problems)
        )


# -- what a campaign costs (``make bench``'s campaign figure) ---------------------------------
@dataclass(frozen=True)
class RowCost:
    """One committed leaderboard row's predict time: its items times its median time per
    unit (a view; a pick episode's decision), in CPU-seconds."""

    suite: str
    backend: str
    track: str | None
    sensor: str | None
    n: int
    ms_per_unit: float
    unit: str
    """``view`` or ``decision`` (a pick episode's: its views and its grasp choice)."""

    @property
    def cpu_s(self) -> float:
        return self.n * self.ms_per_unit / 1000.0


@dataclass(frozen=True)
class CampaignCost:
    """The predict CPU time of a set of leaderboard rows, the runs a campaign makes.

    Only predict time is recorded in a row (``ms_per_view_median``,
    ``ms_per_decision_median``): a run's rendering, scoring and physics are not, so these
    are the backends' share of a campaign, and ``n * median`` is an estimate of it (the mean
    of a skewed time is above its median)."""

    rows: tuple[RowCost, ...]

    @property
    def cpu_hours(self) -> float:
        return sum(r.cpu_s for r in self.rows) / 3600.0

    def wall_hours(self, cores: int = 2) -> float:
        """Its wall time with one worker per core (each run's items spread over them)."""
        return self.cpu_hours / cores

    def hours_by(self) -> dict[tuple[str, str], float]:
        """(suite, backend) -> CPU-hours, summed over tracks and sensors."""
        out: dict[tuple[str, str], float] = {}
        for r in self.rows:
            out[(r.suite, r.backend)] = out.get((r.suite, r.backend), 0.0) + r.cpu_s / 3600.0
        return out

    def projected(self, speedups: dict[str, float]) -> CampaignCost:
        """The same rows with each named backend's times divided by its speed-up (a
        measured ratio of old to new time per view): a projection, not a run."""
        return CampaignCost(
            tuple(
                RowCost(
                    r.suite,
                    r.backend,
                    r.track,
                    r.sensor,
                    r.n,
                    r.ms_per_unit / speedups.get(r.backend, 1.0),
                    r.unit,
                )
                for r in self.rows
            )
        )

    def text(self, cores: int = 2) -> str:
        """CPU-hours by suite (rows) and backend (columns), the totals, the wall time."""
        cells = self.hours_by()
        suites = sorted({s for s, _ in cells})
        backends = sorted({b for _, b in cells})
        w0 = max(len(s) for s in [*suites, "suite", "all"])
        widths = [max(len(b), 6) for b in backends]
        head = f"{'suite':<{w0}} " + " ".join(
            f"{b:>{w}}" for b, w in zip(backends, widths, strict=True)
        )
        lines = [head + f" {'all':>7}"]
        for s in suites:
            row = [cells.get((s, b), 0.0) for b in backends]
            lines.append(
                f"{s:<{w0}} "
                + " ".join(f"{v:>{w}.2f}" for v, w in zip(row, widths, strict=True))
                + f" {sum(row):>7.2f}"
            )
        per_b = [sum(cells.get((s, b), 0.0) for s in suites) for b in backends]
        lines.append(
            f"{'all':<{w0}} "
            + " ".join(f"{v:>{w}.2f}" for v, w in zip(per_b, widths, strict=True))
            + f" {self.cpu_hours:>7.2f}"
        )
        lines.append(
            f"{len(self.rows)} runs: {self.cpu_hours:.2f} CPU-hours of predict time (items x "
            f"median ms per view or pick decision), {self.wall_hours(cores):.2f} h of wall "
            f"time on {cores} cores; rendering, scoring and physics are not recorded in a row"
        )
        return "\n".join(lines)


def campaign_cost(leaderboards: Path = Path("leaderboards")) -> CampaignCost:
    """The predict time of every run on the leaderboard pages under ``leaderboards`` (its
    ``<suite>.json`` files and ``ablations/``'s; each run once, though pages may share it)."""
    import json

    seen: set[tuple[Any, ...]] = set()
    rows = []
    pages = sorted(leaderboards.glob("*.json")) + sorted(leaderboards.glob("ablations/*.json"))
    for page in pages:
        if page.name.endswith("_paired.json"):
            continue
        for r in json.loads(page.read_text()):
            prov = r.get("provenance", {})
            key = (
                r["suite"],
                r.get("track"),
                r.get("sensor"),
                r["backend"],
                r.get("seed"),
                r["n"],
                json.dumps(prov.get("backend_kwargs"), sort_keys=True),
            )
            if key in seen:
                continue
            seen.add(key)
            m = r["metrics"]
            unit = "decision" if m.get("ms_per_decision_median") is not None else "view"
            ms = m.get(f"ms_per_{unit}_median")
            if ms is None or ms != ms:  # no timed view (every item failed): no time known
                continue
            rows.append(
                RowCost(
                    r["suite"],
                    r["backend"],
                    r.get("track"),
                    r.get("sensor"),
                    int(r["n"]),
                    float(ms),
                    unit,
                )
            )
    return CampaignCost(tuple(rows))
