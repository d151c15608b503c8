"""``ideal``: the render as it is, metric z-depth with no error (what the dissertation's
views were: rendered depth, Burchfiel 2019, section 3.3.2). The isolated suites' default."""

from __future__ import annotations

from typing import Any

import numpy as np

from beo_bench.scenes.renderer import Frame, Renderer
from beo_bench.scenes.sensors.base import Sensor
from beo_bench.types import Mat4


class IdealSensor(Sensor):
    """Metric depth straight from the renderer; draws nothing from ``rng``."""

    name = "ideal"
    citation = "MuJoCo's metric depth buffer (no sensor model)"

    @property
    def ideal(self) -> bool:
        return True

    def _sense(
        self, renderer: Renderer, data: Any, cam_to_world: Mat4, rng: np.random.Generator,
        frame: Frame,
    ) -> Frame:  # fmt: skip
        return frame
