"""The BOP 2019 protocol (``beo_bench.bop.protocol``) and the depth renderings VSD compares
(``beo_bench.bop.render``), against cases worked out by hand from the BOP toolkit's definitions
(``pose_error.vsd``, ``visibility.py``, ``misc.depth_im_to_dist_im_fast``,
``pose_matching.match_poses``, ``score.calc_localization_scores``, ``eval_bop19_pose.py``)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
import trimesh

from beo_bench import metrics as M
from beo_bench.bop import protocol as P
from beo_bench.bop.render import ModelRenderer, render_depth
from beo_bench.geometry import axis_angle, cyclic_z

F = 500.0


def _K(w: int, h: int, f: float = F) -> np.ndarray:
    return np.array([[f, 0.0, (w - 1) / 2], [0.0, f, (h - 1) / 2], [0.0, 0.0, 1.0]])


def _box(extents: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    m = trimesh.creation.box(extents=extents)
    return np.asarray(m.vertices), np.asarray(m.faces)


# -- constants ----------------------------------------------------------------------------------
def test_constants_are_the_toolkits_lists() -> None:
    fractions = list(np.arange(0.05, 0.51, 0.05))  # eval_bop19_pose.py, bit for bit
    assert list(P.VSD_TAUS) == fractions
    assert list(P.VSD_THRESHOLDS) == fractions
    assert list(P.MSSD_THRESHOLDS) == fractions
    assert list(P.MSPD_THRESHOLDS_PX) == [5.0 * k for k in range(1, 11)]
    assert len(P.VSD_TAUS) == 10 and P.VSD_TAUS[2] == 0.15000000000000002
    assert np.allclose(P.VSD_TAUS, 0.05 * np.arange(1, 11), atol=1e-15)
    assert (P.VSD_DELTA_MM, P.VISIB_GT_MIN, P.MAX_SYM_DISC_STEP) == (15.0, 0.1, 0.01)


# -- distance image -----------------------------------------------------------------------------
def test_distance_image_by_hand() -> None:
    K = np.array([[2.0, 0.0, 1.0], [0.0, 4.0, 0.0], [0.0, 0.0, 1.0]])
    depth = np.array([[0.0, 1.0, 2.0], [5.0, 0.0, 3.0]])
    d = P.distance_image(depth, K)
    # pixel (u, v) = (2, 1): z (1/2, 1/4, 1); (0, 1): z (-1/2, 1/4, 1); (1, 0): on the axis
    assert d[1, 2] == pytest.approx(3.0 * np.sqrt(1 + 0.25 + 0.0625), rel=1e-15)
    assert d[1, 0] == pytest.approx(5.0 * np.sqrt(1 + 0.25 + 0.0625), rel=1e-15)
    assert d[0, 1] == 1.0
    assert d[0, 2] == pytest.approx(2.0 * np.sqrt(1 + 0.25), rel=1e-15)
    assert d[0, 0] == 0.0 and d[1, 1] == 0.0


@pytest.mark.parametrize(
    ("depth", "K", "match"),
    [
        (np.ones(3), np.eye(3), "2-D"),
        (-np.ones((2, 2)), np.eye(3), ">= 0"),
        (np.full((2, 2), np.nan), np.eye(3), "finite"),
        (np.ones((2, 2)), np.zeros((3, 3)), "fx, fy"),
    ],
)
def test_distance_image_refuses_bad_input(depth: np.ndarray, K: np.ndarray, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        P.distance_image(depth, K)


# -- VSD on a constructed case ------------------------------------------------------------------
def _from_distances(dist: np.ndarray, K: np.ndarray) -> np.ndarray:
    """The depth image whose distance image is ``dist`` (so the case reads in distances)."""
    return dist / P.distance_image(np.ones_like(dist), K)


def test_vsd_by_hand() -> None:
    """Eight pixels (distances in mm; delta 15, diameter 100; taus 0.05, 0.1, 0.2):

    ====  ====  ====  ====  =====================================================
    px    gt    est   test  masks
    ====  ====  ====  ====  =====================================================
    0     500   500   500   both visible, |diff| 0
    1     500   508   500   both visible (8 <= delta), |diff| / diameter 0.08
    2     500   530   500   est 30 behind the test surface, but it covers V_gt: both, 0.30
    3     500   0     500   gt only
    4     0     500   500   est only
    5     0     530   500   est occluded (30 > delta): neither
    6     600   600   500   both occluded by a surface 100 in front: neither
    7     600   612   0     no test depth: visible (bop19), both, 0.12
    ====  ====  ====  ====  =====================================================

    union 6 (0, 1, 2, 3, 4, 7), intersection 4, so 2 pixels of complement; costs
    (|diff| >= tau): tau 0.05 -> 3 (1, 2, 7), 0.1 -> 2 (2, 7), 0.2 -> 1 (2);
    errors (cost + 2) / 6.
    """
    K = np.array([[100.0, 0.0, 1.5], [0.0, 100.0, 0.5], [0.0, 0.0, 1.0]])
    gt = np.array([[500, 500, 500, 500], [0, 0, 600, 600]], dtype=float)
    est = np.array([[500, 508, 530, 0], [500, 530, 600, 612]], dtype=float)
    test = np.array([[500, 500, 500, 500], [500, 500, 500, 0]], dtype=float)
    d_gt, d_est, d_test = (_from_distances(x, K) for x in (gt, est, test))
    e = P.vsd_errors(d_test, d_est, d_gt, K, 15.0, [0.05, 0.1, 0.2], 100.0)
    assert e == pytest.approx([5 / 6, 4 / 6, 3 / 6], abs=1e-12)
    # the same case in metres, delta and diameter scaled alike: the same errors
    e_m = P.vsd_errors(d_test / 1000, d_est / 1000, d_gt / 1000, K, 0.015, [0.05, 0.1, 0.2], 0.1)
    assert e_m == pytest.approx(e, abs=1e-12)


def test_vsd_step_cost_at_tau() -> None:
    """The step cost is 1 from tau on (``dists >= tau``): one pixel on the optical axis (its
    distance is its depth), 10 apart with diameter 100: error 1 at tau 0.1, 0 at 0.11."""
    K = np.array([[100.0, 0.0, 0.0], [0.0, 100.0, 0.0], [0.0, 0.0, 1.0]])
    gt, est = np.array([[500.0]]), np.array([[510.0]])
    assert list(P.vsd_errors(gt, est, gt, K, 15.0, [0.1, 0.11], 100.0)) == [1.0, 0.0]


def test_vsd_empty_union_is_one() -> None:
    K = _K(4, 3)
    nothing = np.zeros((3, 4))
    assert list(P.vsd_errors(nothing, nothing, nothing, K, 15.0, P.VSD_TAUS, 100.0)) == [1.0] * 10
    # the true object fully hidden behind a nearer surface and no estimate: still no union
    gt = np.full((3, 4), 800.0)
    test = np.full((3, 4), 500.0)
    assert list(P.vsd_errors(test, nothing, gt, K, 15.0, [0.1, 0.3], 100.0)) == [1.0, 1.0]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"depth_est": np.zeros((2, 3))}, "one shape"),
        ({"diameter": 0.0}, "diameter"),
        ({"delta": -1.0}, "delta"),
        ({"taus": []}, "taus"),
        ({"taus": [0.0, 0.1]}, "taus"),
    ],
)
def test_vsd_refuses_bad_input(kwargs: dict, match: str) -> None:
    args = {
        "depth_test": np.ones((3, 3)),
        "depth_est": np.ones((3, 3)),
        "depth_gt": np.ones((3, 3)),
        "K": _K(3, 3),
        "delta": 15.0,
        "taus": [0.1],
        "diameter": 100.0,
    } | kwargs
    with pytest.raises(ValueError, match=match):
        P.vsd_errors(**args)


# -- the whole pipeline: a perfect estimate and known perturbations -----------------------------
EXTENTS = (0.1, 0.1, 0.1)
DIAMETER = float(np.linalg.norm(EXTENTS))
R_GT, T_GT = np.eye(3), np.array([0.0, 0.0, 1.0])


def _scores_of(R_est: np.ndarray, t_est: np.ndarray, width: int = 640, f: float = F) -> tuple:
    v, faces = _box(EXTENTS)
    K = _K(width, 480, f)
    ren = ModelRenderer(v, faces)
    d_gt = ren.depth(R_GT, T_GT, K, width, 480)
    d_est = ren.depth(R_est, t_est, K, width, 480)
    vsd = P.vsd_errors(d_gt, d_est, d_gt, K, P.VSD_DELTA_MM / 1000, P.VSD_TAUS, DIAMETER)
    mssd = P.normalize_mssd(M.mssd(R_est, t_est, R_GT, T_GT, v), DIAMETER)
    mspd = P.normalize_mspd(M.mspd(R_est, t_est, R_GT, T_GT, K, v), width)
    return vsd, float(mssd), float(mspd), d_gt, d_est


def test_perfect_estimate_scores_one() -> None:
    vsd, mssd, mspd, d_gt, _ = _scores_of(R_GT, T_GT)
    assert (d_gt > 0).sum() > 2000
    assert list(vsd) == [0.0] * 10 and mssd == 0.0 and mspd == 0.0
    scores = P.average_recalls(
        P.recalls_single(vsd[None, :], P.VSD_THRESHOLDS),
        P.recalls_single([mssd], P.MSSD_THRESHOLDS),
        P.recalls_single([mspd], P.MSPD_THRESHOLDS_PX),
    )
    assert scores == P.BopScores(1.0, 1.0, 1.0, 1.0)


def test_depth_shift_scores_the_recalls_by_hand() -> None:
    """The estimate 0.12 diameters farther than the truth, seen face-on: MSSD is exactly 0.12
    diameters (recall 0 at thresholds 0.05 and 0.10, 1 from 0.15); VSD: the estimate's
    silhouette lies inside the truth's and covers it where it is (the bop19 rule), every
    shared pixel differs by 0.12 to 0.1203 diameters (distance, not depth), so tau 0.05 and
    0.10 cost every shared pixel (error 1) and taus from 0.15 cost none (error = the share
    of the truth's silhouette the smaller estimate leaves uncovered: with f = 600 the truth's
    face spans 64 x 64 pixels (half-width 600 * 0.05 / 0.95 = 31.6), the estimate's 62 x 62
    (30.9), an error of 1 - 62^2 / 64^2 = 0.0615, found from threshold 0.1)."""
    shift = 0.12 * DIAMETER
    vsd, mssd, mspd, d_gt, d_est = _scores_of(R_GT, T_GT + np.array([0, 0, shift]), f=600.0)
    n_gt, n_est = int((d_gt > 0).sum()), int((d_est > 0).sum())
    assert ((d_est > 0) <= (d_gt > 0)).all() and n_est < n_gt
    uncovered = (n_gt - n_est) / n_gt
    assert (n_gt, n_est) == (64 * 64, 62 * 62)
    assert vsd == pytest.approx([1.0, 1.0] + [uncovered] * 8, abs=1e-12)
    assert mssd == pytest.approx(0.12, abs=1e-9)
    vsd_recall = P.recalls_single(vsd[None, :], P.VSD_THRESHOLDS).recall
    expected_vsd = np.array([[0.0] * 10] * 2 + [[0.0] + [1.0] * 9] * 8)
    assert np.array_equal(vsd_recall, expected_vsd)
    mssd_recall = P.recalls_single([mssd], P.MSSD_THRESHOLDS).recall[0]
    assert list(mssd_recall) == [0.0, 0.0] + [1.0] * 8
    # MSPD: the near corners (z = 0.95) move most, to 0.05 f (1/0.95 - 1/(0.95 + shift)) sqrt 2
    by_hand = 600 * 0.05 * np.sqrt(2) * (1 / 0.95 - 1 / (0.95 + shift))
    assert mspd == pytest.approx(by_hand, rel=1e-9)
    scores = P.average_recalls(
        P.recalls_single(vsd[None, :], P.VSD_THRESHOLDS),
        P.recalls_single([mssd], P.MSSD_THRESHOLDS),
        P.recalls_single([mspd], P.MSPD_THRESHOLDS_PX),
    )
    ar_vsd = 72 / 100  # 8 taus x 9 thresholds found of the 10 x 10 pairs
    assert scores.ar_vsd == pytest.approx(ar_vsd, abs=1e-15)
    assert (scores.ar_mssd, scores.ar_mspd) == (0.8, 1.0)
    assert scores.ar == pytest.approx((ar_vsd + 0.8 + 1.0) / 3, abs=1e-15)


@pytest.mark.parametrize(("width", "expected"), [(640, [0, 0] + [1] * 8), (1280, [0] + [1] * 9)])
def test_sideways_shift_mspd_recalls(width: int, expected: list[int]) -> None:
    """Moved sideways by 0.0228 m, the near corners (z = 0.95) move 500 * 0.0228 / 0.95 =
    12 px: MSPD 12 in a 640-wide image (found from threshold 15), 6 after scaling a
    1280-wide image's error by 640 / 1280 (found from 10)."""
    v, _ = _box(EXTENTS)
    t_est = T_GT + np.array([0.0228, 0.0, 0.0])
    raw = M.mspd(R_GT, t_est, R_GT, T_GT, _K(width, 480), v)
    assert raw == pytest.approx(12.0, rel=1e-12)
    err = P.normalize_mspd(raw, width)
    assert float(err) == pytest.approx(12.0 * 640 / width, rel=1e-12)
    assert list(P.recalls_single([err], P.MSPD_THRESHOLDS_PX).recall[0]) == expected


