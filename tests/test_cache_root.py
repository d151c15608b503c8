"""The asset cache's root is carried, never set: a run's context (``RunContext.cache_root``)
and the arguments of ``objects.prepare`` name it, and worker processes use the root they are
handed, not ``$BEO_BENCH_CACHE`` (which nothing in the package writes)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from beo_bench.bench.runner import run
from beo_bench.bench.runs import RunConfig, RunContext
from beo_bench.bench.suites import get_suite
from beo_bench.objects import ObjectSet, cache
from beo_bench.objects.prepare import prepare
from tests.bench.runs import FAST_RANDOM


def entries(root: Path) -> dict[str, int]:
    """Cache entries under ``root`` by kind."""
    out: dict[str, int] = {}
    for f in root.rglob("*.npz"):
        kind = f.relative_to(root).parts[0]
        out[kind] = out.get(kind, 0) + 1
    return out


@pytest.fixture
def roots(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[Path, Path]:
    """(the root given, the root the environment names)."""
    given, env = tmp_path / "given", tmp_path / "env"
    monkeypatch.setenv(cache.CACHE_ENV, str(env))
    return given, env


def test_prepare_workers_fill_the_root_they_are_given(roots: tuple[Path, Path]) -> None:
    given, env = roots
    objects = ObjectSet("val", ["can", "box"], per_category=1, cache_root=given)
    stats = prepare(objects, D=8, workers=2, progress=False)
    assert [s.key for s in stats] == [i.key for i in objects]
    assert entries(given).keys() >= {"generated", "voxels", "surface"}
    assert entries(env) == {} and os.environ[cache.CACHE_ENV] == str(env)
    # read back in this process from the same root: nothing is computed or written again
    before = sorted(given.rglob("*.npz"))
    objects.get("can", 0).voxels(8)
    assert sorted(given.rglob("*.npz")) == before and entries(env) == {}


def test_a_run_keeps_its_objects_in_its_contexts_cache(roots: tuple[Path, Path]) -> None:
    """The context names one root and the environment another: the driver's means and the
    workers' instances all land in the context's."""
    given, env = roots
    suite = get_suite("pose-3dof").with_overrides(size=4)
    ctx = RunContext.of(RunConfig(suite, "random", FAST_RANDOM), cache_root=given)
    assert ctx.cache_root == given and ctx.for_workers().cache_root == given
    run(ctx, given.parent / "out", progress=False, workers=2)
    assert entries(given).keys() >= {"classmeans", "voxels", "generated"}
    assert entries(env) == {}


def test_a_context_resolves_the_environments_root_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "a"))
    ctx = RunContext.of(RunConfig(get_suite("pose-3dof"), "random"))
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "b"))
    assert ctx.cache_root == tmp_path / "a"
    assert cache.cache_root() == tmp_path / "b"  # a root given none: read at each call


@pytest.mark.parametrize("backend", ["beo", "hbeo"])
def test_a_backends_model_store_is_its_contexts_cache(
    roots: tuple[Path, Path], backend: str
) -> None:
    """A named model is looked up in the run's cache, not the environment's: the error for a
    missing one names the path under the context's root."""
    from beo_bench.backend import get_backend
    from beo_bench.errors import CheckpointError

    given, env = roots
    ctx = RunContext.of(
        RunConfig(get_suite("pose-3dof"), backend, {"model": "absent"}), cache_root=given
    )
    b = get_backend(backend, model="absent")
    with pytest.raises(CheckpointError) as e:
        b.prepare(ctx)
    assert str(given / "models") in str(e.value) and str(env) not in str(e.value)


def test_the_model_and_training_stores_resolve_a_given_root(roots: tuple[Path, Path]) -> None:
    from beo_bench.perception.beo.model import model_dir
    from beo_bench.perception.hbeo.data import DatasetConfig, dataset_dir
    from beo_bench.perception.hbeo.model import model_path

    given, env = roots
    assert model_dir(None, ("mug",), cache_root=given).is_relative_to(given / "models" / "beo")
    assert model_path("m", given) == given / "models" / "hbeo" / "m"
    cfg = DatasetConfig(categories=("mug",))
    assert dataset_dir(cfg, given).parent == given / "datasets" / "hbeo"
    assert dataset_dir(cfg).is_relative_to(env)  # given none: the environment's
