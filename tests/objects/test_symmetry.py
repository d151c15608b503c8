"""Symmetry estimation (:mod:`beo_bench.objects.symmetry`) on shapes whose groups are known,
each estimated in its own frame and in random frames: the group found must be the same
up to the frame's rotation, element for element."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from beo_bench.geometry import axis_angle, cyclic_z, discrete_symmetry, no_symmetry, rigid
from beo_bench.objects.symmetry import (
    analyse_symmetry,
    estimate_symmetry,
    pack_symmetry,
    rotation_iou,
    symmetry_name,
    unpack_symmetry,
)
from beo_bench.types import Symmetry

FRAMES = (1, 2, 3)
"""Seeds of the random rotations each shape is estimated in (besides its own frame)."""

MAX_SECONDS = 3.0
"""Per estimate; typically 0.05-0.5 s here (more on a loaded machine), 1-2 s for a cube."""


def _box(extents: tuple[float, float, float], centre=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    return trimesh.creation.box(
        extents, transform=trimesh.transformations.translation_matrix(centre)
    )


def _centred(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The mesh with its bounding-box centre at the origin (the canonical frame's origin)."""
    mesh.apply_translation(-mesh.bounds.mean(axis=0))
    return mesh


def _cylinder() -> trimesh.Trimesh:
    return trimesh.creation.cylinder(0.04, 0.1, sections=64)


def _cone() -> trimesh.Trimesh:
    return _centred(trimesh.creation.cone(0.04, 0.12, sections=64))


def _ell() -> trimesh.Trimesh:
    # an L with arms of different lengths: no rotation maps it onto itself
    arms = [_box((0.2, 0.05, 0.05)), _box((0.05, 0.12, 0.05), (0.075, 0.06, 0.0))]
    return _centred(trimesh.boolean.union(arms, engine="manifold"))


SHAPES: dict[str, tuple[Callable[[], trimesh.Trimesh], int, int, str]] = {
    # name: (builder, continuous axes, discrete elements, name of the group)
    "box": (lambda: _box((0.1, 0.2, 0.3)), 0, 3, "2-fold+flips"),  # D2
    "square box": (lambda: _box((0.1, 0.1, 0.3)), 0, 7, "4-fold+flips"),  # D4
    "cylinder": (
        lambda: trimesh.creation.cylinder(0.04, 0.1, sections=64),
        1,
        1,
        "continuous+flip",
    ),
    "cone": (_cone, 1, 0, "continuous"),
    "triangular prism": (
        lambda: _centred(trimesh.creation.cylinder(0.04, 0.1, sections=3)),
        0,
        5,
        "3-fold+flips",
    ),  # D3, its bounding-box centre off the 3-fold axis
    # a 12-gon prism: its continuous score (~0.966) sits near the cut of 0.97, so it came out
    # continuous in some frames before the sampling frame was fixed by the shape
    "12-gon prism": (
        lambda: _centred(trimesh.creation.cylinder(0.04, 0.1, sections=12)),
        0,
        23,
        "12-fold+flips",
    ),
    "asymmetric": (_ell, 0, 0, "none"),
}


def _frame(seed: int) -> np.ndarray:
    return Rotation.random(random_state=seed).as_matrix()


def _moved(mesh: trimesh.Trimesh, R: np.ndarray) -> trimesh.Trimesh:
    out = mesh.copy()
    out.apply_transform(rigid(R))
    return out


def _conjugated(sym: Symmetry, R: np.ndarray) -> Symmetry:
    """The group of a mesh after rotating it by R about the origin."""
    T, Ti = rigid(R), rigid(R.T)
    return {
        "continuous": [
            {"axis": (R @ c["axis"]).tolist(), "offset": (R @ c["offset"]).tolist()}
            for c in sym["continuous"]
        ],
        "discrete": [(T @ np.asarray(D) @ Ti).tolist() for D in sym["discrete"]],
    }


