"""HBEO and HBEO-MDN: crops and their frame, the mixture head against scipy, the silhouette
prior, batched re-projection, a short training run that learns, the three backends'
conformance, and clear errors for mismatched checkpoints."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy import ndimage
from scipy.spatial.transform import Rotation
from scipy.stats import multivariate_normal

from beo_bench.backend import ClassHint, check_backend, get_spec, sample_views
from beo_bench.errors import CheckpointError, InvalidNameError, ViewError
from beo_bench.metrics import rotation_error
from beo_bench.objects import ObjectSet
from beo_bench.perception.beo.model import BEOConfig, train_beo
from beo_bench.perception.beo.model import model_path as beo_model_path
from beo_bench.perception.digest import model_digest
from beo_bench.perception.hbeo.backend import BY_MODE, HBEOBackend, MDNLikelihoodBackend
from beo_bench.perception.hbeo.crop import make_crop
from beo_bench.perception.hbeo.data import (
    DatasetConfig,
    canonical_rotation,
    dataset_dir,
    load_split,
    render_dataset,
)
from beo_bench.perception.hbeo.model import HBEOConfig, HBEOModel, default_config, model_path
from beo_bench.perception.hbeo.net import (
    HBEONet,
    Mixture,
    NetConfig,
    losses,
    point_rotation,
    rotvec_to_matrix,
    sixd_to_matrix,
)
from beo_bench.perception.hbeo.silhouette import sdf_errors, signed_distance, silhouettes
from beo_bench.perception.hbeo.train import load_hbeo, train_hbeo
from tests.perception.contexts import run_context

CATS = ("airplane", "bowl", "chair")


# -- pure pieces -------------------------------------------------------------------------------
def test_crop_frame_round_trips_pose_and_size() -> None:
    """Targets computed from a pose convert back to the same pose (what inference relies
    on), and the crop holds the object's normalised depth on its mask."""
    (view,) = sample_views(picks=[("car", 0)], seed=3)
    gt = view.ground_truth
    c = make_crop(view.depth, view.mask, view.K)
    R = c.rotation_from(c.rotation_target(gt.R_cam))
    assert np.allclose(R, gt.R_cam, atol=1e-9)
    assert np.allclose(c.translation_from(c.translation_target(gt.t_cam)), gt.t_cam, atol=1e-9)
    assert np.allclose(c.size_from(c.size_target(gt.size)), gt.size, atol=1e-9)
    # the ray frame's z is the ray through the crop centre
    assert np.allclose(c.R_ray[:, 2], c.ray / np.linalg.norm(c.ray))
    assert c.image.shape == (2, 64, 64) and c.mask.sum() > 200
    assert np.all(c.image[0][~c.mask] == 0)


def test_empty_mask_is_a_view_error() -> None:
    with pytest.raises(ViewError, match="no pixel with valid depth"):
        make_crop(np.ones((32, 32), np.float32), np.zeros((32, 32), bool), np.eye(3))


def test_canonical_rotation_picks_the_symmetric_twin_closest_to_identity() -> None:
    rng = np.random.default_rng(0)
    cont = {"continuous": [{"axis": [0, 0, 1], "offset": [0, 0, 0]}], "discrete": []}
    flip = np.diag([-1.0, -1.0, 1.0, 1.0]).tolist()
    disc = {"continuous": [], "discrete": [flip]}
    for _ in range(20):
        R = Rotation.random(random_state=rng).as_matrix()
        for sym in (cont, disc):
            C = canonical_rotation(R, sym)
            # same rotation up to the symmetry: zero symmetric error
            assert rotation_error(C, R, sym) < 1e-4
            # and no twin is closer to the identity (dense check of the continuous case)
            twins = [R @ Rotation.from_euler("z", a).as_matrix() for a in np.linspace(0, 6.28, 720)]
            twins = twins if sym is cont else [R, R @ np.diag([-1.0, -1.0, 1.0])]
            assert np.trace(C) >= max(np.trace(T) for T in twins) - 1e-3


