"""The ModelNet10 classes of the library: every one registered under its ModelNet folder
name, the geometric symmetry estimator finds the group each declares, the classes that
ModelNet10 confuses overlap in size, and docs/objects.md shows them all."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from beo_bench.objects import ObjectSet, categories, get_category
from beo_bench.objects.sets import MODELNET10
from beo_bench.objects.symmetry import analyse_symmetry, symmetry_name

DOCS = Path(__file__).resolve().parents[2] / "docs"


@pytest.mark.parametrize("name", MODELNET10)
def test_each_modelnet10_class_is_registered_under_its_folder_name(name: str) -> None:
    assert name in get_category(name).modelnet_names
    others = [c for c in categories() if c != name and name in get_category(c).modelnet_names]
    assert others == [], f"ModelNet's {name!r} folder maps to {others} too"


# A closed dresser or night stand differs from its half turn by millimetres of relief (the
# estimator, at IoU 0.95 about the centre of mass, calls some 2-fold; docs/objects.md says why
# they are declared without symmetry); the other new classes' groups are found as declared.
@pytest.mark.parametrize("name", ["bathtub", "bed", "desk", "monitor", "toilet"])
def test_the_estimator_finds_the_declared_group(name: str) -> None:
    objs = ObjectSet("test", [name], per_category=8)
    for i in range(8):
        inst = objs.get(name, i)
        assert analyse_symmetry(inst.mesh).name == symmetry_name(inst.symmetry), inst.key


def _extents(name: str) -> np.ndarray:
    objs = ObjectSet("test", [name])
    return np.array([objs.get(name, i).mesh.extents.max() for i in range(objs.count(name))])


@pytest.mark.parametrize(
    ("small", "large"), [("night_stand", "dresser"), ("table", "desk"), ("sofa", "bed")]
)
def test_classes_modelnet10_confuses_overlap_in_size(small: str, large: str) -> None:
    """A night stand is a small dresser, a desk a table with drawers, a daybed a sofa: the
    size alone (which known-pose gives) does not separate them."""
    a, b = _extents(small), _extents(large)
    assert a.max() > b.min(), (small, a.max(), large, b.min())


def test_docs_show_every_class() -> None:
    text = (DOCS / "objects.md").read_text()
    listing = text.split("**Procedural categories**", 1)[1].split("\n\n", 1)[0]
    for name in categories():
        assert name in listing, name
    assert (DOCS / "images" / "library.png").is_file()
