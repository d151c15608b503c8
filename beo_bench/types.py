"""Array aliases and small shared value types.

Shapes are given in the alias names' docstrings; units are metres and radians unless a
name says otherwise. Frames: an object's *canonical* frame has +z up and +x front, with the
origin at the centre of its axis-aligned bounding box (see ``beo_bench.objects``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypedDict

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.floating[Any]]
"""Any float array."""
Vec3 = NDArray[np.float64]
"""(3,) vector."""
Mat3 = NDArray[np.float64]
"""(3, 3) matrix, e.g. a rotation."""
Mat4 = NDArray[np.float64]
"""(4, 4) homogeneous transform."""
Points = NDArray[np.float64]
"""(N, 3) points."""
BoolGrid = NDArray[np.bool_]
"""(D, D, D) occupancy grid indexed [x, y, z]."""


class ContinuousSymmetry(TypedDict):
    """A continuous rotational symmetry: any angle about ``axis`` through ``offset``."""

    axis: list[float]
    offset: list[float]


class Symmetry(TypedDict):
    """A symmetry group in the BOP toolkit's ``models_info`` form.

    ``continuous`` lists axes of continuous rotational symmetry; ``discrete`` lists the
    non-identity 4x4 transforms (nested lists, metres) that map the object onto itself.
    An empty group is ``{"continuous": [], "discrete": []}``.
    """

    continuous: list[ContinuousSymmetry]
    discrete: list[list[list[float]]]


@dataclass(frozen=True)
class ObjectState:
    """Ground truth of one object in a scene (``env.unwrapped.ground_truth()``).

    Poses map the object's canonical frame (+z up, +x front, bounding-box centre at the
    origin) to the camera frame (OpenCV axes: x right, y down, z forward) or the world frame
    (+z up). Metres.
    """

    label: int
    """Its value in the segmentation image (1..k)."""
    category: str
    key: str
    """Instance key (``beo_bench.objects.instance_from_key`` rebuilds the instance)."""
    symmetry: Symmetry
    size: Vec3
    """(3,) extents of the canonical bounding box (m)."""
    R_cam: Mat3
    t_cam: Vec3
    R_world: Mat3
    t_world: Vec3
    pixels: int
    """How many pixels of the current observation show it (0: occluded or out of view)."""


@dataclass(frozen=True)
class GroundTruth:
    """The truth about the object a ``View`` shows; given to metrics, and to a backend only
    whose spec declares it ``privileged`` (the ``oracle`` bound).

    Frames and units as ``ObjectState``: ``R_cam`` (3, 3) and ``t_cam`` (3,) map the
    canonical frame to the camera frame (OpenCV axes), metres.
    """

    category: str
    class_index: int
    """Index of ``category`` in the view's ``categories``."""
    key: str
    symmetry: Symmetry
    R_cam: Mat3
    t_cam: Vec3
    size: Vec3
    """(3,) canonical bounding-box extents (m)."""

    @classmethod
    def of(cls, obj: Any, categories: tuple[str, ...], R_cam: Mat3, t_cam: Vec3) -> GroundTruth:
        """The truth about ``obj`` (anything with ``category``, ``key``, ``symmetry`` and
        ``size``: an ``ObjectInstance`` or an ``ObjectState``) seen at (R_cam, t_cam)."""
        return cls(
            category=obj.category,
            class_index=categories.index(obj.category),
            key=obj.key,
            symmetry=obj.symmetry,
            R_cam=np.asarray(R_cam, dtype=np.float64),
            t_cam=np.asarray(t_cam, dtype=np.float64),
            size=np.asarray(obj.size, dtype=np.float64),
        )


