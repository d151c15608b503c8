"""Training and storing HBEO / HBEO-MDN models (``beo-bench train hbeo|hbeo-mdn``).

A model is a directory under ``<asset cache>/models/hbeo/<name>/``:

- ``config.json``: the :class:`HBEOConfig`, the subspace's fingerprint, the class list,
  the per-epoch validation history, provenance and the digest of the weights;
- ``weights.pt``: the network's weights and the coefficient standardisation (tensors only,
  read with ``torch.load(weights_only=True)``);
- while training, ``checkpoint.pt`` (weights, optimiser and scheduler state: tensors and
  plain containers only, read with ``weights_only=True``, so a crafted file cannot run code)
  and ``checkpoint.json`` beside it (config, subspace, history, epoch and the SHA-256 of the
  checkpoint file), written after every epoch (:func:`_write_checkpoint`), so a killed run
  resumes at the last finished epoch with the same result it would have had (each epoch's
  shuffle is seeded by (seed, epoch)).

The finished model is written to a temporary sibling directory and renamed into place,
replacing only a model directory this package wrote (:mod:`.modeldir`); models are
addressed by name under :func:`models_root`, never by a path.

The network regresses the subspace coefficients of eq. 4.1, o' = W^T (o - mu), of BEO's
shared subspace (the same W and mu as the ``beo`` backend); a model is refused with
:class:`CheckpointError` when the subspace, class list or crop size it was trained for
differs from the one asked for.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from beo_bench.atomic import atomic_write_bytes
from beo_bench.errors import CheckpointError, UsageError
from beo_bench.perception import modeldir
from beo_bench.perception.beo.model import BEOModel, load_model
from beo_bench.perception.hbeo.data import Shard, load_split, render_dataset
from beo_bench.perception.hbeo.model import (
    CHECKPOINT_FILES,
    CHECKPOINT_FORMAT,
    FILES,
    KINDS,
    HBEOConfig,
    HBEOModel,
    Kind,
    default_config,
    default_name,
    fingerprint,
    model_path,
    published_for,
    published_per_category,
    with_overrides,
)
from beo_bench.perception.hbeo.net import (
    HBEONet,
    geodesic_deg,
    losses,
    point_rotation,
)

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset


TRAIN_THREADS = 2
"""Threads for training, whatever the machine's core count. A float reduction split over
another number of threads sums in another order, so the weights would differ in the last
bits and then drift apart over the epochs. A fixed count makes a retrained default model
bitwise the published one, on a machine with the same kind of CPU. (Measured: retraining the
default ``hbeo`` model on 2 cores reproduced every weight exactly.)"""


# -- training ---------------------------------------------------------------------------------
def _coefficients(
    beo: BEOModel, keys: list[str], dataset: Dataset | None = None, cache_root: Path | None = None
) -> np.ndarray:
    """(n, k) o' = W^T (o - mu) of each instance's voxels (eq. 4.1); ``dataset``: where
    the keys of a user's dataset are looked up (None: the procedural library), kept in the
    asset cache ``cache_root`` (None: the environment's)."""
    from beo_bench.objects import instance_from_key

    grids = np.stack(
        [instance_from_key(k, dataset, cache_root).voxels(beo.D).reshape(-1) for k in keys]
    )
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
    coef_weight: torch.Tensor | None = None
    device: torch.device = field(default_factory=lambda: torch.device("cpu"))

    def __len__(self) -> int:
        return int(self.label.shape[0])

    def batch(self, idx: torch.Tensor) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        """The crops ``idx`` (indices on the CPU, where the data stays) on :attr:`device`."""
        d = self.device
        tgt = {
            "label": self.label[idx].to(d),
            "coefficients": self.coefficients[idx].to(d),
            "rotvec": self.rotvec[idx].to(d),
            "R": self.R[idx].to(d),
            "offset": self.offset[idx].to(d),
            "log_size": self.log_size[idx].to(d),
        }
        if self.coef_weight is not None:
            tgt["coef_weight"] = self.coef_weight.to(d)
        return crops_to_input(self.x[idx].to(d)), tgt


def crops_to_input(depth: torch.Tensor) -> torch.Tensor:
    """(B, S, S) float16 depth with NaN off the mask -> (B, 2, S, S) network input."""
    d = depth.float()
    m = torch.isfinite(d)
    return torch.stack([torch.where(m, d, torch.zeros_like(d)), m.float()], 1)


def _tensors(
    ts: Shard,
    codes: np.ndarray,
    mean: np.ndarray,
    std: np.ndarray,
    weighting: str = "uniform",
    device: torch.device | None = None,
) -> _Tensors:
    weight = None
    if weighting == "variance":  # each coefficient's share of the variance, mean 1
        var = std.astype(np.float64) ** 2
        weight = torch.from_numpy((var / var.mean()).astype(np.float32))
    return _Tensors(
        coef_weight=weight,
        device=device if device is not None else torch.device("cpu"),
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
        errs.append(geodesic_deg(point_rotation(out, net.cfg), tgt["R"]).cpu())
    n = max(len(data), 1)
    res = {k: v / n for k, v in sums.items()}
    res["class_acc"] = correct / n
    res["rot_err_median"] = float(torch.cat(errs).median()) if errs else float("nan")
    return res


def check_steps(config: HBEOConfig) -> None:
    """A :class:`~beo_bench.errors.UsageError` when ``config`` would train no step: an epoch
    drops its ragged last batch (BatchNorm), so fewer training crops than one batch leave
    nothing, and the untouched network would be saved as if trained."""
    n, b = config.dataset.images, config.batch_size
    if n < b:
        raise UsageError(
            f"--images {n} is fewer than --batch-size {b}: training would run no step "
            f"(each epoch drops its ragged last batch). Give --images {b} or more, or "
            f"--batch-size {n} or less (in a run: --opt images=...)"
        )


def train_hbeo(
    config: HBEOConfig,
    path: Path,
    progress: bool = True,
    workers: int | None = None,
    log: Any = print,
    resume: bool = True,
    device: str = "cpu",
    cache_root: Path | None = None,
) -> HBEOModel:
    """Train (or, with ``resume``, resume training) the model ``config`` describes into the
    model directory ``path``, with torch and BLAS on ``TRAIN_THREADS`` threads (the caller's
    settings are restored afterwards). ``resume=False`` discards a checkpoint there first.
    ``device``: ``cpu`` (the default: deterministic, bitwise reproducible on the same kind of
    CPU), ``cuda`` or ``auto`` (CUDA when available); the model comes back on the CPU.

    ``path`` must be missing or a model directory this package wrote (checked before any
    work: :class:`CheckpointError` otherwise). A checkpoint that does not match its
    ``checkpoint.json`` or cannot be read as plain tensors raises :class:`CheckpointError`
    (it is never run as code); one for other settings is ignored and training starts over.
    ``cache_root``: the asset cache its BEO model, training crops and objects are kept in
    (None: the environment's)."""
    from threadpoolctl import threadpool_limits

    check_steps(config)  # before anything is rendered or trained
    path = Path(path)
    modeldir.check_replaceable(path, FILES, KINDS)
    if not resume and path.exists():
        for name in CHECKPOINT_FILES:  # the directory is ours (checked above)
            (path / name).unlink(missing_ok=True)
    threads = torch.get_num_threads()
    torch.set_num_threads(TRAIN_THREADS)
    try:
        with threadpool_limits(limits=TRAIN_THREADS):
            return _train(config, path, progress, workers, log, resolve_device(device), cache_root)
    finally:
        torch.set_num_threads(threads)


# -- checkpoints ----------------------------------------------------------------------------------
def _plain(config: HBEOConfig) -> Any:
    """``config`` as it reads back from JSON (tuples become lists), for comparisons."""
    return json.loads(json.dumps(config.to_json()))


def _write_sidecar(path: Path, config: HBEOConfig, subspace: str, **fields: Any) -> None:
    meta = {
        "kind": config.kind,
        "format": CHECKPOINT_FORMAT,
        "config": config.to_json(),
        "subspace": subspace,
        **fields,
    }
    atomic_write_bytes(path / "checkpoint.json", (json.dumps(meta, indent=1) + "\n").encode())


def _write_checkpoint(
    path: Path, config: HBEOConfig, subspace: str, state: dict[str, Any], history: list[Any]
) -> None:
    """One epoch's checkpoint. The tensors go to ``checkpoint.next.pt``, then
    ``checkpoint.json`` names its SHA-256, then it is renamed to ``checkpoint.pt``: a kill
    at any point leaves a ``checkpoint.json`` whose hash matches one of the two files."""
    buf = io.BytesIO()
    torch.save(state, buf)
    data = buf.getvalue()
    atomic_write_bytes(path / "checkpoint.next.pt", data)
    _write_sidecar(
        path,
        config,
        subspace,
        epoch=state["epoch"],
        history=history,
        sha256=hashlib.sha256(data).hexdigest(),
    )
    os.replace(path / "checkpoint.next.pt", path / "checkpoint.pt")


def _read_checkpoint(
    path: Path, config: HBEOConfig, subspace: str, log: Any
) -> tuple[dict[str, Any], list[Any]] | None:
    """The (tensor state, history) of the last finished epoch in ``path``, or None when
    there is no checkpoint for this config and subspace (training starts over). A damaged
    or altered checkpoint raises :class:`CheckpointError`; nothing in it is run as code."""
    again = f"delete {path}/checkpoint.* (or run `beo-bench train` without --resume) to start over"
    side = path / "checkpoint.json"
    if not side.exists():
        if (path / "checkpoint.pt").exists():
            old = path / "checkpoint.pt"
            log(f"ignoring {old}: no checkpoint.json beside it (an older version's); starting over")
        return None
    try:
        meta = json.loads(side.read_text())
        epoch, want = int(meta["epoch"]), meta["sha256"]
    except Exception as e:  # a damaged sidecar
        raise CheckpointError(f"{side} is damaged ({type(e).__name__}: {e}); {again}") from e
    if meta.get("format") != CHECKPOINT_FORMAT or meta.get("config") != _plain(config):
        log(f"the checkpoint in {path} is for other settings; training starts over")
        return None
    if meta.get("subspace") != subspace:
        log(f"the checkpoint in {path} is for another BEO subspace; training starts over")
        return None
    if epoch < 0:  # training had started, no epoch had finished
        return None
    files = [path / n for n in ("checkpoint.pt", "checkpoint.next.pt") if (path / n).exists()]
    if not files:  # deleted to start over (by hand, or `train` without --resume)
        log(f"no checkpoint.pt beside {side}; training starts over")
        return None
    for f in files:
        data = f.read_bytes()
        if hashlib.sha256(data).hexdigest() == want:
            break
    else:
        raise CheckpointError(
            f"{path}/checkpoint.pt does not match the SHA-256 in checkpoint.json (damaged or "
            f"replaced); {again}"
        )
    try:
        # weights_only: tensors and plain containers; a pickled object is refused, never run
        state = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
        ok = isinstance(state, dict) and state["epoch"] == epoch
        ok = ok and all(isinstance(state[k], dict) for k in ("net", "opt", "sched"))
    except Exception as e:
        raise CheckpointError(
            f"{path}/checkpoint.pt is unreadable as plain tensors ({type(e).__name__}: "
            f"{str(e).splitlines()[0] if str(e) else ''}); {again}"
        ) from e
    if not ok:
        raise CheckpointError(f"{path}/checkpoint.pt lacks net, opt, sched or epoch; {again}")
    return state, list(meta.get("history", []))


def resolve_device(device: str) -> torch.device:
    """``auto`` (CUDA when available, else the CPU), ``cpu`` or ``cuda``; a ``cuda`` asked
    for on a machine without one is a :class:`~beo_bench.errors.UsageError`."""
    from beo_bench.errors import UsageError

    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if device not in ("cpu", "cuda"):
        raise UsageError(f"device {device!r}: use auto, cpu or cuda")
    if device == "cuda" and not torch.cuda.is_available():
        raise UsageError(
            "device 'cuda' was asked for, but torch sees no CUDA GPU here; use --device cpu "
            "(or auto)"
        )
    return torch.device(device)


@dataclass
class _Data:
    """What training reads: the subspace model, the coefficient standardisation and the
    train and validation crops as tensors (on the CPU; batches go to the device)."""

    beo: BEOModel
    mean: np.ndarray
    std: np.ndarray
    train: _Tensors
    val: _Tensors | None


@dataclass
class _Run:
    """A training run's state between epochs: what a checkpoint stores and restores."""

    net: HBEONet
    opt: torch.optim.Optimizer
    sched: torch.optim.lr_scheduler.LRScheduler
    history: list[dict[str, float]] = field(default_factory=list)
    best: dict[str, Any] | None = None  # {"net", "epoch", "loss"} of the best validation epoch
    start: int = 0  # the first epoch still to train


def _load_data(
    config: HBEOConfig, beo: BEOModel, device: torch.device, cache_root: Path | None
) -> _Data:
    """The rendered dataset's splits as tensors, with subspace coefficients standardised by
    the training split's mean and spread."""
    train = load_split(config.dataset, config.dataset.split, cache_root)
    val = load_split(config.dataset, config.dataset.val_split, cache_root)
    objects = config.dataset.objects
    codes_tr = _coefficients(beo, train.keys, objects, cache_root)
    mean, std = codes_tr.mean(0), codes_tr.std(0) + 1e-3
    w = config.projection_weighting
    tr = _tensors(train, codes_tr, mean, std, w, device)
    va = (
        _tensors(val, _coefficients(beo, val.keys, objects, cache_root), mean, std, w, device)
        if len(val)
        else None
    )
    return _Data(beo, mean, std, tr, va)


def _new_run(config: HBEOConfig, data: _Data, device: torch.device) -> _Run:
    """A fresh network (initialised from ``config.seed``), its optimiser and schedule."""
    torch.manual_seed(config.seed)
    net = HBEONet(config.net(data.beo.k)).to(device)
    opt = torch.optim.AdamW(net.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    steps = config.epochs * -(-len(data.train) // config.batch_size)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=config.lr, total_steps=steps)
    return _Run(net, opt, sched)


def _resume(run: _Run, resumed: tuple[dict[str, Any], list[Any]], path: Path) -> None:
    """Restore ``run`` from a checkpoint read by :func:`_read_checkpoint`; training goes on
    after its epoch. :class:`CheckpointError` when it does not fit the network."""
    state, history = resumed
    try:
        run.net.load_state_dict(state["net"])
        run.opt.load_state_dict(state["opt"])
        run.sched.load_state_dict(state["sched"])
        run.best = state.get("best")
    except (RuntimeError, KeyError, ValueError, TypeError) as e:
        raise CheckpointError(
            f"{path}/checkpoint.pt does not fit this network ({e}); delete "
            f"{path}/checkpoint.* to start over"
        ) from e
    run.history = history
    run.start = int(state["epoch"]) + 1


def _train_epoch(
    run: _Run, data: _Data, config: HBEOConfig, epoch: int, progress: bool
) -> dict[str, float]:
    """Train ``run`` for one epoch, then score it on the validation split (keeping the best
    epoch's weights); returns the epoch's history row, also appended to ``run.history``.
    The shuffle is seeded by (seed, epoch), so a resumed run sees the same batches."""
    from tqdm import tqdm

    net, opt, sched, tr = run.net, run.opt, run.sched, data.train
    net.train()
    g = torch.Generator().manual_seed(config.seed * 1000 + epoch)
    order = torch.randperm(len(tr), generator=g)
    nb = len(tr) // config.batch_size  # drop the ragged last batch (BatchNorm)
    bar = tqdm(
        range(nb),
        desc=f"{config.kind} epoch {epoch + 1}/{config.epochs}",
        disable=None if progress else True,
    )
    loss_avg = 0.0
    for b in bar:
        x, tgt = tr.batch(order[b * config.batch_size : (b + 1) * config.batch_size])
        terms = losses(net(x), net.cfg, tgt)
        opt.zero_grad(set_to_none=True)
        terms["total"].backward()
        opt.step()
        sched.step()
        loss = float(terms["total"].detach())
        loss_avg = 0.9 * loss_avg + 0.1 * loss if b else loss
        bar.set_postfix(loss=f"{loss_avg:.3f}")
    row = {"epoch": epoch + 1, "train_loss": loss_avg}
    if data.val is not None:
        row.update({f"val_{k}": v for k, v in evaluate(net, data.val).items()})
        if run.best is None or row["val_total"] < float(run.best["loss"]):
            run.best = {"net": _cpu_state(net), "epoch": epoch + 1, "loss": row["val_total"]}
    run.history.append(row)
    return row


def _checkpoint(path: Path, config: HBEOConfig, subspace: str, run: _Run, epoch: int) -> None:
    """Store ``run`` after ``epoch`` (:func:`_write_checkpoint`), for the BEO subspace of
    fingerprint ``subspace``."""
    state = {
        "net": run.net.state_dict(),
        "opt": run.opt.state_dict(),
        "sched": run.sched.state_dict(),
        "epoch": epoch,
    }
    if run.best is not None:
        state["best"] = run.best
    _write_checkpoint(path, config, subspace, state, run.history)


def _epoch_line(row: dict[str, float]) -> str:
    line = f"epoch {row['epoch']}: train loss {row['train_loss']:.3f}"
    if "val_total" in row:
        line += (
            f", val loss {row['val_total']:.3f}, class acc {row['val_class_acc']:.1%}, "
            f"rotation median {row['val_rot_err_median']:.1f} deg"
        )
    return line


def _train(
    config: HBEOConfig,
    path: Path,
    progress: bool,
    workers: int | None,
    log: Any,
    device: torch.device,
    cache_root: Path | None,
) -> HBEOModel:
    """Load (render first, if needed) the data, resume from the checkpoint in ``path`` or
    start afresh, train the remaining epochs with a checkpoint after each, and save the
    model over the training directory."""
    from beo_bench.objects import cache

    t0 = time.perf_counter()
    beo = load_model(
        config.beo_model,
        config.categories,
        config.resolution,
        progress=progress,
        per_category=config.beo_instances,
        dataset=config.dataset.objects,
        cache_root=cache_root,
    )
    # the checkpoint is checked before the minutes of rendering: a bad one fails fast
    subspace = fingerprint(beo)
    resumed = _read_checkpoint(path, config, subspace, log)
    _, render_stats = render_dataset(config.dataset, workers, progress, cache_root)
    t_render = time.perf_counter() - t0
    data = _load_data(config, beo, device, cache_root)
    run = _new_run(config, data, device)
    cache.claim_for(path, cache_root)
    path.mkdir(parents=True, exist_ok=True)
    if resumed is not None:
        _resume(run, resumed, path)
        log(f"resuming {path.name} after epoch {run.start}/{config.epochs}")
    else:
        # before any checkpoint.pt exists, so the directory always shows whose it is
        _write_sidecar(path, config, subspace, epoch=-1, history=[], sha256=None)
    t_train = time.perf_counter()
    for epoch in range(run.start, config.epochs):
        row = _train_epoch(run, data, config, epoch, progress)
        _checkpoint(path, config, subspace, run, epoch)
        log(_epoch_line(row))  # logged after the checkpoint: an epoch reported done is on disk
    kept = len(run.history)
    net = run.net
    if config.select == "best-val" and run.best is not None:
        net.load_state_dict(run.best["net"])
        kept = int(run.best["epoch"])
        log(f"keeping epoch {kept} (lowest validation loss, {float(run.best['loss']):.3f})")
    net = net.cpu().eval()
    from beo_bench.objects import LIBRARY_VERSION

    model = HBEOModel(
        config=config,
        net=net,
        beo=beo,
        coef_mean=data.mean.astype(np.float32),
        coef_std=data.std.astype(np.float32),
        info={
            "library_version": LIBRARY_VERSION,
            "history": run.history,
            "epoch_kept": kept,
            "device": device.type,
            "train_images": len(data.train),
            "val_images": len(data.val) if data.val is not None else 0,
            "render_s": round(t_render, 1),
            "render_images_per_s": round(render_stats["images_per_s"], 1),
            "train_s": round(time.perf_counter() - t_train, 1),
            "total_s": round(time.perf_counter() - t0, 1),
        },
    )
    model.save(path, cache_root)  # replacing the training directory drops its checkpoint
    return model


def _cpu_state(net: HBEONet) -> dict[str, torch.Tensor]:
    """A copy of the network's weights on the CPU (the best epoch's, kept while training)."""
    return {k: v.detach().to("cpu", copy=True) for k, v in net.state_dict().items()}


def load_hbeo(
    name: str | None,
    kind: Kind,
    categories: tuple[str, ...],
    progress: bool = False,
    train_default: bool = True,
    size: str = "small",
    recipe: str = "default",
    dataset: Dataset | None = None,
    cache_root: Path | None = None,
    **small: int | None,
) -> HBEOModel:
    """The model called ``name`` (a plain name under :func:`models_root`; a path is refused
    with :class:`~beo_bench.errors.InvalidNameError`), or with ``name=None`` the default
    ``kind`` model of network ``size`` for ``categories``: the published reference model
    (:mod:`.published`) where there is one for these categories, otherwise the ``default``
    recipe's (made smaller by ``small``: :func:`default_config`'s ``instances``, ``images``,
    ``epochs``), trained on first use; or, with another ``recipe`` or ``train_default=False``,
    the trained one (:class:`CheckpointError` naming the ``beo-bench train`` command that
    makes it when there is none). On a user's ``dataset`` (None: the procedural library)
    the default model is the one ``beo-bench train ... --objects ROOT`` stored, never
    trained here. Models (and what a default one trains on) are kept in the asset cache
    ``cache_root`` (None: the environment's)."""
    from beo_bench.objects import LIBRARY_VERSION

    quick = any(v is not None for v in small.values())
    one = len(categories) == 1 and dataset is None and size == "small" and not quick
    if name is None and recipe == "per-category" and one:
        model = published_per_category(kind, categories[0])
        if model is not None:  # chapter 5's published network: nothing to train
            return model
    if name is None and recipe == "default" and not quick:
        if size == "small":
            model = published_for(kind, tuple(categories))
            if model is not None:  # the published reference model: nothing to train
                return model
        else:
            # the larger networks are the reference recipe's, trained once on a GPU and kept
            # in the cache (not published: too large for the repository); never trained here
            recipe = "reference"
    cfg = None
    if name is None:
        base = default_config(kind, categories, recipe=recipe, dataset=dataset, **small)
        cfg = with_overrides(base, size=size)
    path = model_path(default_name(cfg) if cfg is not None else str(name), cache_root)
    from beo_bench.objects.datasets import train_command

    if cfg is not None and not (path / "weights.pt").exists():
        if dataset is not None or not train_default or recipe != "default":
            big = size != "small"
            how = train_command(
                kind,
                categories,
                dataset,
                recipe=None if recipe == "default" else recipe,
                per_category=small.get("instances"),
                images=small.get("images"),
                epochs=small.get("epochs"),
                size=size if big else None,
                device="cuda" if big else None,
            )
            where = (
                f"no {kind} model for the dataset {dataset.root} (digest {dataset.short}, "
                f"classes {', '.join(categories)})"
                if dataset is not None
                else f"no {recipe} {kind} model for {', '.join(categories)}"
            )
            # training inside a run (minutes) is what a user must ask for
            raise CheckpointError(
                f"{where} at {path}: train it first with `{how}`"
                + (" (models for a dataset are never trained implicitly)" if dataset else "")
            )
        train_hbeo(cfg, path, progress=progress, cache_root=cache_root)
    model = HBEOModel.load(path)
    if model.config.kind != kind:
        raise CheckpointError(
            f"{path} holds a {model.config.kind} model; this backend needs {kind} "
            f"(train one with `beo-bench train {kind}`)"
        )
    if name is None:
        model.check_matches(tuple(categories), f"at {path}")
    else:
        # a named model answers a suite on some of its classes, as the published one does
        # (:func:`published_for`): its class scores are read at theirs
        model.check_covers(tuple(categories), f"at {path}")
    if model.info.get("library_version") != LIBRARY_VERSION:
        raise CheckpointError(
            f"the {kind} model at {path} was trained on object library version "
            f"{model.info.get('library_version')}, this is {LIBRARY_VERSION}; retrain it"
        )
    return model
