"""Measurements of a sensor on the scenes its published validation used: a plane at a
distance and an angle, a plane's straight edge, a box standing in front of a wall.

Each function renders its scene with one reused renderer and returns what was measured, so
that the tests (tests/scenes/test_sensors.py) check the sign and size of each effect and
``make bench`` (benchmarks/bench_sensors.py) prints and plots it against the published
curve. The plane's angle turns it about the image's vertical axis, as Nguyen, Izadi and
Lovell (2012, Fig. 3) turned theirs; the measurements are taken in a central patch, where
the incidence is the plane's angle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from beo_bench.scenes.builder import build_boxes
from beo_bench.scenes.camera import Intrinsics, look_at
from beo_bench.scenes.renderer import Renderer
from beo_bench.scenes.sensors.base import Sensor
from beo_bench.types import Mat4

WALL_HALF = 10.0
"""Half side (m) of the planes: wide enough to fill the view at 3 m and 75 degrees."""


@dataclass(frozen=True)
class PlaneStats:
    """Depth error on a plane at ``distance`` (m, along the optical axis) and ``angle_deg``:
    ``sigma`` the standard deviation of measured minus true depth (m), ``rms`` its root mean
    square (bias included), ``spatial`` the root mean square over captures of the spread
    within one capture (a frontal plane's deviation from its fitted plane: how Intel
    measures a D4xx's RMS error), ``fill`` the share of the central patch with depth,
    over ``captures`` draws."""

    distance: float
    angle_deg: float
    sigma: float
    rms: float
    spatial: float
    fill: float
    captures: int


class Bench:
    """A renderer and sensor pair for the validation scenes (one GL context for all)."""

    def __init__(self, sensor: Sensor) -> None:
        self.sensor = sensor
        self.intrinsics: Intrinsics = sensor.intrinsics
        self.renderer = Renderer(self.intrinsics, max_geom=16)
        self._models: dict[str, tuple[Any, Any]] = {}
        self._bound = ""

    def close(self) -> None:
        self.renderer.close()

    def __enter__(self) -> Bench:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _scene(self, key: str, boxes: list[tuple[np.ndarray, np.ndarray]]) -> Any:
        if key not in self._models:
            self._models[key] = build_boxes(boxes, self.intrinsics)
        model, data = self._models[key]
        if self._bound != key:
            self.renderer.bind(model, np.ones(model.ngeom, dtype=np.int32))
            self._bound = key
        return data

    def _plane(self, half_plane: bool = False) -> Any:
        """A plane x = 0 facing +x (only its y < 0 half with ``half_plane``)."""
        if half_plane:
            box = (np.array([-0.001, -WALL_HALF, 0.0]), np.array([0.001, WALL_HALF, WALL_HALF]))
            return self._scene("half", [box])
        box = (np.array([-0.01, 0.0, 0.0]), np.array([0.01, WALL_HALF, WALL_HALF]))
        return self._scene("plane", [box])

    @staticmethod
    def camera(distance: float, angle_deg: float) -> Mat4:
        """A camera ``distance`` from the origin, turned ``angle_deg`` about the vertical
        (world z) from the plane's normal, looking at the origin."""
        a = math.radians(angle_deg)
        eye = distance * np.array([math.cos(a), math.sin(a), 0.0])
        return look_at(eye, np.zeros(3))

    def _patch(self) -> tuple[slice, slice]:
        """The central patch: tall and narrow, since a plane turned about the vertical
        changes incidence and depth along the rows only."""
        h, w = self.sensor.shape
        r = max(4, min(h, w) // 12)
        c = max(2, w // 160)
        return slice(h // 2 - r, h // 2 + r), slice(w // 2 - c, w // 2 + c)

    def plane(
        self,
        distance: float,
        angle_deg: float,
        rng: np.random.Generator,
        captures: int = 8,
        spread: float = 0.0,
    ) -> PlaneStats:
        """Depth error of a plane at ``distance`` and ``angle_deg`` in the central patch.
        ``spread``: each capture's distance is drawn uniformly within this fraction of
        ``distance`` (a stereo matcher's error depends on where the disparity falls between
        whole pixels, "pixel locking": the spread averages over it, as a real scene's
        varied depths do)."""
        data = self._plane()
        rows, cols = self._patch()
        errs, filled, total = [], 0, 0
        spatial: list[float] = []
        for _ in range(captures):
            T = self.camera(distance * (1.0 + spread * rng.uniform(-1.0, 1.0)), angle_deg)
            truth = self.renderer.render(data, T).depth
            d = self.sensor.capture(self.renderer, data, T, rng, None).depth[rows, cols]
            t = truth[rows, cols]
            ok = (d > 0) & (t > 0)
            errs.append((d[ok] - t[ok]).astype(np.float64))
            spatial.append(float(errs[-1].var()) if errs[-1].size > 1 else float("nan"))
            filled += int(ok.sum())
            total += int((t > 0).sum())
        e = np.concatenate(errs) if errs else np.zeros(0)
        return PlaneStats(
            distance=distance,
            angle_deg=angle_deg,
            sigma=float(e.std()) if e.size > 1 else float("nan"),
            rms=float(np.sqrt(np.mean(e**2))) if e.size else float("nan"),
            spatial=float(np.sqrt(np.mean(spatial))) if spatial else float("nan"),
            fill=filled / max(total, 1),
            captures=captures,
        )

    def edge(
        self, distance: float, angle_deg: float, rng: np.random.Generator, captures: int = 8
    ) -> float:
        """The standard deviation (pixels) of a straight vertical edge's position across
        rows and captures: per row, the count of pixels with depth in a window around the
        true edge (a hole or an extra pixel anywhere in the window moves it, as it moves
        the edge a line fit finds)."""
        data = self._plane(half_plane=True)
        T = self.camera(distance, angle_deg)
        h, w = self.sensor.shape
        win = max(6, w // 16)
        rows = slice(h // 4, 3 * h // 4)
        cols = slice(w // 2 - win, w // 2 + win)
        truth = (self.renderer.render(data, T).depth[rows, cols] > 0).sum(axis=1)
        counts = []
        for _ in range(captures):
            d = self.sensor.capture(self.renderer, data, T, rng).depth[rows, cols]
            counts.append((d > 0).sum(axis=1) - truth)
        return float(np.concatenate(counts).astype(np.float64).std())

    def step(
        self, front: float, back: float, rng: np.random.Generator, captures: int = 4
    ) -> tuple[float, float]:
        """A box whose face is ``front`` m from a frontal camera, before a wall at ``back``
        m: the mean width (pixels) of the band without depth just left and just right of
        the box in the image's central rows."""
        wall = (np.array([-0.01, 0.0, 0.0]), np.array([0.01, WALL_HALF, WALL_HALF]))
        depth_box = 0.05
        half = 0.5 * front * math.tan(math.radians(self.intrinsics.fovy_deg) / 2)
        box = (
            np.array([back - front - depth_box, 0.0, 0.0]),
            np.array([depth_box, half, half]),
        )
        data = self._scene(f"step{front}-{back}", [wall, box])
        T = self.camera(back, 0.0)
        h = self.sensor.shape[0]
        truth = self.renderer.render(data, T).depth
        rows = range(h // 2 - max(1, h // 16), h // 2 + max(1, h // 16))
        lefts, rights = [], []
        for _ in range(captures):
            d = self.sensor.capture(self.renderer, data, T, rng).depth
            for r in rows:
                on_box = np.flatnonzero(np.abs(truth[r] - front) < 1e-3)
                if not on_box.size:
                    continue
                lo, hi = int(on_box[0]), int(on_box[-1])
                lefts.append(_gap(d[r, :lo][::-1], front))
                rights.append(_gap(d[r, hi + 1 :], front))
        return float(np.mean(lefts)), float(np.mean(rights))


def _gap(row: np.ndarray, front: float) -> int:
    """Pixels without depth in ``row`` (pixels outward from the box's edge) before the
    first that reads the wall. Pixels that read the box itself (its edge moved outward by
    lateral noise or a matcher's window) are skipped first: they are the box, fattened."""
    on_box = np.abs(row - front) < 0.05 * front
    start = int(np.argmin(on_box)) if not on_box.all() else row.size
    rest = row[start:]
    wall = np.flatnonzero(rest > 0)
    return int(wall[0]) if wall.size else int(rest.size)


def shadow_width_px(sensor: Sensor, baseline: float, front: float, back: float) -> float:
    """The width (pixels) of the band a device at ``baseline`` leaves beside a step from
    ``front`` to ``back``: the disparity difference f b (1/front - 1/back)."""
    return sensor.f * baseline * (1.0 / front - 1.0 / back)
