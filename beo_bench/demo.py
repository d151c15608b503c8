"""``beo-bench demo``: the main job on the embedded defaults, from library functions.

The object library (test split), one BEOPick-v0 scene that the ground-truth planner picks,
the planner's pick rate, every suite shortened with every registered backend and the
leaderboard, then the asset cache. Re-running resumes the finished runs.

What it prints is short: a line per step and per finished run, then a one-screen headline
(:func:`headline`: every backend's main figure on every suite, and where the full pages
are). The long texts (the library's table, the pick table, the leaderboard's suite tables,
the cache) go to ``OUT/demo.md``.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from beo_bench import inspection
from beo_bench.bench import campaign
from beo_bench.bench.columns import spec
from beo_bench.bench.rundir import SUMMARY_NAME
from beo_bench.bench.runner import default_workers
from beo_bench.envs import pickcheck
from beo_bench.errors import BeoBenchError
from beo_bench.sceneview import view_scene

if TYPE_CHECKING:
    from beo_bench.bench.runs import RunContext

DEMO_SIZES = {
    "known-pose": 18,
    "pose-1dof": 18,
    "pose-3dof": 18,
    "tabletop": 4,
    "pick": 6,
}
"""Items per suite in ``make demo``: every kind of suite (isolated views under each of the
three protocols, tabletop scenes, pick episodes), short. The isolated suites take one view
of each of the library's 18 classes (a multiple of the classes, so every class is seen as
often). No ``modelnet10-*`` suite: on those ten classes ``beo`` needs a BEO model of its own,
fit on first use from 2,000 training instances (about two minutes on 2 cores), and the
published models' 20 MB cap has no room for it (docs/reference-models.md); ``beo-bench
all --suites modelnet10-3dof`` runs it."""
DEMO_SPLIT = "test"
DEMO_PER_CATEGORY = 6
"""Test instances a category that the demo builds, processes and summarises: the contact
sheet's six (the suites draw their own instances, built when a view needs them)."""
DEMO_PICK_EPISODES = 10
"""Episodes of the demo's ground-truth pick check (seeds 0..9)."""
SEED_SEARCH = 100
"""How many seeds :func:`picked_seed` tries before giving up."""


@dataclass(frozen=True)
class PickedSeed:
    """The scene the demo shows: its seed, its target and the seeds passed over."""

    seed: int
    target: str
    skipped: tuple[tuple[int, str], ...]
    """(seed, why) of each earlier seed: ``no_grasp`` or the failed pick's reason."""


def picked_seed(split: str = DEMO_SPLIT, start: int = 0, limit: int = SEED_SEARCH) -> PickedSeed:
    """The first seed from ``start`` whose BEOPick-v0 scene the ground-truth planner picks:
    it finds a grasp of the target and executing its best grasp lifts the target (one
    episode of :func:`beo_bench.envs.pickcheck.ground_truth_pick_check` per seed, so this is
    exactly what ``beo-bench pick-check`` counts as a success; deterministic)."""
    skipped: list[tuple[int, str]] = []
    for seed in range(start, start + limit):
        episode = pickcheck.ground_truth_pick_check(episodes=1, seed=seed, split=split).episodes[0]
        if episode.success:
            return PickedSeed(seed, episode.category, tuple(skipped))
        skipped.append((seed, episode.reason))
    raise BeoBenchError(
        f"no scene of split {split!r} with seeds {start}..{start + limit - 1} was picked by "
        "the ground-truth planner: run `beo-bench pick-check` to see why its grasps fail"
    )


