"""``icp``: the dissertation's ICP baseline, made solid.

The observed partial cloud (the mask's camera-frame points) is aligned to the surface of
the **class-mean shape** (the 0.5 iso-surface of the mean training occupancy, see
:mod:`beo_bench.perception.means`) by trimmed ICP from several starting rotations.

- *Model*: per class, marching cubes on the mean occupancy grid (padded by one empty voxel),
  in metres (the grid's unit-cube edge = the largest class-mean extent), thinned by
  farthest-point sampling to ``model_points`` points with outward normals (the occupancy
  gradient); a k-d tree over them, and a nearest-point lookup grid filled from it. Built
  lazily on first use and kept per (categories, class) on the backend.
- *Starts*: with ``View.up_hint`` (the ``pose-1dof`` protocol) ``starts`` yaw angles about
  the known up, and every update keeps that axis fixed (only the yaw about canonical +z and
  the translation are estimated); on a table (``View.world_up``: ``tabletop`` and ``pick``)
  with ``pose_prior``, ``starts`` gravity-aligned rotations drawn from the published rest
  prior (:class:`~beo_bench.types.RestPrior`, the training split's resting poses, as
  ``beo`` uses it: stratified yaws about the world's up, tilts as objects rest), every
  update free; otherwise ``starts`` rotations spread evenly over SO(3) (super-Fibonacci
  sampling, Alexa 2022). Each start's translation puts the centroid of the
  model's camera-facing surface (points weighted by how squarely their normals face the
  viewing ray) on the centroid of the observed points: a partial view sees the front
  surface, so the object's centre lies behind the observed centroid, by about half its depth
  along the ray.
- *Iterations*: nearest model point per observed point, keep the ``trim`` fraction of closest
  pairs (trimmed ICP), then a point-to-plane Gauss-Newton step (linearised small rotation +
  translation: batched 6x6, or 4x4 for yaw + translation) or a point-to-point
  Kabsch/Procrustes step. All starts are iterated together (one nearest-point query and one
  batched solve per iteration), coarse to fine: the first half of the ``iterations`` on
  ``coarse_points`` observed points with the O(1) lookup grid, the rest on up to
  ``max_points`` points with exact k-d tree queries for the ``refine_starts`` best starts.
- *Score*: the trimmed mean nearest-point distance (``residual_mm``) plus, weighted by
  ``free_space``, a free-space term: the camera-facing model surface of a pose must not lie
  in front of the observed depth nor project off the mask where the camera sees past it
  (see :meth:`Observation.free_space`). A one-sided ICP residual cannot tell a partial view
  from its flipped fit (the front surface fitted into the back of the model); this check
  can (on our library, 3-DOF median error 22 vs 79 degrees). The lowest score wins.
- *Scale* (``scale_range``, off by default): a few more point-to-plane iterations on the
  winner with a relative scale of the class-mean size as one more unknown, shrunk towards 1
  and clipped to the range. Partial views constrain size weakly; on our library it made
  the size error worse (20% vs 17%), hence off.
- *Class*: given whenever the view carries ``View.class_hint`` (one-hot probabilities; the
  backend's capabilities say ``ClassHint.OPTIONAL``, and the runner gives the hint in the
  ``class-given`` track of a pose suite only), or else the class whose mean shape fits best:
  every class is aligned and ``class_probs`` = softmax(-score_mm / ``temperature_mm``); the
  default temperature of 1 mm makes a fit 1 mm worse e times less likely.
- *Known pose* (``View.pose_hint``, the ``known-pose`` protocol of Table 3.1): nothing is
  aligned; each class-mean surface, scaled to the given size, is scored at the given pose
  with the same residual and free-space terms, which makes ``icp`` the mean-shape
  nearest-class baseline there.

The estimate: rotation (canonical -> camera), the canonical origin (bounding-box centre) in
the camera frame, size = class-mean size x scale, shape = the class-mean occupancy.
Deterministic: nothing is random (observed points are thinned by even striding).

``icp-plain`` is the dissertation's baseline (the ICP of Figures 3.6 and 4.3, which "got
stuck in local minima"): the same code with one start (the identity, or with
``View.up_hint``, or on a table the world's up, the up-aligned start at yaw 0), every
correspondence kept (no trimming), point-to-point (Kabsch) steps and no free-space term, so
the lowest plain ICP residual chooses the class when it is not given.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial import cKDTree

from beo_bench.backend import Backend, Capabilities, ClassHint, PrepareContext
from beo_bench.errors import ViewError
from beo_bench.geometry import orthonormalise, super_fibonacci, yaw_starts
from beo_bench.options import option
from beo_bench.perception.means import ClassMeans, class_means, rest_prior
from beo_bench.types import Estimate, Mat3, Points, RestPrior, View

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset

_EZ = np.array([0.0, 0.0, 1.0])
LOOKUP_CELLS = 48
"""Cells per axis of each mean surface's nearest-point lookup grid."""
MAX_STEP_RAD = 0.3
"""Largest rotation of one point-to-plane step (its linearisation holds for small angles)."""
FREE_SPACE_TOL = 0.005
"""Depth slack (m) before a model point in front of the observed surface counts."""
FREE_SPACE_CAP = 0.03
"""Largest contribution (m) of one model point to the free-space term."""
UPRIGHT = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])
"""The one start of a 3-DOF alignment from a single start (``starts=1``, ``icp-plain``):
the object upright and facing the camera (canonical +z up in the image, +x towards the
camera), the identity pose as a level camera sees it. (The camera frame's own identity
would point the object's up along the optical axis, a start no view of the suites is near:
136 deg mean error on 110 ``pose-3dof`` views, worse than chance.)"""
SCALE_PRIOR = 0.5
"""Weight of the prior that keeps the fitted scale near the class-mean size, relative to the
data's curvature in log-scale (partial views constrain the size weakly)."""


