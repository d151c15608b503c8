"""BEOPick-v0: pick the object of a target class from one segmented depth image.

The environment's reference is :class:`BEOPickEnv`'s docstring (Gymnasium's layout:
description, action and observation spaces, rewards, starting state, episode end, arguments,
version history) and, in prose with examples, docs/env.md.

``gym.make("BEOPick-v0", ...)`` goes through :func:`make_pick_env`: its keywords are a
:class:`~beo_bench.scenes.pickconfig.PickConfig`'s fields (bad or unknown ones become an
:class:`~beo_bench.errors.EnvConfigError` naming the valid ones). How many grasps an episode
allows is gymnasium's ``TimeLimit`` (``max_episode_steps``, registered 1).
"""

from __future__ import annotations

import copy
import difflib
import numbers
from collections.abc import Mapping
from dataclasses import fields
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import trimesh
from gymnasium import spaces

from beo_bench.errors import ActionError, BeoBenchError, EnvConfigError
from beo_bench.grasping import Grasp, plan_grasps
from beo_bench.scenes.builder import Scene
from beo_bench.scenes.camera import pixels_to_points
from beo_bench.scenes.execute import GraspOutcome, execute_grasp, release, settle
from beo_bench.scenes.gripper import MAX_OPENING
from beo_bench.scenes.pickconfig import RENDER_MODES, PickConfig
from beo_bench.scenes.renderer import Frame, Renderer, mujoco
from beo_bench.scenes.sensors import Sensor
from beo_bench.scenes.tabletop import TabletopScenes
from beo_bench.types import Mat4, ObjectState

FAR_CLIP = 20.0
"""Largest depth a scene can report (the far clip plane, metres)."""

OPENING_TOLERANCE = 1e-6
"""How far (m) a finger opening may stray outside [0, ``MAX_OPENING``] and still be taken
(clipped): float32 rounding of a bound, not a user's mistake."""

MAX_POSITION_M = 10.0
"""The largest |x|, |y| or |z| (m) a grasp position may have: far beyond the table (a grasp
off the table but within it is valid and misses), so that only a unit mistake or garbage
is refused (an :class:`ActionError`), never a strategy."""

_STATE = mujoco.mjtState.mjSTATE_INTEGRATION
"""What a copy of the env restores of the physics: everything ``mj_step`` reads (time,
qpos, qvel, actuator state, warm start, controls, applied forces, mocap poses)."""


class EnvStateError(BeoBenchError, RuntimeError):
    """A call the episode's state does not allow: ``step`` before ``reset`` or after the
    episode terminated (gymnasium's ``OrderEnforcing`` raises ``ResetNeeded`` for the first
    through ``gym.make``; the env itself checks both)."""


