"""Camera maths: K, the rig's distribution, the one MuJoCo <-> OpenCV conversion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beo_bench.scenes.camera import (
    OBJECT_RIG,
    ROLL_SIGMA_DEG,
    CameraRig,
    Intrinsics,
    backproject,
    look_at,
    opencv_to_mujoco,
    project,
)


def test_intrinsics_k() -> None:
    K = Intrinsics(640, 480, 45.0).K
    f = 240 / math.tan(math.radians(22.5))
    np.testing.assert_allclose(K, [[f, 0, 319.5], [0, f, 239.5], [0, 0, 1]])


@pytest.mark.parametrize("bad", [(0, 480), (640, 0), (-1, 10)])
def test_intrinsics_reject_empty_images(bad: tuple[int, int]) -> None:
    with pytest.raises(ValueError, match="image size"):
        Intrinsics(*bad)


def test_look_at_axes() -> None:
    T = look_at(np.array([1.0, 0.0, 0.0]), np.zeros(3))
    R = T[:3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R[:, 2], [-1, 0, 0], atol=1e-12)  # optical axis to target
    np.testing.assert_allclose(R[:, 1], [0, 0, -1], atol=1e-12)  # image down = world down


def test_opencv_to_mujoco_flips_y_and_z() -> None:
    T = look_at(np.array([0.3, -0.4, 1.2]), np.array([0.0, 0.1, 0.7]), roll_rad=0.3)
    pos, xmat = opencv_to_mujoco(T)
    Rm = xmat.reshape(3, 3)
    np.testing.assert_allclose(pos, T[:3, 3])
    # MuJoCo's camera looks down its -z; OpenCV's down its +z
    np.testing.assert_allclose(-Rm[:, 2], T[:3, 2], atol=1e-12)
    np.testing.assert_allclose(-Rm[:, 1], T[:3, 1], atol=1e-12)
    np.testing.assert_allclose(Rm[:, 0], T[:3, 0], atol=1e-12)


def test_rig_distribution() -> None:
    rng = np.random.default_rng(0)
    rig = CameraRig(elevation_deg=(10, 50), distance=(0.5, 0.9), target_jitter=0.0)
    els, dists, rolls, azs = [], [], [], []
    for _ in range(4000):
        T = rig.sample(rng, np.zeros(3))
        p = T[:3, 3]
        dists.append(np.linalg.norm(p))
        els.append(math.degrees(math.asin(p[2] / np.linalg.norm(p))))
        azs.append(math.degrees(math.atan2(p[1], p[0])))
        # roll: angle of the camera's x axis out of the horizontal plane
        rolls.append(math.degrees(math.asin(np.clip(T[2, 0], -1, 1))))
    assert 10 - 1e-6 <= min(els) and max(els) <= 50 + 1e-6
    assert 0.5 <= min(dists) and max(dists) <= 0.9
    assert np.histogram(azs, bins=8, range=(-180, 180))[0].min() > 350  # full circle
    rolls = np.abs(rolls)
    assert np.mean(rolls < 25) == pytest.approx(0.99, abs=0.01)
    assert ROLL_SIGMA_DEG == pytest.approx(25 / 2.5758, rel=1e-4)


def test_project_backproject_round_trip() -> None:
    K = Intrinsics(64, 48, 50.0).K
    depth = np.random.default_rng(1).uniform(0.5, 1.5, (48, 64)).astype(np.float32)
    pts = backproject(depth, K)
    uv = project(pts, K)
    v, u = np.nonzero(depth > 0)
    np.testing.assert_allclose(uv, np.stack([u, v], 1), atol=1e-4)
    assert OBJECT_RIG.target_jitter == 0.0


def test_top_down_views_look_straight_down_with_the_yaw_in_the_image() -> None:
    """TOP_DOWN_RIG's camera is straight above the object; its azimuth still turns the
    image (at 90 deg the image's x axis is the limit of the rig's at 90 - epsilon)."""
    import math

    from beo_bench.scenes.camera import TOP_DOWN_RIG, look_at

    rng = np.random.default_rng(0)
    yaws = []
    for _ in range(20):
        T = TOP_DOWN_RIG.sample(rng, np.zeros(3))
        np.testing.assert_allclose(T[:3, 2], [0.0, 0.0, -1.0], atol=1e-9)  # looks down
        assert 0.45 <= T[2, 3] <= 0.8
        yaws.append(math.degrees(math.atan2(T[1, 0], T[0, 0])))
    assert np.ptp(yaws) > 270  # the azimuth spreads the yaw over the circle
    az = math.radians(40.0)
    for el_deg in (89.999, 90.0):
        el = math.radians(el_deg)
        eye = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        T = look_at(eye, np.zeros(3), right=np.array([-math.sin(az), math.cos(az), 0.0]))
        np.testing.assert_allclose(T[:3, 0], [-math.sin(az), math.cos(az), 0.0], atol=1e-4)
