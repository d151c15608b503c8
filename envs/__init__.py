"""Gymnasium environments (``beo_bench.envs``); ``import beo_bench`` registers them.

Registration only records entry-point strings, so importing the package stays light: MuJoCo
and the GL platform load when an env is first made. ``gym.make("beo_bench:BEOPick-v0")``
imports ``beo_bench`` itself (gymnasium imports the part before the colon), so it works
without an ``import beo_bench`` of one's own.
"""

from __future__ import annotations

import gymnasium as gym

ENV_IDS = ("BEOPick-v0",)


def register_envs() -> None:
    """Register every env id with gymnasium (idempotent)."""
    if "BEOPick-v0" not in gym.registry:
        gym.register(
            id="BEOPick-v0",
            entry_point="beo_bench.envs.pick:make_pick_env",
            # one grasp per episode: gymnasium's TimeLimit is the episode's only length
            max_episode_steps=1,
        )


__all__ = ["ENV_IDS", "register_envs"]
