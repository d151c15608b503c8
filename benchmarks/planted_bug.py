"""The planted bug of issue 47, as a third-party backend plugin: every estimate of a base
backend turned by ``yaw_deg`` about the object's up axis and moved ``shift_cm`` along the
camera's x axis, and (``class_drop``) a share of its views given the next class instead of
the one it found. It is what the regression gate must catch (``tests/bench/test_gate_e2e.py``
installs it as an entry point and gates it against its base backend's runs;
``benchmarks/bench_gate.py`` gates it at several sizes against ``hbeo``'s smoke runs, which
is what docs/ci.md's detection figures are).

With ``shift_cm=0``, ``yaw_deg=0`` and ``class_drop=0`` it is its base backend exactly: the
no-op change.
This file is a plugin module, not a benchmark: ``run.py`` runs ``bench_*.py`` only.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from beo_bench.backend import Backend, Capabilities, PrepareContext, get_spec
from beo_bench.options import option
from beo_bench.types import Estimate, View

NAME = "planted"
"""The entry point's name (``beo_bench.backends``: ``planted = planted_bug:PlantedBackend``)."""


@dataclass(frozen=True)
class PlantedOptions:
    """The options of ``planted`` (``--opt KEY=VALUE``)."""

    base: str = option("oracle", "the backend whose estimates are changed")
    shift_cm: float = option(5.0, "added to every translation, along the camera's x axis")
    yaw_deg: float = option(90.0, "every rotation turned by it about the object's up axis")
    class_drop: float = option(
        0.0, "the share of views whose class probabilities are shifted to the next class"
    )


class PlantedBackend(Backend):
    """A base backend with the planted bug (module docstring)."""

    name = NAME
    description = "a base backend with a planted bug: every estimate turned and moved"
    Options = PlantedOptions
    options: PlantedOptions

    @classmethod
    def capabilities_for(cls, options: PlantedOptions) -> Capabilities:
        """The base backend's (class hint, privileged, model): the plugin only changes its
        answers."""
        base = get_spec(options.base)
        return base.capabilities_of(base.parse({}))

    def __init__(self, options: PlantedOptions | None = None, **kwargs: Any) -> None:
        super().__init__(options, **kwargs)
        options = self.options
        self.base = get_spec(options.base).make(get_spec(options.base).parse({}))
        # the object's up axis is its canonical +z: R_est @ Rz turns it about that axis
        self.turn = Rotation.from_euler("z", options.yaw_deg, degrees=True).as_matrix()
        self.shift = np.array([options.shift_cm / 100.0, 0.0, 0.0])

    def prepare(self, ctx: PrepareContext) -> None:
        self.base.prepare(ctx)

    def model_digest(self) -> str | None:
        return self.base.model_digest()

    def predict(self, view: View) -> Estimate:
        est = self.base.predict(view)
        samples = est.pose_samples
        probs = np.asarray(est.class_probs)
        # which views lose their class: drawn from the view's depth, so a view always does
        # or never does (the same view, the same estimate)
        digest = hashlib.sha256(np.ascontiguousarray(view.depth).tobytes()).digest()
        if int.from_bytes(digest[:8], "little") / 2**64 < self.options.class_drop:
            probs = np.roll(probs, 1)
        return replace(
            est,
            class_probs=probs,
            rotation=np.asarray(est.rotation) @ self.turn,
            translation=np.asarray(est.translation) + self.shift,
            pose_samples=None if samples is None else np.asarray(samples) @ self.turn,
        )
