"""Perception backends (``beo_bench.perception``; DESIGN.md "Perception backends").

- :mod:`.bounds`: ``oracle`` (ground truth) and ``random`` (chance);
- :mod:`.means`: per-class mean shapes and sizes from the ``train`` split.

Backends are looked up through :func:`beo_bench.backend.get_backend`.
"""