@dataclass(frozen=True)
class MeanSurface:
    """Surface samples of one class-mean shape in the canonical frame at class-mean size."""

    points: np.ndarray
    """(M, 3) points (m), canonical frame, centred on the bounding-box centre."""
    normals: np.ndarray
    """(M, 3) outward unit normals."""
    tree: cKDTree
    """k-d tree over ``points`` (exact nearest neighbours)."""
    lookup: np.ndarray
    """(G, G, G) int32: the index of the point nearest to each cell centre of a grid over
    the cube ``[-half, half]^3`` (approximate nearest neighbours in O(1), for the many-start
    coarse stage)."""
    half: float

    def nearest(self, q: np.ndarray, exact: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Distances and indices of the nearest surface points of ``q`` (..., 3): exact by
        the k-d tree, or approximate (the point nearest to ``q``'s lookup cell; queries
        outside the cube use the nearest boundary cell)."""
        if exact:
            d, idx = self.tree.query(q.reshape(-1, 3))
            return d.reshape(q.shape[:-1]), idx.reshape(q.shape[:-1])
        G = self.lookup.shape[0]
        ijk = np.clip(((q + self.half) * (G / (2 * self.half))).astype(np.int64), 0, G - 1)
        idx = self.lookup[ijk[..., 0], ijk[..., 1], ijk[..., 2]]
        return np.linalg.norm(q - self.points[idx], axis=-1), idx


def mean_surface(
    occupancy: np.ndarray, size: np.ndarray, n_points: int = 800, level: float = 0.5
) -> MeanSurface:
    """The ``level`` iso-surface of a (D, D, D) mean occupancy grid (indexed [x, y, z] over
    the unit cube of edge ``max(size)``) as ``n_points`` farthest-point-sampled vertices with
    outward normals. A grid that never reaches ``level`` uses half its maximum instead."""
    from skimage.measure import marching_cubes

    grid = np.asarray(occupancy, dtype=np.float32)
    D = grid.shape[0]
    top = float(grid.max())
    if top <= 0:
        raise ValueError("the mean occupancy grid is empty: no surface to align to")
    iso = level if top > level else 0.5 * top
    verts, _faces, normals, _ = marching_cubes(np.pad(grid, 1), iso)
    # padded index j is voxel j - 1, whose centre is ((j - 1 + 0.5) / D - 0.5) * edge
    edge = float(np.max(size))
    pts = ((verts - 0.5) / D - 0.5) * edge
    nrm = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    keep = _farthest_points(pts, n_points)
    pts, nrm = pts[keep].astype(np.float64), nrm[keep].astype(np.float64)
    tree = cKDTree(pts)
    # the lookup cube holds the model (half an edge) and a margin for stray observations
    half = 0.75 * edge
    g = ((np.arange(LOOKUP_CELLS) + 0.5) / LOOKUP_CELLS * 2 - 1) * half
    centres = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    lookup = tree.query(centres)[1].astype(np.int32).reshape((LOOKUP_CELLS,) * 3)
    return MeanSurface(pts, nrm, tree, lookup, half)


def _farthest_points(pts: np.ndarray, n: int) -> np.ndarray:
    """Indices of ``n`` farthest-point samples (deterministic: starts at the point farthest
    from the centroid)."""
    if len(pts) <= n:
        return np.arange(len(pts))
    chosen = np.empty(n, dtype=np.int64)
    chosen[0] = int(np.argmax(np.sum((pts - pts.mean(axis=0)) ** 2, axis=1)))
    dist = np.sum((pts - pts[chosen[0]]) ** 2, axis=1)
    for k in range(1, n):
        chosen[k] = int(np.argmax(dist))
        np.minimum(dist, np.sum((pts - pts[chosen[k]]) ** 2, axis=1), out=dist)
    return chosen


@dataclass(frozen=True)
class Observation:
    """What one view gives the alignment: its points and the image to check poses against."""

    points: Points
    """(N, 3) camera-frame points of the mask (all of them)."""
    depth: np.ndarray
    """(H, W) float64 depth (m), 0 = no data."""
    mask: np.ndarray
    """(H, W) bool, the object's pixels."""
    K: Mat3
    outside: np.ndarray
    """(H, W) distance (pixels) of each pixel to the nearest mask pixel (0 on the mask)."""

    @classmethod
    def from_view(cls, view: View) -> Observation:
        from scipy.ndimage import distance_transform_edt

        depth = np.nan_to_num(np.asarray(view.depth, dtype=np.float64), nan=0.0, posinf=0.0)
        mask = np.asarray(view.mask, dtype=bool) & (depth > 0)
        return cls(
            points=view.points(),
            depth=depth,
            mask=mask,
            K=np.asarray(view.K, dtype=np.float64),
            outside=distance_transform_edt(~mask),
        )

    def free_space(
        self, surf: MeanSurface, R: np.ndarray, t: np.ndarray, scale: float = 1.0
    ) -> np.ndarray:
        """(S,) how much the camera-facing model surface of each pose (R (S, 3, 3), t (S, 3);
        the surface scaled by ``scale``) contradicts the image (m, mean over those model
        points in the image): a model point in front of the observed surface on the mask
        counts by how far in front; off the mask,
        where the camera sees past it (background or farther depth), by its image distance
        to the mask, in metres at its depth. Both capped at ``FREE_SPACE_CAP``. Points hidden
        behind a nearer surface cost nothing (occluders, the object's own far side)."""
        X = np.einsum("sij,mj->smi", R, scale * surf.points) + t[:, None, :]
        N = np.einsum("sij,mj->smi", R, surf.normals)
        Z = X[..., 2]
        ok = (np.sum(N * X, axis=2) < 0) & (Z > 1e-3)
        Zs = np.where(ok, Z, 1.0)
        K = self.K
        u = np.rint(K[0, 0] * X[..., 0] / Zs + K[0, 2]).astype(np.int64)
        v = np.rint(K[1, 1] * X[..., 1] / Zs + K[1, 2]).astype(np.int64)
        H, W = self.depth.shape
        ok &= (u >= 0) & (u < W) & (v >= 0) & (v < H)
        u, v = np.where(ok, u, 0), np.where(ok, v, 0)
        d, on = self.depth[v, u], self.mask[v, u]
        tol = FREE_SPACE_TOL
        err = np.where(on, d - Z - tol, 0.0)
        beyond = ~on & ((d <= 0) | (d > Z + tol))
        err = np.where(beyond, self.outside[v, u] * Z / K[0, 0], err)
        err = np.clip(err, 0.0, FREE_SPACE_CAP) * ok
        return err.sum(axis=1) / np.maximum(ok.sum(axis=1), 1)


@dataclass
class Fit:
    """One class's alignment: canonical -> camera rotation and translation, the scale of the
    class-mean size, and the trimmed mean nearest-point distance (m)."""

    rotation: Mat3
    translation: np.ndarray
    scale: float
    residual: float
    score: float
    """What chose this fit among the starts: ``residual`` plus the free-space term (m)."""
    size: np.ndarray | None = None
    """(3,) extents (m) when known (the ``known-pose`` protocol), else class-mean x scale."""


def _rotvec_to_matrix(w: np.ndarray) -> np.ndarray:
    """Batched Rodrigues: (S, 3) rotation vectors -> (S, 3, 3)."""
    th = np.linalg.norm(w, axis=1)
    k = w / np.maximum(th, 1e-12)[:, None]
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = k[:, 2], -k[:, 1], k[:, 0]
    s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


class _Aligner:
    """Trimmed ICP of observed points to one mean surface, batched over starts.

    State per start: ``B`` (S, 3, 3) camera -> canonical rotation and ``b`` (S, 3), so that
    an observed point p (camera frame) maps to q = B p + b in the canonical frame (metres),
    where it should lie on the mean surface scaled by the start's scale factor sigma. The
    canonical -> camera pose is R = B^T, t = -B^T b.
    """

    def __init__(self, surf: MeanSurface, trim: float, point_to_plane: bool, yaw_only: bool):
        self.surf = surf
        self.trim = trim
        self.point_to_plane = point_to_plane
        self.yaw_only = yaw_only

    def _match(
        self, q: np.ndarray, exact: bool = True
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest model points of (S, N, 3) ``q``: distances (S, N), indices, and the
        trimming weights (1 for the ``trim`` fraction of closest pairs per start)."""
        N = q.shape[1]
        d, idx = self.surf.nearest(q, exact)
        k = max(3, int(np.ceil(self.trim * N))) if N >= 3 else N
        k = min(k, N)
        thresh = np.partition(d, k - 1, axis=1)[:, k - 1]
        w = (d <= thresh[:, None]).astype(np.float64)
        return d, idx, w

    def run(
        self,
        obs: np.ndarray,
        B: np.ndarray,
        b: np.ndarray,
        iterations: int,
        fit_scale: tuple[float, float] | None = None,
        exact: bool = True,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``iterations`` ICP steps from (B, b) on ``obs`` (N, 3). With ``fit_scale`` (a
        (lo, hi) range) a scale factor of the model is estimated too (point-to-plane only);
        ``exact=False`` uses the approximate nearest-point lookup. Returns B, b, the scale
        factors (S,) and the final (S,) trimmed mean distances."""
        surf = self.surf
        S = len(B)
        sigma = np.ones(S)  # scale of the mean surface: q ~ sigma * m
        for _ in range(iterations):
            q = obs @ B.transpose(0, 2, 1) + b[:, None, :]
            _d, idx, w = self._match(q / sigma[:, None, None], exact)
            m = surf.points[idx] * sigma[:, None, None]
            if self.point_to_plane:
                dR, v, step = self._plane_step(q, m, surf.normals[idx], w, sigma, fit_scale)
                if fit_scale is not None:
                    sigma = np.clip(sigma * (1.0 + step), *fit_scale)
            else:
                dR, v = self._procrustes(q, m, w)
            B = dR @ B
            b = np.einsum("sij,sj->si", dR, b) + v
            if np.abs(dR - np.eye(3)).max() < 1e-6 and np.abs(v).max() < 1e-6:
                break
        q = obs @ B.transpose(0, 2, 1) + b[:, None, :]
        d, _, w = self._match(q / sigma[:, None, None], exact)
        scores = np.sum(d * w, axis=1) / np.sum(w, axis=1) * sigma
        return B, b, sigma, scores

    def _plane_step(
        self,
        q: np.ndarray,
        m: np.ndarray,
        n: np.ndarray,
        w: np.ndarray,
        sigma: np.ndarray,
        fit_scale: tuple[float, float] | None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One Gauss-Newton step of the trimmed point-to-plane error sum w (n.(q' - m))^2
        over a small rotation (about +z only when ``yaw_only``), a translation, and with
        ``fit_scale`` a relative scale step of the model (with a weak prior towards the
        class-mean size). Returns the rotation and translation updates and the scale step."""
        r = np.sum(n * (q - m), axis=2)  # (S, N) signed plane distances
        qxn = np.cross(q, n)
        cols = [qxn[..., 2:3] if self.yaw_only else qxn, n]
        if fit_scale is not None:
            cols.append(-np.sum(n * m, axis=2, keepdims=True))  # d r / d log(scale)
        J = np.concatenate(cols, axis=2)  # (S, N, P)
        P = J.shape[2]
        Jw = J * w[..., None]
        H = Jw.transpose(0, 2, 1) @ J
        g = -(Jw.transpose(0, 2, 1) @ r[..., None])[..., 0]
        # a tiny Levenberg damping keeps degenerate views (a flat patch) solvable
        H = H + (1e-6 * np.einsum("sii->si", H).max(axis=1) + 1e-12)[:, None, None] * np.eye(P)
        if fit_scale is not None:
            # prior: log(scale) ~ N(0, .), worth SCALE_PRIOR of the data's own curvature
            lam = SCALE_PRIOR * H[:, -1, -1]
            H[:, -1, -1] += lam
            g[:, -1] -= lam * np.log(sigma)
        x = np.linalg.solve(H, g[..., None])[..., 0]
        rot = x[:, 0:1] * _EZ if self.yaw_only else x[:, 0:3]
        k = 1 if self.yaw_only else 3
        v = x[:, k : k + 3]
        # bound the rotation step: the linearisation holds for small angles
        ang = np.linalg.norm(rot, axis=1, keepdims=True)
        rot = rot * np.minimum(1.0, MAX_STEP_RAD / np.maximum(ang, 1e-12))
        step = np.clip(x[:, -1], -0.1, 0.1) if fit_scale is not None else np.zeros(len(x))
        return _rotvec_to_matrix(rot), v, step

    def _procrustes(
        self, q: np.ndarray, m: np.ndarray, w: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Weighted least-squares rotation (about +z only when ``yaw_only``) and translation
        taking q onto m, per start."""
        ws = np.sum(w, axis=1, keepdims=True)
        qc = np.einsum("sn,sni->si", w, q) / ws
        mc = np.einsum("sn,sni->si", w, m) / ws
        q0, m0 = q - qc[:, None], m - mc[:, None]
        if self.yaw_only:
            sin = np.einsum("sn,sn->s", w, q0[..., 0] * m0[..., 1] - q0[..., 1] * m0[..., 0])
            cos = np.einsum("sn,sn->s", w, q0[..., 0] * m0[..., 0] + q0[..., 1] * m0[..., 1])
            dR = _rotvec_to_matrix(np.arctan2(sin, cos)[:, None] * _EZ)
        else:
            H = np.einsum("sn,sni,snj->sij", w, q0, m0)
            U, _, Vt = np.linalg.svd(H)
            det = np.sign(np.linalg.det(Vt.transpose(0, 2, 1) @ U.transpose(0, 2, 1)))
            D = np.zeros_like(H)
            D[:, 0, 0], D[:, 1, 1], D[:, 2, 2] = 1.0, 1.0, det
            dR = Vt.transpose(0, 2, 1) @ D @ U.transpose(0, 2, 1)
        v = mc - np.einsum("sij,sj->si", dR, qc)
        return dR, v


@dataclass(frozen=True)
class ICPOptions:
    """The options of ``icp`` (``beo-bench run --opt KEY=VALUE``)."""

    resolution: int = option(32, "D of the class-mean occupancy (and of Estimate.shape)")
    mean_instances: int | None = option(
        None, "training instances per class in the class means (null: all)"
    )
    starts: int = option(
        24,
        "starting rotations (yaw angles with View.up_hint; one start is the identity, or "
        "yaw 0 about the up)",
    )
    iterations: int = option(30, "ICP iterations in all (coarse + fine)")
    trim: float = option(0.8, "fraction of closest correspondences kept per iteration")
    point_to_plane: bool = option(True, "point-to-plane steps, else point-to-point (Kabsch)")
    max_points: int = option(500, "observed points used (thinned by even striding)")
    coarse_points: int = option(120, "observed points of the coarse stage")
    refine_starts: int = option(3, "best starts refined by the fine stage")
    scale_range: tuple[float, float] | None = option(
        None,
        "e.g. [0.7, 1.4] fits an isotropic scale of the class-mean size in that range "
        "(point-to-plane only); null keeps the class-mean size",
    )
    temperature_mm: float = option(
        1.0, "softmax temperature of the class probabilities when the class is chosen by fit"
    )
    model_points: int = option(800, "surface samples of each class-mean shape")
    free_space: float = option(
        1.0,
        "weight of the free-space term in choosing among starts and classes (0: the plain "
        "trimmed ICP residual)",
    )
    pose_prior: bool = option(
        True,
        "on a table (View.world_up), start from rotations drawn from the published rest "
        "prior (upright about the world's up); false: starts over all of SO(3)",
    )

    def __post_init__(self) -> None:
        if self.starts < 1 or self.iterations < 1 or self.max_points < 3:
            raise ValueError("starts and iterations must be >= 1 and max_points >= 3")
        if not 0.0 < self.trim <= 1.0:
            raise ValueError(f"trim={self.trim}: keep a fraction in (0, 1] of the pairs")
        if self.temperature_mm <= 0:
            raise ValueError(f"temperature_mm={self.temperature_mm} must be > 0")
        lo, hi = self.scale_range or (1.0, 1.0)
        if not 0 < lo <= 1 <= hi:
            raise ValueError(f"scale_range={self.scale_range} must hold 1 and be positive")


class ICPBackend(Backend):
    """Multi-start trimmed ICP of the observed partial cloud to the class-mean surface
    (options: :class:`ICPOptions`).

    The class is taken from ``View.class_hint`` whenever a view carries one (the runner
    gives it in the ``class-given`` track: its capabilities say ``ClassHint.OPTIONAL``);
    otherwise every class is fitted and the best fit chosen.
    """

    name = "icp"
    Options = ICPOptions
    capabilities = Capabilities(class_hint=ClassHint.OPTIONAL)
    options: ICPOptions

    def __init__(self, options: ICPOptions | None = None, **kwargs: Any) -> None:
        super().__init__(options, **kwargs)
        self._digest: str | None = None
        self._dataset: Dataset | None = None
        self._cache_root: Path | None = None  # the run's asset cache (prepare's)
        self._means: dict[tuple[str, ...], ClassMeans] = {}
        self._surfaces: dict[tuple[tuple[str, ...], int], MeanSurface] = {}

    # -- models -------------------------------------------------------------------------
    def _class_means(self, cats: tuple[str, ...], progress: bool = False) -> ClassMeans:
        if cats not in self._means:
            self._means[cats] = class_means(
                cats,
                self.options.resolution,
                self.options.mean_instances,
                progress,
                self._dataset,
                self._cache_root,
            )
        return self._means[cats]

    def prepare(self, ctx: PrepareContext) -> None:
        """Compute (or load) the class means of the run's classes and dataset once (with a
        progress bar where ``ctx.progress``)."""
        self._cache_root = ctx.cache_root
        if ctx.dataset != self._dataset:  # another dataset's means and surfaces are not these
            self._dataset = ctx.dataset
            self._means.clear()
            self._surfaces.clear()
        self._class_means(tuple(ctx.categories), progress=ctx.progress)
        # on a table the starts come from the published rest prior: its digest is what the
        # run's model is (a refit moves the scores); elsewhere ICP learns nothing but means
        table = self.options.pose_prior and ctx.suite.protocol.world_frame == "robot"
        self._digest = rest_prior()[1] if table else None

    def model_digest(self) -> str | None:
        """The published rest prior's digest on a table suite (its starts), else None."""
        return self._digest

    def surface(self, cats: tuple[str, ...], c: int) -> MeanSurface:
        """The mean surface of class ``c`` of ``cats`` (built on first use, then kept)."""
        key = (tuple(cats), c)
        if key not in self._surfaces:
            means = self._class_means(tuple(cats))
            self._surfaces[key] = mean_surface(
                means.shape[c], means.size[c], self.options.model_points
            )
        return self._surfaces[key]

    # -- alignment ----------------------------------------------------------------------
    def _start_rotations(self, up: np.ndarray | None, rest: RestPrior | None) -> np.ndarray:
        if up is not None:
            return yaw_starts(up, self.options.starts)
        if rest is not None:
            if self.options.starts == 1:  # the prior's mode: upright, yaw 0
                return yaw_starts(np.asarray(rest.up), 1)
            return rest.frame() @ _rest_starts(rest.canonical(), self.options.starts)
        if self.options.starts == 1:
            return UPRIGHT[None]
        return super_fibonacci(self.options.starts)

    def fit(
        self,
        obs: Observation,
        surf: MeanSurface,
        up: np.ndarray | None,
        rest: RestPrior | None = None,
    ) -> Fit:
        """Align the observed points of ``obs`` to ``surf``; ``up``: the known canonical +z in
        the camera frame (1-DOF), or None (3-DOF); ``rest``: on a table, the rest prior in
        the camera frame the starts are drawn from."""
        pts = _thin(obs.points, self.options.max_points)
        coarse = _thin(pts, self.options.coarse_points)
        R0 = self._start_rotations(up, rest)
        yaw_only = up is not None
        aligner = _Aligner(surf, self.options.trim, self.options.point_to_plane, yaw_only)

        # translation of each start: the camera-facing model surface's centroid onto the
        # observed centroid (the centre lies behind the visible surface)
        centroid = pts.mean(axis=0)
        ray = centroid / max(np.linalg.norm(centroid), 1e-9)
        facing = np.clip(-np.einsum("sij,mj,i->sm", R0, surf.normals, ray), 0.0, None)
        facing += 1e-9
        c_vis = facing @ surf.points / facing.sum(axis=1, keepdims=True)  # (S, 3) model
        B = R0.transpose(0, 2, 1)
        b = c_vis - np.einsum("sij,j->si", B, centroid)

        def cost(B: np.ndarray, b: np.ndarray, res: np.ndarray) -> np.ndarray:
            if self.options.free_space <= 0:
                return res
            R = B.transpose(0, 2, 1)
            fs = obs.free_space(surf, R, -np.einsum("sij,sj->si", R, b))
            return res + self.options.free_space * fs

        n_coarse = max(1, self.options.iterations // 2)
        B, b, _, res = aligner.run(coarse, B, b, n_coarse, exact=False)
        keep = np.argsort(cost(B, b, res), kind="stable")[: max(1, self.options.refine_starts)]
        B, b = B[keep], b[keep]
        B, b, _, res = aligner.run(pts, B, b, max(1, self.options.iterations - n_coarse))
        total = cost(B, b, res)
        best = int(np.argmin(total))
        B, b, scale = B[best : best + 1], b[best : best + 1], 1.0
        residual, score = float(res[best]), float(total[best])
        if self.options.scale_range is not None and self.options.point_to_plane:
            # q = B p + b ~ sigma m: the canonical frame stays in metres, so R = B^T and
            # t = -B^T b whatever sigma is
            B, b, sig, sc = aligner.run(pts, B, b, 8, fit_scale=self.options.scale_range)
            scale, residual = float(sig[0]), float(sc[0])
        R = orthonormalise(B[0].T)
        t = -R @ b[0]
        return Fit(R, t, scale, residual, score)

    def fit_known_pose(
        self,
        obs: Observation,
        cats: tuple[str, ...],
        c: int,
        R: np.ndarray,
        t: np.ndarray,
        size: np.ndarray,
    ) -> Fit:
        """Score class ``c``'s mean surface at the given pose, scaled so that its largest
        extent is the given one (the grids' unit cube is the largest extent)."""
        surf = self.surface(cats, c)
        scale = float(np.max(size) / np.max(self._class_means(cats).size[c]))
        pts = _thin(obs.points, self.options.max_points)
        q = (pts - t) @ R / scale  # camera -> canonical, in units of the mean surface
        d, _ = surf.nearest(q)
        k = min(len(d), max(3, int(np.ceil(self.options.trim * len(d)))))
        residual = float(np.mean(np.partition(d, k - 1)[:k]) * scale)
        score = residual
        if self.options.free_space > 0:
            score += self.options.free_space * float(
                obs.free_space(surf, R[None], t[None], scale)[0]
            )
        return Fit(R, t, scale, residual, score, size=np.array(size, dtype=np.float64))

    def predict(self, view: View) -> Estimate:
        obs = Observation.from_view(view)
        if len(obs.points) == 0:
            raise ViewError(
                "the mask has no pixel with valid depth: ICP has no points to align "
                f"(mask pixels: {int(np.count_nonzero(view.mask))})"
            )
        cats = tuple(view.categories)
        means = self._class_means(cats)
        up = view.unit_up()
        classes = view.candidate_classes(use_hint=True)
        if view.pose_hint is not None:
            R, t, size = (np.asarray(a, dtype=np.float64) for a in view.pose_hint)
            fits = [self.fit_known_pose(obs, cats, c, R, t, size) for c in classes]
        else:
            rest = None
            if up is None and view.world_up is not None and self.options.pose_prior:
                rest = rest_prior()[0].in_view(np.asarray(view.world_up, dtype=np.float64))
            fits = [self.fit(obs, self.surface(cats, c), up, rest) for c in classes]
        res_mm = np.array([f.residual * 1e3 for f in fits])
        score_mm = np.array([f.score * 1e3 for f in fits])
        probs = np.zeros(len(cats))
        if len(classes) == 1:
            probs[classes[0]] = 1.0
        else:
            z = -(score_mm - score_mm.min()) / self.options.temperature_mm
            probs[classes] = np.exp(z) / np.exp(z).sum()
        k = int(np.argmin(score_mm))
        c, fit = classes[k], fits[k]
        info = {
            "residual_mm": float(res_mm[k]),
            "score_mm": float(score_mm[k]),
            "starts": self.options.starts,
            "scale": fit.scale,
            "protocol": _protocol(view),
        }
        if len(classes) > 1:
            info["class_scores_mm"] = [float(r) for r in score_mm]
        return Estimate(
            class_probs=probs,
            rotation=fit.rotation,
            translation=fit.translation,
            size=means.size[c] * fit.scale if fit.size is None else fit.size,
            shape=np.clip(means.shape[c], 0.0, 1.0).astype(np.float32),
            info=info,
        )


PLAIN_DEFAULTS: dict[str, object] = {
    "starts": 1,
    "trim": 1.0,
    "point_to_plane": False,
    "refine_starts": 1,
    "free_space": 0.0,
}
"""What makes ``icp`` the dissertation's plain ICP: one start, every pair kept,
point-to-point steps, the plain residual alone."""


@dataclass(frozen=True)
class PlainICPOptions(ICPOptions):
    """The options of ``icp-plain``: ``icp``'s, with :data:`PLAIN_DEFAULTS`."""

    starts: int = option(
        PLAIN_DEFAULTS["starts"], "starting rotations (1: upright facing the camera, or yaw 0)"
    )
    trim: float = option(PLAIN_DEFAULTS["trim"], "fraction of closest pairs kept (1: all)")
    point_to_plane: bool = option(
        PLAIN_DEFAULTS["point_to_plane"], "point-to-plane steps, else point-to-point (Kabsch)"
    )
    refine_starts: int = option(
        PLAIN_DEFAULTS["refine_starts"], "best starts refined by the fine stage"
    )
    free_space: float = option(
        PLAIN_DEFAULTS["free_space"], "weight of the free-space term (0: the plain residual)"
    )


class PlainICPBackend(ICPBackend):
    """``icp`` with :data:`PLAIN_DEFAULTS` (the dissertation's ICP baseline, see the module
    docstring); every ``icp`` option can still be given."""

    name = "icp-plain"
    Options = PlainICPOptions


def _protocol(view: View) -> str:
    if view.pose_hint is not None:
        return "known-pose"
    return "1dof" if view.up_hint is not None else "3dof"


@functools.lru_cache(maxsize=8)
def _rest_starts(rest: RestPrior, n: int) -> np.ndarray:
    """``n`` starts drawn from the rest prior about +z (a fixed generator: the same starts
    for every view), read-only."""
    R = rest.sample(n, np.random.default_rng(0))
    R.setflags(write=False)
    return R


def _thin(pts: np.ndarray, n: int) -> np.ndarray:
    """At most ``n`` of ``pts``, evenly strided (deterministic)."""
    if len(pts) <= n:
        return pts
    return pts[np.linspace(0, len(pts) - 1, n).round().astype(np.int64)]
