"""Statistics over items: the bootstrap intervals of a summary's metrics, and the paired
comparison of two runs' per-view values (``compare``, ``gate`` and the leaderboards' primary
comparisons): per-item sums of the views both runs scored, the cluster bootstrap interval of
their mean difference, the paired sign-flip test, Holm's correction, and what ``n`` items
can tell. Pure numpy functions, cheap to import, like :mod:`beo_bench.metrics`: NaN
entries are dropped, an aggregate over nothing is NaN.

References:

- [Efron] Efron & Tibshirani, "An Introduction to the Bootstrap", 1993 (percentile CI).
- [Holm] S. Holm, "A Simple Sequentially Rejective Multiple Test Procedure", Scandinavian
  Journal of Statistics 6(2), 1979.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from statistics import NormalDist
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from beo_bench.metrics._arrays import _vector

__all__ = [
    "DEFAULT_PERMUTATIONS",
    "EXACT_MAX_ITEMS",
    "Z95",
    "bootstrap_ci",
    "detectable_difference",
    "holm",
    "item_sums",
    "paired_half_width",
    "per_item_sums",
    "rate_half_width",
    "ratio_interval",
    "sign_flip_p",
    "smallest_p",
]

EXACT_MAX_ITEMS = 16
"""Up to this many items with a non-zero difference the sign-flip test enumerates every
pattern (2^16 = 65,536: milliseconds); above it, random patterns."""
DEFAULT_PERMUTATIONS = 10_000
"""Random sign patterns above :data:`EXACT_MAX_ITEMS` items: the p-value's Monte Carlo
error is then at most 0.005 (at p = 0.5; 0.002 near p = 0.05)."""

ViewKey = tuple[int, int]
"""(item, view)."""


# --------------------------------------------------------------------------- bootstrap


def bootstrap_ci(
    values: ArrayLike,
    statistic: Callable[..., Any] = np.mean,
    n_resamples: int = 1000,
    confidence: float = 0.95,
    seed: int = 0,
    groups: ArrayLike | None = None,
) -> tuple[float, float]:
    """Percentile bootstrap confidence interval ``(lo, hi)`` of ``statistic`` [Efron].

    Draws an (n_resamples, n) matrix of indices with replacement from
    ``numpy.random.default_rng(seed)`` (deterministic), evaluates ``statistic`` on every
    row (``statistic(samples, axis=1)`` when it accepts ``axis``, else row by row) and
    returns the ``(1 - confidence) / 2`` and ``(1 + confidence) / 2`` percentiles. NaNs are
    dropped first; no values -> ``(nan, nan)``; bools count as 0/1.

    ``groups`` (one label per value) makes it a cluster bootstrap: the *groups* are drawn
    with replacement (an (n_resamples, G) matrix of group indices, groups in sorted label
    order) and each drawn group brings all its values, so values that share a group (the
    views of one tabletop scene, which are not independent) move together, as the suite
    samples them. With one value per group it draws exactly as without ``groups``. The
    statistic is then taken over the pooled values of each resample (for ``np.mean``: the
    drawn groups' summed values over their summed counts; for ``np.median``: the median of
    the pooled values, as ``np.median`` takes it).
    """
    v = _vector(values, "values")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    if int(n_resamples) < 1:
        raise ValueError(f"n_resamples must be >= 1, got {n_resamples}")
    if groups is not None:
        g = np.asarray(groups).reshape(-1)
        if g.shape != v.shape:
            raise ValueError(f"groups must give one label per value: {g.size} for {v.size}")
        keep = ~np.isnan(v)
        stats = _cluster_stats(v[keep], g[keep], statistic, int(n_resamples), seed)
        return _percentiles(stats, confidence)
    v = v[~np.isnan(v)]
    if v.size == 0:
        return float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    samples = v[rng.integers(0, v.size, size=(int(n_resamples), v.size))]
    try:
        stats = np.asarray(statistic(samples, axis=1), dtype=np.float64)
        if stats.shape != (int(n_resamples),):
            raise TypeError("statistic did not reduce along axis 1")
    except TypeError:
        stats = np.array([float(statistic(row)) for row in samples])
    return _percentiles(stats, confidence)


def _percentiles(stats: np.ndarray, confidence: float) -> tuple[float, float]:
    if stats.size == 0:
        return float("nan"), float("nan")
    alpha = (1.0 - confidence) / 2.0
    lo, hi = np.nanpercentile(stats, [100.0 * alpha, 100.0 * (1.0 - alpha)])
    return float(lo), float(hi)


def _cluster_stats(
    v: np.ndarray, groups: np.ndarray, statistic: Callable[..., Any], n: int, seed: int
) -> np.ndarray:
    """``statistic`` of each of ``n`` cluster resamples (see :func:`bootstrap_ci`)."""
    if v.size == 0:
        return np.zeros(0)
    labels, member = np.unique(groups, return_inverse=True)
    G = len(labels)
    draws = np.random.default_rng(seed).integers(0, G, size=(n, G))
    if statistic is np.mean:
        sums = np.bincount(member, weights=v, minlength=G)
        counts = np.bincount(member, minlength=G).astype(np.float64)
        return sums[draws].sum(axis=1) / counts[draws].sum(axis=1)
    # how often each group is drawn, then each value's weight in its resample
    flat = (np.arange(n)[:, None] * G + draws).ravel()
    times = np.bincount(flat, minlength=n * G).reshape(n, G)
    weights = times[:, member]  # (n, N): integer multiplicities of each value
    if statistic is np.median:
        order = np.argsort(v, kind="stable")
        return _weighted_medians(v[order], weights[:, order])
    return np.array([float(statistic(np.repeat(v, w))) for w in weights])


def _weighted_medians(sorted_v: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``np.median`` of each row's sample, given as the sorted values repeated ``weights``
    times (integers): the mean of the elements at ranks ``floor((T-1)/2)`` and
    ``ceil((T-1)/2)`` of the T pooled values."""
    cum = np.cumsum(weights, axis=1)
    total = cum[:, -1]
    out = np.empty(len(weights))
    for i, (c, t) in enumerate(zip(cum, total, strict=True)):
        lo, hi = np.searchsorted(c, [(t - 1) // 2 + 1, t // 2 + 1])
        out[i] = 0.5 * (sorted_v[lo] + sorted_v[hi])
    return out


# --------------------------------------------------------------------------- two runs, paired


def item_sums(
    va: Mapping[ViewKey, float], vb: Mapping[ViewKey, float]
) -> dict[int, tuple[float, float, int]]:
    """Per item (in item order): the sums of A's and B's values over the views both scored
    (finite in both), and how many views that is. Items are the unit a suite draws (a
    tabletop item's views are not independent), so every paired figure resamples or flips
    these sums, never views."""
    out: dict[int, tuple[float, float, int]] = {}
    for key in sorted(va.keys() & vb.keys()):
        x, y = va[key], vb[key]
        if math.isfinite(x) and math.isfinite(y):
            sx, sy, k = out.get(key[0], (0.0, 0.0, 0))
            out[key[0]] = (sx + x, sy + y, k + 1)
    return out


def per_item_sums(
    va: Mapping[ViewKey, float], vb: Mapping[ViewKey, float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`item_sums` as three arrays over the common items: A's sums, B's, view counts."""
    arr = np.array(list(item_sums(va, vb).values()), dtype=np.float64).reshape(-1, 3)
    return arr[:, 0], arr[:, 1], arr[:, 2]


def ratio_interval(
    d: np.ndarray, n: np.ndarray, n_resamples: int, seed: int, tail: float
) -> tuple[float, float]:
    """The percentile bootstrap interval of ``sum(d) / sum(n)`` over units drawn with
    replacement (the cluster bootstrap of a mean over views: ``d`` the units' summed
    differences, ``n`` their view counts) [Efron]: the ``tail`` and ``100 - tail``
    percentiles of ``n_resamples`` resamples drawn from ``numpy.random.default_rng(seed)``.
    ``tail`` is a percentage, not a confidence, because its callers' published intervals
    were drawn with two spellings of 2.5 that differ in the last bit (``compare``'s
    ``100 * (1 - 0.95) / 2`` and the gate's ``2.5``), and the intervals must not move."""
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(n), size=(int(n_resamples), len(n)))
    stats = d[idx].sum(axis=1) / n[idx].sum(axis=1)
    lo, hi = np.percentile(stats, [tail, 100 - tail])
    return float(lo), float(hi)


def sign_flip_p(
    diffs: np.ndarray,
    permutations: int = DEFAULT_PERMUTATIONS,
    seed: int = 0,
    alternative: str = "two-sided",
) -> float:
    """The p-value of the paired sign-flip permutation test that the units' summed
    differences ``diffs`` have mean 0: the share of sign patterns whose sum is at least the
    observed one, in absolute value (``alternative="two-sided"``) or as it is (``"greater"``:
    the one-sided test that the mean is above 0, the gate's, with the differences already
    oriented worse-positive and less the margin). Units whose difference is exactly 0 are
    the same under a flip, so only the others are flipped; up to :data:`EXACT_MAX_ITEMS` of
    them every pattern is enumerated (an exact test), beyond that ``permutations`` random
    patterns drawn from ``seed`` and the observed one ((1 + hits) / (1 + permutations), a
    valid p-value)."""
    if alternative not in ("two-sided", "greater"):
        raise ValueError(f"alternative {alternative!r}: 'two-sided' or 'greater'")
    d = np.asarray(diffs, dtype=np.float64)
    d = d[d != 0]
    if not len(d):
        return 1.0
    two = alternative == "two-sided"
    observed = abs(float(d.sum())) if two else float(d.sum())

    def stat(sums: np.ndarray) -> np.ndarray:
        return np.abs(sums) if two else sums

    # the same terms summed in another order differ in the last bits: a pattern that gives
    # the observed sum must count as reaching it
    tol = 1e-9 * float(np.abs(d).sum())
    k = len(d)
    if k <= EXACT_MAX_ITEMS:
        patterns = np.arange(2**k, dtype=np.int64)[:, None] >> np.arange(k) & 1
        sums = stat((1 - 2 * patterns) @ d)
        return float(np.mean(sums >= observed - tol))
    rng = np.random.default_rng(seed)
    hits, left = 0, int(permutations)
    while left:  # in blocks: 10,000 patterns of 1,000 items would be 80 MB at once
        n = min(left, 1000)
        signs = rng.integers(0, 2, size=(n, k)) * 2 - 1
        hits += int(np.count_nonzero(stat(signs @ d) >= observed - tol))
        left -= n
    return (1 + hits) / (1 + int(permutations))


def holm(pvalues: Sequence[float]) -> list[float]:
    """Holm's step-down adjusted p-values: the k-th smallest (from 0) times ``m - k``, made
    non-decreasing in that order and capped at 1. Rejecting where the adjusted value is at
    most alpha keeps the family-wise error rate at most alpha, under any dependence
    between the tests."""
    m = len(pvalues)
    out = [1.0] * m
    running = 0.0
    for rank, i in enumerate(sorted(range(m), key=lambda j: pvalues[j])):
        running = max(running, min(1.0, (m - rank) * float(pvalues[i])))
        out[i] = running
    return out


def smallest_p(units: int, permutations: int = DEFAULT_PERMUTATIONS) -> float:
    """The smallest p-value the one-sided sign-flip test can give on ``units`` units: every
    unit worse, only the observed pattern reaches its sum, ``2^-units`` exactly up to
    :data:`EXACT_MAX_ITEMS` differing units; above it ``1 / (1 + permutations)`` (the
    observed pattern counts). A regression confined to a suite of ``units`` items, the
    other units no worse than the margin, cannot reach a smaller p pooled either: flipping
    the other units' (non-positive) differences only raises the sum, so at least one
    pattern of the suite's ``2^units`` reaches the observed sum for each of theirs."""
    exact = 2.0**-units
    return exact if units <= EXACT_MAX_ITEMS else max(exact, 1.0 / (1 + int(permutations)))


# --------------------------------------------------------------------------- what n items can tell
Z95 = NormalDist().inv_cdf(0.975)
"""The two-sided 95% normal quantile (1.96)."""


def rate_half_width(rate: float, n: int) -> float:
    """The half-width of the 95% interval of a rate (a class accuracy, a > 15 deg rate, pick
    success) measured on ``n`` items: ``1.96 sqrt(rate (1 - rate) / n)``, what the
    summary's bootstrap over items approaches for one view an item."""
    return Z95 * math.sqrt(rate * (1 - rate) / n)


def paired_half_width(discordant: float, n: int) -> float:
    """The half-width of the 95% interval of the paired difference of two rates on ``n``
    items when a share ``discordant`` of the items is right in one run and wrong in the
    other, and no difference on the whole: each item's difference is then +-1 on that share,
    0 elsewhere, of variance ``discordant``, so ``1.96 sqrt(discordant / n)``. Items both
    runs get right or both get wrong cost nothing: pairing is why a gate needs fewer items
    than two intervals that must not overlap."""
    return Z95 * math.sqrt(discordant / n)


def detectable_difference(discordant: float, n: int, power: float = 0.8) -> float:
    """The smallest paired difference of two rates that a two-sided 5% test on ``n`` items
    finds with probability ``power`` when a share ``discordant`` of the items differ
    (normal approximation): the test rejects past ``1.96 sqrt(discordant / n)`` (the null's
    spread), and a difference ``delta`` spreads as ``sqrt((discordant - delta^2) / n)``, so
    ``delta`` solves ``delta - 1.96 sqrt(q / n) = z_power sqrt((q - delta^2) / n)``, found by
    bisection in ``[0, discordant]`` (no difference can exceed the share that differs)."""
    z = NormalDist().inv_cdf(power)
    q = discordant

    def short(delta: float) -> float:  # < 0 while delta is found with less than `power`
        return delta - Z95 * math.sqrt(q / n) - z * math.sqrt(max(q - delta * delta, 0.0) / n)

    lo, hi = 0.0, q
    if short(hi) < 0:
        return math.inf  # not even every differing item going one way is found
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if short(mid) < 0 else (lo, mid)
    return hi
