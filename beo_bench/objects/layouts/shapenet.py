"""ShapeNetCore v2: ``<root>/<8-digit synset>/<model id>/models/model_normalized.obj``.

Synsets map to category names through the registry (``shapenet_synsets``), else
:data:`SHAPENET_SYNSETS`, else the synset id itself. Models are +y up, -z front
(:data:`SHAPENET_TO_CANONICAL`) and normalised to a unit diagonal (default units
``normalised``). Splits: a stable hash of ``<synset>/<model id>``.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from beo_bench.objects.dataset_load import Entry, LoadOptions, hash_split, subdirs
from beo_bench.objects.registry import categories as registered_categories
from beo_bench.objects.registry import get_category
from beo_bench.types import Mat3

# ShapeNetCore v2 README (shapenet.org download page, mirrored e.g. at
# https://www.graviti.cn/open-datasets/ShapeNet): "The OBJ files are now pre-aligned so that
# the up direction is the +Y axis, and the front is the -Z axis (this fixes the mirroring
# issue in ShapeNetCore v1)". Our canonical frame is +z up, +x front, so the rotation maps
# +y -> +z and -z -> +x (hence +z -> -x and, right-handed, +x -> -y): (x, y, z) -> (-z, -x, y).
SHAPENET_TO_CANONICAL: Mat3 = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


# The 55 ShapeNetCore v2 synsets (WordNet 3.0 offsets) with short snake_case names, used
# when no registered category claims a synset through ``shapenet_synsets``.
SHAPENET_SYNSETS: dict[str, str] = {
    "02691156": "airplane",
    "02747177": "trash_bin",
    "02773838": "bag",
    "02801938": "basket",
    "02808440": "bathtub",
    "02818832": "bed",
    "02828884": "bench",
    "02834778": "bicycle",
    "02843684": "birdhouse",
    "02871439": "bookshelf",
    "02876657": "bottle",
    "02880940": "bowl",
    "02924116": "bus",
    "02933112": "cabinet",
    "02942699": "camera",
    "02946921": "can",
    "02954340": "cap",
    "02958343": "car",
    "02992529": "cellphone",
    "03001627": "chair",
    "03046257": "clock",
    "03085013": "keyboard",
    "03207941": "dishwasher",
    "03211117": "display",
    "03261776": "earphone",
    "03325088": "faucet",
    "03337140": "file_cabinet",
    "03467517": "guitar",
    "03513137": "helmet",
    "03593526": "jar",
    "03624134": "knife",
    "03636649": "lamp",
    "03642806": "laptop",
    "03691459": "loudspeaker",
    "03710193": "mailbox",
    "03759954": "microphone",
    "03761084": "microwave",
    "03790512": "motorcycle",
    "03797390": "mug",
    "03928116": "piano",
    "03938244": "pillow",
    "03948459": "pistol",
    "03991062": "pot",
    "04004475": "printer",
    "04074963": "remote_control",
    "04090263": "rifle",
    "04099429": "rocket",
    "04225987": "skateboard",
    "04256520": "sofa",
    "04330267": "stove",
    "04379243": "table",
    "04401088": "telephone",
    "04460130": "tower",
    "04468005": "train",
    "04530566": "vessel",
    "04554684": "washer",
}


_SYNSET_RE = re.compile(r"^\d{8}$")

MODEL_FILE = Path("models") / "model_normalized.obj"
"""Where a model's mesh is, relative to its folder ``<root>/<synset>/<model id>``."""


class ShapeNetLayout:
    """The ShapeNetCore v2 layout (:data:`SHAPENET`)."""

    name = "shapenet"
    title = "ShapeNetCore v2"
    pattern = "<root>/<8-digit synset>/<model id>/models/model_normalized.obj"
    root_env = "BEO_BENCH_SHAPENET"
    default_units = "normalised"
    axes_option = False
    key_form = "shapenet/<8-digit synset>/<model id>"

    def holds_models(self, folder: Path) -> bool:
        """A synset folder with a model among its first 20 entries."""
        return bool(_SYNSET_RE.match(folder.name)) and any(
            (folder / m / MODEL_FILE).is_file() for m in subdirs(folder)[:20]
        )

    def category_name(self, dirname: str) -> str:
        for c in registered_categories():
            if dirname in get_category(c).shapenet_synsets:
                return c
        return SHAPENET_SYNSETS.get(dirname, dirname)

    def entries(self, root: Path, dirname: str) -> list[Entry]:
        cat = self.category_name(dirname)
        out = []
        for m in subdirs(root / dirname):
            ident = f"{dirname}/{m}"
            out.append(Entry(ident, cat, hash_split(ident), root / dirname / m / MODEL_FILE))
        return out

    def key_ok(self, parts: Sequence[str]) -> bool:
        return len(parts) == 2 and bool(_SYNSET_RE.match(parts[0]))

    def rotation(self, opts: LoadOptions) -> Mat3:
        return SHAPENET_TO_CANONICAL

    def __repr__(self) -> str:
        return "SHAPENET"


SHAPENET = ShapeNetLayout()
