"""Object-centred depth crops for HBEO (dissertation section 4.2) and the frame they define.

A crop is a square window around the object's mask, resampled to S x S pixels (default
64). It changes the viewing ray: an object off the optical axis is seen from the side, so
the network predicts the rotation *relative to the ray through the crop centre* and the
translation and size *in units of the crop*, and :class:`Crop` converts back:

- ray frame: ``R_ray`` is the smallest rotation taking the camera's +z to the ray through
  the crop centre; the network's rotation target is ``R_ray^T R_cam``;
- reference depth ``z_ref``: the median depth of the mask's pixels; ``scale``: the metric
  width of the crop at that depth (so normalised depth and offsets do not depend on how far
  the object is);
- translation target: the object's centre in the ray frame minus the point of the ray at
  ``z_ref``, divided by ``scale``; size target: log(extents / scale).

Channel 0 holds (depth - z_ref) / scale on the mask and 0 elsewhere; channel 1 holds the
mask. Both are resampled with nearest neighbours so no depth is blended with background.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from beo_bench.errors import ViewError
from beo_bench.types import Mat3, Vec3

CROP_SIZE = 64
MARGIN = 1.25
"""Crop side = MARGIN x the larger side of the mask's bounding box (context at the edges)."""


@dataclass(frozen=True)
class Crop:
    """One crop and the frame it defines. ``image``: (2, S, S) float32; ``affine``: (2, 3)
    image pixel (u, v) -> crop pixel; ``R_ray``: (3, 3) ray frame -> camera frame;
    ``z_ref`` and ``scale`` in metres; ``mask``: (S, S) bool (channel 1)."""

    image: np.ndarray
    affine: np.ndarray
    R_ray: Mat3
    ray: Vec3
    """The ray through the crop centre with z = 1 (camera frame)."""
    z_ref: float
    scale: float

    @property
    def mask(self) -> np.ndarray:
        return self.image[1] > 0.5

    # -- targets <-> camera-frame pose -------------------------------------------------------
    def rotation_target(self, R_cam: Mat3) -> Mat3:
        return self.R_ray.T @ np.asarray(R_cam, dtype=np.float64)

    def rotation_from(self, R_rel: np.ndarray) -> np.ndarray:
        """Camera-frame rotations of ray-frame ones, (..., 3, 3)."""
        return np.einsum("ij,...jk->...ik", self.R_ray, R_rel)

    def _anchor(self) -> Vec3:
        return np.array([0.0, 0.0, self.z_ref * float(np.linalg.norm(self.ray))])

    def translation_target(self, t_cam: Vec3) -> Vec3:
        return (self.R_ray.T @ np.asarray(t_cam, dtype=np.float64) - self._anchor()) / self.scale

    def translation_from(self, offset: np.ndarray) -> Vec3:
        return self.R_ray @ (np.asarray(offset, dtype=np.float64) * self.scale + self._anchor())

    def size_target(self, size: Vec3) -> Vec3:
        return np.log(np.maximum(np.asarray(size, dtype=np.float64), 1e-4) / self.scale)

    def size_from(self, log_size: np.ndarray) -> Vec3:
        return np.exp(np.clip(np.asarray(log_size, dtype=np.float64), -6.0, 3.0)) * self.scale


def ray_rotation(ray: np.ndarray) -> Mat3:
    """The smallest rotation taking +z to the direction of ``ray`` (Rodrigues)."""
    d = np.asarray(ray, dtype=np.float64) / np.linalg.norm(ray)
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, d)
    c = float(d[2])
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3)
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def make_crop(
    depth: np.ndarray, mask: np.ndarray, K: Mat3, size: int = CROP_SIZE, margin: float = MARGIN
) -> Crop:
    """The crop of the object in ``mask`` (pixels with depth > 0 count). Raises
    :class:`ViewError` when no masked pixel has valid depth."""
    d = np.asarray(depth, dtype=np.float32)
    m = np.asarray(mask, dtype=bool) & np.isfinite(d) & (d > 0)
    vs, us = np.nonzero(m)
    if len(vs) == 0:
        raise ViewError(
            "the view's mask has no pixel with valid depth: HBEO needs at least one "
            "(check that the mask selects the object and depth is metric, 0 = no data)"
        )
    u0, u1, v0, v1 = us.min(), us.max(), vs.min(), vs.max()
    cu, cv = 0.5 * (u0 + u1), 0.5 * (v0 + v1)
    side = max(margin * (max(u1 - u0, v1 - v0) + 1), 8.0)
    k = size / side
    # integer-centred pixels: the crop's centre (S - 1) / 2 sits on the box centre (cu, cv)
    A = np.array([[k, 0.0, size / 2 - 0.5 - k * cu], [0.0, k, size / 2 - 0.5 - k * cv]])
    z_ref = float(np.median(d[vs, us]))
    Kd = np.asarray(K, dtype=np.float64)
    scale = side * z_ref / Kd[0, 0]
    dn = np.where(m, (d - z_ref) / scale, 0.0).astype(np.float32)
    flags = cv2.INTER_NEAREST
    ch0 = cv2.warpAffine(dn, A, (size, size), flags=flags, borderValue=0.0)
    ch1 = cv2.warpAffine(m.astype(np.float32), A, (size, size), flags=flags, borderValue=0.0)
    ray = np.linalg.solve(Kd, np.array([cu, cv, 1.0]))
    return Crop(
        image=np.stack([ch0, ch1]),
        affine=A,
        R_ray=ray_rotation(ray),
        ray=ray,
        z_ref=z_ref,
        scale=float(scale),
    )