def test_rotation_parametrisations() -> None:
    rng = np.random.default_rng(1)
    w = Rotation.random(50, random_state=rng).as_rotvec()
    R = rotvec_to_matrix(torch.from_numpy(w)).numpy()
    assert np.allclose(R, Rotation.from_rotvec(w).as_matrix(), atol=1e-9)
    assert np.allclose(rotvec_to_matrix(torch.zeros(1, 3)).numpy(), np.eye(3))
    M = sixd_to_matrix(torch.from_numpy(rng.normal(size=(50, 6)))).numpy()
    assert np.allclose(M @ M.transpose(0, 2, 1), np.eye(3), atol=1e-9)
    assert np.allclose(np.linalg.det(M), 1.0)


@pytest.mark.parametrize("head", ["axis-angle", "6d", "mdn"])
def test_every_rotation_head_trains_and_gives_proper_rotations(head) -> None:
    torch.manual_seed(0)
    cfg = NetConfig(classes=3, coefficients=7, rotation=head)
    net = HBEONet(cfg)
    R = torch.from_numpy(Rotation.random(8, random_state=0).as_matrix()).float()
    tgt = {
        "label": torch.arange(8) % 3,
        "coefficients": torch.randn(8, 7),
        "rotvec": torch.from_numpy(Rotation.from_matrix(R.double().numpy()).as_rotvec()).float(),
        "R": R,
        "offset": torch.randn(8, 3),
        "log_size": torch.randn(8, 3),
    }
    x = torch.randn(8, 2, 64, 64)
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    first = None
    for _ in range(15):  # fitting one batch must drive its loss down
        loss = losses(net(x), cfg, tgt)["total"]
        first = float(loss.detach()) if first is None else first
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert float(loss.detach()) < first
    net.eval()
    P = point_rotation(net(x), cfg).detach().double()
    assert torch.allclose(P @ P.transpose(1, 2), torch.eye(3, dtype=torch.float64), atol=1e-5)
    assert torch.allclose(torch.linalg.det(P), torch.ones(8, dtype=torch.float64), atol=1e-5)


def _mixture(rng: np.random.Generator, B: int = 3, M: int = 5) -> Mixture:
    raw = torch.from_numpy(rng.normal(size=(B, M * 7)))
    return Mixture.from_raw(raw, M)


def test_mdn_nll_equals_scipy() -> None:
    """eq. 5.1-5.4 against an independent computation: sum_k pi_k N(y; mu_k, diag s_k)."""
    rng = np.random.default_rng(2)
    mix = _mixture(rng)
    y = torch.from_numpy(rng.normal(size=(3, 3)))
    ours = float(mix.nll(y))
    pi = mix.log_weights.exp().numpy()
    ref = []
    for b in range(3):
        p = sum(
            pi[b, k]
            * multivariate_normal(
                mix.means[b, k].numpy(), np.diag(mix.variances[b, k].numpy())
            ).pdf(y[b].numpy())
            for k in range(5)
        )
        ref.append(-np.log(p))
    assert ours == pytest.approx(np.mean(ref), rel=1e-9)
    assert torch.all(mix.variances > 0)
    assert torch.allclose(mix.log_weights.exp().sum(-1), torch.ones(3, dtype=torch.float64))


def test_mdn_samples_have_the_mixture_moments() -> None:
    rng = np.random.default_rng(3)
    mix = _mixture(rng, B=2)
    x = mix.sample(200_000, np.random.default_rng(4))  # (B, n, 3)
    pi = mix.log_weights.exp().numpy()[..., None]
    mu, var = mix.means.numpy(), mix.variances.numpy()
    mean = (pi * mu).sum(1)
    second = (pi * (var + mu**2)).sum(1)
    assert np.allclose(x.mean(1), mean, atol=0.02)
    assert np.allclose(x.var(1), second - mean**2, rtol=0.03, atol=0.02)


# -- silhouette prior ------------------------------------------------------------------------
def test_signed_distance_is_exact_and_reproducible() -> None:
    """Against scipy's exact EDT, and bit-identical on every call (OpenCV's precise
    transform alone differs in the last bit between calls)."""
    rng = np.random.default_rng(6)
    for _ in range(5):
        m = np.zeros((64, 64), bool)
        for _ in range(3):
            r, c = rng.integers(5, 50, 2)
            m[r : r + rng.integers(3, 14), c : c + rng.integers(3, 14)] = True
        ref = ndimage.distance_transform_edt(~m) - ndimage.distance_transform_edt(m)
        first = signed_distance(m)
        assert np.abs(first - ref).max() < 1e-9
        assert all(np.array_equal(first, signed_distance(m)) for _ in range(20))


