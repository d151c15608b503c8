"""Scoring one view: the estimate against the truth (the pose and completion metrics, the
true shapes they are measured against, the meshes a pick plans on), the field's own figures
of the view beside ours, and the view's row.

Pure functions of an :class:`~beo_bench.types.Estimate` and a
:class:`~beo_bench.types.GroundTruth` (the metric definitions themselves are in
:mod:`beo_bench.metrics`); the item kinds (:mod:`beo_bench.bench.kinds`) call them.

The field's figures: the BOP 2019 errors (VSD, MSSD, MSPD; Hodan et al. 2020,
``beo_bench.bop.protocol``) and the NOCS report's 3D box IoU (Wang et al. 2019,
``beo_bench.bop.nocs``). A view row of a pose suite gets, besides our pose metrics
(:func:`score_pose`), from :func:`score_bop`:

- ``bop_vsd``: VSD's error at each of BOP's ten tau (``protocol.VSD_TAUS``, fractions of the
  object's diameter), delta 15 mm, the estimate rendered (``beo_bench.bop.render``) at the
  estimated pose with the true model, as BOP renders the object model it is given;
- ``bop_mssd_mm`` and ``bop_mspd_px``: MSSD and MSPD over every vertex of the true model
  (the model BOP evaluates with), under its symmetry group as the toolkit samples it
  (``metrics.mssd`` with ``refine=False``: our own MSSD and MSPD columns refine the
  minimum on a continuous axis, BOP's recalls threshold the sampled one);
- ``bop_diameter_mm``: the model's diameter, which MSSD's thresholds scale with;
- ``bop_visib_fract``: the visible fraction of the object (``visib_gt_min`` leaves a view
  below 0.1 out of the average recalls, as BOP does); an isolated view's object is never
  occluded (1);
- ``iou3d``: NOCS's 3D IoU of the estimated box (estimated size, pose) with the true one.

The summary turns them into the average recalls (``tally.recall_values``): one estimate
per target, so the matching of BOP's ``eval_calc_scores`` is the identity here (an
estimate per object, nothing to rank). ``beo-bench score`` matches a results file's
estimates as BOP does (:mod:`.bopscore`).
"""

from __future__ import annotations

import functools
import hashlib
from collections import OrderedDict
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench import metrics
from beo_bench.bench.tally import SAMPLE_FIELDS
from beo_bench.bop import nocs, protocol
from beo_bench.bop.render import ModelRenderer
from beo_bench.objects import instance_from_key
from beo_bench.types import Estimate, GroundTruth, View

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset

FSCORE_TAU = metrics.FSCORE_TAU
"""F-score threshold: 1% of the unit cube's side, i.e. of the object's largest extent (the
canonical shapes are scaled into the unit cube; Tatarchenko et al. 2019)."""


ISO_EPS = 1e-6
"""Marching cubes runs just below the 0.5 level, so that a cell of exactly 0.5, which every
metric counts as filled (``>= 0.5``), lies inside the surface too."""
SURFACE_POINTS = 1024
"""Surface samples per shape for Chamfer-L1 and the F-score: the points whose distances to the
other surface are taken (each exact, see :class:`~beo_bench.metrics.Surface`), so they only
average the distance over the area: no sampling floor, and a standard error of at most 1.6%
on a view's precision and recall (sqrt(0.25 / 1024)), which averages out over a suite. (Sample
to sample, 2048 were too few by far: a surface scored F = 0.13-0.84 against itself.)"""


