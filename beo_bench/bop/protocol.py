"""The BOP 2019 evaluation protocol: VSD, the thresholds of correctness, the greedy matching of
estimates to ground-truth instances and the average recalls.

Written from the definitions of the BOP toolkit (``scripts/eval_bop19_pose.py`` for the
parameters, ``bop_toolkit_lib/pose_error.py:vsd``, ``visibility.py``,
``misc.depth_im_to_dist_im_fast``, ``scripts/eval_calc_errors.py`` for which estimates get
errors, ``pose_matching.py:match_poses`` / ``match_poses_scene`` for the matching,
``score.py:calc_localization_scores`` for the recall) and of the papers: Hodaň et al., "BOP:
Benchmark for 6D Object Pose Estimation", ECCV 2018 (VSD, the visibility masks); Hodaň et al.,
"BOP Challenge 2020 on 6D Object Localization", ECCVW 2020 (the 2019/2020 protocol: AR_VSD,
AR_MSSD, AR_MSPD and their mean AR). MSSD and MSPD themselves are
:func:`beo_bench.metrics.mssd` / :func:`beo_bench.metrics.mspd`.

Units: VSD takes depth images, ``delta`` and the diameter in one length unit (the toolkit's is
mm, so ``delta`` is :data:`VSD_DELTA_MM`; in metres pass ``VSD_DELTA_MM / 1000``); its ``taus``
are fractions of the diameter, so the errors are unitless. MSSD and MSPD errors are brought to
the thresholds' scale as the toolkit's ``eval_calc_scores.py`` does, by
:func:`normalize_mssd` (divide by the diameter) and :func:`normalize_mspd` (times
``640 / image width``).

How the scoring is shaped: the errors of each estimate are computed by the caller (they need
renderings and models), one (E,) vector per ground-truth instance (E = 1 for MSSD / MSPD,
``len(taus)`` for VSD). :func:`match_and_recall` takes a BOP results file's estimates
(several per image and object, with scores) and matches them as the toolkit does;
:func:`recalls_single` is the shortcut for one estimate per target. Both return
:class:`Recalls` (counts, so runs can be pooled with :meth:`Recalls.pooled`), and
:func:`average_recalls` turns the three into :class:`BopScores`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from beo_bench.metrics import MAX_SYM_DISC_STEP

__all__ = [
    "MAX_SYM_DISC_STEP",
    "MSPD_REFERENCE_WIDTH",
    "MSPD_THRESHOLDS_PX",
    "MSSD_THRESHOLDS",
    "VISIB_GT_MIN",
    "VSD_DELTA_MM",
    "VSD_TAUS",
    "VSD_THRESHOLDS",
    "BopScores",
    "EstimateErrors",
    "GtInstance",
    "Recalls",
    "average_recalls",
    "distance_image",
    "match_and_recall",
    "normalize_mspd",
    "normalize_mssd",
    "recalls_single",
    "vsd_errors",
]

# The toolkit builds these lists with ``np.arange(0.05, 0.51, 0.05)`` / ``np.arange(5, 51, 5)``
# (``eval_bop19_pose.py``, ``p["errors"]``); the same expressions give bit-identical values
# (e.g. 0.15000000000000002), so a threshold tie is decided exactly as there.
VSD_DELTA_MM = 15.0
"""VSD's visibility tolerance delta for every BOP 2019 dataset but ITODD (5 mm), in mm."""
VSD_TAUS: tuple[float, ...] = tuple(float(x) for x in np.arange(0.05, 0.51, 0.05))
"""VSD's misalignment tolerances tau, fractions of the object diameter
(``vsd_normalized_by_diameter=True``): 0.05, 0.10, ..., 0.50."""
VSD_THRESHOLDS: tuple[float, ...] = tuple(float(x) for x in np.arange(0.05, 0.51, 0.05))
"""Thresholds of correctness on the VSD error (unitless): 0.05, 0.10, ..., 0.50."""
MSSD_THRESHOLDS: tuple[float, ...] = tuple(float(x) for x in np.arange(0.05, 0.51, 0.05))
"""Thresholds on the MSSD error as a fraction of the object diameter (:func:`normalize_mssd`):
0.05, 0.10, ..., 0.50."""
MSPD_THRESHOLDS_PX: tuple[float, ...] = tuple(float(x) for x in np.arange(5, 51, 5))
"""Thresholds on the MSPD error in pixels of a 640-pixel-wide image (:func:`normalize_mspd`
scales the error by ``640 / width``, i.e. each threshold by ``width / 640``): 5, 10, ..., 50."""
MSPD_REFERENCE_WIDTH = 640.0
"""The image width :data:`MSPD_THRESHOLDS_PX` are stated for."""
VISIB_GT_MIN = 0.1
"""A ground-truth instance visible in less than this fraction of its silhouette is no target
(BOP 2019's ``visib_gt_min``; ``visib_fract`` of ``scene_gt_info.json``)."""


