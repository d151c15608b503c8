"""Compose MuJoCo models with ``MjSpec``: tabletop scenes and isolated instances.

A tabletop model holds a floor, a table, the objects (free joints, their convex collision
parts as mesh geoms), lights, the depth camera and the gripper (:mod:`.gripper_model`).
Object bodies are in their canonical frame (``beo_bench.objects``), so a body's pose *is*
the object's pose. Procedural instances render their collision parts (their union is the
exact mesh); a loaded mesh, whose CoACD parts only approximate it, renders its own mesh as a
massless visual geom and hides the parts (geom group 3), so depth always shows the true
surface.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from beo_bench.objects.instance import ObjectInstance
from beo_bench.scenes.camera import Intrinsics
from beo_bench.scenes.gl import load_mujoco
from beo_bench.scenes.gripper import GRIPPER, GripperGeometry
from beo_bench.scenes.renderer import CAMERA_NAME
from beo_bench.types import Mat4

mujoco = load_mujoco()

COLLISION_ONLY_GROUP = 3
"""Geom group of collision parts that are not drawn (approximate parts of loaded meshes)."""
GRIPPER_GROUP = 2
"""Geom group of the gripper: drawn in RGB, hidden from depth and segmentation."""

OBJECT_COLOURS = np.array(  # object i is drawn in colour i mod 8 (RGB in 0..1)
    [
        [0.12, 0.47, 0.71],
        [1.00, 0.50, 0.05],
        [0.17, 0.63, 0.17],
        [0.84, 0.15, 0.16],
        [0.58, 0.40, 0.74],
        [0.55, 0.34, 0.29],
        [0.89, 0.47, 0.76],
        [0.50, 0.50, 0.50],
    ]
)


@dataclass(frozen=True)
class TableConfig:
    """The physical set-up (metres, seconds, kg/m^3)."""

    table_height: float = 0.72
    table_half: tuple[float, float] = (0.45, 0.35)
    area_half: tuple[float, float] = (0.22, 0.18)  # objects are placed in this central area
    timestep: float = 0.002
    object_density: float = 300.0
    object_friction: float = 0.8
    gripper: GripperGeometry = GRIPPER


@dataclass
class Scene:
    """A compiled tabletop model and what the env needs to know about it."""

    model: Any
    data: Any
    instances: list[ObjectInstance]
    body_ids: np.ndarray  # (k,) body id of object i (label i + 1)
    qpos_adr: np.ndarray  # (k,) start of each object's free-joint qpos (x y z qw qx qy qz)
    qvel_adr: np.ndarray  # (k,) start of each object's free-joint qvel (6)
    geom_labels: np.ndarray  # (ngeom,) segmentation label per geom
    config: TableConfig
    hand_mocap: int = -1  # mocap id of the hand's target
    hand_qpos_adr: int = -1  # the hand's free joint (x y z qw qx qy qz)
    hand_qvel_adr: int = -1
    finger_qpos_adr: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    finger_actuators: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    gripper_geoms: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def table_height(self) -> float:
        return self.config.table_height

    def object_pose(self, i: int) -> Mat4:
        """World pose (4x4) of object ``i``'s canonical frame."""
        T = np.eye(4)
        T[:3, :3] = self.data.xmat[self.body_ids[i]].reshape(3, 3)
        T[:3, 3] = self.data.xpos[self.body_ids[i]]
        return T

    def object_heights(self) -> np.ndarray:
        """(k,) world z of every object's origin."""
        return self.data.xpos[self.body_ids, 2].copy()


@lru_cache(maxsize=1024)
def _part_arrays(instance: ObjectInstance) -> tuple[tuple[np.ndarray, ...], bool]:
    """Vertices of every collision part (flattened, float64) and whether they are exact."""
    parts = instance.collision_parts()
    exact = instance.exact_parts
    return tuple(np.asarray(p.vertices, dtype=np.float64).ravel() for p in parts), exact


def _base_spec(intrinsics: Intrinsics, timestep: float, extent: float) -> Any:
    spec = mujoco.MjSpec()
    spec.modelname = "beo_bench_scene"
    spec.option.timestep = timestep
    # Elliptic friction cones with a high impratio hold grasped objects without creep
    # (MuJoCo's documentation recommends both for manipulation).
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 10.0
    spec.visual.global_.offwidth = max(int(intrinsics.width), 64)
    spec.visual.global_.offheight = max(int(intrinsics.height), 64)
    # no shadows and no multisampling: the model uploads in ~4 ms and segmentation colours
    # are never blended at edges
    spec.visual.quality.shadowsize = 0
    spec.visual.quality.offsamples = 0
    # a fixed extent makes near/far clip planes independent of the objects: 1 cm .. 20 m
    spec.stat.extent = extent
    spec.visual.map.znear = 0.01 / extent
    spec.visual.map.zfar = 20.0 / extent
    spec.worldbody.add_camera(name=CAMERA_NAME, pos=[0.0, 0.0, 1.0], fovy=intrinsics.fovy_deg)
    return spec


