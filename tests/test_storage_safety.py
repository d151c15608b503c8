"""Safety and integrity of what the package stores: the asset cache deletes only what it
made, models go by name and never replace a foreign directory, checkpoints are never run
as code, and damaged or altered cache entries, shards, models and checkpoints are rebuilt
or refused with a package error that says what to do (docs/failure-behaviour.md).

The models here are synthetic (a random orthonormal subspace, an untrained network): what
is tested is how they are stored, not what they predict, so nothing is trained."""

from __future__ import annotations

import hashlib
import io
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from beo_bench.backend import get_backend
from beo_bench.errors import CheckpointError, CorruptDataError, InvalidNameError, UsageError
from beo_bench.objects import LIBRARY_VERSION, cache
from beo_bench.perception.beo.backend import BEOBackend
from beo_bench.perception.beo.model import BEOConfig, BEOModel, load_model
from beo_bench.perception.beo.model import model_path as beo_path
from beo_bench.perception.digest import model_digest
from beo_bench.perception.hbeo.backend import HBEOBackend
from beo_bench.perception.hbeo.data import (
    DatasetConfig,
    Shard,
    dataset_dir,
    load_split,
    render_dataset,
    shard_path,
)
from beo_bench.perception.hbeo.model import HBEOConfig, HBEOModel, fingerprint
from beo_bench.perception.hbeo.model import model_path as hbeo_path
from beo_bench.perception.hbeo.net import HBEONet
from beo_bench.perception.hbeo.train import load_hbeo, train_hbeo
from tests.perception.contexts import run_context

CATS = ("bowl", "can")


@pytest.fixture
def fresh_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An asset cache of this test's own (not created yet: the first write creates it)."""
    root = tmp_path / "cache"
    monkeypatch.setenv(cache.CACHE_ENV, str(root))
    return root


def tiny_beo(D: int = 8, k: int = 3) -> BEOModel:
    """A BEO model with a random orthonormal subspace (no training)."""
    rng = np.random.default_rng(0)
    C = len(CATS)
    return BEOModel(
        config=BEOConfig(categories=CATS, resolution=D),
        basis=np.linalg.qr(rng.normal(size=(D**3, k)))[0].astype(np.float32),
        mean=np.full(D**3, 0.5, np.float32),
        class_mean=rng.normal(size=(C, k)).astype(np.float32),
        class_cov=np.stack([np.eye(k)] * C),
        class_size=np.full((C, 3), 0.1),
        components=np.ones(C, np.int64),
        shrinkage=np.zeros((C, 2)),
        info={"library_version": LIBRARY_VERSION},
    )


def hbeo_config(beo_name: str) -> HBEOConfig:
    """One epoch on two crops (and two to validate): small enough that even a run that
    should have been refused (on the code before these checks) ends in seconds."""
    ds = DatasetConfig(
        categories=CATS, images=2, val_images=2, shard_size=2, per_category=2, tabletop_share=0
    )
    return HBEOConfig(
        kind="hbeo", dataset=ds, epochs=1, batch_size=2, beo_model=beo_name, resolution=8
    )


def tiny_hbeo(beo_name: str) -> HBEOModel:
    """An untrained HBEO model regressing the subspace of the BEO model ``beo_name``."""
    beo = load_model(beo_name, CATS, 8)
    cfg = hbeo_config(beo_name)
    torch.manual_seed(0)
    return HBEOModel(
        config=cfg,
        net=HBEONet(cfg.net(beo.k)).eval(),
        beo=beo,
        coef_mean=np.zeros(beo.k, np.float32),
        coef_std=np.ones(beo.k, np.float32),
        info={"library_version": LIBRARY_VERSION},
    )


def victim(tmp_path: Path) -> Path:
    """A directory of the user's that nothing in the package may touch."""
    d = tmp_path / "precious"
    (d / "sub").mkdir(parents=True)
    (d / "notes.txt").write_text("mine")
    (d / "sub" / "config.json").write_text('{"kind": "mine"}')
    return d


