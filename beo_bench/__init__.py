"""beo-bench: a simulation-backed benchmark for object-centric robot perception."""

from __future__ import annotations

__version__ = "0.1.0"
