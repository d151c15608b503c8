"""The published reference models: the backends' defaults load them without training,
each file is checked against its digest, and docs/reference-models.md lists the digests."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from beo_bench.errors import CheckpointError
from beo_bench.perception import published
from beo_bench.perception.beo import model as beo_model
from beo_bench.perception.digest import state_digest
from beo_bench.perception.hbeo import model as hbeo_model
from beo_bench.perception.hbeo import train as hbeo_train
from beo_bench.perception.hbeo.publish import hbeo_arrays
from beo_bench.scenes.pickconfig import default_categories
from tests.perception.contexts import run_context

MODELS_PAGE = Path(__file__).resolve().parents[2] / "docs" / "reference-models.md"


@pytest.fixture
def no_training(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*a: object, **k: object) -> None:
        raise AssertionError("a published default model was trained instead of loaded")

    monkeypatch.setattr(beo_model, "train_beo", refuse)
    monkeypatch.setattr(hbeo_train, "train_hbeo", refuse)


def test_every_published_model_is_listed_with_its_digest() -> None:
    files = published.manifest()
    assert {f"{s}.npz" for s in published.STEMS} <= set(files)
    total = sum(size for _, size, _ in published.files_table())
    assert total <= 20e6, f"published models take {total / 1e6:.1f} MB (at most 20 MB)"
    for name, size, _ in published.files_table():
        assert size <= 10e6, f"{name} takes {size / 1e6:.1f} MB (at most 10 MB a file)"
    text = MODELS_PAGE.read_text()
    for name, sha in files.items():
        if name.endswith(".npz"):
            assert re.search(rf"`{re.escape(name)}`.*{sha}", text), (
                f"docs/reference-models.md lacks {name} {sha}"
            )


def test_the_models_page_states_the_published_sizes() -> None:
    """docs/reference-models.md's sizes are the files': each file's row (MB, two decimals)
    and every total ("N MB in all", "with the JSON sidecars and the manifest: N MB"), which
    is every published file with the manifest, to 0.1 MB."""
    text = MODELS_PAGE.read_text()
    for name, size, sha in published.files_table():
        if name.endswith(".npz"):
            row = re.search(
                rf"^\| `{re.escape(name)}` \|.*\| ([\d.]+) MB \| `{sha}` \|$", text, re.M
            )
            assert row, f"docs/reference-models.md has no row of {name} with its size"
            assert row.group(1) == f"{size / 1e6:.2f}", f"{name}: {size / 1e6:.2f} MB"
    total = sum(size for _, size, _ in published.files_table())
    total += (published.PUBLISHED_DIR / published.MANIFEST).stat().st_size
    stated = re.findall(r"([\d.]+) MB in all", text)
    stated += re.findall(r"the JSON sidecars and the manifest: ([\d.]+) MB", text)
    assert len(stated) == 2, stated
    assert set(stated) == {f"{total / 1e6:.1f}"}, f"the published files take {total / 1e6:.1f} MB"


def test_the_models_page_states_the_top_down_share_of_the_recipe() -> None:
    """The recipes' share of top-down views on the page is the code's, and the published
    networks were trained with it."""
    from beo_bench.perception.hbeo.data import DatasetConfig

    d = DatasetConfig(categories=("car",))
    for kind in ("hbeo", "hbeo-mdn"):
        meta, _ = published.read(kind)
        got = meta["config"]["dataset"]
        assert got["top_down_share"] == d.top_down_share
        assert got["tabletop_share"] == d.tabletop_share
        assert got["noise_share"] == d.noise_share
    text = " ".join(MODELS_PAGE.read_text().split())
    isolated = (1 - d.tabletop_share) * d.top_down_share
    assert (
        f"{d.tabletop_share:.0%} are tabletop scenes" in text
        and f"with probability {d.top_down_share:g} (`top_down_share`: "
        f"{d.top_down_share:.0%} of the isolated crops, {isolated:.0%} of all of them"
        in text
        and f"{d.noise_share:.0%} of the crops get the depth-noise augmentation" in text
    ), "docs/reference-models.md's recipe shares differ from DatasetConfig's"


def test_the_models_page_names_the_default_beo_model_of_a_class_subset() -> None:
    """The page's command for the ``modelnet10`` classes' BEO model stores it under the name
    the backend looks for (trained on first use otherwise)."""
    from beo_bench.objects.sets import MODELNET10

    name = beo_model.default_name(tuple(MODELNET10), 32, None, None)
    assert f"beo-bench train beo --categories modelnet10   # -> models/beo/{name}" in (
        MODELS_PAGE.read_text()
    )
    assert beo_model.published_for(tuple(MODELNET10), 32, None) is None  # not the published


def test_the_default_models_are_the_published_ones(no_training) -> None:
    cats = default_categories()
    beo = beo_model.load_model(None, cats, 32)
    meta, _ = published.read("beo")
    assert state_digest(beo.arrays()) == meta["digest"]
    for kind in ("hbeo", "hbeo-mdn"):
        m = hbeo_train.load_hbeo(None, kind, cats)  # type: ignore[arg-type]
        meta, _ = published.read(kind)
        assert state_digest(m.state()) == meta["digest"]
        assert m.beo is beo  # regresses the published subspace
        assert m.config.select == "best-val" and m.config.dataset.images == 100_000
        # the larger networks are not published: without one in the cache the error names
        # the GPU command, and nothing trains
        with pytest.raises(CheckpointError, match="--size dissertation --device cuda"):
            hbeo_train.load_hbeo(None, kind, cats, size="dissertation")  # type: ignore[arg-type]


def test_an_altered_published_file_is_reported_not_used(tmp_path, monkeypatch) -> None:
    root = tmp_path / "published"
    shutil.copytree(published.PUBLISHED_DIR, root)
    (root / "hbeo.json").write_text((root / "hbeo.json").read_text().replace("\n", "\n ", 1))
    monkeypatch.setattr(published, "PUBLISHED_DIR", root)
    # the models read are cached by the published files' place and digests: not that one
    with pytest.raises(CheckpointError, match=r"altered.*git checkout"):
        hbeo_train.load_hbeo(None, "hbeo", default_categories())


def test_a_suite_on_some_classes_is_answered_by_the_published_network(no_training) -> None:
    """``pose-3dof-percat`` holds three of the 18 classes: the published network answers
    it (nothing trains), its class scores read at those three classes."""
    from beo_bench.backend import sample_views
    from beo_bench.perception.hbeo.backend import HBEOBackend

    cats = ("airplane", "car", "sofa")
    m = hbeo_train.load_hbeo(None, "hbeo", cats)
    assert m.categories == default_categories()  # the 11-class published one
    b = HBEOBackend()
    b.prepare(run_context("hbeo", cats))
    (view,) = sample_views(picks=[("car", 0)], seed=3)
    from dataclasses import replace

    est = b.predict(replace(view, categories=cats))
    assert est.class_probs.shape == (3,) and abs(est.class_probs.sum() - 1) < 1e-9
    assert int(est.class_probs.argmax()) == 1  # car


def test_an_array_too_large_for_one_file_is_published_in_chunks(tmp_path, monkeypatch) -> None:
    """A split array that would pass the file limit goes into as few row-block files as keep
    each under it; read() joins them, losslessly. Publishing it again small writes one file
    and removes the chunks (and only them) from the directory and the manifest."""
    import numpy as np

    rng = np.random.default_rng(0)
    basis = rng.normal(size=(4000, 30)).astype(np.float32)  # about 0.45 MB packed
    arrays = {"basis": basis, "mu": rng.normal(size=4000).astype(np.float32)}
    (tmp_path / "mine.txt").write_text("not ours")
    monkeypatch.setattr(published, "FILE_LIMIT", 200_000)
    published.write("beo", {"k": 30}, arrays, tmp_path)
    chunks = sorted(p.name for p in tmp_path.glob("beo-basis-*.npz"))
    assert len(chunks) >= 3 and not (tmp_path / "beo-basis.npz").exists()
    assert all((tmp_path / c).stat().st_size <= 200_000 for c in chunks)
    _, got = published.read("beo", tmp_path)
    np.testing.assert_array_equal(got["basis"], basis)
    np.testing.assert_array_equal(got["mu"], arrays["mu"])
    monkeypatch.setattr(published, "FILE_LIMIT", 10_000_000)
    published.write("beo", {"k": 30}, arrays, tmp_path)
    assert not list(tmp_path.glob("beo-basis-*.npz")) and (tmp_path / "beo-basis.npz").exists()
    assert not any(n.startswith("beo-basis-") for n in published.manifest(tmp_path))
    np.testing.assert_array_equal(published.read("beo", tmp_path)[1]["basis"], basis)
    assert (tmp_path / "mine.txt").read_text() == "not ours"


def test_the_published_beo_basis_is_rounded_to_16_significant_bits() -> None:
    """Publishing rounds the basis to nearest (relative error at most 2^-16) and keeps the
    class covariances at float32's precision; the published model is that rounded one."""
    import numpy as np

    a = np.random.default_rng(1).normal(size=50_000).astype(np.float32)
    r = published.round_mantissa(a, published.BASIS_DROPPED_BITS)
    assert np.all(r.view(np.uint32) & 0xFF == 0)
    rel = np.abs(r - a) / np.abs(a)
    assert rel.max() <= 2.0**-16 and rel.mean() > 2.0**-19  # nearest, not truncated away
    _, arrays = published.read("beo")
    assert np.all(arrays["basis"].view(np.uint32) & 0xFF == 0)
    cov = arrays["class_cov"]
    assert np.array_equal(cov, cov.astype(np.float32).astype(np.float64))


