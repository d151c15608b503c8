"""Where objects go on the table: each instance's stable rest pose, and non-overlapping
placement with random yaw.

An instance dropped alone onto a plane comes to rest in a pose of its own (a mug whose
handle reaches below its base tilts; a chair rocks onto its legs). Finding that pose takes
seconds of simulated time, so it is found once per instance by physics and cached
(``rest`` entries of the asset cache). A scene then places every object in its rest pose
with a random yaw, on footprint discs that do not overlap, and a short settle in the scene
confirms it. Reset stays fast and the objects are physically at rest.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from beo_bench.errors import BeoBenchError
from beo_bench.objects import cache
from beo_bench.objects.instance import ObjectInstance
from beo_bench.scenes.gl import load_mujoco
from beo_bench.types import Mat4

mujoco = load_mujoco()

REST_SETTINGS = {"v": 1, "steps": 2000, "dt": 0.002, "drop": 0.001}


class PlacementError(BeoBenchError):
    """The objects do not fit on the table without overlapping."""


class ObjectTooLargeError(PlacementError, ValueError):
    """An object whose footprint cannot lie on the table in its rest pose, wherever it is
    put: drawing other objects would not help, so it is refused instead of retried."""


@dataclass(frozen=True)
class RestPose:
    """An instance resting on a plane at z = 0: ``rotation`` (canonical -> world, yaw as
    it fell), ``height`` of the canonical origin above the plane, and ``radius`` of the
    footprint disc about the vertical through the origin (any yaw fits in it)."""

    rotation: np.ndarray
    height: float
    radius: float


def _simulate_rest(instance: ObjectInstance) -> dict[str, np.ndarray]:
    from beo_bench.scenes.builder import add_object_geoms

    spec = mujoco.MjSpec()
    spec.option.timestep = REST_SETTINGS["dt"]
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 10.0
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1, 1, 0.1])
    verts = np.asarray(instance.mesh.vertices)
    z0 = -verts[:, 2].min() + REST_SETTINGS["drop"]
    body = spec.worldbody.add_body(name="o", pos=[0.0, 0.0, z0])
    body.add_freejoint()
    add_object_geoms(spec, body, instance, "o", np.array([1.0, 1.0, 1.0, 1.0]))
    model = spec.compile()
    data = mujoco.MjData(model)
    for n in range(int(REST_SETTINGS["steps"])):
        mujoco.mj_step(model, data)
        # still: below 1 mm/s and 0.01 rad/s after the first 0.1 s
        if n > 50 and np.abs(data.qvel[:3]).max() < 1e-3 and np.abs(data.qvel[3:]).max() < 1e-2:
            break
    R = data.xmat[1].reshape(3, 3).copy()
    return {"rotation": R, "height": np.array(data.xpos[1, 2])}


@functools.lru_cache(maxsize=1024)
def rest_pose(instance: ObjectInstance) -> RestPose:
    """The instance's stable pose on a plane (found by simulation once, then cached)."""
    out = cache.cached(
        "rest",
        instance.content_hash,
        REST_SETTINGS,
        lambda: _simulate_rest(instance),
        instance.cache_dir,
    )
    R = np.asarray(out["rotation"], dtype=np.float64)
    # the lowest point of the rested mesh defines the height exactly (no contact softness)
    world = np.asarray(instance.mesh.vertices) @ R.T
    height = float(-world[:, 2].min())
    radius = float(np.hypot(world[:, 0], world[:, 1]).max())
    return RestPose(rotation=R, height=height, radius=radius)


def yaw(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def place_objects(
    instances: list[ObjectInstance],
    rng: np.random.Generator,
    table_height: float,
    area_half: tuple[float, float],
    gap: float = 0.005,
    tries: int = 400,
    table_half: tuple[float, float] | None = None,
) -> list[Mat4]:
    """World poses for ``instances``: rest pose, uniform random yaw, centres uniform in the
    table's central area on footprint discs ``gap`` apart (no initial interpenetration).
    Larger objects are placed first. Raises :class:`PlacementError` when they do not fit.

    With ``table_half`` (the table top's half-extents), every footprint disc also lies
    wholly on the table: a centre's range shrinks to ``table_half - radius`` where that is
    smaller than ``area_half`` (objects overhanging the edge tipped off the table and left
    episodes with an invisible target), and an object whose disc is wider than the table
    raises :class:`ObjectTooLargeError` naming it."""
    rests = [rest_pose(inst) for inst in instances]
    area = [np.asarray(area_half, dtype=np.float64) for _ in rests]
    if table_half is not None:
        half = np.asarray(table_half, dtype=np.float64)
        for i, (inst, rp) in enumerate(zip(instances, rests, strict=True)):
            if rp.radius > half.min():
                raise ObjectTooLargeError(
                    f"object {inst.key} ({inst.category}) does not fit on the table: its "
                    f"footprint radius in its rest pose is {rp.radius:.3f} m and the table top "
                    f"is {2 * half[0]:.2f} x {2 * half[1]:.2f} m; load it smaller (size=<metres> "
                    f"or the right units=) or use a larger TableConfig.table_half"
                )
            area[i] = np.minimum(area[i], half - rp.radius)
    order = np.argsort([-r.radius for r in rests], kind="stable")
    centres: dict[int, np.ndarray] = {}
    for i in order:
        r = rests[i].radius
        for _ in range(tries):
            # the same draw as before the table bound; only its scale shrinks for objects
            # that would overhang, so seeds of scenes that fitted give the same scenes
            c = rng.uniform(-1.0, 1.0, 2) * area[i]
            if all(np.linalg.norm(c - centres[j]) >= r + rests[j].radius + gap for j in centres):
                centres[int(i)] = c
                break
        else:
            raise PlacementError(
                f"could not place {len(instances)} objects (footprint radii "
                f"{[round(x.radius, 3) for x in rests]} m) in the table area "
                f"{2 * area_half[0]:.2f} x {2 * area_half[1]:.2f} m without overlap; "
                "use fewer objects or a larger area"
            )
    poses = []
    for i, rp in enumerate(rests):
        T = np.eye(4)
        T[:3, :3] = yaw(rng.uniform(0.0, 2 * math.pi)) @ rp.rotation
        # 0.5 mm above the table: no initial contact force, a drop too small to bounce
        T[:3, 3] = [*centres[i], table_height + rp.height + 0.0005]
        poses.append(T)
    return poses
