"""``beo-bench view``: look at one BEOPick-v0 scene.

Writes a rerun recording (``.rrd``: world-frame object meshes, the camera with its frustum,
depth and segmentation images, the depth back-projected to world points, the table plane
and the ground-truth planner's best grasp as the gripper's boxes) and a PNG with depth,
segmentation and RGB side by side. Open the recording with ``rerun FILE.rrd``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from beo_bench.errors import BeoBenchError
from beo_bench.scenes.builder import OBJECT_COLOURS
from beo_bench.scenes.camera import backproject
from beo_bench.scenes.gripper import GRIPPER

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


def _atomic_target(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


def _write_png(path: Path, obs: dict[str, Any], rgb: np.ndarray, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    depth = np.where(obs["depth"] > 0, obs["depth"], np.nan)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), constrained_layout=True)
    im = axes[0].imshow(depth, cmap="viridis")
    fig.colorbar(im, ax=axes[0], label="depth (m); white = no hit", shrink=0.85)
    axes[1].imshow(colour_segmentation(obs["segmentation"]), interpolation="nearest")
    axes[2].imshow(rgb)
    for ax, t in zip(axes, ("depth", "segmentation (0 = background/table)", "RGB"), strict=True):
        ax.set_title(t)
        ax.set_axis_off()
    fig.suptitle(title)
    tmp = _atomic_target(path)
    fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)
    os.replace(tmp, path)


def _log_rerun(path: Path, env: Any, obs: dict[str, Any], grasp: Any) -> None:
    try:
        import rerun as rr
    except ImportError as e:  # pragma: no cover - the viz extra is installed by make
        raise BeoBenchError(
            "writing a .rrd needs rerun-sdk: `pip install 'beo-bench[viz]'` (or use --no-rrd)"
        ) from e
    u = env.unwrapped
    rec = rr.RecordingStream("beo-bench-view")
    tmp = _atomic_target(path)
    rec.save(tmp)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    for g in u.ground_truth():
        mesh = u.object_mesh_world(g.label)
        colour = colour_segmentation(np.array([g.label]))[0]
        rec.log(f"world/objects/{g.label}_{g.category}", rerun_mesh(mesh, np.append(colour, 255)))
    half = np.array(u.table.table_half)
    th = u.table.table_height
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
    os.replace(tmp, path)


def view_scene(
    seed: int, out: Path | str = "out/view", rrd: bool = True, **env_kwargs: Any
) -> ViewResult:
    """Reset BEOPick-v0 with ``seed`` and write ``scene_{seed}.png`` (and ``.rrd``) to ``out``."""
    out = Path(out)
    env = gym.make("BEOPick-v0", render_mode="rgb_array", **env_kwargs)
    try:
        obs, _ = env.reset(seed=seed)
        u = env.unwrapped
        grasps = u.ground_truth_grasps()
        best = grasps[0] if grasps else None
        rgb = env.render()
        target = u.categories[obs["target_class"]]
        objects = tuple(g.category for g in u.ground_truth())
        title = (
            f"BEOPick-v0 seed {seed}: {len(objects)} objects ({', '.join(objects)}); "
            f"target: {target}; {len(grasps)} ground-truth grasps"
        )
        png = out / f"scene_{seed}.png"
        _write_png(png, obs, rgb, title)
        rrd_path = out / f"scene_{seed}.rrd" if rrd else None
        if rrd_path is not None:
            _log_rerun(rrd_path, env, obs, best)
    finally:
        env.close()
    return ViewResult(rrd_path, png, target, objects, len(grasps))
