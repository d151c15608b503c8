"""The NOCS 3D IoU (``beo_bench.bop.nocs``) against values worked out by hand from the
reference code's definition (NOCS_CVPR2019 ``utils.py``: ``compute_3d_iou_new`` with its
per-corner bounds, ``get_3d_bbox``'s corner order, the 20 rotations about a symmetry axis;
``compute_3d_matches``' strict ``iou > threshold``)."""

from __future__ import annotations

import numpy as np
import pytest

from beo_bench.bop import nocs as N
from beo_bench.geometry import axis_angle, continuous_symmetry, cyclic_z, discrete_symmetry

I3 = np.eye(3)
CUBE = np.ones(3)
AT = np.array([0.0, 0.0, 2.0])  # in front of the camera, on its axis
ROOT_HALF = 1 / np.sqrt(2)


def _reference_by_definition(
    size_gt: np.ndarray, R_gt: np.ndarray, t_gt: np.ndarray, size_est, R_est, t_est
) -> float:
    """compute_3d_iou_new's asymmetric IoU written from its definition: corner i of each box
    in get_3d_bbox's order (y sign outermost, then x, then z, + before -), per-corner
    [min, max] over its 3 camera coordinates, intervals paired by corner index."""
    signs = [(sx, sy, sz) for sy in (1, -1) for sx in (1, -1) for sz in (1, -1)]
    vol_g = vol_e = inter = 1.0
    for s in signs:
        cg = R_gt @ (np.multiply(s, size_gt) / 2) + t_gt
        ce = R_est @ (np.multiply(s, size_est) / 2) + t_est
        vol_g *= cg.max() - cg.min()
        vol_e *= ce.max() - ce.min()
        inter *= max(0.0, min(cg.max(), ce.max()) - max(cg.min(), ce.min()))
    return inter / (vol_g + vol_e - inter)


@pytest.mark.parametrize("method", ["nocs", "aabb"])
def test_identical_boxes(method: str) -> None:
    R = axis_angle([1, 2, 3], 0.7)
    assert N.box_iou([0.1, 0.2, 0.3], R, [0.1, 0, 0.8], [0.1, 0.2, 0.3], R, [0.1, 0, 0.8],
                     method=method) == pytest.approx(1.0, abs=1e-12)  # fmt: skip


def test_aabb_half_shift_is_a_third() -> None:
    """Unit cubes, one moved half a side along x: overlap 1/2, union 3/2."""
    iou = N.box_iou(CUBE, I3, AT, CUBE, I3, AT + np.array([0.5, 0, 0]), method="aabb")
    assert iou == pytest.approx(1 / 3, abs=1e-12)


def test_nocs_half_shift_by_hand() -> None:
    """The same shift as the reference scores it. Corner (x, y, z), z in {1.5, 2.5} (always its
    largest coordinate), has the interval [min(x, y), z]. Shifting x by 1/2 changes only the
    corners with x = -1/2, y = +1/2: [-1/2, z] becomes [0, z]. Per corner pair (z = 2.5, 1.5):
    (+,+): 2 and 1, equal; (-,+): 3 and 2 against 2.5 and 1.5, overlap 2.5 and 1.5; (+,-) and
    (-,-): 3 and 2, equal. vol_gt = (2 * 3 * 3 * 3)(1 * 2 * 2 * 2) = 432,
    vol_est = inter = (2 * 2.5 * 3 * 3)(1 * 1.5 * 2 * 2) = 270: IoU = 270 / 432 = 0.625."""
    moved = AT + np.array([0.5, 0, 0])
    iou = N.box_iou(CUBE, I3, AT, CUBE, I3, moved)
    assert iou == pytest.approx(0.625, abs=1e-12)
    assert iou == pytest.approx(_reference_by_definition(CUBE, I3, AT, CUBE, I3, moved))