def grid_mesh(
    grid: np.ndarray, edge: float = 1.0, level: float = 0.5, mirror_outside: bool = False
) -> Any:
    """The ``level`` iso-surface of a (D, D, D) occupancy grid (marching cubes, sub-voxel
    where the grid holds probabilities) as a mesh in the canonical frame, the grid spanning
    the cube of side ``edge`` centred at the origin (1: the unit cube; the largest extent:
    metres). ``None`` when no cell reaches ``level``.

    Outside the grid is empty (0). With ``mirror_outside`` a filled border cell of value
    ``p`` faces ``2 level - p`` instead, so the surface leaves the grid half a voxel beyond
    it whatever ``p`` is, as it does for a 0/1 grid (against 0 it would sit ``(p - level)
    / p`` of a voxel out: a perfect estimate given as 0.6/0.4 would lie a third of a voxel
    inside the truth wherever the object touches the cube, which is everywhere along its
    largest extent). Empty border cells still face themselves (no surface)."""
    import trimesh
    from skimage.measure import marching_cubes

    inner = np.asarray(grid, dtype=np.float32)
    g = np.pad(inner, 1)
    if mirror_outside:
        e = np.pad(inner, 1, mode="edge")
        border = np.ones(g.shape, dtype=bool)
        border[1:-1, 1:-1, 1:-1] = False
        g[border] = np.minimum(e, 2.0 * level - e)[border]
    if g.max() < level or g.min() > level - ISO_EPS:
        # no cell crosses the level: nothing reaches it, or (a grid of exactly ``level``
        # with the outside mirrored) nothing falls below it; either way there is no surface
        return None
    verts, faces, _, _ = marching_cubes(g, level - ISO_EPS)
    D = g.shape[0] - 2
    unit = (verts - 0.5) / D - 0.5  # padded index j is voxel j - 1, centred at (j-1+0.5)/D
    return trimesh.Trimesh(unit * edge, faces, process=False)


def surface_points(grid: np.ndarray, n: int = SURFACE_POINTS) -> np.ndarray:
    """``n`` area-uniform samples (seeded) of a grid's 0.5 iso-surface (:func:`grid_surface`)
    in the unit cube [-0.5, 0.5]^3; empty when the grid is."""
    return grid_surface(grid, n).samples


