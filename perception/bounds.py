"""The bounds every leaderboard shows: ``oracle`` (the truth) and ``random`` (chance)."""

from __future__ import annotations

import hashlib

import numpy as np
from scipy.spatial.transform import Rotation

from beo_bench.backend import as_bool, register_backend
from beo_bench.errors import ViewError
from beo_bench.objects import instance_from_key
from beo_bench.perception.means import class_means
from beo_bench.types import Estimate, View


@register_backend("oracle")
class OracleBackend:
    """Returns the ground truth (class one-hot, pose, size, the instance's own voxels and,
    with ``mesh`` (default), its exact mesh for grasp planning): the upper bound, and a check
    of the metrics and the grasp planner. Privileged: the runner gives it the view's
    ``ground_truth``. ``mesh=False`` makes the pick suite plan on its voxels like any other
    backend (the ceiling of a D^3 shape)."""

    name = "oracle"
    privileged = True

    def __init__(self, resolution: int = 32, mesh: bool = True) -> None:
        self.resolution = int(resolution)
        self.mesh = as_bool(mesh)

    def predict(self, view: View) -> Estimate:
        gt = view.ground_truth
        if gt is None:
            raise ViewError("the oracle needs View.ground_truth (the runner fills it for it)")
        p = np.zeros(len(view.categories))
        p[gt.class_index] = 1.0
        inst = instance_from_key(gt.key)
        shape = inst.voxels(self.resolution).astype(np.float32)
        R, t, size = np.array(gt.R_cam), np.array(gt.t_cam), np.array(gt.size)
        return Estimate(p, R, t, size, shape, mesh=inst.mesh if self.mesh else None)


@register_backend("random")
class RandomBackend:
    """Chance: a uniformly random class (its probabilities peak there), a uniformly random
    rotation, the class-mean shape and size, placed at the centroid of the observed points.
    Deterministic for a given view (its generator is seeded from the view's bytes and
    ``seed``)."""

    name = "random"

    def __init__(self, seed: int = 0, resolution: int = 32, mean_instances: int | None = None):
        self.seed = int(seed)
        self.resolution = int(resolution)
        self.mean_instances = mean_instances
        self._means: dict[tuple[str, ...], object] = {}

    def _rng(self, view: View) -> np.random.Generator:
        h = hashlib.sha256(np.ascontiguousarray(view.depth).tobytes())
        h.update(np.packbits(np.asarray(view.mask, dtype=bool)).tobytes())
        return np.random.default_rng([self.seed, int.from_bytes(h.digest()[:8], "little")])

    def prepare(self, categories: tuple[str, ...]) -> None:
        """Compute (or load) the class means once, with a progress bar."""
        cats = tuple(categories)
        if cats not in self._means:
            self._means[cats] = class_means(cats, self.resolution, self.mean_instances, True)

    def predict(self, view: View) -> Estimate:
        pts = view.points()
        if len(pts) == 0:
            raise ViewError("the mask has no pixel with valid depth: nothing to estimate from")
        cats = view.categories
        if cats not in self._means:
            self._means[cats] = class_means(cats, self.resolution, self.mean_instances)
        means = self._means[cats]
        rng = self._rng(view)
        c = int(rng.integers(len(cats)))
        R = Rotation.random(random_state=rng).as_matrix()
        # the class it drew gets twice the others' probability: argmax is that uniformly
        # drawn class (uniform probabilities would make argmax always class 0), and the
        # probabilities still say how little it knows
        p = np.full(len(cats), 1.0 / (len(cats) + 1))
        p[c] *= 2.0
        return Estimate(p, R, pts.mean(axis=0), means.size[c].copy(), means.shape[c].copy())