@dataclass(frozen=True)
class ViewpointPrior:
    """The distribution a suite draws its viewpoints from, published as part of the protocol
    so that any backend may use it as its pose prior P(R) (eq. 3.22). The learned backends
    absorb it from their training views (rendered from the same rig); a search-based one
    (``beo``) is told it here.

    The isolated suites' rig (``scenes.camera.OBJECT_RIG``) looks at the object's centre
    from an azimuth uniform over the full circle, an elevation uniform in ``elevation_deg``
    above the object's horizontal plane, with a roll about the optical axis drawn from
    N(0, ``roll_sigma_deg``). So P(R) depends only on where the object's up (canonical +z,
    ``R[:, 2]``) points in the camera frame (OpenCV axes): ``u = (-sin(roll) cos(el),
    -cos(roll) cos(el), -sin(el))``, uniform in the rotation about it. :meth:`log_prob` is
    log P(R) relative to the uniform distribution over SO(3) (0 everywhere would be no
    prior): ``log 4 pi + log p(el) + log p(roll) - log cos(el)``, the last term the area
    element of the (el, roll) chart of the sphere."""

    elevation_deg: tuple[float, float]
    roll_sigma_deg: float

    def __post_init__(self) -> None:
        from beo_bench.errors import ViewError

        lo, hi = self.elevation_deg
        if not -90.0 <= lo <= hi <= 90.0 or not 0.0 <= self.roll_sigma_deg < 180.0:
            raise ViewError(
                f"ViewpointPrior(elevation_deg={self.elevation_deg}, roll_sigma_deg="
                f"{self.roll_sigma_deg}): give an elevation range low <= high within [-90, 90] "
                "degrees and a roll standard deviation in [0, 180) degrees"
            )

    @classmethod
    def of_rig(cls, rig: Any) -> ViewpointPrior:
        """The prior of a ``scenes.camera.CameraRig`` whose target is the object's centre."""
        lo, hi = rig.elevation_deg
        return cls((float(lo), float(hi)), float(rig.roll_sigma_deg))

    def angles(self, R: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(elevation, roll) in degrees of rotations ``R`` (..., 3, 3) canonical -> camera:
        the rig's angles that would give the object's up ``R[..., :, 2]``."""
        u = np.asarray(R, dtype=np.float64)[..., :, 2]
        el = np.degrees(np.arcsin(np.clip(-u[..., 2], -1.0, 1.0)))
        roll = np.degrees(np.arctan2(-u[..., 0], -u[..., 1]))
        return el, roll

    def log_prob(self, R: FloatArray, soft_deg: float = 0.0) -> FloatArray:
        """log P(R) (..., ) relative to uniform over SO(3) (see the class docstring).
        ``soft_deg`` > 0 replaces the elevation range's hard edges (-inf outside) by a
        Gaussian fall-off of that width, for a search whose hypotheses may lie a little
        outside it."""
        el, roll = self.angles(R)
        lo, hi = self.elevation_deg
        width = np.radians(max(hi - lo, 1e-6))
        out_by = np.maximum(lo - el, 0.0) + np.maximum(el - hi, 0.0)
        if soft_deg > 0:
            log_el = -np.log(width) - 0.5 * (out_by / soft_deg) ** 2
        else:
            log_el = np.where(out_by > 0, -np.inf, -np.log(width))
        sigma = np.radians(max(self.roll_sigma_deg, 1e-6))
        log_roll = -0.5 * (np.radians(roll) / sigma) ** 2 - np.log(sigma * np.sqrt(2 * np.pi))
        # the area element of the (el, roll) chart; clipped where the chart is singular
        cos_el = np.maximum(np.cos(np.radians(el)), 1e-3)
        return np.log(4 * np.pi) + log_el + log_roll - np.log(cos_el)

    def support(
        self, R: FloatArray, margin_deg: float = 0.0, roll_sigmas: float = 3.0
    ) -> NDArray[np.bool_]:
        """(...,) bool: rotations whose elevation lies in the range widened by
        ``margin_deg`` and whose roll is within ``roll_sigmas`` standard deviations (plus
        the margin): where a search need look (3 sigma hold 99.7% of the rolls)."""
        el, roll = self.angles(R)
        lo, hi = self.elevation_deg
        in_el = (el >= lo - margin_deg) & (el <= hi + margin_deg)
        in_roll = np.abs(roll) <= roll_sigmas * self.roll_sigma_deg + margin_deg
        return np.asarray(in_el & in_roll, dtype=bool)

    def frame(self) -> Mat3:
        """The rotation that takes this prior's reference frame to the camera's: the
        identity (the rig's angles are the camera's own)."""
        return np.eye(3)

    def canonical(self) -> ViewpointPrior:
        """This prior in its reference frame (:meth:`frame` the identity): itself."""
        return self


@dataclass(frozen=True)
class RestPrior:
    """How objects rest on a table: the distribution of the angle (tilt) between an
    object's canonical up (+z) and the world's up, learned from the training split's own
    tabletop scenes (:func:`beo_bench.perception.means.fit_rest_prior`, published as
    ``perception/published/rest-prior``). Where a view carries the world's up
    (``View.world_up``: the tabletop and pick suites, whose protocol reveals the table
    plane), :meth:`in_view` places it in the camera frame and it is a pose prior P(R) as
    :class:`ViewpointPrior` is: ``beo`` adds log P(R) to eq. 3.22 and searches its support,
    ``icp`` starts from rotations drawn from it. It is the prior the learned backends absorb
    from their tabletop training crops, given to the search-based ones explicitly.

    The density is a kernel estimate in the polar chart of the sphere about the up (tilt t,
    azimuth a; coordinates t cos a, t sin a): each training tilt ``tilt_deg[i]`` at a
    uniformly random azimuth (a scene's yaw is uniform) smoothed by an isotropic Gaussian of
    ``bandwidth_deg``. Averaged over the azimuth, a sample's kernel is the Rice density,
    ``exp(-(t^2 + t_i^2) / 2h^2) I0(t t_i / h^2) / (2 pi h^2)`` per unit chart area, times
    ``t / sin t`` per steradian; uniform over SO(3) the up is uniform on the sphere (1 / 4 pi
    per steradian), so :meth:`log_prob` is ``log 4 pi + log f(t)`` relative to uniform.
    ``up``: the world's up in the frame rotations are given in (camera axes after
    :meth:`in_view`)."""

    tilt_deg: tuple[float, ...]
    bandwidth_deg: float
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        from beo_bench.errors import ViewError

        t = np.asarray(self.tilt_deg, dtype=np.float64)
        u = np.asarray(self.up, dtype=np.float64)
        if (
            t.ndim != 1
            or not len(t)
            or not np.all(np.isfinite(t))
            or np.any((t < 0) | (t > 180))
            or not 0.0 < self.bandwidth_deg < 45.0
            or u.shape != (3,)
            or not np.all(np.isfinite(u))
            or abs(np.linalg.norm(u) - 1.0) > 1e-6
        ):
            raise ViewError(
                f"RestPrior(tilt_deg of {len(t)} values, bandwidth_deg={self.bandwidth_deg}, "
                f"up={self.up}): give at least one tilt in [0, 180] degrees, a bandwidth in "
                "(0, 45) degrees and a unit up vector"
            )

    def in_view(self, world_up: Vec3) -> RestPrior:
        """This prior with the world's up at ``world_up`` (the camera frame's
        ``View.world_up``)."""
        u = np.asarray(world_up, dtype=np.float64).reshape(3)
        u = u / np.linalg.norm(u)
        return RestPrior(self.tilt_deg, self.bandwidth_deg, (float(u[0]), float(u[1]), float(u[2])))

    def canonical(self) -> RestPrior:
        """This prior with the up at +z: its reference frame (a search's candidate set,
        cached once, is turned into a view's camera frame by :meth:`frame`)."""
        return RestPrior(self.tilt_deg, self.bandwidth_deg)

    def frame(self) -> Mat3:
        """The rotation taking +z to ``up`` (the reference frame to the camera's)."""
        from scipy.spatial.transform import Rotation

        u = np.asarray(self.up, dtype=np.float64)
        if u[2] < -1.0 + 1e-12:  # straight down: any half-turn about a horizontal axis
            return np.diag([1.0, -1.0, -1.0])
        # the smallest rotation (scipy's for one pair of vectors); no import of geometry,
        # which imports this module
        return Rotation.align_vectors(u[None], np.array([[0.0, 0.0, 1.0]]))[0].as_matrix()

    def tilt(self, R: FloatArray) -> FloatArray:
        """(...,) degrees between each rotation's canonical up ``R[..., :, 2]`` and ``up``."""
        u = np.asarray(R, dtype=np.float64)[..., :, 2] @ np.asarray(self.up, dtype=np.float64)
        return np.degrees(np.arccos(np.clip(u, -1.0, 1.0)))

    def log_prob(self, R: FloatArray, soft_deg: float = 0.0) -> FloatArray:
        """log P(R) (...,) relative to uniform over SO(3) (the class docstring). The kernel
        estimate is smooth already: ``soft_deg`` (:meth:`ViewpointPrior.log_prob`'s edge
        softening) changes nothing."""
        from scipy.special import i0e, logsumexp

        t = np.radians(self.tilt(R))[..., None]
        ti = np.radians(np.asarray(self.tilt_deg, dtype=np.float64))
        h2 = np.radians(self.bandwidth_deg) ** 2
        # log of exp(-(t^2 + ti^2) / 2h^2) I0(t ti / h^2), with I0(x) = i0e(x) e^x (x >= 0)
        x = t * ti / h2
        terms = -((t - ti) ** 2) / (2 * h2) + np.log(i0e(x))
        log_f = logsumexp(terms, axis=-1) - np.log(len(ti)) - np.log(2 * np.pi * h2)
        # the chart's area element is t dt da, the sphere's sin(t) dt da: per steradian the
        # density is t / sin(t) times the chart's (1 at the pole, 1.6 at 95 degrees)
        t = t[..., 0]
        jac = np.where(t < 1e-6, 1.0, t / np.maximum(np.sin(t), 1e-6))
        return np.log(4 * np.pi) + log_f + np.log(jac)

    def max_tilt_deg(self, sigmas: float = 3.0) -> float:
        """The tilt beyond which the density is negligible: the largest training tilt plus
        ``sigmas`` bandwidths."""
        return float(max(self.tilt_deg)) + sigmas * self.bandwidth_deg

    def support(
        self, R: FloatArray, margin_deg: float = 0.0, roll_sigmas: float = 3.0
    ) -> NDArray[np.bool_]:
        """(...,) bool: rotations tilted at most :meth:`max_tilt_deg` (``roll_sigmas``
        bandwidths) plus ``margin_deg``: where a search need look."""
        return np.asarray(self.tilt(R) <= self.max_tilt_deg(roll_sigmas) + margin_deg, dtype=bool)

    def sample(self, n: int, rng: np.random.Generator) -> FloatArray:
        """(n, 3, 3) rotations drawn from the prior: a yaw about the up (stratified over the
        circle), then a tilt, a training sample's at a uniform azimuth plus the kernel's
        Gaussian; built about +z and turned by :meth:`frame`."""
        from scipy.spatial.transform import Rotation

        ti = np.radians(np.asarray(self.tilt_deg, dtype=np.float64))
        base = ti[rng.integers(len(ti), size=n)]
        az = rng.uniform(0.0, 2 * np.pi, n)
        # the tangent-plane tilt vector: the sample's at its azimuth, plus the kernel
        w = base[:, None] * np.stack([np.cos(az), np.sin(az)], 1)
        w = w + rng.normal(0.0, np.radians(self.bandwidth_deg), (n, 2))
        tilt = Rotation.from_rotvec(np.concatenate([w, np.zeros((n, 1))], 1))
        # stratified yaws (one in each n-th of the circle): drawn, and spread as starts need
        psi = 2 * np.pi * (np.arange(n) + rng.uniform(0.0, 1.0, n)) / n
        yaw = Rotation.from_rotvec(psi[:, None] * np.array([0.0, 0.0, 1.0]))
        return self.frame() @ (tilt * yaw).as_matrix()


PosePrior = ViewpointPrior | RestPrior
"""A pose prior P(R) a view may come with: the isolated suites' rig, or how objects rest
on a table placed by the world's up."""


@dataclass(frozen=True)
class View:
    """One segmented depth observation of one object: what a perception backend sees.

    - ``depth``: (H, W) float32, metric z-depth along the optical axis (m), 0 = no data;
    - ``mask``: (H, W) bool, the object's pixels (its segment, possibly occluded);
    - ``K``: (3, 3) OpenCV intrinsics (pixels); ``cam_to_world``: (4, 4), OpenCV camera axes
      (x right, y down, z forward), world +z up;
    - ``categories``: the class list that ``Estimate.class_probs`` indexes;
    - ``segmentation``: optional (H, W) instance labels of the whole image (0 = background
      and table, 1..k objects), for backends that use context; uint8 when the scene's
      labels are below 255 (every BEOPick-v0 scene), int32 otherwise (see
      ``scenes.renderer.Frame``): widen it before arithmetic such as ``seg - 1``;
    - ``class_hint``: optional index of the true class, given in the ``class-given`` track
      of a pose suite (``Suite.track``) to backends whose capabilities use it
      (``Capabilities.class_hint``: optional or required); a
      backend that can use it uses it whenever a view carries it (the dissertation's pose
      comparisons gave every method the class);
    - ``up_hint``: optional (3,) unit vector, the object's canonical +z in the camera frame,
      given when only the rotation about the vertical is unknown (the ``pose-1dof`` protocol,
      section 3.3.2; on a table it is the world's up);
    - ``pose_hint``: optional (R_cam, t_cam, size) truth, given by the ``known-pose``
      protocol (class and completion with the pose known, Table 3.1);
    - ``viewpoint_prior``: optional :class:`ViewpointPrior`, the distribution the suite
      drew this view's camera pose from (the isolated suites' rig), for backends that use
      a pose prior; None where no such distribution is published (tabletop scenes, views
      a user makes);
    - ``world_up``: optional (3,) unit vector, the world's up (against gravity) in the
      camera frame, where the protocol reveals the table plane (``tabletop`` and ``pick``:
      ``cam_to_world``'s +z, which :meth:`from_observation` gives); None where the world
      frame is a random rigid frame that says nothing (the isolated suites). Objects rest
      on a table in poses a backend may learn from the training split
      (:class:`RestPrior`);
    - ``ground_truth``: filled only for privileged backends (see ``GroundTruth``).

    Making one: :meth:`from_observation` for an object of a BEOPick-v0 observation,
    ``scenes.IsolatedView.to_view`` for a rendered isolated instance.
    """

    depth: FloatArray
    mask: NDArray[np.bool_]
    K: Mat3
    cam_to_world: Mat4
    categories: tuple[str, ...]
    segmentation: NDArray[np.integer[Any]] | None = None
    class_hint: int | None = None
    up_hint: Vec3 | None = None
    pose_hint: tuple[Mat3, Vec3, Vec3] | None = None
    ground_truth: GroundTruth | None = None
    viewpoint_prior: ViewpointPrior | None = None
    world_up: Vec3 | None = None

    def __post_init__(self) -> None:
        from beo_bench.errors import ViewError

        d = np.asarray(self.depth)
        if d.ndim != 2:
            raise ViewError(f"View.depth must be (H, W), got shape {d.shape}")
        m = np.asarray(self.mask)
        if m.shape != d.shape:
            raise ViewError(f"View.mask must match depth {d.shape}, got {m.shape}")
        if np.asarray(self.K).shape != (3, 3) or np.asarray(self.cam_to_world).shape != (4, 4):
            raise ViewError("View.K must be (3, 3) and View.cam_to_world (4, 4)")
        if not self.categories:
            raise ViewError("View.categories is empty: give the class list to predict over")

    @classmethod
    def from_observation(
        cls, obs: Mapping[str, Any], label: int, categories: Sequence[str]
    ) -> View:
        """The view of the object labelled ``label`` in a BEOPick-v0 observation (the dict
        ``reset()`` and ``step()`` return), built as the tabletop and pick suites build
        theirs: its ``depth``, ``mask = segmentation == label``, ``K`` from
        ``intrinsics``, ``cam_to_world``, and the whole ``segmentation`` for context.
        ``categories`` is the class list the estimate's ``class_probs`` index (the env's
        ``env.unwrapped.categories``). Objects are labelled 1..k
        (``env.unwrapped.ground_truth()`` lists them; ``env.unwrapped.target_label`` is the
        one asked for). Raises :class:`~beo_bench.errors.ViewError` for an observation
        without those keys, a label that is not an object's, or one that shows no pixel
        (hidden or out of view)."""
        from beo_bench.errors import ViewError

        keys = ("depth", "segmentation", "intrinsics", "cam_to_world")
        missing = [k for k in keys if k not in obs]
        if missing:
            raise ViewError(
                f"the observation has no {', '.join(repr(k) for k in missing)}: pass the dict "
                "that BEOPick-v0's reset() or step() returns"
            )
        if isinstance(categories, str):
            raise ViewError(
                f"categories={categories!r} is one string: give the sequence of class names "
                "(env.unwrapped.categories)"
            )
        if isinstance(label, bool) or not isinstance(label, int | np.integer):
            raise ViewError(f"label must be an integer object label (1..k), got {label!r}")
        seg = np.asarray(obs["segmentation"])

        def present() -> list[int]:  # for the messages only (np.unique is 3 ms at 640x480)
            return [int(x) for x in np.unique(seg) if x > 0]

        if label < 1:
            raise ViewError(
                f"label {label} is not an object: 0 is the background and table, objects are "
                f"1..k (in this image: {present()})"
            )
        mask = seg == label
        if not mask.any():
            raise ViewError(
                f"label {label} shows no pixel in this observation (hidden or out of view); "
                f"the objects in the image are {present()}"
            )
        cam_to_world = np.asarray(obs["cam_to_world"], dtype=np.float64)
        return cls(
            depth=np.asarray(obs["depth"]),
            mask=mask,
            K=np.asarray(obs["intrinsics"], dtype=np.float64),
            cam_to_world=cam_to_world,
            categories=tuple(categories),
            segmentation=seg,
            # the env's world is the robot's: +z is up, the table plane's normal
            world_up=cam_to_world[2, :3].copy(),
        )

    def unit_up(self) -> Vec3 | None:
        """``up_hint`` as a unit vector, or None without one; raises ``ViewError`` for a
        non-finite or zero vector."""
        from beo_bench.errors import ViewError

        if self.up_hint is None:
            return None
        up = np.asarray(self.up_hint, dtype=np.float64).reshape(3)
        if not np.all(np.isfinite(up)) or np.linalg.norm(up) < 1e-9:
            raise ViewError(f"View.up_hint must be a finite non-zero 3-vector, got {up}")
        return up / np.linalg.norm(up)

    def candidate_classes(self, use_hint: bool) -> list[int]:
        """The class indices a backend should consider: only ``class_hint`` when it is given
        and the backend uses it, else all; raises ``ViewError`` for a hint out of range."""
        from beo_bench.errors import ViewError

        if not use_hint or self.class_hint is None:
            return list(range(len(self.categories)))
        if not 0 <= int(self.class_hint) < len(self.categories):
            raise ViewError(
                f"View.class_hint={self.class_hint} is not an index into "
                f"{len(self.categories)} classes"
            )
        return [int(self.class_hint)]

    def points(self) -> Points:
        """(N, 3) camera-frame points of the mask's pixels with valid depth (OpenCV axes)."""
        d = np.asarray(self.depth)
        keep = np.asarray(self.mask, dtype=bool) & np.isfinite(d) & (d > 0)
        v, u = np.nonzero(keep)
        z = d[v, u].astype(np.float64)
        K = np.asarray(self.K, dtype=np.float64)
        return np.stack([(u - K[0, 2]) * z / K[0, 0], (v - K[1, 2]) * z / K[1, 1], z], axis=1)


@dataclass
class Estimate:
    """A backend's estimate of one object.

    - ``class_probs``: (C,) probabilities over ``View.categories``, summing to 1;
    - ``rotation``: (3, 3) canonical -> camera (a proper rotation);
    - ``translation``: (3,) canonical origin (bounding-box centre) in the camera frame (m);
    - ``size``: (3,) canonical bounding-box extents (m), all > 0;
    - ``shape``: (D, D, D) float32 occupancy probabilities in [0, 1], canonical frame scaled
      into the unit cube (edge = the largest extent), indexed [x, y, z] like
      ``ObjectInstance.voxels``;
    - ``pose_samples`` / ``pose_weights``: optional (N, 3, 3) rotations and (N,) weights
      summing to 1 (HBEO-MDN's samples);
    - ``mesh``: optional explicit surface (a watertight ``trimesh.Trimesh``) in the canonical
      frame at the estimated size (metres, not the unit cube), for backends that have one
      (the oracle's true mesh, a CAD-retrieval method); grasp planning uses it instead of
      marching cubes on ``shape``, which is still required and still scored;
    - ``info``: free-form extras (JSON-serialisable) a backend wants recorded.
    """

    class_probs: FloatArray
    rotation: Mat3
    translation: Vec3
    size: Vec3
    shape: FloatArray
    pose_samples: FloatArray | None = None
    pose_weights: FloatArray | None = None
    mesh: Any | None = None
    info: dict[str, Any] | None = None

    @property
    def class_index(self) -> int:
        return int(np.argmax(self.class_probs))
