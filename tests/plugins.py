"""Installing a third-party backend package for a test: a distribution's metadata with
``beo_bench.backends`` entry points, in a folder put on ``sys.path`` (what ``pip install``
of a plugin leaves behind, as far as ``importlib.metadata`` can tell)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import pytest


def install_plugin(
    site: Path, dist: str, entry_points: Mapping[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Make distribution ``dist`` 0.1 (its modules already written into ``site``) advertise
    ``entry_points`` (backend name -> ``"module:object"``), with ``site`` importable for
    the rest of the test."""
    info = site / f"{dist.replace('-', '_')}-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n")
    lines = "".join(f"{name} = {target}\n" for name, target in entry_points.items())
    (info / "entry_points.txt").write_text(f"[beo_bench.backends]\n{lines}")
    monkeypatch.syspath_prepend(str(site))