def test_rotation_mssd_recalls() -> None:
    """A 90-degree turn about z moves the cube's corners onto each other: MSSD 0 with the 4-fold
    symmetry; without it the corners (0.05, 0.05, z) go to (-0.05, 0.05, z), 0.1 away, i.e.
    0.1 / (0.1 sqrt 3) = 0.577 diameters: beyond every threshold."""
    v, _ = _box(EXTENTS)
    R = axis_angle([0, 0, 1], np.pi / 2)
    plain = P.normalize_mssd(M.mssd(R, T_GT, R_GT, T_GT, v), DIAMETER)
    assert float(plain) == pytest.approx(1 / np.sqrt(3), rel=1e-12)
    sym = P.normalize_mssd(M.mssd(R, T_GT, R_GT, T_GT, v, cyclic_z(4)), DIAMETER)
    r = P.recalls_single([plain, sym], P.MSSD_THRESHOLDS).recall[0]
    assert list(r) == [0.5] * 10


# -- recalls for one estimate per target --------------------------------------------------------
def test_recalls_single_strict_threshold_and_missing() -> None:
    # 0.1 is not below the threshold 0.1 (match_poses: error < threshold); inf: not found
    r = P.recalls_single([0.04, 0.1, np.inf, 0.3], [0.05, 0.1, 0.15, 0.5])
    assert r.targets == 4
    assert r.found.tolist() == [[1, 1, 2, 3]]
    assert list(r.recall[0]) == [0.25, 0.25, 0.5, 0.75]
    assert r.average == pytest.approx(0.4375)