@pytest.fixture(scope="module")
def car_view():
    (view,) = sample_views(picks=[("car", 1)], seed=5)
    inst = ObjectSet("test").get("car", 1)
    return view, torch.from_numpy(inst.voxels(32).astype(np.float32))


def _wrong(R: np.ndarray, deg: float, axis: str) -> np.ndarray:
    return R @ Rotation.from_euler(axis, deg, degrees=True).as_matrix()


def test_batched_reprojection_equals_per_sample(car_view) -> None:
    view, shape = car_view
    gt = view.ground_truth
    c = make_crop(view.depth, view.mask, view.K)
    Rs = np.stack([_wrong(gt.R_cam, a, "z") for a in (0, 30, 90, 150, 200)])
    batched = silhouettes(shape, gt.size, Rs, gt.t_cam, view.K, c)
    looped = np.stack([silhouettes(shape, gt.size, R[None], gt.t_cam, view.K, c)[0] for R in Rs])
    assert batched.shape == (5, 64, 64)
    assert np.array_equal(batched, looped)


def test_silhouette_prior_ranks_the_true_rotation_first(car_view) -> None:
    """The true shape re-projected at the true pose matches the observed mask (IoU), and
    its SDF error is smaller than at any of several wrong rotations."""
    view, shape = car_view
    gt = view.ground_truth
    c = make_crop(view.depth, view.mask, view.K)
    Rs = np.stack([gt.R_cam] + [_wrong(gt.R_cam, a, ax) for ax in "zxy" for a in (40, 90, 180)])
    masks = silhouettes(shape, gt.size, Rs, gt.t_cam, view.K, c)
    iou = (masks[0] & c.mask).sum() / (masks[0] | c.mask).sum()
    assert iou > 0.85
    e = sdf_errors(c.mask, masks)
    assert int(np.argmin(e)) == 0
    prior = 1 / (e**4 + 1e-6)
    assert prior[0] > 2 * np.max(prior[1:])


# -- a short training run ------------------------------------------------------------------------
def _config(kind: str, beo: str) -> HBEOConfig:
    ds = DatasetConfig(
        categories=CATS,
        images=600,
        val_images=150,
        shard_size=150,
        per_category=10,
        tabletop_share=0.25,
        seed=7,
    )
    return HBEOConfig(kind=kind, dataset=ds, epochs=4, batch_size=32, beo_model=beo)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def beo_dir() -> str:
    """The name of a tiny BEO model in the (per-session) cache: models go by name."""
    model = train_beo(BEOConfig(categories=CATS, per_category=10))
    model.save(beo_model_path("test-hbeo-subspace"))
    return "test-hbeo-subspace"


@pytest.fixture(scope="module")
def trained(beo_dir) -> dict[str, HBEOModel]:
    out = {}
    for kind in ("hbeo", "hbeo-mdn"):
        path = model_path(f"test-{kind}")
        out[kind] = train_hbeo(_config(kind, beo_dir), path, progress=False, workers=1)
        out[kind + "-path"] = path  # type: ignore[assignment]
    return out


def test_dataset_is_deterministic_and_resumable(beo_dir) -> None:
    """Shards do not depend on which run rendered them: delete one, render again, and the
    crops come back identical; the rest are not re-rendered."""
    cfg = _config("hbeo", beo_dir).dataset
    render_dataset(cfg, workers=1, progress=False)
    before = load_split(cfg, "train")
    shards = sorted(dataset_dir(cfg).glob("train-*.npz"))
    assert len(shards) == 4
    shards[1].unlink()
    _, stats = render_dataset(cfg, workers=1, progress=False)
    assert stats["images"] == 150  # only the missing shard
    after = load_split(cfg, "train")
    assert np.array_equal(np.nan_to_num(before.depth), np.nan_to_num(after.depth))
    assert np.array_equal(before.rotation, after.rotation)
    assert len(before) == 600 and set(before.label.tolist()) == {0, 1, 2}
    assert 0 < before.noisy.mean() < 1


