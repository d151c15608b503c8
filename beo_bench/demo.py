"""``beo-bench demo``: the main job on the embedded defaults, from library functions.

The object library (test split), one BEOPick-v0 scene that the ground-truth planner picks,
the planner's pick rate, every suite shortened with every registered backend and the
leaderboard, then the asset cache. Re-running resumes the finished runs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from beo_bench import inspection
from beo_bench.bench import campaign
from beo_bench.bench.runner import default_workers
from beo_bench.envs import pickcheck
from beo_bench.errors import BeoBenchError
from beo_bench.sceneview import view_scene

DEMO_SIZES = {
    "known-pose": 36,
    "pose-1dof": 36,
    "pose-3dof": 36,
    "modelnet10-3dof": 20,
    "tabletop": 6,
    "pick": 10,
}
"""Items per suite in ``make demo``: a multiple of the suite's classes for isolated suites
(the library's 18, ModelNet10's 10), so every class is seen as often."""
DEMO_SPLIT = "test"
DEMO_PICK_EPISODES = 20
"""Episodes of the demo's ground-truth pick check (seeds 0..19)."""
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


def run_demo(
    out: Path | str = "out/demo",
    per_category: int = 20,
    workers: int | None = None,
    say: Callable[[str], None] = print,
) -> None:
    """Everything ``beo-bench demo`` does, printing through ``say``; files go to ``out``
    (``objects.png``, ``scene_SEED.png``/``.rrd``, ``runs/``, ``leaderboards/``)."""
    out = Path(out)
    workers = workers or default_workers()
    say(f"beo-bench demo: the object library ({DEMO_SPLIT} split)\n")
    objects, counts = inspection.select_objects(DEMO_SPLIT, per_category=per_category)
    say(
        inspection.summarise_objects(
            objects, DEMO_SPLIT, workers=workers, sheet=out / "objects.png", split_counts=counts
        ).text()
    )

    # The picture should show what the benchmark is about: a target the planner grasps and
    # lifts. Seed 0's target may have no ground-truth grasp at all, so the demo takes the
    # first seed that the pick check counts as a success, and says which and why.
    chosen = picked_seed(DEMO_SPLIT)
    passed = "; ".join(f"seed {s}: {why}" for s, why in chosen.skipped)
    say(
        f"\nbeo-bench demo: one BEOPick-v0 scene, seed {chosen.seed}: the first seed whose "
        f"target ({chosen.target}) the ground-truth planner grasps and lifts"
        + (f" (passed over {passed})" if passed else "")
        + "\n"
    )
    say(view_scene(chosen.seed, out, split=DEMO_SPLIT).text())

    say(f"\nbeo-bench demo: the ground-truth grasp ceiling on {DEMO_PICK_EPISODES} episodes\n")
    say(inspection.pick_check(DEMO_PICK_EPISODES, 0, DEMO_SPLIT).text())

    demo_suites(out, workers, say)
    say(inspection.cache_report().text())


def demo_suites(out: Path, workers: int | None, say: Callable[[str], None] = print) -> list[Path]:
    """Every suite, shortened (:data:`DEMO_SIZES`), with every registered backend; then the
    leaderboard. Re-running resumes the finished runs (nothing is recomputed)."""
    backends = inspection.every_backend()
    say(f"\nbeo-bench demo: short suites with {', '.join(backends)}\n")
    c = campaign.Campaign(
        dict(DEMO_SIZES),
        [(b, {}) for b in backends],
        runs=out / "runs",
        leaderboards=out / "leaderboards",
        workers=workers,
    )
    written = campaign.run_campaign(c)
    say(inspection.leaderboard_text(written, c.leaderboards))
    return written
