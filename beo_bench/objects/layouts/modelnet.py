"""ModelNet10 / ModelNet40: ``<root>/<class>/{train,test}/<name>.off``.

Classes map to category names through the registry (``modelnet_names``, e.g. ModelNet
``cup`` is our ``mug``), else keep the class folder's name. ModelNet is +z up, as we are;
its front direction is not consistent within a class, so its axes are kept as they are.
Its units are arbitrary (default units ``normalised``). Splits: ``test`` is ModelNet's test
folder; its train folder is split by a hash of the file name into ``val``
(:data:`MODELNET_VAL_SHARE`) and ``train``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from beo_bench.objects.dataset_load import Entry, LoadOptions, unit_hash
from beo_bench.objects.registry import categories as registered_categories
from beo_bench.objects.registry import get_category
from beo_bench.objects.walk import valid_name
from beo_bench.types import Mat3

MODELNET_VAL_SHARE = 0.10
"""Share of ModelNet's train folder that becomes our ``val`` split."""

FOLDERS = ("train", "test")
"""ModelNet's split folders in each class folder."""


def modelnet_split(folder: str, name: str) -> str:
    """Our split of the file ``name`` (its stem) in ModelNet's ``folder`` (train or test)."""
    if folder == "test":
        return "test"
    return "val" if unit_hash(name) < MODELNET_VAL_SHARE else "train"


class ModelNetLayout:
    """The ModelNet10/40 layout (:data:`MODELNET`)."""

    name = "modelnet"
    title = "ModelNet10/40"
    pattern = "<root>/<class>/{train,test}/<name>.off"
    root_env = "BEO_BENCH_MODELNET"
    default_units = "normalised"
    axes_option = False
    key_form = "modelnet/<class>/<train|test>/<name>"

    def holds_models(self, folder: Path) -> bool:
        """A class folder with an OFF file in its train or test folder."""
        return any(next((folder / s).glob("*.off"), None) is not None for s in FOLDERS)

    def category_name(self, dirname: str) -> str:
        for c in registered_categories():
            if dirname in get_category(c).modelnet_names:
                return c
        return dirname

    def entries(self, root: Path, dirname: str) -> list[Entry]:
        cat = self.category_name(dirname)
        return [
            Entry(f"{dirname}/{folder}/{f.stem}", cat, modelnet_split(folder, f.stem), f)
            for folder in FOLDERS
            for f in sorted((root / dirname / folder).glob("*.off"))
            if valid_name(f)
        ]

    def key_ok(self, parts: Sequence[str]) -> bool:
        return len(parts) == 3 and parts[1] in FOLDERS

    def rotation(self, opts: LoadOptions) -> Mat3:
        return np.eye(3)

    def __repr__(self) -> str:
        return "MODELNET"


MODELNET = ModelNetLayout()
