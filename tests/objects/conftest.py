"""Shared fixtures of the object-library tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from beo_bench.objects import loaders


@pytest.fixture
def isolated_loaders(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Cache in tmp_path, no dataset roots from the user's environment or earlier tests."""
    monkeypatch.setenv("BEO_BENCH_CACHE", str(tmp_path / "cache"))
    for var in loaders.ROOT_ENV.values():
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setattr(loaders, "_ROOTS", {})
