"""Scripted, physical grasp execution with the simulated gripper (docs/design.md "Environments").

Phases (simulated time): check the pre-grasp and grasp poses; approach from the pre-grasp
offset along the gripper's +z with the fingers open (0.3 s); close with force-limited
fingers (0.3 s); lift 15 cm straight up (0.5 s); hold (1 s). The outcome is read from the
objects' heights: an object is lifted when it ends at least 10 cm above its rest height.
Then, when something was lifted, a shake audits the hold without changing the outcome: the
hand is accelerated at +-2 g along the world x, y and z axes in turn (``SHAKE_*``), and the
record says whether the object is still up afterwards and how far it slipped in the hand.
A grasp that would start inside the table or an object fails before any motion, with the
reason in the outcome, and leaves the scene untouched.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from beo_bench.scenes.builder import PARK, Scene
from beo_bench.scenes.gl import load_mujoco
from beo_bench.scenes.gripper import GripperGeometry

mujoco = load_mujoco()

APPROACH_S = 0.3
CLOSE_S = 0.3
LIFT_S = 0.5
HOLD_S = 1.0
LIFT_SUCCESS = 0.10
"""An object counts as lifted when it ends this far above its rest height (docs/design.md)."""
PENETRATION_TOL = 0.001
SHAKE_G = 2.0
"""Peak acceleration of the shake, in g. A pick-and-place arm moving at full speed reaches
about 1-2 g at the tool (a Franka Panda's joint limits give up to ~13 m/s^2 at the flange:
Franka Emika, "Robot and interface specifications"); 2 g is the upper end."""
SHAKE_HZ = 5.0
"""Each axis is shaken for one period of a raised cosine at this frequency: 0.2 s, so the
whole shake lasts 0.6 s, with a displacement of at most 4 cm."""
SHAKE_SETTLE_S = 0.2
"""The hand then holds still this long before the object is looked at again."""


@dataclass
class GraspOutcome:
    """What one grasp execution did."""

    reason: str  # "lifted", "nothing_lifted", "pregrasp_in_collision", "inside_table"
    lifted_label: int = 0  # segmentation label of the lifted object (0: none)
    lift_height: float = 0.0  # rise of the lifted (or highest-rising) object (m)
    touched: dict[str, list[int]] = field(default_factory=dict)  # finger -> object labels
    colliding_label: int = 0  # for pregrasp_in_collision: the object hit (0: table/none)
    contacts: dict[str, int] = field(default_factory=dict)  # finger -> contacts at hold's end
    grip_n: dict[str, float] = field(default_factory=dict)  # finger -> normal force (N) then
    shake_held: bool | None = None  # still lifted after the shake (None: nothing was lifted)
    slip_cm: float | None = None  # how far the lifted object moved in the hand's frame


def _box_corners(g: GripperGeometry, half_opening: float, T: np.ndarray) -> np.ndarray:
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    pts = [c + signs * h for c, h in g.boxes(half_opening)]
    local = np.concatenate(pts)
    return local @ T[:3, :3].T + T[:3, 3]


def _below_table(scene: Scene, corners: np.ndarray) -> bool:
    cfg = scene.config
    on_table = (np.abs(corners[:, 0]) <= cfg.table_half[0]) & (
        np.abs(corners[:, 1]) <= cfg.table_half[1]
    )
    under_top = corners[:, 2] < cfg.table_height - PENETRATION_TOL
    above_underside = corners[:, 2] > cfg.table_height - 0.04 - 0.05
    return bool(np.any(on_table & under_top & above_underside) or np.any(corners[:, 2] < 0))


def _set_hand(scene: Scene, T: np.ndarray, half_opening: float) -> None:
    m, d = scene.model, scene.data
    d.mocap_pos[scene.hand_mocap] = T[:3, 3]
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(T[:3, :3]).reshape(9))
    d.mocap_quat[scene.hand_mocap] = q
    # teleport the hand onto its target too (the weld only pulls it there over time)
    d.qpos[scene.hand_qpos_adr : scene.hand_qpos_adr + 3] = T[:3, 3]
    d.qpos[scene.hand_qpos_adr + 3 : scene.hand_qpos_adr + 7] = q
    d.qvel[scene.hand_qvel_adr : scene.hand_qvel_adr + 6] = 0.0
    d.qpos[scene.finger_qpos_adr] = half_opening
    d.qvel[[m.jnt_dofadr[m.actuator_trnid[a, 0]] for a in scene.finger_actuators]] = 0.0
    d.ctrl[scene.finger_actuators] = half_opening


def _hand_contacts(scene: Scene) -> list[tuple[int, int, float]]:
    """(gripper geom, other geom, signed distance) of every contact of the hand."""
    d = scene.data
    hand = set(scene.gripper_geoms.tolist())
    out = []
    for i in range(d.ncon):
        c = d.contact[i]
        g1, g2 = int(c.geom1), int(c.geom2)
        if g1 in hand and g2 not in hand:
            out.append((g1, g2, float(c.dist)))
        elif g2 in hand and g1 not in hand:
            out.append((g2, g1, float(c.dist)))
    return out


def _finger_touches(scene: Scene) -> dict[str, list[int]]:
    m = scene.model
    fingers = {m.geom(f"finger_{s}").id: s for s in ("left", "right")}
    out: dict[str, set[int]] = {"left": set(), "right": set()}
    for g, other, _ in _hand_contacts(scene):
        if g in fingers and scene.geom_labels[other] > 0:
            out[fingers[g]].add(int(scene.geom_labels[other]))
    return {k: sorted(v) for k, v in out.items()}


def _finger_load(scene: Scene, label: int) -> tuple[dict[str, int], dict[str, float]]:
    """Per finger: how many contacts it has with object ``label`` and their total normal
    force (N, from ``mj_contactForce``)."""
    m, d = scene.model, scene.data
    fingers = {m.geom(f"finger_{s}").id: s for s in ("left", "right")}
    count = {"left": 0, "right": 0}
    force = {"left": 0.0, "right": 0.0}
    f6 = np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        g1, g2 = int(c.geom1), int(c.geom2)
        finger, other = (g1, g2) if g1 in fingers else (g2, g1)
        if finger not in fingers or int(scene.geom_labels[other]) != label or c.dist > 0:
            continue
        mujoco.mj_contactForce(m, d, i, f6)
        count[fingers[finger]] += 1
        force[fingers[finger]] += abs(float(f6[0]))  # the normal component comes first
    return count, {k: round(v, 3) for k, v in force.items()}


def _hand_pose(scene: Scene) -> np.ndarray:
    d, a = scene.data, scene.hand_qpos_adr
    T = np.eye(4)
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, d.qpos[a + 3 : a + 7])
    T[:3, :3], T[:3, 3] = mat.reshape(3, 3), d.qpos[a : a + 3]
    return T


def shake(scene: Scene, label: int, rest_heights: np.ndarray) -> tuple[bool, float]:
    """Shake the hand holding object ``label`` (``SHAKE_G`` along world x, y, z in turn:
    x(t) = A (1 - cos wt) over one period, so the hand starts and ends at rest, with
    a(t) = A w^2 cos wt peaking at +-SHAKE_G), hold ``SHAKE_SETTLE_S``, and return whether
    the object is still lifted (``LIFT_SUCCESS``) and how far (cm) it moved in the hand's
    frame."""
    m, d = scene.model, scene.data
    i = label - 1
    mujoco.mj_forward(m, d)  # mj_step leaves body poses one step behind qpos
    before = np.linalg.inv(_hand_pose(scene)) @ scene.object_pose(i)
    w = 2 * np.pi * SHAKE_HZ
    amplitude = SHAKE_G * 9.81 / w**2
    start = d.mocap_pos[scene.hand_mocap].copy()
    n = _steps(scene, 1.0 / SHAKE_HZ)
    for axis in range(3):
        for k in range(1, n + 1):
            offset = np.zeros(3)
            offset[axis] = amplitude * (1.0 - np.cos(w * k * m.opt.timestep))
            d.mocap_pos[scene.hand_mocap] = start + offset
            mujoco.mj_step(m, d)
    d.mocap_pos[scene.hand_mocap] = start
    for _ in range(_steps(scene, SHAKE_SETTLE_S)):
        mujoco.mj_step(m, d)
    mujoco.mj_forward(m, d)
    after = np.linalg.inv(_hand_pose(scene)) @ scene.object_pose(i)
    held = bool(scene.object_heights()[i] - rest_heights[i] >= LIFT_SUCCESS)
    return held, 100.0 * float(np.linalg.norm(after[:3, 3] - before[:3, 3]))


def _steps(scene: Scene, seconds: float) -> int:
    return max(1, round(seconds / scene.model.opt.timestep))


def execute_grasp(
    scene: Scene, T_grasp: np.ndarray, opening: float, rest_heights: np.ndarray
) -> GraspOutcome:
    """Run one grasp (gripper frame ``T_grasp`` in the world, finger ``opening`` in metres)
    and report the outcome. ``rest_heights[i]`` is object i's origin height at rest."""
    g = scene.config.gripper
    m, d = scene.model, scene.data
    half = float(np.clip(opening, 0.0, g.max_opening)) / 2
    approach = T_grasp[:3, 2]
    T_pre = T_grasp.copy()
    T_pre[:3, 3] = T_grasp[:3, 3] - g.pregrasp_distance * approach

    # 1. kinematic checks before anything moves
    if _below_table(scene, _box_corners(g, half, T_pre)) or _below_table(
        scene, _box_corners(g, half, T_grasp)
    ):
        return GraspOutcome(reason="inside_table")
    qpos0, qvel0 = d.qpos.copy(), d.qvel.copy()
    _set_hand(scene, T_pre, half)
    mujoco.mj_forward(m, d)
    hits = [(o, dist) for _, o, dist in _hand_contacts(scene) if dist < -PENETRATION_TOL]
    if hits:
        label = max(int(scene.geom_labels[o]) for o, _ in hits)
        d.qpos[:], d.qvel[:] = qpos0, qvel0
        park(scene)
        return GraspOutcome(
            reason="pregrasp_in_collision" if label else "inside_table", colliding_label=label
        )

    # 2. approach along +z with the fingers open
    n = _steps(scene, APPROACH_S)
    for k in range(1, n + 1):
        d.mocap_pos[scene.hand_mocap] = T_pre[:3, 3] + (k / n) * g.pregrasp_distance * approach
        mujoco.mj_step(m, d)
    # 3. close (position servos saturate at the grip force)
    d.ctrl[scene.finger_actuators] = 0.0
    for _ in range(_steps(scene, CLOSE_S)):
        mujoco.mj_step(m, d)
    touched = _finger_touches(scene)
    # 4. lift straight up, then 5. hold
    start = d.mocap_pos[scene.hand_mocap].copy()
    n = _steps(scene, LIFT_S)
    for k in range(1, n + 1):
        d.mocap_pos[scene.hand_mocap] = start + np.array([0.0, 0.0, g.lift_height * k / n])
        mujoco.mj_step(m, d)
    for _ in range(_steps(scene, HOLD_S)):
        mujoco.mj_step(m, d)

    rise = scene.object_heights() - rest_heights
    best = int(np.argmax(rise)) if len(rise) else -1
    if best >= 0 and rise[best] >= LIFT_SUCCESS:
        contacts, grip = _finger_load(scene, best + 1)
        held, slip = shake(scene, best + 1, rest_heights)
        return GraspOutcome(
            reason="lifted",
            lifted_label=best + 1,
            lift_height=float(rise[best]),
            touched=touched,
            contacts=contacts,
            grip_n=grip,
            shake_held=held,
            slip_cm=round(slip, 3),
        )
    return GraspOutcome(
        reason="nothing_lifted",
        lift_height=float(max(rise.max(), 0.0)) if len(rise) else 0.0,
        touched=touched,
    )


