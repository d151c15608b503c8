"""The bounds every leaderboard shows: ``oracle`` (the truth) and ``random`` (chance); and
the oracle with controlled damage (``rot_deg``, ``trans_cm``, ``shape=class-mean``): a
privileged diagnostic of which errors of an estimate the pick suite punishes (issue 49)."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from scipy.spatial.transform import Rotation

from beo_bench.backend import Backend, Capabilities, PrepareContext
from beo_bench.errors import ViewError
from beo_bench.objects import instance_from_key
from beo_bench.options import option
from beo_bench.perception.means import ClassMeans, class_means
from beo_bench.types import Estimate, View

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset


@dataclass(frozen=True)
class OracleOptions:
    """The options of ``oracle`` (``--opt KEY=VALUE``)."""

    resolution: int = option(32, "D of the instance's own voxels (Estimate.shape)")
    mesh: bool = option(
        True,
        "hand out the instance's exact mesh for grasp planning (false: plan on its voxels "
        "like any other backend, the ceiling of a D^3 shape)",
    )
    # the truth with controlled damage (issue 49): which errors of an estimate pick punishes
    rot_deg: float = option(
        0.0, "turn the true rotation by this many degrees (0-180) about rot_axis"
    )
    rot_axis: Literal["random", "up"] = option(
        "random",
        "the damage's axis: random (uniform on the sphere, drawn per view) or up (the "
        "world's vertical, a wrong yaw)",
    )
    trans_cm: float = option(
        0.0, "move the true translation this far (0-50 cm), in a direction drawn per view"
    )
    shape: Literal["true", "class-mean"] = option(
        "true",
        "the instance's own shape, or its class's mean occupancy (no mesh: planned on the "
        "voxels) at the true pose and the class's mean size",
    )
    seed: int = option(0, "seeds the damage's draws, with the view's bytes")
    mean_instances: int | None = option(
        None, "with shape=class-mean: training instances per class in the means (null: all)"
    )

    def __post_init__(self) -> None:
        if not 0 <= self.rot_deg <= 180:
            raise ValueError(f"rot_deg={self.rot_deg}: use 0 to 180")
        if not 0 <= self.trans_cm <= 50:
            raise ValueError(f"trans_cm={self.trans_cm}: use 0 to 50")
        if self.rot_axis not in ("random", "up"):
            raise ValueError(f"rot_axis={self.rot_axis!r}: use random or up")
        if self.shape not in ("true", "class-mean"):
            raise ValueError(f"shape={self.shape!r}: use true or class-mean")

    @property
    def damaged(self) -> bool:
        return bool(self.rot_deg or self.trans_cm or self.shape != "true")


class OracleBackend(Backend):
    """Returns the ground truth (class one-hot, pose, size, the instance's own voxels and,
    with ``mesh`` (default), its exact mesh for grasp planning): the upper bound, and a check
    of the metrics and the grasp planner. Privileged: the runner gives it the view's
    ``ground_truth``. ``mesh=False`` makes the pick suite plan on its voxels like any other
    backend (the ceiling of a D^3 shape)."""

    name = "oracle"
    Options = OracleOptions
    capabilities = Capabilities(privileged=True)
    options: OracleOptions

    def __init__(self, options: OracleOptions | None = None, **kwargs: Any) -> None:
        super().__init__(options, **kwargs)
        self._means = MeansCache(self.options.resolution, self.options.mean_instances)

    def prepare(self, ctx: PrepareContext) -> None:
        """Remember the run's dataset, where the views' instance keys are looked up (and
        with ``shape=class-mean`` compute its classes' means once)."""
        self._means.use(ctx.dataset, ctx.cache_root)
        if self.options.shape == "class-mean":
            self._means.get(tuple(ctx.categories), ctx.progress)

    def predict(self, view: View) -> Estimate:
        gt = view.ground_truth
        if gt is None:
            raise ViewError("the oracle needs View.ground_truth (the runner fills it for it)")
        p = np.zeros(len(view.categories))
        p[gt.class_index] = 1.0
        R, t, size = np.array(gt.R_cam), np.array(gt.t_cam), np.array(gt.size)
        o = self.options
        if o.shape == "class-mean":
            means = self._means.get(tuple(view.categories))
            shape, size = means.shape[gt.class_index].copy(), means.size[gt.class_index].copy()
            mesh = None
        else:
            inst = instance_from_key(gt.key, self._means.dataset, self._means.cache_root)
            shape = inst.voxels(o.resolution).astype(np.float32)
            mesh = inst.mesh if o.mesh else None
        if o.damaged:
            R, t = damage(R, t, view, o)
        return Estimate(p, R, t, size, shape, mesh=mesh)


def view_rng(seed: int, view: View) -> np.random.Generator:
    """A generator seeded by ``seed`` and the view's depth and mask bytes: the same view
    draws the same numbers in any process."""
    h = hashlib.sha256(np.ascontiguousarray(view.depth).tobytes())
    h.update(np.packbits(np.asarray(view.mask, dtype=bool)).tobytes())
    return np.random.default_rng([seed, int.from_bytes(h.digest()[:8], "little")])


class MeansCache:
    """The class means (:func:`class_means`) of each class list of one dataset, computed
    once: what ``random`` and the damaged ``oracle`` hand out as a shape."""

    def __init__(self, resolution: int, instances: int | None) -> None:
        self.resolution, self.instances = resolution, instances
        self.dataset: Dataset | None = None
        self.cache_root: Path | None = None
        self._means: dict[tuple[str, ...], ClassMeans] = {}

    def use(self, dataset: Dataset | None, cache_root: Path | None = None) -> None:
        """Another dataset's means are not these; ``cache_root``: the run's asset cache."""
        self.cache_root = cache_root
        if dataset != self.dataset:
            self.dataset = dataset
            self._means.clear()

    def get(self, cats: tuple[str, ...], progress: bool = False) -> ClassMeans:
        if cats not in self._means:
            self._means[cats] = class_means(
                cats, self.resolution, self.instances, progress, self.dataset, self.cache_root
            )
        return self._means[cats]


def damage(
    R: np.ndarray, t: np.ndarray, view: View, o: OracleOptions
) -> tuple[np.ndarray, np.ndarray]:
    """The true pose (camera frame) with ``o``'s damage: turned by ``rot_deg`` about its own
    centre (about an axis uniform on the sphere, or the world's vertical), moved by
    ``trans_cm`` in a direction uniform on the sphere; both drawn per view (seeded by
    ``seed`` and the view's bytes), so a run is deterministic and every view errs by
    exactly the amount asked (before the object's symmetry, which may make a turn about its
    own axis no error at all)."""
    rng = view_rng(o.seed, view)
    axis, direction = rng.normal(size=3), rng.normal(size=3)
    if o.rot_axis == "up":  # the world's +z in the camera frame
        axis = np.asarray(view.cam_to_world, dtype=np.float64)[:3, :3].T @ np.array([0, 0, 1.0])
    axis /= np.linalg.norm(axis)
    direction /= np.linalg.norm(direction)
    turn = Rotation.from_rotvec(np.radians(o.rot_deg) * axis).as_matrix()
    return turn @ R, t + 0.01 * o.trans_cm * direction


@dataclass(frozen=True)
class RandomOptions:
    """The options of ``random`` (``--opt KEY=VALUE``)."""

    seed: int = option(0, "seeds the draws, with the view's bytes (same view, same estimate)")
    resolution: int = option(32, "D of the class-mean occupancy (Estimate.shape)")
    mean_instances: int | None = option(
        None, "training instances per class in the class means (null: all)"
    )


class RandomBackend(Backend):
    """Chance: a uniformly random class (its probabilities peak there), a uniformly random
    rotation, the class-mean shape and size, placed at the centroid of the observed points.
    Deterministic for a given view (its generator is seeded from the view's bytes and
    ``seed``)."""

    name = "random"
    Options = RandomOptions
    options: RandomOptions

    def __init__(self, options: RandomOptions | None = None, **kwargs: Any) -> None:
        super().__init__(options, **kwargs)
        self._means = MeansCache(self.options.resolution, self.options.mean_instances)

    def prepare(self, ctx: PrepareContext) -> None:
        """Compute (or load) the class means of the run's classes and dataset once (with a
        progress bar where ``ctx.progress``)."""
        self._means.use(ctx.dataset, ctx.cache_root)
        self._means.get(tuple(ctx.categories), ctx.progress)

    def predict(self, view: View) -> Estimate:
        pts = view.points()
        if len(pts) == 0:
            raise ViewError("the mask has no pixel with valid depth: nothing to estimate from")
        cats = view.categories
        means = self._means.get(tuple(cats))
        rng = view_rng(self.options.seed, view)
        c = int(rng.integers(len(cats)))
        R = Rotation.random(random_state=rng).as_matrix()
        # the class it drew gets twice the others' probability: argmax is that uniformly
        # drawn class (uniform probabilities would make argmax always class 0), and the
        # probabilities still say how little it knows
        p = np.full(len(cats), 1.0 / (len(cats) + 1))
        p[c] *= 2.0
        return Estimate(p, R, pts.mean(axis=0), means.size[c].copy(), means.shape[c].copy())
