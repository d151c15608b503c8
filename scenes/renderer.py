"""Off-screen metric depth, instance segmentation and RGB from MuJoCo models.

Why not one ``mujoco.Renderer`` per scene: it binds a GL context to a single model, and
creating one costs 0.05-0.4 s (measured), while BEOPick builds a new model per episode.
:class:`Renderer` keeps one GL context for its whole life and, when the model changes, only
re-uploads the model (an ``MjrContext`` with shadows and multisampling off: ~4 ms). Depth
and segmentation come from *one* segmentation pass (the depth buffer is valid in it, and it
is also the pass ``mujoco.Renderer`` uses for accurate depth), so a frame costs one render.
Buffers are allocated once per image size; the hot path allocates only its outputs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from beo_bench.scenes.camera import Intrinsics, opencv_to_mujoco
from beo_bench.scenes.gl import load_mujoco
from beo_bench.types import Mat4

mujoco = load_mujoco()

CAMERA_NAME = "depth_camera"
"""Every scene model has a world camera of this name; the renderer moves it per frame."""


@dataclass
class Frame:
    """One rendered view: metric z-depth (float32 m, 0 = no surface) and instance labels
    (int32, 0 = background, table and anything unlabelled, 1..k objects)."""

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
        self._opt = mujoco.MjvOption()
        self._cam = mujoco.MjvCamera()
        self._cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._model: Any = None
        self._con: Any = None
        self._scn: Any = None
        self._labels = np.zeros(0, dtype=np.int32)
        self._closed = False

    # -- binding ---------------------------------------------------------------------------
    def bind(self, model: Any, geom_labels: np.ndarray | None = None) -> None:
        """Use ``model`` from now on. ``geom_labels[g]`` is the segmentation label of model
        geom ``g`` (0 for background; default all 0)."""
        self._check_open()
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
        labels = np.zeros(model.ngeom, dtype=np.int32)
        if geom_labels is not None:
            labels[:] = geom_labels
        self._labels = labels
        # metric-depth constants (reverse-Z projection, as mujoco.Renderer computes them)
        extent = model.stat.extent
        znear = np.float32(model.vis.map.znear * extent)
        zfar = np.float32(model.vis.map.zfar * extent)
        c = -(zfar + znear) / (zfar - znear)
        d = -(np.float32(2) * zfar * znear) / (zfar - znear)
        self._c = float(np.float32(-0.5) * c - np.float32(0.5))
        self._d = float(np.float32(-0.5) * d)

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

    def render(self, data: Any, cam_to_world: Mat4) -> Frame:
        """Metric depth and instance labels of ``data``'s state seen from ``cam_to_world``
        (OpenCV axes) with this renderer's intrinsics."""
        self._update(data, cam_to_world, segment=True)
        mujoco.mjr_render(self._rect, self._scn, self._con)
        mujoco.mjr_readPixels(self._rgb, self._zbuf, self._rect, self._con)
        z = self._zbuf[::-1]  # OpenGL rows run bottom-up
        hit = z > 0  # reverse Z: the cleared far plane reads 0
        depth = np.zeros((self._h, self._w), dtype=np.float32)
        depth[hit] = (self._d / (z[hit].astype(np.float64) + self._c)).astype(np.float32)
        # segmentation colour = scene-geom index + 1, encoded in RGB
        rgb = self._rgb[::-1].astype(np.int32)
        segid = rgb[..., 0] | (rgb[..., 1] << 8) | (rgb[..., 2] << 16)
        lut = self._segid_to_label()
        return Frame(depth=depth, segmentation=lut[np.minimum(segid, len(lut) - 1)])

    def render_rgb(self, data: Any, cam_to_world: Mat4) -> np.ndarray:
        """A lit colour image (H, W, 3) uint8, for people and videos."""
        self._update(data, cam_to_world, segment=False)
        mujoco.mjr_render(self._rect, self._scn, self._con)
        mujoco.mjr_readPixels(self._rgb, None, self._rect, self._con)
        return self._rgb[::-1].copy()

    def _segid_to_label(self) -> np.ndarray:
        scn = self._scn
        n = scn.ngeom
        lut = np.zeros(n + 2, dtype=np.int32)
        geom_type = int(mujoco.mjtObj.mjOBJ_GEOM)
        for i in range(n):
            g = scn.geoms[i]
            if g.objtype == geom_type and 0 <= g.objid < len(self._labels):
                lut[g.segid + 1] = self._labels[g.objid]
        return lut

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