class _ByContent:
    """The last ``size`` values of a function of a grid, by the grid's content (a digest of
    its bytes, dtype and shape): a grid scored again (the oracle's, which is its truth's; a
    class mean, which ``random`` hands out for every view of its class) costs a look-up.
    Values are read-only; the same grid gives the same value, so nothing scored changes."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._values: OrderedDict[Hashable, Any] = OrderedDict()

    @staticmethod
    def key(grid: np.ndarray, *extra: Hashable) -> Hashable:
        a = np.ascontiguousarray(grid)
        h = hashlib.blake2b(a.data, digest_size=16)
        return (h.digest(), a.dtype.str, a.shape, *extra)

    def get(self, key: Hashable, make: Callable[[], Any]) -> Any:
        if key in self._values:
            self._values.move_to_end(key)
            return self._values[key]
        value = self._values[key] = make()
        if len(self._values) > self.size:
            self._values.popitem(last=False)
        return value

    def clear(self) -> None:
        self._values.clear()


_SURFACES = _ByContent(32)
"""Surfaces by grid (about 0.5 MB each at 32^3): the truths of the instances being scored
and the class means of a run fit."""
_EDTS = _ByContent(32)
"""EDTs by binarised grid (256 KB each at 32^3)."""


def grid_surface(grid: np.ndarray, n: int = SURFACE_POINTS) -> metrics.Surface:
    """A grid's 0.5 iso-surface (:func:`grid_mesh` with the outside mirrored, in the unit
    cube; a 0/1 grid's is the same either way) with ``n`` area-uniform samples of it
    (seeded), ready for exact distances (:class:`~beo_bench.metrics.Surface`) [Tatarchenko:
    F-score on surfaces]; empty when the grid is. Kept by content (the last few grids'):
    its arrays are read-only."""
    g = np.asarray(grid, dtype=np.float32)
    return _SURFACES.get(_ByContent.key(g, int(n)), lambda: _grid_surface(g, n))


def _grid_surface(grid: np.ndarray, n: int) -> metrics.Surface:
    import trimesh

    mesh = grid_mesh(grid, mirror_outside=True)
    if mesh is None:
        out = metrics.Surface(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), np.zeros((0, 3)))
    else:
        points, _ = trimesh.sample.sample_surface(mesh, n, seed=0)
        out = metrics.Surface(mesh.vertices, mesh.faces, np.asarray(points, dtype=np.float64))
    out.freeze()
    return out


def grid_edt(occupied: np.ndarray) -> np.ndarray:
    """:func:`beo_bench.metrics.edt` of a bool grid, kept by content (read-only)."""

    def make() -> np.ndarray:
        e = metrics.edt(occupied)
        e.setflags(write=False)
        return e

    return _EDTS.get(_ByContent.key(np.packbits(occupied), occupied.shape), make)


@dataclass(frozen=True)
class TruthShape:
    """What scoring needs of one instance's true shape at resolution D, computed once per
    process (0.4-1.3 MB at 32^3: the surface's triangles, and the EDT, 8 bytes a voxel)."""

    voxels: np.ndarray
    """(D, D, D) bool occupancy."""
    surface: metrics.Surface
    """Its 0.5 iso-surface in the unit cube, with SURFACE_POINTS samples."""
    model_points: np.ndarray
    """(H, 3) the vertices of the true mesh's convex hull (canonical frame, metres): the
    model points of MSSD and MSPD (a distance affine in the point is largest at one of
    them, so they stand for the whole surface)."""
    edt: np.ndarray
    """(D, D, D) its EDT (:func:`beo_bench.metrics.edt`): the truth's side of every view's
    EDT error."""


@functools.lru_cache(maxsize=256)
def truth_shape(
    key: str, D: int, dataset: Dataset | None = None, cache_root: Path | None = None
) -> TruthShape:
    """The true shape of instance ``key`` (of ``dataset``, for a dataset's key; voxels
    disk-cached at ``cache_root``, default the environment's; the rest kept per process)."""
    from beo_bench.objects import cache

    inst = instance_from_key(key, dataset, cache_root)
    v = inst.voxels(D)
    hull = np.array(inst.mesh.convex_hull.vertices, dtype=float)

    def compute() -> dict[str, np.ndarray]:
        # squared distances are integers (an EDT is sqrt of a sum of three integer squares):
        # kept exactly, and their float square roots are the EDT's values to the bit
        surface = grid_surface(v)
        return {
            "samples": surface.samples,
            "edt2": np.rint(grid_edt(v) ** 2).astype(np.int32),
            # the samples' distances to their own surface: what the oracle's view measures
            "own": surface.distances(surface.samples),
        }

    # the samples and the EDT (half of an instance's cost to score) are kept on disk, by the
    # grid they are of: a suite's instance is mostly new to a worker process
    grid = hashlib.sha256(np.packbits(v).tobytes()).hexdigest()[:32]
    kept = cache.cached(
        "truth", grid, {"D": int(D), "n": SURFACE_POINTS, "v": 2}, compute, cache_root
    )
    mesh = grid_mesh(v, mirror_outside=True)
    if mesh is None:  # no true surface (an empty grid): as grid_surface has it
        surface = grid_surface(v)
    else:
        surface = metrics.Surface(mesh.vertices, mesh.faces, kept["samples"]).freeze()
        surface.keep_own_distances(kept["own"])
    edt = np.sqrt(kept["edt2"].astype(np.float64))
    out = TruthShape(v, surface, hull, edt)
    for a in (out.voxels, out.model_points, out.edt):
        a.setflags(write=False)
    return out


def score_shape(
    est: Estimate, gt: GroundTruth, truth: TruthShape, tau: float = FSCORE_TAU
) -> dict[str, Any]:
    """Completion metrics of one estimate against the truth, at the truth's resolution:
    voxel IoU, camera-frame IoU (shape, pose and size together: what a planner using the
    estimate sees), the EDT error (eq. 4.5), Chamfer-L1 and F-score at ``tau`` (exact
    distances from each surface's samples to the other surface: a perfect estimate scores
    F = 1 at any occupancy probability above 0.5)."""
    D = truth.voxels.shape[0]
    pred = resample(est.shape, D)
    out: dict[str, Any] = {"iou": metrics.voxel_iou(pred, truth.voxels)}
    # the truth's own grid (the oracle's estimate) has the truth's surface and EDT: the same
    # values as computing them again from the estimate
    exact = bool(np.array_equal(pred, truth.voxels))
    posed = [(est.rotation, est.translation, est.size), (gt.R_cam, gt.t_cam, gt.size)]
    if exact and all(np.array_equal(a, b) for a, b in zip(*posed, strict=True)):
        # the same grid at the same pose and size: the same samples inside both, IoU 1
        out["iou_cam"] = 1.0
    else:
        out["iou_cam"] = metrics.camera_frame_iou(
            pred,
            (est.rotation, est.translation),
            est.size,
            truth.voxels,
            (gt.R_cam, gt.t_cam),
            gt.size,
            resolution=D,
        )
    # metrics.edt_error(pred, truth.voxels), with the truth's EDT made once
    occupied = np.asarray(pred, dtype=np.float64) >= 0.5
    pred_edt = truth.edt if exact else grid_edt(occupied)
    out["edt_err"] = float(np.linalg.norm(truth.edt - pred_edt))
    pred_surface = truth.surface if exact else grid_surface(pred)
    surf = metrics.surface_scores(pred_surface, truth.surface, tau)
    out["fscore"] = surf["fscore"]
    out["chamfer_l1"] = surf["chamfer_l1"] if np.isfinite(surf["chamfer_l1"]) else None
    return out


def score_pose(
    est: Estimate, gt: GroundTruth, truth: TruthShape, K: np.ndarray | None
) -> dict[str, Any]:
    """Pose metrics of one estimate, each under the object's symmetry group: rotation
    error (deg), translation error (cm; at the symmetric pose nearest in translation), size
    error (%), MSSD (cm) and, where the camera ``K`` is known, MSPD (pixels; None when the
    estimate puts the object behind the camera) over the true model's hull vertices."""
    return pose_metrics(est, gt, truth.model_points, K)


def pose_metrics(
    est: Estimate, gt: GroundTruth, model_points: np.ndarray, K: np.ndarray | None
) -> dict[str, Any]:
    """:func:`score_pose` given the true model's hull vertices ``model_points`` (what a
    scored results file has of the truth: ``bopscore``)."""
    sym = gt.symmetry
    args = (est.rotation, est.translation, gt.R_cam, gt.t_cam)
    out: dict[str, Any] = {
        "rot_err_deg": metrics.rotation_error(est.rotation, gt.R_cam, sym),
        "trans_err_cm": metrics.translation_error(est.translation, gt.t_cam, gt.R_cam, sym),
        "size_err_pct": metrics.size_error(est.size, gt.size),
        "mssd_cm": 100.0 * metrics.mssd(*args, model_points, sym),
    }
    if K is not None:
        px = metrics.mspd(*args, np.asarray(K, dtype=np.float64), model_points, sym)
        out["mspd_px"] = px if np.isfinite(px) else None
    if est.pose_samples is not None and len(est.pose_samples):
        out.update(score_samples(est, gt))
    return out


def viewpoints(est: Estimate, gt: GroundTruth) -> dict[str, list[float]]:
    """Pix3D's viewpoints of the estimate and of the symmetric truth nearest to it."""
    R_sym = metrics.closest_symmetric_pose(est.rotation, gt.R_cam, gt.symmetry)
    return {
        "viewpoint_est": list(metrics.viewpoint(est.rotation)),
        "viewpoint_gt": list(metrics.viewpoint(R_sym)),
    }


def score_samples(est: Estimate, gt: GroundTruth) -> dict[str, float]:
    """What a sampling backend's samples offer and how it ranked them: the error of the
    best sample (deg, under the symmetry group: no ranking of these samples can do better),
    that sample's rank under ``pose_weights`` (0: the sample the weights put first; ties
    broken by the sample order, as ``argmax`` does) and the samples' spread (the median
    angle between a sample and the estimate, deg). Paired over the same samples (HBEO-MDN
    seeds them by the crop), the likelihood and posterior modes differ only in the rank:
    this is what says whether the silhouette prior (eq. 5.6) moves the best sample up."""
    S = np.asarray(est.pose_samples, dtype=np.float64)
    errs = np.array([metrics.rotation_error(R, gt.R_cam, gt.symmetry) for R in S])
    best = int(np.argmin(errs))
    w = np.asarray(est.pose_weights) if est.pose_weights is not None else np.ones(len(S))
    order = np.argsort(-w, kind="stable")
    cos = (np.einsum("nij,ij->n", S, np.asarray(est.rotation)) - 1.0) / 2.0
    values = (
        float(errs[best]),
        int(np.flatnonzero(order == best)[0]),
        float(np.degrees(np.median(np.arccos(np.clip(cos, -1, 1))))),
    )
    return dict(zip(SAMPLE_FIELDS, values, strict=True))


def resample(grid: np.ndarray, D: int) -> np.ndarray:
    g = np.asarray(grid, dtype=np.float32)
    if g.shape[0] == D:
        return g
    idx = ((np.arange(D) + 0.5) * g.shape[0] / D).astype(int)
    return g[np.ix_(idx, idx, idx)]


def local_mesh(est: Estimate) -> Any:
    """The estimate's surface in its canonical frame (metres): ``Estimate.mesh`` when given,
    else :func:`grid_mesh` of its occupancy scaled by the estimated size (the grid's cube
    edge is the largest extent). ``None`` when the grid is empty."""
    if est.mesh is not None:
        return est.mesh
    return grid_mesh(est.shape, edge=float(np.max(est.size)))


def _to_world(points: np.ndarray, est: Estimate, cam_to_world: np.ndarray) -> np.ndarray:
    cam = points @ np.asarray(est.rotation).T + np.asarray(est.translation)
    return cam @ cam_to_world[:3, :3].T + cam_to_world[:3, 3]


def estimate_mesh(est: Estimate, cam_to_world: np.ndarray) -> Any:
    """The estimate's surface (:func:`local_mesh`) placed by its pose, then by
    ``cam_to_world``: a world-frame mesh (``None`` when the shape is empty)."""
    import trimesh

    mesh = local_mesh(est)
    if mesh is None:
        return None
    world = _to_world(np.asarray(mesh.vertices), est, cam_to_world)
    return trimesh.Trimesh(world, mesh.faces, process=False)  # the planner fixes orientation


def obstacle_points(est: Estimate | None, view: View, cam_to_world: np.ndarray) -> np.ndarray:
    """World points that a grasp of another object must avoid: ``SURFACE_SAMPLES`` samples
    of this object's estimated surface, placed by its estimate (the same samples the
    ground-truth planner takes of a true mesh), or its observed points when there is no
    estimate or the shape is empty."""
    from beo_bench.objects.instance import SURFACE_SAMPLES
    from beo_bench.objects.processing import surface_samples

    mesh = local_mesh(est) if est is not None else None
    if est is None or mesh is None:
        return view.points() @ cam_to_world[:3, :3].T + cam_to_world[:3, 3]
    points, _ = surface_samples(mesh, SURFACE_SAMPLES, seed=0)
    return _to_world(points, est, cam_to_world)


PICK_ERRORS: tuple[str, ...] = (
    "rot_err_deg", "trans_err_cm", "size_err_pct", "iou", "iou_cam", "chamfer_world_cm",
)  # fmt: skip
"""The errors a pick episode records of the estimate it grasped (:func:`pick_errors`)."""
CHAMFER_SAMPLES = 2000


def pick_errors(
    est: Estimate,
    gt: GroundTruth,
    cam_to_world: np.ndarray,
    resolution: int,
    dataset: Dataset | None = None,
    cache_root: Path | None = None,
) -> dict[str, Any]:
    """The errors of the estimate a pick episode grasped, against its object's truth (issue
    49: success tied to each estimate's error): rotation (deg, under the object's
    symmetry), translation (cm), size (%), shape IoU in the canonical frame and in the
    camera's (shape, pose and size together), and the symmetric Chamfer distance (mean of
    both directions, cm) between the surface the grasp was planned on and the true surface,
    both in the world frame, from :data:`CHAMFER_SAMPLES` samples of each."""
    from scipy.spatial import cKDTree

    from beo_bench.objects.processing import surface_samples

    truth = truth_shape(gt.key, resolution, dataset, cache_root)
    sym, pred = gt.symmetry, resample(est.shape, resolution)
    # only the errors recorded (score_pose / score_shape add EDT, F-score, MSSD: not needed)
    out: dict[str, Any] = {
        "rot_err_deg": metrics.rotation_error(est.rotation, gt.R_cam, sym),
        "trans_err_cm": metrics.translation_error(est.translation, gt.t_cam, gt.R_cam, sym),
        "size_err_pct": metrics.size_error(est.size, gt.size),
        "iou": metrics.voxel_iou(pred, truth.voxels),
        "iou_cam": metrics.camera_frame_iou(
            pred, (est.rotation, est.translation), est.size, truth.voxels,
            (gt.R_cam, gt.t_cam), gt.size, resolution=resolution,
        ),
    }  # fmt: skip
    inst = instance_from_key(gt.key, dataset, cache_root)
    true_est = Estimate(
        np.ones(1), np.asarray(gt.R_cam), np.asarray(gt.t_cam), np.asarray(gt.size),
        truth.voxels.astype(np.float32), mesh=inst.mesh,
    )  # fmt: skip
    planned, true = estimate_mesh(est, cam_to_world), estimate_mesh(true_est, cam_to_world)
    chamfer = None
    if planned is not None and true is not None:
        a, _ = surface_samples(planned, CHAMFER_SAMPLES, seed=0)
        b, _ = surface_samples(true, CHAMFER_SAMPLES, seed=0)
        d_ab, d_ba = cKDTree(b).query(a)[0], cKDTree(a).query(b)[0]
        chamfer = 100.0 * 0.5 * (float(d_ab.mean()) + float(d_ba.mean()))
    out["chamfer_world_cm"] = chamfer
    return {k: out.get(k) for k in PICK_ERRORS}


# -- the field's figures (BOP, NOCS) ----------------------------------------------------------
BOP_FIELDS = ("bop_vsd", "bop_mssd_mm", "bop_mspd_px", "bop_diameter_mm", "bop_visib_fract")
"""The BOP row fields of a scored view (see the module docstring)."""


@dataclass(frozen=True)
class BopModel:
    """What the BOP errors need of one instance's true model (made once per process)."""

    vertices: np.ndarray
    """(N, 3) the model's vertices (canonical frame, metres): BOP's model points."""
    hull: np.ndarray
    """(H, 3) its convex hull's vertices: our own MSSD and MSPD's model points, as
    ``scoring.TruthShape.model_points``."""
    diameter: float
    """The largest distance between two of its points (metres), as ``models_info`` has it."""
    renderer: ModelRenderer
    """Its depth images at any pose (VSD's renderings)."""


@functools.lru_cache(maxsize=64)
def bop_model(key: str, dataset: Dataset | None = None, cache_root: Path | None = None) -> BopModel:
    """The BOP model of instance ``key`` (kept per process, as ``scoring.truth_shape``)."""
    from scipy.spatial.distance import pdist

    mesh = instance_from_key(key, dataset, cache_root).mesh
    V = np.array(mesh.vertices, dtype=np.float64)
    hull = np.asarray(mesh.convex_hull.vertices, dtype=np.float64)
    diameter = float(pdist(hull).max()) if len(hull) > 1 else 0.0
    V.setflags(write=False)
    hull.setflags(write=False)
    return BopModel(V, hull, diameter, ModelRenderer(V, np.asarray(mesh.faces)))


def _label(view: View) -> int | None:
    """The segmentation label of the object a scene view shows (None: an isolated view)."""
    if view.segmentation is None:
        return None
    return int(np.asarray(view.segmentation)[np.asarray(view.mask)][0])


def visible_fraction(view: View, full: np.ndarray) -> float:
    """BOP's ``visib_fract`` of the view's object: its visible pixels (the segmentation's)
    over those of its whole silhouette ``full`` (the true model rendered alone; a visible
    pixel counts in both, so the fraction is at most 1). An isolated view has no other
    object and no segmentation: 1."""
    label = _label(view)
    if label is None:
        return 1.0
    visible = np.asarray(view.segmentation) == label
    n_all = int(np.count_nonzero(visible | full))
    return float(np.count_nonzero(visible)) / n_all if n_all else 0.0


def _crop(
    d_est: np.ndarray, d_gt: np.ndarray, K: np.ndarray
) -> tuple[tuple[slice, slice], np.ndarray]:
    """The window of the image where either rendering has the object, and the intrinsics of
    that window (the principal point moved by its corner): VSD counts no pixel outside it
    (its visibility masks need the model there), so VSD on the window is VSD on the image,
    at a fraction of a 640x480 image's cost. One pixel when neither has the object (the
    union is empty: VSD is 1)."""
    rows = np.flatnonzero((d_est > 0).any(axis=1) | (d_gt > 0).any(axis=1))
    cols = np.flatnonzero((d_est > 0).any(axis=0) | (d_gt > 0).any(axis=0))
    if not len(rows):
        return (slice(0, 1), slice(0, 1)), K
    v0, v1, u0, u1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    Kc = K.copy()
    Kc[0, 2] -= u0
    Kc[1, 2] -= v0
    return (slice(int(v0), int(v1)), slice(int(u0), int(u1))), Kc


def score_bop(
    est: Estimate | None,
    gt: GroundTruth,
    view: View,
    dataset: Dataset | None = None,
    cache_root: Path | None = None,
) -> dict[str, Any]:
    """The BOP fields of one view (:data:`BOP_FIELDS`) and NOCS's ``iou3d`` for ``est``
    (None: the backend failed; only the diameter and the visible fraction, which a
    failure's row needs to count as a target or not)."""
    model = bop_model(gt.key, dataset, cache_root)
    K = np.asarray(view.K, dtype=np.float64)
    h, w = np.asarray(view.depth).shape
    d_gt = model.renderer.depth(gt.R_cam, gt.t_cam, K, w, h)
    out: dict[str, Any] = {
        "bop_diameter_mm": 1000.0 * model.diameter,
        "bop_visib_fract": visible_fraction(view, d_gt > 0),
    }
    if est is None:
        return out
    R, t = np.asarray(est.rotation), np.asarray(est.translation)
    same_pose = np.array_equal(R, gt.R_cam) and np.array_equal(t, gt.t_cam)
    d_est = d_gt if same_pose else model.renderer.depth(R, t, K, w, h)  # the same render
    crop, Kc = _crop(d_est, d_gt, K)
    out["bop_vsd"] = [
        float(e)
        for e in protocol.vsd_errors(
            1000.0 * np.asarray(view.depth, dtype=np.float64)[crop],
            1000.0 * d_est[crop],
            1000.0 * d_gt[crop],
            Kc,
            protocol.VSD_DELTA_MM,
            protocol.VSD_TAUS,
            1000.0 * model.diameter,
        )
    ]
    sym = gt.symmetry
    args = (R, t, gt.R_cam, gt.t_cam)
    # BOP's own values: its sampled symmetry group, not refined (metrics.mssd), so that the
    # recalls are the toolkit's to the threshold
    out["bop_mssd_mm"] = 1000.0 * metrics.mssd(*args, model.vertices, sym, refine=False)
    px = metrics.mspd(*args, K, model.vertices, sym, refine=False)
    out["bop_mspd_px"] = px if np.isfinite(px) else None
    out["iou3d"] = nocs.box_iou(gt.size, gt.R_cam, gt.t_cam, est.size, R, t, sym)
    return out


# -- the row ---------------------------------------------------------------------------------
Answer = tuple[Estimate | None, float, str | None]
"""A backend's answer for one view: the estimate (None: it failed), the seconds it took,
and why it failed (None: it did not)."""


def base_row(index: int, j: int, view: View, gt: GroundTruth, class_given: bool) -> dict[str, Any]:
    """The row of view ``j`` of item ``index`` as far as it is known without the backend."""
    return {
        "item": index,
        "view": j,
        "key": gt.key,
        "category": gt.category,
        "true_class": gt.class_index,
        "pixels": int(np.count_nonzero(view.mask)),
        "class_given": class_given,
    }


def view_row(
    row: dict[str, Any],
    view: View,
    gt: GroundTruth,
    answer: Answer,
    resolution: int,
    scores_pose: bool,
    dataset: Dataset | None = None,
    cache_root: Path | None = None,
) -> dict[str, Any]:
    """``row`` (:func:`base_row`) completed with the scores of ``answer``: the class, and
    where the protocol does not give the pose (``scores_pose``) the pose metrics and Pix3D
    viewpoints, then the completion metrics at ``resolution``."""
    est, seconds, failure = answer
    row.update(ms=1000 * seconds, failure=failure)
    if scores_pose:  # the field's figures (BOP, NOCS): a failure's row counts as a target
        row.update(score_bop(est, gt, view, dataset, cache_root))
    if est is None:
        row.update(pred_class=-1, correct=False)
        return row
    row["pred_class"] = est.class_index
    row["correct"] = est.class_index == gt.class_index
    row["class_prob_true"] = float(est.class_probs[gt.class_index])
    truth = truth_shape(gt.key, resolution, dataset, cache_root)
    if scores_pose:
        row.update(score_pose(est, gt, truth, view.K))
        row.update(viewpoints(est, gt))
    row.update(score_shape(est, gt, truth))
    return row
