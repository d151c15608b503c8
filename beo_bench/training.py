"""What ``beo-bench train`` sets up: the class list and the training configuration of a
model, on the procedural library or on a user's dataset (the CLI parses the command line
into a :class:`TrainRequest`; this module turns it into the model's configuration).

A model for a dataset is trained on that dataset, passed explicitly: the BEO subspace an
HBEO network regresses is the dataset's (``beo-bench train beo --objects ROOT`` first).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from beo_bench.errors import UsageError

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset
    from beo_bench.perception.beo.model import BEOConfig
    from beo_bench.perception.hbeo.model import HBEOConfig, Kind


@dataclass(frozen=True)
class TrainRequest:
    """A ``train`` command's options (None: the model's default); the command's flags are
    declared by these fields (``beo_bench.argparsing.field_option``)."""

    dataset: Dataset | None = None
    """``--objects``: train on a user's dataset (None: the procedural library)."""
    split: str | None = None
    """``--split``: the dataset's split to train on (default ``train``)."""
    categories: tuple[str, ...] | None = None
    per_category: int | None = None
    # beo
    resolution: int = 32
    variance_fraction: float = 0.6
    # hbeo and hbeo-mdn
    images: int | None = None
    val_images: int | None = None
    epochs: int | None = None
    recipe: str = "default"
    """``--recipe``: default, reference or per-category (``hbeo.model.default_config``)."""
    seed: int | None = None
    crop: int | None = None
    size: str | None = None
    rotation: str | None = None
    batch_size: int | None = None
    projection_weighting: str | None = None
    sensor: str | None = None
    """``--sensor``: the depth sensor HBEO's noisy crops are captured by (None: the
    published recipe's ``DepthNoise`` augmentation; ``DatasetConfig.sensor``)."""

    @property
    def train_split(self) -> str:
        return self.split or "train"


def library_categories(categories: Sequence[str] | None) -> tuple[str, ...]:
    """The procedural classes to train on: ``categories`` (each must be registered) or
    every class of the library (the ``library`` set: what the isolated suites' views carry)."""
    from beo_bench.objects import categories as library
    from beo_bench.objects import get_category

    cats = tuple(categories) if categories else library()
    for c in cats:
        get_category(c)  # an unknown name raises, listing the known ones
    return cats


def dataset_categories(
    dataset: Dataset,
    split: str,
    categories: Sequence[str] | None = None,
    per_category: int | None = None,
) -> tuple[str, ...]:
    """The classes to train on a user's dataset: ``categories`` (each must be in it) or
    every class of the dataset (the class list its suites' views carry); each needs models
    in ``split``."""
    objects = dataset.objects(split, list(categories or dataset.categories()), per_category)
    empty = [c for c in objects.categories if objects.count(c) == 0]
    if empty or not objects.categories:
        raise UsageError(
            f"the {split!r} split of {dataset.root} has no models of "
            f"{', '.join(empty) or 'any class'}: use --split all (every model), or add files"
        )
    return objects.categories


def train_categories(req: TrainRequest) -> tuple[str, ...]:
    """The classes ``req`` trains on."""
    if req.dataset is None:
        return library_categories(req.categories)
    return dataset_categories(req.dataset, req.train_split, req.categories, req.per_category)


def beo_config(req: TrainRequest) -> BEOConfig:
    """The BEO model ``req`` describes."""
    from beo_bench.perception.beo.model import BEOConfig

    return BEOConfig(
        categories=train_categories(req),
        resolution=req.resolution,
        per_category=req.per_category,
        variance_fraction=req.variance_fraction,
    )


def hbeo_config(req: TrainRequest, kind: Kind) -> HBEOConfig:
    """The HBEO (or HBEO-MDN) training set-up ``req`` describes; on a dataset, rendered from
    it, its BEO subspace the dataset's."""
    from beo_bench.perception.hbeo.model import default_config, with_overrides

    split = req.train_split
    cats = train_categories(req)
    # a folder too small for a hash split validates on what it trains on (--split all)
    splits: dict[str, Any] = {}
    if req.dataset is not None:
        splits = {"split": split, "val_split": "val" if split == "train" else split}
    base = default_config(
        kind,
        cats,
        instances=req.per_category,
        images=req.images,
        epochs=req.epochs,
        recipe=req.recipe,
        dataset=req.dataset,
    )
    return with_overrides(
        base,
        val_images=req.val_images,
        seed=req.seed,
        crop=req.crop,
        size=req.size,
        rotation=req.rotation,
        batch_size=req.batch_size,
        projection_weighting=req.projection_weighting,
        sensor=req.sensor,
        **splits,
    )