class BEOPickEnv(gym.Env):
    """Pick the object of a target class from one segmented depth image.

    ## Description

    On ``reset``, 1-k objects of distinct categories from an object split are placed on a
    table in their rest poses with a random yaw, settled by physics, and seen by one depth
    camera sampled around the table (docs/design.md "Environments"). The observation names
    the category to pick (``target_class``, "pick the mug"); the agent answers with one
    parallel-jaw grasp, which ``step`` executes physically with a free-floating gripper.

    ## Action Space

    ``Box(8,)`` float32, a grasp in the **world frame** (z up, the table top at
    ``table.table_height`` = 0.72 m):

    | index | meaning | unit / range |
    |---|---|---|
    | 0-2 | TCP position x y z | metres; x, y within the table, z in [0, 2] |
    | 3-6 | gripper orientation, quaternion **w x y z** | any (normalised; zero: identity) |
    | 7 | finger opening | metres, [0, 0.08] |

    The gripper frame approaches along its +z axis and closes along +y (see
    ``beo_bench.scenes.gripper``). The space is not normalised to [-1, 1]: positions are in
    metres so that a planner's grasp (``Grasp.action``) is an action as it is. A zero
    quaternion is the identity orientation, so that the zero action of an agent behind
    ``RescaleAction`` (the space's centre) is valid. A wrong shape, NaN/inf or an opening
    outside [0, 0.08] raises :class:`~beo_bench.errors.ActionError`.

    ## Observation Space

    A ``Dict``; H, W = ``image_size[1]``, ``image_size[0]``; k = ``max_objects``.

    ``obs_mode="image"`` (default):

    - ``depth``: (H, W) float32, metric z-depth in metres, 0 where nothing was hit;
    - ``segmentation``: (H, W) uint8 (int32 when k >= 255), 0 background and table, 1..k
      objects;
    - ``target_class``: ``Discrete(len(categories))``, an index into
      ``env.unwrapped.categories``;
    - ``intrinsics``: (3, 3) float64 OpenCV K; ``cam_to_world``: (4, 4) float64, OpenCV
      camera axes (x right, y down, z forward).

    ``obs_mode="pointcloud"``: ``points`` (N, 3) float32, camera frame (OpenCV axes),
    metres; ``point_labels`` (N,) with the segmentation's dtype and labels; and
    ``target_class``, ``intrinsics``, ``cam_to_world`` as above. N = ``num_points``
    (default 4096) pixels with depth > 0 are drawn from the env's RNG without replacement
    and back-projected with K; when fewer than N pixels have depth, all of them come first
    and the rest are repeats drawn with replacement, so every point is a real surface point
    (no zero padding); an image without any depth gives N zero points labelled 0.

    ## Rewards

    1.0 when an object of the target class ends lifted at least 10 cm above its rest
    height, else 0.0 (sparse). ``info`` holds ``success`` and ``is_success`` (the same
    bool; the key Stable-Baselines3 and Gymnasium-Robotics read), ``reason`` ("success",
    "wrong_class", "nothing_lifted", "inside_table", ...), ``lifted_label``,
    ``lifted_category``, ``lift_height``, ``finger_contacts``, ``colliding_label`` and
    ``attempt``. When something was lifted, the hold is audited by a shake (+-2 g along x, y
    and z in turn, 0.6 s; ``scenes/execute.py``) that does not change the reward: ``info``
    then holds ``shake_held`` (still lifted afterwards), ``slip_cm`` (how far the object
    moved in the hand), and, from the end of the hold, ``hold_contacts`` and ``grip_n``
    (per finger: contacts with the lifted object and their normal force, N); they are None
    and empty when nothing was lifted.

    ## Starting State

    Drawn from ``np_random`` (``reset(seed=...)`` makes it reproducible): how many objects,
    their categories, instances, positions and yaws, the camera pose from ``camera``, and
    the target among the placed objects. ``reset(options={"target_class": c})`` asks for the
    target's class (``c`` an index into ``categories`` or a category name): every scene
    then holds an object of that class and it is the target, the rest drawn as without the
    option given that target class; without it (or with ``options=None`` or ``{}``) the seed
    gives the scene it always gave. Any other option is an
    :class:`~beo_bench.errors.EnvConfigError`. The target always shows at least
    ``min_target_pixels`` pixels: ``reset`` draws another camera pose (up to
    :data:`~beo_bench.scenes.tabletop.CAMERA_DRAWS`), then another scene (up to
    :data:`~beo_bench.scenes.tabletop.SCENE_DRAWS`), and otherwise raises
    :class:`~beo_bench.scenes.tabletop.NoVisibleTargetError`; an object too large for the
    table raises :class:`~beo_bench.scenes.layout.ObjectTooLargeError`. ``info`` holds
    ``num_objects``, ``attempt`` (0) and ``target_pixels``.

    ## Episode End

    Terminated on success. How many grasps an episode allows is gymnasium's ``TimeLimit``:
    ``gym.make`` adds one of ``max_episode_steps`` steps (registered 1: one grasp; pass
    ``max_episode_steps=3`` for three), which truncates the episode at its last allowed
    miss. The env itself (``BEOPickEnv(...)`` without ``gym.make``) has no limit. ``step``
    after termination (or before ``reset``) raises :class:`EnvStateError`.

    ## Arguments

    ``BEOPickEnv(config)`` takes a :class:`~beo_bench.scenes.pickconfig.PickConfig`;
    ``gym.make("BEOPick-v0", ...)`` takes its fields as keywords, all optional. Bad values
    raise :class:`~beo_bench.errors.EnvConfigError` when the config is made (``gym.make``).

    - ``split``: object split, "train", "val" or "test" ("test");
    - ``num_objects``: a count or a (min, max) range of objects per scene ((1, 4));
    - ``categories``: category names to draw from and to index ``target_class`` with
      (default: every pickable category);
    - ``objects``: an ``ObjectSet`` to draw from instead (e.g. a loaded dataset);
    - ``image_size``: (width, height) in pixels ((640, 480));
    - ``fovy_deg``: vertical field of view in degrees (45);
    - ``camera``: a ``CameraRig`` or a dict of its fields (where cameras are sampled);
    - ``sensor``: the depth sensor, "ideal" (the render as it is), "kinect-v1" or "d435"
      ("ideal"; docs/sensors.md); its noise is drawn from ``np_random``, so the seed fixes
      it too;
    - ``render_mode``: None, "rgb_array" or "depth_array" (metric depth, metres);
    - ``table``: a ``TableConfig``;
    - ``min_target_pixels``: the least visible pixels of the target (50 at 640x480,
      scaled with the image area);
    - ``obs_mode``: "image" or "pointcloud";
    - ``num_points``: points per observation (pointcloud mode only; 4096; at most
      :data:`~beo_bench.scenes.pickconfig.MAX_NUM_POINTS`, 2**20);
    - ``cache_root``: the asset cache the library's objects are kept in (a path; default
      None: ``$BEO_BENCH_CACHE``, else ``~/.cache/beo_bench``).

    ## Version History

    - v0: initial version (depth + segmentation observation, one grasp per episode by
      default, the visible-target guarantee, ``info["is_success"]``, ``depth_array``
      rendering, ``obs_mode="pointcloud"``, uint8 segmentation); ``sensor=`` in place of
      ``noise=`` (the default, ideal depth, observes as before); the ``target_class``
      reset option (a reset without it draws as before); ``max_attempts`` removed: the
      ``TimeLimit`` (``max_episode_steps``) alone sets the grasps per episode, and the last
      allowed miss is truncated rather than terminated.
    """

    # gymnasium annotates Env.metadata as an instance attribute, but it is the class's (read
    # from the class by gym.make and the wrappers, shared by every instance)
    metadata: ClassVar[dict[str, Any]] = {  # type: ignore[misc]
        "render_modes": list(RENDER_MODES),
        "render_fps": 4,
    }

    def __init__(self, config: PickConfig | None = None) -> None:
        self.config = PickConfig() if config is None else config  # checked when made
        self.render_mode = self.config.render_mode
        self.sensor: Sensor = self.config.make_sensor()
        self.observation_space = self._observation_space()
        half = np.array(self.config.table.table_half)
        low = np.array([-half[0], -half[1], 0.0, -1, -1, -1, -1, 0.0], np.float32)
        high = np.array([half[0], half[1], 2.0, 1, 1, 1, 1, MAX_OPENING], np.float32)
        self.action_space = spaces.Box(low, high, dtype=np.float32)
        # the scenes (drawing, settling, rendering) and the current one with its renderer
        self._tabletop = TabletopScenes(self.config)
        self._image: dict[str, np.ndarray] | None = None  # depth + segmentation, either mode
        self._obs: dict[str, Any] | None = None
        self._rest = np.zeros(0)
        self._attempts = 0
        self._terminated = False

    @property
    def categories(self) -> tuple[str, ...]:
        """The classes drawn from; the observation's ``target_class`` indexes them."""
        return self.config.classes

    def _observation_space(self) -> spaces.Dict:
        cfg = self.config
        w, h = cfg.intrinsics.width, cfg.intrinsics.height
        common = {
            "target_class": spaces.Discrete(len(self.categories)),
            "intrinsics": spaces.Box(0.0, 1e6, (3, 3), np.float64),
            "cam_to_world": spaces.Box(-100.0, 100.0, (4, 4), np.float64),
        }
        if cfg.obs_mode == "image":
            return spaces.Dict(
                {
                    "depth": spaces.Box(0.0, FAR_CLIP, (h, w), np.float32),
                    "segmentation": spaces.Box(0, cfg.max_objects, (h, w), cfg.seg_dtype),
                    **common,
                }
            )
        # the view frustum up to the far plane bounds every back-projected point
        K = cfg.intrinsics.K
        x_max = FAR_CLIP * max(K[0, 2], w - 1 - K[0, 2]) / K[0, 0]
        y_max = FAR_CLIP * max(K[1, 2], h - 1 - K[1, 2]) / K[1, 1]
        n = cfg.points
        high = np.tile(np.array([x_max, y_max, FAR_CLIP], np.float32), (n, 1))
        low = -high * np.array([1, 1, 0], np.float32)  # z >= 0: in front of the camera
        return spaces.Dict(
            {
                "points": spaces.Box(low, high, (n, 3), np.float32),
                "point_labels": spaces.Box(0, cfg.max_objects, (n,), cfg.seg_dtype),
                **common,
            }
        )

    # -- the current scene (held by the TabletopScenes) ------------------------------------------
    @property
    def _scene(self) -> Scene | None:
        return self._tabletop.scene

    @property
    def _cam(self) -> Mat4:
        """cam_to_world of the current view (OpenCV axes)."""
        return self._tabletop.cam

    @property
    def _target(self) -> int:
        return self._tabletop.target

    @property
    def _renderer(self) -> Renderer | None:
        """The scenes' renderer (None until the first render, after ``close`` and in a copy)."""
        return self._tabletop.renderer

    # -- public state --------------------------------------------------------------------------
    @property
    def model(self) -> Any:
        """The current scene's MjModel (a new one per episode)."""
        return None if self._scene is None else self._scene.model

    @property
    def data(self) -> Any:
        """The current scene's MjData."""
        return None if self._scene is None else self._scene.data

    @property
    def scene(self) -> Scene | None:
        return self._scene

    @property
    def target_label(self) -> int:
        """Label (in the segmentation) of the object whose category was asked for."""
        return self._target

    def ground_truth(self) -> list[ObjectState]:
        """Per object: label, category, key, symmetry, size, pose in camera and world frames,
        visible pixels in the current observation. Never part of the observation."""
        if self._scene is None or self._image is None:
            raise EnvStateError("call reset() before ground_truth()")
        return self._tabletop.ground_truth(self._image["segmentation"])

    def object_mesh_world(self, label: int) -> trimesh.Trimesh:
        """The ground-truth mesh of object ``label`` posed in the world frame (a copy)."""
        if self._scene is None:
            raise EnvStateError("call reset() before object_mesh_world()")
        if not 1 <= label <= len(self._scene.instances):
            raise ValueError(
                f"label {label}: this scene has objects 1..{len(self._scene.instances)}"
            )
        mesh = self._scene.instances[label - 1].mesh.copy()
        mesh.apply_transform(self._scene.object_pose(label - 1))
        return mesh

    def ground_truth_grasps(self, label: int | None = None, **planner: Any) -> list[Grasp]:
        """Grasps of object ``label`` (default: the target) from its true mesh and pose, with
        the other objects' true surfaces as obstacles: the planner's ceiling, used by the
        ``oracle`` backend and ``beo-bench pick-check``. ``planner`` goes to ``plan_grasps``."""
        label = self._target if label is None else int(label)
        mesh = self.object_mesh_world(label)
        assert self._scene is not None
        others = []
        for i, inst in enumerate(self._scene.instances):
            if i + 1 == label:
                continue
            pts, _ = inst.surface_points()
            T = self._scene.object_pose(i)
            others.append(pts @ T[:3, :3].T + T[:3, 3])
        obstacles = np.concatenate(others) if others else None
        return plan_grasps(mesh, self.config.table.table_height, obstacles, **planner)

    # -- gymnasium API -------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        target = check_reset_options(options, self.categories)
        super().reset(seed=seed)
        frame, pixels = self._tabletop.draw(self.np_random, target)
        assert self._scene is not None  # the draw made it
        self._attempts = 0
        self._terminated = False
        obs = self._observe(frame)
        k = len(self._scene.instances)
        return _copy(obs), {"num_objects": k, "attempt": 0, "target_pixels": pixels}

    def _observe(self, frame: Frame | None = None) -> dict[str, Any]:
        """The observation of the current scene; ``frame``: its rendering if reset has just
        made it (rendering twice would cost a second pass)."""
        assert self._scene is not None
        if frame is None:
            frame = self._tabletop.render()
        if not self.sensor.ideal:
            # the sensor's view of the scene, its noise drawn from the env's generator (the
            # ideal sensor draws nothing: ideal observations are as they always were)
            frame = self._tabletop.capture(self.sensor, self.np_random, frame)
        # depth, segmentation (seg_dtype), target_class, intrinsics, cam_to_world
        view = self._tabletop.observation(frame)
        depth, seg = view.pop("depth"), view.pop("segmentation")
        self._image = {"depth": depth, "segmentation": seg}
        self._rest = self._scene.object_heights()
        if self.config.obs_mode == "image":
            self._obs = {"depth": depth, "segmentation": seg, **view}
        else:
            points, labels = self._sample_points(depth, seg)
            self._obs = {"points": points, "point_labels": labels, **view}
        return self._obs

    def _sample_points(self, depth: np.ndarray, seg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``num_points`` camera-frame points of pixels with depth, drawn from ``np_random``,
        and their labels (see the class docstring for how few valid pixels are padded)."""
        n = self.config.points
        v, u = np.nonzero(depth > 0)
        count = len(v)
        if count == 0:
            return np.zeros((n, 3), np.float32), np.zeros(n, self.config.seg_dtype)
        rng = self.np_random
        if count >= n:
            idx = rng.choice(count, n, replace=False)
        else:  # every valid pixel once, then repeats: all points stay on surfaces
            idx = np.concatenate([np.arange(count), rng.choice(count, n - count, replace=True)])
        # only the drawn pixels are back-projected (not the whole image)
        v, u = v[idx], u[idx]
        points = pixels_to_points(u, v, depth[v, u], self.config.intrinsics.K).astype(np.float32)
        return points, seg[v, u]

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        success, info = self._execute(action, "step")
        assert self._scene is not None and self._obs is not None  # _execute checked
        # a miss leaves the episode open: the TimeLimit (max_episode_steps) ends it
        self._terminated = success
        if not success:
            # another attempt: drop what is held, let the scene come to rest, look again
            release(self._scene)
            settle(self._scene, max_steps=500)
            obs = self._observe()
        else:
            obs = self._obs
        return _copy(obs), float(success), success, False, info

    def grasp(self, action: Any) -> tuple[bool, dict[str, Any]]:
        """One grasp, judged as :meth:`step` judges it (success and the same ``info``), and
        the episode ends there: after a miss the scene is neither settled nor seen again
        (about 0.13 s a miss at 640x480 that a one-grasp episode never uses). The pick
        suite's items make one grasp an episode; :meth:`reset` starts the next."""
        success, info = self._execute(action, "grasp")
        self._terminated = True
        return success, info

    def _execute(self, action: Any, call: str) -> tuple[bool, dict[str, Any]]:
        """Execute and judge one grasp (what :meth:`step` and :meth:`grasp` share)."""
        if self._scene is None or self._obs is None:
            raise EnvStateError(f"call reset() before {call}(): there is no episode to act in")
        if self._terminated:
            raise EnvStateError(
                f"{call}() after the episode terminated (the target was picked, or grasp() "
                "ended it): call reset() to start a new episode"
            )
        T, opening = parse_action(action)
        outcome: GraspOutcome = execute_grasp(self._scene, T, opening, self._rest)
        self._attempts += 1
        lifted = outcome.lifted_label
        lifted_cat = self._scene.instances[lifted - 1].category if lifted else None
        target_cat = self.categories[self._obs["target_class"]]
        success = lifted_cat == target_cat
        reason = "success" if success else outcome.reason
        if lifted and not success:
            reason = "wrong_class"
        info = {
            "success": success,
            # the key Stable-Baselines3's Monitor and Gymnasium-Robotics read for success rates
            "is_success": success,
            "reason": reason,
            "lifted_label": lifted,
            "lifted_category": lifted_cat,
            "lift_height": outcome.lift_height,
            "finger_contacts": outcome.touched,
            "colliding_label": outcome.colliding_label,
            "hold_contacts": outcome.contacts,
            "grip_n": outcome.grip_n,
            "shake_held": outcome.shake_held,
            "slip_cm": outcome.slip_cm,
            "attempt": self._attempts,
        }
        return success, info

    def render(self) -> np.ndarray | None:
        """``rgb_array``: (H, W, 3) uint8 colour image of the camera; ``depth_array``: the
        observation's metric depth (H, W) float32, metres (Gymnasium's own ``depth_array``
        of MuJoCo envs is not metric); None without a render mode."""
        if self.render_mode is None:
            return None
        if self._scene is None or self._image is None:
            raise EnvStateError("call reset() before render()")
        if self.render_mode == "depth_array":
            return np.array(self._image["depth"], dtype=np.float32, copy=True)
        return self._tabletop.render_rgb()

    def rgb(self) -> np.ndarray:
        """(H, W, 3) uint8 colour image of the current scene from the camera, whatever the
        render mode (a BOP export's ``rgb``; never part of the observation)."""
        if self._scene is None or self._image is None:
            raise EnvStateError("call reset() before rgb()")
        return self._tabletop.render_rgb()

    def close(self) -> None:
        self._tabletop.close()  # the renderer and the scene; a later reset makes new ones
        self._image = None
        self._obs = None
        super().close()

    # -- copy and pickle -------------------------------------------------------------------------
    # A GL context cannot be copied, and a scene holds ctypes-backed MuJoCo structures, so a
    # copy is rebuilt from what made it: the constructor's arguments and the episode's state
    # (which objects, where they were placed, the physics state, camera, target, attempts and
    # the RNG). The renderer is not copied; the copy makes its own when it next renders.
    def __getstate__(self) -> dict[str, Any]:
        episode = None
        drawn = self._tabletop.drawn
        if self._scene is not None and drawn is not None and self._obs is not None:
            model, data = self._scene.model, self._scene.data
            physics = np.empty(mujoco.mj_stateSize(model, _STATE))
            mujoco.mj_getState(model, data, physics, _STATE)
            assert self._image is not None
            episode = {
                "drawn": list(drawn[0]),
                "poses": list(drawn[1]),
                "physics": physics,
                "cam": self._cam,
                "target": self._target,
                "attempts": self._attempts,
                "terminated": self._terminated,
                "rest": self._rest,
                # not copied here: pickle and deepcopy copy them, and their memo keeps the
                # observation and the image sharing their arrays (stored once)
                "image": self._image,
                "obs": self._obs,
            }
        return {
            "config": self.config,
            "spec": self.spec,
            "np_random": self._np_random,
            "np_random_seed": self._np_random_seed,
            "episode": episode,
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        # rebuilt by its own class's constructor (mypy: calling __init__ on an instance is unsound)
        self.__init__(state["config"])  # type: ignore[misc]
        self.spec = state["spec"]
        self._np_random = state["np_random"]
        self._np_random_seed = state["np_random_seed"]
        episode = state["episode"]
        if episode is None:
            return
        scene = self._tabletop.restore(
            episode["drawn"], episode["poses"], episode["cam"], episode["target"]
        )
        mujoco.mj_setState(scene.model, scene.data, episode["physics"], _STATE)
        mujoco.mj_forward(scene.model, scene.data)
        self._attempts = episode["attempts"]
        self._terminated = episode["terminated"]
        self._rest = episode["rest"]
        self._image = episode["image"]
        self._obs = episode["obs"]

    def __deepcopy__(self, memo: dict[int, Any]) -> BEOPickEnv:
        # the config is frozen, and its object set may hold a whole dataset: share it
        memo[id(self.config)] = self.config
        new = type(self).__new__(type(self))
        memo[id(self)] = new
        new.__setstate__(copy.deepcopy(self.__getstate__(), memo))
        return new


def make_pick_env(**kwargs: Any) -> BEOPickEnv:
    """``gym.make("BEOPick-v0", ...)``'s entry point: :class:`BEOPickEnv` of
    ``PickConfig(**kwargs)``.

    Two reasons it is a function rather than the class. ``gym.make`` reads the entry point's
    ``metadata`` and, for ``render_mode="human"``, silently swaps in its pygame
    ``HumanRendering`` wrapper (which fails at the first reset without a display); without a
    ``metadata`` attribute the mode reaches the config, which refuses it with the supported
    ones. And ``gym.make`` rewraps a ``TypeError`` from the constructor, so a misspelt keyword
    is reported here as an :class:`EnvConfigError` naming the valid keywords.
    """
    unknown = sorted(set(kwargs) - set(KEYWORDS))
    if unknown:
        valid = list(KEYWORDS)
        hints = [
            f"{u!r}: did you mean {close[0]!r}?"
            for u in unknown
            if (close := difflib.get_close_matches(u, valid, n=1))
        ]
        hint = f" ({'; '.join(hints)})" if hints else ""
        raise EnvConfigError(
            f"BEOPick-v0 got unknown keyword arguments {unknown}{hint}; valid ones are {valid}"
        )
    return BEOPickEnv(PickConfig(**kwargs))


KEYWORDS: tuple[str, ...] = tuple(f.name for f in fields(PickConfig) if f.init)
""":class:`PickConfig`'s fields: what ``gym.make("BEOPick-v0", ...)`` accepts."""


def _copy(obs: dict[str, Any]) -> dict[str, Any]:
    # users keep what they are given: never hand out the env's own arrays
    return {k: v.copy() if isinstance(v, np.ndarray) else v for k, v in obs.items()}


RESET_OPTIONS: tuple[str, ...] = ("target_class",)
"""The keys ``reset(options=...)`` takes: ``target_class``, the class the episode's target
must be (an index into ``categories``, as the observation's, or a category name)."""


def check_reset_options(options: Any, categories: tuple[str, ...]) -> str | None:
    """The category a ``reset(options=...)`` asks for as the target (``target_class``: an
    index into ``categories`` or a name), None when it asks for none (``None`` or an empty
    dict: the target is the seed's draw). Anything else is an :class:`EnvConfigError`
    naming the fix: gymnasium itself passes any options through, so a typo'd one would
    otherwise be silently ignored."""
    if options is None:
        return None
    if not isinstance(options, Mapping):
        raise EnvConfigError(
            f"reset(options={options!r}): options must be a dict or None, got "
            f"{type(options).__name__}"
        )
    unknown = [k for k in options if k not in RESET_OPTIONS]
    if unknown:
        raise EnvConfigError(
            f"reset(options=...): unknown option(s) {', '.join(map(repr, unknown))}; "
            "BEOPick-v0 takes only 'target_class' (the scene is the seed's: reset(seed=N); "
            "the sensor, camera and categories are gym.make keywords)"
        )
    if "target_class" not in options or options["target_class"] is None:
        return None
    return _target_category(options["target_class"], categories)


def _target_category(value: Any, categories: tuple[str, ...]) -> str:
    """The category ``reset(options={"target_class": value})`` names: an index into
    ``categories`` (an int, as the observation's ``target_class``) or one of their names."""
    if isinstance(value, str):
        if value not in categories:
            close = difflib.get_close_matches(value, categories, n=1)
            hint = f"did you mean {close[0]!r}? " if close else ""
            raise EnvConfigError(
                f"reset(options={{'target_class': {value!r}}}): not one of this env's "
                f"categories; {hint}use an index 0..{len(categories) - 1} or a name of "
                f"{list(categories)}"
            )
        return value
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        if not 0 <= int(value) < len(categories):
            raise EnvConfigError(
                f"reset(options={{'target_class': {value!r}}}): out of range; use an index "
                f"0..{len(categories) - 1} into env.unwrapped.categories (or a category name)"
            )
        return categories[int(value)]
    raise EnvConfigError(
        f"reset(options={{'target_class': {value!r}}}): give an index into "
        "env.unwrapped.categories (as the observation's target_class) or a category name"
    )


def parse_action(action: Any) -> tuple[np.ndarray, float]:
    """The gripper pose (4x4, world) and opening of an action; raises :class:`ActionError`
    on a non-numeric action (strings, dicts), a wrong shape, NaN/inf or a finger opening
    outside [0, ``MAX_OPENING``]; normalises the quaternion (zero: the identity)."""
    a = _numeric(action)
    if a.shape != (8,):
        raise ActionError(
            f"action has shape {a.shape}; BEOPick-v0 takes 8 numbers: position x y z (m, "
            "world), quaternion w x y z of the gripper frame, finger opening (m)"
        )
    if not np.all(np.isfinite(a)):
        raise ActionError(f"action {a.tolist()} contains NaN or inf; every entry must be finite")
    opening = float(a[7])
    if not -OPENING_TOLERANCE <= opening <= MAX_OPENING + OPENING_TOLERANCE:
        raise ActionError(
            f"finger opening {opening} m (entry 7) is outside the gripper's range [0, "
            f"{MAX_OPENING}] m; give an opening in that range (it is never clipped for you)"
        )
    reach = np.abs(a[:3]).max()
    if reach > MAX_POSITION_M:
        raise ActionError(
            f"action position {a[:3].tolist()} (entries 0-2) is {reach:g} m from the origin "
            f"along an axis, beyond any reach (|x|, |y|, |z| <= {MAX_POSITION_M:g} m); give the "
            "grasp position in metres in the world frame"
        )
    q = a[3:7]
    T = np.eye(4)
    # a zero quaternion is the identity orientation: the centre of the action space, which
    # an agent's zero action is through RescaleAction (a policy starts there), is an action
    big = float(np.abs(q).max())
    if big > 0:
        from scipy.spatial.transform import Rotation

        # scaled by its largest entry first: the norm of a finite quaternion with an entry
        # near 1e155 overflows to inf, and one near 1e-170 underflows to zero
        u = q / big
        w, x, y, z = u / np.linalg.norm(u)
        T[:3, :3] = Rotation.from_quat([x, y, z, w]).as_matrix()
    T[:3, 3] = a[:3]
    return T, min(max(opening, 0.0), MAX_OPENING)


def _numeric(action: Any) -> np.ndarray:
    """``action`` as a float64 array if it holds numbers (ints or floats) only; numpy would
    turn ``"0.1"`` into 0.1 and fail on a dict with a bare TypeError."""
    try:
        raw = np.asarray(action)
    except (TypeError, ValueError) as e:  # ragged nested lists
        raise ActionError(f"action {action!r} is not an array of 8 numbers: {e}") from e
    if raw.dtype.kind not in "iuf":
        raise ActionError(
            f"action {action!r} is not numeric ({type(action).__name__} of dtype "
            f"{raw.dtype}); give 8 numbers: position x y z (m, world), quaternion w x y z, "
            "finger opening (m)"
        )
    return raw.astype(np.float64)
