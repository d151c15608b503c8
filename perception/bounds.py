"""The bounds every leaderboard shows: ``oracle`` (the truth) and ``random`` (chance)."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial.transform import Rotation

from beo_bench.backend import Backend, BackendSpec, Capabilities, register
from beo_bench.errors import ViewError
from beo_bench.objects import instance_from_key
from beo_bench.options import option
from beo_bench.perception.means import ClassMeans, class_means
from beo_bench.types import Estimate, View

if TYPE_CHECKING:
    from beo_bench.bench.runs import RunContext
    from beo_bench.objects.dataset import Dataset


@dataclass(frozen=True)
class OracleOptions:
    """The options of ``oracle`` (``--opt KEY=VALUE``)."""

    resolution: int = option(32, "D of the instance's own voxels (Estimate.shape)")
    mesh: bool = option(
        True,
        "hand out the instance's exact mesh for grasp planning (false: plan on its voxels "
        "like any other backend, the ceiling of a D^3 shape)",
    )


class OracleBackend(Backend):
    """Returns the ground truth (class one-hot, pose, size, the instance's own voxels and,
    with ``mesh`` (default), its exact mesh for grasp planning): the upper bound, and a check
    of the metrics and the grasp planner. Privileged: the runner gives it the view's
    ``ground_truth``. ``mesh=False`` makes the pick suite plan on its voxels like any other
    backend (the ceiling of a D^3 shape)."""

    name = "oracle"

    def __init__(self, options: OracleOptions | None = None, **kwargs: Any) -> None:
        self.options = options if options is not None else OracleOptions(**kwargs)
        self.resolution = self.options.resolution
        self.mesh = self.options.mesh
        self._dataset: Dataset | None = None

    def prepare(self, ctx: RunContext) -> None:
        """Remember the run's dataset, where the views' instance keys are looked up."""
        self._dataset = ctx.dataset

    def predict(self, view: View) -> Estimate:
        gt = view.ground_truth
        if gt is None:
            raise ViewError("the oracle needs View.ground_truth (the runner fills it for it)")
        p = np.zeros(len(view.categories))
        p[gt.class_index] = 1.0
        inst = instance_from_key(gt.key, self._dataset)
        shape = inst.voxels(self.resolution).astype(np.float32)
        R, t, size = np.array(gt.R_cam), np.array(gt.t_cam), np.array(gt.size)
        return Estimate(p, R, t, size, shape, mesh=inst.mesh if self.mesh else None)


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

    def __init__(self, options: RandomOptions | None = None, **kwargs: Any) -> None:
        self.options = options if options is not None else RandomOptions(**kwargs)
        self.seed = self.options.seed
        self.resolution = self.options.resolution
        self.mean_instances = self.options.mean_instances
        self._dataset: Dataset | None = None
        self._means: dict[tuple[str, ...], ClassMeans] = {}

    def _rng(self, view: View) -> np.random.Generator:
        h = hashlib.sha256(np.ascontiguousarray(view.depth).tobytes())
        h.update(np.packbits(np.asarray(view.mask, dtype=bool)).tobytes())
        return np.random.default_rng([self.seed, int.from_bytes(h.digest()[:8], "little")])

    def prepare(self, ctx: RunContext) -> None:
        """Compute (or load) the class means of the run's classes and dataset once (with a
        progress bar where ``ctx.progress``)."""
        if ctx.dataset != self._dataset:  # another dataset's means are not these
            self._dataset = ctx.dataset
            self._means.clear()
        self._class_means(tuple(ctx.categories), ctx.progress)

    def _class_means(self, cats: tuple[str, ...], progress: bool = False) -> ClassMeans:
        if cats not in self._means:
            self._means[cats] = class_means(
                cats, self.resolution, self.mean_instances, progress, self._dataset
            )
        return self._means[cats]

    def predict(self, view: View) -> Estimate:
        pts = view.points()
        if len(pts) == 0:
            raise ViewError("the mask has no pixel with valid depth: nothing to estimate from")
        cats = view.categories
        means = self._class_means(cats)
        rng = self._rng(view)
        c = int(rng.integers(len(cats)))
        R = Rotation.random(random_state=rng).as_matrix()
        # the class it drew gets twice the others' probability: argmax is that uniformly
        # drawn class (uniform probabilities would make argmax always class 0), and the
        # probabilities still say how little it knows
        p = np.full(len(cats), 1.0 / (len(cats) + 1))
        p[c] *= 2.0
        return Estimate(p, R, pts.mean(axis=0), means.size[c].copy(), means.shape[c].copy())


register(
    BackendSpec(
        name="oracle",
        build=OracleBackend,
        options=OracleOptions,
        capabilities=Capabilities(privileged=True),
    )
)
register(
    BackendSpec(
        name="random",
        build=RandomBackend,
        options=RandomOptions,
    )
)
