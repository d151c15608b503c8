"""Evaluation metrics: pure numpy/scipy functions, cheap to import (no torch, no mujoco).

Conventions shared by every function here:

- Rotations are (3, 3) matrices acting on column vectors and map the object's canonical
  frame (+z up, +x front) to the camera frame (OpenCV axes: x right, y down, z forward),
  like ``Estimate.rotation`` and ``GroundTruth.R_cam``. Translations and sizes are metres.
- Symmetry groups are in the BOP toolkit's ``models_info`` form
  (:class:`beo_bench.types.Symmetry`); a symmetry element ``S`` maps the object onto itself,
  so poses ``R`` and ``R @ S`` are indistinguishable.
- Aggregates over many episodes (rates, accuracies) drop NaN entries; an aggregate over
  nothing is NaN. Intervals and paired tests over items are in :mod:`beo_bench.stats`.
- Shape errors raise ``ValueError`` saying what was expected.

References:

- [BOP] Hodaň et al., "BOP: Benchmark for 6D Object Pose Estimation", ECCV 2018, and the
  BOP toolkit (``bop_toolkit_lib/pose_error.py``: ``re``, ``te``, ``mssd``, ``mspd``;
  ``misc.get_symmetry_transformations``); MSSD and MSPD are defined in the BOP Challenge
  2019 evaluation (Hodaň et al., "BOP Challenge 2020 on 6D Object Localization", ECCVW 2020).
- [NOCS] Wang et al., "Normalized Object Coordinate Space for Category-Level 6D Object Pose
  and Size Estimation", CVPR 2019 (the 5deg2cm / 5deg5cm / 10deg5cm accuracies; a pose
  passes when both errors are <= the thresholds).
- [Pix3D] Sun et al., "Pix3D: Dataset and Methods for Single-Image 3D Shape Modeling",
  CVPR 2018 (azimuth / elevation bin accuracy, following Pascal3D+'s AVP bins).
- [Burchfiel] B. Burchfiel, "Bayesian Eigenobjects ..." (PhD dissertation, Duke 2019):
  EDT error (eq. 4.5), gross-error rate (Table 5.2), entropy "unknown" (section 6.2.4).
- [ONet] Mescheder et al., "Occupancy Networks", CVPR 2019 (Chamfer-L1, voxel IoU).
- [Tatarchenko] Tatarchenko et al., "What Do Single-view 3D Reconstruction Networks
  Learn?", CVPR 2019 (F-score at a distance threshold).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from beo_bench.types import Symmetry

__all__ = [
    "AZIMUTH_BINS",
    "ELEVATION_BINS",
    "FSCORE_TAU",
    "GROSS_ERROR_DEG",
    "MAX_SYM_DISC_STEP",
    "NEAREST_TRIANGLES",
    "NOCS_THRESHOLDS",
    "Surface",
    "bin_accuracy",
    "camera_frame_iou",
    "chamfer_l1",
    "class_accuracy",
    "closest_symmetric_pose",
    "confusion_matrix",
    "edt",
    "edt_error",
    "edt_error_per_voxel",
    "entropy",
    "fscore",
    "gross_error_rate",
    "is_gross_error",
    "mspd",
    "mssd",
    "nocs_accuracies",
    "per_class_accuracy",
    "pick_summary",
    "pose_accuracy",
    "pose_hits",
    "posed_iou",
    "predict_with_unknown",
    "rotation_error",
    "runtime_stats",
    "size_error",
    "surface_scores",
    "symmetry_rotations",
    "symmetry_transforms",
    "translation_error",
    "viewpoint",
    "viewpoint_bin_accuracy",
    "viewpoint_bins",
    "voxel_iou",
]

AZIMUTH_BINS: tuple[int, ...] = (4, 8, 12, 24)
"""Azimuth bin counts of the Pix3D protocol (over 360 degrees)."""
ELEVATION_BINS: tuple[int, ...] = (4, 6, 12)
"""Elevation bin counts of the Pix3D protocol (over 180 degrees)."""
NOCS_THRESHOLDS: dict[str, tuple[float, float]] = {
    "5deg2cm": (5.0, 2.0),
    "5deg5cm": (5.0, 5.0),
    "10deg2cm": (10.0, 2.0),
    "10deg5cm": (10.0, 5.0),
}
"""NOCS accuracy names -> (degrees, centimetres)."""
FSCORE_TAU = 0.01
"""The benchmark's F-score threshold: 1% of the side of the unit cube the canonical shapes are
scaled into, i.e. 1% of the object's largest extent [Tatarchenko]."""
GROSS_ERROR_DEG = 15.0
"""The gross-error threshold of [Burchfiel] Table 5.2 (a rotation error strictly above it)."""
MAX_SYM_DISC_STEP = 0.01
"""BOP's ``max_sym_disc_step`` for MSSD / MSPD: a continuous symmetry is sampled so that the
model point farthest from its axis moves at most this fraction of the model's diameter
between neighbouring samples (``ceil(pi / step)`` rotations, as in the BOP evaluation); the
best sample is then refined to the exact minimum (:func:`mssd`)."""
NEAREST_TRIANGLES = 4
"""Triangles (those with the nearest centroids) a point's distance to a :class:`Surface` is
taken over (see :meth:`Surface.distances`)."""

_ROT_ATOL = 1e-3


# --------------------------------------------------------------------------- validation


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


# --------------------------------------------------------------------------- pose


