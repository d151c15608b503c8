"""``beo-bench publish``: write a trained model as a published one (compact, pickle-free,
digests in the manifest): what the backends load by default."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from beo_bench.cli.common import categories_of
from beo_bench.cli.options import (
    MODELS,
    categories_parent,
    model_name_parent,
    option_parent,
    out_parent,
)
from beo_bench.errors import UsageError
from beo_bench.perception import published
from beo_bench.training import library_categories


def add(sub: Any, help: str) -> None:
    pb = sub.add_parser(
        "publish",
        help=help,
        parents=[
            option_parent("model", choices=[*MODELS, "rest-prior", "class-means"]),
            model_name_parent("the trained model (beo: default model)"),
            categories_parent("classes or sets (beo default: library)"),
            out_parent(None, "default: the package's perception/published"),
        ],
    )
    pb.add_argument(
        "--storage",
        choices=published.STORAGE,
        default="float16",
        help="how the network's weights are stored (int8: per-channel scales, half float16's "
        "bytes; the per-category networks')",
    )


def run(args: argparse.Namespace) -> int:
    out = Path(args.out) if args.out else published.PUBLISHED_DIR
    # each model's modules are imported by its branch only: hbeo's import torch
    if args.model == "rest-prior":  # fitted here: a minute of the training split's scenes
        from beo_bench.perception.means import publish_rest_prior

        sha = publish_rest_prior(out, progress=True)
    elif args.model == "class-means":  # computed here: the 3,600 training instances' voxels
        from beo_bench.perception.means import publish_class_means

        sha = publish_class_means(out, progress=True)
    elif args.model == "beo":
        from beo_bench.perception.beo.model import BEOModel, model_dir, publish_beo

        cats = library_categories(categories_of(args))
        path = model_dir(args.name, cats, 32)
        sha = publish_beo(BEOModel.load(path), out)
    else:
        from beo_bench.perception.hbeo.model import (
            HBEOModel,
            default_config,
            default_name,
            is_per_category_default,
            model_path,
        )
        from beo_bench.perception.hbeo.publish import publish_hbeo

        name = args.name
        cats = tuple(args.categories or ())
        if name is None and len(cats) == 1 and cats[0] in published.PER_CATEGORY:
            # chapter 5's network of that class: the per-category recipe's default model
            name = default_name(default_config(args.model, cats, recipe="per-category"))
        if name is None:
            raise UsageError(
                f"publish {args.model} needs --name (the trained model's name), or "
                "--categories C for the per-category network of C "
                f"({', '.join(published.PER_CATEGORY)})"
            )
        model = HBEOModel.load(model_path(name))
        if model.config.kind != args.model:
            raise UsageError(f"{args.name!r} is a {model.config.kind} model, not {args.model}")
        one = len(model.categories) == 1 and is_per_category_default(model.config)
        sha = publish_hbeo(model, out, storage=args.storage, per_category=one)
    print(f"published {args.model} -> {out} (SHA-256 {sha})")
    for name, size, digest in published.files_table(out):
        print(f"  {name:<16} {size / 1e6:6.2f} MB  {digest}")
    return 0
