"""Completion metrics [ONet; Tatarchenko; Burchfiel]: voxel IoU, the EDT error of eq. 4.5,
Chamfer-L1 and F-score on exact point-to-surface distances (:class:`Surface`), and the IoU
of two posed, sized grids (conventions and references: :mod:`beo_bench.metrics`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage
from scipy.spatial import cKDTree

from beo_bench.metrics._arrays import _array, _grid, _rotation

FSCORE_TAU = 0.01
"""The benchmark's F-score threshold: 1% of the side of the unit cube the canonical shapes are
scaled into, i.e. 1% of the object's largest extent [Tatarchenko]."""
NEAREST_TRIANGLES = 4
"""Triangles (those with the nearest centroids) a point's distance to a :class:`Surface` is
taken over (see :meth:`Surface.distances`)."""


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
        self._centroids = cKDTree(_centroids(self.triangles)) if len(self.triangles) else None
        self._own: NDArray[np.float64] | None = None

    def keep_own_distances(self, distances: ArrayLike) -> None:
        """Keep ``distances(self.samples)`` (computed earlier, e.g. stored with the surface),
        handed out when the surface is measured against its own samples (the same values)."""
        d = np.array(distances, dtype=np.float64)
        if d.shape != (len(self.samples),):
            raise ValueError(f"distances must have shape ({len(self.samples)},), got {d.shape}")
        d.setflags(write=False)
        self._own = d

    def __len__(self) -> int:
        return len(self.samples)

    def freeze(self) -> Surface:
        """Make its arrays read-only (a surface kept and shared between callers); itself."""
        self.triangles.setflags(write=False)
        self.samples.setflags(write=False)
        return self

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
        if points is self.samples and self._own is not None and k == NEAREST_TRIANGLES:
            return self._own.copy()
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


# The per-triangle figures below are taken a coordinate at a time: the same operations, in
# the same order, as numpy's ``mean(axis=1)`` and ``linalg.norm(axis=-1)`` over (F, 3[, 3])
# (a sum of three is added left to right either way), so the same values to the bit, without
# a broadcast over rows of three, several times slower.
def _centroids(tri: np.ndarray) -> np.ndarray:
    """(F, 3) each triangle's centroid (``tri.mean(axis=1)``)."""
    out = np.empty((len(tri), 3))
    for i in range(3):
        np.add(tri[:, 0, i], tri[:, 1, i], out=out[:, i])
        out[:, i] += tri[:, 2, i]
    out /= 3.0
    return out


def _norms(x: np.ndarray) -> np.ndarray:
    """(F,) ``np.linalg.norm(x, axis=1)`` of (F, 3) vectors."""
    s = x[:, 0] * x[:, 0]
    s += x[:, 1] * x[:, 1]
    s += x[:, 2] * x[:, 2]
    return np.sqrt(s, out=s)


def _radii(tri: np.ndarray) -> np.ndarray:
    """Each triangle's largest corner-to-centroid distance."""
    c = _centroids(tri)
    return np.maximum.reduce([_norms(tri[:, j] - c) for j in range(3)])


def _areas(tri: np.ndarray) -> np.ndarray:
    """Each triangle's area."""
    return 0.5 * _norms(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))


def _even(tri: np.ndarray, max_triangles: int = 200_000) -> np.ndarray:
    """The triangles, each split in four at its edges' midpoints (the same surface) until
    its radius (:func:`_radii`) is at most ``sqrt(area / EVEN_TRIANGLES)``, a sixteenth of
    the surface's "side". A point's nearest few centroids then hold its nearest triangle
    (see :meth:`Surface.distances`) on a coarse mesh too (a box of 12 triangles becomes
    768), as on a marching-cubes one of a 32^3 grid, whose triangles are smaller already
    (radius < 0.03 of the cube for surfaces of area 0.37-4.5): it is left as it is."""
    if len(tri) == 0:
        return tri
    area = _areas(tri)
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
    d_gp = d_pg if pred is gt else _to(pred, g)  # one surface against itself: once
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
    cells = np.empty((res, res, res, 3))  # the sample points, [x, y, z] in C order
    cells[..., 0], cells[..., 1], cells[..., 2] = (
        axes[0][:, None, None],
        axes[1][None, :, None],
        axes[2][None, None, :],
    )
    X = cells.reshape(-1, 3)
    inside = []
    local = np.empty_like(X)
    for g, R, t, s in shapes:
        # p = R^T (x - t), then the voxel index floor((p / s + 0.5) D): the same operations
        # as on (N, 3) rows, done a coordinate at a time (a broadcast over rows of 3 is
        # many times slower), with the grid read through flat indices
        for i in range(3):
            np.subtract(X[:, i], t[i], out=local[:, i])
        P = local @ R
        flat = np.zeros(len(X), dtype=np.int64)
        ok = np.ones(len(X), dtype=bool)
        for i, n in enumerate(g.shape):
            c = np.floor((P[:, i] / s + 0.5) * float(n))
            ok &= (c >= 0) & (c < n)
            flat *= n
            flat += np.where(ok, c, 0).astype(np.int64)
        occ = np.zeros(len(X), dtype=bool)
        occ[ok] = g.reshape(-1)[flat[ok]]
        inside.append(occ)
    union = np.count_nonzero(inside[0] | inside[1])
    return float(np.count_nonzero(inside[0] & inside[1]) / union) if union else 1.0


camera_frame_iou = posed_iou
"""Alias of :func:`posed_iou` (the design's "camera-frame IoU")."""