def _symmetry_parts(
    symmetry: Symmetry | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """``(R, t, axis, offset)`` of a BOP symmetry group: ``R`` (K, 3, 3) and ``t`` (K, 3)
    the discrete elements ``x -> R x + t``, the identity first; ``axis`` as in
    :func:`symmetry_rotations`; ``offset`` (3,) the point the (first) continuous axis passes
    through (zeros without one)."""
    rotations, translations = [np.eye(3)], [np.zeros(3)]
    axis: np.ndarray | None = None
    offset = np.zeros(3)
    if symmetry is None:
        return np.stack(rotations), np.stack(translations), axis, offset
    for k, T in enumerate(symmetry.get("discrete", []) or []):
        M = np.asarray(T, dtype=np.float64)
        if M.shape not in ((4, 4), (3, 3)):
            raise ValueError(f"symmetry['discrete'][{k}] must be (4, 4), got {M.shape}")
        rotations.append(_rotation(M[:3, :3], f"symmetry['discrete'][{k}][:3, :3]"))
        translations.append(M[:3, 3] if M.shape == (4, 4) else np.zeros(3))
    for k, c in enumerate(symmetry.get("continuous", []) or []):
        a = _array(c["axis"], f"symmetry['continuous'][{k}]['axis']", (3,))
        n = np.linalg.norm(a)
        if not np.isfinite(n) or n == 0:
            raise ValueError(f"symmetry['continuous'][{k}]['axis'] must be a non-zero 3-vector")
        a = a / n
        if axis is None:
            axis = a
            offset = _array(c.get("offset", [0.0, 0.0, 0.0]), "offset", (3,))
        elif np.linalg.norm(np.cross(axis, a)) > 1e-9 and np.any(axis):
            axis = np.zeros(3)
    return np.stack(rotations), np.stack(translations), axis, offset


def symmetry_rotations(symmetry: Symmetry | None) -> tuple[np.ndarray, np.ndarray | None]:
    """The rotation parts of a BOP symmetry group, split for :func:`rotation_error`.

    Returns ``(discrete, axis)``: ``discrete`` is (K, 3, 3), the identity first, then the
    rotation part of every ``symmetry["discrete"]`` transform; ``axis`` is the unit (3,)
    axis of the continuous symmetry, or None. Offsets only move the translation and are
    ignored here (:func:`translation_error` uses them). Several parallel continuous axes
    count as one. Continuous rotations about two non-parallel axes generate all of SO(3) (a
    sphere); then ``axis`` is ``np.zeros(3)``.
    """
    rotations, _, axis, _ = _symmetry_parts(symmetry)
    return rotations, axis


def _axis_rotations(axis: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations by ``theta`` (radians, any shape) about the unit ``axis``."""
    return (
        Rotation.from_rotvec(np.asarray(theta).reshape(-1, 1) * axis)
        .as_matrix()
        .reshape((*np.shape(theta), 3, 3))
    )


def _closest_symmetric(
    Re: np.ndarray, Rg: np.ndarray, symmetry: Symmetry | None
) -> tuple[float, np.ndarray]:
    """(angle in radians, S) minimising ``angle(Re^T Rg S)`` over the group of ``symmetry``
    (the exact continuous minimisation of :func:`rotation_error`)."""
    discrete, axis = symmetry_rotations(symmetry)
    M = Re.T @ Rg
    if axis is not None and not np.any(axis):  # a sphere: every rotation is a symmetry
        return 0.0, Rg.T @ Re
    # trace(M C D) = trace(D M C): the continuous rotation acts last in N = D M.
    N = discrete @ M  # (K, 3, 3)
    C = np.broadcast_to(np.eye(3), N.shape)
    if axis is not None:
        a = axis
        ax = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
        aNa = np.einsum("i,kij,j->k", a, N, a)
        A = np.trace(N, axis1=1, axis2=2) - aNa
        B = np.einsum("kij,ji->k", N, ax)
        theta = np.arctan2(B, A)
        C = Rotation.from_rotvec(theta[:, None] * a[None, :]).as_matrix()
        N = N @ C
    # from_matrix re-orthonormalises, so tiny numerical drift cannot produce NaN.
    angles = Rotation.from_matrix(N).magnitude()
    k = int(np.argmin(angles))
    return float(angles[k]), C[k] @ discrete[k]


def rotation_error(R_est: ArrayLike, R_gt: ArrayLike, symmetry: Symmetry | None = None) -> float:
    """Geodesic rotation error in degrees, minimised over the object's symmetry group.

    ``min over S in G of angle(R_est^T R_gt S)``, where ``angle(M) = arccos((tr M - 1) / 2)``
    is the geodesic distance on SO(3) [BOP ``re``, with the symmetric poses ``R_gt S`` as in
    ``get_symmetry_transformations``]. ``G`` is built from ``symmetry`` like
    :func:`beo_bench.geometry.symmetry_transformations` (elements ``C(theta) @ D`` with ``C``
    a rotation about the continuous axis and ``D`` the identity or a discrete element), but
    the continuous part is minimised exactly instead of on a 5-degree grid:

    with ``N = D R_est^T R_gt`` and ``C(theta) = cos(theta) I + sin(theta) [a]_x +
    (1 - cos(theta)) a a^T``, ``tr(N C(theta)) = a^T N a + A cos(theta) + B sin(theta)`` with
    ``A = tr N - a^T N a`` and ``B = tr(N [a]_x)``, maximised at ``theta* = atan2(B, A)``.
    (With no discrete part this equals the angle between ``R_est a`` and ``R_gt a``.) The
    angle of ``N C(theta*)`` is then taken with scipy's ``Rotation.magnitude`` (accurate near
    0, unlike arccos). Vectorised over the discrete elements.

    ``symmetry`` None or empty: the plain geodesic distance. Two non-parallel continuous axes
    (a sphere) give 0. Raises ``ValueError`` unless both are finite proper (3, 3) rotations.
    """
    angle, _ = _closest_symmetric(_rotation(R_est, "R_est"), _rotation(R_gt, "R_gt"), symmetry)
    return float(np.degrees(angle))


def closest_symmetric_pose(
    R_est: ArrayLike, R_gt: ArrayLike, symmetry: Symmetry | None = None
) -> NDArray[np.float64]:
    """The pose ``R_gt S`` (S in the symmetry group) nearest to ``R_est``: the truth that
    :func:`rotation_error` measures against. Viewpoint-bin metrics use it, so that a
    symmetric object seen from an equivalent side is not counted wrong."""
    Rg = _rotation(R_gt, "R_gt")
    _, S = _closest_symmetric(_rotation(R_est, "R_est"), Rg, symmetry)
    return Rg @ S


def translation_error(
    t_est: ArrayLike,
    t_gt: ArrayLike,
    R_gt: ArrayLike | None = None,
    symmetry: Symmetry | None = None,
) -> float:
    """Translation error in centimetres (inputs in metres): ``||t_est - t_gt||`` [BOP
    ``te``], minimised over the object's symmetry group when ``symmetry`` is given.

    A symmetry element ``x -> S x + s`` whose axis does not pass through the canonical
    origin moves the origin, so the equivalent poses ``(R_gt S, t_gt + R_gt s)`` have other
    translations (BOP's MSSD applies them: :func:`mssd`). The error is taken at the member
    that minimises it: ``min over (S, s) of ||t_est - t_gt - R_gt s||``, with ``R_gt`` the
    true rotation (required with a symmetry). The elements are ``C(theta) o D`` as in
    :func:`rotation_error` (``D = (S_k, s_k)`` the identity or a discrete element, ``C`` a
    rotation about the continuous axis ``a`` through the offset ``o``), whose translation is
    ``o + C(theta) (s_k - o)``; with ``u = R_gt^T (t_est - t_gt) - o`` and
    ``v = s_k - o`` the error ``||u - C(theta) v||`` is least at
    ``theta* = atan2(u . (a x v), u . v_perp)`` (``v_perp`` the part of ``v`` across the
    axis): exact, no discretisation. Two non-parallel continuous axes (a sphere about ``o``)
    give ``| ||u|| - ||v|| |``.
    """
    a = _array(t_est, "t_est", (3,))
    b = _array(t_gt, "t_gt", (3,))
    if symmetry is None:
        return float(np.linalg.norm(a - b) * 100.0)
    if R_gt is None:
        raise ValueError(
            "translation_error needs R_gt, the true rotation, to apply a symmetry's "
            "translation part: pass R_gt=... (or symmetry=None for the plain distance)"
        )
    Rg = _rotation(R_gt, "R_gt")
    _, translations, axis, offset = _symmetry_parts(symmetry)
    w = Rg.T @ (a - b)  # the error in the canonical frame (a rotation keeps lengths)
    if axis is None:
        d = np.linalg.norm(w[None, :] - translations, axis=1)
    else:
        u, v = w - offset, translations - offset
        if not np.any(axis):  # a sphere: C v reaches every point at distance ||v|| from o
            d = np.abs(np.linalg.norm(u) - np.linalg.norm(v, axis=1))
        else:
            v_perp = v - np.outer(v @ axis, axis)
            theta = np.arctan2(np.cross(axis, v) @ u, v_perp @ u)
            Cv = np.einsum("kij,kj->ki", _axis_rotations(axis, theta), v)
            d = np.linalg.norm(u[None, :] - Cv, axis=1)
    return float(d.min() * 100.0)


def size_error(s_est: ArrayLike, s_gt: ArrayLike) -> float:
    """Size error in percent: the mean over the 3 extents of ``|s_est - s_gt| / s_gt``,
    times 100. ``s_gt`` must be positive."""
    a = _array(s_est, "s_est", (3,))
    b = _array(s_gt, "s_gt", (3,))
    if not np.all(b > 0):
        raise ValueError(f"s_gt must have 3 positive extents, got {b.tolist()}")
    return float(np.mean(np.abs(a - b) / b) * 100.0)


def is_gross_error(errors_deg: ArrayLike, threshold: float = GROSS_ERROR_DEG) -> NDArray[np.bool_]:
    """Per error: strictly greater than ``threshold`` degrees ([Burchfiel] Table 5.2 counts
    errors > 15 degrees); a NaN is not a gross error (leave it out before averaging)."""
    e = _vector(errors_deg, "errors_deg")
    with np.errstate(invalid="ignore"):
        return e > threshold


def gross_error_rate(errors_deg: ArrayLike, threshold: float = GROSS_ERROR_DEG) -> float:
    """Fraction (0..1) of rotation errors that are gross (:func:`is_gross_error`). NaNs
    dropped; empty -> NaN."""
    e = _vector(errors_deg, "errors_deg")
    e = e[~np.isnan(e)]
    return float(np.mean(is_gross_error(e, threshold))) if e.size else float("nan")


def pose_hits(
    rot_err_deg: ArrayLike, trans_err_cm: ArrayLike, deg: float, cm: float
) -> NDArray[np.bool_]:
    """Per pose: rotation error <= ``deg`` and translation error <= ``cm`` [NOCS]; False
    where either is NaN."""
    r = _vector(rot_err_deg, "rot_err_deg")
    t = _vector(trans_err_cm, "trans_err_cm")
    if r.shape != t.shape:
        raise ValueError(
            f"rot_err_deg and trans_err_cm must have equal lengths: {r.size}, {t.size}"
        )
    with np.errstate(invalid="ignore"):
        return (r <= deg) & (t <= cm)


def pose_accuracy(rot_err_deg: ArrayLike, trans_err_cm: ArrayLike, deg: float, cm: float) -> float:
    """Fraction (0..1) of poses that pass (:func:`pose_hits`) [NOCS]. Pairs with a NaN are
    dropped; empty -> NaN."""
    hits = pose_hits(rot_err_deg, trans_err_cm, deg, cm)
    r, t = _vector(rot_err_deg, "rot_err_deg"), _vector(trans_err_cm, "trans_err_cm")
    keep = ~(np.isnan(r) | np.isnan(t))
    if not keep.any():
        return float("nan")
    return float(np.mean(hits[keep]))


def nocs_accuracies(rot_err_deg: ArrayLike, trans_err_cm: ArrayLike) -> dict[str, float]:
    """``{"5deg2cm", "5deg5cm", "10deg5cm"}`` accuracies (0..1) via :func:`pose_accuracy`."""
    return {
        name: pose_accuracy(rot_err_deg, trans_err_cm, deg, cm)
        for name, (deg, cm) in NOCS_THRESHOLDS.items()
    }


def _continuous_axes(symmetry: Symmetry | None) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each continuous symmetry's (unit axis, offset), as BOP lists them."""
    out = []
    continuous = symmetry.get("continuous", []) if symmetry else []
    for k, c in enumerate(continuous or []):
        a = _array(c["axis"], f"symmetry['continuous'][{k}]['axis']", (3,))
        n = np.linalg.norm(a)
        if not np.isfinite(n) or n == 0:
            raise ValueError(f"symmetry['continuous'][{k}]['axis'] must be a non-zero 3-vector")
        out.append((a / n, _array(c.get("offset", [0.0, 0.0, 0.0]), "offset", (3,))))
    return out


def _steps(max_sym_disc_step: float) -> int:
    """How many rotations BOP samples a continuous axis with (``ceil(pi / step)``)."""
    if not max_sym_disc_step > 0:
        raise ValueError(f"max_sym_disc_step must be positive, got {max_sym_disc_step}")
    return int(np.ceil(np.pi / max_sym_disc_step))


def symmetry_transforms(
    symmetry: Symmetry | None, max_sym_disc_step: float = MAX_SYM_DISC_STEP
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The symmetry group as BOP's ``misc.get_symmetry_transformations`` discretises it:
    ``(R (K, 3, 3), t (K, 3))``, identity first; each discrete element ``D`` (identity
    included) composed with ``ceil(pi / max_sym_disc_step)`` rotations ``C`` about each
    continuous axis through its offset ``o``: ``R = R_C R_D``, ``t = R_C t_D + o - R_C o``."""
    d_rot, d_trans, _, _ = _symmetry_parts(symmetry)
    axes = _continuous_axes(symmetry)
    if not axes:
        return d_rot, d_trans
    n = _steps(max_sym_disc_step)
    Rs, ts = [], []
    for Rd, td in zip(d_rot, d_trans, strict=True):
        for a, o in axes:
            C = _axis_rotations(a, 2.0 * np.pi * np.arange(n) / n)
            Rs.append(C @ Rd)
            ts.append(C @ (td - o) + o)
    return np.concatenate(Rs), np.concatenate(ts)


def _project(p: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Pixel coordinates (..., 2) of camera-frame points (..., 3) (BOP ``project_pts``)."""
    x = p @ K.T
    return x[..., :2] / x[..., 2:3]


class _SymmetricDistance:
    """The largest distance between the estimate's model points and the truth's under one
    group element (MSSD; MSPD with ``K``), for the discrete elements and for whole families
    ``C(theta) o D`` about a continuous axis.

    Under ``C(theta) o D`` (axis ``a`` through ``o``) the true position of model point ``x``
    is ``M + cos(theta) U + sin(theta) V`` in the camera: with ``y = D x - o``,
    ``M = R_gt (o + (y . a) a) + t_gt``, ``U = R_gt y_perp`` and ``V = R_gt (a x y)``. In
    space the squared distance to the estimate's point ``e + M`` is then the sinusoid
    ``|e|^2 + |y_perp|^2 - 2 cos(theta) e.U - 2 sin(theta) e.V`` (``U``, ``V`` orthogonal,
    both of length ``|y_perp|``), and through the linear ``K`` each homogeneous image
    coordinate is one too: a family costs a few multiplications per point and angle."""

    def __init__(
        self,
        pe: np.ndarray,
        Rg: np.ndarray,
        tg: np.ndarray,
        P: np.ndarray,
        K: np.ndarray | None,
    ) -> None:
        self.pe, self.Rg, self.tg, self.P, self.K = pe, Rg, tg, P, K
        self.ue = _project(pe, K) if K is not None else pe

    def discrete(self, R: np.ndarray, t: np.ndarray) -> np.ndarray:
        """(E,) largest distance under each element ``x -> R x + t``."""
        G = np.einsum("ij,ejk->eik", self.Rg, R)
        pg = np.einsum("eij,nj->eni", G, self.P) + (t @ self.Rg.T + self.tg)[:, None, :]
        if self.K is not None:
            pg = _project(pg, self.K)
        return np.sqrt(np.sum((self.ue[None] - pg) ** 2, axis=-1).max(axis=1))

    def family(
        self,
        Rd: np.ndarray,
        td: np.ndarray,
        a: np.ndarray,
        o: np.ndarray,
        theta: np.ndarray,
        exact: bool = False,
    ) -> np.ndarray:
        """(S,) largest distance under ``C(theta) o D`` for each angle (``exact``: from the
        positions, free of the sinusoid's cancellation near 0, at 3 times the cost)."""
        y = self.P @ Rd.T + (td - o)
        along = y @ a
        M = (o + along[:, None] * a) @ self.Rg.T + self.tg
        Pp = (y - along[:, None] * a) @ self.Rg.T
        Qp = np.cross(a, y) @ self.Rg.T
        c, s = np.cos(theta)[None, :], np.sin(theta)[None, :]
        if self.K is None and not exact:
            e = self.pe - M
            const = np.sum(e * e, axis=1) + np.sum(Pp * Pp, axis=1)
            d2 = const[:, None] - 2.0 * (np.sum(e * Pp, axis=1)[:, None] * c)
            d2 -= 2.0 * (np.sum(e * Qp, axis=1)[:, None] * s)
            return np.sqrt(np.maximum(d2.max(axis=0), 0.0))
        if self.K is not None:  # K is linear: each image coordinate is a sinusoid too
            h = [(M @ self.K[i]).reshape(-1, 1) for i in range(3)]
            h = [m + (Pp @ self.K[i])[:, None] * c + (Qp @ self.K[i])[:, None] * s
                 for i, m in enumerate(h)]  # fmt: skip
            du = h[0] / h[2] - self.ue[:, 0:1]
            dv = h[1] / h[2] - self.ue[:, 1:2]
            return np.sqrt((du * du + dv * dv).max(axis=0))
        pg = M[:, None, :] + c[..., None] * Pp[:, None, :] + s[..., None] * Qp[:, None, :]
        return np.sqrt(np.sum((self.pe[:, None, :] - pg) ** 2, axis=-1).max(axis=0))


REFINE_PASSES = 3
"""Zoom passes (each 33 angles over the last bracket) that refine a continuous family's best
sampled angle: the bracket shrinks 16-fold a pass, to ~5e-6 rad from BOP's 0.02 (a 1 um
move of a point 20 cm from the axis)."""


def _max_symmetric_distance(
    R_est: ArrayLike,
    t_est: ArrayLike,
    R_gt: ArrayLike,
    t_gt: ArrayLike,
    points: ArrayLike,
    symmetry: Symmetry | None,
    K: np.ndarray | None,
    max_sym_disc_step: float,
    refine: bool = True,
) -> float:
    """MSSD (``K`` None) or MSPD: the minimum over BOP's discretised group, with each
    continuous family's best angle then refined (never above BOP's value; ``refine``
    False: BOP's sampled value itself)."""
    Re, Rg = _rotation(R_est, "R_est"), _rotation(R_gt, "R_gt")
    te, tg = _array(t_est, "t_est", (3,)), _array(t_gt, "t_gt", (3,))
    P = _array(points, "points", (None, 3))
    if len(P) == 0 or not np.isfinite(P).all():
        raise ValueError("points must be a non-empty finite (N, 3) array of model points")
    pe = P @ Re.T + te
    if K is not None and not (pe[:, 2] > 0).all():
        return float("inf")  # the estimate puts model points behind the camera: no image
    dist = _SymmetricDistance(pe, Rg, tg, P, K)
    d_rot, d_trans, _, _ = _symmetry_parts(symmetry)
    axes = _continuous_axes(symmetry)
    if not axes:
        return float(dist.discrete(d_rot, d_trans).min())
    n = _steps(max_sym_disc_step)
    step = 2.0 * np.pi / n
    best = np.inf
    for Rd, td in zip(d_rot, d_trans, strict=True):
        for a, o in axes:
            grid = step * np.arange(n)
            errors = dist.family(Rd, td, a, o, grid)
            k = int(np.argmin(errors))
            centre, half = grid[k], step
            # the minimum lies within a step of the best sample
            for _ in range(REFINE_PASSES if refine else 0):
                local = centre + np.linspace(-half, half, 33)  # holds the centre: never worse
                centre, half = local[int(np.argmin(dist.family(Rd, td, a, o, local)))], half / 16
            best = min(best, float(dist.family(Rd, td, a, o, np.array([centre]), True)[0]))
    return best


def mssd(
    R_est: ArrayLike,
    t_est: ArrayLike,
    R_gt: ArrayLike,
    t_gt: ArrayLike,
    points: ArrayLike,
    symmetry: Symmetry | None = None,
    max_sym_disc_step: float = MAX_SYM_DISC_STEP,
    refine: bool = True,
) -> float:
    """Maximum Symmetry-aware Surface Distance [BOP ``mssd``]: ``min over S of max over x of
    ||(R_est x + t_est) - (R_gt S_R x + R_gt S_t + t_gt)||``, ``x`` the model ``points``
    (N, 3) in the canonical frame, in the units of the points and translations.

    The group is BOP's (:func:`symmetry_transforms`, continuous axes sampled with
    ``max_sym_disc_step``); on a continuous axis the best sample is then refined (a zoom
    within one step either side, :data:`REFINE_PASSES`), so a pose anywhere on the axis
    scores ~0 and the result is never above BOP's. ``refine`` False leaves that out: the
    toolkit's own value on its sampled group (what BOP's recalls threshold; a pose between
    two samples scores up to a few per cent of the diameter above the true minimum). The
    maximum over a surface of a distance that is affine in ``x`` is reached at a vertex of
    its convex hull, so the hull's vertices give the maximum over the whole surface.
    """
    return _max_symmetric_distance(
        R_est, t_est, R_gt, t_gt, points, symmetry, None, max_sym_disc_step, refine
    )


def mspd(
    R_est: ArrayLike,
    t_est: ArrayLike,
    R_gt: ArrayLike,
    t_gt: ArrayLike,
    K: ArrayLike,
    points: ArrayLike,
    symmetry: Symmetry | None = None,
    max_sym_disc_step: float = MAX_SYM_DISC_STEP,
    refine: bool = True,
) -> float:
    """Maximum Symmetry-aware Projection Distance [BOP ``mspd``], in pixels: as
    :func:`mssd`, with each point replaced by its projection ``(K p)[:2] / (K p)[2]``
    through the (3, 3) intrinsics ``K`` (``refine`` as there). ``inf`` when the estimate
    puts a model point at or behind the camera's plane (it has no projection)."""
    Km = _array(K, "K", (3, 3))
    if not np.isfinite(Km).all():
        raise ValueError("K must be a finite (3, 3) intrinsics matrix")
    return _max_symmetric_distance(
        R_est, t_est, R_gt, t_gt, points, symmetry, Km, max_sym_disc_step, refine
    )


# --------------------------------------------------------------------------- viewpoint


def viewpoint(R: ArrayLike) -> tuple[float, float]:
    """(azimuth, elevation) in degrees of the camera seen from the object.

    ``R`` maps the canonical frame to the camera frame (OpenCV, the camera looks along its
    +z). The direction from the object towards the camera, in the canonical frame, is
    ``v = -R^T e_z`` (the reversed optical axis; exact for an object on the optical axis,
    and independent of the translation, as in [Pix3D]). Azimuth is ``atan2(v_y, v_x)`` in
    [0, 360) with 0 = seen from the front (+x) and 90 = from the left (+y); elevation is
    ``asin(v_z)`` in [-90, 90], positive when the camera is above.
    """
    M = _rotation(R, "R")
    v = -M[2, :]  # = -R^T @ [0, 0, 1]
    az = np.degrees(np.arctan2(v[1], v[0])) % 360.0
    el = np.degrees(np.arcsin(np.clip(v[2], -1.0, 1.0)))
    return float(az), float(el)


def viewpoint_bins(R: ArrayLike, bins: tuple[int, int]) -> tuple[int, int]:
    """(azimuth bin, elevation bin) of the viewpoint of ``R`` (see :func:`viewpoint`).

    ``bins = (n_azimuth, n_elevation)``. Azimuth bins have width ``w = 360 / n`` and are
    centred on the front: bin 0 is ``[-w/2, w/2)``, bin ``i`` is centred on ``i w`` (the
    Pascal3D+ AVP convention that Pix3D follows). Elevation bins split [-90, 90] evenly from
    the bottom (bin 0 starts at -90; +90 falls into the last bin).
    """
    az, el = viewpoint(R)
    i_az, i_el = _bins(np.array([az]), np.array([el]), *(int(b) for b in bins))
    return int(i_az[0]), int(i_el[0])


def _bins(az: np.ndarray, el: np.ndarray, n_az: int, n_el: int) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth and elevation bin indices of viewpoints in degrees (see :func:`viewpoint_bins`)."""
    if n_az < 1 or n_el < 1:
        raise ValueError(
            f"bins must be two positive counts (n_azimuth, n_elevation), got {(n_az, n_el)}"
        )
    w_az = 360.0 / n_az
    i_az = np.floor((np.mod(az, 360.0) + w_az / 2.0) / w_az).astype(np.int64) % n_az
    i_el = np.minimum(np.floor((el + 90.0) / (180.0 / n_el)).astype(np.int64), n_el - 1)
    return i_az, i_el


def viewpoint_bin_accuracy(
    view_est: ArrayLike, view_gt: ArrayLike, n_azimuth_bins: int, n_elevation_bins: int
) -> dict[str, float]:
    """:func:`bin_accuracy` on viewpoints already computed: ``view_est`` and ``view_gt`` are
    (N, 2) (azimuth, elevation) in degrees from :func:`viewpoint`. Rows with a NaN (a failed
    estimate) count as wrong. Returns ``{"azimuth", "elevation", "both"}`` (0..1)."""
    E = _array(view_est, "view_est", (None, 2))
    G = _array(view_gt, "view_gt", (None, 2))
    if E.shape != G.shape:
        raise ValueError(f"view_est and view_gt must have equal shapes, got {E.shape}, {G.shape}")
    if len(E) == 0:
        return {"azimuth": float("nan"), "elevation": float("nan"), "both": float("nan")}
    ok = np.isfinite(E).all(axis=1) & np.isfinite(G).all(axis=1)
    E, G = np.where(ok[:, None], E, 0.0), np.where(ok[:, None], G, 0.0)
    ea, ee = _bins(E[:, 0], E[:, 1], int(n_azimuth_bins), int(n_elevation_bins))
    ga, ge = _bins(G[:, 0], G[:, 1], int(n_azimuth_bins), int(n_elevation_bins))
    same_az, same_el = (ea == ga) & ok, (ee == ge) & ok
    return {
        "azimuth": float(same_az.mean()),
        "elevation": float(same_el.mean()),
        "both": float((same_az & same_el).mean()),
    }


def bin_accuracy(
    R_est: ArrayLike | Sequence[ArrayLike],
    R_gt: ArrayLike | Sequence[ArrayLike],
    n_azimuth_bins: int,
    n_elevation_bins: int,
) -> dict[str, float]:
    """Pix3D-style viewpoint classification accuracy [Pix3D, Tables 4.5/5.3 of Burchfiel].

    ``R_est`` / ``R_gt``: one (3, 3) rotation or a stack (N, 3, 3). A view counts as correct
    for azimuth (elevation) when both rotations fall into the same bin of
    :func:`viewpoint_bins`. Returns ``{"azimuth", "elevation", "both"}`` fractions (0..1).
    """
    E = _array(R_est, "R_est")
    G = _array(R_gt, "R_gt")
    if E.shape == (3, 3):
        E = E[None]
    if G.shape == (3, 3):
        G = G[None]
    if E.ndim != 3 or E.shape[1:] != (3, 3) or E.shape != G.shape:
        raise ValueError(
            f"R_est and R_gt must both be (3, 3) or (N, 3, 3) with equal N, got {E.shape} "
            f"and {G.shape}"
        )
    views = [np.array([viewpoint(r) for r in X]).reshape(-1, 2) for X in (E, G)]
    return viewpoint_bin_accuracy(views[0], views[1], n_azimuth_bins, n_elevation_bins)


# --------------------------------------------------------------------------- classes


def class_accuracy(pred: ArrayLike, true: ArrayLike) -> float:
    """Fraction of ``pred == true`` (an "unknown" prediction, -1, counts as wrong)."""
    p, t = _labels(pred, "pred"), _labels(true, "true")
    if p.shape != t.shape:
        raise ValueError(f"pred and true must have equal lengths, got {p.size} and {t.size}")
    return float(np.mean(p == t)) if p.size else float("nan")


def per_class_accuracy(pred: ArrayLike, true: ArrayLike, n_classes: int) -> NDArray[np.float64]:
    """(n_classes,) accuracy over the views of each true class (recall); NaN for a class
    that has no views."""
    p, t = _labels(pred, "pred"), _labels(true, "true")
    if p.shape != t.shape:
        raise ValueError(f"pred and true must have equal lengths, got {p.size} and {t.size}")
    if t.size and (t.min() < 0 or t.max() >= n_classes):
        raise ValueError(f"true labels must be in [0, {n_classes}), got {sorted(set(t.tolist()))}")
    count = np.bincount(t, minlength=n_classes).astype(np.float64)
    hit = np.bincount(t[p == t], minlength=n_classes).astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, hit / np.maximum(count, 1), np.nan)


def confusion_matrix(
    pred: ArrayLike, true: ArrayLike, n_classes: int, unknown: bool = False
) -> NDArray[np.int64]:
    """Counts with rows = true class, columns = predicted class, (n_classes, n_classes).

    With ``unknown=True`` the matrix has one extra last column counting "unknown" (-1)
    predictions (see :func:`predict_with_unknown`); otherwise a -1 raises ``ValueError``.
    """
    p, t = _labels(pred, "pred"), _labels(true, "true")
    if p.shape != t.shape:
        raise ValueError(f"pred and true must have equal lengths, got {p.size} and {t.size}")
    if t.size and (t.min() < 0 or t.max() >= n_classes):
        raise ValueError(f"true labels must be in [0, {n_classes}), got {sorted(set(t.tolist()))}")
    lo = -1 if unknown else 0
    if p.size and (p.min() < lo or p.max() >= n_classes):
        raise ValueError(
            f"pred labels must be in [{lo}, {n_classes}) (unknown={unknown}), "
            f"got {sorted(set(p.tolist()))}"
        )
    cols = n_classes + 1 if unknown else n_classes
    p = np.where(p < 0, n_classes, p)
    M = np.zeros((n_classes, cols), dtype=np.int64)
    np.add.at(M, (t, p), 1)
    return M


def _probs(probs: ArrayLike) -> np.ndarray:
    P = np.asarray(probs, dtype=np.float64)
    if P.ndim not in (1, 2) or P.shape[-1] == 0:
        raise ValueError(f"probs must be (C,) or (N, C) class probabilities, got {P.shape}")
    if not np.isfinite(P).all() or (P < 0).any():
        raise ValueError("probs must be finite and non-negative")
    s = P.sum(axis=-1, keepdims=True)
    if (s <= 0).any():
        raise ValueError("probs must not sum to 0")
    return P / s


def entropy(probs: ArrayLike) -> float | NDArray[np.float64]:
    """Shannon entropy in nats, ``-sum p log p`` (0 log 0 = 0), of (C,) probabilities (a
    float) or of each row of (N, C) (an (N,) array). Rows are normalised to sum 1 first."""
    P = _probs(probs)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(P > 0, -P * np.log(np.where(P > 0, P, 1.0)), 0.0)
    H = terms.sum(axis=-1)
    return float(H) if H.ndim == 0 else H


def predict_with_unknown(probs: ArrayLike, threshold: float) -> int | NDArray[np.int64]:
    """The argmax class, or -1 ("unknown") when the entropy (nats) exceeds ``threshold``
    ([Burchfiel] section 6.2.4). (C,) -> int; (N, C) -> (N,) int array. The maximum entropy
    of C classes is ``log C``."""
    P = _probs(probs)
    H = np.asarray(entropy(P))
    cls = np.where(H > threshold, -1, np.argmax(P, axis=-1)).astype(np.int64)
    return int(cls) if cls.ndim == 0 else cls


# --------------------------------------------------------------------------- completion


def voxel_iou(pred: ArrayLike, gt: ArrayLike, threshold: float = 0.5) -> float:
    """Intersection over union of two occupancy grids of equal shape [ONet].

    Float grids are occupied where ``>= threshold``; bool grids are used as they are. Both
    empty: 1.0 (they agree everywhere).
    """
    a, b = _grid(pred, "pred", threshold), _grid(gt, "gt", threshold)
    if a.shape != b.shape:
        raise ValueError(f"pred and gt must have the same shape, got {a.shape} and {b.shape}")
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else 1.0


def edt(grid: ArrayLike, threshold: float = 0.5) -> NDArray[np.float64]:
    """Euclidean distance transform of an occupancy grid, in voxel units: each voxel's
    distance to the nearest occupied voxel (0 on occupied voxels).

    An empty grid has no occupied voxel; its transform is defined as the grid diagonal
    ``sqrt(sum(shape^2))`` (``D sqrt(3)`` for D^3) everywhere, larger than any distance
    inside a non-empty grid.
    """
    g = _grid(grid, "grid", threshold)
    if not g.any():
        return np.full(g.shape, float(np.sqrt(np.sum(np.square(g.shape)))))
    return ndimage.distance_transform_edt(~g).astype(np.float64)


def edt_error(pred: ArrayLike, gt: ArrayLike, threshold: float = 0.5) -> float:
    """The EDT error ``||EDT(gt) - EDT(pred)||_2`` over all voxels ([Burchfiel] eq. 4.5),
    with :func:`edt` (voxel units; the empty-grid convention there). Float grids are
    binarised at ``threshold``."""
    a, b = _grid(pred, "pred", threshold), _grid(gt, "gt", threshold)
    if a.shape != b.shape:
        raise ValueError(f"pred and gt must have the same shape, got {a.shape} and {b.shape}")
    return float(np.linalg.norm(edt(b) - edt(a)))


def edt_error_per_voxel(pred: ArrayLike, gt: ArrayLike, threshold: float = 0.5) -> float:
    """The EDT error per voxel as a root mean square: ``edt_error / sqrt(N)`` with N the
    number of voxels (D^3), so grids of different resolution are comparable (voxel units)."""
    g = np.asarray(gt)
    return edt_error(pred, gt, threshold) / float(np.sqrt(max(g.size, 1)))


def _points(x: ArrayLike, name: str) -> np.ndarray:
    a = _array(x, name)
    if a.size == 0:
        return a.reshape(0, 3)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {a.shape}")
    return a


class Surface:
    """A triangle surface, prepared for exact point-to-surface distances, with area-uniform
    samples of it: what :func:`surface_scores` measures completion on without a sampling
    floor.

    ``vertices`` (V, 3) and ``faces`` (F, 3) indices give the triangles; ``samples`` (N, 3)
    are points on them (area-uniform, e.g. ``trimesh.sample.sample_surface``). Two sample
    sets of one surface are each other's nearest neighbours only up to the sampling's
    spacing (2048 samples of a unit-cube shape are ~0.02 apart, twice the F-score's
    ``tau``), so a perfect estimate scored sample to sample lands far below 1; measured
    against the other *surface* each sample's distance is exact, and the sampling only
    decides where the distance is averaged (an unbiased area average). An empty surface
    has no faces and no samples.
    """

    def __init__(self, vertices: ArrayLike, faces: ArrayLike, samples: ArrayLike) -> None:
        V = _points(vertices, "vertices")
        F = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
        if F.size and (F.min() < 0 or F.max() >= len(V)):
            raise ValueError(f"faces must index the {len(V)} vertices, got {F.min()}..{F.max()}")
        self.triangles: NDArray[np.float64] = _even(V[F])
        """(F, 3, 3) corners of each triangle (large ones split, see :func:`_even`)."""
        self.samples: NDArray[np.float64] = _points(samples, "samples")
        """(N, 3) points on the surface (the queries when it is measured against another)."""
        if len(self.samples) and not len(self.triangles):
            raise ValueError("a Surface with samples needs its triangles")
        self._centroids = cKDTree(self.triangles.mean(axis=1)) if len(self.triangles) else None

    def __len__(self) -> int:
        return len(self.samples)

    def distances(self, points: ArrayLike, k: int = NEAREST_TRIANGLES) -> NDArray[np.float64]:
        """(M,) distance of each point to the surface: the least exact point-to-triangle
        distance over the ``k`` triangles whose centroids are nearest the point. That is an
        upper bound of the distance to the whole surface and equals it unless the nearest
        triangle's centroid is not among the ``k`` nearest (a sliver's, far from its
        nearest part). On marching-cubes surfaces of 32^3 grids (22 instances, points on,
        1% and 5% of the cube off the surface) k = 4 left 0.6% of the points above the exact
        distance (k = 128), by at most 0.004 of the cube's side and 1e-5 on average, and put
        7 in a million on the wrong side of the F-score's ``tau = 0.01``; k = 6 costs 1.5x
        for 0.035%. Coarse meshes are split evenly first (:func:`_even`); near their sharp
        edges a point can still miss its own triangle (a 12-triangle box sampled twice
        scored F = 0.9995 against itself). ``inf`` for an empty surface."""
        q = _points(points, "points")
        if self._centroids is None:
            return np.full(len(q), np.inf)
        k = max(1, min(int(k), len(self.triangles)))
        _, idx = self._centroids.query(q, k=k)
        tri = self.triangles[np.asarray(idx).reshape(len(q), k)]  # (M, k, 3, 3)
        d = _triangle_distances(q[:, None, :], tri[..., 0, :], tri[..., 1, :], tri[..., 2, :])
        return d.min(axis=1)


EVEN_TRIANGLES = 250
"""A :class:`Surface` splits triangles whose radius exceeds ``sqrt(area / EVEN_TRIANGLES)``
(see :func:`_even`)."""


def _radii(tri: np.ndarray) -> np.ndarray:
    """Each triangle's largest corner-to-centroid distance."""
    return np.linalg.norm(tri - tri.mean(axis=1, keepdims=True), axis=2).max(axis=1)


def _even(tri: np.ndarray, max_triangles: int = 200_000) -> np.ndarray:
    """The triangles, each split in four at its edges' midpoints (the same surface) until
    its radius (:func:`_radii`) is at most ``sqrt(area / EVEN_TRIANGLES)``, a sixteenth of
    the surface's "side". A point's nearest few centroids then hold its nearest triangle
    (see :meth:`Surface.distances`) on a coarse mesh too (a box of 12 triangles becomes
    768), as on a marching-cubes one of a 32^3 grid, whose triangles are smaller already
    (radius < 0.03 of the cube for surfaces of area 0.37-4.5): it is left as it is."""
    if len(tri) == 0:
        return tri
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    rho = _radii(tri)
    target = float(np.sqrt(area.sum() / EVEN_TRIANGLES))
    while target > 0 and len(tri) < max_triangles:
        big = rho > target
        if not big.any():
            break
        t = tri[big]
        m01, m12, m20 = (t[:, 0] + t[:, 1]) / 2, (t[:, 1] + t[:, 2]) / 2, (t[:, 2] + t[:, 0]) / 2
        parts = [np.stack(c, axis=1) for c in (
            (t[:, 0], m01, m20), (m01, t[:, 1], m12), (m20, m12, t[:, 2]), (m01, m12, m20)
        )]  # fmt: skip
        tri = np.concatenate([tri[~big], *parts])
        rho = _radii(tri)
    return tri


def _dot(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", x, y)


def _segment_distances(ap: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Distance from points (``ap``: relative to a segment's start) to segments ``e``."""
    t = np.clip(_dot(ap, e) / np.maximum(_dot(e, e), 1e-300), 0.0, 1.0)
    return np.linalg.norm(ap - t[..., None] * e, axis=-1)


def _triangle_distances(
    p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray
) -> NDArray[np.float64]:
    """Exact distance from points ``p`` to triangles ``(a, b, c)`` (broadcast, last axis 3):
    to the foot of the perpendicular when it falls inside the triangle, else to the nearest
    of the three edges (a convex polygon's nearest point to an outside point is on its
    boundary). Degenerate triangles are measured by their edges."""
    ab, ac = b - a, c - a
    ap = np.broadcast_to(p - a, ab.shape)
    d00, d01, d11 = _dot(ab, ab), _dot(ab, ac), _dot(ac, ac)
    d20, d21 = _dot(ap, ab), _dot(ap, ac)
    det = d00 * d11 - d01 * d01
    ok = det > 1e-12 * d00 * d11
    safe = np.where(ok, det, 1.0)
    v = (d11 * d20 - d01 * d21) / safe
    w = (d00 * d21 - d01 * d20) / safe
    inside = ok & (v >= 0) & (w >= 0) & (v + w <= 1)
    foot = ap - v[..., None] * ab - w[..., None] * ac
    d = np.linalg.norm(foot, axis=-1)
    out = ~inside
    if out.any():
        ap_o, ab_o, ac_o = ap[out], ab[out], ac[out]
        edge = np.minimum(_segment_distances(ap_o, ab_o), _segment_distances(ap_o, ac_o))
        d[out] = np.minimum(edge, _segment_distances(ap_o - ab_o, ac_o - ab_o))
    return d


def chamfer_l1(points_a: ArrayLike | Surface, points_b: ArrayLike | Surface) -> float:
    """Chamfer-L1 distance [ONet; Tatarchenko]: the mean of the two directed mean
    nearest-neighbour Euclidean (not squared) distances,
    ``0.5 * (mean_a min_b ||a - b|| + mean_b min_a ||b - a||)`` (ONet's
    ``0.5 * (accuracy + completeness)``). Same units as the points. Either side may be a
    :class:`Surface`: its samples are the points, and distances *to* it are exact.

    One set empty: inf; both empty: 0.
    """
    return surface_scores(points_a, points_b)["chamfer_l1"]


def fscore(
    points_pred: ArrayLike | Surface, points_gt: ArrayLike | Surface, tau: float = 0.01
) -> float:
    """F-score at distance ``tau`` [Tatarchenko]: ``2 P R / (P + R)`` where precision ``P``
    is the fraction of predicted points closer than ``tau`` (strictly) to the ground truth
    and recall ``R`` the fraction of ground-truth points closer than ``tau`` to the
    prediction; 0 when ``P + R = 0``. The default ``tau = 0.01`` is 1% of the side of the
    unit cube the canonical shapes live in (1% of the object's largest extent). Either side
    may be a :class:`Surface` (see :func:`surface_scores`).

    One set empty: 0; both empty: 1.
    """
    return surface_scores(points_pred, points_gt, tau)["fscore"]


def _to(target: np.ndarray | Surface, points: np.ndarray) -> np.ndarray:
    """Distance from each of ``points`` to ``target``: exact to a :class:`Surface`, to the
    nearest point of a point set."""
    if isinstance(target, Surface):
        return target.distances(points)
    return cKDTree(target).query(points)[0]


def surface_scores(
    points_pred: ArrayLike | Surface, points_gt: ArrayLike | Surface, tau: float = 0.01
) -> dict[str, float]:
    """:func:`chamfer_l1` and :func:`fscore` (with its precision and recall) from one pair
    of distance queries: ``{"chamfer_l1", "fscore", "precision", "recall"}``; their
    definitions and edge cases are given there.

    Each side is an (N, 3) point set or a :class:`Surface`. A surface's samples are its
    points, and the other side's points are measured to the surface itself (exactly), not
    to its samples: so the same surface sampled twice scores F = 1 and Chamfer ~0 (to
    point sets, two samplings of 2048 points score F ~0.1-0.8 at ``tau = 0.01``, the
    sampling floor). Precision and recall are then area fractions estimated from the
    samples (standard error ``sqrt(p (1 - p) / N)``), free of bias.
    """
    sides = []
    for x, name in ((points_pred, "points_pred"), (points_gt, "points_gt")):
        sides.append(x if isinstance(x, Surface) else _points(x, name))
    pred, gt = sides
    p = pred.samples if isinstance(pred, Surface) else pred
    g = gt.samples if isinstance(gt, Surface) else gt
    if tau <= 0:
        raise ValueError(f"tau must be positive, got {tau}")
    if len(p) == 0 or len(g) == 0:
        same = len(p) == len(g)
        return {
            "chamfer_l1": 0.0 if same else float("inf"),
            "fscore": 1.0 if same else 0.0,
            "precision": 1.0 if same else 0.0,
            "recall": 1.0 if same else 0.0,
        }
    d_pg = _to(gt, p)
    d_gp = _to(pred, g)
    precision, recall = float(np.mean(d_pg < tau)), float(np.mean(d_gp < tau))
    f = 2.0 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    return {
        "chamfer_l1": float(0.5 * (d_pg.mean() + d_gp.mean())),
        "fscore": f,
        "precision": precision,
        "recall": recall,
    }


def _pose(pose: Any, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) from a (4, 4) transform or an (R, t) pair."""
    if isinstance(pose, tuple | list) and len(pose) == 2:
        R = _rotation(pose[0], f"{name}[0]")
        t = _array(pose[1], f"{name}[1]", (3,))
        return R, t
    T = _array(pose, name)
    if T.shape != (4, 4):
        raise ValueError(f"{name} must be a (4, 4) transform or an (R (3, 3), t (3,)) pair")
    return _rotation(T[:3, :3], f"{name}[:3, :3]"), T[:3, 3].copy()


def _scale(size: ArrayLike, name: str) -> float:
    s = _array(size, name)
    if s.shape not in ((), (1,), (3,)) or not np.all(s > 0):
        raise ValueError(f"{name} must be 3 positive extents (or one scale), got {s.tolist()}")
    return float(np.max(s))


def posed_iou(
    grid_a: ArrayLike,
    pose_a: Any,
    size_a: ArrayLike,
    grid_b: ArrayLike,
    pose_b: Any,
    size_b: ArrayLike,
    resolution: int = 64,
    threshold: float = 0.5,
) -> float:
    """IoU of two voxelised shapes placed in the camera frame with their poses and sizes.

    Each grid is a canonical-frame (D, D, D) occupancy grid indexed [x, y, z] filling the
    unit cube centred on the origin (edge = the object's largest extent), like
    ``Estimate.shape`` and ``ObjectInstance.voxels``. Object ``k`` occupies the cube of edge
    ``s_k = max(size_k)`` (only the largest extent is used: the grid carries the aspect),
    posed by ``pose_k`` (a (4, 4) canonical -> camera transform or an ``(R, t)`` pair).

    A common axis-aligned box covering both posed cubes is sampled at ``resolution``^3 cell
    centres; a sample ``x`` is inside object k when ``p = R_k^T (x - t_k)`` falls in an
    occupied voxel (nearest voxel: index ``floor((p / s_k + 0.5) D)``). The IoU is the
    ratio of sample counts (every sample stands for the same volume), accurate to about one
    sample cell. Both empty: 1.0. This is the overlap a grasp planner would see if it used
    the estimate; it mixes shape, pose and size errors.
    """
    if int(resolution) < 2:
        raise ValueError(f"resolution must be >= 2, got {resolution}")
    res = int(resolution)
    shapes = []
    for grid, pose, size, tag in ((grid_a, pose_a, size_a, "a"), (grid_b, pose_b, size_b, "b")):
        g = _grid(grid, f"grid_{tag}", threshold)
        R, t = _pose(pose, f"pose_{tag}")
        shapes.append((g, R, t, _scale(size, f"size_{tag}")))
    corners = np.array(np.meshgrid([-0.5, 0.5], [-0.5, 0.5], [-0.5, 0.5])).reshape(3, -1).T
    placed = np.concatenate([corners * s @ R.T + t for _, R, t, s in shapes])
    lo, hi = placed.min(axis=0), placed.max(axis=0)
    axes = [lo[i] + (np.arange(res) + 0.5) * (hi[i] - lo[i]) / res for i in range(3)]
    X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    inside = []
    for g, R, t, s in shapes:
        D = np.array(g.shape)
        idx = np.floor(((X - t) @ R / s + 0.5) * D).astype(np.int64)
        ok = np.all((idx >= 0) & (idx < D), axis=1)
        occ = np.zeros(len(X), dtype=bool)
        occ[ok] = g[idx[ok, 0], idx[ok, 1], idx[ok, 2]]
        inside.append(occ)
    union = np.count_nonzero(inside[0] | inside[1])
    return float(np.count_nonzero(inside[0] & inside[1]) / union) if union else 1.0


camera_frame_iou = posed_iou
"""Alias of :func:`posed_iou` (the design's "camera-frame IoU")."""


# --------------------------------------------------------------------------- pick, runtime


def pick_summary(
    successes: Iterable[bool], reasons: Iterable[str | None] | None = None
) -> dict[str, Any]:
    """``{"n", "successes", "success_rate", "failure_reasons"}`` of pick attempts.

    ``failure_reasons`` counts the reason of each failed attempt (None or "" as
    ``"unknown"``), most frequent first; reasons of successful attempts are ignored.
    ``success_rate`` is NaN for no attempts.
    """
    ok = [bool(s) for s in successes]
    why = list(reasons) if reasons is not None else [None] * len(ok)
    if len(why) != len(ok):
        raise ValueError(f"successes and reasons must have equal lengths: {len(ok)}, {len(why)}")
    counts = Counter(str(r) if r else "unknown" for s, r in zip(ok, why, strict=True) if not s)
    return {
        "n": len(ok),
        "successes": sum(ok),
        "success_rate": sum(ok) / len(ok) if ok else float("nan"),
        "failure_reasons": dict(counts.most_common()),
    }


def runtime_stats(seconds: ArrayLike) -> dict[str, float]:
    """``{"n", "ms_median", "ms_p95", "ms_mean", "hz"}`` of per-view times given in seconds.

    ``hz = 1000 / ms_median`` (views per second at the median time); p95 uses numpy's
    linear interpolation. NaNs dropped; no times -> NaNs.
    """
    s = _vector(seconds, "seconds")
    s = s[~np.isnan(s)]
    if s.size == 0:
        nan = float("nan")
        return {"n": 0, "ms_median": nan, "ms_p95": nan, "ms_mean": nan, "hz": nan}
    ms = s * 1000.0
    med = float(np.median(ms))
    return {
        "n": int(s.size),
        "ms_median": med,
        "ms_p95": float(np.percentile(ms, 95)),
        "ms_mean": float(ms.mean()),
        "hz": 1000.0 / med if med > 0 else float("inf"),
    }