def test_cube_turned_45_degrees_by_hand() -> None:
    """A unit cube turned 45 degrees about z against the same cube.

    aabb: the turned cube's bounds are sqrt 2 x sqrt 2 x 1 (volume 2) and hold the other
    cube (volume 1): IoU 1/2 (the boxes themselves share a regular octagonal prism of volume
    2 (sqrt 2 - 1), an IoU of 1 / sqrt 2; the bounds are what is compared).

    nocs: corner (x, y) goes to ((x - y) a, (x + y) a), a = 1/sqrt 2. Per corner with depth z:
    (+,+): [1/2, z] against [0, z]; (-,+): [-1/2, z] against [-a, z]; (+,-): [-1/2, z]
    against [0, z]; (-,-): [-1/2, z] against [-a, z]. vol_gt = 432 as before,
    inter = (z - 1/2)(z + 1/2)(z)(z + 1/2) over z = 2.5, 1.5 = 45 * 6 = 270,
    vol_est = (z (z + a))^2 over z = 2.5, 1.5."""
    R = axis_angle([0, 0, 1], np.pi / 4)
    assert N.box_iou(CUBE, I3, AT, CUBE, R, AT, method="aabb") == pytest.approx(0.5, abs=1e-12)
    a = ROOT_HALF
    vol_est = (2.5 * (2.5 + a)) ** 2 * (1.5 * (1.5 + a)) ** 2
    by_hand = 270 / (432 + vol_est - 270)
    assert N.box_iou(CUBE, I3, AT, CUBE, R, AT) == pytest.approx(by_hand, abs=1e-12)
    assert by_hand == pytest.approx(0.3115662619, abs=1e-9)  # what compute_3d_iou_new gives


def test_quarter_turn_of_a_square_section_box() -> None:
    """A 0.1 x 0.1 x 0.3 box turned 90 degrees about its long (z) axis occupies the same
    space: the aabb IoU is 1 without any symmetry. The reference pairs corners by index, and
    the turn permutes them, so its IoU falls below 1 unless the symmetry group brings the
    corners back: the 4-fold group, or the continuous axis (its 20 angles include 90)."""
    size = [0.1, 0.1, 0.3]
    R = axis_angle([0, 0, 1], np.pi / 2)
    t = np.array([0.05, -0.02, 0.7])
    assert N.box_iou(size, I3, t, size, R, t, method="aabb") == pytest.approx(1.0, abs=1e-12)
    plain = N.box_iou(size, I3, t, size, R, t)
    assert plain < 0.99
    assert plain == pytest.approx(_reference_by_definition(np.array(size), I3, t, size, R, t))
    assert N.box_iou(size, I3, t, size, R, t, cyclic_z(4)) == pytest.approx(1.0, abs=1e-12)
    assert N.box_iou(size, I3, t, size, R, t, continuous_symmetry((0, 0, 1))) == pytest.approx(
        1.0, abs=1e-12
    )


@pytest.mark.parametrize("method", ["nocs", "aabb"])
def test_symmetric_maximisation_uses_the_groups_axis(method: str) -> None:
    """A box with a square section about its x, the estimate turned 36 degrees (two of the
    18-degree steps) about that axis from a true pose that is itself turned: with the
    continuous symmetry about the object's x the turn is undone (IoU 1: the turn acts in the
    object's frame, ``R_est S``); about y, the NOCS reference's hard-coded axis, it is not;
    the maximum over the group is never below the plain IoU."""
    size = [0.3, 0.1, 0.1]
    Rg = axis_angle([1, 2, 2], 0.8)
    R = Rg @ axis_angle([1, 0, 0], np.radians(36))
    t = np.array([0.0, 0.05, 0.9])
    plain = N.box_iou(size, Rg, t, size, R, t, method=method)
    about_x = N.box_iou(size, Rg, t, size, R, t, continuous_symmetry((1, 0, 0)), method=method)
    about_y = N.box_iou(size, Rg, t, size, R, t, continuous_symmetry((0, 1, 0)), method=method)
    assert plain < 0.95 and about_x == pytest.approx(1.0, abs=1e-12)
    assert plain <= about_y < 0.99


def test_symmetric_maximum_is_over_the_estimates_turns() -> None:
    """Turned 30 degrees (not a multiple of 18): the best of the 20 turns of the estimate
    about the axis leaves it 6 degrees off, i.e. exactly the plain IoU of a 6-degree turn."""
    size = [0.3, 0.1, 0.1]
    t = np.array([0.0, 0.05, 0.9])
    sym = continuous_symmetry((1, 0, 0))
    got = N.box_iou(size, I3, t, size, axis_angle([1, 0, 0], np.radians(30)), t, sym)
    candidates = [
        N.box_iou(size, I3, t, size, axis_angle([1, 0, 0], np.radians(30 + 18 * k)), t)
        for k in range(20)
    ]
    assert got == pytest.approx(max(candidates), abs=1e-12)
    assert got == pytest.approx(
        N.box_iou(size, I3, t, size, axis_angle([1, 0, 0], np.radians(-6)), t), abs=1e-9
    )


