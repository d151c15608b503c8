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
   camera (f = 585 px): an edge's position jitters by that much, theta being the incidence
   on the surface whose edge it is (Nguyen et al. measured the edges of a plane turned to
   theta; here the most oblique returned surface within reach of the edge, so a pixel
   beside an edge with nothing behind it moves with the plane's edge). Applied where a depth
   edge is within reach: a pixel takes the depth of the pixel its displacement lands on.
   The displacement fields are smooth across an edge (horizontal displacements are drawn
   per pixel row every ``LATERAL_TILE`` pixels along it and interpolated; vertical ones per
   column, likewise), so the pixels on both sides of an edge move together and the edge
   itself moves by the rounded draw; each row of a vertical edge (column of a horizontal
   one) moves independently, as Nguyen et al. measured them.
3. **Axial noise** (Nguyen et al. 2012, eq. 1): sigma_z(z, theta) = 0.0012 + 0.0019 (z -
   0.4)^2 m for theta <= 60 deg, plus 0.0001/sqrt(z) theta^2 / (pi/2 - theta)^2 beyond; theta
   is the angle between the surface normal and the viewing ray. Drawn per 2x2 pixel block
   (the device's depth comes from a correlation window, so neighbours err together), with
   the sigma of the block's top-left pixel (its depth and incidence): each pixel's spread is
   Nguyen's, except where a block straddles a depth edge.
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

Speed: the incidence, the noise and the edges are computed per 2x2 block (a quarter of the
pixels) and the shadows on every other row; per pixel, only the depth plus its block's
noise, the 1/8-pixel rounding and the edge pixels' moves (a gather). The capture costs
under 2x the ideal render at 640x480 (docs/performance.md has the figure).
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
"""Side of the pixel blocks that share a noise draw, a displacement, a normal and an
incidence (the device's depth comes from a correlation window around each pixel)."""

LATERAL_TILE = 32
"""Pixels between the draws of a displacement field along its own direction (across the
edges it moves; linearly interpolated between draws, normalised to unit variance): the
pixels on both sides of an edge move together, so the edge itself moves."""

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


TABLE_STEP = 0.0005
"""Depth step (m) of the table of the axial sigma below the knee (the sigma changes by
less than 0.1% over it at 3 m)."""

TABLE_MAX = 20.0
"""Deepest depth (m) in the table; deeper depths take its last entry."""


def _effective_sigma(z: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """The Gaussian part of a depth spread ``sigma`` at depth ``z``: sqrt(sigma^2 - step^2 /
    12), the variance the 1/8-pixel rounding adds taken out (Sheppard's correction)."""
    step = quantisation_step(z)
    return np.sqrt(np.maximum(sigma * sigma - step * step / 12.0, 0.0))


def _sigma_table() -> np.ndarray:
    """The effective axial sigma (:func:`_effective_sigma`) below the knee at depths 0,
    ``TABLE_STEP``, ... ``TABLE_MAX`` (float32)."""
    z = np.arange(round(TABLE_MAX / TABLE_STEP) + 1) * TABLE_STEP
    return _effective_sigma(z, axial_sigma(z, np.zeros_like(z))).astype(np.float32)


class _BlockGrid(Sensor):
    """The geometry of a :class:`KinectV1`'s 2x2 pixel blocks: an image of one pixel per
    block (each block's top-left pixel), whose rays are those pixels' rays in the full
    image (so its normals are the full image's, sampled)."""

    name = "kinect-v1 blocks"

    def __init__(self, full: Intrinsics, shape: tuple[int, int]) -> None:
        bh, bw = shape
        super().__init__(Intrinsics(bw, bh, full.fovy_deg))
        K = full.K
        f = float(full.focal)
        u = (LATERAL_BLOCK * np.arange(bw, dtype=np.float32) - np.float32(K[0, 2])) / np.float32(f)
        v = (LATERAL_BLOCK * np.arange(bh, dtype=np.float32) - np.float32(K[1, 2])) / np.float32(f)
        # one block is LATERAL_BLOCK pixels: the derivatives per block are per
        # LATERAL_BLOCK pixels, so the focal length in blocks is f / LATERAL_BLOCK
        self.f = f / LATERAL_BLOCK
        self._ray_x = np.broadcast_to(u[None, :], (bh, bw))
        self._ray_y = np.broadcast_to(v[:, None], (bh, bw))
        self._ray_norm2 = (self._ray_x**2 + self._ray_y**2 + np.float32(1.0)).astype(np.float32)

    def _sense(
        self, renderer: Renderer, data: Any, cam_to_world: Mat4, rng: np.random.Generator,
        frame: Frame,
    ) -> Frame:  # fmt: skip
        raise NotImplementedError


def _smooth_norm(n: int, draws: int) -> np.ndarray:
    """The factor that gives unit variance to ``draws`` unit-variance draws interpolated
    linearly onto ``n`` positions by ``cv2.resize`` (its own weights, read off an identity
    matrix): 1 / sqrt(sum of the squared weights) at each position."""
    import cv2

    weights = cv2.resize(
        np.eye(draws, dtype=np.float32), (n, draws), interpolation=cv2.INTER_LINEAR
    )
    return (1.0 / np.sqrt((weights.astype(np.float64) ** 2).sum(axis=0))).astype(np.float32)


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
        B = LATERAL_BLOCK
        self._bh, self._bw = -(-h // B), -(-w // B)
        self._blocks = _BlockGrid(intrinsics, (self._bh, self._bw))
        self._k3 = np.ones((3, 3), np.uint8)
        # the largest lateral sigma (at the incidence limit) bounds how far an edge can reach
        self._top = float(lateral_sigma_px(np.radians(MAX_INCIDENCE_DEG))) * self.px_scale
        reach = math.ceil(math.ceil(3.0 * self._top) / B)  # in blocks
        self._kreach = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
        # the edge's blocks are the two beside the jump: the band reaches one block less
        band = max(reach - 1, 0)
        self._kband = np.ones((2 * band + 1, 2 * band + 1), np.uint8)
        # a block's 3x3 range spans 2 B pixels' steps (a pixel's spans 2)
        self._slope = np.float32(
            B * EDGE_SLOPES * math.tan(math.radians(MAX_INCIDENCE_DEG)) / self.f
        )
        self._cos2_max = np.float32(math.cos(math.radians(MAX_INCIDENCE_DEG)) ** 2)
        self._cos2_knee = np.float32(math.cos(math.radians(AXIAL_KNEE_DEG)) ** 2)
        self._table = _sigma_table()
        # the displacement fields: along the rows (u) a draw per block row every
        # LATERAL_TILE pixels, interpolated; along the columns (v) the same, transposed
        tile = max(1, LATERAL_TILE // B)
        self._nu, self._nv = -(-self._bw // tile) + 1, -(-self._bh // tile) + 1
        self._norm_u = _smooth_norm(self._bw, self._nu)
        self._norm_v = _smooth_norm(self._bh, self._nv)
        # a block's rows (in the u field) and columns (in the v field), and its pixels'
        # rows and columns, from its top-left pixel's
        self._rows_u = (np.arange(B) * self._bw)[None, :]
        self._cols_v = np.arange(B)[None, :]
        self._offsets = (B * self._bw * np.arange(B)[:, None] + np.arange(B)[None, :])[None]

    def _sense(
        self, renderer: Renderer, data: Any, cam_to_world: Mat4, rng: np.random.Generator,
        frame: Frame,
    ) -> Frame:  # fmt: skip
        import cv2

        h, w = self.shape
        B = LATERAL_BLOCK
        bh, bw = self._bh, self._bw
        z = frame.depth
        # the projector's shadows on every other row (a block's rows share its top row's):
        # the rows are its epipolar lines, so each row's shadows are found along it
        zr = z[::B]
        lit = self.lit_by(zr, BASELINE)
        # the blocks: each block's top-left pixel (its depth, normal and return)
        zb = self._buf("k_zb", shape=(bh, bw))
        zb[:] = zr[:, ::B]
        c2 = self._blocks.incidence_cos2(zb, out=self._buf("k_c2", shape=(bh, bw)))
        okb = np.greater(c2, self._cos2_max, out=self._buf("k_okb", bool, (bh, bw)))
        okb &= lit[:, ::B]
        noise = self._axial_blocks(zb, c2, okb, rng)
        # each pixel: its depth plus its block's noise, NaN without a return, on 1/8-pixel
        # disparity steps
        t = self._buf("k_t", shape=(bh * B, bw * B))
        cv2.resize(noise, (bw * B, bh * B), dst=t, interpolation=cv2.INTER_NEAREST)
        t = t[:h, :w]
        t += z
        # a pixel the render has no surface at returns nothing, whatever its block's noise
        # (version 3 added the noise to its 0 and returned a depth of a few mm there)
        cv2.copyTo(self._const("nan", np.nan, (h, w)), np.less_equal(z, 0).view(np.uint8), t)
        nolit = self._buf("k_nolit", bool, (bh, B, w))
        np.logical_not(lit[:, None, :], out=nolit)
        cv2.copyTo(
            self._const("nan", np.nan, (h, w)), nolit.reshape(bh * B, w)[:h].view(np.uint8), t
        )
        fb8 = np.float32(NATIVE_FOCAL_PX * BASELINE / DISPARITY_STEP)
        np.divide(fb8, t, out=t)
        np.rint(t, out=t)
        # the capture's own array (the blocks' size: larger by a row or column where the
        # image's side is odd)
        out = np.empty((bh * B, bw * B), dtype=np.float32)
        np.divide(fb8, t, out=out[:h, :w])
        self._lateral(out, zb, c2, okb, rng)
        cv2.patchNaNs(out, 0.0)
        if out.shape != (h, w):
            out = np.ascontiguousarray(out[:h, :w])
        return Frame(depth=out, segmentation=frame.segmentation)

    def _axial_blocks(
        self, zb: np.ndarray, c2: np.ndarray, okb: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        """Each block's axial noise (m; effects 3 and 4): one draw per block times Nguyen's
        sigma at the block's depth and incidence, less the variance the 1/8-pixel rounding
        adds; NaN where the block has no return (beyond the incidence limit)."""
        import cv2

        shape = zb.shape
        # below the knee sigma depends on the depth alone: read off a table
        # (``_sigma_table``), the depth rounded to its step
        q = np.multiply(zb, np.float32(1.0 / TABLE_STEP), out=self._buf("k_q", shape=shape))
        q += np.float32(0.5)
        idx = q.astype(np.intp)
        np.minimum(idx, self._table.size - 1, out=idx)
        t = self._table.take(idx, out=self._buf("k_ax", shape=shape))
        below = np.less(c2, self._cos2_knee, out=self._buf("k_below", bool, shape))
        below &= okb
        grazing = np.flatnonzero(below)
        if grazing.size:
            zg = np.maximum(zb.ravel()[grazing], np.float32(1e-6)).astype(np.float64)
            th = np.arccos(np.sqrt(c2.ravel()[grazing].astype(np.float64)))
            t.ravel()[grazing] = _effective_sigma(zg, axial_sigma(zg, th))
        t *= gaussian(rng, t.size).reshape(shape)
        nok = np.logical_not(okb, out=self._buf("k_nokb", bool, shape))
        cv2.copyTo(self._const("nan_b", np.nan, shape), nok.view(np.uint8), t)
        return t

    def _lateral(
        self,
        t: np.ndarray,
        zb: np.ndarray,
        c2: np.ndarray,
        okb: np.ndarray,
        rng: np.random.Generator,
    ) -> None:
        """Edge jitter (effect 2), in place: near depth edges each pixel of ``t`` (the
        image, in an array of the blocks' size) takes the value of the pixel its block's
        displacement lands on."""
        import cv2

        h, w = self.shape
        B = LATERAL_BLOCK
        bh, bw = self._bh, self._bw
        if self._top * self._top <= 1.0 / 12.0:
            return  # sub-pixel at this focal length: no edge moves a pixel
        # edges between blocks: the 3x3 range of returned depth (none: far) against the
        # step of a plane at the incidence limit
        far = self._buf("k_far", shape=(bh, bw))
        far[:] = zb
        nok = self._buf("k_nokb", bool, (bh, bw))  # set by _axial_blocks
        cv2.copyTo(self._const("far_b", 1e3, (bh, bw)), nok.view(np.uint8), far)
        jump = cv2.morphologyEx(
            far, cv2.MORPH_GRADIENT, self._k3, dst=self._buf("k_jump", shape=(bh, bw))
        )
        zo = np.multiply(zb, self._slope, out=self._buf("k_zo", shape=(bh, bw)))
        edge = np.greater(jump, zo, out=self._buf("k_edge", bool, (bh, bw))).view(np.uint8)
        band = cv2.dilate(edge, self._kband, dst=self._buf("k_band", np.uint8, (bh, bw)))
        at = np.flatnonzero(band.view(bool))
        if not at.size:
            return
        # the edge's incidence: the most oblique returned surface within reach
        cm = self._buf("k_cm", shape=(bh, bw))
        cm[:] = c2
        cv2.copyTo(self._const("one_b", 1.0, (bh, bw)), nok.view(np.uint8), cm)
        cv2.erode(cm, self._kreach, dst=cm)
        theta = np.arccos(np.sqrt(np.clip(cm.ravel()[at], self._cos2_max, 1.0)))
        sigma = lateral_sigma_px(theta) * self.px_scale
        # Nguyen's figure is of edges found on whole pixels: the draw leaves out the
        # variance that rounding to a pixel adds (1/12 px^2)
        sigma = np.sqrt(np.maximum(sigma * sigma - 1.0 / 12.0, 0.0))
        # smooth unit-variance displacement fields, interpolated between draws
        # LATERAL_TILE pixels apart: u along the rows, v along the columns
        # (u: one field per pixel row, v: one per pixel column, so that an edge's rows, or
        # columns, move independently, as Nguyen et al. measured them)
        H, W = bh * B, bw * B
        g = gaussian(rng, H * self._nu + self._nv * W)
        gu = g[: H * self._nu].reshape(H, self._nu)
        gv = g[H * self._nu :].reshape(self._nv, W)
        lin = cv2.INTER_LINEAR
        du = cv2.resize(gu, (bw, H), dst=self._buf("k_du", shape=(H, bw)), interpolation=lin)
        dv = cv2.resize(gv, (W, bh), dst=self._buf("k_dv", shape=(bh, W)), interpolation=lin)
        r, c = np.divmod(at, bw)
        sigma *= self._norm_u[c]
        at_u = (B * r)[:, None] * bw + c[:, None] + self._rows_u  # (n, B): the block's rows
        iu = np.rint(du.ravel()[at_u] * sigma[:, None]).astype(np.intp)
        sigma *= self._norm_v[r] / self._norm_u[c]
        at_v = (r * W + B * c)[:, None] + self._cols_v  # (n, B): the block's columns
        iv = np.rint(dv.ravel()[at_v] * sigma[:, None]).astype(np.intp)
        # each pixel of a band block reads the pixel its displacement, rounded, lands on
        # (within the image: at its border, as the border's block reads); pixel (i, j) of a
        # block moves by its row i's u and its column j's v
        rows = np.clip((B * r)[:, None] + iv, 0, h - B)
        rows *= W
        cols = np.clip((B * c)[:, None] + iu, 0, w - B)
        src = rows[:, None, :] + cols[:, :, None]
        src += self._offsets
        # a block past an odd image's last row or column writes into the array's margin
        dst = (r * (B * W) + B * c)[:, None, None] + self._offsets
        flat = t.reshape(-1)
        flat[dst] = flat[src]
