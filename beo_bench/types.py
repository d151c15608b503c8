"""Array aliases and small shared value types.

Shapes are given in the alias names' docstrings; units are metres and radians unless a
name says otherwise. Frames: an object's *canonical* frame has +z up and +x front, with the
origin at the centre of its axis-aligned bounding box (see ``beo_bench.objects``).
"""

from __future__ import annotations

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
