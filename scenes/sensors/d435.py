"""``d435``: Intel RealSense D435 (active infrared stereo), simulated from first principles.

A capture renders what the device's hardware sees and matches it as a stereo camera does:

1. **Two infrared images.** The left imager is the depth camera (the D435's depth is in the
   left imager's frame); the right imager is ``BASELINE`` = 50 mm to its right (Intel
   RealSense D400 series datasheet, rev. 7 and later: D435 baseline 50 mm). Each is
   rendered from its own pose (the right one reuses the model the renderer already holds).
   A pixel's radiance is that of its surface point lit by the emitter: the point is
   projected into the emitter, which sits between the imagers, to read its dot pattern;
   the emitter's visibility (a point it does not light gets only ambient light, found along
   the epipolar rows: ``Sensor.lit_by``), Lambertian incidence falloff and inverse-square
   distance scale it; ambient light is added, then sensor noise (shot noise and read
   noise), and the image is quantised to 8 bits.
2. **Matching.** OpenCV's StereoSGBM (semi-global matching, Hirschmueller 2008) matches the
   pair, with its left-right check and speckle filter: occlusions, low texture and the
   left border band (where the right imager sees nothing of the left's view) come out
   invalid, and depth edges fatten by the matching window, as on the device. It searches
   the disparities of the scene's own depth range (:meth:`D435._window`), as the device
   does with its disparity shift set for the scene.
3. **Depth** is f b / d at the device's baseline, d SGBM's disparity refined to sub-pixel
   precision by a Lucas-Kanade step (see below).

The pattern is a fixed pseudo-random dot field (the D4 series' emitter projects a static
semi-random pattern: Grunnet-Jepsen, Sweetser and Woodfill 2018, "Projectors for Intel
RealSense depth cameras D4xx"), generated at the depth image's angular resolution so that
every image size is textured as the device is at its own. Its contrast and the noise are
a camera's (read noise and shot noise, at an auto-exposed mean of 60 DN). SGBM's sub-pixel
step fits a parabola to three integer costs and so pulls its estimate towards whole pixels
(pixel locking, Shimizu and Okutomi 2001), which the D4's matcher does not do to that
degree: the disparity is refined by one Lucas-Kanade step on the matching window
(:meth:`D435.refine`). The sensor noise is then the model's one calibrated figure, set so
that the matching precision on a lit plane is the D4 series' published sub-pixel RMS (about
0.08 px: Grunnet-Jepsen et al. 2018, "Tuning depth cameras for best performance", which
gives RMS depth error = z^2 sigma_d / (f b)); docs/sensors.md has the measured curve.
Intrinsics: the depth image's own (focal length from its size and field of view), with the
physical baseline, so the errors in metres follow f.
"""

from __future__ import annotations

import copy
import math
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from beo_bench.scenes.camera import Intrinsics
from beo_bench.scenes.renderer import Frame, Renderer
from beo_bench.scenes.sensors.base import Sensor, SensorError, gaussian
from beo_bench.types import Mat4

BASELINE = 0.050
"""Left to right imager (m): the D435's datasheet."""

EMITTER_X = 0.5 * BASELINE
"""The emitter between the imagers (m from the left one, along x)."""

MIN_Z = 0.32
"""The nearest depth the disparity search reaches (m): nearer than any suite's camera
(isolated views 0.45-0.8 m from their object, tabletop cameras 0.7-1.1 m from the table's
centre), so the search range never limits a suite; a nearer surface gets no depth. Each
capture searches the part of this range that its scene's depths span."""

PATTERN_SEED = 435
"""The dot pattern is the device's, the same in every capture (a fixed seed)."""

DOT_DENSITY = 0.1
"""Dot centres per image pixel (at the image's angular pitch)."""

DOT_SIGMA_PX = 1.2

PATTERN_OVERSAMPLE = 2
"""A dot's Gaussian radius (depth-image pixels)."""

