"""What every depth sensor shares: the interface, its errors and the geometry of an active
sensor (a camera beside a projector or a second camera at a baseline).

A sensor turns the scene a :class:`~beo_bench.scenes.renderer.Renderer` is bound to into
the depth image a real device would return. It may render the scene again from other poses
(the projector, the right camera): those renders reuse the model the renderer already holds,
so a capture never compiles anything. Segmentation stays the ideal camera's (the benchmark's
masks are ground truth, as the dissertation's were); a pixel a sensor leaves without depth
reads 0, so ``mask & (depth > 0)`` is what a backend can use.

Intrinsics scale with the image (docs/sensors.md, "Any size"): a sensor's parameters are
physical (a baseline in metres, a noise in metres or in pixels *of the device's own camera*,
converted through the ratio of focal lengths), so one sensor runs at any image size and
field of view, and its errors in metres stay those of the device.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

from beo_bench.errors import BeoBenchError
from beo_bench.scenes.camera import Intrinsics
from beo_bench.scenes.renderer import Frame, Renderer
from beo_bench.types import Mat4


class SensorError(BeoBenchError, ValueError):
    """A sensor that does not exist, or one asked for at an image size or field of view it
    cannot support (the message says which sizes it can)."""

    exit_code = 2


class Sensor(ABC):
    """A depth sensor at ``intrinsics`` (image size and field of view of its depth image).

    :meth:`capture` is the hot path: called once per observation, it allocates only its
    outputs and what numpy's element-wise operations need."""

    name: ClassVar[str]
    citation: ClassVar[str] = ""
    """The published sources of the sensor's parameters (docs/sensors.md quotes them)."""

    def __init__(self, intrinsics: Intrinsics) -> None:
        self.intrinsics = intrinsics
        self.K = intrinsics.K
        self.f = float(intrinsics.focal)
        w, h = int(intrinsics.width), int(intrinsics.height)
        self.shape = (h, w)
        # rays through the pixel centres, z = 1 (OpenCV axes): points are z * ray
        u = (np.arange(w, dtype=np.float32) - np.float32(self.K[0, 2])) / np.float32(self.f)
        v = (np.arange(h, dtype=np.float32) - np.float32(self.K[1, 2])) / np.float32(self.f)
        self._ray_x = np.broadcast_to(u[None, :], (h, w))
        self._ray_y = np.broadcast_to(v[:, None], (h, w))
        self._ray_norm2 = (self._ray_x**2 + self._ray_y**2 + np.float32(1.0)).astype(np.float32)

    def capture(
        self,
        renderer: Renderer,
        data: Any,
        cam_to_world: Mat4,
        rng: np.random.Generator,
        frame: Frame | None = None,
    ) -> Frame:
        """The depth and segmentation this sensor returns of ``data``'s scene (the model
        ``renderer`` is bound to) with its depth camera at ``cam_to_world`` (OpenCV axes).
        ``frame``: the ideal render from ``cam_to_world``, when the caller already has it
        (it is not rendered again). ``rng`` draws every random effect."""
        if frame is None:
            frame = renderer.render(data, cam_to_world)
        return self._sense(renderer, data, cam_to_world, rng, frame)

    @abstractmethod
    def _sense(
        self, renderer: Renderer, data: Any, cam_to_world: Mat4, rng: np.random.Generator,
        frame: Frame,
    ) -> Frame:  # fmt: skip
        """What the device returns, given the ideal render ``frame`` of the same pose."""

    @property
    def ideal(self) -> bool:
        """Whether the sensor returns the render as it is (no draw from ``rng``)."""
        return False

    # -- geometry shared by the active sensors ---------------------------------------------------
    def incidence_cos2(self, depth: np.ndarray) -> np.ndarray:
        """(H, W) float32 squared cosine of the angle between each pixel's surface normal and
        its viewing ray; 0 where there is no depth.

        The normal comes from the depth image: with P(u, v) = z r(u, v) and
        r = ((u - cx)/f, (v - cy)/f, 1) = (a, b, 1), the cross product of dP/du and dP/dv is
        proportional to n' = (-z_u, -z_v, a z_u + b z_v + z/f), and n' . r = z/f, so
        cos^2 = (z/f)^2 / (|n'|^2 |r|^2). The derivatives take the one-sided difference of
        smaller magnitude, so a pixel beside a depth jump gets the normal of its own
        surface rather than of the jump."""
        z = depth
        zu = _one_sided(z, axis=1)
        zv = _one_sided(z, axis=0)
        zf = z * np.float32(1.0 / self.f)
        nz = self._ray_x * zu
        nz += self._ray_y * zv
        nz += zf
        nn = zu * zu
        nn += zv * zv
        nn += nz * nz
        nn *= self._ray_norm2
        zf *= zf
        with np.errstate(invalid="ignore", divide="ignore"):
            c2 = np.divide(zf, nn, out=np.zeros_like(zf), where=nn > 0)
        return c2

    def lit_by(self, depth: np.ndarray, offset_x: float) -> np.ndarray:
        """(H, W) bool: which pixels of ``depth`` a device ``offset_x`` metres along the
        camera's x axis (a projector, or a second camera) sees.

        With the offset along x the two devices' epipolar lines are the image rows, so
        visibility is a scan per row: a point at column u appears to the other device at
        column x = u - f b / z (b = ``offset_x``), and for b > 0 it is hidden when a point
        further right in the row appears at or left of it (x(u') <= x(u) for some u' > u:
        the device's ray to it passes through a nearer surface); b < 0 mirrors this. No
        second render is needed. Occluders the camera does not see (outside its image) are
        not known, and the other device is taken to see at least the camera's field."""
        h, w = self.shape
        fb = np.float32(self.f * offset_x)
        cols = np.arange(w, dtype=np.float32)[None, :]
        valid = depth > 0
        with np.errstate(divide="ignore"):
            shift = fb / depth
        if offset_x >= 0:
            x = np.where(valid, cols - shift, np.float32(np.inf))
            # the least x strictly to the right of each pixel
            after = np.minimum.accumulate(x[:, ::-1], axis=1)[:, ::-1]
            nxt = np.full((h, w), np.inf, dtype=np.float32)
            nxt[:, :-1] = after[:, 1:]
            return valid & (x < nxt - np.float32(1e-3))
        x = np.where(valid, cols - shift, np.float32(-np.inf))
        before = np.maximum.accumulate(x, axis=1)
        prv = np.full((h, w), -np.inf, dtype=np.float32)
        prv[:, 1:] = before[:, :-1]
        return valid & (x > prv + np.float32(1e-3))


def _one_sided(z: np.ndarray, axis: int) -> np.ndarray:
    """d z / d (pixel) along ``axis``: of the forward and backward differences, the one of
    smaller magnitude (0 at the image border and where no neighbour has depth)."""
    valid = z > 0
    d = np.diff(z, axis=axis)
    if axis == 0:
        ok = valid[:-1] & valid[1:]
    else:
        ok = valid[:, :-1] & valid[:, 1:]
    inf = np.float32(np.inf)
    d = np.where(ok, d, inf)
    front = [(0, 0), (0, 0)]
    back = [(0, 0), (0, 0)]
    front[axis] = (1, 0)
    back[axis] = (0, 1)
    bwd = np.pad(d, front, constant_values=inf)  # z[i] - z[i-1]
    fwd = np.pad(d, back, constant_values=inf)  # z[i+1] - z[i]
    out = np.where(np.abs(bwd) <= np.abs(fwd), bwd, fwd)
    return np.where(np.isfinite(out), out, np.float32(0.0)).astype(np.float32)
