"""Gymnasium environments (``beo_bench.envs``); ``import beo_bench`` registers them.

Registration only records entry-point strings, so importing the package stays light: MuJoCo
and the GL platform load when an env is first made. ``gym.make("beo_bench:BEOPick-v0")``
imports ``beo_bench`` itself (gymnasium imports the part before the colon), so it works
without an ``import beo_bench`` of one's own.
"""

from __future__ import annotations

import gymnasium as gym
from gymnasium.envs.registration import WrapperSpec

ENV_IDS = ("BEOPick-v0",)


class RegisteredSteps(int):
    """The registered ``max_episode_steps`` of BEOPick-v0: an ``int`` that gymnasium's
    ``TimeLimit`` takes as it is, and whose type tells
    :func:`beo_bench.envs.pick.follow_time_limit` that the limit is the registry's default
    rather than a caller's ``max_episode_steps=`` (which ``gym.make`` does not pass on)."""

    def __repr__(self) -> str:
        return int.__repr__(self)


def register_envs() -> None:
    """Register every env id with gymnasium (idempotent)."""
    if "BEOPick-v0" not in gym.registry:
        gym.register(
            id="BEOPick-v0",
            entry_point="beo_bench.envs.pick:make_pick_env",
            # one grasp per episode; max_attempts and this limit follow each other
            max_episode_steps=RegisteredSteps(1),
            additional_wrappers=(
                WrapperSpec(
                    name="FollowTimeLimit",
                    entry_point="beo_bench.envs.pick:follow_time_limit",
                    kwargs={},
                ),
            ),
        )


__all__ = ["ENV_IDS", "RegisteredSteps", "register_envs"]
