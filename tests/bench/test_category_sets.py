"""Named category sets and class-restricted suites: ``--categories modelnet10`` expands to
the ten ModelNet10 classes, ``SUITE+SET`` is its own suite (own name, own items), and only
isolated suites can be restricted."""

from __future__ import annotations

import pytest

from beo_bench.bench.suites import Kind, base_name, get_suite
from beo_bench.errors import UnknownCategoryError, UsageError
from beo_bench.objects import categories
from beo_bench.objects.sets import (
    MODELNET10,
    SHAPENET_CH5,
    category_sets,
    resolve_categories,
    set_name,
)


def test_sets_expand_in_order_each_class_once() -> None:
    assert resolve_categories(["modelnet10"]) == MODELNET10
    assert resolve_categories(["shapenet-ch5", "mug", "car"]) == (*SHAPENET_CH5, "mug")
    assert resolve_categories(["library"]) == categories()
    with pytest.raises(UnknownCategoryError, match="at least one"):
        resolve_categories([])


def test_the_library_holds_every_modelnet10_class() -> None:
    sets = category_sets()
    assert len(MODELNET10) == 10
    assert set(MODELNET10) | set(SHAPENET_CH5) <= set(sets["library"])


def test_set_names_are_found_back() -> None:
    assert set_name(reversed(MODELNET10)) == "modelnet10"
    assert set_name(["car", "sofa", "airplane"]) == "shapenet-ch5"
    assert set_name(["car", "mug"]) is None


def test_a_restricted_suite_is_its_own_suite() -> None:
    s = get_suite("pose-3dof").with_categories(["modelnet10"])
    assert s.name == "pose-3dof+modelnet10" and s.categories == MODELNET10
    assert base_name(s.name) == "pose-3dof" and s.version == get_suite("pose-3dof").version
    assert get_suite("pose-3dof+modelnet10") == s
    two = get_suite("known-pose+mug+car")
    assert two.name == "known-pose+mug+car" and two.categories == ("mug", "car")


def test_restricted_items_come_from_the_chosen_classes_only() -> None:
    from beo_bench.bench.kinds.isolated import IsolatedItems

    items = IsolatedItems(get_suite("known-pose+mug+car"))
    try:
        truths = [items.isolated_truth(i) for i in range(6)]
    finally:
        items.close()
    assert {t.category for t in truths} == {"mug", "car"}


def test_only_isolated_suites_take_a_class_subset() -> None:
    assert get_suite("tabletop").kind is Kind.TABLETOP
    with pytest.raises(UsageError, match="isolated suites only"):
        get_suite("tabletop").with_categories(["mug"])
    with pytest.raises(UsageError, match="may only choose among them"):
        get_suite("pose-3dof-percat").with_categories(["mug"])
    assert get_suite("pose-3dof-percat+car").categories == ("car",)


def test_the_modelnet10_suites() -> None:
    for name, viewpoint in (
        ("modelnet10-known-pose", "top-down"),
        ("modelnet10-1dof", "top-down"),
        ("modelnet10-3dof", "rig"),
    ):
        s = get_suite(name)
        assert s.categories == MODELNET10 and s.viewpoint == viewpoint and s.split == "test"