def test_recalls_single_columns_and_pooling() -> None:
    e = np.array([[0.02, 0.2], [0.3, np.inf]])  # two targets, two VSD taus
    r = P.recalls_single(e, [0.1, 0.25, 0.5])
    assert r.found.tolist() == [[1, 1, 2], [0, 1, 1]]
    both = P.Recalls.pooled([r, P.recalls_single(np.zeros((3, 2)), [0.1, 0.25, 0.5])])
    assert both.targets == 5 and both.found.tolist() == [[4, 4, 5], [3, 4, 4]]
    assert P.recalls_single(np.zeros((0, 2)), [0.1]).recall.tolist() == [[0.0], [0.0]]


def test_recalls_refuse_nan_and_bad_shapes() -> None:
    with pytest.raises(ValueError, match="NaN"):
        P.recalls_single([0.1, np.nan], [0.2])
    with pytest.raises(ValueError, match="n_targets"):
        P.recalls_single(np.zeros((2, 2, 2)), [0.2])
    with pytest.raises(ValueError, match="thresholds"):
        P.recalls_single([0.1], [])
    with pytest.raises(ValueError, match="share"):
        P.Recalls.pooled([P.recalls_single([0.1], [0.2]), P.recalls_single([0.1], [0.3])])
    with pytest.raises(ValueError, match="recalls in"):
        P.average_recalls([1.5], [1.0], [1.0])


