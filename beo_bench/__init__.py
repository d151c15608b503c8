"""beo-bench: a simulation-backed benchmark for object-centric robot perception.

``import beo_bench`` registers the gymnasium ids (``gym.make("BEOPick-v0")``); gymnasium
1.4 has no plugin entry point, so the import is what makes them known. Without it,
``gym.make("beo_bench:BEOPick-v0")`` imports this package itself (docs/env.md).
"""

from __future__ import annotations

__version__ = "0.1.0"

from beo_bench.envs import register_envs

register_envs()