# --------------------------------------------------------------------------- validation


def _finite_positive(x: float, name: str) -> float:
    v = float(x)
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a finite positive number, got {x!r}")
    return v


def _intrinsics(K: ArrayLike) -> NDArray[np.float64]:
    Km = np.asarray(K, dtype=np.float64)
    if Km.shape != (3, 3) or not np.isfinite(Km).all() or Km[0, 0] == 0 or Km[1, 1] == 0:
        raise ValueError(
            f"K must be a finite (3, 3) intrinsics matrix with fx, fy != 0, got {Km.tolist()}"
        )
    return Km


def _depth(depth: ArrayLike, name: str) -> NDArray[np.float64]:
    d = np.asarray(depth, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"{name} must be a 2-D (H, W) depth image, got shape {d.shape}")
    if not np.isfinite(d).all() or (d < 0).any():
        raise ValueError(f"{name} must be finite and >= 0 (0 where there is no depth)")
    return d


def _thresholds(thresholds: ArrayLike) -> NDArray[np.float64]:
    t = np.atleast_1d(np.asarray(thresholds, dtype=np.float64))
    if t.ndim != 1 or t.size == 0 or np.isnan(t).any():
        raise ValueError(f"thresholds must be a non-empty 1-D sequence of numbers, got {t.shape}")
    return t


def _no_nan(errors: NDArray[np.float64], name: str) -> None:
    if np.isnan(errors).any():
        raise ValueError(f"{name} must not be NaN (use inf for an estimate that is missing)")


# --------------------------------------------------------------------------- errors


def distance_image(depth: ArrayLike, K: ArrayLike) -> NDArray[np.float64]:
    """The distance of each pixel's 3-D point from the camera centre, from its depth (z).

    VSD compares distances, not depths, so that its tolerances mean the same everywhere in the
    image (BOP ``misc.depth_im_to_dist_im_fast``). Pixel ``(u, v)`` (column, row; centres at
    integer coordinates) with depth ``z`` is the point ``z ((u - cx) / fx, (v - cy) / fy, 1)``;
    depth 0 (no point) stays 0. Evaluated in the toolkit's order of operations, so the values
    are bit-identical to its.
    """
    d = _depth(depth, "depth")
    Km = _intrinsics(K)
    h, w = d.shape
    px = (np.arange(w, dtype=np.float64) - Km[0, 2]) / Km[0, 0]
    py = (np.arange(h, dtype=np.float64) - Km[1, 2]) / Km[1, 1]
    result: NDArray[np.float64] = np.sqrt((px[None, :] * d) ** 2 + (py[:, None] * d) ** 2 + d**2)
    return result


def _visible(d_test: NDArray[np.float64], d_model: NDArray[np.float64], delta: float) -> NDArray:
    """The bop19 visibility mask (``visibility._estimate_visib_mask``, ``visib_mode="bop19"``):
    where the model is rendered and not more than ``delta`` behind the test surface, or where
    the test image has no depth (shiny or dark surfaces: missing depth counts as visible). The
    difference is taken in float32, as the toolkit does."""
    diff = d_model.astype(np.float32) - d_test.astype(np.float32)
    return ((diff <= delta) | (d_test == 0)) & (d_model > 0)


