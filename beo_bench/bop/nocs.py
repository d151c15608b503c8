"""The NOCS report's 3D IoU of an estimated object box (Wang et al., "Normalized Object
Coordinate Space for Category-Level 6D Object Pose and Size Estimation", CVPR 2019: the
IoU25 / IoU50 / IoU75 columns of its tables), as its reference code computes it
(github.com/hughw19/NOCS_CVPR2019, ``utils.py``: ``compute_3d_iou_new``, ``get_3d_bbox``,
``transform_coordinates_3d``; the thresholds in ``compute_3d_matches``).

**The reference's quirk.** ``compute_3d_iou_new`` builds each box's 8 corners (extents
``size``, centred on the object's origin) as a (3, 8) array, moves them by the 4x4 pose into
the camera frame, and then takes ``np.amax`` / ``np.amin`` over ``axis=0``, the *coordinate*
axis, not the corner axis. So what it intersects are not the boxes' axis-aligned bounds in
the camera frame (3 intervals, one per coordinate) but 8 intervals, one per corner ``i``:
``[min(x_i, y_i, z_i), max(x_i, y_i, z_i)]`` of that corner's camera coordinates, paired with
the other box's corner of the same index; the "volumes" are products of 8 lengths and
``IoU = inter / (vol_1 + vol_2 - inter)`` (``inter = 0`` when an interval is empty). It is 1 for
identical boxes and falls as they separate, but it is not a volume overlap: it depends on
where the boxes are in the camera frame (a box seen at the principal point at depth ``z``
mostly measures ``z - min(x, y)`` per corner), on which corner is which (a rotation that
maps the box onto itself but permutes its corners changes it), and is NaN (0 / 0) when both
boxes have a corner with three equal coordinates. It was reported (NOCS_CVPR2019 issue #47)
and kept; later category-level work (SPD, SGPA, ...) copies it so that numbers stay
comparable. This module reproduces it by default (``method="nocs"``) so that the IoU
columns compare with the published ones, and also offers ``method="aabb"``: the IoU of the
two boxes' axis-aligned bounds in the camera frame (what the code was presumably meant to
compute; still not the IoU of the oriented boxes: a rotated box is replaced by its bounds).

**Symmetry.** For a symmetric category (``bottle``, ``bowl``, ``can``, and ``mug`` with its
handle hidden) the reference turns the *predicted* pose about the object's y axis (NOCS'
up) by ``2 pi i / 20``, ``i = 0..19``, and keeps the largest IoU. Here the symmetry comes from
the object's own group (:class:`beo_bench.types.Symmetry`, BOP form): each continuous axis
(through its offset) is sampled at those 20 angles, composed with every discrete element
(identity first) as BOP's ``misc.get_symmetry_transformations`` composes them
(:func:`beo_bench.metrics.symmetry_transforms`); a purely discrete group is tried element by
element. The estimate's pose ``(R, t)`` becomes ``(R S_R, R S_t + t)`` for each element ``S``.

**Thresholds.** ``compute_3d_matches`` accepts a match when ``iou > threshold`` (strict), on
IoUs stored as float32; :func:`iou_accuracies` does the same on per-view IoUs (one estimate
per view, so an accuracy rather than NOCS' average precision over detections).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from beo_bench.metrics import symmetry_transforms
from beo_bench.types import Symmetry

__all__ = ["NOCS_IOU_THRESHOLDS", "NOCS_SYMMETRY_ANGLES", "box_iou", "iou_accuracies"]

NOCS_IOU_THRESHOLDS: tuple[float, ...] = (0.25, 0.5, 0.75)
"""The IoU thresholds of the NOCS tables (IoU25, IoU50, IoU75)."""
NOCS_SYMMETRY_ANGLES = 20
"""How many rotations about a symmetry axis the reference tries (``n = 20``)."""

# Corner signs in get_3d_bbox's order: (+,+,+), (+,+,-), (-,+,+), (-,+,-), (+,-,+), ...
# The "nocs" method pairs the two boxes' corners by index, i.e. by their sign vector.
_CORNER_SIGNS = np.array(
    [[sx, sy, sz] for sy in (1.0, -1.0) for sx in (1.0, -1.0) for sz in (1.0, -1.0)]
)


def _size(size: ArrayLike, name: str) -> NDArray[np.float64]:
    s = np.asarray(size, dtype=np.float64)
    if s.shape != (3,) or not np.isfinite(s).all() or (s <= 0).any():
        raise ValueError(f"{name} must be 3 finite positive box extents, got {s.tolist()}")
    return s


def _pose(R: ArrayLike, t: ArrayLike, name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    Rm = np.asarray(R, dtype=np.float64)
    tv = np.asarray(t, dtype=np.float64).reshape(-1)
    if Rm.shape != (3, 3) or not np.isfinite(Rm).all():
        raise ValueError(f"R_{name} must be a finite (3, 3) rotation matrix, got {Rm.shape}")
    if not np.allclose(Rm.T @ Rm, np.eye(3), atol=1e-6) or np.linalg.det(Rm) < 0:
        raise ValueError(f"R_{name} must be a proper rotation matrix (R^T R = I, det R = +1)")
    if tv.shape != (3,) or not np.isfinite(tv).all():
        raise ValueError(f"t_{name} must be a finite 3-vector, got shape {np.shape(t)}")
    return Rm, tv


def _bounds(
    corners: NDArray[np.float64], method: str
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(lo, hi) of (..., 8, 3) camera-frame corners: per corner over its coordinates
    ("nocs", the reference's ``axis=0`` of a (3, 8) array) or per coordinate ("aabb")."""
    axis = -1 if method == "nocs" else -2
    return corners.min(axis=axis), corners.max(axis=axis)


