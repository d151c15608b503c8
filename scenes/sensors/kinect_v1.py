"""``kinect-v1``: Microsoft Kinect v1 (PrimeSense structured light), from published
measurements.

Effects, each from its source (docs/sensors.md has the curves and the validation):

1. **Projector shadows.** The IR projector sits ``BASELINE`` = 7.5 cm beside the IR camera
   (Khoshelham and Elberink 2012, section 2); a point the projector does not light has no
   depth. The projector is on the camera's +x side, so the shadow of an object falls on its
   left in the image, ``f b (1/z_front - 1/z_back)`` pixels wide. Found along the image
   rows, which are the projector's epipolar lines (``Sensor.lit_by``); the projector
   lights all the camera sees, so only occlusion makes shadows.
2. **Lateral noise** (Nguyen, Izadi and Lovell 2012, eq. 2):
   sigma_L(theta) [px] = 0.8 + 0.035 theta / (pi/2 - theta), in pixels of the Kinect's
   camera (f = 585 px): an edge's position jitters by that much. Drawn per 2x2 pixel block
   (the device correlates a window around each pixel, so neighbours move together) and
   applied where a depth edge is within reach: a pixel takes the depth of the pixel its
   displacement lands on.
3. **Axial noise** (Nguyen et al. 2012, eq. 1): sigma_z(z, theta) = 0.0012 + 0.0019 (z -
   0.4)^2 m for theta <= 60 deg, plus 0.0001/sqrt(z) theta^2 / (pi/2 - theta)^2 beyond; theta
   is the angle between the surface normal and the viewing ray. Drawn per 2x2 pixel block,
   as the lateral noise (the device's depth comes from a correlation window): each pixel's
   spread is Nguyen's, and neighbours err together.
4. **Disparity quantisation** to 1/8 pixel (Konolige and Mihelich 2011, "Technical
   description of Kinect calibration": disparity is reported in 1/8-pixel units), at the
   device's own focal length and baseline: a step of z^2 / (8 f b). Nguyen's curves are
   the output's spread, quantisation included, so the Gaussian part is drawn with
   sigma^2 - step^2 / 12 (the variance a uniform rounding adds; Sheppard's correction).
5. **No return at grazing incidence:** beyond ``MAX_INCIDENCE_DEG`` the speckle is too
   foreshortened to correlate. Nguyen et al.'s plane measurements end at about 80 degrees;
   the limit is this model's choice at that end, not a measured cut-off.

Not modelled: range limits (the suites' cameras are 0.45-1.1 m from their objects, inside
the device's 0.4-4 m), IR interference, and the slow depth bias of an uncalibrated unit.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from beo_bench.scenes.camera import Intrinsics
from beo_bench.scenes.renderer import Frame, Renderer
from beo_bench.scenes.sensors.base import Sensor, SensorError, gaussian
from beo_bench.types import Mat4

BASELINE = 0.075
"""Projector to IR camera (m): Khoshelham and Elberink 2012."""

NATIVE_FOCAL_PX = 585.0
"""The Kinect IR camera's focal length at 640x480 (px), the one Nguyen et al. 2012 convert
lateral noise with (their eq. 3)."""

DISPARITY_STEP = 1.0 / 8.0
"""Sub-pixel resolution of the reported disparity (px of the native camera)."""

AXIAL_A, AXIAL_B, AXIAL_Z0 = 0.0012, 0.0019, 0.4
"""Nguyen et al. 2012 eq. 1: sigma_z = a + b (z - z0)^2 (m, m/m^2, m)."""

AXIAL_GRAZING = 0.0001
"""Nguyen et al. 2012 eq. 1 beyond 60 deg: + c / sqrt(z) theta^2 / (pi/2 - theta)^2 (m)."""

AXIAL_KNEE_DEG = 60.0

LATERAL_A, LATERAL_B = 0.8, 0.035
"""Nguyen et al. 2012 eq. 2: sigma_L = a + b theta / (pi/2 - theta) (native px)."""

MAX_INCIDENCE_DEG = 80.0

LATERAL_BLOCK = 2
"""Side of the pixel blocks a lateral displacement is shared by."""

EDGE_SLOPES = 4.0
"""A depth edge: the 3x3 range of depth exceeds this many times the step between
neighbours of a surface at the incidence limit (z tan(80 deg) / f), so that no plane the
sensor returns counts as an edge, however slanted."""

MIN_SIDE = 8


def axial_sigma(z: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Nguyen et al. 2012 eq. 1: the axial standard deviation (m) at depth ``z`` (m) and
    incidence ``theta`` (rad)."""
    z = np.asarray(z, dtype=np.float64)
    theta = np.asarray(theta, dtype=np.float64)
    base = AXIAL_A + AXIAL_B * (z - AXIAL_Z0) ** 2
    knee = math.radians(AXIAL_KNEE_DEG)
    with np.errstate(divide="ignore", invalid="ignore"):
        extra = AXIAL_GRAZING / np.sqrt(np.maximum(z, 1e-6)) * theta**2 / (math.pi / 2 - theta) ** 2
    return np.where(theta > knee, base + extra, base)


