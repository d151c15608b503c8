"""The ground-truth grasp planner on simple solids whose good grasps are known: a box
standing on a table, a cube too wide for the hand, a can lying on its side, an obstacle
wall, and meshes with flipped normals or holes like those reconstructions produce."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from beo_bench.errors import BeoBenchError
from beo_bench.grasping import Grasp, GraspPlanningError, plan_grasps
from beo_bench.scenes.gripper import GRIPPER

TABLE = 0.7
BOX_SIZE = (0.05, 0.05, 0.10)


def standing_box(size: tuple[float, float, float] = BOX_SIZE) -> trimesh.Trimesh:
    """An axis-aligned box centred at the origin in xy, its bottom on the table."""
    box = trimesh.creation.box(size)
    box.apply_translation([0.0, 0.0, TABLE + size[2] / 2])
    return box


def lying_can(radius: float = 0.033, length: float = 0.12) -> trimesh.Trimesh:
    """A cylinder with its axis along world x, resting on the table."""
    can = trimesh.creation.cylinder(radius=radius, height=length, sections=48)
    can.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    can.apply_translation([0.0, 0.0, TABLE + radius])
    return can


def corners(grasp: Grasp, centre: np.ndarray, half: np.ndarray, back: float = 0.0) -> np.ndarray:
    """World corners of a hand box, with the hand moved ``back`` along -approach."""
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
    local = centre + signs * half - [0.0, 0.0, back]
    return local @ grasp.rotation.T + grasp.position


def inside_box(
    grasp: Grasp, centre: np.ndarray, half: np.ndarray, points: np.ndarray
) -> np.ndarray:
    """Which world points lie inside a hand box at the grasp pose."""
    local = (points - grasp.position) @ grasp.rotation
    return np.all(np.abs(local - centre) <= half, axis=1)


@pytest.fixture(scope="module")
def box_grasps() -> list[Grasp]:
    return plan_grasps(standing_box(), TABLE)


# ----------------------------------------------------------------------------- the box


def test_box_has_grasps_across_its_narrow_faces(box_grasps: list[Grasp]) -> None:
    assert len(box_grasps) == 32
    for g in box_grasps:
        # the rays run along face normals, so every pair spans the 5 cm between two faces
        assert g.width == pytest.approx(0.05, abs=1e-3)
        assert g.width <= g.opening <= GRIPPER.max_opening
    scores = [g.score for g in box_grasps]
    assert scores == sorted(scores, reverse=True)


def test_box_grasp_frames_are_proper_rotations(box_grasps: list[Grasp]) -> None:
    for g in box_grasps:
        R = g.rotation
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-9)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-9)
        np.testing.assert_allclose(g.pose[:3, :3], R)
        np.testing.assert_allclose(g.pose[:3, 3], g.position)
        np.testing.assert_allclose(g.pose[3], [0, 0, 0, 1])


def test_quaternion_and_action_match_the_pose(box_grasps: list[Grasp]) -> None:
    for g in box_grasps:
        q = g.quaternion
        assert q.shape == (4,)
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-12)
        assert q[0] >= 0
        w, x, y, z = q
        np.testing.assert_allclose(
            Rotation.from_quat([x, y, z, w]).as_matrix(), g.rotation, atol=1e-9
        )
        a = g.action
        assert a.shape == (8,)
        assert a.dtype == np.float32
        np.testing.assert_allclose(a[:3], g.position, atol=1e-6)
        np.testing.assert_allclose(a[3:7], q, atol=1e-6)
        assert a[7] == pytest.approx(g.opening, abs=1e-6)


def test_best_box_grasp_closes_along_a_side_normal_from_above(box_grasps: list[Grasp]) -> None:
    best = box_grasps[0]
    y, z = best.rotation[:, 1], best.rotation[:, 2]
    assert abs(y[2]) < 1e-6  # horizontal closing axis ...
    assert max(abs(y[0]), abs(y[1])) == pytest.approx(1.0, abs=1e-6)  # ... along a face normal
    assert z[2] < -0.99  # approaching from above
    # near the top (the palm must clear the box) and near the middle in xy
    assert TABLE + 0.05 < best.position[2] < TABLE + 0.10
    assert np.linalg.norm(best.position[:2]) < 0.015


def test_box_grasps_keep_the_hand_above_the_table_and_out_of_the_box(
    box_grasps: list[Grasp],
) -> None:
    dense = trimesh.sample.sample_surface(standing_box(), 20000, seed=1)[0]
    for g in box_grasps:
        boxes = GRIPPER.boxes(g.opening / 2)
        for centre, half in boxes:
            for back in (0.0, GRIPPER.pregrasp_distance / 2, GRIPPER.pregrasp_distance):
                assert corners(g, centre, half, back)[:, 2].min() >= TABLE
            assert not inside_box(g, centre, half, dense).any()


def test_box_too_wide_for_the_hand_has_no_grasp() -> None:
    assert plan_grasps(standing_box((0.2, 0.2, 0.2)), TABLE) == []


# ----------------------------------------------------------------------------- other shapes


def test_lying_can_is_grasped_across_its_axis() -> None:
    grasps = plan_grasps(lying_can(), TABLE, max_grasps=10_000)
    assert len(grasps) > 32
    for g in grasps:
        closing = g.rotation[:, 1]
        assert abs(closing[0]) < np.sin(np.radians(10))  # can axis is world x
        assert g.width == pytest.approx(0.066, abs=2e-3)
        # the can is low: closing vertically or approaching from below would hit the table
        for centre, half in GRIPPER.boxes(g.opening / 2):
            for back in (0.0, GRIPPER.pregrasp_distance):
                assert corners(g, centre, half, back)[:, 2].min() >= TABLE
    assert grasps[0].rotation[2, 2] < -0.95  # best: from above


def test_friction_cone_rejects_slanted_pairs() -> None:
    # A prism with an equilateral cross-section: a ray along one side face's normal meets
    # another side face at 60 degrees, far outside the friction cone; only the two end caps
    # (4 cm apart along y) are antipodal.
    s, length = 0.05, 0.04
    tri = [(-s / 2, TABLE), (s / 2, TABLE), (0.0, TABLE + s * np.sqrt(3) / 2)]
    prism = trimesh.Trimesh([(x, y, z) for x, z in tri for y in (-length / 2, length / 2)])
    grasps = plan_grasps(prism.convex_hull, TABLE, max_grasps=10_000)
    assert grasps
    for g in grasps:
        assert abs(g.rotation[1, 1]) > 0.99
        assert g.width == pytest.approx(length, abs=1e-3)


def test_obstacle_wall_blocks_the_side_next_to_it() -> None:
    box = standing_box()
    free = plan_grasps(box, TABLE)
    # without the wall some grasps close along x, i.e. put a finger on the +x face
    assert any(abs(g.rotation[0, 1]) > 0.9 for g in free)

    gy, gz = np.meshgrid(np.linspace(-0.1, 0.1, 41), np.linspace(TABLE, TABLE + 0.2, 41))
    wall = np.stack([np.full(gy.size, 0.025 + 0.006), gy.ravel(), gz.ravel()], axis=1)
    grasps = plan_grasps(box, TABLE, wall)
    assert grasps  # the hand still reaches the box from the other sides / from above
    for g in grasps:
        for centre, half in GRIPPER.finger_boxes(g.opening / 2):
            assert not inside_box(g, centre, half, wall).any()
        # a finger does not fit in the 6 mm gap between the box and the wall
        assert abs(g.rotation[0, 1]) < 0.5


def test_planning_is_deterministic_for_a_seed() -> None:
    can = lying_can()
    first = plan_grasps(can, TABLE, seed=3)
    again = plan_grasps(can, TABLE, seed=3)
    assert first
    assert first == again
    assert len({*first}) == len(first)  # hashable and distinct


def test_max_grasps_limits_the_list() -> None:
    assert len(plan_grasps(standing_box(), TABLE, max_grasps=5)) == 5
    assert plan_grasps(standing_box(), TABLE, max_grasps=0) == []


def test_inverted_and_open_meshes_still_get_grasps() -> None:
    # reconstructions may be wound inside-out or have holes
    inverted = standing_box()
    inverted.invert()
    open_box = standing_box()
    top = open_box.face_normals[:, 2] > 0.9
    open_box.update_faces(~top)
    assert not open_box.is_watertight
    for mesh in (inverted, open_box):
        grasps = plan_grasps(mesh, TABLE)
        assert grasps
        assert all(g.width == pytest.approx(0.05, abs=1e-3) for g in grasps)


def test_grasp_arrays_are_read_only(box_grasps: list[Grasp]) -> None:
    with pytest.raises(ValueError):
        box_grasps[0].position[0] = 1.0


# ----------------------------------------------------------------------------- bad input


def test_empty_mesh_is_rejected() -> None:
    with pytest.raises(GraspPlanningError, match="no faces"):
        plan_grasps(trimesh.Trimesh(), TABLE)


def test_nan_vertices_are_rejected() -> None:
    box = standing_box()
    vertices = box.vertices.copy()
    vertices[0] = np.nan
    bad = trimesh.Trimesh(vertices, box.faces, process=False)
    with pytest.raises(GraspPlanningError, match="NaN"):
        plan_grasps(bad, TABLE)


def test_obstacles_must_be_n_by_3() -> None:
    with pytest.raises(GraspPlanningError, match=r"\(N, 3\)"):
        plan_grasps(standing_box(), TABLE, np.zeros((10, 2)))


def test_table_height_must_be_finite() -> None:
    with pytest.raises(GraspPlanningError, match="table_height") as info:
        plan_grasps(standing_box(), float("nan"))
    assert isinstance(info.value, BeoBenchError)
    assert isinstance(info.value, ValueError)


# -- the analytic audit (closure_friction) and the robust planner (robust_order) -----------


def _grip(yaw_deg: float = 0.0, x: float = 0.0) -> np.ndarray:
    """A gripper frame at the origin (shifted ``x`` along world x), turned ``yaw_deg``
    about its approach axis (z)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix()
    T[0, 3] = x
    return T