def vsd_errors(
    depth_test: ArrayLike,
    depth_est: ArrayLike,
    depth_gt: ArrayLike,
    K: ArrayLike,
    delta: float,
    taus: ArrayLike,
    diameter: float,
) -> NDArray[np.float64]:
    """Visible Surface Discrepancy with the 'step' cost, one error per ``tau`` (BOP
    ``pose_error.vsd``, ``cost_type="step"``, ``normalized_by_diameter=True``, visibility
    ``"bop19"``; Hodaň et al. ECCV 2018, eq. for ``e_VSD``).

    ``depth_test`` is the test image's depth; ``depth_est`` / ``depth_gt`` the model rendered
    at the estimated / true pose (:class:`beo_bench.bop.render.ModelRenderer`), 0 where the
    model is not; all (H, W) z-depths in the unit of ``delta`` and ``diameter`` (mm with
    :data:`VSD_DELTA_MM`; metres work as well with ``delta`` in metres). ``taus`` are fractions
    of ``diameter``. On distance images (:func:`distance_image`): ``V_gt`` is where the true
    model is visible in the test image, ``V_est`` where the estimated one is, plus wherever it
    covers ``V_gt`` (``visibility.estimate_visib_mask_est``: the estimate is not excused for
    hiding behind the object itself). Then, over the union ``U`` of the two masks,
    ``e = (#{p in V_gt & V_est: |dist_gt - dist_est| / diameter >= tau} + #(U - V_gt & V_est))
    / #U``, and 1 for every tau when ``U`` is empty. Returns (len(taus),) errors in [0, 1].
    """
    d_test, d_est, d_gt = (
        _depth(depth_test, "depth_test"),
        _depth(depth_est, "depth_est"),
        _depth(depth_gt, "depth_gt"),
    )
    if not d_test.shape == d_est.shape == d_gt.shape:
        raise ValueError(
            f"depth_test, depth_est and depth_gt must have one shape, got "
            f"{d_test.shape}, {d_est.shape}, {d_gt.shape}"
        )
    Km = _intrinsics(K)
    delta = float(delta)  # a Python float: compared in float32 with the float32 differences
    if not (np.isfinite(delta) and delta >= 0):
        raise ValueError(f"delta must be a finite number >= 0, got {delta!r}")
    diam = _finite_positive(diameter, "diameter")
    tau = np.atleast_1d(np.asarray(taus, dtype=np.float64))
    if tau.ndim != 1 or tau.size == 0 or not np.isfinite(tau).all() or (tau <= 0).any():
        raise ValueError(
            f"taus must be a non-empty 1-D sequence of positive numbers, got {tau.tolist()}"
        )
    dist_test, dist_est, dist_gt = (distance_image(d, Km) for d in (d_test, d_est, d_gt))
    visib_gt = _visible(dist_test, dist_gt, delta)
    visib_est = _visible(dist_test, dist_est, delta) | (visib_gt & (dist_est > 0))
    inter = visib_gt & visib_est
    union = int(np.count_nonzero(visib_gt | visib_est))
    if union == 0:
        return np.ones(tau.size)
    comp = union - int(np.count_nonzero(inter))
    dists = np.abs(dist_gt[inter] - dist_est[inter]) / diam
    costs = np.count_nonzero(dists[None, :] >= tau[:, None], axis=1)
    result: NDArray[np.float64] = (costs + comp) / float(union)
    return result


def normalize_mssd(errors: ArrayLike, diameter: float) -> NDArray[np.float64]:
    """MSSD errors as fractions of the object diameter, the scale of :data:`MSSD_THRESHOLDS`
    (``eval_calc_scores.py``: ``normalized_by_diameter`` holds ``"mssd"``)."""
    return np.asarray(errors, dtype=np.float64) / _finite_positive(diameter, "diameter")


def normalize_mspd(errors: ArrayLike, image_width: float) -> NDArray[np.float64]:
    """MSPD errors (pixels) brought to a 640-pixel-wide image, the scale of
    :data:`MSPD_THRESHOLDS_PX` (``eval_calc_scores.py``: ``normalized_by_im_width`` holds
    ``"mspd"``, the error times ``640 / width``; equivalently each threshold times
    ``width / 640``)."""
    factor = MSPD_REFERENCE_WIDTH / _finite_positive(image_width, "image_width")
    return factor * np.asarray(errors, dtype=np.float64)


# --------------------------------------------------------------------------- recalls