# -- matching a results file's estimates --------------------------------------------------------
GTS = [
    P.GtInstance(scene_id=1, im_id=3, gt_id=0, obj_id=5, visib_fract=0.9),
    P.GtInstance(scene_id=1, im_id=3, gt_id=1, obj_id=5, visib_fract=0.5),
    P.GtInstance(scene_id=1, im_id=3, gt_id=2, obj_id=5, visib_fract=0.05),  # ignored
    P.GtInstance(scene_id=1, im_id=3, gt_id=3, obj_id=7, visib_fract=0.8),  # never estimated
]


def _est(score: float, errors: dict[int, float], obj_id: int = 5) -> P.EstimateErrors:
    return P.EstimateErrors(1, 3, obj_id, score, {k: [v] for k, v in errors.items()})


# B is listed before A though A scores higher; C is perfect but ranks third of inst_count = 2
A = _est(0.9, {0: 0.30, 1: 0.10, 2: 0.01})
B = _est(0.8, {0: 0.40, 1: 0.20, 2: 0.50})
C = _est(0.1, {0: 0.0, 1: 0.0, 2: 0.0})


def test_matching_greedy_by_score_lowest_error() -> None:
    """Targets: gt 0 and 1 of obj 5 (gt 2 is 5% visible: no target, never matched) and gt 3
    of obj 7: 3 in all. Only the 2 best-scored estimates of obj 5 count (A, B; not C).
    A goes first and takes the unmatched target with its smallest error below the threshold
    (gt 1, 0.10; gt 2's 0.01 does not count); B then gets gt 0 only where 0.40 is below
    the threshold:

    - 0.25: A -> gt 1; B: gt 0 at 0.40 is too far             -> 1 of 3
    - 0.35: A -> gt 1 (not gt 0, 0.30, though it is below);
            B: gt 0 at 0.40 too far                           -> 1 of 3
    - 0.45: A -> gt 1; B -> gt 0                              -> 2 of 3

    (B first would take gt 1 at 0.35 and leave gt 0 to A; matching A to gt 2 would free gt 1
    for B; keeping C would find gt 0 everywhere; counting gt 2 would make 4 targets.)"""
    r = P.match_and_recall(GTS, [B, A, C], [0.25, 0.35, 0.45])
    assert r.targets == 3
    assert r.found.tolist() == [[1, 1, 2]]
    assert r.recall[0] == pytest.approx([1 / 3, 1 / 3, 2 / 3])


