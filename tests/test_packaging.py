"""The packaging configuration (pyproject.toml): every folder inside a package is itself a
listed package, so setuptools ships it without its "Package would be ignored" warning (a
folder of data files, such as perception/published, is a namespace package to Python), and
the published models' files are package data of it, so a wheel carries them."""

from __future__ import annotations

import fnmatch
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib")

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def setuptools_config() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def _package_dirs(cfg: dict) -> dict[str, Path]:
    """Each listed package's folder, through ``package-dir``."""
    mapping = cfg.get("package-dir", {})
    out = {}
    for pkg in cfg["packages"]:
        parts = pkg.split(".")
        for i in range(len(parts), 0, -1):  # the longest mapped prefix
            head = ".".join(parts[:i])
            if head in mapping:
                out[pkg] = ROOT / mapping[head] / Path(*parts[i:])
                break
        else:
            out[pkg] = ROOT / Path(*parts)
    return out


def test_every_folder_inside_a_package_is_a_listed_package(setuptools_config) -> None:
    dirs = _package_dirs(setuptools_config)
    assert all(d.is_dir() for d in dirs.values()), dirs
    listed = set(dirs.values())
    missing = [
        sub.relative_to(ROOT)
        for d in dirs.values()
        for sub in d.iterdir()
        if sub.is_dir() and not sub.name.startswith((".", "__")) and sub not in listed
    ]
    assert missing == [], f"folders setuptools would warn about and ignore: {missing}"


def test_the_published_models_are_package_data(setuptools_config) -> None:
    patterns = setuptools_config["package-data"]["beo_bench.perception.published"]
    files = sorted(p.name for p in (ROOT / "perception" / "published").iterdir() if p.is_file())
    assert {"MANIFEST.json", "beo.npz", "hbeo.npz", "hbeo-mdn.npz"} <= set(files)
    assert [f for f in files if not any(fnmatch.fnmatch(f, p) for p in patterns)] == []
