"""Shared fixtures of the object-library tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from beo_bench.objects.datasets import ROOT_ENV


@pytest.fixture
def isolated_loaders(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Cache in tmp_path, no dataset roots from the user's environment (a process keeps
    none of its own: keys resolve given their dataset)."""
    monkeypatch.setenv("BEO_BENCH_CACHE", str(tmp_path / "cache"))
    for var in ROOT_ENV.values():
        monkeypatch.delenv(var, raising=False)