def add_object_geoms(
    spec: Any,
    parent: Any,
    instance: ObjectInstance,
    name: str,
    rgba: np.ndarray,
    density: float = 300.0,
    friction: float = 0.8,
) -> None:
    """Add ``instance``'s geoms (meshes named ``{name}_...``) to the body ``parent``."""
    verts, exact = _part_arrays(instance)
    group = 0 if exact else COLLISION_ONLY_GROUP
    for j, v in enumerate(verts):
        mesh_name = f"{name}_p{j}"
        spec.add_mesh(name=mesh_name, uservert=v)
        parent.add_geom(
            name=f"{name}_c{j}",
            type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname=mesh_name,
            density=density,
            friction=[friction, 0.005, 0.0001],
            group=group,
            rgba=rgba,
        )
    if not exact:
        m = instance.mesh
        spec.add_mesh(
            name=f"{name}_visual",
            uservert=np.asarray(m.vertices, dtype=np.float64).ravel(),
            userface=np.asarray(m.faces, dtype=np.int32).ravel(),
        )
        parent.add_geom(
            name=f"{name}_v",
            type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname=f"{name}_visual",
            contype=0,
            conaffinity=0,
            density=0.0,
            group=0,
            rgba=rgba,
        )


def _add_gripper(spec: Any, g: GripperGeometry, park: np.ndarray, timestep: float) -> None:
    """The hand: a free body (the TCP frame, see gripper.py) with a palm and two fingers on
    slide joints, each driven by a force-limited position actuator, welded to a mocap
    target that the scripted grasp moves.

    Not the mocap body itself: MuJoCo treats a mocap body as fixed to the world in the
    dynamics (zero velocity), so fingers attached to it teleport upwards and friction never
    drags a held object along (measured: 0 of 100 ground-truth grasps lifted). Through the
    weld the hand has real velocities and the pads' friction carries the object."""
    spec.worldbody.add_body(name="hand_target", mocap=True, pos=park.tolist())
    hand = spec.worldbody.add_body(name="hand", pos=park.tolist(), gravcomp=1.0)
    hand.add_freejoint(name="hand")
    weld = spec.add_equality(
        type=mujoco.mjtEq.mjEQ_WELD,
        objtype=mujoco.mjtObj.mjOBJ_BODY,
        name1="hand",
        name2="hand_target",
        # stiff enough to track the scripted motion within a millimetre, soft enough to
        # stay stable at a 2 ms step
        solref=[4 * timestep, 1.0],
    )
    # weld data: anchor (3) on the target, relative pose (pos 3, quat 4), torque scale. Set
    # in full: MjSpec's default puts the anchor 1 m away, which makes the weld lag by cm.
    weld.data[:11] = [0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1]
    grey = [0.35, 0.35, 0.38, 1.0]
    c, h = g.palm_box()
    hand.add_geom(
        name="palm",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=h.tolist(),
        pos=c.tolist(),
        group=GRIPPER_GROUP,
        rgba=grey,
    )
    fz = g.finger_tip - g.finger_length / 2
    for side, sign in (("left", 1.0), ("right", -1.0)):
        finger = hand.add_body(name=f"finger_{side}", gravcomp=1.0)
        finger.add_joint(
            name=f"finger_{side}",
            type=mujoco.mjtJoint.mjJNT_SLIDE,
            axis=[0.0, sign, 0.0],
            range=[0.0, g.max_opening / 2],
            damping=20.0,
            armature=0.01,
        )
        finger.add_geom(
            name=f"finger_{side}",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[g.finger_width / 2, g.finger_thickness / 2, g.finger_length / 2],
            pos=[0.0, sign * g.finger_thickness / 2, fz],
            # pads: high friction plus torsional friction so a held object does not spin
            # about the closing axis (condim 4)
            friction=[g.pad_friction, 0.01, 0.0001],
            condim=4,
            # Stiff pads. With the default solref time constant (0.02 s) a 20 N squeeze on a
            # 26 g finger settles ~1.5 cm deep in the object (steady state of MuJoCo's
            # reference acceleration, k = 1 / timeconst^2), and the object slips out on the
            # lift. 2 x timestep is the stiffest stable setting (MuJoCo docs, "Solver
            # parameters"); priority makes these, not the object's, the contact's parameters.
            priority=1,
            solref=[2 * timestep, 1.0],
            solimp=[0.95, 0.99, 0.001, 0.5, 2.0],
            density=2000.0,
            group=GRIPPER_GROUP,
            rgba=[0.2, 0.2, 0.22, 1.0],
        )
        act = spec.add_actuator(name=f"finger_{side}", target=f"finger_{side}")
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        # position servo whose force saturates at the grip force: closing on an object
        # squeezes it with a constant force, like a force-limited real gripper
        act.set_to_position(kp=2000.0)
        act.ctrlrange = [0.0, g.max_opening / 2]
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-g.grip_force, g.grip_force]
    spec.add_exclude(bodyname1="finger_left", bodyname2="finger_right")


PARK = np.array([0.0, 0.0, 4.0])
"""Where the hand waits between grasps: far above the table, outside every camera view."""