def _assert_same_group(found: Symmetry, expected: Symmetry, scale: float) -> None:
    """Same continuous axes (as lines: any point of an axis is a valid offset) and the same
    discrete elements, matched one to one (rotations within ~1 degree, translations within
    0.1% of the object's size); with a continuous axis, discrete elements match up to a
    rotation about it (a cylinder's flips about all its diameters are one class)."""
    assert len(found["continuous"]) == len(expected["continuous"])
    lines = []
    for c, e in zip(found["continuous"], expected["continuous"], strict=True):
        a, b = np.asarray(c["axis"]), np.asarray(e["axis"])
        assert abs(float(a @ b)) > np.cos(np.deg2rad(1.0)), (a, b)
        d = np.asarray(c["offset"]) - np.asarray(e["offset"])
        assert np.linalg.norm(d - (d @ b) * b) < 1e-3 * scale  # the same line
        lines.append((b, np.asarray(e["offset"])))

    def err(F: np.ndarray, E: np.ndarray) -> float:
        if lines:  # F E^-1 must be a rotation about the continuous axis
            b, p = lines[0]
            M = F @ np.linalg.inv(E)
            rotvec = Rotation.from_matrix(M[:3, :3]).as_rotvec()
            off_axis = np.linalg.norm(rotvec - (rotvec @ b) * b)
            return max(off_axis, np.linalg.norm(M[:3, :3] @ p + M[:3, 3] - p) / scale)
        return max(np.abs(F[:3, :3] - E[:3, :3]).max(), np.abs(F[:3, 3] - E[:3, 3]).max() / scale)

    assert len(found["discrete"]) == len(expected["discrete"])
    unmatched = [np.asarray(D) for D in expected["discrete"]]
    for F in map(np.asarray, found["discrete"]):
        errors = [err(F, E) for E in unmatched]
        i = int(np.argmin(errors))
        assert errors[i] < 0.02, (F.round(4), errors[i])
        unmatched.pop(i)


def _timed(mesh: trimesh.Trimesh) -> Symmetry:
    t = time.perf_counter()
    sym = estimate_symmetry(mesh)
    assert time.perf_counter() - t < MAX_SECONDS
    return sym


@pytest.mark.parametrize("name", list(SHAPES))
def test_known_groups_in_random_frames(name: str) -> None:
    build, n_cont, n_disc, group_name = SHAPES[name]
    mesh = build()
    scale = float(mesh.extents.max())
    sym = _timed(mesh)
    assert (len(sym["continuous"]), len(sym["discrete"])) == (n_cont, n_disc)
    assert symmetry_name(sym) == group_name
    # each element really maps the solid onto itself (an independent IoU estimate, from
    # points uniform in the bounding cube)
    for D in sym["discrete"]:
        assert rotation_iou(mesh, np.asarray(D), n=8000) > 0.97
    for seed in FRAMES:
        R = _frame(seed)
        moved = _timed(_moved(mesh, R))
        assert symmetry_name(moved) == group_name, seed
        _assert_same_group(moved, _conjugated(sym, R), scale)


def test_discrete_groups_are_closed() -> None:
    # the elements found form a group: every product is an element (or the identity)
    mesh = _moved(_box((0.1, 0.1, 0.3)), _frame(4))
    Ts = [np.eye(4)] + [np.asarray(D) for D in estimate_symmetry(mesh)["discrete"]]
    assert len(Ts) == 8
    for A in Ts:
        for B in Ts:
            assert min(np.abs(A @ B - C).max() for C in Ts) < 1e-6


def test_cube_gets_the_octahedral_group() -> None:
    # isotropic inertia: every direction is principal, so the hull's facets name the axes
    cube = _box((0.1, 0.1, 0.1))
    sym = _timed(cube)
    assert symmetry_name(sym) == "octahedral" and len(sym["discrete"]) == 23
    R = _frame(5)
    _assert_same_group(_timed(_moved(cube, R)), _conjugated(sym, R), 0.1)