def test_short_training_lowers_loss_and_beats_chance(trained) -> None:
    for kind in ("hbeo", "hbeo-mdn"):
        hist = trained[kind].info["history"]
        assert hist[-1]["train_loss"] < hist[0]["train_loss"]
        assert hist[-1]["val_total"] < hist[0]["val_total"]
        # held-out instances (the val split): three classes, chance is 1/3
        assert hist[-1]["val_class_acc"] > 0.6, hist[-1]


def test_each_mode_passes_check_backend(trained) -> None:
    views = sample_views(n=2, categories=CATS)
    for mode, kind in (("hbeo", "hbeo"), ("likelihood", "hbeo-mdn"), ("posterior", "hbeo-mdn")):
        opts = {} if mode == "hbeo" else {"samples": 16}  # samples: the MDN modes' option
        b = BY_MODE[mode](model=trained[kind + "-path"].name, **opts)  # type: ignore[arg-type]
        check_backend(b, views)
        est = b.predict(views[0])
        if mode == "hbeo":
            assert est.pose_samples is None
        else:
            assert est.pose_samples.shape == (16, 3, 3)
            assert est.pose_weights.sum() == pytest.approx(1.0)
            # the estimate is the best-weighted sample
            assert np.allclose(
                est.rotation, est.pose_samples[np.argmax(est.pose_weights)], atol=1e-6
            )


def test_resume_after_a_kill_gives_the_same_model(tmp_path, beo_dir, trained) -> None:
    """A run killed after epoch 2 (its checkpoint written) resumes there and ends with the
    uninterrupted run's weights."""
    cfg = _config("hbeo", beo_dir)
    path = tmp_path / "m"

    def kill_after_epoch_2(line: str) -> None:
        if line.startswith("epoch 2:"):
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train_hbeo(cfg, path, progress=False, workers=1, log=kill_after_epoch_2)
    assert (path / "checkpoint.pt").exists() and not (path / "weights.pt").exists()
    logs: list[str] = []
    resumed = train_hbeo(cfg, path, progress=False, workers=1, log=logs.append)
    assert logs[0].startswith("resuming") and len(logs) == 3  # epochs 3 and 4 only
    assert not (path / "checkpoint.pt").exists()
    ref = trained["hbeo"].net.state_dict()
    for k, v in resumed.net.state_dict().items():
        assert torch.equal(v, ref[k]), k
    # and `beo-bench cache info` shows the two as the same model
    assert model_digest(path) == model_digest(Path(trained["hbeo-path"]))


def test_mismatched_checkpoints_are_refused(trained, beo_dir) -> None:
    name = trained["hbeo-path"].name
    with pytest.raises(CheckpointError, match="trained for categories"):
        load_hbeo(name, "hbeo", ("airplane", "bowl", "car"))
    # a suite on some of its classes is answered by it, as by the published network
    assert load_hbeo(name, "hbeo", CATS[:2]).categories == CATS
    with pytest.raises(CheckpointError, match="holds a hbeo model"):
        load_hbeo(name, "hbeo-mdn", CATS)
    with pytest.raises(CheckpointError, match="no HBEO model"):
        load_hbeo("nothing", "hbeo", CATS)
    with pytest.raises(InvalidNameError, match="not a plain name"):  # names are names
        load_hbeo(str(trained["hbeo-path"]), "hbeo", CATS)
    other = train_beo(BEOConfig(categories=CATS, per_category=8))
    with pytest.raises(CheckpointError, match="another BEO subspace"):
        HBEOModel.load(trained["hbeo-path"], beo=other)


def test_cli_renders_a_dataset_and_trains_a_named_model(capsys) -> None:
    from beo_bench.cli import main

    small = ["--categories", *CATS, "--per-category", "10", "--images", "150", "--workers", "1"]
    assert main(["render-dataset", *small, "--val-images", "30"]) == 0
    assert "images/s" in capsys.readouterr().out
    assert main(["train", "hbeo-mdn", *small, "--epochs", "1", "--name", "cli-test"]) == 0
    assert "validation: class accuracy" in capsys.readouterr().out
    model = load_hbeo("cli-test", "hbeo-mdn", CATS)
    assert model.config.dataset.images == 150 and model.config.epochs == 1