def build_tabletop(
    instances: list[ObjectInstance],
    poses: list[Mat4],
    intrinsics: Intrinsics,
    config: TableConfig | None = None,
    with_gripper: bool = True,
) -> Scene:
    """Compile a tabletop model with ``instances`` at ``poses`` (world, canonical frame)."""
    cfg = config or TableConfig()
    spec = _base_spec(intrinsics, cfg.timestep, extent=2.0)
    wb = spec.worldbody
    wb.add_light(
        name="sun",
        pos=[0.5, -0.5, 3.0],
        dir=[-0.2, 0.2, -1.0],
        type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
        castshadow=0,
    )
    wb.add_geom(
        name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[3, 3, 0.1], rgba=[0.8, 0.8, 0.8, 1]
    )
    th = cfg.table_height
    wb.add_geom(
        name="table",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[cfg.table_half[0], cfg.table_half[1], 0.02],
        pos=[0.0, 0.0, th - 0.02],
        friction=[0.8, 0.005, 0.0001],
        rgba=[0.55, 0.42, 0.3, 1],
    )
    for sx in (-1, 1):
        for sy in (-1, 1):
            wb.add_geom(
                type=mujoco.mjtGeom.mjGEOM_BOX,
                size=[0.025, 0.025, (th - 0.04) / 2],
                pos=[sx * (cfg.table_half[0] - 0.05), sy * (cfg.table_half[1] - 0.05), th / 2],
                rgba=[0.45, 0.33, 0.22, 1],
            )
    names = []
    for i, (inst, T) in enumerate(zip(instances, poses, strict=True)):
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(T[:3, :3]).reshape(9))
        name = f"obj{i}"
        body = wb.add_body(name=name, pos=T[:3, 3].tolist(), quat=quat.tolist())
        body.add_freejoint(name=name)
        add_object_geoms(
            spec,
            body,
            inst,
            name,
            np.append(OBJECT_COLOURS[i % len(OBJECT_COLOURS)], 1.0),
            cfg.object_density,
            cfg.object_friction,
        )
        names.append(name)
    if with_gripper:
        _add_gripper(spec, cfg.gripper, PARK, cfg.timestep)
    model = spec.compile()
    data = mujoco.MjData(model)
    body_ids = np.array([model.body(n).id for n in names], dtype=np.int64)
    jnt = [model.joint(n) for n in names]
    labels = np.zeros(model.ngeom, dtype=np.int32)
    geom_body = model.geom_bodyid
    for i, b in enumerate(body_ids):
        labels[geom_body == b] = i + 1
    scene = Scene(
        model=model,
        data=data,
        instances=list(instances),
        body_ids=body_ids,
        qpos_adr=np.array([j.qposadr[0] for j in jnt], dtype=np.int64),
        qvel_adr=np.array([j.dofadr[0] for j in jnt], dtype=np.int64),
        geom_labels=labels,
        config=cfg,
    )
    if with_gripper:
        scene.hand_mocap = int(model.body("hand_target").mocapid[0])
        scene.hand_qpos_adr = int(model.joint("hand").qposadr[0])
        scene.hand_qvel_adr = int(model.joint("hand").dofadr[0])
        scene.finger_qpos_adr = np.array(
            [model.joint(f"finger_{s}").qposadr[0] for s in ("left", "right")], dtype=np.int64
        )
        scene.finger_actuators = np.array(
            [model.actuator(f"finger_{s}").id for s in ("left", "right")], dtype=np.int64
        )
        gb = {model.body(n).id for n in ("hand", "finger_left", "finger_right")}
        scene.gripper_geoms = np.array(
            [g for g in range(model.ngeom) if geom_body[g] in gb], dtype=np.int64
        )
    mujoco.mj_forward(model, data)
    return scene


def build_isolated(instance: ObjectInstance, intrinsics: Intrinsics) -> tuple[Any, Any]:
    """A model holding only ``instance``, fixed at the world origin in its canonical frame
    (no table, no gravity needed), and its data after kinematics."""
    spec = _base_spec(intrinsics, 0.002, extent=1.0)
    body = spec.worldbody.add_body(name="object")
    add_object_geoms(spec, body, instance, "obj0", np.array([0.7, 0.7, 0.7, 1.0]))
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return model, data


def build_boxes(
    boxes: list[tuple[np.ndarray, np.ndarray]], intrinsics: Intrinsics
) -> tuple[Any, Any]:
    """A static model of boxes, each ``(centre (3,), half-sizes (3,))`` in the world frame
    (axis-aligned), and its data after kinematics: the planes and steps that the sensors'
    validation measures on (:mod:`beo_bench.scenes.sensors.validation`)."""
    spec = _base_spec(intrinsics, 0.002, extent=1.0)
    for i, (centre, half) in enumerate(boxes):
        spec.worldbody.add_geom(
            name=f"box{i}",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            pos=[float(c) for c in centre],
            size=[float(s) for s in half],
            rgba=[0.7, 0.7, 0.7, 1.0],
        )
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return model, data