@dataclass(frozen=True, eq=False)
class Recalls:
    """How many targets were found at each error column and threshold of correctness.

    ``found`` is (E, T): E error columns (one per VSD tau; 1 for MSSD / MSPD), T thresholds.
    Counts rather than rates so that scenes, datasets or runs pool by adding them
    (:meth:`pooled`), as the toolkit's recall pools all targets of a dataset
    (``score.calc_localization_scores``: ``recall = tp_count / targets_count``).
    """

    found: NDArray[np.int64]
    targets: int
    thresholds: tuple[float, ...]

    def __post_init__(self) -> None:
        if np.ndim(self.found) != 2 or np.shape(self.found)[1] != len(self.thresholds):
            raise ValueError(
                f"found must be (E, {len(self.thresholds)}) for {len(self.thresholds)} "
                f"thresholds, got shape {np.shape(self.found)}"
            )
        if self.targets < 0 or (np.asarray(self.found) > self.targets).any():
            raise ValueError(f"found must be within 0..targets ({self.targets})")

    @property
    def recall(self) -> NDArray[np.float64]:
        """(E, T) fraction of targets found; 0 where there are no targets (as the toolkit's
        ``score.calc_recall``)."""
        if self.targets == 0:
            return np.zeros(np.shape(self.found))
        result: NDArray[np.float64] = np.asarray(self.found, dtype=np.float64) / self.targets
        return result

    @property
    def average(self) -> float:
        """The mean recall over all (column, threshold) pairs: AR_VSD for VSD (over the 10 x
        10 (tau, threshold) pairs), AR_MSSD / AR_MSPD for the others."""
        return float(np.mean(self.recall))

    @staticmethod
    def pooled(parts: Sequence[Recalls]) -> Recalls:
        """The recalls of the union of the targets of ``parts`` (same shapes and thresholds)."""
        if not parts:
            raise ValueError("pooled needs at least one Recalls")
        first = parts[0]
        for p in parts[1:]:
            if p.thresholds != first.thresholds or np.shape(p.found) != np.shape(first.found):
                raise ValueError("pooled Recalls must share their thresholds and shape")
        found = np.sum([np.asarray(p.found) for p in parts], axis=0).astype(np.int64)
        return Recalls(found, sum(p.targets for p in parts), first.thresholds)


def recalls_single(errors: ArrayLike, thresholds: ArrayLike) -> Recalls:
    """Recalls when each target has exactly one estimate (this benchmark's own runs).

    ``errors`` is (n_targets,) or (n_targets, E) (E: one column per VSD tau), already on the
    thresholds' scale (:func:`normalize_mssd`, :func:`normalize_mspd`), ``inf`` for a target
    whose estimate is missing (the backend failed: it counts as not found). With one estimate
    and one instance the toolkit's greedy matching reduces to the test ``error < threshold``
    (strict, as ``pose_matching.match_poses``). NaN is refused (it would hide a failure)."""
    e = np.asarray(errors, dtype=np.float64)
    if e.ndim == 1:
        e = e[:, None]
    if e.ndim != 2:
        raise ValueError(f"errors must be (n_targets,) or (n_targets, E), got shape {e.shape}")
    _no_nan(e, "errors")
    t = _thresholds(thresholds)
    found = np.count_nonzero(e.T[:, :, None] < t[None, None, :], axis=1).astype(np.int64)
    return Recalls(found, int(e.shape[0]), tuple(float(x) for x in t))


@dataclass(frozen=True)
class GtInstance:
    """One ground-truth object instance in one image (an entry of BOP's ``scene_gt.json`` with
    its ``scene_gt_info.json`` visibility)."""

    scene_id: int
    im_id: int
    gt_id: int
    """Its index in the image's ``scene_gt`` list; the keys of :attr:`EstimateErrors.errors`."""
    obj_id: int
    visib_fract: float
    """Fraction of its silhouette that is visible (``scene_gt_info``'s ``visib_fract``)."""


@dataclass(frozen=True, eq=False)
class EstimateErrors:
    """One pose estimate (a row of a BOP results CSV) with its errors.

    ``errors`` maps the ``gt_id`` of every ground-truth instance of ``obj_id`` in the image to
    the (E,) errors of the estimate against it, on the thresholds' scale (``eval_calc_errors.py``
    computes them against all instances of the object, visible or not); a ``gt_id`` left out
    cannot be matched (as an infinite error).
    """

    scene_id: int
    im_id: int
    obj_id: int
    score: float
    errors: Mapping[int, ArrayLike] = field(default_factory=dict)


