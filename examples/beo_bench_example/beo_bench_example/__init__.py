"""``box-fit``: an example third-party backend for beo-bench.

It fits a box to the observed points and reads the class off the box's size:

1. The observed points are the view's masked pixels back-projected (``View.points``).
2. The rotation comes from their principal axes. With ``View.up_hint`` (the ``pose-1dof``
   protocol), the up axis is given and only the horizontal axes are fitted.
3. The size is the points' extent along those axes; the extent along the viewing ray is at
   least the median of the others (a view sees only the front). The box is pushed back
   along the ray by a quarter of that depth, since its centre lies behind the seen side.
4. The class is the one whose mean training size (from beo-bench's class means) is
   nearest in log-size. The shape is that class's mean occupancy grid.

It is deliberately simple: it shows the contract (one :class:`~beo_bench.backend.Backend`
subclass with its ``name``, typed options, capabilities, ``predict`` and ``prepare(ctx)``;
determinism; clear errors), not a good method.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beo_bench.backend import Backend, Capabilities, PrepareContext
from beo_bench.errors import ViewError
from beo_bench.options import option
from beo_bench.perception.means import ClassMeans, class_means
from beo_bench.types import Estimate, View

__all__ = ["BoxFitBackend", "BoxFitOptions"]


@dataclass(frozen=True)
class BoxFitOptions:
    """``beo-bench run --opt KEY=VALUE``: beo-bench converts each value to the field's type
    (a bad one is a usage error listing these), so the backend never parses strings."""

    instances: int | None = option(20, "training instances per class in the means (null: all)")
    temperature: float = option(0.25, "softmax temperature of the log-size distances (> 0)")

    def __post_init__(self) -> None:
        if self.temperature <= 0:
            raise ValueError(f"temperature={self.temperature} must be > 0")


class BoxFitBackend(Backend):
    """A box fitted to the observed points; the class by its size. What the entry point
    names: beo-bench reads its options and capabilities from the class without building
    it."""

    name = "box-fit"
    description = "a box fitted to the observed points; the class by its size"
    Options = BoxFitOptions
    capabilities = Capabilities()  # no class hint, not privileged, no trained model
    options: BoxFitOptions  # self.options: parsed from --opt KEY=VALUE

    def __init__(self, options: BoxFitOptions | None = None) -> None:
        super().__init__(options)
        self._dataset = None
        self._means: dict[tuple[str, ...], ClassMeans] = {}

    def prepare(self, ctx: PrepareContext) -> None:
        """Called once in every process before its first view (the runner's first, then
        each worker's): build what is slow, cached on disk, for the run's class list and
        dataset (None: the procedural library)."""
        self._dataset = ctx.dataset
        self._class_means(tuple(ctx.categories))

    def _class_means(self, cats: tuple[str, ...]) -> ClassMeans:
        if cats not in self._means:
            self._means[cats] = class_means(
                cats, per_category=self.options.instances, dataset=self._dataset
            )
        return self._means[cats]

    def predict(self, view: View) -> Estimate:
        pts = view.points()
        if len(pts) < 3:
            raise ViewError(
                f"box-fit needs at least 3 masked pixels with depth, got {len(pts)}: "
                "check the mask and that depth is metric (0 = no data)"
            )
        centre = pts.mean(axis=0)
        R = _axes(pts - centre, view.unit_up())
        local = (pts - centre) @ R
        lo, hi = local.min(axis=0), local.max(axis=0)
        size = np.maximum(hi - lo, 1e-3)
        # the camera sees the front: push the box back by a quarter of its depth along the ray
        ray = centre / np.linalg.norm(centre)
        depth_axis = int(np.argmax(np.abs(R.T @ ray)))
        size[depth_axis] = max(size[depth_axis], float(np.median(size)))
        t = R @ (0.5 * (lo + hi)) + centre + 0.25 * size[depth_axis] * ray
        means = self._class_means(tuple(view.categories))
        # nearest class by sorted log-extents (the box's axes are not the object's)
        d = np.abs(np.log(np.sort(size)) - np.log(np.sort(means.size, axis=1))).sum(axis=1)
        logits = -d / self.options.temperature
        probs = np.exp(logits - logits.max())
        probs /= probs.sum()
        shape = means.shape[int(np.argmax(probs))].astype(np.float32)
        return Estimate(
            class_probs=probs,
            rotation=R,
            translation=t,
            size=size,
            shape=np.clip(shape, 0.0, 1.0),
            info={"points": len(pts)},
        )


def _axes(p: np.ndarray, up: np.ndarray | None) -> np.ndarray:
    """A proper rotation whose columns are the points' principal axes (with ``up`` as the
    third axis when given)."""
    if up is None:
        _, _, vt = np.linalg.svd(p, full_matrices=False)
        R = vt.T
    else:
        flat = p - np.outer(p @ up, up)
        _, _, vt = np.linalg.svd(flat, full_matrices=False)
        x = vt[0] - (vt[0] @ up) * up
        x /= np.linalg.norm(x)
        R = np.stack([x, np.cross(up, x), up], axis=1)
    if np.linalg.det(R) < 0:
        R[:, 0] = -R[:, 0]
    return R