def box_iou(
    size_gt: ArrayLike,
    R_gt: ArrayLike,
    t_gt: ArrayLike,
    size_est: ArrayLike,
    R_est: ArrayLike,
    t_est: ArrayLike,
    symmetry: Symmetry | None = None,
    method: Literal["nocs", "aabb"] = "nocs",
) -> float:
    """The NOCS 3D IoU of the estimated box against the true one (see the module docstring
    for what ``"nocs"`` computes and why; ``"aabb"`` is the IoU of the camera-frame bounds).

    ``size_*`` (3,) are each box's full extents along its object's own axes, centred on the
    object's origin; ``(R, t)`` map the object to the camera frame; ``t``, the sizes and the
    symmetry's offsets and translations are in one length unit. With ``symmetry`` the
    largest IoU over the estimate's symmetric poses is returned (module docstring; as the
    reference's running maximum from 0, a NaN pose is skipped). Returns a float in [0, 1]
    (NaN where the reference divides 0 by 0 without symmetry).
    """
    if method not in ("nocs", "aabb"):
        raise ValueError(f"method must be 'nocs' or 'aabb', got {method!r}")
    s_gt, s_est = _size(size_gt, "size_gt"), _size(size_est, "size_est")
    Rg, tg = _pose(R_gt, t_gt, "gt")
    Re, te = _pose(R_est, t_est, "est")
    if symmetry is None:
        S_R, S_t = np.eye(3)[None], np.zeros((1, 3))
    else:
        # ceil(pi / step) = NOCS_SYMMETRY_ANGLES rotations per axis, at 2 pi k / 20 as NOCS.
        S_R, S_t = symmetry_transforms(symmetry, np.pi / (NOCS_SYMMETRY_ANGLES - 0.5))
    gt_corners = (_CORNER_SIGNS * s_gt / 2) @ Rg.T + tg  # (8, 3)
    est_R = Re @ S_R  # (K, 3, 3)
    est_t = S_t @ Re.T + te  # (K, 3)
    est_corners = np.einsum("kij,nj->kni", est_R, _CORNER_SIGNS * s_est / 2) + est_t[:, None]
    lo_g, hi_g = _bounds(gt_corners, method)
    lo_e, hi_e = _bounds(est_corners, method)
    overlap = np.minimum(hi_g, hi_e) - np.maximum(lo_g, lo_e)  # (K, n)
    inter = np.where((overlap < 0).any(axis=-1), 0.0, np.prod(overlap, axis=-1))
    union = np.prod(hi_g - lo_g) + np.prod(hi_e - lo_e, axis=-1) - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        ious = inter / union
    if len(ious) == 1:
        return float(ious[0])
    # The reference's running ``max_iou = max(max_iou, iou)`` from 0 skips NaN.
    return float(max(0.0, np.nanmax(ious))) if not np.isnan(ious).all() else 0.0


def iou_accuracies(ious: ArrayLike) -> dict[str, float]:
    """``{"iou25", "iou50", "iou75"}``: the fraction (0..1) of views whose box IoU is above
    each of :data:`NOCS_IOU_THRESHOLDS`, strictly and in float32 as ``compute_3d_matches``
    tests ``iou > iou_thres`` on its float32 overlaps. A view without an estimate should
    count with IoU 0; NaN entries are dropped (``beo_bench.metrics``' convention), an
    accuracy over nothing is NaN."""
    a = np.atleast_1d(np.asarray(ious, dtype=np.float64))
    if a.ndim != 1:
        raise ValueError(f"ious must be a 1-D sequence of IoUs, got shape {a.shape}")
    a = a[~np.isnan(a)]
    if ((a < 0) | (a > 1)).any():
        raise ValueError("ious must lie in [0, 1] (NaN for a view to leave out)")
    a32 = a.astype(np.float32)
    return {
        f"iou{round(th * 100)}": float(np.mean(a32 > np.float32(th))) if a.size else float("nan")
        for th in NOCS_IOU_THRESHOLDS
    }
