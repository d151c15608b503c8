"""Pose metrics [BOP; NOCS; Burchfiel; Pix3D]: symmetry-aware rotation and translation
errors, size error, gross-error rate, NOCS accuracies, MSSD and MSPD, and the Pix3D
viewpoint bins (conventions and references: :mod:`beo_bench.metrics`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from beo_bench.metrics._arrays import _array, _rotation, _vector
from beo_bench.types import Symmetry

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
GROSS_ERROR_DEG = 15.0
"""The gross-error threshold of [Burchfiel] Table 5.2 (a rotation error strictly above it)."""
MAX_SYM_DISC_STEP = 0.01
"""BOP's ``max_sym_disc_step`` for MSSD / MSPD: a continuous symmetry is sampled so that the
model point farthest from its axis moves at most this fraction of the model's diameter
between neighbouring samples (``ceil(pi / step)`` rotations, as in the BOP evaluation); the
best sample is then refined to the exact minimum (:func:`mssd`)."""


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