def test_int8_storage_reads_back_within_half_a_step(tmp_path, monkeypatch) -> None:
    """``--storage int8`` keeps each quantised weight within half its row's step of the
    trained one (and every other tensor within float16's rounding), the digest names the
    weights as used, and an all-zero row reads back as zeros."""
    import numpy as np
    import torch

    q, scale = published.quantise(np.array([[0.0, 0.0], [1.0, -0.5]], np.float32))
    assert q.tolist() == [[0, 0], [127, -64]] and scale[0] == 1.0
    from beo_bench.perception.hbeo.net import HBEONet, NetConfig

    torch.manual_seed(0)
    net = HBEONet(NetConfig.preset("small", classes=1, coefficients=6, crop=32, rotation="mdn"))
    monkeypatch.setattr(published, "INT8_MIN_SIZE", 1000)
    model = type("M", (), {"net": net, "coef_mean": np.zeros(6), "coef_std": np.ones(6)})()
    arrays = hbeo_arrays(model, "int8")  # type: ignore[arg-type]
    quantised = [k for k in arrays if k.endswith(published.SCALE)]
    assert quantised
    assert all(arrays[k.removesuffix(published.SCALE)].dtype == np.int8 for k in quantised)
    state = published._state(arrays)["net"]
    for k, v in net.state_dict().items():
        s = arrays.get(published.NET_PREFIX + k + published.SCALE)
        if s is not None:
            step = torch.from_numpy(s).reshape(-1, *[1] * (v.ndim - 1))
            assert bool(((state[k] - v).abs() <= step / 2 + 1e-7).all()), k
        elif v.dtype == torch.float32:
            torch.testing.assert_close(state[k], v, rtol=1e-3, atol=1e-4)