def test_matching_single_estimate_near_an_ignored_instance() -> None:
    """One estimate next to a 5%-visible instance (0.01) and 0.3 from the target: the ignored
    instance cannot take it, the target takes it from threshold 0.3 on (strictly above)."""
    gts = [P.GtInstance(0, 0, 0, 1, 0.9), P.GtInstance(0, 0, 1, 1, 0.05)]
    est = P.EstimateErrors(0, 0, 1, 0.5, {0: [0.3], 1: [0.01]})
    r = P.match_and_recall(gts, [est], [0.2, 0.3, 0.4])
    assert (r.targets, r.found.tolist()) == (1, [[0, 0, 1]])


def test_matching_ignores_estimates_of_no_target() -> None:
    """An estimate of an object that is not in the image, or is only there below 10%
    visibility, or of an image not evaluated, changes nothing (eval_calc_errors.py computes
    errors for the targets only)."""
    gts = [*GTS, P.GtInstance(1, 3, 4, obj_id=8, visib_fract=0.02)]
    others = [
        _est(0.99, {}, obj_id=9),
        _est(0.99, {4: 0.0}, obj_id=8),
        P.EstimateErrors(2, 3, 5, 0.99, {0: [0.0]}),  # an image that is not evaluated
    ]
    base = P.match_and_recall(gts, [B, A, C], [0.25, 0.35, 0.45])
    r = P.match_and_recall(gts, [B, A, C, *others], [0.25, 0.35, 0.45])
    assert r.targets == 3 and r.found.tolist() == base.found.tolist() == [[1, 1, 2]]


def test_matching_one_estimate_per_target_equals_recalls_single() -> None:
    gts = [P.GtInstance(0, k, 0, obj_id=1, visib_fract=1.0) for k in range(4)]
    errors = [0.04, 0.12, np.inf, 0.3]
    ests = [P.EstimateErrors(0, k, 1, 1.0, {0: [e]}) for k, e in enumerate(errors[:2])]
    ests.append(P.EstimateErrors(0, 3, 1, 1.0, {0: [errors[3]]}))  # image 2: no estimate
    r = P.match_and_recall(gts, ests, P.MSSD_THRESHOLDS)
    assert r.found.tolist() == P.recalls_single(errors, P.MSSD_THRESHOLDS).found.tolist()


