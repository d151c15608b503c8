"""``beo-bench view``: look at one BEOPick-v0 scene.

Writes a rerun recording (``.rrd``: world-frame object meshes, the camera with its frustum,
depth and segmentation images, the depth back-projected to world points, the table plane
and the ground-truth planner's best grasp as the gripper's boxes) and a PNG with depth,
segmentation and RGB side by side, the planner's best grasp outlined on the RGB panel. Open
the recording with ``rerun FILE.rrd``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np

from beo_bench.atomic import atomic_path
from beo_bench.errors import BeoBenchError
from beo_bench.scenes.builder import OBJECT_COLOURS
from beo_bench.scenes.camera import backproject
from beo_bench.scenes.gripper import GRIPPER

if TYPE_CHECKING:
    from beo_bench.envs.pick import BEOPickEnv
    from beo_bench.objects import ObjectSet

# label 0 black, label i the colour the scene gives object i - 1 (so the PNG's segmentation
# and RGB panels agree)
_PALETTE = np.vstack([[0, 0, 0], np.round(255 * OBJECT_COLOURS)]).astype(np.uint8)


@dataclass(frozen=True)
class ViewResult:
    """What ``view_scene`` wrote and what the scene holds."""

    rrd: Path | None
    png: Path
    target: str
    objects: tuple[str, ...]
    grasps: int
    """How many grasps of the target the ground-truth planner found (the best is drawn)."""
    seed: int

    def text(self) -> str:
        """What ``beo-bench view`` prints: the scene, then where the files are."""
        lines = [
            f"seed {self.seed}: objects {', '.join(self.objects)}; target {self.target}; "
            f"{self.grasps} ground-truth grasps of the target",
            f"image:     {self.png}",
        ]
        if self.rrd is not None:
            lines.append(f"recording: {self.rrd}  (open with `rerun {self.rrd}`)")
        return "\n".join(lines)


def colour_segmentation(seg: np.ndarray) -> np.ndarray:
    """(H, W) labels -> (H, W, 3) uint8, background black."""
    seg = np.asarray(seg)
    return np.where(seg[..., None] > 0, _PALETTE[1 + (seg - 1) % (len(_PALETTE) - 1)], 0).astype(
        np.uint8
    )


def rerun_mesh(mesh: Any, rgba: Any) -> Any:
    """A rerun ``Mesh3D`` of a trimesh (vertices, faces, normals) in one colour."""
    import rerun as rr

    return rr.Mesh3D(
        vertex_positions=mesh.vertices,
        triangle_indices=mesh.faces,
        vertex_normals=mesh.vertex_normals,
        albedo_factor=rgba,
    )


# the 12 edges of a box, as pairs of corner indices (corner i has sign bits of i on x, y, z)
_BOX_EDGES = [(a, a | 1 << k) for a in range(8) for k in range(3) if not a & 1 << k]


def grasp_outline(grasp: Any, obs: dict[str, Any]) -> list[np.ndarray]:
    """The gripper of ``grasp`` (palm and fingers at its opening) as image polylines: one
    (2, 2) array of pixel (u, v) per box edge in front of the camera of ``obs``."""
    P, T, K = grasp.pose, obs["cam_to_world"], obs["intrinsics"]
    signs = np.array([[(i >> k & 1) * 2 - 1 for k in range(3)] for i in range(8)], float)
    lines = []
    for centre, half in GRIPPER.boxes(grasp.opening / 2):
        world = (centre + signs * half) @ P[:3, :3].T + P[:3, 3]
        cam = (world - T[:3, 3]) @ T[:3, :3]  # world -> camera: R^T (x - t)
        for a, b in _BOX_EDGES:
            if cam[a, 2] > 0 and cam[b, 2] > 0:
                uvw = cam[[a, b]] @ K.T
                lines.append(uvw[:, :2] / uvw[:, 2:])
    return lines


DEPTH_PERCENTILES = (2.0, 98.0)
DEPTH_MARGIN_M = 0.05


def depth_range(depth: np.ndarray, seg: np.ndarray) -> tuple[float, float]:
    """The depth panel's colour range: the objects' depths (segmented pixels, robust
    percentiles :data:`DEPTH_PERCENTILES`), widened by :data:`DEPTH_MARGIN_M` so the table
    around them shows too. The whole image's range would be the floor's (0.7-2.75 m on
    BEOPick-v0), in which the objects are one colour. Without object pixels: every hit's."""
    hit = depth > 0
    objects = depth[hit & (seg > 0)]
    values = objects if objects.size >= 20 else depth[hit]
    if values.size == 0:
        return 0.0, 1.0
    lo, hi = np.percentile(values, DEPTH_PERCENTILES)
    return float(lo) - DEPTH_MARGIN_M, float(hi) + DEPTH_MARGIN_M


def _write_png(
    path: Path, obs: dict[str, Any], rgb: np.ndarray, title: str, grasp: Any = None
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    depth = np.where(obs["depth"] > 0, obs["depth"], np.nan)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), constrained_layout=True)
    lo, hi = depth_range(obs["depth"], obs["segmentation"])
    im = axes[0].imshow(depth, cmap="viridis", vmin=lo, vmax=hi)
    fig.colorbar(
        im,
        ax=axes[0],
        label="depth (m), the objects' range; white = no hit",
        shrink=0.85,
        extend="both",
    )
    axes[1].imshow(colour_segmentation(obs["segmentation"]), interpolation="nearest")
    axes[2].imshow(rgb)
    if grasp is not None:
        h, w = rgb.shape[:2]
        for line in grasp_outline(grasp, obs):
            axes[2].plot(line[:, 0], line[:, 1], color="#ffc800", linewidth=1.2)
        axes[2].set_xlim(-0.5, w - 0.5)  # edges leaving the image do not widen the panel
        axes[2].set_ylim(h - 0.5, -0.5)
    rgb_title = "RGB" if grasp is None else "RGB; yellow: the planner's best grasp"
    titles = ("depth", "segmentation (0 = background/table)", rgb_title)
    for ax, t in zip(axes, titles, strict=True):
        ax.set_title(t)
        ax.set_axis_off()
    fig.suptitle(title)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=90, format="png")
    finally:
        plt.close(fig)