def test_canonical_frame_gives_exact_transforms_and_bounding_box_offsets() -> None:
    # a box centred on its bounding box: exact half turns, no translation
    box = estimate_symmetry(_box((0.1, 0.2, 0.3)))
    diagonals = sorted(np.diag(np.asarray(D)[:3, :3]).tolist() for D in box["discrete"])
    assert diagonals == [[-1.0, -1.0, 1.0], [-1.0, 1.0, -1.0], [1.0, -1.0, -1.0]]
    assert all(np.asarray(D)[:3, 3].tolist() == [0.0, 0.0, 0.0] for D in box["discrete"])
    # a cone: its centre of mass is a quarter of its height below the bounding-box centre,
    # but the axis point given is the bounding-box centre (the canonical frame's origin)
    cone = _cone()
    assert cone.center_mass[2] == pytest.approx(-0.03, abs=1e-3)
    sym = estimate_symmetry(cone)
    assert sym["continuous"] == [{"axis": [0.0, 0.0, 1.0], "offset": [0.0, 0.0, 0.0]}]
    # a cylinder: continuous about z, and its flip is about x
    cyl = estimate_symmetry(_cylinder())
    assert cyl["continuous"] == [{"axis": [0.0, 0.0, 1.0], "offset": [0.0, 0.0, 0.0]}]
    assert np.allclose(cyl["discrete"][0], np.diag([1.0, -1.0, -1.0, 1.0]))
    # a shifted triangular prism: the axes keep off the bounding-box centre, as they must
    tri = _centred(trimesh.creation.cylinder(0.04, 0.1, sections=3))
    for D in estimate_symmetry(tri)["discrete"]:
        assert rotation_iou(tri, np.asarray(D), n=20000) > 0.97


def test_near_square_carton_is_decided_with_a_margin_in_every_frame() -> None:
    # the carton: a footprint 2.8% from square scores 0.946 under the quarter turn,
    # just under the old hard threshold of 0.95, and flipped between 2- and 4-fold with the
    # file's frame. Scored against the best candidate (1.0 here) the cut is 0.97.
    carton = _box((0.2, 0.2 * 0.9723, 0.1))
    quarter_turns = []
    for seed in (0, *FRAMES):
        mesh = carton if seed == 0 else _moved(carton, _frame(seed))
        est = analyse_symmetry(mesh)
        assert est.name == "2-fold+flips", seed
        assert est.cut == pytest.approx(0.97, abs=1e-3)
        quarter = max(c.iou for c in est.candidates if c.order == 4)
        assert est.cut - quarter > 0.02  # decided with a margin, not by noise
        assert min(est.elements_iou) - est.cut > 0.02
        quarter_turns.append(quarter)
    # samples drawn in the principal frame: the score itself does not move with the frame
    assert quarter_turns[0] == pytest.approx(0.946, abs=0.003)
    assert max(quarter_turns) - min(quarter_turns) < 1e-3


def test_square_carton_is_four_fold() -> None:
    # the same carton made square: the quarter turn is an exact symmetry
    est = analyse_symmetry(_moved(_box((0.2, 0.2, 0.1)), _frame(6)))
    assert est.name == "4-fold+flips"


def test_names_follow_group_structure() -> None:
    half = axis_angle([0, 0, 1], np.pi)
    quarter = axis_angle([0, 0, 1], np.pi / 2)
    flip = axis_angle([1, 0, 0], np.pi)
    assert symmetry_name(no_symmetry()) == "none"
    assert symmetry_name(cyclic_z(2)) == "2-fold"
    assert symmetry_name(cyclic_z(4)) == "4-fold"
    assert symmetry_name(discrete_symmetry([half, flip])) == "2-fold+flips"  # not "4-fold"
    assert symmetry_name(discrete_symmetry([quarter, flip])) == "4-fold+flips"  # not "8-fold"


def test_cache_packing() -> None:
    mesh = _cylinder()
    sym = estimate_symmetry(mesh)
    assert unpack_symmetry(pack_symmetry(sym)) == sym
