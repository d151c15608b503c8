"""Pick items: a BEOPick-v0 episode decided from the backend's estimates of every visible
object and executed in simulation (the ``pick`` suite)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench import metrics
from beo_bench.bench.kinds.common import Announce, ItemKind, Rows
from beo_bench.bench.kinds.tabletop import SceneItems, categories, view_label
from beo_bench.bench.scoring import estimate_mesh, obstacle_points
from beo_bench.bench.suites import Kind, Suite
from beo_bench.bench.tally import Tally, flags

if TYPE_CHECKING:
    from beo_bench.bench.evaluate import Evaluator


class PickItems(SceneItems):
    """The suite's episodes: the scenes of :class:`SceneItems`, one row per episode."""

    def pick_row(self, index: int, obs: dict[str, Any], n_views: int) -> dict[str, Any]:
        """The row of episode ``index`` as far as it is known without the backend (the
        asked class is the task, not a secret)."""
        target = int(obs["target_class"])
        return {
            "item": index,
            "view": 0,
            "category": self.env.categories[target],
            "true_class": target,
            "views": n_views,
        }

    def templates(self, index: int) -> Rows:
        obs = self.reset(index)
        return [self.pick_row(index, obs, len(self.scene_views(obs)))]


def run_item(ev: Evaluator, index: int, announce: Announce) -> Rows:
    """One episode: the target is the object with the highest probability of the asked
    class; the grasp is planned on its estimated surface (``Estimate.mesh``, else marching
    cubes on ``shape``) placed by its estimated pose and size, with the other objects'
    estimated surfaces as obstacles (their observed points where the backend failed); the
    env executes the best grasp once."""
    from beo_bench.grasping import plan_grasps

    items = ev.items
    assert isinstance(items, PickItems)
    env = items.env
    obs = items.reset(index)
    target = int(obs["target_class"])
    views = items.scene_views(obs)
    row = items.pick_row(index, obs, len(views))
    announce([dict(row)])
    row["failure"] = None
    estimates, total, failures = [], 0.0, []
    for j, v in enumerate(views):
        est, seconds, failure = ev.predict(index, j, v)
        estimates.append(est)
        total += seconds
        if failure:
            failures.append(failure)
    row["ms"] = 1000 * total / max(len(views), 1)  # per view, as in the other suites
    row["ms_decision"] = 1000 * total  # every view of the scene: one pick decision
    scores = [-1.0 if e is None else float(e.class_probs[target]) for e in estimates]
    if not views or max(scores) < 0:
        row.update(success=False, reason="no_estimate", failure=failures[0] if failures else None)
        return [row]
    k = int(np.argmax(scores))  # ties: the first, in label order
    best, chosen = estimates[k], views[k]
    assert best is not None
    label = view_label(chosen)
    row["chosen_label"] = label
    row["chosen_is_target"] = label == env.target_label
    row["chosen_category"] = items.scene_truths([chosen])[0].category
    cam_to_world = np.asarray(obs["cam_to_world"], dtype=np.float64)
    mesh = estimate_mesh(best, cam_to_world)
    if mesh is None:
        row.update(success=False, reason="empty_shape")
        return [row]
    obstacles = [
        obstacle_points(e, v, cam_to_world)
        for j, (e, v) in enumerate(zip(estimates, views, strict=True))
        if j != k
    ]
    grasps = plan_grasps(
        mesh, env.table.table_height, np.concatenate(obstacles) if obstacles else None
    )
    if not grasps:
        row.update(success=False, reason="no_grasp")
        return [row]
    _, reward, _, _, info = env.step(grasps[0].action)
    row.update(success=bool(reward > 0), reason=str(info["reason"]))
    return [row]


def failed_rows(templates: Rows, reason: str) -> Rows:
    """The row of an episode whose backend never answered: unsuccessful, its ``reason``
    ``timeout`` or ``worker_died``. No time is recorded."""
    why = "timeout" if reason.startswith("timeout") else "worker_died"
    rows = [{**t, "failure": reason, "success": False, "reason": why} for t in templates]
    if rows:
        rows[0]["item_rows"] = len(rows)
    return rows


def view_values(suite: Suite, rows: Rows) -> dict[str, np.ndarray]:
    """Per episode: failed, picked, and whether the chosen object was the target (an
    episode that chose nothing did not find it)."""
    return {
        "failure_rate": flags(rows, "failure", 0.0),
        "pick_success": flags(rows, "success", 0.0),
        "target_found_rate": flags(rows, "chosen_is_target", 0.0),
    }


def collect(M: Tally, rows: Rows, values: dict[str, np.ndarray]) -> None:
    """The failure reasons' counts."""
    s = metrics.pick_summary(
        [bool(r.get("success")) for r in rows], [r.get("reason") for r in rows]
    )
    M.m["pick_failure_reasons"] = dict(sorted(s["failure_reasons"].items()))


def timing(M: Tally, rows: Rows) -> None:
    """The time of one pick decision (every view of the scene)."""
    ms = [np.nan if r.get("ms_decision") is None else float(r["ms_decision"]) for r in rows]
    M.median("ms_per_decision_median", np.array(ms))


def worst_cases(suite: Suite) -> dict[str, float]:
    """Nothing is capped: an episode succeeds or not."""
    return {}


def primary_metric(suite: Suite) -> str:
    """Pick success: what the suite is for."""
    return "pick_success"


PICK = ItemKind(
    Kind.PICK,
    categories,
    PickItems,
    run_item=run_item,
    failed_rows=failed_rows,
    view_values=view_values,
    collect=collect,
    timing=timing,
    worst_cases=worst_cases,
    primary_metric=primary_metric,
)
"""Pick items: one episode per item, decided from every visible object's estimate."""