def _log_rerun(path: Path, env: Any, obs: dict[str, Any], grasp: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        _record(tmp, env, obs, grasp)


def _record(tmp: Path, env: Any, obs: dict[str, Any], grasp: Any) -> None:
    """Write the scene's rerun recording to ``tmp``."""
    try:
        import rerun as rr
    except ImportError as e:  # pragma: no cover - the viz extra is installed by make
        raise BeoBenchError(
            "writing a .rrd needs rerun-sdk: `pip install 'beo-bench[viz]'` (or use --no-rrd)"
        ) from e
    u = env.unwrapped
    rec = rr.RecordingStream("beo-bench-view")
    rec.save(tmp)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    for g in u.ground_truth():
        mesh = u.object_mesh_world(g.label)
        colour = colour_segmentation(np.array([g.label]))[0]
        rec.log(f"world/objects/{g.label}_{g.category}", rerun_mesh(mesh, np.append(colour, 255)))
    half = np.array(u.config.table.table_half)
    th = u.config.table.table_height
    rec.log(
        "world/table",
        rr.Boxes3D(
            centers=[[0.0, 0.0, th - 0.02]], half_sizes=[[*half, 0.02]], colors=[[140, 107, 77]]
        ),
    )
    K, T = obs["intrinsics"], obs["cam_to_world"]
    h, w = obs["depth"].shape
    # rerun's pinhole uses OpenCV axes (RDF) by default, as our cam_to_world does
    rec.log("world/camera", rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]))
    rec.log("world/camera/image", rr.Pinhole(image_from_camera=K, width=w, height=h))
    rec.log("world/camera/image/depth", rr.DepthImage(obs["depth"], meter=1.0))
    rec.log("world/camera/image/segmentation", rr.SegmentationImage(obs["segmentation"]))
    seg = obs["segmentation"]
    mask = obs["depth"] > 0
    pts_cam = backproject(obs["depth"], K, mask)
    pts = pts_cam @ T[:3, :3].T + T[:3, 3]
    rec.log(
        "world/points",
        rr.Points3D(pts, colors=colour_segmentation(seg[mask]), radii=0.001),
    )
    if grasp is not None:
        P = grasp.pose
        boxes = GRIPPER.boxes(grasp.opening / 2)
        centers = np.array([P[:3, :3] @ c + P[:3, 3] for c, _ in boxes])
        from scipy.spatial.transform import Rotation

        q = Rotation.from_matrix(P[:3, :3]).as_quat()  # x y z w, rerun's order
        rec.log(
            "world/grasp",
            rr.Boxes3D(
                centers=centers,
                half_sizes=[h_ for _, h_ in boxes],
                quaternions=[rr.Quaternion(xyzw=q)] * len(boxes),
                colors=[[255, 200, 0]],
                labels=["palm", "finger", "finger"],
            ),
        )
        rec.log(
            "world/grasp/approach",
            rr.Arrows3D(
                origins=[P[:3, 3] - GRIPPER.pregrasp_distance * P[:3, 2]],
                vectors=[GRIPPER.pregrasp_distance * P[:3, 2]],
                colors=[[255, 200, 0]],
            ),
        )
    rec.flush()
    rec.disconnect()


def view_scene(
    seed: int,
    out: Path | str = "out/view",
    rrd: bool = True,
    *,
    split: str = "test",
    image_size: tuple[int, int] = (640, 480),
    num_objects: int | tuple[int, int] | None = None,
    objects: ObjectSet | None = None,
    **env_kwargs: Any,
) -> ViewResult:
    """Reset BEOPick-v0 with ``seed`` and write ``scene_{seed}.png`` (and ``.rrd``) to ``out``.

    ``objects``: the object set to draw scenes from (a user's dataset's split); the scenes
    then hold 1 to min(4, its classes) objects unless ``num_objects`` says otherwise (a
    scene's objects are of distinct classes). Other keyword arguments go to the env."""
    out = Path(out)
    env_kwargs.update(split=split, image_size=tuple(image_size))
    if objects is not None:
        env_kwargs["objects"] = objects
        env_kwargs["num_objects"] = (1, min(4, len(objects.categories)))
    if num_objects is not None:
        env_kwargs["num_objects"] = num_objects
    env = gym.make("BEOPick-v0", render_mode="rgb_array", **env_kwargs)
    try:
        obs, _ = env.reset(seed=seed)
        u = cast("BEOPickEnv", env.unwrapped)
        grasps = u.ground_truth_grasps()
        best = grasps[0] if grasps else None
        rgb = cast(np.ndarray, env.render())  # render_mode="rgb_array": one (H, W, 3) frame
        target = u.categories[obs["target_class"]]
        names = tuple(g.category for g in u.ground_truth())
        title = (
            f"BEOPick-v0 seed {seed}: {len(names)} objects ({', '.join(names)}); "
            f"target: {target}; {len(grasps)} ground-truth grasps"
        )
        png = out / f"scene_{seed}.png"
        _write_png(png, obs, rgb, title, best)
        rrd_path = out / f"scene_{seed}.rrd" if rrd else None
        if rrd_path is not None:
            _log_rerun(rrd_path, env, obs, best)
    finally:
        env.close()
    return ViewResult(rrd_path, png, target, names, len(grasps), seed)