def test_matching_columns_are_matched_separately_and_ties() -> None:
    """Two error columns (VSD taus): each column is its own matching. Equal scores keep the
    given order; equal errors go to the lower gt_id."""
    gts = GTS[:2]
    first = P.EstimateErrors(1, 3, 5, 0.5, {0: [0.1, 0.3], 1: [0.1, 0.1]})
    second = P.EstimateErrors(1, 3, 5, 0.5, {0: [0.1, 0.1], 1: [0.3, 0.3]})
    r = P.match_and_recall(gts, [first, second], [0.2])
    # column 0: first -> gt 0 (tie, lower id), second: gt 1 at 0.3 too far -> 1
    # column 1: first -> gt 1 (0.1 < 0.3), second -> gt 0 (0.1)             -> 2
    assert r.found.tolist() == [[1], [2]]


def test_matching_inst_counts_from_a_targets_file() -> None:
    """inst_counts (test_targets_bop19.json) override how many estimates count and which
    objects are targets: with inst_count 1 for obj 5 only A (the best score) is evaluated,
    and obj 7, not listed, is no target."""
    r = P.match_and_recall(GTS, [B, A, C], [0.45], inst_counts={(1, 3, 5): 1})
    assert (r.targets, r.found.tolist()) == (2, [[1]])


def test_matching_no_estimates() -> None:
    r = P.match_and_recall(GTS, [], P.VSD_THRESHOLDS, columns=10)
    assert r.targets == 3 and r.found.shape == (10, 10) and not r.found.any()


