"""Named category sets: the class lists the dissertation's experiments use, by name.

``--categories`` takes class names and set names mixed (``--categories modelnet10``,
``--categories shapenet-ch5 mug``); :func:`resolve_categories` expands them, in the order
given, each class once. A set is a name for a tuple of registered procedural classes; it
says nothing about a user's dataset (whose classes are its folders' names), so a set name
there is expanded the same way and each class must then be in the dataset.

- ``modelnet10``: the ten ModelNet10 classes (Wu et al. 2015), on which chapter 3 (Table 3.1)
  and chapter 4 (Table 4.1) classify and complete objects.
- ``shapenet-ch5``: chapter 5's three ShapeNet classes (car, airplane, and sofa for its
  "couch"), on which Tables 5.1 and 5.2 measure pose.
- ``library``: every registered procedural class.
"""

from __future__ import annotations

from collections.abc import Sequence

from beo_bench.errors import UnknownCategoryError

MODELNET10: tuple[str, ...] = (
    "bathtub",
    "bed",
    "chair",
    "desk",
    "dresser",
    "monitor",
    "night_stand",
    "sofa",
    "table",
    "toilet",
)
"""ModelNet10's classes, by its folder names (``night_stand``), sorted as its folders are."""

SHAPENET_CH5: tuple[str, ...] = ("airplane", "car", "sofa")
"""Chapter 5's ShapeNet classes (Tables 5.1, 5.2: cars, planes, couches), sorted."""


def category_sets() -> dict[str, tuple[str, ...]]:
    """Every named set and its classes (``library`` is read from the registry now, so it
    holds what is registered when asked)."""
    from beo_bench.objects.registry import categories

    return {"library": categories(), "modelnet10": MODELNET10, "shapenet-ch5": SHAPENET_CH5}


def is_set(name: str) -> bool:
    return name in category_sets()


def resolve_categories(names: Sequence[str]) -> tuple[str, ...]:
    """``names`` with each set name replaced by its classes, in order, each class once.
    Class names are kept as given (whoever uses them checks them against the library or the
    dataset); an empty list is an error, not "every class"."""
    if not names:
        raise UnknownCategoryError("--categories needs at least one class or set name")
    sets = category_sets()
    out: list[str] = []
    for n in names:
        for c in sets.get(n, (n,)):
            if c not in out:
                out.append(c)
    return tuple(out)


def set_name(categories: Sequence[str]) -> str | None:
    """The name of the set whose classes are exactly ``categories`` (in any order), if one
    is; ``library`` last, so a subset that happens to equal today's library keeps its own
    name."""
    want = set(categories)
    sets = category_sets()
    for name in ("modelnet10", "shapenet-ch5", "library"):
        if set(sets[name]) == want:
            return name
    return None