EXPOSED_DN = 60.0
"""The mean emitter light the auto-exposure aims at (8-bit digital numbers); a dot's peak
is then about twice as bright."""

MAX_GAIN = 4000.0
"""The longest exposure, as a gain on a dot's peak at 1 m: a scene so far or dark that it
needs more stays darker. It lets the auto-exposure reach a lit plane beyond 3 m (the D435's
rated range), so that the precision follows z^2 out to there (at 400 it capped from 2 m and
sigma_d doubled at 3 m; at 1600 it capped from 2 m and sigma_d grew a third by 3 m,
measured)."""

AMBIENT_DN = 20.0
"""Ambient infrared on a surface (digital numbers, at the exposure)."""

READ_NOISE_DN = 2.0
SHOT_NOISE_GAIN = 0.5
"""Shot-noise variance per digital number of signal (DN^2 / DN: 2 electrons a DN). With the
read noise, the one calibrated figure of the model: set so that the matching precision on a
lit plane is the D4 series' published sub-pixel RMS, about 0.08 px (Grunnet-Jepsen et al.
2018); its growth with distance (z^2) and its fill rates are then predictions."""

TEXTURE_MIN_DN = 6.0
"""The least spread (standard deviation, digital numbers) of a matching window's intensity
that the device matches: above the sensor noise of a surface lit by ambient light alone
(3.7 DN at ``AMBIENT_DN``), far below the dot pattern's contrast (tens of DN)."""

MIN_SIDE = 32

SEARCH_MARGIN_PX = 2
"""Disparities searched beyond the scene's own, each way (px): SGBM's sub-pixel parabola
needs the costs on both sides of a match, and a match may stray by a pixel or two."""


PARALLEL_MIN_PIXELS = 65536
"""The least window (pixels) whose two infrared images are made in parallel: on a smaller
one a thread's hand-offs cost more than they save."""


def _area(box: tuple[slice, slice]) -> int:
    return int((box[0].stop - box[0].start) * (box[1].stop - box[1].start))


def _ceil16(x: float) -> int:
    return 16 * max(1, math.ceil(x / 16.0))


