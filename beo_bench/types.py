"""Array aliases and small shared value types.

Shapes are given in the alias names' docstrings; units are metres and radians unless a
name says otherwise. Frames: an object's *canonical* frame has +z up and +x front, with the
origin at the centre of its axis-aligned bounding box (see ``beo_bench.objects``).
"""

from __future__ import annotations

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