def test_the_published_set_is_refused_over_its_cap(tmp_path, monkeypatch) -> None:
    """A publication that would take the set past TOTAL_LIMIT is a usage error naming
    ``--storage int8``, and nothing is written: the manifest and the files stay as they
    were."""
    import numpy as np

    from beo_bench.errors import UsageError

    arrays = {"basis": np.arange(20000, dtype=np.float32).reshape(100, 200)}
    published.write("beo", {"k": 1}, arrays, tmp_path)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    monkeypatch.setattr(published, "TOTAL_LIMIT", sum(len(b) for b in before.values()) + 10)
    published.write("beo", {"k": 1}, arrays, tmp_path)  # replacing itself: same size, fits
    with pytest.raises(UsageError, match=r"over its 0 MB.*--storage int8"):
        published.write("hbeo-mdn", {"k": 1}, {"x": np.ones(5000, np.float32)}, tmp_path)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_the_per_category_networks_are_published_with_their_subspaces(no_training) -> None:
    """Chapter 5's per-category MDNs (car, airplane, sofa) load from the published files
    with ``recipe="per-category"`` (nothing trains), each regressing its own class's
    published subspace, int8-stored; a class without one is not answered by them."""
    for c in published.PER_CATEGORY:
        m = hbeo_train.load_hbeo(None, "hbeo-mdn", (c,), recipe="per-category")
        meta, _ = published.read(f"hbeo-mdn-{c}")
        assert meta["stored_dtype"] == "int8" and state_digest(m.state()) == meta["digest"]
        assert m.categories == (c,) and hbeo_model.is_per_category_default(m.config)
        assert m.beo is beo_model.published_model(f"beo-{c}")
        assert hbeo_model.fingerprint(m.beo) == meta["subspace"]
        assert beo_model.load_model(None, (c,), 32) is m.beo  # BEO of that class alone
    assert hbeo_model.published_per_category("hbeo-mdn", "chair") is None
    assert hbeo_model.published_per_category("hbeo", "car") is None  # not published
