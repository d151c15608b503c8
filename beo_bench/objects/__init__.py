"""The object library: ShapeNet-style procedural categories; a user's dataset is opened by
:func:`beo_bench.objects.datasets.open_dataset`.

Canonical frame of every instance: +z up, +x front, origin at the bounding-box centre
(objects are *centred*, not resting on z = 0), real size in metres.
"""

from __future__ import annotations

import importlib

from beo_bench.objects.datasets import instance_from_key
from beo_bench.objects.instance import ObjectInstance
from beo_bench.objects.objectset import ObjectSet
from beo_bench.objects.registry import (
    DEFAULT_SPLIT_SIZES,
    LIBRARY_VERSION,
    SPLITS,
    CategorySpec,
    categories,
    get_category,
    pickable_categories,
    register_category,
)

# One module per category; importing registers it.
CATEGORY_MODULES = (
    "airplane",
    "bathtub",
    "bed",
    "bottle",
    "bowl",
    "box",
    "can",
    "car",
    "chair",
    "desk",
    "dresser",
    "lamp",
    "monitor",
    "mug",
    "night_stand",
    "sofa",
    "table",
    "toilet",
)
for _m in CATEGORY_MODULES:
    importlib.import_module(f"beo_bench.objects.{_m}")


__all__ = [
    "DEFAULT_SPLIT_SIZES",
    "LIBRARY_VERSION",
    "SPLITS",
    "CategorySpec",
    "ObjectInstance",
    "ObjectSet",
    "categories",
    "get_category",
    "instance_from_key",
    "pickable_categories",
    "register_category",
]
