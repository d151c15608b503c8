"""Off-screen metric depth, instance segmentation and RGB from MuJoCo models.

Why not one ``mujoco.Renderer`` per scene: it binds a GL context to a single model, and
creating one costs 0.05-0.4 s (measured), while BEOPick builds a new model per episode.
:class:`Renderer` keeps one GL context for its whole life and, when the model changes, only
re-uploads the model (an ``MjrContext`` with shadows and multisampling off: ~4 ms). Depth
and segmentation come from *one* segmentation pass (the depth buffer is valid in it, and it
is also the pass ``mujoco.Renderer`` uses for accurate depth), so a frame costs one render.
Buffers are allocated once per image size; the hot path allocates only its outputs.

Why labels are drawn as colours: in the segmentation pass MuJoCo paints each scene geom in
the colour ``mjvGeom.segid + 1`` (24 bits over R, G, B; black where nothing is drawn). The
renderer overwrites every scene geom's ``segid`` with its *label* before drawing, so a
pixel's colour is ``label + 1``: with labels below 255 the red channel alone is the image
(one uint8 pass, no per-pixel lookup table), whatever the number of geoms in the scene.
Labels are not shifted down to make the colour the label itself: ``segid = -1`` hides a
geom (the table would vanish from the depth). Drawing labels changes no depth value
(tests/scenes/test_labels.py checks both against MuJoCo's own segmentation).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from beo_bench.scenes.camera import Intrinsics, opencv_to_mujoco
from beo_bench.scenes.gl import load_mujoco
from beo_bench.types import Mat4

mujoco = load_mujoco()

_GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)

CAMERA_NAME = "depth_camera"
"""Every scene model has a world camera of this name; the renderer moves it per frame."""


MAX_LABEL = 2**24 - 2
"""The largest label a geom may have: ``label + 1`` is drawn as a 24-bit colour."""

UINT8_LABELS = 254
"""Models whose labels are all <= this get uint8 segmentation images (``label + 1`` must
fit the red channel); larger labels give int32."""


@dataclass
class Frame:
    """One rendered view.

    ``depth``: (H, W) float32 metric z-depth (m), 0 = no surface. ``segmentation``: (H, W)
    instance labels, 0 = background, table and anything unlabelled, 1..k objects; its dtype
    is **uint8** when every label of the bound model is <= 254 (BEOPick scenes, isolated
    views) and int32 otherwise (``Renderer.segmentation_dtype``). Comparisons,
    indexing and ``np.bincount`` work the same on both; widen (``astype(np.int32)``) before
    arithmetic that can leave 0..255, e.g. ``seg - 1`` wraps around in uint8.
    """

    depth: np.ndarray
    segmentation: np.ndarray


class Renderer:
    """An off-screen renderer owning one GL context; bind it to any number of models in
    turn. Close it (or use it as a context manager) to free the GL resources."""

    def __init__(self, intrinsics: Intrinsics, max_geom: int = 4000) -> None:
        from mujoco import gl_context

        self.intrinsics = intrinsics
        self._w, self._h = int(intrinsics.width), int(intrinsics.height)
        self._gl: Any = gl_context.GLContext(self._w, self._h)
        self._gl.make_current()
        self._max_geom = max_geom
        self._rect = mujoco.MjrRect(0, 0, self._w, self._h)
        self._rgb = np.empty((self._h, self._w, 3), dtype=np.uint8)
        self._zbuf = np.empty((self._h, self._w), dtype=np.float32)
        self._zsum = np.empty((self._h, self._w), dtype=np.float32)  # scratch: z + c
        self._hit = np.empty((self._h, self._w), dtype=bool)  # scratch: z > 0
        self._opt = mujoco.MjvOption()
        self._cam = mujoco.MjvCamera()
        self._cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._model: Any = None
        self._con: Any = None
        self._scn: Any = None
        self._label_list: list[int] = []
        self._seg_dtype: type[np.integer[Any]] = np.uint8
        self._closed = False

    # -- binding ---------------------------------------------------------------------------
    def bind(self, model: Any, geom_labels: np.ndarray | None = None) -> None:
        """Use ``model`` from now on. ``geom_labels[g]`` is the segmentation label of model
        geom ``g``: an integer in 0..``MAX_LABEL``, 0 for background (default all 0). Labels
        up to 254 give uint8 segmentation images, larger ones int32 (see ``Frame``)."""
        self._check_open()
        labels = np.zeros(model.ngeom, dtype=np.int32)
        if geom_labels is not None:
            given = np.asarray(geom_labels)
            if given.shape != (model.ngeom,) or not (
                given.size == 0 or np.issubdtype(given.dtype, np.integer)
            ):
                raise ValueError(
                    f"geom_labels must be ({model.ngeom},) integers, one label per model geom; "
                    f"got {given.dtype} of shape {given.shape}"
                )
            if given.size and (given.min() < 0 or given.max() > MAX_LABEL):
                raise ValueError(
                    f"geom_labels must lie in 0..{MAX_LABEL} (the label + 1 is drawn as a 24-bit "
                    f"colour); got {given.min()}..{given.max()}"
                )
            labels[:] = given
        if model.vis.global_.offwidth < self._w or model.vis.global_.offheight < self._h:
            raise ValueError(
                f"the model's off-screen buffer is {model.vis.global_.offwidth}x"
                f"{model.vis.global_.offheight}, smaller than the {self._w}x{self._h} image; "
                "build it with beo_bench.scenes.builder (it sizes the buffer) or set "
                "<visual><global offwidth offheight/></visual>"
            )
        self._camid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA_NAME)
        if self._camid < 0:
            raise ValueError(f"the model has no camera named {CAMERA_NAME!r} to render from")
        self._gl.make_current()
        if self._con is not None:
            self._con.free()
        self._con = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_50)
        self._con.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR  # reverse Z: 0 = far
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._con)
        if self._scn is None:
            self._scn = mujoco.MjvScene(model, maxgeom=self._max_geom)
        self._cam.fixedcamid = self._camid
        self._model = model
        self._label_list = labels.tolist()  # Python ints: cheap to assign per frame
        fits = not labels.size or int(labels.max()) <= UINT8_LABELS
        self._seg_dtype = np.uint8 if fits else np.int32
        # metric-depth constants (reverse-Z projection, as mujoco.Renderer computes them)
        extent = model.stat.extent
        znear = np.float32(model.vis.map.znear * extent)
        zfar = np.float32(model.vis.map.zfar * extent)
        c = -(zfar + znear) / (zfar - znear)
        d = -(np.float32(2) * zfar * znear) / (zfar - znear)
        self._c = np.float32(np.float32(-0.5) * c - np.float32(0.5))
        self._d = np.float32(np.float32(-0.5) * d)

    @property
    def segmentation_dtype(self) -> type[np.integer[Any]]:
        """dtype of the bound model's segmentation images: uint8 when every label is <= 254,
        int32 otherwise."""
        return self._seg_dtype

    # -- rendering -------------------------------------------------------------------------
    def _update(self, data: Any, cam_to_world: Mat4, segment: bool) -> None:
        self._check_bound()
        pos, xmat = opencv_to_mujoco(cam_to_world)
        self._model.cam_fovy[self._camid] = self.intrinsics.fovy_deg
        # A fixed camera is drawn from data.cam_xpos/cam_xmat: write the pose there directly
        # (no kinematics pass needed, and the next mj_step recomputes it anyway).
        data.cam_xpos[self._camid] = pos
        data.cam_xmat[self._camid] = xmat
        self._gl.make_current()
        mujoco.mjv_updateScene(
            self._model, data, self._opt, None, self._cam, mujoco.mjtCatBit.mjCAT_ALL, self._scn
        )
        self._scn.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = segment
        self._scn.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = segment
        if segment:
            self._draw_labels()

    def _draw_labels(self) -> None:
        """Make each scene geom's id colour its label + 1 (see the module docstring).
        mjv_updateScene numbers ``segid`` afresh every frame, so this runs per frame: one
        attribute write per scene geom (~0.05 ms for a BEOPick scene's 85)."""
        labels = self._label_list
        n = len(labels)
        geom_type = _GEOM
        for g in self._scn.geoms[: self._scn.ngeom]:
            i = g.objid
            g.segid = labels[i] if g.objtype == geom_type and 0 <= i < n else 0

    def render(self, data: Any, cam_to_world: Mat4) -> Frame:
        """Metric depth and instance labels of ``data``'s state seen from ``cam_to_world``
        (OpenCV axes) with this renderer's intrinsics."""
        self._update(data, cam_to_world, segment=True)
        mujoco.mjr_render(self._rect, self._scn, self._con)
        mujoco.mjr_readPixels(self._rgb, self._zbuf, self._rect, self._con)
        return Frame(depth=self._depth(), segmentation=self._decode_labels())

    def render_depth(self, data: Any, cam_to_world: Mat4) -> np.ndarray:
        """:meth:`render`'s metric depth alone (the same values), without reading back or
        decoding the labels: a sensor's second view (its right imager) needs no labels."""
        self._update(data, cam_to_world, segment=True)
        mujoco.mjr_render(self._rect, self._scn, self._con)
        mujoco.mjr_readPixels(None, self._zbuf, self._rect, self._con)
        return self._depth()

    def _depth(self) -> np.ndarray:
        """Metric depth from the depth buffer just read back."""
        # OpenGL rows run bottom-up: every read below goes through a flipped view.
        z = self._zbuf[::-1]
        # metric depth d / (z + c) in float32: two roundings instead of a float64 round trip's
        # one, within 1 ulp of it (measured on BEOPick scenes and isolated views); 0 where
        # the cleared far plane reads 0 (reverse Z)
        np.greater(z, 0, out=self._hit)
        np.add(z, self._c, out=self._zsum)
        depth = np.zeros((self._h, self._w), dtype=np.float32)
        np.divide(self._d, self._zsum, out=depth, where=self._hit)
        return depth

    def _decode_labels(self) -> np.ndarray:
        """Labels from the id colours (label + 1; 0 where nothing was drawn)."""
        rgb = self._rgb[::-1]
        if self._seg_dtype is np.uint8:
            seg8 = np.maximum(rgb[..., 0], 1, out=np.empty((self._h, self._w), np.uint8))
            seg8 -= 1
            return seg8
        seg = np.empty((self._h, self._w), dtype=np.int32)
        seg[:] = rgb[..., 2]
        seg <<= 8
        seg |= rgb[..., 1]
        seg <<= 8
        seg |= rgb[..., 0]
        np.maximum(seg, 1, out=seg)
        seg -= 1
        return seg

    def render_rgb(self, data: Any, cam_to_world: Mat4) -> np.ndarray:
        """A lit colour image (H, W, 3) uint8, for people and videos."""
        self._update(data, cam_to_world, segment=False)
        mujoco.mjr_render(self._rect, self._scn, self._con)
        mujoco.mjr_readPixels(self._rgb, None, self._rect, self._con)
        return self._rgb[::-1].copy()

    # -- lifetime --------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("this renderer was closed; create a new one")

    def _check_bound(self) -> None:
        self._check_open()
        if self._model is None:
            raise RuntimeError("bind(model) the renderer to a model before rendering")

    def close(self) -> None:
        """Free the MjrContext and the GL context (idempotent)."""
        if self._closed:
            return
        self._closed = True
        if self._con is not None:
            self._gl.make_current()
            self._con.free()
            self._con = None
        self._gl.free()
        self._gl = None
        self._scn = None
        self._model = None

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # interpreter shutdown: GL may already be gone
            pass
