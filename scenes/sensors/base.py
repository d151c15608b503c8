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

import math
from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

from beo_bench.errors import BeoBenchError
from beo_bench.scenes.camera import Intrinsics
from beo_bench.scenes.renderer import Frame, Renderer
from beo_bench.types import Mat4

_BAND_ELEMENTS = 32768
"""Pixels in a band of rows that :meth:`Sensor.incidence_cos2` computes at a time (128 KB
per float32 temporary: a band's temporaries stay in a core's L2 cache)."""


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
        self._rays: (
            tuple[tuple[tuple[int, int], tuple[int, int]], tuple[np.ndarray, ...]] | None
        ) = None

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

    def _const(
        self, name: str, value: float, shape: tuple[int, ...], dtype: Any = np.float32
    ) -> np.ndarray:
        """An array of ``shape`` and ``dtype`` holding ``value`` everywhere, kept between
        captures (the source of a masked fill: ``cv2.copyTo`` from it is 5x faster than
        numpy's masked ``copyto``)."""
        a = self._scratch.get(name)
        if a is None or a.shape != shape or a.dtype != dtype:
            a = self._scratch[name] = np.full(shape, value, dtype=dtype)
        return a

    def _padded(self, z: np.ndarray) -> np.ndarray:
        """``z`` in a (h + 2, w + 1) scratch array with a NaN border (a row above and below,
        a column at the right) and NaN where it has no depth: on its flattened form a
        pixel's neighbours along the rows are 1 element away, along the columns w + 1, and
        a neighbour outside the image is NaN, as is one without depth."""
        import cv2

        h, w = z.shape
        p = self._buf("pad_z", shape=(h + 2, w + 1))
        p[0] = np.nan
        p[-1] = np.nan
        p[:, w] = np.nan
        inner = p[1:-1, :w]
        inner[:] = z
        hole = np.less_equal(z, 0, out=self._buf("pad_hole", bool, z.shape))
        cv2.copyTo(self._const("nan", np.nan, z.shape), hole.view(np.uint8), inner)
        return p

    def _select(self, flat: np.ndarray, i0: int, n: int, s: int, tag: str) -> np.ndarray:
        """The one-sided differences (see :meth:`_one_sided`) of the ``n`` elements of
        ``flat`` (a padded image, :meth:`_padded`, flattened) from ``i0`` on, with
        neighbours ``s`` elements away: a scratch array of ``n``.

        Branch-free: a difference without depth on both ends is NaN, which ``fmin`` passes
        over, so the backward difference is kept where its magnitude equals the pair's
        ``fmin`` (a tie keeps it too); a pixel left with NaN (no difference on either
        side) reads 0. The choice is a masked ``cv2.copyTo``, since a data-dependent
        ``np.where`` on a noisy surface mispredicts about every other pixel."""
        import cv2

        src = flat[i0 - s : i0 + n + s]
        d = np.subtract(src[s:], src[:-s], out=self._buf(tag + "d", shape=(n + s,)))
        m = np.abs(d, out=self._buf(tag + "m", shape=(n + s,)))
        # pixel j: backward d[j], forward d[j + s]
        lo = np.fmin(m[:-s], m[s:], out=self._buf(tag + "lo", shape=(n,)))
        back = np.equal(m[:-s], lo, out=self._buf(tag + "back", bool, (n,)))
        out = self._buf(tag + "out", shape=(n,))
        out[:] = d[s:]
        cv2.copyTo(d[:-s], back.view(np.uint8), out)
        cv2.patchNaNs(out.reshape(1, n), 0.0)
        return out

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
        smaller magnitude (:meth:`_one_sided`), so a pixel beside a depth jump gets the
        normal of its own surface rather than of the jump.

        Computed in bands of rows small enough that a band's dozen temporaries stay in the
        CPU's cache (a third faster than whole-image passes at 640x480, measured)."""
        import cv2

        h, w = depth.shape
        wp = w + 1
        padded = self._padded(depth)
        flat = padded.reshape(-1)
        c2 = np.empty((h, w), dtype=np.float32) if out is None else out
        rows = max(1, _BAND_ELEMENTS // wp)
        inv_f = np.float32(1.0 / self.f)
        tiny = np.float32(np.finfo(np.float32).tiny)
        ray_x, ray_y, ray_n2 = self._padded_rays(corner, (h, w))
        for r0 in range(0, h, rows):
            r1 = min(h, r0 + rows)
            n = (r1 - r0) * wp
            i0 = (r0 + 1) * wp
            shape = (r1 - r0, wp)
            zu = self._select(flat, i0, n, 1, "os1_").reshape(shape)
            zv = self._select(flat, i0, n, wp, "os0_").reshape(shape)
            zf = np.multiply(padded[r0 + 1 : r1 + 1], inv_f, out=self._buf("c2_zf", shape=shape))
            cv2.patchNaNs(zf, 0.0)  # no depth: z/f = 0
            tmp = self._buf("c2_tmp", shape=shape)
            nz = np.multiply(ray_x, zu, out=self._buf("c2_nz", shape=shape))
            nz += np.multiply(ray_y[r0:r1], zv, out=tmp)
            nz += zf
            nn = np.multiply(zu, zu, out=self._buf("c2_nn", shape=shape))
            nn += np.multiply(zv, zv, out=tmp)
            nn += np.multiply(nz, nz, out=tmp)
            nn *= ray_n2[r0:r1]
            zf *= zf
            # nn is 0 only where z is (then so is zf^2): the least normal float in its
            # place makes that pixel's quotient 0 without a masked divide, and changes no
            # other (nn >= (z/f)^2 |r|^2 elsewhere)
            np.maximum(nn, tiny, out=nn)
            np.divide(zf[:, :w], nn[:, :w], out=c2[r0:r1])
        return c2

    def _padded_rays(
        self, corner: tuple[int, int], shape: tuple[int, int]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The rays' x (1, w + 1), y (h, 1) and squared norm (h, w + 1) of the window of
        ``shape`` at ``corner``, in :meth:`_padded`'s layout (0 in the padding column);
        the last window's are kept."""
        key = (corner, shape)
        if self._rays is not None and self._rays[0] == key:
            rx, ry, n2 = self._rays[1]
            return rx, ry, n2
        (r, c), (h, w) = corner, shape
        rx = np.zeros((1, w + 1), np.float32)
        rx[0, :w] = self._ray_x[0, c : c + w]
        ry = np.ascontiguousarray(self._ray_y[r : r + h, 0:1])
        n2 = np.zeros((h, w + 1), np.float32)
        n2[:, :w] = self._ray_norm2[r : r + h, c : c + w]
        self._rays = (key, (rx, ry, n2))
        return rx, ry, n2

    def _one_sided(self, z: np.ndarray, axis: int) -> np.ndarray:
        """d z / d (pixel) along ``axis``: of the forward and backward differences, the one
        of smaller magnitude (0 at the image border and where no neighbour has depth).
        A view of a scratch array (valid until the next call for the same axis);
        :meth:`incidence_cos2` takes the same differences a band of rows at a time."""
        h, w = z.shape
        wp = w + 1
        flat = self._padded(z).reshape(-1)
        s = 1 if axis == 1 else wp
        return self._select(flat, wp, h * wp, s, f"os{axis}_").reshape(h, wp)[:, :w]

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
        import cv2

        h, w = depth.shape
        fb = np.float32(self.f * offset_x)
        valid = np.greater(depth, 0, out=self._buf("lit_valid", bool, depth.shape))
        out = np.zeros((h, w), dtype=bool)
        zmin, zmax, _, _ = cv2.minMaxLoc(depth, valid.view(np.uint8))
        if zmax <= 0:
            return out
        with np.errstate(divide="ignore"):
            x = np.divide(fb, depth, out=self._buf("lit_x", shape=depth.shape))
        np.subtract(self._cols[:, corner[1] : corner[1] + w], x, out=x)
        # x < (the least x strictly to the right) for b > 0; x > (the largest strictly to
        # the left) for b < 0. Only points within ``reach`` columns can hide one another:
        # x(u') - x(u) = u' - u - f b (1/z' - 1/z) exceeds 1 beyond it, so the running
        # extremum over that window of each row decides as the whole row's would. A
        # morphological erosion (dilation) with a 1 x window kernel takes it, doubled by
        # numpy passes where the window is wide (cv2's is linear in the kernel's width).
        reach = abs(float(fb)) * (1.0 / zmin - 1.0 / zmax) + 2.0
        window = int(min(w, math.ceil(reach)))
        right = offset_x >= 0
        fill = np.inf if right else -np.inf
        hole = np.logical_not(valid, out=self._buf("lit_inv", bool, (h, w)))
        cv2.copyTo(self._const(f"lit_fill{right}", fill, (h, w)), hole.view(np.uint8), x)
        k = min(window, 16)
        kernel = np.ones((1, k), np.uint8)
        a = self._buf("lit_a", shape=(h, w))
        b = self._buf("lit_b", shape=(h, w))
        if right:  # a[:, u] = min(x[:, u .. u + k - 1])
            cv2.erode(x, kernel, dst=a, anchor=(0, 0), borderType=cv2.BORDER_CONSTANT,
                      borderValue=fill)  # fmt: skip
        else:  # a[:, u] = max(x[:, u - k + 1 .. u])
            cv2.dilate(x, kernel, dst=a, anchor=(k - 1, 0), borderType=cv2.BORDER_CONSTANT,
                       borderValue=fill)  # fmt: skip
        op = np.minimum if right else np.maximum
        while k < window:
            if right:
                op(a[:, : w - k], a[:, k:], out=b[:, : w - k])
                b[:, w - k :] = a[:, w - k :]
            else:
                op(a[:, k:], a[:, : w - k], out=b[:, k:])
                b[:, :k] = a[:, :k]
            a, b = b, a
            k *= 2
        if right:
            nxt = a[:, 1:]
            nxt -= np.float32(1e-3)
            np.less(x[:, :-1], nxt, out=out[:, :-1])
            out[:, -1] = True
        else:
            prv = a[:, :-1]
            prv += np.float32(1e-3)
            np.greater(x[:, 1:], prv, out=out[:, 1:])
            out[:, 0] = True
        out &= valid
        return out


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