def files_of(d: Path) -> dict[str, bytes]:
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


# -- 1. cache clear deletes only the cache's own kinds -----------------------------------------
@pytest.mark.parametrize("kind", ["ABS", "../precious", "voxels/../../precious", ".", ""])
def test_cache_clear_refuses_a_kind_that_is_not_a_known_kind(
    kind: str, tmp_path: Path, fresh_cache: Path
) -> None:
    keep = victim(tmp_path)
    before = files_of(keep)
    cache.cached("voxels", "ab" * 16, {"D": 4}, lambda: {"x": np.arange(3)})
    with pytest.raises(UsageError, match="voxels"):  # the message lists the kinds
        cache.clear(str(keep) if kind == "ABS" else kind)
    assert files_of(keep) == before
    assert cache.info()["kinds"]["voxels"]["entries"] == 1  # and the cache is untouched


def test_cache_clear_never_wipes_a_root_it_did_not_create(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """BEO_BENCH_CACHE pointing at someone's directory (say $HOME) by mistake: entries are
    written there on request, but clearing deletes nothing."""
    home = tmp_path / "home"
    (home / "models").mkdir(parents=True)
    (home / "models" / "thesis.tex").write_text("years of work")
    (home / ".bashrc").write_text("export X=1")
    before = files_of(home)
    monkeypatch.setenv(cache.CACHE_ENV, str(home))
    cache.cached("voxels", "ab" * 16, {"D": 4}, lambda: {"x": np.arange(3)})
    with pytest.raises(UsageError, match=r"CACHEDIR\.TAG"):
        cache.clear()
    with pytest.raises(UsageError, match="nothing was deleted"):
        cache.clear("models")
    after = files_of(home)
    assert {k: v for k, v in after.items() if not k.startswith("voxels")} == before
    assert not (home / cache.TAG_NAME).exists()  # it never claimed the directory


def test_cache_clear_removes_only_known_kinds_and_follows_no_link(
    tmp_path: Path, fresh_cache: Path
) -> None:
    outside = victim(tmp_path)
    before = files_of(outside)
    cache.cached("voxels", "ab" * 16, {"D": 4}, lambda: {"x": np.arange(3)})
    cache.cached("surface", "cd" * 16, {"n": 4}, lambda: {"p": np.ones(4)})
    (fresh_cache / "README.mine").write_text("not the cache's")
    (fresh_cache / "voxels" / "link").symlink_to(outside, target_is_directory=True)
    (fresh_cache / "rest").symlink_to(outside, target_is_directory=True)  # a kind as a link
    assert cache.clear("surface") > 0
    assert not (fresh_cache / "surface").exists() and (fresh_cache / "voxels").exists()
    cache.clear()
    assert sorted(p.name for p in fresh_cache.iterdir()) == ["CACHEDIR.TAG", "README.mine", "rest"]
    assert files_of(outside) == before


# -- 2. models go by name, and saving never replaces what the package did not write ------------
def test_a_model_name_is_never_a_path(tmp_path: Path, fresh_cache: Path) -> None:
    tiny_beo().save(tmp_path / "elsewhere")  # a real model, outside the models root
    tiny_beo().save(beo_path("ok"))
    hbeo = tiny_hbeo("ok")
    hbeo.save(tmp_path / "elsewhere-hbeo")
    for name in (str(tmp_path / "elsewhere"), "../elsewhere", ".hidden", "a/b"):
        with pytest.raises(InvalidNameError, match="not a plain name"):
            load_model(name, CATS, 8)
    with pytest.raises(InvalidNameError, match="not a plain name"):
        load_hbeo(str(tmp_path / "elsewhere-hbeo"), "hbeo", CATS)
    with pytest.raises(UsageError, match="not a plain name"):  # parsed as --opt is
        BEOBackend(model=str(tmp_path / "elsewhere"))
    # a link in the models root does not lead out of it either
    beo_path("ok").parent.joinpath("link").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(InvalidNameError, match="outside"):
        load_model("link", CATS, 8)
    assert load_model("ok", CATS, 8).k == 3  # and a name works


@pytest.mark.parametrize("which", ["beo", "hbeo"])
def test_saving_a_model_never_replaces_a_foreign_directory(
    which: str, tmp_path: Path, fresh_cache: Path
) -> None:
    keep = victim(tmp_path)
    before = files_of(keep)
    tiny_beo().save(beo_path("sub"))
    model = tiny_beo() if which == "beo" else tiny_hbeo("sub")
    with pytest.raises(CheckpointError, match="refusing to write a model into"):
        model.save(keep)
    assert files_of(keep) == before
    # nor is a model of the other kind replaced
    other = (tiny_hbeo("sub") if which == "beo" else tiny_beo()).save(tmp_path / "other")
    with pytest.raises(CheckpointError, match="refusing"):
        model.save(other)
    # its own kind of model is replaced, whole, leaving nothing else behind
    first = model.save(tmp_path / "m")
    assert model.save(first) == first
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cache", "m", "other", "precious"]


def test_training_into_a_foreign_directory_fails_before_touching_it(
    tmp_path: Path, fresh_cache: Path
) -> None:
    keep = victim(tmp_path)
    (keep / "checkpoint.pt").write_bytes(b"someone else's checkpoint")
    before = files_of(keep)
    tiny_beo().save(beo_path("sub"))
    with pytest.raises(CheckpointError, match="not a hbeo model this package wrote"):
        train_hbeo(hbeo_config("sub"), keep, progress=False, workers=1)
    assert files_of(keep) == before
    with pytest.raises(CheckpointError, match="not a hbeo model this package wrote"):
        train_hbeo(hbeo_config("sub"), keep, progress=False, workers=1, resume=False)
    assert files_of(keep) == before


# -- 3. a checkpoint is never run as code ------------------------------------------------------
class _Payload:
    """Unpickling this creates ``marker``: what a crafted checkpoint could do instead."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[object, tuple[Path]]:
        return (Path.touch, (self.marker,))


@pytest.mark.parametrize("sidecar", [True, False], ids=["with-checkpoint.json", "alone"])
def test_a_malicious_checkpoint_is_never_run(
    sidecar: bool, tmp_path: Path, fresh_cache: Path
) -> None:
    """A crafted checkpoint.pt in a shared cache: resuming refuses it with CheckpointError
    (with a checkpoint.json vouching for its hash, it is read as plain tensors and fails;
    alone, its directory is not one this package wrote) and its code never runs."""
    marker = tmp_path / "pwned"
    tiny_beo().save(beo_path("sub"))
    cfg = hbeo_config("sub")
    path = hbeo_path("victim")
    path.mkdir(parents=True)
    torch.save({"net": _Payload(marker), "epoch": 0}, path / "checkpoint.pt")
    if sidecar:
        data = (path / "checkpoint.pt").read_bytes()
        meta = {
            "kind": "hbeo",
            "format": 2,
            "config": json.loads(json.dumps(cfg.to_json())),
            "subspace": fingerprint(load_model("sub", CATS, 8)),
            "epoch": 0,
            "history": [],
            "sha256": hashlib.sha256(data).hexdigest(),
        }
        (path / "checkpoint.json").write_text(json.dumps(meta))
    error: CheckpointError | None = None
    try:
        train_hbeo(cfg, path, progress=False, workers=1)
    except CheckpointError as e:
        error = e
    assert not marker.exists(), "unpickling the checkpoint ran its code"
    assert error is not None and "checkpoint" in str(error)


# -- 7. damaged models, checkpoints and shards: package errors that say what to do -------------
@pytest.mark.parametrize("damage", ["empty", "truncated", "garbage"])
def test_damaged_model_files_raise_checkpoint_errors(
    damage: str, tmp_path: Path, fresh_cache: Path
) -> None:
    tiny_beo().save(beo_path("sub"))
    hbeo = tiny_hbeo("sub")
    hbeo.save(hbeo_path("net"))
    for f in (beo_path("sub") / "arrays.npz", hbeo_path("net") / "weights.pt"):
        data = f.read_bytes()
        f.write_bytes(
            {"empty": b"", "truncated": data[: len(data) // 2], "garbage": b"\x80"}[damage]
        )
    with pytest.raises(CheckpointError, match="train it again with `beo-bench train hbeo"):
        HBEOModel.load(hbeo_path("net"), beo=hbeo.beo)
    with pytest.raises(CheckpointError, match="train it again with `beo-bench train beo"):
        load_model("sub", CATS, 8)
    with pytest.raises(CheckpointError, match="retrain"):
        model_digest(hbeo_path("net"))


def test_a_valid_model_file_with_altered_values_is_refused(fresh_cache: Path) -> None:
    tiny_beo().save(beo_path("sub"))
    f = beo_path("sub") / "arrays.npz"
    with np.load(f) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["class_size"] = np.zeros_like(arrays["class_size"])  # zero extents, a valid file
    np.savez(f, **arrays)
    with pytest.raises(CheckpointError, match="digest"):
        load_model("sub", CATS, 8)


def _torn_checkpoint(path: Path, cfg: HBEOConfig) -> None:
    """A checkpoint.json and, beside it, its checkpoint.pt cut in half (a disk error)."""
    buf = io.BytesIO()
    torch.save({"net": HBEONet(cfg.net(3)).state_dict(), "opt": {}, "sched": {}, "epoch": 0}, buf)
    meta = {
        "kind": "hbeo",
        "format": 2,
        "config": json.loads(json.dumps(cfg.to_json())),
        "subspace": fingerprint(load_model("sub", CATS, 8)),
        "epoch": 0,
        "sha256": hashlib.sha256(buf.getvalue()).hexdigest(),
    }
    path.mkdir(parents=True, exist_ok=True)
    (path / "checkpoint.json").write_text(json.dumps(meta))
    (path / "checkpoint.pt").write_bytes(buf.getvalue()[: len(buf.getvalue()) // 2])


def test_a_corrupt_checkpoint_raises_a_checkpoint_error(fresh_cache: Path) -> None:
    tiny_beo().save(beo_path("sub"))
    cfg = hbeo_config("sub")
    path = hbeo_path("torn")
    _torn_checkpoint(path, cfg)
    with pytest.raises(CheckpointError, match=r"delete .*checkpoint\.\* .* to start over"):
        train_hbeo(cfg, path, progress=False, workers=1)
    # as the message says: training without resuming starts over ...
    logs: list[str] = []
    train_hbeo(cfg, path, progress=False, workers=1, log=logs.append, resume=False)
    assert sorted(p.name for p in path.iterdir()) == ["config.json", "weights.pt"]
    assert not any("resuming" in line for line in logs)
    # ... and so does deleting the checkpoint.pt alone
    _torn_checkpoint(path, cfg)
    (path / "checkpoint.pt").unlink()
    train_hbeo(cfg, path, progress=False, workers=1, log=logs.append)
    assert sorted(p.name for p in path.iterdir()) == ["config.json", "weights.pt"]


def _shard(n: int, seed: int) -> Shard:
    rng = np.random.default_rng(seed)
    return Shard(
        depth=rng.random((n, 8, 8)).astype(np.float16),
        label=np.arange(n, dtype=np.int16) % 2,
        instance=np.zeros(n, np.int32),
        keys=["proc/v2/bowl/train/0"],
        rotation=np.tile(np.eye(3, dtype=np.float32), (n, 1, 1)),
        offset=np.zeros((n, 3), np.float32),
        log_size=np.zeros((n, 3), np.float32),
        noisy=np.zeros(n, bool),
    )


def test_a_truncated_or_altered_shard_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "train-00000-4.npz"
    _shard(4, 0).save(path)
    assert len(Shard.load(path)) == 4
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(CorruptDataError, match="render-dataset"):
        Shard.load(path)
    bad = _shard(4, 0)
    bad.log_size[:] = -50.0  # wrong values in a valid file, its old checksum kept
    arrays = {**bad.arrays(), "__checksum__": np.array(cache.array_checksum(_shard(4, 0).arrays()))}
    np.savez_compressed(path, **arrays)
    with pytest.raises(CorruptDataError, match="checksum"):
        Shard.load(path)


def test_render_dataset_rerenders_damaged_shards() -> None:
    """`render-dataset` never counts a damaged shard as rendered: a truncated one and one
    with altered values are rendered again, identical to the originals."""
    cfg = DatasetConfig(
        categories=CATS, images=4, val_images=0, shard_size=2, per_category=2,
        tabletop_share=0.0, seed=11,
    )  # fmt: skip
    render_dataset(cfg, workers=1, progress=False)
    before = load_split(cfg, "train")
    first, second = (shard_path(dataset_dir(cfg), "train", i, 2) for i in (0, 1))
    first.write_bytes(first.read_bytes()[:100])
    with np.load(second) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["label"] = 1 - arrays["label"]  # the wrong class, checksum kept
    np.savez_compressed(second, **arrays)
    with pytest.raises(CorruptDataError):
        load_split(cfg, "train")
    _, stats = render_dataset(cfg, workers=1, progress=False)
    assert stats["images"] == 4 and stats["repaired"] == 2
    after = load_split(cfg, "train")
    assert np.array_equal(after.label, before.label)
    assert np.array_equal(np.nan_to_num(after.depth), np.nan_to_num(before.depth))


# -- 9. cache entries carry a checksum ---------------------------------------------------------
def test_a_cache_entry_with_wrong_values_is_recomputed(fresh_cache: Path) -> None:
    calls = []

    def compute() -> dict[str, np.ndarray]:
        calls.append(1)
        return {"extents": np.array([0.1, 0.2, 0.3])}

    good = cache.cached("rest", "ef" * 16, {"v": 1}, compute)
    path = cache.entry_path("rest", "ef" * 16, {"v": 1})
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    for tampered in (
        {**arrays, "extents": np.zeros(3)},  # zero extents, the checksum kept
        {"extents": np.zeros(3)},  # no checksum at all (as an older version wrote)
    ):
        np.savez_compressed(path, **tampered)
        out = cache.cached("rest", "ef" * 16, {"v": 1}, compute)
        np.testing.assert_array_equal(out["extents"], good["extents"])
        assert "__checksum__" not in out
    assert len(calls) == 3
    # rewritten with a checksum: the next load is trusted, not recomputed
    np.testing.assert_array_equal(
        cache.cached("rest", "ef" * 16, {"v": 1}, compute)["extents"], good["extents"]
    )
    assert len(calls) == 3


# -- 8. model digests of the learned backends --------------------------------------------------
def test_learned_backends_report_their_model_digest(fresh_cache: Path) -> None:
    tiny_beo().save(beo_path("sub"))
    tiny_hbeo("sub").save(hbeo_path("net"))
    beo = BEOBackend(model="sub", resolution=8)
    assert beo.model_digest() is None  # before prepare: no model chosen yet
    beo.prepare(run_context("beo", CATS, model="sub", resolution=8))
    assert beo.model_digest() == model_digest(beo_path("sub"))
    swap = get_backend("swap", base="beo", truth="class", model="sub", resolution=8)
    swap.prepare(run_context("swap", CATS, base="beo", truth="class", model="sub", resolution=8))
    assert swap.model_digest() == model_digest(beo_path("sub"))
    hbeo = HBEOBackend(model="net")
    hbeo.prepare(run_context("hbeo", CATS, model="net"))
    assert hbeo.model_digest() == model_digest(hbeo_path("net"))
    assert get_backend("swap", base="oracle").model_digest() is None
