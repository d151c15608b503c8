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
        self._cols = np.arange(w, dtype=np.float32)[None, :]
        self._scratch: dict[str, np.ndarray] = {}

    def _buf(
        self, name: str, dtype: Any = np.float32, shape: tuple[int, ...] | None = None
    ) -> np.ndarray:
        """A scratch array kept between captures (a capture's temporaries would otherwise
        be fresh mappings of the allocator, page-faulted on first touch: a third of a
        640x480 capture's time, measured). Its contents are whatever was left in it."""
        shape = self.shape if shape is None else shape
        a = self._scratch.get(name)
        if a is None or a.shape != shape or a.dtype != dtype:
            a = self._scratch[name] = np.empty(shape, dtype=dtype)
        return a

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
    def incidence_cos2(
        self, depth: np.ndarray, out: np.ndarray | None = None, corner: tuple[int, int] = (0, 0)
    ) -> np.ndarray:
        """Float32 squared cosine of the angle between each pixel's surface normal and its
        viewing ray; 0 where there is no depth. Written into ``out`` if given. ``depth``
        is the image, or a window of it whose top-left pixel is ``corner`` (row, column).

        The normal comes from the depth image: with P(u, v) = z r(u, v) and
        r = ((u - cx)/f, (v - cy)/f, 1) = (a, b, 1), the cross product of dP/du and dP/dv is
        proportional to n' = (-z_u, -z_v, a z_u + b z_v + z/f), and n' . r = z/f, so
        cos^2 = (z/f)^2 / (|n'|^2 |r|^2). The derivatives take the one-sided difference of
        smaller magnitude, so a pixel beside a depth jump gets the normal of its own
        surface rather than of the jump."""
        z = depth
        win = _window(z.shape, corner)
        zu = self._one_sided(z, axis=1)
        zv = self._one_sided(z, axis=0)
        zf = np.multiply(z, np.float32(1.0 / self.f), out=self._buf("c2_zf", shape=z.shape))
        tmp = self._buf("c2_tmp", shape=z.shape)
        nz = np.multiply(self._ray_x[win], zu, out=self._buf("c2_nz", shape=z.shape))
        nz += np.multiply(self._ray_y[win], zv, out=tmp)
        nz += zf
        nn = np.multiply(zu, zu, out=self._buf("c2_nn", shape=z.shape))
        nn += np.multiply(zv, zv, out=tmp)
        nn += np.multiply(nz, nz, out=tmp)
        nn *= self._ray_norm2[win]
        zf *= zf
        if out is None:
            c2 = np.zeros(z.shape, dtype=np.float32)
        else:
            c2 = out
            c2.fill(0.0)
        hit = np.greater(nn, 0, out=self._buf("c2_hit", bool, z.shape))
        with np.errstate(invalid="ignore", divide="ignore"):
            np.divide(zf, nn, out=c2, where=hit)
        return c2

    def _one_sided(self, z: np.ndarray, axis: int) -> np.ndarray:
        """d z / d (pixel) along ``axis``: of the forward and backward differences, the one
        of smaller magnitude (0 at the image border and where no neighbour has depth).
        Returns a scratch array (valid until the next call for the same axis).

        On the flattened image (a neighbour along the rows is 1 element away, along the
        columns ``w``; the pairs that wrap across a row end are masked), and branch-free:
        the choice between the two differences is a bit mask on their float32 bit patterns,
        since a data-dependent ``np.where`` on a noisy surface mispredicts about every
        other pixel (the two together are 3x faster at 640x480, measured)."""
        h, w = z.shape
        n = h * w
        s = 1 if axis == 1 else w
        tag = f"os{axis}_"
        flat = z.reshape(-1)
        a, b = flat[s:], flat[:-s]
        d = np.subtract(a, b, out=self._buf(tag + "d", shape=(n - s,)))  # z[i + s] - z[i]
        ok = np.greater(a, 0, out=self._buf(tag + "ok", bool, (n - s,)))
        nb = np.greater(b, 0, out=self._buf(tag + "nb", bool, (n - s,)))
        ok &= nb
        if axis == 1:
            ok[w - 1 :: w] = False  # z[i + 1] is the next row's first pixel
        d *= ok  # a difference without depth on both sides reads 0 ...
        m = np.abs(d, out=self._buf(tag + "m", shape=(n - s,)))
        np.logical_not(ok, out=nb)
        np.copyto(m, np.float32(3e38), where=nb)  # ... and loses every comparison
        # pixel i (s <= i < n - s): backward d[i - s], forward d[i]
        le = np.less_equal(m[:-s], m[s:], out=self._buf(tag + "le", bool, (n - 2 * s,)))
        keep = self._buf(tag + "keep", np.int32, (n - 2 * s,))
        keep[:] = le
        np.negative(keep, out=keep)  # all ones where the backward difference is kept
        out = self._buf(tag + "out", shape=(n,))
        inner = out[s:-s].view(np.int32)
        np.bitwise_and(d[:-s].view(np.int32), keep, out=inner)
        np.invert(keep, out=keep)
        np.bitwise_and(d[s:].view(np.int32), keep, out=keep)
        np.bitwise_or(inner, keep, out=inner)
        out[:s] = d[:s]  # no backward neighbour
        out[-s:] = d[-s:]  # no forward neighbour
        return out.reshape(h, w)

    def lit_by(
        self, depth: np.ndarray, offset_x: float, corner: tuple[int, int] = (0, 0)
    ) -> np.ndarray:
        """Bool: which pixels of ``depth`` (the image, or a window of it whose top-left
        pixel is ``corner``, holding every pixel with depth) a device ``offset_x`` metres
        along the camera's x axis (a projector, or a second camera) sees.

        With the offset along x the two devices' epipolar lines are the image rows, so
        visibility is a scan per row: a point at column u appears to the other device at
        column x = u - f b / z (b = ``offset_x``), and for b > 0 it is hidden when a point
        further right in the row appears at or left of it (x(u') <= x(u) for some u' > u:
        the device's ray to it passes through a nearer surface); b < 0 mirrors this. No
        second render is needed. Occluders the camera does not see (outside its image) are
        not known, and the other device is taken to see at least the camera's field."""
        h, w = depth.shape
        fb = np.float32(self.f * offset_x)
        valid = np.greater(depth, 0, out=self._buf("lit_valid", bool, depth.shape))
        with np.errstate(divide="ignore"):
            x = np.divide(fb, depth, out=self._buf("lit_x", shape=depth.shape))
        np.subtract(self._cols[:, corner[1] : corner[1] + w], x, out=x)
        # x < (the least x strictly to the right) for b > 0; x > (the largest strictly to
        # the left) for b < 0: a running extremum along each row, by doubling (log2(w)
        # passes) on the transposed image, whose rows are then contiguous blocks (numpy's
        # ufunc.accumulate runs element by element: 3x slower at 640x480, measured)
        right = offset_x >= 0
        fill = np.float32(np.inf if right else -np.inf)
        np.copyto(x, fill, where=np.logical_not(valid, out=self._buf("lit_inv", bool, (h, w))))
        op = np.minimum if right else np.maximum
        a = self._buf("lit_a", shape=(w + 1, h))  # column u of x is a[u] (right) or a[u + 1]
        b = self._buf("lit_b", shape=(w + 1, h))
        edge = w if right else 0
        a[edge] = fill
        b[edge] = fill
        (a[:w] if right else a[1:])[:] = x.T
        step = 1
        while step < w:
            if right:  # a[u] = min(x[u .. u + 2 step - 1])
                op(a[: w - step], a[step:w], out=b[: w - step])
                b[w - step : w] = a[w - step : w]
            else:  # a[u + 1] = max(x[u - 2 step + 1 .. u])
                op(a[step + 1 :], a[1 : w + 1 - step], out=b[step + 1 :])
                b[1 : step + 1] = a[1 : step + 1]
            a, b = b, a
            step *= 2
        out = np.empty((h, w), dtype=bool)
        if right:
            nxt = a[1:]
            nxt -= np.float32(1e-3)
            np.less(x, nxt.T, out=out)
        else:
            prv = a[:w]
            prv += np.float32(1e-3)
            np.greater(x, prv.T, out=out)
        out &= valid
        return out


def _window(shape: tuple[int, ...], corner: tuple[int, int]) -> tuple[slice, slice]:
    r, c = corner
    return slice(r, r + shape[0]), slice(c, c + shape[1])


def gaussian(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` float32 standard normal draws from ``rng``, by the Box-Muller transform of
    float32 uniforms (Box and Muller 1958): three times faster than
    ``Generator.standard_normal`` at a depth image's size (1.0 vs 3.3 ms for 640x480,
    measured), which is most of a structured-light capture's cost."""
    half = (n + 1) // 2
    u = rng.random(2 * half, dtype=np.float32)
    r = np.log1p(-u[:half])  # 1 - u is in (0, 1]: the log is finite
    r *= np.float32(-2.0)
    np.sqrt(r, out=r)
    t = u[half:]
    t *= np.float32(2.0 * np.pi)
    out = np.empty(2 * half, dtype=np.float32)
    np.cos(t, out=out[:half])
    np.sin(t, out=out[half:])
    out[:half] *= r
    out[half:] *= r
    return out[:n]
