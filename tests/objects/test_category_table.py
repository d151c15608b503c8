"""What each furniture category promises beyond tests/objects/test_categories.py, which
checks every category on a few instances: here, on the first 50 test instances, its size
range and proportions, that its key rebuilds it, its declared symmetry, where its tall
parts stand, and that every sub-style is drawn in the train split.

One row of :data:`EXPECT` a category, so a threshold cannot drift between categories and a
new category's promises are one row; the tests read the rows.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

from beo_bench.geometry import axis_angle, symmetry_transformations
from beo_bench.objects import (
    DEFAULT_SPLIT_SIZES,
    LIBRARY_VERSION,
    ObjectInstance,
    ObjectSet,
    instance_from_key,
)
from beo_bench.objects.cache import mesh_hash
from beo_bench.objects.dresser import MAX_COLUMNS, plan
from beo_bench.objects.registry import generate, instance_params
from beo_bench.objects.symmetry import analyse_symmetry, rotation_iou, symmetry_name

Params = Mapping[str, Any]
Check = Callable[[Sequence[ObjectInstance]], None]

IOU_KEEPS = 0.95
"""Volume IoU above which a rotation counts as keeping the solid (a symmetry), below which
as changing it."""

QUARTER_Z = axis_angle([0.0, 0.0, 1.0], np.pi / 2)
HALF_Z = axis_angle([0.0, 0.0, 1.0], np.pi)
QUARTER_X = axis_angle([1.0, 0.0, 0.0], np.pi / 2)
QUARTER_Y = axis_angle([0.0, 1.0, 0.0], np.pi / 2)


def _is(key: str, *values: object) -> Callable[[Params], bool]:
    return lambda p: p[key] in values


def _always(p: Params) -> bool:
    return True


def _never(p: Params) -> bool:
    return False


@dataclass(frozen=True)
class Drawn:
    """Over the train split's 200 instances that ``where`` admits, ``of`` (a parameter's
    name, or a function of the parameters) takes exactly ``values``."""

    of: str | Callable[[Params], object]
    values: set[object]
    where: Callable[[Params], bool] = _always

    def taken(self, ps: Sequence[Params]) -> set[object]:
        of = self.of
        return {p[of] if isinstance(of, str) else of(p) for p in ps if self.where(p)}


@dataclass(frozen=True)
class TopAt:
    """On every instance that ``where`` admits, the highest vertices (within 0.1 mm of the
    top) lie on the ``sign`` side of the plane ``axis`` = 0: the tall part (a headboard, a
    tank, taps) stands at that end."""

    axis: int
    sign: int
    where: Callable[[Params], bool]

    def __call__(self, insts: Sequence[ObjectInstance]) -> None:
        for inst in insts:
            if self.where(inst.params):
                v = inst.mesh.vertices
                top = v[v[:, 2] > v[:, 2].max() - 1e-4]
                assert (self.sign * top[:, self.axis]).min() > 0.0, inst.key

    @property
    def __name__(self) -> str:
        return f"top_at_{'+' if self.sign > 0 else '-'}{'xyz'[self.axis]}"


def _open_basin(insts: Sequence[ObjectInstance]) -> None:
    """A bathtub's basin is open at the top: some vertical line down through the middle of
    the plan first meets the solid (the basin's floor) in the lower half of its height."""
    for inst in insts:
        m = inst.mesh
        u = np.linspace(-0.3, 0.3, 7)
        xy = np.array([(a * m.extents[0], b * m.extents[1]) for a in u for b in u])
        origins = np.column_stack([xy, np.full(len(xy), 1.0)])
        dirs = np.tile([0.0, 0.0, -1.0], (len(xy), 1))
        hits, _, _ = m.ray.intersects_location(origins, dirs, multiple_hits=False)
        assert len(hits), inst.key
        assert hits[:, 2].min() < m.bounds[0][2] + 0.5 * m.extents[2], inst.key


def _wall_hung_floor_behind(insts: Sequence[ObjectInstance]) -> None:
    """A wall-hung toilet's floor contact (its panel) is all behind the bowl."""
    for inst in insts:
        if inst.params["tank"] == "panel" and inst.params["wall_hung"]:
            v = inst.mesh.vertices
            lo = inst.mesh.bounds[0]
            floor = v[v[:, 2] < lo[2] + 1e-4]
            assert floor[:, 0].max() < lo[0] + 0.4 * inst.mesh.extents[0], inst.key


def _table_half_turn_about_centre_of_mass(insts: Sequence[ObjectInstance]) -> None:
    """The known trap: a table night stand open between its legs could be nearly symmetric
    under a half turn, its drawer front the only difference. Its half turn about the
    vertical axis through the centre of mass (the axis a symmetry would have to use) still
    changes it."""
    tables = [i for i in insts if i.params["style"] == "table"]
    assert tables
    for inst in tables:
        c = inst.mesh.center_mass
        T = np.eye(4)
        T[:3, :3] = HALF_Z
        T[:2, 3] = (c - HALF_Z @ c)[:2]
        assert rotation_iou(inst.mesh, T) < IOU_KEEPS, inst.key


@dataclass(frozen=True)
class Expect:
    """A category's promises. ``size``: its largest extent's range (metres, both ends
    included); ``shape(extents, params)``: its proportions; ``two_fold``: the instances
    declared 2-fold about z (the others declare no symmetry at all); ``quarter_xy_on``: on
    that many first instances, quarter turns about x and y change the solid too;
    ``rebuilt``: the test indices whose keys and parameters must rebuild them;
    ``estimated``: the geometric symmetry estimator finds the declared group;
    ``drawn``/``occurs``: what the train split draws (``occurs``: each holds for some
    instance); ``checks``: the category's own geometric checks on the test instances."""

    size: tuple[float, float]
    drawn: tuple[Drawn, ...]
    shape: Callable[[np.ndarray, Params], bool] = lambda e, p: True
    two_fold: Callable[[Params], bool] = _never
    quarter_xy_on: int = 0
    rebuilt: tuple[int, ...] = (0, 1, 2)
    estimated: bool = True
    occurs: Mapping[str, Callable[[Params], bool]] = field(default_factory=dict)
    checks: tuple[Check, ...] = ()


BATHTUB_STYLES = ("built_in", "corner", "freestanding", "clawfoot")


def _bathtub_two_fold(p: Params) -> bool:
    """A shell with two equal ends and no taps."""
    return p["style"] in ("freestanding", "clawfoot") and p["ends"] == "double" and not p["taps"]


def _plain_bed(p: Params) -> bool:
    """A mattress on a base: no boards, no pillows, neither daybed nor bunk."""
    return p["style"] == "standard" and p["headboard"] == "none" and not p["pillows"]


def _dresser_columns(p: Params) -> int:
    return min(int(p["columns"]), MAX_COLUMNS[str(p["form"])])


BOOL = {True, False}
STANDARD_BED = _is("style", "standard")
CASE = _is("style", "drawers", "cabinet")  # a night stand with a case (not the table style)
CABINET = _is("style", "cabinet")

EXPECT: dict[str, Expect] = {
    "bathtub": Expect(
        size=(0.095, 0.17),
        # long along y (a corner tub a little less so), and low
        shape=lambda e, p: (
            e[1] > (1.05 if p["style"] == "corner" else 1.6) * e[0] and e[2] < 0.6 * e[1]
        ),
        two_fold=_bathtub_two_fold,
        drawn=(
            Drawn("style", set(BATHTUB_STYLES)),
            *(Drawn("ends", {"double", "single"}, _is("style", s)) for s in BATHTUB_STYLES),
            *(Drawn("taps", BOOL, _is("style", s)) for s in BATHTUB_STYLES),
            Drawn("plinth", BOOL, _is("style", "freestanding")),
            Drawn("apron_panel", BOOL, _is("style", "built_in")),
        ),
        occurs={
            "two-fold": _bathtub_two_fold,
            "oval plan": lambda p: p["squareness"] < 2.3,
            "rounded-rectangle plan": lambda p: p["squareness"] > 4.0,
        },
        # a mixer is the highest part of a tub without a swept-up backrest, at its +y end
        checks=(
            _open_basin,
            TopAt(
                1, +1, lambda p: p["taps"] and p["ends"] != "single" and p["style"] != "clawfoot"
            ),
        ),
    ),
    "bed": Expect(
        size=(0.10, 0.18),
        # long and low: the length along x, at least 1.2 times the width
        shape=lambda e, p: e[0] == e.max() and e[0] > 1.2 * e[1],
        two_fold=_plain_bed,
        drawn=(
            Drawn("style", {"standard", "daybed", "bunk"}),
            Drawn("base", {"legs", "plinth", "box"}),
            Drawn("headboard", {"none", "panel", "slatted", "upholstered"}, STANDARD_BED),
        ),
        occurs={
            "foot and head boards": lambda p: (
                STANDARD_BED(p) and p["footboard"] and p["headboard"] != "none"
            ),
            "pillows and duvet": lambda p: STANDARD_BED(p) and p["pillows"] and p["duvet"],
            "arched panel": lambda p: STANDARD_BED(p) and p["headboard"] == "panel" and p["arched"],
            "panel and posts": lambda p: (
                STANDARD_BED(p) and p["headboard"] == "panel" and p["posts"]
            ),
            "the 2-fold plain bed": _plain_bed,
        },
        # a headboard is the highest part of a standard bed and stands at its -x end
        checks=(TopAt(0, -1, lambda p: STANDARD_BED(p) and p["headboard"] != "none"),),
    ),
    "desk": Expect(
        size=(0.07, 0.18),  # table.py's tops are 0.09-0.16 m
        rebuilt=(0, 7, 31),
        drawn=(
            Drawn("style", {"writing", "one_pedestal", "two_pedestals", "panel_ends"}),
            Drawn("handle", {"knob", "bar", "lip"}),
            Drawn("end_support", {"legs", "panel"}, _is("style", "one_pedestal")),
            # a two-pedestal desk builds no wing
            Drawn(lambda p: bool(p["wing"]) and p["style"] != "two_pedestals", BOOL),
            Drawn(lambda p: bool(p["hutch"]), BOOL),
            Drawn(lambda p: bool(p["center_drawer"]), BOOL, lambda p: p["style"] != "writing"),
            Drawn(lambda p: bool(p["modesty"]), BOOL, _is("style", "writing")),
        ),
    ),
    "dresser": Expect(
        size=(0.078, 0.16),
        # wider than deep (at least 1.3 x), under 7.5 cm deep: picked across the depth
        shape=lambda e, p: e[1] > 1.3 * e[0] and e[0] < 0.075,
        quarter_xy_on=10,
        # a closed case differs from its half turn by millimetres of relief: the estimator,
        # at IoU 0.95 about the centre of mass, calls some 2-fold (docs/objects.md says why
        # it is declared without symmetry)
        estimated=False,
        drawn=(
            Drawn("form", {"low", "chest", "tall"}),
            Drawn("support", {"plinth", "legs", "bracket"}),
            Drawn("handle", {"knob", "bar", "recessed"}),
            Drawn("front_style", {"overlay", "framed"}),
            Drawn("leg_style", {"square", "tapered", "round"}, _is("support", "legs")),
            Drawn("mirror_shape", {"rect", "arched"}, lambda p: p["mirror"] and p["form"] == "low"),
            Drawn(_dresser_columns, {1, 2, 3}),
            Drawn("top_edge", {"square", "bevel"}),
            Drawn(lambda p: 2 <= plan(p).drawers <= 12, {True}),
        ),
        occurs={
            "a split top on one column": lambda p: p["top_split"] and _dresser_columns(p) == 1,
            "two drawers": lambda p: plan(p).drawers == 2,
            "twelve drawers": lambda p: plan(p).drawers == 12,
        },
    ),
    "monitor": Expect(
        size=(0.07, 0.16),  # the panel's width (0.08-0.15 m aimed at)
        rebuilt=(0, 7, 31),
        drawn=(
            Drawn("back", {"flat", "housing", "crt"}),
            Drawn("aspect", {"4:3", "16:10", "16:9", "21:9"}),
            # a CRT stands on its swivel foot, flat (whatever was drawn)
            Drawn(
                "stand",
                {"post_round", "post_rect", "v_foot", "two_leg", "arm_clamp", "kickstand"},
                lambda p: p["back"] != "crt",
            ),
            Drawn(lambda p: bool(p["curved"]), BOOL, lambda p: p["back"] != "crt"),
        ),
    ),
    "night_stand": Expect(
        size=(0.06, 0.117),
        # wider than deep: a quarter turn about z is no symmetry of the plan
        shape=lambda e, p: e[1] > 1.15 * e[0],
        quarter_xy_on=10,
        # a closed case differs from its half turn by millimetres of relief: the estimator,
        # at IoU 0.95 about the centre of mass, calls some 2-fold (docs/objects.md says why
        # it is declared without symmetry)
        estimated=False,
        drawn=(
            Drawn("style", {"drawers", "table", "cabinet"}),
            Drawn("support", {"plinth", "legs", "bracket"}, CASE),
            Drawn("handle", {"knob", "bar", "recessed"}),
            Drawn("front_style", {"overlay", "framed"}, CASE),
            Drawn("drawers", {1, 2, 3}, _is("style", "drawers")),
            Drawn("niche", {"none", "top", "bottom"}, _is("style", "drawers")),
            Drawn("shelf_enclosure", {"open", "back", "boxed"}, _is("style", "table")),
            Drawn("leg_style", {"square", "tapered", "round"}, _is("style", "table")),
            Drawn("hinge", {"left", "right"}, CABINET),
        ),
        # a cabinet's door under a drawer, under a niche, or alone
        occurs={
            "a door under drawers": lambda p: CABINET(p) and p["drawers"] > 1,
            "a door under a niche": lambda p: (
                CABINET(p) and p["drawers"] == 1 and p["niche"] != "none"
            ),
            "a door alone": lambda p: CABINET(p) and p["drawers"] == 1 and p["niche"] == "none",
        },
        checks=(_table_half_turn_about_centre_of_mass,),
    ),
    "toilet": Expect(
        size=(0.06, 0.10),
        shape=lambda e, p: e[0] > 1.2 * e[1],  # deeper (x) than wide (y)
        drawn=(
            Drawn("tank", {"close_coupled", "panel", "none"}),
            Drawn("wall_hung", BOOL, _is("tank", "panel")),
            Drawn("lid", {"down", "up", "none"}),
            Drawn("seat", {"closed", "open_front"}),
            Drawn("flush", {"button", "lever"}, _is("tank", "close_coupled")),
        ),
        occurs={
            "a round bowl": lambda p: p["bowl_length"] < 0.44,
            "an elongated bowl": lambda p: p["bowl_length"] > 0.5,
        },
        # the bowl's front is foremost: with the lid down or off, the highest points (the
        # tank, panel or pipe) are in the rear half
        checks=(TopAt(0, -1, lambda p: p["lid"] != "up"), _wall_hung_floor_behind),
    ),
}

CATEGORIES = list(EXPECT)
CHECKS = [(c, check) for c, e in EXPECT.items() for check in e.checks]


@pytest.fixture(scope="module")
def test_set(category: str) -> list[ObjectInstance]:
    """The first 50 instances of the category's test split, in index order. Module-scoped
    (the category parametrised at module scope): building and measuring them is the slow
    part, and every test of a category reads the same instances."""
    return list(ObjectSet("test", [category], per_category=50))


@pytest.mark.parametrize("category", CATEGORIES, scope="module")
def test_solid_sized_and_proportioned(category: str, test_set: list[ObjectInstance]) -> None:
    """Watertight, because volumes, voxels, IoU and the simulator's inside tests need a
    closed surface; one body with faces wound outward, because a loose part or a closed
    cavity is no single graspable solid; the size range, because the class is meant at
    tabletop scale, within the gripper's reach and apart from (or overlapping by design
    with) its neighbours."""
    e = EXPECT[category]
    lo, hi = e.size
    for inst in test_set:
        m = inst.mesh
        assert m.is_watertight, inst.key
        assert m.body_count == 1, (inst.key, "one connected solid, no closed cavities")
        assert m.volume > 0, inst.key
        assert lo <= m.extents.max() <= hi, (inst.key, m.extents)
        assert e.shape(m.extents, inst.params), (inst.key, m.extents)


@pytest.mark.parametrize("category", CATEGORIES, scope="module")
def test_deterministic_per_key(category: str, test_set: list[ObjectInstance]) -> None:
    """An instance's key (as carried, and as spelled out, which checks its form) rebuilds
    it, its parameters generate it again, and two instances differ: runs, caches and
    published results name objects by key alone."""
    for i in EXPECT[category].rebuilt:
        inst = test_set[i]
        spelled = f"proc/v{LIBRARY_VERSION}/{category}/test/{i}"
        for key in (inst.key, spelled):
            assert instance_from_key(key).content_hash == inst.content_hash, key
        rebuilt = generate(category, instance_params(category, "test", inst.index))
        assert mesh_hash(rebuilt.mesh) == inst.content_hash, inst.key
    assert test_set[0].content_hash != test_set[1].content_hash


def _in_group(R: np.ndarray, group: Sequence[np.ndarray]) -> bool:
    return any(np.allclose(T[:3, :3], R, atol=1e-6) for T in group)


@pytest.mark.parametrize("category", CATEGORIES, scope="module")
def test_symmetry_as_declared(category: str, test_set: list[ObjectInstance]) -> None:
    """Declared 2-fold about z exactly where the row says, else no symmetry at all; every
    declared rotation keeps the solid, and the quarter and half turns about z outside the
    group do not (nor, on the first ``quarter_xy_on``, quarter turns about x and y). The
    declaration is what rotation error is scored against: a declared element that changes
    the solid forgives real errors, an undeclared turn that keeps it charges for correct
    answers."""
    e = EXPECT[category]
    for inst in test_set:
        group = symmetry_transformations(inst.symmetry)
        if e.two_fold(inst.params):
            assert not inst.symmetry["continuous"] and len(group) == 2, inst.key
        else:
            assert inst.symmetry == {"continuous": [], "discrete": []}, inst.key
        for T in group[1:]:
            assert rotation_iou(inst.mesh, T) > IOU_KEEPS, (inst.key, T.round(3))
        for R in (QUARTER_Z, HALF_Z):
            if not _in_group(R, group):
                assert rotation_iou(inst.mesh, R) < IOU_KEEPS, (inst.key, R.round(3))
    for inst in test_set[: e.quarter_xy_on]:
        for R in (QUARTER_X, QUARTER_Y):
            assert rotation_iou(inst.mesh, R) < IOU_KEEPS, (inst.key, R.round(3))


@pytest.mark.parametrize("category", [c for c, e in EXPECT.items() if e.estimated], scope="module")
def test_the_estimator_finds_the_declared_group(
    category: str, test_set: list[ObjectInstance]
) -> None:
    for inst in test_set[:8]:
        assert analyse_symmetry(inst.mesh).name == symmetry_name(inst.symmetry), inst.key


@pytest.mark.parametrize("category", CATEGORIES)
def test_every_sub_style_drawn(category: str) -> None:
    e = EXPECT[category]
    ps = [instance_params(category, "train", i) for i in range(DEFAULT_SPLIT_SIZES["train"])]
    for drawn in e.drawn:
        assert drawn.taken(ps) == drawn.values, drawn
    for what, holds in e.occurs.items():
        assert any(holds(p) for p in ps), what


@pytest.mark.parametrize(
    ("category", "check"), CHECKS, ids=[f"{c}-{k.__name__}" for c, k in CHECKS], scope="module"
)
def test_category_geometry(category: str, check: Check, test_set: list[ObjectInstance]) -> None:
    check(test_set)
