"""``beo_bench.stats`` against independent computations: sign patterns enumerated by hand,
Holm by hand, bootstrap resamples redrawn, the intervals ``compare`` and ``gate`` publish
redrawn bit for bit."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from beo_bench import stats as S

# --------------------------------------------------------------------------- bootstrap


def test_bootstrap_ci() -> None:
    rng = np.random.default_rng(1)
    small = rng.normal(3.0, 1.0, 50)
    big = rng.normal(3.0, 1.0, 2000)
    lo, hi = S.bootstrap_ci(small)
    assert lo < small.mean() < hi
    assert 0.3 < hi - lo < 0.8  # about 2 * 1.96 / sqrt(50) = 0.55
    lo2, hi2 = S.bootstrap_ci(big)
    assert lo2 < big.mean() < hi2
    assert hi2 - lo2 < (hi - lo) / 3
    assert S.bootstrap_ci(small, seed=5) == S.bootstrap_ci(small, seed=5)
    assert S.bootstrap_ci(small, seed=5) != S.bootstrap_ci(small, seed=6)
    assert S.bootstrap_ci(np.append(small, np.nan)) == pytest.approx((lo, hi))  # NaN dropped
    nan_lo, nan_hi = S.bootstrap_ci([np.nan])
    assert np.isnan(nan_lo) and np.isnan(nan_hi)
    # statistics without an axis argument go row by row on the same resamples
    assert S.bootstrap_ci(small, lambda x: float(np.median(x))) == pytest.approx(
        S.bootstrap_ci(small, np.median)
    )
    narrow = S.bootstrap_ci(small, confidence=0.5)
    assert lo < narrow[0] < narrow[1] < hi
    assert S.bootstrap_ci([2.0, 2.0, 2.0]) == (2.0, 2.0)
    with pytest.raises(ValueError, match="1-D"):
        S.bootstrap_ci(np.ones((2, 2)))


def test_cluster_bootstrap_resamples_groups() -> None:
    rng = np.random.default_rng(2)
    v = rng.normal(size=40)
    # one value per group: the same draws as without groups
    assert S.bootstrap_ci(v, groups=np.arange(40)) == pytest.approx(S.bootstrap_ci(v))
    assert S.bootstrap_ci(v, np.median, groups=np.arange(40)) == pytest.approx(
        S.bootstrap_ci(v, np.median)
    )
    # views of a scene share its difficulty: 60 scenes x 4 views, strongly correlated
    scene = rng.normal(size=60)
    views = np.repeat(scene, 4) + 0.2 * rng.normal(size=240)
    groups = np.repeat(np.arange(60), 4)
    by_view = np.subtract(*S.bootstrap_ci(views)[::-1])
    by_scene = np.subtract(*S.bootstrap_ci(views, groups=groups)[::-1])
    assert by_scene > 1.5 * by_view  # ~sqrt(4): views are nearly copies of their scene
    # and it is the interval of the scene means' bootstrap (equal-size groups)
    means = views.reshape(60, 4).mean(axis=1)
    assert by_scene == pytest.approx(np.subtract(*S.bootstrap_ci(means)[::-1]), rel=1e-9)
    # the median of the pooled values, as np.median takes it, for every resample
    lab, draws = np.array([0, 0, 1, 2, 2, 2]), np.random.default_rng(0).integers(0, 3, (7, 3))
    vals = np.array([5.0, 1.0, 3.0, 2.0, 8.0, 4.0])
    got = S._cluster_stats(vals, lab, np.median, 7, 0)
    want = [np.median(np.concatenate([vals[lab == g] for g in row])) for row in draws]
    np.testing.assert_allclose(got, want)
    got = S._cluster_stats(vals, lab, np.max, 7, 0)  # any other statistic: pooled, row by row
    np.testing.assert_allclose(got, [max(vals[np.isin(lab, row)]) for row in draws])
    # NaNs are dropped with their labels; a label per value is required
    assert S.bootstrap_ci(np.append(v, np.nan), groups=np.arange(41)) == pytest.approx(
        S.bootstrap_ci(v, groups=np.arange(40))
    )
    with pytest.raises(ValueError, match="one label per value"):
        S.bootstrap_ci(v, groups=np.arange(3))


# --------------------------------------------------------------------------- two runs, paired


def test_item_sums_pair_the_views_both_runs_scored() -> None:
    a = {(0, 0): 1.0, (0, 1): 2.0, (1, 0): float("nan"), (2, 0): 5.0, (3, 0): 1.0}
    b = {(0, 0): 3.0, (0, 1): 4.0, (1, 0): 1.0, (2, 0): float("inf"), (4, 0): 1.0}
    # item 1 and 2 have no view finite in both; items 3 and 4 are in one run only
    assert S.item_sums(a, b) == {0: (3.0, 7.0, 2)}
    sa, sb, n = S.per_item_sums(a, b)
    assert sa.tolist() == [3.0] and sb.tolist() == [7.0] and n.tolist() == [2.0]
    empty = S.per_item_sums({}, {})
    assert all(x.shape == (0,) for x in empty)


def test_ratio_interval_redraws_the_published_intervals_bit_for_bit() -> None:
    """The cluster bootstrap of a mean over views, redrawn here: the same resamples and the
    same percentiles, exactly (compare's tail is 100 * (1 - 0.95) / 2, not 2.5: the two
    differ in the last bit, and so do the intervals, which must not move)."""
    rng = np.random.default_rng(3)
    n = rng.integers(1, 5, 80).astype(np.float64)
    d = rng.normal(size=80) * n
    for tail in (2.5, 100 * (1 - 0.95) / 2):
        idx = np.random.default_rng(7).integers(0, 80, size=(1000, 80))
        redrawn = d[idx].sum(axis=1) / n[idx].sum(axis=1)
        want = tuple(float(x) for x in np.percentile(redrawn, [tail, 100 - tail]))
        assert S.ratio_interval(d, n, 1000, 7, tail) == want
    assert S.ratio_interval(d, n, 1000, 7, 2.5) != S.ratio_interval(
        d, n, 1000, 7, 100 * (1 - 0.95) / 2
    )
    lo, hi = S.ratio_interval(d, n, 1000, 7, 2.5)
    assert lo < d.sum() / n.sum() < hi


# --------------------------------------------------------------------------- the paired test


def test_sign_flip_is_exact_on_few_items() -> None:
    d = np.array([1.0, 2.0, 3.0, 4.0, -0.5])
    every = [abs(sum(s * x for s, x in zip(signs, d, strict=True)))
             for signs in itertools.product((1, -1), repeat=len(d))]  # fmt: skip
    expected = np.mean([t >= abs(d.sum()) - 1e-12 for t in every])
    assert S.sign_flip_p(d) == pytest.approx(expected)
    assert S.sign_flip_p(np.array([1.0, 1.0, 1.0])) == pytest.approx(2 / 8)
    # items that do not differ change nothing under a flip: the same p
    assert S.sign_flip_p(np.array([1.0, 1.0, 1.0, 0.0, 0.0])) == pytest.approx(2 / 8)
    assert S.sign_flip_p(np.zeros(5)) == 1.0


def test_sign_flip_samples_many_items_deterministically() -> None:
    d = np.ones(40)  # only the two all-equal patterns reach |sum| = 40: p = 2 / 2^40
    p = S.sign_flip_p(d, permutations=2000, seed=3)
    assert p == pytest.approx(1 / 2001)  # nothing sampled reaches it; the observed counts
    noise = np.random.default_rng(1).normal(size=40)
    assert S.sign_flip_p(noise, 2000, 5) == S.sign_flip_p(noise, 2000, 5)  # seeded
    assert 0.05 < S.sign_flip_p(noise, 2000, 5) <= 1


def test_the_one_sided_sign_flip_counts_sums_at_least_the_observed_one() -> None:
    d = np.array([1.0, 2.0, 3.0, 4.0, -0.5])
    every = [sum(s * x for s, x in zip(signs, d, strict=True))
             for signs in itertools.product((1, -1), repeat=len(d))]  # fmt: skip
    expected = np.mean([t >= d.sum() - 1e-12 for t in every])
    assert S.sign_flip_p(d, alternative="greater") == pytest.approx(expected) == 2 / 32
    assert S.sign_flip_p(np.array([1.0, 1.0, 1.0]), alternative="greater") == pytest.approx(1 / 8)
    # every unit better: the one-sided test of "worse" finds nothing (two-sided: 2/8)
    assert S.sign_flip_p(-np.ones(3), alternative="greater") == 1.0
    assert S.sign_flip_p(-np.ones(3)) == pytest.approx(2 / 8)
    with pytest.raises(ValueError, match="'two-sided' or 'greater'"):
        S.sign_flip_p(d, alternative="less")


def test_the_one_sided_test_keeps_its_level_on_noise() -> None:
    """Differences symmetric about 0 (a stochastic backend re-seeded): the one-sided test
    rejects at 5% about 5% of the time, and less with a margin subtracted."""
    rng = np.random.default_rng(7)
    plain = shifted = 0
    for k in range(300):
        d = rng.normal(0, 10, size=40)
        plain += S.sign_flip_p(d, 499, k, "greater") <= 0.05
        shifted += S.sign_flip_p(d - 2.0, 499, k, "greater") <= 0.05
    assert 0.025 <= plain / 300 <= 0.085 and shifted / 300 < 0.02


def test_holm_by_hand() -> None:
    # sorted: 0.005 x 4 = 0.02, 0.01 x 3 = 0.03, 0.03 x 2 = 0.06, 0.04 x 1 -> max 0.06
    assert S.holm([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert S.holm([0.5]) == [0.5] and S.holm([0.9, 0.8]) == [1.0, 1.0]
    assert S.holm([0.2, 0.01]) == pytest.approx([0.2, 0.02]) and S.holm([]) == []


def test_smallest_p() -> None:
    assert S.smallest_p(6) == 1 / 64 and S.smallest_p(40, 999) == 1 / 1000
    assert S.smallest_p(S.EXACT_MAX_ITEMS) == 2.0**-S.EXACT_MAX_ITEMS