def match_and_recall(
    gts: Sequence[GtInstance],
    estimates: Sequence[EstimateErrors],
    thresholds: ArrayLike,
    visib_gt_min: float = VISIB_GT_MIN,
    inst_counts: Mapping[tuple[int, int, int], int] | None = None,
    columns: int | None = None,
) -> Recalls:
    """Match a results file's estimates to the ground truth and count the targets found.

    As the BOP 2019 evaluation (``n_top = -1``, localization): the targets are the instances
    with ``visib_fract >= visib_gt_min``; per image and object, ``inst_count`` is how many
    (``inst_counts[(scene_id, im_id, obj_id)]`` when given, as the targets file
    ``test_targets_bop19.json`` states it, whose objects are then the only targets); only the
    ``inst_count`` estimates with the highest scores are evaluated (``eval_calc_errors.py``),
    and estimates of an object that is no target of its image (or of an image without
    instances in ``gts``: the toolkit evaluates the targets' images only) are ignored. Then,
    separately for each error column and threshold (``pose_matching.match_poses``), the
    estimates are taken in order of decreasing score (ties: the given order) and each is
    matched to the not yet matched target of its object with the smallest error, if that
    error is strictly below the threshold (ties: the lowest ``gt_id``). Instances below
    ``visib_gt_min`` can never be matched (``gt_valid_mask``): an estimate close to one of
    them stays free to match a target or nothing, and they are not in the denominator. The
    localization task has no false positives: an unmatched estimate costs nothing but the
    target it missed.

    ``gts`` lists every ground-truth instance of the evaluated images (one per
    ``(scene_id, im_id, gt_id)``); ``thresholds`` are on the errors' scale; ``columns`` is E,
    the length of every error vector (default: taken from the errors, 1 when no estimate has
    any). Returns :class:`Recalls` with ``targets`` the number of targets.
    """
    t = _thresholds(thresholds)
    if columns is not None and columns < 1:
        raise ValueError(f"columns must be a positive number of error columns, got {columns}")
    n_cols: int | None = columns
    by_image: dict[tuple[int, int], dict[int, GtInstance]] = {}
    for g in gts:
        image = by_image.setdefault((g.scene_id, g.im_id), {})
        if g.gt_id in image:
            raise ValueError(f"gt_id {g.gt_id} appears twice in scene {g.scene_id} im {g.im_id}")
        if not np.isfinite(g.visib_fract):
            raise ValueError(f"visib_fract of {g} must be a finite number")
        image[g.gt_id] = g
    # (scene, im, obj) -> gt_ids of all its instances (ascending) and which are targets.
    groups: dict[tuple[int, int, int], list[GtInstance]] = {}
    for (scene_id, im_id), image in by_image.items():
        for gt_id in sorted(image):
            g = image[gt_id]
            groups.setdefault((scene_id, im_id, g.obj_id), []).append(g)
    valid = {
        key: np.array([g.visib_fract >= visib_gt_min for g in inst], dtype=bool)
        for key, inst in groups.items()
    }
    if inst_counts is not None:
        for key in inst_counts:
            if key not in groups:
                raise ValueError(f"inst_counts names {key} (scene, im, obj) with no gt instance")
        valid = {k: v & (k in inst_counts) for k, v in valid.items()}
        counts = {k: int(inst_counts.get(k, 0)) for k in groups}
    else:
        counts = {k: int(v.sum()) for k, v in valid.items()}

    per_group: dict[tuple[int, int, int], list[EstimateErrors]] = {}
    for est in estimates:
        key = (est.scene_id, est.im_id, est.obj_id)
        if key not in groups:
            continue  # no instance of the object in an evaluated image: ignored as by the toolkit
        if not np.isfinite(est.score):
            raise ValueError(f"score of the estimate for {key} must be finite, got {est.score}")
        per_group.setdefault(key, []).append(est)

    found: NDArray[np.int64] | None = None
    for key, ests in per_group.items():
        if counts[key] <= 0:
            continue
        ranked = sorted(ests, key=lambda e: -e.score)[: counts[key]]  # stable: ties keep order
        gt_ids = [g.gt_id for g in groups[key]]
        column = {gt_id: j for j, gt_id in enumerate(gt_ids)}
        errs = None
        for i, est in enumerate(ranked):
            for gt_id, value in est.errors.items():
                if gt_id not in column:
                    raise ValueError(
                        f"an estimate for (scene, im, obj) {key} has errors for gt_id {gt_id}, "
                        f"which is no instance of obj {key[2]} in that image"
                    )
                v = np.atleast_1d(np.asarray(value, dtype=np.float64))
                if v.ndim != 1 or (n_cols is not None and v.size != n_cols):
                    raise ValueError(
                        f"every error vector must be 1-D of one length ({n_cols}), got {v.shape}"
                    )
                _no_nan(v, f"errors of the estimate for {key}")
                n_cols = v.size
                if errs is None:
                    errs = np.full((len(ranked), len(gt_ids), n_cols), np.inf)
                errs[i, column[gt_id]] = v
        if errs is None:
            continue  # no errors at all: nothing can match
        if found is None:
            found = np.zeros((errs.shape[2], t.size), dtype=np.int64)
        found += _greedy_matches(errs, valid[key], t)
    targets = sum(int(v.sum()) for v in valid.values())
    if found is None:
        found = np.zeros((1 if n_cols is None else n_cols, t.size), dtype=np.int64)
    return Recalls(found, targets, tuple(float(x) for x in t))