def lateral_sigma_px(theta: np.ndarray) -> np.ndarray:
    """Nguyen et al. 2012 eq. 2: the lateral standard deviation in the native camera's
    pixels at incidence ``theta`` (rad)."""
    theta = np.asarray(theta, dtype=np.float64)
    return LATERAL_A + LATERAL_B * theta / (math.pi / 2 - theta)


def quantisation_step(z: np.ndarray) -> np.ndarray:
    """The depth step (m) of one 1/8-pixel disparity step at depth ``z``."""
    return np.asarray(z, dtype=np.float64) ** 2 / (NATIVE_FOCAL_PX * BASELINE) * DISPARITY_STEP


class KinectV1(Sensor):
    """The Kinect v1 model of this module at any image size and field of view: its errors
    in metres are the device's, its lateral noise in pixels scales with the focal length
    (f / 585 px)."""

    name = "kinect-v1"
    citation = (
        "Nguyen, Izadi and Lovell 2012 (3DIMPVT), 'Modeling Kinect sensor noise for improved "
        "3D reconstruction and tracking', eqs. 1-3; Khoshelham and Elberink 2012 (Sensors "
        "12(2)), baseline; Konolige and Mihelich 2011, 1/8-pixel disparity"
    )

    def __init__(self, intrinsics: Intrinsics) -> None:
        if min(intrinsics.width, intrinsics.height) < MIN_SIDE:
            raise SensorError(
                f"sensor 'kinect-v1' at {intrinsics.width}x{intrinsics.height}: its edge and "
                f"normal estimates need at least {MIN_SIDE} pixels a side; use a larger "
                "image size"
            )
        super().__init__(intrinsics)
        self.px_scale = self.f / NATIVE_FOCAL_PX
        h, w = self.shape
        self._bh, self._bw = -(-h // LATERAL_BLOCK), -(-w // LATERAL_BLOCK)
        self._k3 = np.ones((3, 3), np.uint8)
        # the largest lateral sigma (at the incidence limit) bounds how far an edge can reach
        self._top = float(lateral_sigma_px(np.radians(MAX_INCIDENCE_DEG))) * self.px_scale
        reach = math.ceil(3.0 * self._top)
        self._kband = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
        self._slope = np.float32(EDGE_SLOPES * math.tan(math.radians(MAX_INCIDENCE_DEG)) / self.f)
        self._cos2_max = np.float32(math.cos(math.radians(MAX_INCIDENCE_DEG)) ** 2)
        self._cos2_knee = np.float32(math.cos(math.radians(AXIAL_KNEE_DEG)) ** 2)

    def _sense(
        self, renderer: Renderer, data: Any, cam_to_world: Mat4, rng: np.random.Generator,
        frame: Frame,
    ) -> Frame:  # fmt: skip
        z = frame.depth
        cos2 = self.incidence_cos2(z, out=self._buf("k_cos2"))
        ok = self.lit_by(z, BASELINE)
        ok &= np.greater(cos2, self._cos2_max, out=self._buf("k_ok", bool))
        z, cos2, ok = self._lateral(z, cos2, ok, rng)
        return Frame(depth=self._axial(z, cos2, ok, rng), segmentation=frame.segmentation)

    def _lateral(
        self, z: np.ndarray, cos2: np.ndarray, ok: np.ndarray, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Edge jitter (effect 2): near depth edges, each pixel reads the pixel its
        displacement lands on (its depth, incidence and return)."""
        import cv2

        h, w = self.shape
        if self._top * self._top <= 1.0 / 12.0:
            return z, cos2, ok  # sub-pixel at this focal length: no edge moves a pixel
        zo = self._buf("k_zo")
        zo[:] = z
        np.copyto(zo, np.float32(1e3), where=np.logical_not(ok, out=self._buf("k_nok", bool)))
        hi = cv2.dilate(zo, self._k3, dst=self._buf("k_hi"))
        jump = np.subtract(hi, cv2.erode(zo, self._k3, dst=self._buf("k_lo")), out=hi)
        np.multiply(z, ok, out=zo)
        zo *= self._slope
        edge = np.greater(jump, zo, out=self._buf("k_edge", bool)).view(np.uint8)
        band = cv2.dilate(edge, self._kband, dst=self._buf("k_band", np.uint8))
        at = np.flatnonzero(band.view(bool))  # flat indices: 2-D fancy indexing is 5x slower
        if not at.size:
            return z, cos2, ok
        v, u = np.divmod(at, w)
        zf, cf, okf = z.ravel(), cos2.ravel(), ok.ravel()
        theta = np.arccos(np.sqrt(np.clip(cf[at], self._cos2_max, 1.0)))
        sigma = lateral_sigma_px(theta) * self.px_scale
        # Nguyen's figure is of edges found on whole pixels: the draw leaves out the
        # variance that rounding to a pixel adds (1/12 px^2)
        sigma = np.sqrt(np.maximum(sigma * sigma - 1.0 / 12.0, 0.0))
        # one displacement per block of the band, so neighbours move together
        block = (v // LATERAL_BLOCK) * self._bw + (u // LATERAL_BLOCK)
        # number the band's blocks in raster order without sorting (a count, not np.unique)
        present = np.zeros(self._bh * self._bw, dtype=bool)
        present[block] = True
        rank = np.cumsum(present) - 1
        n = int(present.sum())
        draws = gaussian(rng, 2 * n)
        pick = rank[block]
        su = np.clip(np.rint(u + draws[:n][pick] * sigma), 0, w - 1).astype(np.intp)
        sv = np.clip(np.rint(v + draws[n:][pick] * sigma), 0, h - 1).astype(np.intp)
        src = sv * w + su
        # cos2 and ok are this capture's own arrays: moved in place (gathered first); the
        # depth is the caller's frame: moved in a copy
        moved_c, moved_ok = cf[src], okf[src]
        cf[at], okf[at] = moved_c, moved_ok
        z2 = self._buf("k_z2")
        z2[:] = z
        z2.ravel()[at] = zf[src]
        return z2, cos2, ok

    def _axial(
        self, z: np.ndarray, cos2: np.ndarray, ok: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        """Axial noise and 1/8-pixel disparity rounding (effects 3 and 4) of the returned
        pixels; 0 elsewhere. float32 throughout (the noise is millimetres, float32 resolves
        micrometres at 3 m), on the whole image: no gather or scatter (a capture's hot
        path)."""
        import cv2

        h, w = self.shape
        # one draw per LATERAL_BLOCK block, as the lateral jitter: the device's depth comes
        # from a correlation window, so neighbouring pixels' errors move together (and a
        # quarter of the draws is most of this function's saving)
        draws = gaussian(rng, self._bh * self._bw).reshape(self._bh, self._bw)
        size = (self._bw * LATERAL_BLOCK, self._bh * LATERAL_BLOCK)
        noise = self._buf("k_noise", shape=(size[1], size[0]))
        cv2.resize(draws, size, dst=noise, interpolation=cv2.INTER_NEAREST)
        out = np.empty((h, w), dtype=np.float32)
        fb8 = np.float32(NATIVE_FOCAL_PX * BASELINE / DISPARITY_STEP)
        # in bands of rows whose temporaries stay in cache (every step is per pixel)
        rows = max(1, 32768 // w)
        for r0 in range(0, h, rows):
            r1 = min(h, r0 + rows)
            zb, t = z[r0:r1], out[r0:r1]
            shape = t.shape
            # sigma^2 - step^2/12 with sigma = a + b (z - z0)^2 and step = z^2 / (8 f b)
            np.subtract(zb, np.float32(AXIAL_Z0), out=t)
            t *= t
            t *= np.float32(AXIAL_B)
            t += np.float32(AXIAL_A)
            below = np.less(cos2[r0:r1], self._cos2_knee, out=self._buf("k_below", bool, shape))
            below &= ok[r0:r1]
            grazing = np.flatnonzero(below)
            if grazing.size:
                th = np.arccos(np.sqrt(cos2[r0:r1].ravel()[grazing])).astype(np.float32)
                zg = zb.ravel()[grazing]
                t.ravel()[grazing] += (
                    np.float32(AXIAL_GRAZING)
                    / np.sqrt(zg)
                    * th
                    * th
                    / (np.float32(math.pi / 2) - th) ** 2
                )
            t *= t
            step = np.multiply(zb, zb, out=self._buf("k_step", shape=shape))
            step *= np.float32(DISPARITY_STEP / (NATIVE_FOCAL_PX * BASELINE))
            step *= step
            step *= np.float32(1.0 / 12.0)
            t -= step
            np.maximum(t, 0.0, out=t)
            np.sqrt(t, out=t)
            t *= noise[r0:r1, :w]
            t += zb
            # disparity in 1/8 px, rounded, and back: z = f b / d
            np.maximum(t, np.float32(1e-3), out=t)
            np.divide(fb8, t, out=t)
            np.rint(t, out=t)
            np.maximum(t, np.float32(1.0), out=t)
            np.divide(fb8, t, out=t)
            t *= ok[r0:r1]
        return out