def test_symmetry_offset_and_discrete_elements() -> None:
    """A 2-fold turn about the object's z through the offset (0.1, 0, 0) maps the box centred
    at the origin to one centred at (0.2, 0, 0): an estimate placed there with that turn is
    the truth under the group (IoU 1), and off by the plain IoU without it."""
    size = [0.3, 0.1, 0.1]
    sym = discrete_symmetry([axis_angle([0, 0, 1], np.pi)], offset=(0.1, 0.0, 0.0))
    Rg = axis_angle([0, 1, 0], 0.4)
    tg = np.array([0.0, 0.0, 1.0])
    # the element S: x -> Rz(pi) (x - o) + o; truth = estimate o S, so estimate = truth o S^-1
    # = truth o S (S is its own inverse): R_est = Rg Rz(pi), t_est = Rg (o - Rz(pi) o) + tg
    Rz = axis_angle([0, 0, 1], np.pi)
    o = np.array([0.1, 0.0, 0.0])
    R_est, t_est = Rg @ Rz, Rg @ (o - Rz @ o) + tg
    assert N.box_iou(size, Rg, tg, size, R_est, t_est, sym) == pytest.approx(1.0, abs=1e-12)
    assert N.box_iou(size, Rg, tg, size, R_est, t_est) < 0.5


def test_reference_agrees_on_random_boxes() -> None:
    rng = np.random.default_rng(3)
    for k in range(20):
        Rg, Re = (
            axis_angle(rng.normal(size=3), rng.uniform(0, 3)),
            axis_angle(rng.normal(size=3), rng.uniform(0, 3)),
        )
        tg = rng.normal(0, 0.1, 3) + np.array([0, 0, 0.8])
        te = tg + rng.normal(0, 0.03, 3)
        sg, se = rng.uniform(0.05, 0.2, 3), rng.uniform(0.05, 0.2, 3)
        assert N.box_iou(sg, Rg, tg, se, Re, te) == pytest.approx(
            _reference_by_definition(sg, Rg, tg, se, Re, te), abs=1e-12
        ), k


def test_nan_where_the_reference_divides_zero_by_zero() -> None:
    """Half a cube against a cube, both at (1, 1, 1) (the case of NOCS_CVPR2019 issue #47):
    the corners (1.5, 1.5, 1.5) and (1.25, 1.25, 1.25) have intervals of zero length, so both
    "volumes" are 0, their intervals do not overlap (intersection 0), and the reference
    returns 0 / 0."""
    t = np.array([1.0, 1.0, 1.0])
    assert np.isnan(N.box_iou(CUBE, I3, t, CUBE / 2, I3, t))


def test_iou_accuracies_strict_and_float32() -> None:
    """> not >=, on float32 values (compute_3d_matches keeps overlaps in float32): 0.25 does
    not pass 0.25, nor do 0.25000001 and 0.5 + 1e-9, which float32 rounds to 0.25 and 0.5.
    The NaN is dropped: 6 views."""
    ious = [0.25, 0.25000001, 0.5 + 1e-9, 0.75, 0.8, np.nan, 0.0]
    acc = N.iou_accuracies(ious)
    assert acc == {"iou25": 3 / 6, "iou50": 2 / 6, "iou75": 1 / 6}
    assert N.NOCS_IOU_THRESHOLDS == (0.25, 0.5, 0.75)
    assert all(np.isnan(v) for v in N.iou_accuracies([np.nan]).values())


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"size_gt": [1.0, 0.0, 1.0]}, "size_gt"),
        ({"size_est": [1.0, 1.0]}, "size_est"),
        ({"R_est": np.eye(3) * 2}, "R_est"),
        ({"t_gt": [0.0, 1.0]}, "t_gt"),
        ({"method": "obb"}, "method"),
    ],
)
def test_box_iou_refuses_bad_input(kwargs: dict, match: str) -> None:
    args = {"size_gt": CUBE, "R_gt": I3, "t_gt": AT, "size_est": CUBE, "R_est": I3, "t_est": AT}
    with pytest.raises(ValueError, match=match):
        N.box_iou(**(args | kwargs))


def test_iou_accuracies_refuses_bad_input() -> None:
    with pytest.raises(ValueError, match="1-D"):
        N.iou_accuracies(np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        N.iou_accuracies([1.2])
