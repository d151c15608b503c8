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

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench.backend import Backend, Capabilities, PrepareContext, get_spec
from beo_bench.errors import UsageError, ViewError
from beo_bench.objects import instance_from_key
from beo_bench.options import option, parse_options
from beo_bench.types import Estimate, View

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset

PARTS = ("class", "pose", "shape")
OWN = ("base", "truth")
"""``swap``'s own options; every other ``KEY=VALUE`` is the base backend's."""


@dataclass(frozen=True)
class SwapOptions:
    """The options of ``swap`` (``--opt base=hbeo-mdn-posterior --opt truth=class --opt
    samples=100``): its own two, and the base backend's, parsed by the base's spec
    (:func:`parse_swap`)."""

    base: str = option("icp", "the backend whose estimate is swapped (not swap itself)")
    truth: str = option(
        "class", "the components replaced by the truth: one or more of class, pose, shape"
    )
    base_options: Any = field(
        default=None,
        # not a user option: every other KEY=VALUE, parsed by the base backend
        metadata={"doc": "the base backend's options", "hidden": True},
    )

    def __post_init__(self) -> None:
        if not self.parts() or any(p not in PARTS for p in self.parts()):
            raise ValueError(
                f"truth={self.truth!r}: name one or more of {PARTS}, e.g. 'class+pose'"
            )
        if self.base == "swap":
            raise ValueError("swap of swap: give the base backend's own name")

    def parts(self) -> tuple[str, ...]:
        """The components ``truth`` names (comma- or plus-separated)."""
        return tuple(p for p in self.truth.replace("+", ",").split(",") if p)


def parse_swap(raw: Mapping[str, Any]) -> SwapOptions:
    """``swap``'s options from ``--opt`` values: ``base`` and ``truth`` as its own (a
    :class:`~beo_bench.errors.UsageError` for a bad one), the rest parsed by the base
    backend's spec (its own usage error for an option it does not have)."""
    if "base_options" in raw:
        raise UsageError(
            "swap has no option 'base_options': give the base backend's options as they are "
            "(--opt base=hbeo-mdn-posterior --opt samples=100)"
        )
    own = parse_options(SwapOptions, {k: v for k, v in raw.items() if k in OWN}, "swap")
    rest = {k: v for k, v in raw.items() if k not in OWN}
    return replace(own, base_options=get_spec(own.base).parse(rest))


def _base_options(options: SwapOptions) -> Any:
    """The base's parsed options (its defaults when none were parsed)."""
    if options.base_options is not None:
        return options.base_options
    return get_spec(options.base).parse({})


class SwapBackend(Backend):
    """A base backend's estimate with some components replaced by the truth (module
    docstring; options: :class:`SwapOptions`)."""

    name = "swap"
    Options = SwapOptions
    options: SwapOptions

    @classmethod
    def parse(cls, raw: Mapping[str, Any]) -> SwapOptions:
        return parse_swap(raw)

    @classmethod
    def capabilities_for(cls, options: SwapOptions) -> Capabilities:
        """The base backend's capabilities (class hint, model), handed the truth; read from
        the base's spec, building nothing."""
        base = get_spec(options.base).capabilities_of(_base_options(options))
        return replace(base, privileged=True)

    def __init__(self, options: SwapOptions | None = None, **kwargs: Any) -> None:
        super().__init__(options, **kwargs)
        self.base = get_spec(self.options.base).make(_base_options(self.options))
        self._dataset: Dataset | None = None
        self._cache_root: Path | None = None

    def prepare(self, ctx: PrepareContext) -> None:
        """Prepare the base backend for the run (its ``prepare(ctx)``), and remember the
        dataset the true shapes come from."""
        self._dataset, self._cache_root = ctx.dataset, ctx.cache_root
        self.base.prepare(ctx)

    def model_digest(self) -> str | None:
        """The wrapped backend's model digest (None when it has no learned model)."""
        return self.base.model_digest()

    def predict(self, view: View) -> Estimate:
        gt = view.ground_truth
        if gt is None:
            raise ViewError("swap needs View.ground_truth (the runner fills it for it)")
        est = self.base.predict(replace(view, ground_truth=None))
        if "class" in self.options.parts():
            p = np.zeros(len(view.categories))
            p[gt.class_index] = 1.0
            est = replace(est, class_probs=p)
        if "pose" in self.options.parts():
            est = replace(
                est,
                rotation=np.array(gt.R_cam),
                translation=np.array(gt.t_cam),
                size=np.array(gt.size),
                pose_samples=None,
                pose_weights=None,
                mesh=None,
            )
        if "shape" in self.options.parts():
            D = int(np.asarray(est.shape).shape[0])
            grid = (
                instance_from_key(gt.key, self._dataset, self._cache_root)
                .voxels(D)
                .astype(np.float32)
            )
            est = replace(est, shape=grid, mesh=None)
        return est
