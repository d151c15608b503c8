"""Gymnasium environments (``beo_bench.envs``); ``import beo_bench`` registers them.

Registration only records entry-point strings, so importing the package stays light: MuJoCo
and the GL platform load when an env is first made.
"""

from __future__ import annotations

import gymnasium as gym

ENV_IDS = ("BEOPick-v0",)


def register_envs() -> None:
    """Register every env id with gymnasium (idempotent)."""
    if "BEOPick-v0" not in gym.registry:
        gym.register(id="BEOPick-v0", entry_point="beo_bench.envs.pick:BEOPickEnv")


__all__ = ["ENV_IDS", "register_envs"]