DEMO_REPORT = "demo.md"
"""The demo's long texts, under its output folder: the library's table, the pick table, the
leaderboard's suite tables and the asset cache (the terminal gets :func:`headline`)."""
DEMO_FIGURES: dict[str, str] = {
    "known-pose": "iou_mean",
    "pose-1dof": "rot_err_deg_median",
    "pose-3dof": "rot_err_deg_median",
    "tabletop": "rot_err_deg_median",
    "pick": "pick_success",
}
"""The headline's figure of each demo suite (a ``summary["metrics"]`` key): the shape's
IoU where the pose is given, the median rotation error where it is estimated, the pick
rate of the pick episodes."""
HEADLINE_MAX_LINES = 40
"""The headline fits one screen."""


def run_demo(
    out: Path | str = "out/demo",
    per_category: int = DEMO_PER_CATEGORY,
    workers: int | None = None,
    say: Callable[[str], None] = print,
) -> Path:
    """Everything ``beo-bench demo`` does, printing through ``say`` a line per step and per
    finished run, then :func:`headline`; files go to ``out`` (``objects.png``,
    ``scene_SEED.png``/``.rrd``, ``runs/``, ``leaderboards/`` and :data:`DEMO_REPORT`, whose
    path it returns)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    workers = workers or default_workers()
    report = out / DEMO_REPORT
    say(f"beo-bench demo: files under {out}/, the long tables in {report}")
    long: list[str] = ["# beo-bench demo", ""]

    objects, counts = inspection.select_objects(DEMO_SPLIT, per_category=per_category)
    lib = inspection.summarise_objects(
        objects, DEMO_SPLIT, workers=workers, sheet=out / "objects.png", split_counts=counts
    )
    long += [f"## The object library ({DEMO_SPLIT} split)", "", "```text", lib.text(), "```", ""]
    say(
        f"objects: {len(lib.stats)} {DEMO_SPLIT} instances built and processed in "
        f"{lib.wall_s:.0f} s; contact sheet {lib.sheet}"
    )

    # The picture should show what the benchmark is about: a target the planner grasps and
    # lifts. Seed 0's target may have no ground-truth grasp at all, so the demo takes the
    # first seed that the pick check counts as a success, and says which and why.
    chosen = picked_seed(DEMO_SPLIT)
    passed = "; ".join(f"seed {s}: {why}" for s, why in chosen.skipped)
    scene = view_scene(chosen.seed, out, split=DEMO_SPLIT)
    long += [
        f"## One BEOPick-v0 scene, seed {chosen.seed}",
        "",
        f"The first seed whose target ({chosen.target}) the ground-truth planner grasps and "
        "lifts" + (f" (passed over {passed})" if passed else "") + ".",
        "",
        "```text",
        scene.text(),
        "```",
        "",
    ]
    say(
        f"scene: seed {chosen.seed}, the first whose target ({chosen.target}) the "
        f"ground-truth planner lifts; {scene.png}"
    )

    pick = inspection.pick_check(DEMO_PICK_EPISODES, 0, DEMO_SPLIT)
    long += [f"## The ground-truth grasp ceiling on {DEMO_PICK_EPISODES} episodes", ""]
    long += [pick.text(), ""]
    say(
        f"grasp ceiling: the ground-truth planner lifts {pick.result.success_rate:.0%} of "
        f"{pick.episodes} episodes ({pick.wall_s:.0f} s)"
    )

    written = demo_suites(out, workers, say)
    long += [
        "## The short suites' leaderboard",
        inspection.leaderboard_text(written, out / "leaderboards"),
        "",
    ]
    cache = inspection.cache_report()
    long += ["## The asset cache", "", "```text", cache.text(), "```", ""]
    report.write_text("\n".join(long))
    say(f"cache: {cache.root} ({inspection.format_bytes(cache.bytes)})")
    say(headline(out, inspection.every_backend()))
    return report


def demo_suites(out: Path, workers: int | None, say: Callable[[str], None] = print) -> list[Path]:
    """Every suite, shortened (:data:`DEMO_SIZES`), with every registered backend, a line
    per finished run; then the leaderboard. Re-running resumes the finished runs (nothing
    is recomputed)."""
    backends = inspection.every_backend()
    say(f"suites: {', '.join(DEMO_SIZES)}, each with {', '.join(backends)}")
    last = [time.perf_counter()]

    def finished(ctx: RunContext, run: Path) -> None:
        now = time.perf_counter()
        say(run_line(ctx.suite.label, ctx.backend.name, run, now - last[0]))
        last[0] = now

    c = campaign.Campaign(
        dict(DEMO_SIZES),
        [(b, {}) for b in backends],
        runs=out / "runs",
        leaderboards=out / "leaderboards",
        workers=workers,
        after_run=finished,
    )
    return campaign.run_campaign(c)


def run_line(label: str, backend: str, run: Path, wall_s: float) -> str:
    """One line for a finished run: its views (episodes), failures and main figure (a log reads one
    line per run; the progress bars draw only on a terminal)."""
    summary = json.loads((run / SUMMARY_NAME).read_text())
    key = DEMO_FIGURES.get(summary["suite"], "")
    fig = ""
    if key in summary["metrics"]:
        m = spec(key)
        fig = f", {m.short} {m.format(summary['metrics'][key])}"
    unit = "episodes" if summary["suite"] == "pick" else "views"  # a scene has several
    return (
        f"  {label} / {backend}: {summary['n']} {unit}, {summary['failures']} failed{fig} "
        f"({wall_s:.0f} s)"
    )


def headline(out: Path, backends: list[str]) -> str:
    """The demo's last screen: each backend's main figure (:data:`DEMO_FIGURES`) on each
    suite, read from the leaderboard's JSON under ``out/leaderboards/`` (a suite's
    class-free track, which every backend runs in), then where the full pages are."""
    boards = out / "leaderboards"
    cells: dict[tuple[str, str], str] = {}
    for suite, key in DEMO_FIGURES.items():
        path = boards / f"{suite}.json"
        rows = json.loads(path.read_text()) if path.exists() else []
        for r in sorted(rows, key=lambda r: r.get("track") == "class-given"):
            # the class-free row first (sorted): the one the headline keeps
            if key in r["metrics"]:
                cells.setdefault((suite, r["backend"]), spec(key).format(r["metrics"][key]))
    suites = list(DEMO_FIGURES)
    scenes = sorted(out.glob("scene_*.png"))
    w0 = max(len(b) for b in [*backends, "backend"])
    widths = [max(len(s), 9) for s in suites]
    figs = [
        f"{spec(DEMO_FIGURES[s]).short} {'↑' if spec(DEMO_FIGURES[s]).higher_is_better else '↓'}"
        for s in suites
    ]
    lines = [
        "",
        "beo-bench demo: each backend's main figure on each short suite (rot med: degrees)",
        "items: "
        + ", ".join(f"{s} {DEMO_SIZES[s]}" for s in suites)
        + "; a suite's class-free track (class-given: on its page)",
        "",
        f"{'backend':<{w0}}  "
        + "  ".join(f"{s:>{w}}" for s, w in zip(suites, widths, strict=True)),
        f"{'':<{w0}}  " + "  ".join(f"{f:>{w}}" for f, w in zip(figs, widths, strict=True)),
    ]
    for b in backends:
        lines.append(
            f"{b:<{w0}}  "
            + "  ".join(
                f"{cells.get((s, b), '-'):>{w}}" for s, w in zip(suites, widths, strict=True)
            )
        )
    lines += [
        "",
        f"full pages:  {boards}/<suite>.md (every metric, tracks, intervals, plots)",
        f"long tables: {out / DEMO_REPORT} (object library, grasp ceiling, suite tables, cache)",
        f"images:      {out / 'objects.png'}, "
        + (", ".join(str(p) for p in scenes) or f"{out}/scene_<seed>.png")
        + " (.rrd beside it: `rerun` it)",
        f"runs:        {out / 'runs'}/ (resumed by the next `beo-bench demo`)",
    ]
    return "\n".join(lines)
