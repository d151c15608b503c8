"""The field's own figures of one scored view, beside ours: the BOP 2019 errors (VSD, MSSD,
MSPD; Hodan et al. 2020, ``beo_bench.bop.protocol``) and the NOCS report's 3D box IoU (Wang
et al. 2019, ``beo_bench.bop.nocs``).

A view row of a pose suite gets, besides the pose metrics of :mod:`.scoring`:

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

The summary turns them into the average recalls (``tally.estimate_values``): one estimate
per target, so the matching of BOP's ``eval_calc_scores`` is the identity here (an
estimate per object, nothing to rank). ``beo-bench score`` matches a results file's
estimates as BOP does (:mod:`.bopscore`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench import metrics
from beo_bench.bop import nocs, protocol
from beo_bench.bop.render import ModelRenderer
from beo_bench.objects import instance_from_key
from beo_bench.types import Estimate, GroundTruth, View

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset

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
def bop_model(key: str, dataset: Dataset | None = None) -> BopModel:
    """The BOP model of instance ``key`` (kept per process, as ``scoring.truth_shape``)."""
    from scipy.spatial.distance import pdist

    mesh = instance_from_key(key, dataset).mesh
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
    est: Estimate | None, gt: GroundTruth, view: View, dataset: Dataset | None = None
) -> dict[str, Any]:
    """The BOP fields of one view (:data:`BOP_FIELDS`) and NOCS's ``iou3d`` for ``est``
    (None: the backend failed; only the diameter and the visible fraction, which a
    failure's row needs to count as a target or not)."""
    model = bop_model(gt.key, dataset)
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
    d_est = model.renderer.depth(R, t, K, w, h)
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


def recall_values(rows: list[dict[str, Any]], image_width: int) -> dict[str, np.ndarray]:
    """Per view, its share of BOP's average recalls (``ar_vsd``, ``ar_mssd``, ``ar_mspd``
    and their mean ``ar_bop``) and NOCS's box-IoU hits (``iou3d_25``/``50``/``75``): with
    one estimate per target, a recall at one threshold is the mean over targets of "its
    error is below the threshold", so the average recall is the mean over targets of each
    one's hit rate over the thresholds (BOP's ``eval_bop19_pose``: VSD over every
    (tau, threshold), MSSD over fractions of the diameter, MSPD over pixels scaled by
    ``image_width / 640``). A failed view is a miss (0); a view below ``visib_gt_min`` is
    no target (NaN: left out of the means, as BOP leaves it out of the denominator)."""
    n = len(rows)
    vsd_th = np.asarray(protocol.VSD_THRESHOLDS)
    mssd_th = np.asarray(protocol.MSSD_THRESHOLDS)
    mspd_th = np.asarray(protocol.MSPD_THRESHOLDS_PX) * (image_width / 640.0)
    out = {k: np.zeros(n) for k in ("ar_vsd", "ar_mssd", "ar_mspd")}
    ious = {f"iou3d_{round(100 * t)}": np.zeros(n) for t in nocs.NOCS_IOU_THRESHOLDS}
    for i, r in enumerate(rows):
        if r.get("bop_visib_fract", 1.0) < protocol.VISIB_GT_MIN:
            for v in (*out.values(), *ious.values()):
                v[i] = np.nan
            continue
        shares = r.get("bop_recall")
        if shares is not None:  # matched as BOP matches several estimates (bopscore)
            for k in ("vsd", "mssd", "mspd"):
                out[f"ar_{k}"][i] = float(shares[k])
        elif r.get("failure") or r.get("bop_vsd") is None:
            continue  # not found: a miss at every threshold
        else:
            vsd = np.asarray(r["bop_vsd"], dtype=np.float64)
            out["ar_vsd"][i] = np.mean(vsd[:, None] < vsd_th[None, :])
            diam = float(r["bop_diameter_mm"])
            out["ar_mssd"][i] = np.mean(float(r["bop_mssd_mm"]) < mssd_th * diam)
            px = r.get("bop_mspd_px")
            out["ar_mspd"][i] = 0.0 if px is None else np.mean(float(px) < mspd_th)
        iou = r.get("iou3d")
        for t, v in zip(nocs.NOCS_IOU_THRESHOLDS, ious.values(), strict=True):
            # NOCS's compute_3d_matches: iou > threshold, strictly, in float32
            v[i] = float(iou is not None and np.float32(iou) > np.float32(t))
    out["ar_bop"] = (out["ar_vsd"] + out["ar_mssd"] + out["ar_mspd"]) / 3.0
    return {**out, **ious}