# -- recipes, best-validation epoch, devices, published files ----------------------------------
def test_every_split_holds_its_share_of_tabletop_crops() -> None:
    """Validation covers what training sees: version 1's rule put no tabletop shard among
    the first four, so a 1,000-crop validation split (two shards) held none."""
    for images, val in ((16000, 1000), (100_000, 10_000), (600, 150)):
        cfg = DatasetConfig(categories=CATS, images=images, val_images=val)
        for split in ("train", "val"):
            shards = [s for s in cfg.shards() if s[0] == split]
            n = sum(s[3] for s in shards)
            share = sum(s[3] for s in shards if s[2] == "tabletop") / n
            assert n == (images if split == "train" else val)
            assert abs(share - cfg.tabletop_share) < 0.05, (split, images, share)


def test_the_reference_recipe_keeps_the_best_validation_epoch(beo_dir) -> None:
    cfg = replace(_config("hbeo-mdn", beo_dir), select="best-val", epochs=4, lr=2e-2)
    model = train_hbeo(cfg, model_path("test-best-val"), progress=False, workers=1)
    hist = model.info["history"]
    best = int(np.argmin([h["val_total"] for h in hist]))
    assert model.info["epoch_kept"] == best + 1
    from beo_bench.perception.hbeo.train import _coefficients, _tensors, evaluate

    val = load_split(cfg.dataset, "val")
    codes = _coefficients(model.beo, val.keys)
    data = _tensors(val, codes, model.coef_mean, model.coef_std)
    # the kept weights are that epoch's: they score its validation loss again
    assert evaluate(model.net, data)["total"] == pytest.approx(hist[best]["val_total"], rel=1e-4)
    ref = default_config("hbeo", CATS, recipe="reference")
    assert (ref.dataset.images, ref.epochs, ref.select) == (100_000, 20, "best-val")


def test_variance_weighting_is_the_voxel_space_reconstruction_error() -> None:
    """With each standardised coefficient weighted by its variance, the projection term is
    |W (c - c_hat)|^2 over the voxels (W orthonormal), up to one constant."""
    g = torch.Generator().manual_seed(0)
    k, d = 6, 50
    W = torch.linalg.qr(torch.randn(d, k, generator=g, dtype=torch.float64))[0]
    std = torch.rand(k, generator=g, dtype=torch.float64) + 0.1
    z, z_hat = torch.randn(4, k, generator=g), torch.randn(4, k, generator=g)
    var = std**2
    out = type("O", (), {})()
    out.coefficients, out.logits = z_hat, torch.zeros(4, 2)
    out.rotation, out.offset, out.log_size = torch.zeros(4, 3), torch.zeros(4, 3), torch.zeros(4, 3)
    tgt = {
        "coefficients": z,
        "coef_weight": (var / var.mean()).float(),
        "label": torch.zeros(4, dtype=torch.long),
        "rotvec": torch.zeros(4, 3),
        "R": torch.eye(3).expand(4, 3, 3),
        "offset": torch.zeros(4, 3),
        "log_size": torch.zeros(4, 3),
    }
    got = losses(out, NetConfig(classes=2, coefficients=k), tgt)["projection"]
    voxels = ((W @ ((z - z_hat).double() * std).T) ** 2).sum(0).mean()
    assert float(got) == pytest.approx(float(voxels / (k * var.mean())), rel=1e-5)


def test_devices_resolve_and_a_missing_gpu_is_a_clear_error() -> None:
    from beo_bench.errors import UsageError
    from beo_bench.perception.hbeo.train import resolve_device

    assert resolve_device("cpu").type == "cpu"
    assert resolve_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    with pytest.raises(UsageError, match="use auto, cpu or cuda"):
        resolve_device("tpu")
    if not torch.cuda.is_available():
        with pytest.raises(UsageError, match="no CUDA GPU"):
            HBEOBackend(device="cuda")