def park(scene: Scene) -> None:
    """Open the fingers and move the hand back to its parking place (kinematically)."""
    g = scene.config.gripper
    T = np.eye(4)
    T[:3, 3] = PARK
    _set_hand(scene, T, g.max_opening / 2)
    mujoco.mj_forward(scene.model, scene.data)


def release(scene: Scene) -> None:
    """Open the fingers for 0.2 s (dropping what they hold), then park the hand."""
    g = scene.config.gripper
    scene.data.ctrl[scene.finger_actuators] = g.max_opening / 2
    for _ in range(_steps(scene, 0.2)):
        mujoco.mj_step(scene.model, scene.data)
    park(scene)


def settle(scene: Scene, max_steps: int = 150, min_steps: int = 20) -> int:
    """Step until every object is still (below 2 mm/s and 0.02 rad/s) or ``max_steps``;
    returns the steps taken."""
    m, d = scene.model, scene.data
    dof = (np.asarray(scene.qvel_adr)[:, None] + np.arange(6)).ravel()
    for n in range(1, max_steps + 1):
        mujoco.mj_step(m, d)
        if n >= min_steps and len(dof):
            v = d.qvel[dof].reshape(-1, 6)
            if np.abs(v[:, :3]).max() < 2e-3 and np.abs(v[:, 3:]).max() < 2e-2:
                break
    # positions of bodies and geoms consistent with qpos (mj_step leaves them one step behind)
    mujoco.mj_forward(m, d)
    return n
