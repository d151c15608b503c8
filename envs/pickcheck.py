"""The grasp pipeline's ceiling: BEOPick-v0 episodes grasped with the ground-truth planner.

Each episode resets the env with its own seed, plans grasps of the target from its true
mesh and pose (other objects' true surfaces as obstacles) and executes the best one. The
rate is what a perfect perception backend could reach with this planner and gripper, and
it is the number the ``pick`` suite's oracle row should show. ``beo-bench pick-check``
prints it per category.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
from tqdm import tqdm

if TYPE_CHECKING:
    from beo_bench.envs.pick import BEOPickEnv


@dataclass(frozen=True)
class PickEpisode:
    """One episode: its seed, the target's category and key, and what happened."""

    seed: int
    category: str
    key: str
    num_objects: int
    success: bool
    reason: str  # the env's info["reason"], or "no_grasp" when the planner found none


@dataclass
class PickCheck:
    """All episodes of a run, with per-category summaries."""

    episodes: list[PickEpisode] = field(default_factory=list)

    @property
    def success_rate(self) -> float:
        return sum(e.success for e in self.episodes) / max(len(self.episodes), 1)

    def per_category(self) -> dict[str, tuple[int, int]]:
        """category -> (successes, episodes), sorted by name."""
        out: dict[str, list[int]] = {}
        for e in self.episodes:
            s = out.setdefault(e.category, [0, 0])
            s[0] += int(e.success)
            s[1] += 1
        return {c: (s[0], s[1]) for c, s in sorted(out.items())}

    def failure_reasons(self) -> Counter[str]:
        return Counter(e.reason for e in self.episodes if not e.success)

    def table(self) -> str:
        """A Markdown table: per category, episodes, successes and rate; then the total."""
        lines = ["| category | episodes | lifted | success |", "|---|---:|---:|---:|"]
        for c, (k, n) in self.per_category().items():
            lines.append(f"| {c} | {n} | {k} | {100 * k / n:.0f}% |")
        n = len(self.episodes)
        k = sum(e.success for e in self.episodes)
        lines.append(f"| **all** | {n} | {k} | **{100 * self.success_rate:.0f}%** |")
        return "\n".join(lines)


def ground_truth_pick_check(
    episodes: int = 100,
    seed: int = 0,
    progress: bool = False,
    reset_options: dict[str, Any] | None = None,
    **env_kwargs: Any,
) -> PickCheck:
    """Run ``episodes`` episodes with seeds ``seed, seed + 1, ...`` (deterministic);
    ``reset_options``: every reset's options (``{"target_class": c}``: the ``pick``
    suite's episodes ask for their target classes)."""
    env_kwargs.setdefault("split", "test")
    env = gym.make("BEOPick-v0", **env_kwargs)
    u = cast("BEOPickEnv", env.unwrapped)
    result = PickCheck()
    try:
        for s in tqdm(
            range(seed, seed + episodes), desc="pick-check", disable=None if progress else True
        ):
            _, info = env.reset(seed=s, options=reset_options)
            assert u.scene is not None  # reset built it
            target = u.scene.instances[u.target_label - 1]
            grasps = u.ground_truth_grasps()
            if grasps:
                _, _, _, _, step_info = env.step(grasps[0].action)
                success, reason = bool(step_info["success"]), str(step_info["reason"])
            else:
                success, reason = False, "no_grasp"
            result.episodes.append(
                PickEpisode(s, target.category, target.key, info["num_objects"], success, reason)
            )
    finally:
        env.close()
    return result