class D435(Sensor):
    """The D435 model of this module at any image size and field of view (at least
    ``MIN_SIDE`` pixels a side, and wider than the disparity search)."""

    name = "d435"
    citation = (
        "Intel RealSense D400 series datasheet (baseline 50 mm); Grunnet-Jepsen et al. 2018, "
        "'Tuning depth cameras for best performance' (sub-pixel RMS ~0.08 px, RMS error "
        "z^2 sigma_d / (f b)) and 'Projectors for Intel RealSense depth cameras D4xx'; "
        "Hirschmueller 2008 (semi-global matching, OpenCV StereoSGBM); Lucas and Kanade "
        "1981, Baker and Matthews 2004 (sub-pixel refinement)"
    )

    def __init__(self, intrinsics: Intrinsics) -> None:
        super().__init__(intrinsics)
        import cv2

        h, w = self.shape
        self.num_disparities = _ceil16(self.f * BASELINE / MIN_Z)
        if min(w, h) < MIN_SIDE or w <= self.num_disparities + 8:
            raise SensorError(
                f"sensor 'd435' at {w}x{h}: stereo matching needs at least {MIN_SIDE} pixels "
                f"a side and an image wider than its disparity search ({self.num_disparities} "
                "px for this field of view); use a larger image size or a wider field of view"
            )
        # The window and the speckle filter scale with the image (SGBM's defaults are for
        # VGA). Light smoothness penalties (P1, P2 = 1, 4 x window area, against OpenCV's
        # suggested 8, 32) keep SGBM's sub-pixel parabola from flattening: its error on a
        # lit plane, averaged over where the disparity falls between whole pixels, drops
        # from 0.16 px to 0.10 px (measured here; docs/sensors.md).
        block = 9 if min(w, h) >= 256 else 5
        self._block = block
        area = w * h / (640 * 480)
        self._matcher = cv2.StereoSGBM.create(
            minDisparity=0,
            numDisparities=self.num_disparities,
            blockSize=block,
            P1=1 * block * block,
            P2=4 * block * block,
            disp12MaxDiff=1,
            uniquenessRatio=10,
            speckleWindowSize=max(4, round(100 * area)),
            speckleRange=2,
            preFilterCap=31,
            mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY,
        )
        # the pattern in the emitter's image, at the depth image's focal length and wide
        # enough for both imagers' views (margins of the disparity search)
        # (PATTERN_OVERSAMPLE pattern pixels to an image pixel: an interpolated read of a
        # pattern sampled at the image's own pitch shifts its phase by a different amount
        # at each sub-pixel offset, which biases the two imagers' match towards whole pixels)
        m = self.num_disparities + 8
        o = PATTERN_OVERSAMPLE
        self._pw, self._ph = o * (w + 2 * m), o * (h + 2 * m)
        self._pcx = np.float32(o * (self.K[0, 2] + m))
        self._pcy = np.float32(o * (self.K[1, 2] + m))
        prng = np.random.default_rng(PATTERN_SEED)
        dots = (prng.random((self._ph, self._pw)) < DOT_DENSITY / (o * o)).astype(np.float32)
        pattern = cv2.GaussianBlur(dots, (0, 0), DOT_SIGMA_PX * o)
        self._pattern = (pattern / max(float(pattern.max()), 1e-6)).astype(np.float32)
        self._fb = np.float32(self.f * BASELINE)
        self._twin: D435 | None = None
        self._worker: tuple[int, ThreadPoolExecutor] | None = None
        # each pixel's pattern coordinates before its parallax to the emitter (which only
        # moves x): f ray + the pattern's centre, at the pattern's sampling
        self._rows_map = np.repeat(np.arange(h, dtype=np.float32)[:, None], w, axis=1)
        fo = np.float32(self.f * PATTERN_OVERSAMPLE)
        self._map_x = (self._ray_x * fo + self._pcx).astype(np.float32)
        self._map_y = (self._ray_y * fo + self._pcy).astype(np.float32)

    def _sense(
        self, renderer: Renderer, data: Any, cam_to_world: Mat4, rng: np.random.Generator,
        frame: Frame,
    ) -> Frame:  # fmt: skip
        import cv2

        T = np.asarray(cam_to_world, dtype=np.float64)
        right_pose = T.copy()
        right_pose[:3, 3] = T[:3, 3] + T[:3, 0] * BASELINE
        # The two imagers' images are independent: where the left imager sees a large area,
        # a worker thread makes the left image while this thread renders the right view
        # (MuJoCo, numpy and OpenCV release the GIL) and makes the right image. The left
        # image is made over its own surfaces' bounding box: outside it there is no surface
        # (no light, -1), and inside it every pixel reads as it would in a larger window.
        h, w = self.shape
        box = self._box(frame.depth) if h * w >= PARALLEL_MIN_PIXELS else None
        twin = None
        if box is not None and _area(box) >= PARALLEL_MIN_PIXELS:
            twin = self._twin_sensor()
            at = (box[0].start, box[1].start)
            job_l = self._pool().submit(twin.irradiance, frame.depth[box], 0.0, at)
        right = renderer.render_depth(data, right_pose)
        depth = np.zeros(self.shape, dtype=np.float32)
        found = self._window(frame.depth, right)
        if found is None:  # nothing within the far clip: no light comes back
            return Frame(depth=depth, segmentation=frame.segmentation)
        win, (d0, nd) = found
        rows, cols = win
        corner = (rows.start, cols.start)
        zl, zr = frame.depth[win], right[win]
        # the noise is drawn in one order (left, right), whichever thread draws or uses it
        noise_l = gaussian(rng, zl.size).reshape(zl.shape)
        if twin is None:
            noise_r = gaussian(rng, zr.size).reshape(zr.shape)
            right_e = self.irradiance(zr, BASELINE, corner)
            left = self.irradiance(zl, 0.0, corner)
        else:
            # the worker reads the right image's pattern term and draws its noise (after
            # the left's, drawn above) while this thread computes the rest of its light
            job_r = self._pool().submit(twin._dots_and_noise, zr, corner, rng)
            right_e = self._shade(zr, corner, lambda: job_r.result()[0])
            noise_r = job_r.result()[1]
            left = np.full(zl.shape, -1.0, dtype=np.float32)
            r0, c0 = at[0] - rows.start, at[1] - cols.start
            part = job_l.result()
            left[r0 : r0 + part.shape[0], c0 : c0 + part.shape[1]] = part
        gain = self.exposure(left)
        if twin is None:
            left_ir = self._expose(left, gain, noise_l)
            right_ir = self._expose(right_e, gain, noise_r)
        else:
            job_ir = self._pool().submit(twin._expose, right_e, gain, noise_r)
            left_ir = self._expose(left, gain, noise_l)
            right_ir = job_ir.result()
        self._matcher.setMinDisparity(d0)
        self._matcher.setNumDisparities(nd)
        if twin is None:
            flat, prep = self._prepare(left_ir, right_ir)
            disp = self._matcher.compute(left_ir, right_ir)
        else:  # what does not need the disparity, beside the matching
            job_prep = self._pool().submit(twin._prepare, left_ir, right_ir)
            disp = self._matcher.compute(left_ir, right_ir)
            flat, prep = job_prep.result()
        # SGBM's fixed point: 16 steps a pixel. Its invalid pixels read (d0 - 1) 16, below
        # every match: they read -16 here at any d0 (SGBM's value at d0 = 0). The windows
        # without texture (the device's texture threshold) read -1.
        shape = disp.shape
        if d0 > 0:
            invalid = np.equal(disp, 16 * (d0 - 1), out=self._buf("d_inv", bool, shape))
            cv2.copyTo(self._const("m16", -16, shape, np.int16), invalid.view(np.uint8), disp)
        cv2.copyTo(self._const("m1", -1, shape, np.int16), flat.view(np.uint8), disp)
        valid = np.greater(disp, 0, out=self._buf("d_valid", bool, shape))
        sub = self.refine(disp, left_ir, right_ir, prep)
        np.divide(self._fb, sub, out=depth[win], where=valid)
        return Frame(depth=depth, segmentation=frame.segmentation)

    def _box(self, depth: np.ndarray) -> tuple[slice, slice] | None:
        """The bounding box of the pixels of ``depth`` with a surface (None if none)."""
        seen = np.greater(depth, 0, out=self._buf("b_seen", bool, depth.shape))
        rows = np.flatnonzero(seen.any(axis=1))
        if not rows.size:
            return None
        cols = np.flatnonzero(seen.any(axis=0))
        return slice(int(rows[0]), int(rows[-1]) + 1), slice(int(cols[0]), int(cols[-1]) + 1)

    def _prepare(
        self, left: np.ndarray, right: np.ndarray
    ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """What follows the matching but does not need its disparity: the texture test
        (:meth:`textureless`) and :meth:`refine`'s images (see :meth:`_refine_images`)."""
        return self.textureless(left), self._refine_images(left, right)

    def _refine_images(
        self, left: np.ndarray, right: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`refine`'s images that do not depend on the disparity: the left image's
        horizontal gradient g, the window sums of g^2 and the right image in float32."""
        import cv2

        g: np.ndarray = cv2.Sobel(left, cv2.CV_32F, 1, 0, ksize=1, scale=0.5)
        g2 = np.multiply(g, g)
        den: np.ndarray = cv2.boxFilter(g2, -1, (self._block, self._block), normalize=False)
        return g, den, right.astype(np.float32)

    def _pool(self) -> ThreadPoolExecutor:
        """This sensor's worker thread, which makes the right imager's image (made on first
        use, and again in a forked child, which does not inherit the parent's thread)."""
        if self._worker is None or self._worker[0] != os.getpid():
            self._worker = (os.getpid(), ThreadPoolExecutor(1, thread_name_prefix="d435"))
        return self._worker[1]

    def _twin_sensor(self) -> D435:
        """A copy of this sensor with scratch arrays of its own (its constants shared), that
        makes the right imager's image in a worker thread."""
        if self._twin is None:
            twin = copy.copy(self)
            twin._scratch = {}
            twin._worker = None
            twin._rays = None
            self._twin = twin
        return self._twin

    def _dots_and_noise(
        self, z: np.ndarray, corner: tuple[int, int], rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray]:
        """The right imager's :meth:`_dots` and its image's noise (standard normal draws,
        one a pixel, from ``rng``)."""
        dots = self._dots(z, BASELINE, corner)
        return dots, gaussian(rng, z.size).reshape(z.shape)

    def refine(
        self,
        disp: np.ndarray,
        left: np.ndarray,
        right: np.ndarray,
        images: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    ) -> np.ndarray:
        """Float32 disparity (px): SGBM's (``disp``, in 1/16 px) refined by one Lucas-Kanade
        step on the matching window (Lucas and Kanade 1981, in its inverse-compositional
        form: Baker and Matthews 2004). SGBM's own sub-pixel step fits a parabola to three
        integer costs, which pulls its estimate towards whole pixels ("pixel locking",
        Shimizu and Okutomi 2001): on a lit plane half its error was that bias. The step
        warps the right image by SGBM's disparity (linear interpolation) and solves, per
        window, for the shift that best aligns it with the left one:
        e = sum(g (R_w - L)) / sum(g^2), g the left image's horizontal gradient. A step
        larger than a pixel (a window across a depth edge, or SGBM's match wrong) keeps
        SGBM's value. Invalid pixels keep theirs (negative). ``images``: those of
        :meth:`_refine_images` for ``left`` and ``right``, when they are already made."""
        import cv2

        h, w = disp.shape
        shape = disp.shape
        g, den, rf = self._refine_images(left, right) if images is None else images
        d = np.multiply(disp, np.float32(1.0 / 16.0), out=self._buf("r_d", shape=shape))
        mapx = np.subtract(self._cols[:, :w], d, out=self._buf("r_mapx", shape=shape))
        warped: np.ndarray = cv2.remap(
            rf, mapx, self._rows_map[:h, :w], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        )
        cv2.subtract(warped, left, dst=warped, dtype=cv2.CV_32F)
        warped *= g
        num = cv2.boxFilter(warped, -1, (self._block, self._block), normalize=False)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.divide(num, den, out=num)
        # NaN (no gradient in the window) is not below 1
        ok = np.abs(step, out=self._buf("r_abs", shape=shape))
        ok = np.less(ok, np.float32(1.0), out=self._buf("r_ok", bool, shape))
        np.add(d, step, out=d, where=ok)
        return d

    def _window(
        self, left: np.ndarray, right: np.ndarray
    ) -> tuple[tuple[slice, slice], tuple[int, int]] | None:
        """The part of the image that is matched and the disparities searched there.

        The window: the rows and columns where either imager sees a surface, widened by
        the matching window and, to the left, by the disparity search (where the left
        imager's pixels find their partners). Outside it both IR images are dark, the
        matcher finds no texture there, and the depth is invalid anyway; matching only
        inside makes an isolated object's capture 10x cheaper.

        The search (first disparity, number of disparities): the disparities of the
        scene's surfaces, from its farthest to its nearest (f b / z), widened by
        ``SEARCH_MARGIN_PX`` each way and rounded up to SGBM's multiple of 16, within the
        fixed range down to ``MIN_Z``. The D4 searches a fixed number of disparities from
        a first one, its "disparity shift", that is set for the scene's depth range
        (Grunnet-Jepsen et al. 2018, "Tuning depth cameras for best performance"); here the
        number too is the scene's: a match outside the scene's disparities could only be
        wrong, and SGBM's cost is proportional to the number it searches.

        None when neither imager sees a surface."""
        import cv2

        lseen = np.greater(left, 0, out=self._buf("w_l", bool, left.shape))
        rseen = np.greater(right, 0, out=self._buf("w_r", bool, right.shape))
        zmin, zmax = math.inf, 0.0
        for z, m in ((left, lseen), (right, rseen)):
            lo, hi, _, _ = cv2.minMaxLoc(z, m.view(np.uint8))
            if hi > 0:
                zmin, zmax = min(zmin, lo), max(zmax, hi)
        if zmax <= 0:
            return None
        seen = np.logical_or(lseen, rseen, out=lseen)
        rows = np.flatnonzero(seen.any(axis=1))
        cols = np.flatnonzero(seen.any(axis=0))
        fb = float(self._fb)
        top = self.num_disparities
        d1 = min(top, math.ceil(fb / zmin) + SEARCH_MARGIN_PX)
        d0 = max(0, min(d1, math.floor(fb / zmax)) - SEARCH_MARGIN_PX)
        nd = _ceil16(d1 - d0)
        d0 = max(0, min(d0, top - nd))
        h, w = self.shape
        pad = self._block
        reach = d0 + nd  # the search's last disparity + 1
        c0 = max(0, int(cols[0]) - reach - pad)
        c1 = min(w, int(cols[-1]) + 1 + pad)
        if c1 - c0 <= reach + pad:  # the matcher needs room for its search
            c0 = max(0, c1 - reach - 2 * pad - 1)
            c1 = min(w, c0 + reach + 2 * pad + 1)
        win = slice(max(0, int(rows[0]) - pad), min(h, int(rows[-1]) + 1 + pad)), slice(c0, c1)
        return win, (d0, nd)

    def textureless(self, image: np.ndarray) -> np.ndarray:
        """Bool: the pixels whose matching window's intensity spreads less than
        ``TEXTURE_MIN_DN`` (standard deviation): the device invalidates them (the D4's
        texture threshold, Grunnet-Jepsen et al. 2018), where SGBM alone would match
        sensor noise: a projector shadow lit only by even ambient light, or the dark
        beyond the far clip."""
        import cv2

        k = (self._block, self._block)
        n = self._block * self._block
        # the window's variance E[I^2] - E[I]^2 times n^2, n S2 - S1^2 of the window's sums
        # of intensities and of their squares: in integers, exactly (below 2^31 for 8-bit
        # images and windows of up to 13 x 13 pixels)
        rep = cv2.BORDER_REPLICATE
        s1 = np.asarray(
            cv2.boxFilter(image, cv2.CV_32S, k, normalize=False, borderType=rep), np.int32
        )
        s2 = np.asarray(
            cv2.sqrBoxFilter(image, cv2.CV_32S, k, normalize=False, borderType=rep), np.int32
        )
        s2 *= n
        s1 *= s1
        s2 -= s1
        return np.less(
            s2, round(TEXTURE_MIN_DN**2) * n * n, out=self._buf("t_flat", bool, s2.shape)
        )

    def irradiance(
        self, depth: np.ndarray, at_x: float, corner: tuple[int, int] = (0, 0)
    ) -> np.ndarray:
        """The emitter's light (in units of a dot's peak at 1 m, frontal) on each pixel of an
        imager ``at_x`` metres right of the left one whose depth image is ``depth`` (or a
        window of it with top-left pixel ``corner``): the pattern read where each surface
        point projects into the emitter, its visibility, Lambertian incidence and
        inverse-square falloff; -1 where there is no surface."""
        return self._shade(depth, corner, self._dots(depth, at_x, corner))

    def _dots(self, z: np.ndarray, at_x: float, corner: tuple[int, int]) -> np.ndarray:
        """:meth:`irradiance`'s pattern term: the pattern read where each surface point
        projects into the emitter, 0 where the emitter lights no surface."""
        import cv2

        shape = z.shape
        win = (slice(corner[0], corner[0] + shape[0]), slice(corner[1], corner[1] + shape[1]))
        # which points the emitter lights (only points with depth are)
        lit = self.lit_by(z, float(EMITTER_X - at_x), corner)
        # the surface point in the emitter's frame (same orientation, EMITTER_X - at_x to
        # the right of this imager): its pattern coordinates, x = f (ray_x - ex / z) + cx
        fex = np.float32((EMITTER_X - at_x) * self.f * PATTERN_OVERSAMPLE)
        with np.errstate(divide="ignore", invalid="ignore"):
            mapx = np.divide(fex, z, out=self._buf("i_mapx", shape=shape))
        np.subtract(self._map_x[win], mapx, out=mapx)
        # outside the pattern (no dot light) where the emitter lights no surface
        unlit = np.logical_not(lit, out=self._buf("i_unlit", bool, shape))
        cv2.copyTo(self._const("m1f", -1.0, shape), unlit.view(np.uint8), mapx)
        dots: np.ndarray = cv2.remap(
            self._pattern, mapx, self._map_y[win], cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT, borderValue=0.0,
        )  # fmt: skip
        return dots

    def _shade(
        self, z: np.ndarray, corner: tuple[int, int], dots: np.ndarray | Callable[[], np.ndarray]
    ) -> np.ndarray:
        """:meth:`irradiance` from its pattern term ``dots`` (:meth:`_dots`; or a function
        that returns it, called once the rest is done): Lambertian incidence and inverse-square
        falloff times the pattern; -1 where there is no surface."""
        import cv2

        shape = z.shape
        invalid = np.less_equal(z, 0, out=self._buf("i_inv", bool, shape))
        light = self.incidence_cos2(z, corner=corner)
        np.sqrt(light, out=light)
        with np.errstate(divide="ignore", invalid="ignore"):
            light /= z
            light /= z
        light *= dots if isinstance(dots, np.ndarray) else dots()
        cv2.copyTo(self._const("m1f", -1.0, shape), invalid.view(np.uint8), light)
        return light

    def exposure(self, irradiance: np.ndarray) -> float:
        """The auto-exposure gain (the D4 series exposes automatically by default): the mean
        emitter light on the left image's surfaces is brought to ``EXPOSED_DN``, within
        the longest exposure ``MAX_GAIN``; both imagers share it."""
        seen = irradiance[irradiance > 0]
        mean = float(seen.mean()) if seen.size else 0.0
        return min(MAX_GAIN, EXPOSED_DN / mean) if mean > 0 else MAX_GAIN

    def expose(self, irradiance: np.ndarray, gain: float, rng: np.random.Generator) -> np.ndarray:
        """The 8-bit image: emitter light and ambient light on the surfaces, times the
        exposure, with shot and read noise; nothing (0 plus noise) where there is no
        surface within the far clip."""
        return self._expose(irradiance, gain, gaussian(rng, irradiance.size))

    def _expose(self, irradiance: np.ndarray, gain: float, noise: np.ndarray) -> np.ndarray:
        """:meth:`expose` with its standard normal draws ``noise`` (one a pixel)."""
        import cv2

        shape = irradiance.shape
        surface = np.greater_equal(irradiance, 0, out=self._buf("e_surf", bool, shape))
        signal = np.maximum(irradiance, np.float32(0.0), out=self._buf("e_sig", shape=shape))
        signal *= np.float32(gain)
        np.add(signal, np.float32(AMBIENT_DN), out=signal, where=surface)
        sigma = np.multiply(signal, np.float32(SHOT_NOISE_GAIN), out=self._buf("e_sd", shape=shape))
        sigma += np.float32(READ_NOISE_DN**2)
        np.sqrt(sigma, out=sigma)
        sigma *= noise.reshape(shape)
        signal += sigma
        # rounded half to even and saturated to 0-255, as np.clip(np.rint(.)) would
        out = cv2.add(signal, self._const("zero", 0.0, shape), dtype=cv2.CV_8U)
        return np.asarray(out, dtype=np.uint8)
