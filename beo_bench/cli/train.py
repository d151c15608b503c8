"""``beo-bench train``: train a perception model (beo, hbeo, hbeo-mdn) and store it under
its name. The options that configure the model are :class:`~beo_bench.training.TrainRequest`'s
fields (:func:`~beo_bench.argparsing.field_option`), and go back into one by name."""

from __future__ import annotations

import argparse
import time
from typing import TYPE_CHECKING, Any

from beo_bench import training
from beo_bench.argparsing import (
    field_option,
    fraction,
    from_namespace,
    positive_int,
    resolution_int,
)
from beo_bench.cli.common import categories_of, dataset_of, split_needs_dataset
from beo_bench.cli.options import (
    MODELS,
    RENDER_GROUP,
    SPLITS_ALL,
    categories_parent,
    dataset_parent,
    model_name_parent,
    option_parent,
    per_category_parent,
    render_parents,
    split_parent,
)
from beo_bench.errors import UsageError
from beo_bench.training import TrainRequest

if TYPE_CHECKING:
    from beo_bench.perception.hbeo.model import HBEOConfig, Kind


def add(sub: Any, help: str) -> None:
    tr = sub.add_parser(
        "train",
        help=help,
        parents=[
            dataset_parent(("--object-size",)),
            option_parent("model", choices=MODELS),
            split_parent(
                SPLITS_ALL,
                None,
                "with --objects: the dataset's split to train on (default train; all: every "
                "model, for folders too small for a hash split, which then also validates on it)",
            ),
            categories_parent(
                "classes or sets (modelnet10, shapenet-ch5, library; default: library)"
            ),
            model_name_parent("model name, a plain name (default: the default model's name)"),
            per_category_parent(
                None,
                "train instances per class (hbeo: for the crops and the default BEO subspace)",
            ),
            *render_parents(RENDER_GROUP),
        ],
    )
    tb = tr.add_argument_group("beo")
    field_option(tb, TrainRequest, "resolution", type=resolution_int, help="voxels per edge (D)")
    field_option(tb, TrainRequest, "variance_fraction", type=fraction, help="in (0, 1]")
    th = tr.add_argument_group("hbeo and hbeo-mdn (defaults: the default small model's)")
    field_option(th, TrainRequest, "epochs", type=positive_int)
    field_option(th, TrainRequest, "batch_size", type=positive_int)
    field_option(th, TrainRequest, "size", choices=["small", "dissertation"])
    field_option(th, TrainRequest, "rotation", choices=["axis-angle", "6d"], help="hbeo only")
    field_option(
        th,
        TrainRequest,
        "recipe",
        choices=["default", "reference", "per-category"],
        help="default: 16k crops x 15 epochs (minutes on CPU); reference: 100k x 20, best "
        "validation epoch (the published models); per-category: one class's network, 30k x "
        "20 (with --categories C, for hbeo's per_category option)",
    )
    # how to train, not what: train_hbeo's arguments, no field of the request
    th.add_argument(
        "--device",
        choices=["auto", "cpu", "cuda"],
        default="cpu",
        help="where to train (auto: CUDA when available); cpu is bitwise reproducible",
    )
    field_option(
        th,
        TrainRequest,
        "projection_weighting",
        choices=["uniform", "variance"],
        help="eq. 4.3's projection term: uniform (dissertation) or variance-weighted",
    )
    field_option(th, TrainRequest, "crop", type=positive_int, help="crop side in pixels (64)")
    th.add_argument(
        "--resume",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="continue from the last finished epoch of a killed run (default)",
    )


def train_request(args: argparse.Namespace) -> TrainRequest:
    """The ``train`` (or ``render-dataset``) command's options as a :class:`TrainRequest`
    (a field the command has no option of keeps its default)."""
    dataset = dataset_of(args)
    split_needs_dataset(args, dataset)
    return from_namespace(TrainRequest, args, dataset=dataset, categories=categories_of(args))


def hbeo_config(args: argparse.Namespace, kind: Kind) -> HBEOConfig:
    """The HBEO training set-up the options describe (:func:`beo_bench.training.hbeo_config`)."""
    return training.hbeo_config(train_request(args), kind)


def run(args: argparse.Namespace) -> int:
    """Train a model and store it under its name (the default name is the one the backend
    looks for, so training it ahead of time only saves the first run the wait)."""
    if args.model != "beo":
        return _train_hbeo(args)
    if args.sensor is not None:
        raise UsageError(
            "--sensor applies to hbeo and hbeo-mdn (the depth sensor their training crops "
            "are captured by); beo trains on voxels, nothing is rendered"
        )
    # each model's module is imported by its branch only: hbeo's imports torch
    from beo_bench.perception.beo.model import default_name, model_path, train_beo

    req = train_request(args)
    cfg = training.beo_config(req)
    cats = cfg.categories
    name = args.name or default_name(cats, args.resolution, args.per_category, req.dataset)
    t0 = time.perf_counter()
    model = train_beo(cfg, progress=True, dataset=req.dataset, split=req.train_split)
    path = model.save(model_path(name))
    print(
        f"BEO model {name!r}: {len(cats)} classes at {args.resolution}^3, subspace k={model.k} "
        f"(per class {dict(zip(cats, model.components.tolist(), strict=True))}), "
        f"trained in {time.perf_counter() - t0:.1f} s -> {path}"
    )
    return 0


def _train_hbeo(args: argparse.Namespace) -> int:
    from beo_bench.perception.hbeo.model import default_name, model_path
    from beo_bench.perception.hbeo.train import train_hbeo

    cfg = hbeo_config(args, args.model)
    name = args.name or default_name(cfg)
    path = model_path(name)
    t0 = time.perf_counter()
    model = train_hbeo(
        cfg, path, progress=True, workers=args.workers, resume=args.resume, device=args.device
    )
    last = model.info["history"][model.info["epoch_kept"] - 1]
    speed = model.info["render_images_per_s"]
    rendered = f"rendered at {speed:.0f} images/s" if speed else "rendering cached"
    print(
        f"{args.model} model {name!r}: {model.info['train_images']} crops ({rendered}), "
        f"{len(model.info['history'])} epochs in {time.perf_counter() - t0:.1f} s "
        f"(kept epoch {model.info['epoch_kept']}, on {model.info['device']}); "
        f"validation: class accuracy {last.get('val_class_acc', float('nan')):.1%}, "
        f"rotation median {last.get('val_rot_err_median', float('nan')):.1f} deg -> {path}"
    )
    return 0