def test_a_published_model_reads_back_as_trained(trained, tmp_path) -> None:
    """Publishing keeps what inference uses: float32 exactly, float16 within its rounding,
    and the digest names the weights as used."""
    from beo_bench.perception import published
    from beo_bench.perception.digest import state_digest

    m = trained["hbeo-mdn"]
    from beo_bench.perception.hbeo.publish import publish_hbeo

    publish_hbeo(m, tmp_path, storage="float32")
    meta, arrays = published.read("hbeo-mdn", tmp_path)
    assert state_digest(published._state(arrays)) == meta["digest"] == state_digest(m.state())
    publish_hbeo(m, tmp_path, storage="float16")
    meta, arrays = published.read("hbeo-mdn", tmp_path)
    state = published._state(arrays)
    assert meta["stored_dtype"] == "float16" and meta["digest"] == state_digest(state)
    for k, v in m.net.state_dict().items():
        torch.testing.assert_close(state["net"][k], v, rtol=1e-3, atol=1e-4)
    # an altered file is refused, never used
    data = bytearray((tmp_path / "hbeo-mdn.npz").read_bytes())
    data[len(data) // 2] ^= 1
    (tmp_path / "hbeo-mdn.npz").write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match="altered"):
        published.read("hbeo-mdn", tmp_path)


def test_the_network_and_its_rotations_stay_on_the_device_of_their_input() -> None:
    """Every tensor the network and its rotation heads make follows the input's device
    (a CPU-made identity broke `--device cuda` training at the first validation). The
    ``meta`` device stands in for a GPU: mixing it with a CPU tensor raises."""
    from beo_bench.perception.hbeo.net import HBEONet, NetConfig, losses, point_rotation

    for rot in ("axis-angle", "6d", "mdn"):
        cfg = NetConfig.preset("small", classes=3, coefficients=5, crop=32, rotation=rot)
        net = HBEONet(cfg).to("meta")
        out = net(torch.zeros(4, 2, 32, 32, device="meta"))
        assert point_rotation(out, cfg).device.type == "meta"
        tgt = {
            "label": torch.zeros(4, dtype=torch.long, device="meta"),
            "coefficients": torch.zeros(4, 5, device="meta"),
            "rotvec": torch.zeros(4, 3, device="meta"),
            "R": torch.zeros(4, 3, 3, device="meta"),
            "offset": torch.zeros(4, 3, device="meta"),
            "log_size": torch.zeros(4, 3, device="meta"),
        }
        assert losses(out, cfg, tgt)["total"].device.type == "meta"


def test_per_category_networks_are_chosen_by_the_hint_and_never_trained_in_a_run(
    monkeypatch,
) -> None:
    """Table 5.1's protocol (``per_category=true``): the hinted class picks its own network;
    a class without one is an error naming the command that trains it (nothing trains
    inside a run), and a view without the hint is refused."""
    from dataclasses import replace as dc_replace

    from beo_bench.errors import UsageError
    from beo_bench.perception.hbeo import train as hbeo_train

    def refuse(*a: object, **k: object) -> None:
        raise AssertionError("a per-category network was trained inside a run")

    monkeypatch.setattr(hbeo_train, "train_hbeo", refuse)
    b = MDNLikelihoodBackend(per_category=True)
    spec = get_spec("hbeo-mdn-likelihood")
    assert spec.capabilities_of(b.options).class_hint is ClassHint.REQUIRED
    assert spec.capabilities_of(spec.parse({})).class_hint is ClassHint.NONE
    assert spec.capabilities_of(spec.parse({"per_category": "yes"})).needs_class_hint
    with pytest.raises(
        CheckpointError,
        match=r"`beo-bench train hbeo-mdn --categories lamp --recipe per-category`",
    ):
        b.prepare(run_context("hbeo-mdn-likelihood", ("lamp",), per_category=True))
    (view,) = sample_views(picks=[("car", 0)], seed=3)
    cats = ("airplane", "car", "sofa")
    assert b._classes(dc_replace(view, categories=cats, class_hint=1)) == ("car",)
    with pytest.raises(UsageError, match="class hint"):
        b.predict(dc_replace(view, class_hint=None))
    with pytest.raises(ValueError, match="leave model unset"):
        HBEOBackend(per_category=True, model="mine")
