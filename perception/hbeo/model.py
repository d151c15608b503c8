"""An HBEO / HBEO-MDN model (dissertation chapters 4 and 5): its configuration and recipes,
the trained network with its BEO subspace and standardisation, where models live and the
published ones (``beo-bench train`` writes them: :mod:`beo_bench.perception.hbeo.train`)."""

from __future__ import annotations

import functools
import hashlib
import json
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import torch

from beo_bench.atomic import atomic_dir
from beo_bench.errors import CheckpointError
from beo_bench.names import inside
from beo_bench.perception import modeldir
from beo_bench.perception.beo.model import BEOModel, load_model, published_model
from beo_bench.perception.digest import state_digest
from beo_bench.perception.hbeo.data import DatasetConfig
from beo_bench.perception.hbeo.net import (
    HBEONet,
    NetConfig,
)

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset

Kind = Literal["hbeo", "hbeo-mdn"]
KINDS: tuple[str, ...] = ("hbeo", "hbeo-mdn")
FORMAT_VERSION = 1
CHECKPOINT_FORMAT = 2
"""Format 1 was one pickled file; 2 keeps everything but tensors in ``checkpoint.json``."""
CHECKPOINT_FILES = ("checkpoint.pt", "checkpoint.next.pt", "checkpoint.json")
FILES = frozenset({"config.json", "weights.pt", *CHECKPOINT_FILES})
"""Everything an HBEO model directory holds (the checkpoint files while it trains)."""


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
    select: str = "last"
    """Which epoch's weights the model keeps: ``last`` or ``best-val`` (the epoch with the
    lowest validation loss; the MDN's validation likelihood gets worse after about epoch 12
    of 20 on the reference recipe's crops)."""
    projection_weighting: str = "uniform"
    """The projection term of eq. 4.3: ``uniform`` (the dissertation's L2 on the
    coefficients) or ``variance`` (each coefficient's squared error weighted by its share of
    the subspace's variance: an ablation)."""

    def __post_init__(self) -> None:
        if self.kind not in ("hbeo", "hbeo-mdn"):
            raise ValueError(f"kind={self.kind!r}: use 'hbeo' or 'hbeo-mdn'")
        if self.rotation not in ("axis-angle", "6d"):
            raise ValueError(f"rotation={self.rotation!r}: use 'axis-angle' or '6d'")
        if self.select not in ("last", "best-val"):
            raise ValueError(f"select={self.select!r}: use 'last' or 'best-val'")
        if self.projection_weighting not in ("uniform", "variance"):
            raise ValueError(
                f"projection_weighting={self.projection_weighting!r}: use 'uniform' or 'variance'"
            )
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
        out = asdict(self)
        if self.dataset.objects is None:  # library models keep the config they had
            del out["dataset"]["objects"]
        if self.dataset.sensor is None:  # so do models of the published recipe
            del out["dataset"]["sensor"]
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> HBEOConfig:
        from beo_bench.objects.datasets import Dataset

        ds = dict(d["dataset"])
        ds["categories"] = tuple(ds["categories"])
        if ds.get("objects") is not None:
            ds["objects"] = Dataset(**ds["objects"])
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

    def stored_meta(self) -> dict[str, Any]:
        """What ``config.json`` holds (:meth:`save`; the published copy's JSON too)."""
        return {
            "kind": self.config.kind,
            "format": FORMAT_VERSION,
            "config": self.config.to_json(),
            "subspace": fingerprint(self.beo),
            "k": self.beo.k,
            "digest": state_digest(self.state()),
            "info": self.info,
        }

    def state(self) -> dict[str, Any]:
        """What ``weights.pt`` holds: tensors only."""
        return {
            "net": self.net.state_dict(),
            "coef_mean": torch.from_numpy(self.coef_mean),
            "coef_std": torch.from_numpy(self.coef_std),
        }

    def save(self, path: Path, cache_root: Path | None = None) -> Path:
        """Write the model to the directory ``path`` atomically (a temporary sibling renamed
        into place). An existing ``path`` is replaced only when it is an HBEO model (or a
        training of one) this package wrote: :class:`CheckpointError` otherwise, leaving it
        untouched. Replacing a training directory removes its checkpoint."""
        from beo_bench.objects import cache

        path = Path(path)
        modeldir.check_replaceable(path, FILES, KINDS)  # fail before writing anything
        cache.claim_for(path, cache_root)  # tags the asset cache it lies in (None: the env's)
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_dir(path, lambda tmp, to: modeldir.install(tmp, to, FILES, KINDS)) as tmp:
            state = self.state()
            with open(tmp / "weights.pt", "wb") as f:
                torch.save(state, f)
            meta = self.stored_meta()
            (tmp / "config.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
        return path

    @classmethod
    def load(cls, path: Path, beo: BEOModel | None = None) -> HBEOModel:
        """Read a model directory written by :meth:`save`; :class:`CheckpointError` for a
        missing, torn, empty, damaged or mismatched one, saying how to get a good one."""
        path = Path(path)
        if not (path / "config.json").exists() or not (path / "weights.pt").exists():
            raise CheckpointError(
                f"no HBEO model at {path}: train one with `beo-bench train hbeo` (or "
                "`hbeo-mdn`), or leave the model option unset for the default"
            )
        retrain = (
            f"delete {path} and train it again with `beo-bench train hbeo|hbeo-mdn --name "
            f"{path.name}` (a run retrains a default model by itself)"
        )
        try:
            meta = json.loads((path / "config.json").read_text())
            cfg = HBEOConfig.from_json(meta["config"])
        except Exception as e:  # JSON, missing or unknown fields, bad values
            raise CheckpointError(
                f"the HBEO model at {path} has an unreadable config.json "
                f"({type(e).__name__}: {e}); {retrain}"
            ) from e
        if meta.get("format") != FORMAT_VERSION:
            raise CheckpointError(
                f"{path} holds format {meta.get('format')}, this version reads "
                f"{FORMAT_VERSION}; retrain with `beo-bench train {cfg.kind}`"
            )
        if meta.get("kind") != cfg.kind:
            raise CheckpointError(
                f"{path}/config.json names kind {meta.get('kind')!r} but holds a {cfg.kind} "
                f"configuration; {retrain}"
            )
        try:
            state = torch.load(path / "weights.pt", map_location="cpu", weights_only=True)
        except Exception as e:  # empty, truncated, garbage or non-tensor (pickled code) data
            raise CheckpointError(
                f"the {cfg.kind} model at {path} has unreadable weights "
                f"({type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}); {retrain}"
            ) from e
        return cls.from_stored(meta, cfg, state, str(path), retrain, beo)

    @classmethod
    def from_stored(
        cls,
        meta: dict[str, Any],
        cfg: HBEOConfig,
        state: Any,
        where: str,
        retrain: str,
        beo: BEOModel | None = None,
    ) -> HBEOModel:
        """The model from its ``config.json`` contents, config and tensor state, checked
        (layout, values, digest, subspace); :class:`CheckpointError` naming ``where``."""
        path = where
        problem = _state_problem(state, meta)
        if problem is not None:
            raise CheckpointError(
                f"the {cfg.kind} model at {path} is damaged ({problem}); {retrain}"
            )
        if beo is None:
            beo = load_model(
                cfg.beo_model,
                cfg.categories,
                cfg.resolution,
                per_category=cfg.beo_instances,
                dataset=cfg.dataset.objects,
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
            raise CheckpointError(f"{path}: weights do not fit the network ({e}); {retrain}") from e
        if tuple(state["coef_mean"].shape) != (beo.k,) or state["coef_std"].shape != (beo.k,):
            raise CheckpointError(f"{path}: the coefficient standardisation is not ({beo.k},)")
        net.eval()
        return cls(
            config=cfg,
            net=net,
            beo=beo,
            coef_mean=state["coef_mean"].numpy(),
            coef_std=state["coef_std"].numpy(),
            info=meta.get("info", {}),
        )

    def check_covers(self, categories: tuple[str, ...], where: str) -> None:
        """Raise :class:`CheckpointError` unless trained for at least these categories."""
        missing = [c for c in categories if c not in self.categories]
        if missing:
            raise CheckpointError(
                f"the {self.config.kind} model {where} was trained for categories "
                f"{list(self.categories)}, not {missing}; train one with `beo-bench train "
                f"{self.config.kind} --name NAME --categories {' '.join(categories)}` and pass "
                "`--opt model=NAME`"
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


def _state_problem(state: Any, meta: dict[str, Any]) -> str | None:
    """What is wrong with the contents of ``weights.pt`` (layout, values, digest), or None."""
    if not isinstance(state, dict) or not {"net", "coef_mean", "coef_std"} <= set(state):
        return "weights.pt does not hold net, coef_mean and coef_std"
    if not isinstance(state["net"], dict) or not all(
        isinstance(v, torch.Tensor) for v in state["net"].values()
    ):
        return "the network's weights are not tensors"
    for name in ("coef_mean", "coef_std"):
        t = state[name]
        if not isinstance(t, torch.Tensor) or t.ndim != 1 or not bool(torch.isfinite(t).all()):
            return f"{name} is not a finite vector"
    # models written before the digest was stored have none
    if "digest" in meta and meta["digest"] != state_digest(state):
        return "the weights do not match the digest in config.json"
    return None


def models_root(cache_root: Path | None = None) -> Path:
    """Where named HBEO and HBEO-MDN models live: ``<asset cache>/models/hbeo``, in the
    run's asset cache (``PrepareContext.cache_root``; None: the environment's)."""
    from beo_bench.objects import cache

    return cache.resolve_root(cache_root) / "models" / "hbeo"


def model_path(name: str, cache_root: Path | None = None) -> Path:
    """The directory of the HBEO / HBEO-MDN model called ``name``: a plain name under
    :func:`models_root` (:class:`~beo_bench.errors.InvalidNameError` for a path, ``..``
    or a leading dot)."""
    return inside(models_root(cache_root), name, "HBEO model name")


RECIPES: dict[str, dict[str, Any]] = {
    "default": {},
    "reference": {"images": 100_000, "val_images": 10_000, "epochs": 20, "select": "best-val"},
    "per-category": {"images": 30_000, "val_images": 6_000, "epochs": 20, "select": "best-val"},
}
"""Training recipes. ``default``: 16,000 crops, 15 epochs, the last epoch's weights (a couple of
minutes on 2 CPU cores; what tests and quick checks shrink further). ``reference``: 100,000
crops, 20 epochs, the best validation epoch's weights: the published models (``beo-bench train
hbeo|hbeo-mdn --recipe reference`` reproduces them; their epochs took 39.5 and 22.8 minutes on 2
CPU cores at 18 classes, plus rendering the crops once). Why: the small network on 16,000 crops
gives 23.9 deg mean on ``pose-3dof``, the reference one 13.0 deg; the method needs the data.
``per-category``: one class's network (chapter 5 trained one per category; ``--categories
car``), 30,000 crops of it (nearly three times the class's share of the reference set), 20
epochs, the best validation epoch: 5 (``hbeo``) to 7 (``hbeo-mdn``) minutes a class on 2 CPU
cores, plus 2 minutes of rendering."""


def default_config(
    kind: Kind,
    categories: tuple[str, ...],
    instances: int | None = None,
    images: int | None = None,
    epochs: int | None = None,
    recipe: str = "default",
    dataset: Dataset | None = None,
) -> HBEOConfig:
    """The ``recipe`` model of ``kind`` for ``categories`` (:data:`RECIPES`); ``instances``
    per class (for the subspace and the crops), ``images`` (training crops; a fifth as many
    validation crops) and ``epochs`` shrink it for quick checks. ``dataset``: a user's
    dataset (``train --objects``, a run's), whose objects the crops and the BEO subspace
    come from (None: the procedural library)."""
    if recipe not in RECIPES:
        raise ValueError(f"recipe {recipe!r}: use one of {sorted(RECIPES)}")
    cfg = HBEOConfig(
        kind=kind, dataset=DatasetConfig(categories=tuple(categories), objects=dataset)
    )
    cfg = with_overrides(cfg, **RECIPES[recipe])
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
    from beo_bench.perception.hbeo.data import DATA_VERSION

    cfg = config.to_json()
    if config.dataset.objects is not None:
        # a dataset's model is named by what the data is, not where it lies, nor which of
        # its splits it was trained on (as BEO's): the backend looks it up by class list
        cfg["dataset"]["objects"] = config.dataset.objects.identity()
        for k in ("split", "val_split"):
            del cfg["dataset"][k]
    key = json.dumps([cfg, LIBRARY_VERSION, FORMAT_VERSION, DATA_VERSION], sort_keys=True)
    return f"default-{config.kind}-{hashlib.sha256(key.encode()).hexdigest()[:10]}"


def published_hbeo(kind: str) -> HBEOModel | None:
    """The published ``kind`` model (:mod:`.published`), read and checked once per version
    of the published files; None when none is published. :class:`CheckpointError` for an
    altered or unreadable file."""
    from beo_bench.perception import published

    files = published.manifest()
    if f"{kind}.npz" not in files:
        return None
    return _read_published(kind, published.PUBLISHED_DIR, tuple(sorted(files.items())))


@functools.cache
def _read_published(kind: str, root: Path, files: tuple[tuple[str, str], ...]) -> HBEOModel:
    """The published ``kind`` model under ``root``, regressing the published BEO subspace;
    ``files`` (the manifest: name, SHA-256) is part of the cache key, so publishing anew
    (:func:`.published.write`) reads it again."""
    from beo_bench.perception import published

    meta, arrays = published.read(kind, root)
    try:
        cfg = HBEOConfig.from_json(meta["config"])
    except Exception as e:
        raise CheckpointError(f"the published {kind} model's config is unreadable ({e})") from e
    want = kind.removesuffix(f"-{cfg.categories[0]}") if len(cfg.categories) == 1 else kind
    if cfg.kind != want or meta.get("kind") != cfg.kind:
        raise CheckpointError(
            f"the published {kind}.json holds a {cfg.kind} model; {published._restore(kind)}"
        )
    state = published._state(arrays)
    one = len(cfg.categories) == 1 and kind != cfg.kind  # a per-category network
    beo = published_model(published.per_category_stem("beo", cfg.categories[0]) if one else "beo")
    if beo is None:
        raise CheckpointError(
            f"the published {kind} model's subspace is not published; " + published._restore(kind)
        )
    where = f"{root}/{kind}"
    return HBEOModel.from_stored(meta, cfg, state, where, published._restore(kind), beo)


def published_for(kind: str, categories: tuple[str, ...]) -> HBEOModel | None:
    """The published ``kind`` model when it was trained for ``categories`` or a superset of
    them (a suite on some of the classes is answered by the network that knows them all, its
    class scores restricted to them), else None."""
    from beo_bench.objects import LIBRARY_VERSION

    model = published_hbeo(kind)
    if model is None or not set(categories) <= set(model.categories):
        return None
    if model.info.get("library_version") != LIBRARY_VERSION:
        return None
    return model


def is_per_category_default(config: HBEOConfig) -> bool:
    """Whether ``config`` is the ``per-category`` recipe's small network for its one class
    (on the procedural library): what ``per_category=true`` loads by default."""
    cats = config.dataset.categories
    if len(cats) != 1 or config.dataset.objects is not None or config.size != "small":
        return False
    want = default_config(config.kind, tuple(cats), recipe="per-category")
    return default_name(config) == default_name(want)


def published_per_category(kind: str, category: str) -> HBEOModel | None:
    """The published one-class ``kind`` network for ``category`` (chapter 5's Tables
    5.1/5.2), when there is one for this recipe and library version, else None."""
    from beo_bench.objects import LIBRARY_VERSION
    from beo_bench.perception import published

    stem = published.per_category_stem(kind, category)
    files = published.manifest()
    if f"{stem}.npz" not in files:
        return None
    model = _read_published(stem, published.PUBLISHED_DIR, tuple(sorted(files.items())))
    if not is_per_category_default(model.config) or model.categories != (category,):
        return None
    if model.info.get("library_version") != LIBRARY_VERSION:
        return None
    return model


def with_overrides(config: HBEOConfig, **kw: Any) -> HBEOConfig:
    """``config`` with dataset fields (``images``, ``val_images``, ``seed`` ...) and training
    fields replaced by the non-None values in ``kw``."""
    ds_fields = set(DatasetConfig.__dataclass_fields__) - {"categories"}
    ds = {k: v for k, v in kw.items() if k in ds_fields and v is not None}
    # the seed seeds both the rendering and the training
    tr = {k: v for k, v in kw.items() if (k not in ds_fields or k == "seed") and v is not None}
    return replace(config, dataset=replace(config.dataset, **ds), **tr)