def test_closure_friction_of_a_squeezed_box_is_zero_and_grows_with_a_slant() -> None:
    from beo_bench.grasping import closure_friction

    box = trimesh.creation.box([0.04, 0.04, 0.04])
    mu = closure_friction(box, np.stack([_grip(), _grip(30.0)]), np.array([0.03, 0.035]))
    assert mu[0] == pytest.approx(0.0, abs=1e-9)  # faces square to the pads
    # 30 degrees off: the pads meet opposite edges, and their line leaves any 0.4 cone
    assert mu[1] > np.tan(np.radians(30.0))


def test_closure_friction_of_a_sphere_uses_the_patch_not_one_facet() -> None:
    from beo_bench.grasping import AUDIT_FRICTION, closure_friction

    sphere = trimesh.creation.icosphere(3, radius=0.02)
    mu = closure_friction(sphere, _grip()[None], np.array([0.03]))[0]
    assert mu < 0.1 < AUDIT_FRICTION


@pytest.mark.parametrize(
    "pose, half, why",
    [
        (_grip(x=0.1), 0.03, "the object is not between the pads"),
        (_grip(), 0.01, "the pads start inside the object"),
    ],
)
def test_closure_friction_is_infinite_without_two_contacts(pose, half, why) -> None:
    from beo_bench.grasping import closure_friction

    box = trimesh.creation.box([0.04, 0.04, 0.04])
    assert np.isinf(closure_friction(box, pose[None], np.array([half]))[0]), why


def test_robust_order_prefers_the_grasp_that_holds_across_the_samples() -> None:
    """A 6 x 3 x 3 cm bar seen at yaw 0 (weight 0.3) or yaw 90 (0.7): a grasp across its
    3 cm side holds only at yaw 0 (at 90 degrees its pads start inside the bar); one
    across the 6 cm length at 8 cm opening holds at both. The planner's first grasp loses."""
    from beo_bench.grasping import robust_order

    bar = trimesh.creation.box([0.06, 0.03, 0.03])
    across = Grasp(np.zeros(3), np.eye(3), opening=0.05, width=0.03, score=2.0)
    along = Grasp(np.zeros(3), _grip(90.0)[:3, :3], opening=0.08, width=0.06, score=1.0)
    poses = np.stack([np.eye(4), _grip(90.0)])
    order, share = robust_order([across, along], bar, poses, np.array([0.3, 0.7]))
    assert share == pytest.approx([0.3, 1.0])
    assert order.tolist() == [1, 0]