@pytest.mark.parametrize(
    ("gts", "ests", "match"),
    [
        (GTS, [_est(0.5, {3: 0.1})], "no instance of obj 5"),
        ([*GTS, GTS[0]], [], "twice"),
        (GTS, [_est(0.5, {0: np.nan})], "NaN"),
        (GTS, [_est(float("nan"), {0: 0.1})], "score"),
        (GTS, [P.EstimateErrors(1, 3, 5, 0.9, {0: [0.1, 0.2], 1: [0.1]})], "one length"),
    ],
)
def test_matching_refuses_bad_input(gts: list, ests: list, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        P.match_and_recall(gts, ests, [0.2])


def test_average_recalls_as_the_toolkit() -> None:
    vsd = np.full((10, 10), 0.5)
    vsd[0] = 0.0  # tau 0.05 finds nothing
    s = P.average_recalls(vsd, np.linspace(0, 0.9, 10), np.ones(10))
    assert s.ar_vsd == pytest.approx(0.45)
    assert s.ar_mssd == pytest.approx(0.45)
    assert s.ar_mspd == 1.0
    assert s.ar == pytest.approx((0.45 + 0.45 + 1.0) / 3)


# -- rendering ----------------------------------------------------------------------------------
def test_render_box_face_on_exact_depth_and_silhouette() -> None:
    """A 0.1 m cube 1 m ahead shows its front face at z = 0.95 exactly; the face spans
    |u - cx| < 500 * 0.05 / 0.95 = 26.3 px, so columns and rows 38..89 of a 128 x 128 image
    (cx = cy = 63.5), 52 x 52 pixels."""
    v, f = _box(EXTENTS)
    d = render_depth(v, f, R_GT, T_GT, _K(128, 128), 128, 128)
    expected = np.zeros((128, 128), dtype=bool)
    expected[38:90, 38:90] = True
    assert np.array_equal(d > 0, expected)
    assert np.abs(d[expected] - 0.95).max() < 1e-12


def test_render_distance_image_of_a_plane() -> None:
    """The face at z = 0.95: its distance image is 0.95 |K^-1 (u, v, 1)|, which is also how far
    the hit point is from the camera centre."""
    v, f = _box(EXTENTS)
    K = _K(128, 128)
    d = ModelRenderer(v, f).depth(R_GT, T_GT, K, 128, 128)
    dist = P.distance_image(d, K)
    u, w = np.meshgrid(np.arange(128.0), np.arange(128.0))
    by_hand = 0.95 * np.sqrt(1 + ((u - 63.5) / F) ** 2 + ((w - 63.5) / F) ** 2)
    assert np.abs(dist - np.where(d > 0, by_hand, 0.0)).max() < 1e-12


def test_render_tilted_plate_depth_is_the_planes() -> None:
    """A 0.2 x 0.2 x 0.02 m plate turned 30 degrees about y, 1 m ahead: inside its front face
    the depth is the plane's, z = (n . p0) / (n . K^-1 (u, v, 1))."""
    v, f = _box((0.2, 0.2, 0.02))
    R = axis_angle([0, 1, 0], np.pi / 6)
    K = _K(160, 120)
    d = ModelRenderer(v, f).depth(R, T_GT, K, 160, 120)
    n = R @ [0.0, 0.0, -1.0]
    p0 = R @ [0.0, 0.0, -0.01] + T_GT
    u, w = np.meshgrid(np.arange(160.0), np.arange(120.0))
    rays = np.stack([(u - K[0, 2]) / F, (w - K[1, 2]) / F, np.ones_like(u)], axis=-1)
    z = (n @ p0) / (rays @ n)
    local = (rays * z[..., None] - T_GT) @ R  # the hit point in the plate's frame
    inside = (np.abs(local[..., 0]) < 0.095) & (np.abs(local[..., 1]) < 0.095)
    assert inside.sum() > 3000
    assert np.abs(d[inside] - z[inside]).max() < 1e-12
    outside = (np.abs(local[..., 0]) > 0.11) | (np.abs(local[..., 1]) > 0.105)
    assert (d[outside] == 0).all()


def test_render_sphere_silhouette_radius() -> None:
    """A sphere of radius r at distance D has a silhouette of radius f r / sqrt(D^2 - r^2)
    pixels (50.25 px here) and its nearest point at D - r; the icosphere's faces lie within
    0.1% of r inside the sphere."""
    m = trimesh.creation.icosphere(subdivisions=4, radius=0.1)
    d = ModelRenderer(m.vertices, m.faces).depth(R_GT, T_GT, _K(128, 128), 128, 128)
    u, w = np.meshgrid(np.arange(128.0), np.arange(128.0))
    radius = np.hypot(u - 63.5, w - 63.5)
    silhouette = F * 0.1 / np.sqrt(1.0 - 0.01)
    assert (d[radius < silhouette - 0.7] > 0).all()
    assert (d[radius > silhouette + 0.1] == 0).all()
    assert d[63:65, 63:65] == pytest.approx(np.full((2, 2), 0.9), abs=2e-4)


def test_render_clipped_hidden_and_enclosing() -> None:
    v, f = _box(EXTENTS)
    K = _K(128, 128)
    ren = ModelRenderer(v, f)
    # half out of the image on the left, seen past its right side face: the silhouette ends
    # at the back edge x = -0.026, z = 1.05, u = 63.5 - 500 * 0.026 / 1.05 = 51.1
    d = ren.depth(R_GT, T_GT + np.array([-0.076, 0.0, 0.0]), K, 128, 128)
    cols = np.flatnonzero((d > 0).any(axis=0))
    assert cols.min() == 0 and cols.max() == 51
    assert d[64, 49] == pytest.approx(0.95, abs=1e-12) and 0.95 < d[64, 51] < 1.05
    # behind the camera: nothing
    assert not ren.depth(R_GT, -T_GT, K, 128, 128).any()
    # the camera inside a 2 m box: every ray meets the far face (z = 1 on the axis)
    big = ModelRenderer(*_box((2.0, 2.0, 2.0)))
    d = big.depth(R_GT, np.zeros(3), K, 128, 128)
    assert (d > 0).all() and d[64, 64] == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda r: r.depth(np.eye(3) * 2, T_GT, _K(8, 8), 8, 8), "rotation"),
        (lambda r: r.depth(R_GT, [0, 1], _K(8, 8), 8, 8), "3-vector"),
        (lambda r: r.depth(R_GT, T_GT, np.eye(3) * 0, 8, 8), "pinhole"),
        (lambda r: r.depth(R_GT, T_GT, _K(8, 8), 0, 8), "positive integers"),
    ],
)
def test_render_refuses_bad_input(call: Callable[[ModelRenderer], object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        call(ModelRenderer(*_box(EXTENTS)))
    with pytest.raises(ValueError, match="faces"):
        ModelRenderer(np.zeros((3, 3)), [[0, 1, 5]])
