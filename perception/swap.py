"""``swap``: a backend's estimate with some components replaced by the truth, to measure
how much of its gap to the oracle each component causes (docs/design.md "Pick"; the pick gap
analysis in docs/results.md).

``get_backend("swap", base="hbeo", truth="class")`` runs ``hbeo`` on the view *without*
its ground truth, then replaces

- ``class``: the class probabilities by the true class's one-hot;
- ``pose``: rotation, translation and size by the true ones;
- ``shape``: the occupancy grid by the instance's true voxels (same resolution; the
  grasp is still planned by marching cubes on the grid, as for any backend, not on the
  oracle's exact mesh).

``truth`` may list several, comma- or plus-separated (``class+pose``). Privileged: the
runner gives it the view's ground truth, which it never passes to the base backend.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from beo_bench.backend import get_backend, prepare_backend, register_backend
from beo_bench.errors import ViewError
from beo_bench.objects import instance_from_key
from beo_bench.types import Estimate, View

PARTS = ("class", "pose", "shape")


@register_backend("swap")
class SwapBackend:
    name = "swap"
    privileged = True

    def __init__(self, base: str = "icp", truth: str = "class", **base_options: Any) -> None:
        parts = tuple(p for p in str(truth).replace("+", ",").split(",") if p)
        unknown = [p for p in parts if p not in PARTS]
        if not parts or unknown:
            raise ValueError(f"truth={truth!r}: name one or more of {PARTS}, e.g. 'class+pose'")
        if base == "swap":
            raise ValueError("swap of swap: give the base backend's own name")
        self.truth = parts
        self.base = get_backend(str(base), **base_options)
        self.base_name = str(base)

    @property
    def wants_class_hint(self) -> bool:
        return bool(getattr(self.base, "wants_class_hint", False))

    def prepare(self, categories: tuple[str, ...]) -> None:
        prepare_backend(self.base, categories)

    def model_digest(self) -> str | None:
        """The wrapped backend's model digest (None when it has no learned model)."""
        digest = getattr(self.base, "model_digest", None)
        return digest() if callable(digest) else None

    def predict(self, view: View) -> Estimate:
        gt = view.ground_truth
        if gt is None:
            raise ViewError("swap needs View.ground_truth (the runner fills it for it)")
        est = self.base.predict(replace(view, ground_truth=None))
        if "class" in self.truth:
            p = np.zeros(len(view.categories))
            p[gt.class_index] = 1.0
            est = replace(est, class_probs=p)
        if "pose" in self.truth:
            est = replace(
                est,
                rotation=np.array(gt.R_cam),
                translation=np.array(gt.t_cam),
                size=np.array(gt.size),
                pose_samples=None,
                pose_weights=None,
                mesh=None,
            )
        if "shape" in self.truth:
            D = int(np.asarray(est.shape).shape[0])
            grid = instance_from_key(gt.key).voxels(D).astype(np.float32)
            est = replace(est, shape=grid, mesh=None)
        return est
