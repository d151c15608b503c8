"""Camera intrinsics, the camera rig, and the one conversion from MuJoCo's camera axes.

Conventions (docs/design.md "Scenes and rendering"): ``K`` is OpenCV's 3x3 intrinsic matrix with
pixel (u, v) = (column, row) and pixel centres at integer coordinates; ``cam_to_world`` is a
4x4 transform whose camera axes are OpenCV's (x right, y down, z forward). MuJoCo's cameras
look down their -z axis with +y up; :func:`opencv_to_mujoco` is the only place that converts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from beo_bench.types import Mat3, Mat4

# OpenCV camera axes -> MuJoCo camera axes: flip y (down -> up) and z (forward -> backward).
_CV_TO_MJ = np.diag([1.0, -1.0, -1.0])

MAX_IMAGE_SIDE = 8192
"""Largest image width or height (pixels). Off-screen frames live in GL renderbuffers, and
a side beyond the context's ``GL_MAX_RENDERBUFFER_SIZE`` makes MuJoCo fail only at the first
render ("Offscreen framebuffer is not complete"); Mesa's llvmpipe, the CPU renderer, allows
16384 (measured with ``glGetIntegerv``), and an 8192 x 8192 frame already holds about 1 GB
in GL buffers and output arrays. Checked when the intrinsics are made, so a too-large size
fails at ``gym.make`` with a message rather than deep in a reset."""

ROLL_SIGMA_DEG = 25.0 / 2.5758293035489
"""A zero-mean Gaussian with 99% of its mass within +/-25 degrees (z_{0.995} = 2.5758)."""


@dataclass(frozen=True)
class Intrinsics:
    """A pinhole camera with square pixels, the principal point at the image centre.

    The default is Kinect-like (640x480, vertical field of view 45 degrees); a RealSense
    D435's depth stream at 640x480 has about 58 degrees.
    """

    width: int = 640
    height: int = 480
    fovy_deg: float = 45.0

    def __post_init__(self) -> None:
        if int(self.width) < 1 or int(self.height) < 1:
            raise ValueError(
                f"image size {self.width}x{self.height}: width and height must be >= 1 pixel"
            )
        if max(int(self.width), int(self.height)) > MAX_IMAGE_SIDE:
            raise ValueError(
                f"image size {self.width}x{self.height}: width and height must be at most "
                f"{MAX_IMAGE_SIDE} pixels (the off-screen GL buffer's limit); use a smaller "
                "image_size"
            )
        if not 1.0 <= float(self.fovy_deg) <= 170.0:
            raise ValueError(f"fovy_deg={self.fovy_deg}: use a field of view in [1, 170] degrees")

    @property
    def focal(self) -> float:
        """Focal length in pixels (fx = fy)."""
        return 0.5 * self.height / math.tan(math.radians(self.fovy_deg) / 2)

    @property
    def K(self) -> Mat3:
        """OpenCV intrinsics. MuJoCo's image spans [0, W] x [0, H] with pixel i centred at
        i + 0.5, so in OpenCV's integer-centred coordinates the principal point is
        (W/2 - 0.5, H/2 - 0.5)."""
        f = self.focal
        return np.array(
            [[f, 0.0, self.width / 2 - 0.5], [0.0, f, self.height / 2 - 0.5], [0.0, 0.0, 1.0]]
        )


def look_at(
    eye: np.ndarray,
    target: np.ndarray,
    roll_rad: float = 0.0,
    right: np.ndarray | None = None,
) -> Mat4:
    """cam_to_world (OpenCV axes) of a camera at ``eye`` looking at ``target`` with the
    world's +z up in the image (before ``roll_rad`` about the optical axis). Looking
    straight up or down, "up in the image" is undefined: the image's +x is then ``right``
    (a horizontal vector; default world +y or -y, by the sign of the view)."""
    eye = np.asarray(eye, dtype=np.float64)
    z = np.asarray(target, dtype=np.float64) - eye
    z /= np.linalg.norm(z)
    up = np.array([0.0, 0.0, 1.0])
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:  # looking straight up or down
        x = (
            np.cross(z, np.array([1.0, 0.0, 0.0]))
            if right is None
            else np.asarray(right, dtype=np.float64) - np.dot(right, z) * z
        )
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=1)
    if roll_rad:
        c, s = math.cos(roll_rad), math.sin(roll_rad)
        R = R @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = eye
    return T


def opencv_to_mujoco(cam_to_world: Mat4) -> tuple[np.ndarray, np.ndarray]:
    """(position (3,), row-major xmat (9,)) of the MuJoCo camera equal to ``cam_to_world``."""
    T = np.asarray(cam_to_world, dtype=np.float64)
    return T[:3, 3].copy(), (T[:3, :3] @ _CV_TO_MJ).reshape(9)


@dataclass(frozen=True)
class CameraRig:
    """Where cameras are sampled: around a target point (a table's centre or an isolated
    object), like the dissertation's rendered views (section 4.3): azimuth over the full
    circle, elevation in a range, roll from a zero-mean Gaussian with 99% within 25 degrees,
    distance in a range. ``target_jitter`` moves the look-at point (metres, per axis)."""

    azimuth_deg: tuple[float, float] = (0.0, 360.0)
    elevation_deg: tuple[float, float] = (25.0, 65.0)
    roll_sigma_deg: float = ROLL_SIGMA_DEG
    distance: tuple[float, float] = (0.7, 1.1)
    target_jitter: float = 0.05

    def __post_init__(self) -> None:
        for name in ("azimuth_deg", "elevation_deg", "distance"):
            lo, hi = getattr(self, name)
            if not lo <= hi:
                raise ValueError(f"CameraRig.{name}={(lo, hi)}: the range needs low <= high")
        if not -90.0 <= self.elevation_deg[0] and self.elevation_deg[1] <= 90.0:
            raise ValueError(f"elevation_deg={self.elevation_deg}: use degrees in [-90, 90]")
        if self.distance[0] <= 0:
            raise ValueError(f"distance={self.distance}: distances must be positive")
        if self.roll_sigma_deg < 0 or self.target_jitter < 0:
            raise ValueError("roll_sigma_deg and target_jitter must be >= 0")

    def sample(self, rng: np.random.Generator, target: np.ndarray) -> Mat4:
        """One cam_to_world (OpenCV axes) looking at ``target`` (plus jitter)."""
        az = math.radians(rng.uniform(*self.azimuth_deg))
        el = math.radians(rng.uniform(*self.elevation_deg))
        d = rng.uniform(*self.distance)
        roll = math.radians(rng.normal(0.0, self.roll_sigma_deg)) if self.roll_sigma_deg else 0.0
        look = np.asarray(target, dtype=np.float64) + rng.uniform(-1, 1, 3) * self.target_jitter
        eye = look + d * np.array(
            [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)]
        )
        # at elevation +-90 deg the azimuth still turns the image: the image's +x is the
        # limit of cross(view, up) as the elevation tends to 90 deg, (-sin az, cos az, 0)
        return look_at(eye, look, roll, right=np.array([-math.sin(az), math.cos(az), 0.0]))


TABLE_RIG = CameraRig()
"""Views of a tabletop scene (default of BEOPick-v0)."""

OBJECT_RIG = CameraRig(elevation_deg=(0.0, 60.0), distance=(0.45, 0.8), target_jitter=0.0)
"""Views of an isolated instance centred at the origin (training data, pose suites)."""

TOP_DOWN_RIG = CameraRig(
    elevation_deg=(90.0, 90.0), roll_sigma_deg=0.0, distance=(0.45, 0.8), target_jitter=0.0
)
"""Chapter 3's single view from straight above (section 3.3.2: the ``modelnet10-*``
top-down suites). The azimuth turns the image about the optical axis, which is the object's
yaw; the distance range is ``OBJECT_RIG``'s, so objects fill the image as they do there."""


def project(points_cam: np.ndarray, K: Mat3) -> np.ndarray:
    """(N, 2) pixel coordinates (u, v) of camera-frame points (OpenCV axes)."""
    p = np.asarray(points_cam, dtype=np.float64)
    uvw = p @ K.T
    return uvw[:, :2] / uvw[:, 2:3]


def backproject(depth: np.ndarray, K: Mat3, mask: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) camera-frame points (OpenCV axes) of the pixels with depth > 0 (and in
    ``mask`` when given), row-major order."""
    d = np.asarray(depth)
    keep = d > 0 if mask is None else (d > 0) & np.asarray(mask, dtype=bool)
    v, u = np.nonzero(keep)
    return pixels_to_points(u, v, d[v, u], K)


def pixels_to_points(u: np.ndarray, v: np.ndarray, z: np.ndarray, K: Mat3) -> np.ndarray:
    """(N, 3) camera-frame points (OpenCV axes, float64) of pixels (``u`` column, ``v``
    row) at z-depths ``z``: the pinhole model inverted."""
    z = np.asarray(z).astype(np.float64)
    x = (u - K[0, 2]) * z / K[0, 0]
    y = (v - K[1, 2]) * z / K[1, 1]
    return np.stack([x, y, z], axis=1)
