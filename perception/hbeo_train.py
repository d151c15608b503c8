"""Training and storing HBEO / HBEO-MDN models (``beo-bench train hbeo|hbeo-mdn``).

A model is a directory under ``<asset cache>/models/hbeo/<name>/``:

- ``config.json``: the :class:`HBEOConfig`, the subspace's fingerprint, the class list,
  the per-epoch validation history and provenance;
- ``weights.pt``: the network's weights and the coefficient standardisation;
- ``checkpoint.pt`` while training: weights, optimiser and epoch, written after every
  epoch through a temporary file and a rename, so a killed run resumes at the last finished
  epoch with the same result it would have had (each epoch's shuffle is seeded by
  (seed, epoch)).

The network regresses the subspace coefficients of eq. 4.1, o' = W^T (o - mu), of BEO's
shared subspace (the same W and mu as the ``beo`` backend); a model is refused with
:class:`CheckpointError` when the subspace, class list or crop size it was trained for
differs from the one asked for.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
from beo_bench.perception.beo_model import BEOModel, load_model
from beo_bench.perception.hbeo_data import DatasetConfig, Shard, load_split, render_dataset
from beo_bench.perception.hbeo_net import (
    HBEONet,
    NetConfig,
    geodesic_deg,
    losses,
    point_rotation,
)

from beo_bench.errors import CheckpointError

Kind = Literal["hbeo", "hbeo-mdn"]
FORMAT_VERSION = 1


@dataclass(frozen=True)
class HBEOConfig:
    """What an HBEO model is trained on and how."""

    kind: Kind
    dataset: DatasetConfig
    size: str = "small"
    """``small`` (CPU default) or ``dissertation`` (Figure 4.2's widths)."""
    rotation: str = "axis-angle"
    """HBEO's rotation head: ``axis-angle`` (dissertation) or ``6d``; the MDN is a mixture
    over axis-angle."""
    epochs: int = 15
    batch_size: int = 128
    lr: float = 2e-3
    weight_decay: float = 1e-4
    seed: int = 0
    beo_model: str | None = None
    """The BEO model whose subspace is regressed (None: the default one)."""
    beo_instances: int | None = None
    """With ``beo_model=None``: the default BEO model trained on this many instances per
    class (None: all, the ``beo`` backend's default)."""
    resolution: int = 32

    def __post_init__(self) -> None:
        if self.kind not in ("hbeo", "hbeo-mdn"):
            raise ValueError(f"kind={self.kind!r}: use 'hbeo' or 'hbeo-mdn'")
        if self.rotation not in ("axis-angle", "6d"):
            raise ValueError(f"rotation={self.rotation!r}: use 'axis-angle' or '6d'")
        if self.epochs < 1 or self.batch_size < 2:
            raise ValueError("epochs >= 1 and batch_size >= 2 are required")

    @property
    def categories(self) -> tuple[str, ...]:
        return self.dataset.categories

    def net(self, k: int) -> NetConfig:
        rot = "mdn" if self.kind == "hbeo-mdn" else self.rotation
        return NetConfig.preset(
            self.size,
            classes=len(self.categories),
            coefficients=k,
            crop=self.dataset.crop,
            rotation=rot,
        )

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> HBEOConfig:
        ds = dict(d["dataset"])
        ds["categories"] = tuple(ds["categories"])
        return cls(**{**d, "dataset": DatasetConfig(**ds)})


def fingerprint(beo: BEOModel) -> str:
    """Identifies a subspace (W, mu): a model regressing other coefficients is refused."""
    h = hashlib.sha256(np.ascontiguousarray(beo.basis).tobytes())
    h.update(np.ascontiguousarray(beo.mean).tobytes())
    return h.hexdigest()[:16]


@dataclass
class HBEOModel:
    """A trained network with what it needs at inference: the subspace it regresses and
    the standardisation of its coefficients."""

    config: HBEOConfig
    net: HBEONet
    beo: BEOModel
    coef_mean: np.ndarray
    coef_std: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def categories(self) -> tuple[str, ...]:
        return self.config.categories

    def save(self, path: Path) -> Path:
        path.mkdir(parents=True, exist_ok=True)
        state = {
            "net": self.net.state_dict(),
            "coef_mean": torch.from_numpy(self.coef_mean),
            "coef_std": torch.from_numpy(self.coef_std),
        }
        tmp = path / f".weights.pt.{os.getpid()}.tmp"
        torch.save(state, tmp)
        os.replace(tmp, path / "weights.pt")
        meta = {
            "kind": self.config.kind,
            "format": FORMAT_VERSION,
            "config": self.config.to_json(),
            "subspace": fingerprint(self.beo),
            "k": self.beo.k,
            "info": self.info,
        }
        tmp = path / f".config.json.{os.getpid()}.tmp"
        tmp.write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
        os.replace(tmp, path / "config.json")
        return path

    @classmethod
    def load(cls, path: Path, beo: BEOModel | None = None) -> HBEOModel:
        if not (path / "config.json").exists() or not (path / "weights.pt").exists():
            raise CheckpointError(
                f"no HBEO model at {path}: train one with `beo-bench train hbeo` (or "
                "`hbeo-mdn`), or leave the model option unset for the default"
            )
        try:
            meta = json.loads((path / "config.json").read_text())
            cfg = HBEOConfig.from_json(meta["config"])
            state = torch.load(path / "weights.pt", map_location="cpu", weights_only=True)
        except (OSError, ValueError, KeyError, TypeError, RuntimeError) as e:
            raise CheckpointError(
                f"the HBEO model at {path} is unreadable ({e}); delete it and retrain"
            ) from e
        if meta.get("format") != FORMAT_VERSION:
            raise CheckpointError(
                f"{path} holds format {meta.get('format')}, this version reads "
                f"{FORMAT_VERSION}; retrain with `beo-bench train {cfg.kind}`"
            )
        if beo is None:
            beo = load_model(
                cfg.beo_model, cfg.categories, cfg.resolution, per_category=cfg.beo_instances
            )
        if meta.get("subspace") != fingerprint(beo):
            raise CheckpointError(
                f"the HBEO model at {path} regresses the coefficients of another BEO "
                f"subspace ({meta.get('subspace')}, this one is {fingerprint(beo)}); retrain "
                f"it with `beo-bench train {cfg.kind}` against the current BEO model"
            )
        net = HBEONet(cfg.net(beo.k))
        try:
            net.load_state_dict(state["net"])
        except RuntimeError as e:
            raise CheckpointError(f"{path}: weights do not fit the network ({e})") from e
        net.eval()
        return cls(
            config=cfg,
            net=net,
            beo=beo,
            coef_mean=state["coef_mean"].numpy(),
            coef_std=state["coef_std"].numpy(),
            info=meta.get("info", {}),
        )

    def check_matches(self, categories: tuple[str, ...], where: str) -> None:
        """Raise :class:`CheckpointError` unless trained for exactly these categories. (The
        crop size needs no check: the network is built from the stored config, and weights
        of another crop size fail to load.)"""
        if tuple(categories) != self.categories:
            raise CheckpointError(
                f"the {self.config.kind} model {where} was trained for categories "
                f"{list(self.categories)} (asked: {list(categories)})"
                + f"; train one with `beo-bench train {self.config.kind} --name NAME "
                f"--categories {' '.join(categories)}` and pass `--opt model=NAME`"
            )


TRAIN_THREADS = 2
"""Threads for training, whatever the machine's core count. A float reduction split over
another number of threads sums in another order, so the weights would differ in the last
bits and then drift apart over the epochs. A fixed count makes a retrained default model
bitwise the published one, on a machine with the same kind of CPU. (Measured: retraining the
default ``hbeo`` model on 2 cores reproduced every weight exactly.)"""


def models_root() -> Path:
    from beo_bench.objects.cache import cache_root

    return cache_root() / "models" / "hbeo"


def default_config(
    kind: Kind,
    categories: tuple[str, ...],
    instances: int | None = None,
    images: int | None = None,
    epochs: int | None = None,
) -> HBEOConfig:
    """The default small model of ``kind`` for ``categories`` (trains in minutes on CPU);
    ``instances`` per class (for the subspace and the crops), ``images`` (training crops;
    a fifth as many validation crops) and ``epochs`` shrink it for quick checks."""
    cfg = HBEOConfig(kind=kind, dataset=DatasetConfig(categories=tuple(categories)))
    if instances is not None:
        cfg = replace(cfg, beo_instances=int(instances))
    return with_overrides(
        cfg,
        per_category=instances,
        images=images,
        val_images=None if images is None else max(int(images) // 5, 1),
        epochs=epochs,
    )


def default_name(config: HBEOConfig) -> str:
    from beo_bench.objects import LIBRARY_VERSION

    key = json.dumps([config.to_json(), LIBRARY_VERSION, FORMAT_VERSION], sort_keys=True)
    return f"default-{config.kind}-{hashlib.sha256(key.encode()).hexdigest()[:10]}"


# -- training ---------------------------------------------------------------------------------
def _coefficients(beo: BEOModel, keys: list[str]) -> np.ndarray:
    """(n, k) o' = W^T (o - mu) of each instance's voxels (eq. 4.1)."""
    from beo_bench.objects import instance_from_key

    grids = np.stack([instance_from_key(k).voxels(beo.D).reshape(-1) for k in keys])
    return (grids.astype(np.float32) - beo.mean) @ beo.basis


def _rotvecs(R: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R.astype(np.float64)).as_rotvec().astype(np.float32)


@dataclass
class _Tensors:
    x: torch.Tensor  # (n, S, S) float16, NaN off the mask
    label: torch.Tensor
    coefficients: torch.Tensor
    rotvec: torch.Tensor
    R: torch.Tensor
    offset: torch.Tensor
    log_size: torch.Tensor

    def __len__(self) -> int:
        return int(self.label.shape[0])

    def batch(self, idx: torch.Tensor) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        return crops_to_input(self.x[idx]), {
            "label": self.label[idx],
            "coefficients": self.coefficients[idx],
            "rotvec": self.rotvec[idx],
            "R": self.R[idx],
            "offset": self.offset[idx],
            "log_size": self.log_size[idx],
        }


def crops_to_input(depth: torch.Tensor) -> torch.Tensor:
    """(B, S, S) float16 depth with NaN off the mask -> (B, 2, S, S) network input."""
    d = depth.float()
    m = torch.isfinite(d)
    return torch.stack([torch.where(m, d, torch.zeros_like(d)), m.float()], 1)


def _tensors(ts: Shard, codes: np.ndarray, mean: np.ndarray, std: np.ndarray) -> _Tensors:
    return _Tensors(
        x=torch.from_numpy(ts.depth),
        label=torch.from_numpy(ts.label),
        coefficients=torch.from_numpy(((codes[ts.instance] - mean) / std).astype(np.float32)),
        rotvec=torch.from_numpy(_rotvecs(ts.rotation)),
        R=torch.from_numpy(ts.rotation),
        offset=torch.from_numpy(ts.offset),
        log_size=torch.from_numpy(ts.log_size),
    )


@torch.no_grad()
def evaluate(net: HBEONet, data: _Tensors, batch: int = 512) -> dict[str, float]:
    """Mean loss terms, class accuracy and median rotation error (degrees, to the
    symmetry-canonical target) over ``data``."""
    net.eval()
    sums: dict[str, float] = {}
    correct, errs = 0, []
    for s in range(0, len(data), batch):
        idx = torch.arange(s, min(s + batch, len(data)))
        x, tgt = data.batch(idx)
        out = net(x)
        for k, v in losses(out, net.cfg, tgt).items():
            sums[k] = sums.get(k, 0.0) + float(v) * len(idx)
        correct += int((out.logits.argmax(1) == tgt["label"]).sum())
        errs.append(geodesic_deg(point_rotation(out, net.cfg), tgt["R"]))
    n = max(len(data), 1)
    res = {k: v / n for k, v in sums.items()}
    res["class_acc"] = correct / n
    res["rot_err_median"] = float(torch.cat(errs).median()) if errs else float("nan")
    return res


def train_hbeo(
    config: HBEOConfig,
    path: Path,
    progress: bool = True,
    workers: int | None = None,
    log: Any = print,
) -> HBEOModel:
    """Train (or resume training) the model ``config`` describes into ``path``, with torch
    and BLAS on ``TRAIN_THREADS`` threads (the caller's settings are restored afterwards)."""
    from threadpoolctl import threadpool_limits

    threads = torch.get_num_threads()
    torch.set_num_threads(TRAIN_THREADS)
    try:
        with threadpool_limits(limits=TRAIN_THREADS):
            return _train(config, path, progress, workers, log)
    finally:
        torch.set_num_threads(threads)


def _train(
    config: HBEOConfig, path: Path, progress: bool, workers: int | None, log: Any
) -> HBEOModel:
    from tqdm import tqdm

    t0 = time.perf_counter()
    beo = load_model(
        config.beo_model,
        config.categories,
        config.resolution,
        progress=progress,
        per_category=config.beo_instances,
    )
    _, render_stats = render_dataset(config.dataset, workers=workers, progress=progress)
    t_render = time.perf_counter() - t0
    train = load_split(config.dataset, config.dataset.split)
    val = load_split(config.dataset, config.dataset.val_split)
    codes_tr = _coefficients(beo, train.keys)
    mean, std = codes_tr.mean(0), codes_tr.std(0) + 1e-3
    tr = _tensors(train, codes_tr, mean, std)
    va = _tensors(val, _coefficients(beo, val.keys), mean, std) if len(val) else None

    torch.manual_seed(config.seed)
    net = HBEONet(config.net(beo.k))
    opt = torch.optim.AdamW(net.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    steps = config.epochs * -(-len(tr) // config.batch_size)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=config.lr, total_steps=steps)
    history: list[dict[str, float]] = []
    start = 0
    ckpt = path / "checkpoint.pt"
    if ckpt.exists():
        state = torch.load(ckpt, map_location="cpu", weights_only=False)
        if state.get("config") == config.to_json() and state.get("subspace") == fingerprint(beo):
            net.load_state_dict(state["net"])
            opt.load_state_dict(state["opt"])
            sched.load_state_dict(state["sched"])
            history, start = state["history"], state["epoch"] + 1
            log(f"resuming {path.name} after epoch {start}/{config.epochs}")
    path.mkdir(parents=True, exist_ok=True)
    t_train = time.perf_counter()
    for epoch in range(start, config.epochs):
        net.train()
        g = torch.Generator().manual_seed(config.seed * 1000 + epoch)
        order = torch.randperm(len(tr), generator=g)
        nb = len(tr) // config.batch_size  # drop the ragged last batch (BatchNorm)
        bar = tqdm(
            range(nb), desc=f"{config.kind} epoch {epoch + 1}/{config.epochs}", disable=not progress
        )
        run = 0.0
        for b in bar:
            x, tgt = tr.batch(order[b * config.batch_size : (b + 1) * config.batch_size])
            terms = losses(net(x), net.cfg, tgt)
            opt.zero_grad(set_to_none=True)
            terms["total"].backward()
            opt.step()
            sched.step()
            loss = float(terms["total"].detach())
            run = 0.9 * run + 0.1 * loss if b else loss
            bar.set_postfix(loss=f"{run:.3f}")
        row = {"epoch": epoch + 1, "train_loss": run}
        if va is not None:
            row.update({f"val_{k}": v for k, v in evaluate(net, va).items()})
        history.append(row)
        state = {
            "config": config.to_json(),
            "subspace": fingerprint(beo),
            "net": net.state_dict(),
            "opt": opt.state_dict(),
            "sched": sched.state_dict(),
            "history": history,
            "epoch": epoch,
        }
        tmp = path / f".checkpoint.pt.{os.getpid()}.tmp"
        torch.save(state, tmp)
        os.replace(tmp, ckpt)
        # logged after the checkpoint: an epoch reported done is on disk
        log(
            f"epoch {epoch + 1}: train loss {run:.3f}"
            + (
                f", val loss {row['val_total']:.3f}, class acc {row['val_class_acc']:.1%}, "
                f"rotation median {row['val_rot_err_median']:.1f} deg"
                if va is not None
                else ""
            )
        )
    net.eval()
    from beo_bench.objects import LIBRARY_VERSION

    model = HBEOModel(
        config=config,
        net=net,
        beo=beo,
        coef_mean=mean.astype(np.float32),
        coef_std=std.astype(np.float32),
        info={
            "library_version": LIBRARY_VERSION,
            "history": history,
            "train_images": len(tr),
            "val_images": len(va) if va is not None else 0,
            "render_s": round(t_render, 1),
            "render_images_per_s": round(render_stats["images_per_s"], 1),
            "train_s": round(time.perf_counter() - t_train, 1),
            "total_s": round(time.perf_counter() - t0, 1),
        },
    )
    model.save(path)
    ckpt.unlink(missing_ok=True)
    return model


def load_hbeo(
    name: str | None,
    kind: Kind,
    categories: tuple[str, ...],
    progress: bool = False,
    train_default: bool = True,
    **small: int | None,
) -> HBEOModel:
    """The model called ``name`` (under :func:`models_root`, or a directory), or with
    ``name=None`` the default ``kind`` model for ``categories`` (made smaller by ``small``:
    :func:`default_config`'s ``instances``, ``images``, ``epochs``), trained on first use."""
    from beo_bench.objects import LIBRARY_VERSION

    if name is None:
        cfg = default_config(kind, categories, **small)
        path = models_root() / default_name(cfg)
        if not (path / "weights.pt").exists():
            if not train_default:
                raise CheckpointError(f"no default {kind} model at {path}")
            train_hbeo(cfg, path, progress=progress)
    else:
        path = Path(name) if os.sep in name or Path(name).is_dir() else models_root() / name
    model = HBEOModel.load(path)
    if model.config.kind != kind:
        raise CheckpointError(
            f"{path} holds a {model.config.kind} model; this backend needs {kind} "
            f"(train one with `beo-bench train {kind}`)"
        )
    model.check_matches(tuple(categories), f"at {path}")
    if model.info.get("library_version") != LIBRARY_VERSION:
        raise CheckpointError(
            f"the {kind} model at {path} was trained on object library version "
            f"{model.info.get('library_version')}, this is {LIBRARY_VERSION}; retrain it"
        )
    return model


def with_overrides(config: HBEOConfig, **kw: Any) -> HBEOConfig:
    """``config`` with dataset fields (``images``, ``val_images``, ``seed`` ...) and training
    fields replaced by the non-None values in ``kw``."""
    ds_fields = set(DatasetConfig.__dataclass_fields__) - {"categories"}
    ds = {k: v for k, v in kw.items() if k in ds_fields and v is not None}
    # the seed seeds both the rendering and the training
    tr = {k: v for k, v in kw.items() if (k not in ds_fields or k == "seed") and v is not None}
    return replace(config, dataset=replace(config.dataset, **ds), **tr)
