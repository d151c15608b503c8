"""The metrics' argument checks: each turns what a caller gave into the array it names, or
raises ``ValueError`` saying what was expected."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

_ROT_ATOL = 1e-3
"""How far from orthonormal a rotation may be (``R^T R = I`` within it)."""


def _array(
    x: ArrayLike | Sequence[ArrayLike], name: str, shape: tuple[int | None, ...] | None = None
) -> np.ndarray:
    """``x`` as a float64 array, checking ``shape`` (None entries match any length)."""
    a = np.asarray(x, dtype=np.float64)
    if shape is not None and (
        a.ndim != len(shape)
        or any(s is not None and s != n for s, n in zip(shape, a.shape, strict=True))
    ):
        want = str(tuple("N" if s is None else s for s in shape)).replace("'", "")
        raise ValueError(f"{name} must have shape {want}, got {a.shape}")
    return a


def _rotation(R: ArrayLike, name: str) -> np.ndarray:
    """A (3, 3) proper rotation (orthonormal, det +1, within 1e-3) as float64."""
    M = _array(R, name, (3, 3))
    if not np.isfinite(M).all():
        raise ValueError(f"{name} must be a finite (3, 3) rotation matrix, got {M.tolist()}")
    if not np.allclose(M.T @ M, np.eye(3), atol=_ROT_ATOL) or np.linalg.det(M) < 0:
        raise ValueError(f"{name} must be a proper rotation matrix (R^T R = I, det R = +1)")
    return M


def _vector(x: ArrayLike, name: str) -> np.ndarray:
    """A 1-D float array (scalars become length 1)."""
    a = np.atleast_1d(np.asarray(x, dtype=np.float64))
    if a.ndim != 1:
        raise ValueError(f"{name} must be a 1-D sequence of numbers, got shape {a.shape}")
    return a


def _labels(x: ArrayLike, name: str) -> np.ndarray:
    """A 1-D integer label array."""
    a = np.atleast_1d(np.asarray(x))
    if a.ndim != 1:
        raise ValueError(f"{name} must be a 1-D sequence of class indices, got shape {a.shape}")
    if a.size and not np.issubdtype(a.dtype, np.integer):
        if not np.all(np.equal(np.mod(a, 1), 0)):
            raise ValueError(f"{name} must hold integer class indices")
        a = a.astype(np.int64)
    return a.astype(np.int64)


def _grid(x: ArrayLike, name: str, threshold: float) -> np.ndarray:
    """A 3-D occupancy grid as bool (bool input as is, numbers ``>= threshold``)."""
    a = np.asarray(x)
    if a.ndim != 3:
        raise ValueError(f"{name} must be a 3-D (D, D, D) occupancy grid, got shape {a.shape}")
    if a.dtype == np.bool_:
        return a
    return a.astype(np.float64) >= threshold