def _greedy_matches(
    errs: NDArray[np.float64], valid: NDArray[np.bool_], thresholds: NDArray[np.float64]
) -> NDArray[np.int64]:
    """(E, T) matches in one image and object: ``errs`` is (n_est, n_gt, E) with the
    estimates in decreasing score, ``valid`` (n_gt,) the matchable instances."""
    n_est, _, n_cols = errs.shape
    if n_est == 1:  # one estimate: found wherever a target is below the threshold
        below = valid[None, :, None] & (errs[0].T[:, :, None] < thresholds[None, None, :])
        return below.any(axis=1).astype(np.int64)
    found = np.zeros((n_cols, thresholds.size), dtype=np.int64)
    for c in range(n_cols):
        for k, th in enumerate(thresholds):
            free = valid.copy()
            for i in range(n_est):
                cand = np.where(free & (errs[i, :, c] < th), errs[i, :, c], np.inf)
                j = int(np.argmin(cand))
                if np.isfinite(cand[j]):
                    free[j] = False
                    found[c, k] += 1
    return found


# --------------------------------------------------------------------------- scores


@dataclass(frozen=True)
class BopScores:
    """The BOP 2019/2020 scores of a method on a dataset (``eval_bop19_pose.py``'s
    ``bop19_average_recall_{vsd,mssd,mspd}`` and ``bop19_average_recall``)."""

    ar_vsd: float
    """Mean recall over the (tau, threshold) pairs of VSD."""
    ar_mssd: float
    """Mean recall over the MSSD thresholds."""
    ar_mspd: float
    """Mean recall over the MSPD thresholds."""
    ar: float
    """The mean of the three."""


def _average(r: Recalls | ArrayLike, name: str) -> float:
    if isinstance(r, Recalls):
        return r.average
    a = np.asarray(r, dtype=np.float64)
    if a.size == 0 or np.isnan(a).any() or (a < 0).any() or (a > 1).any():
        raise ValueError(f"{name} must be a non-empty array of recalls in [0, 1]")
    return float(np.mean(a))


def average_recalls(
    vsd: Recalls | ArrayLike, mssd: Recalls | ArrayLike, mspd: Recalls | ArrayLike
) -> BopScores:
    """AR_VSD, AR_MSSD, AR_MSPD and AR (their mean) from the three errors' recalls
    (:class:`Recalls`, or arrays of recall rates, each averaged over all its entries), as
    ``eval_bop19_pose.py`` averages the recalls it gets from ``eval_calc_scores.py``."""
    a_vsd, a_mssd, a_mspd = _average(vsd, "vsd"), _average(mssd, "mssd"), _average(mspd, "mspd")
    return BopScores(a_vsd, a_mssd, a_mspd, float(np.mean([a_vsd, a_mssd, a_mspd])))
