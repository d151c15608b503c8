"""Shrinkage covariance for the class densities in BEO's subspace (dissertation eq. 3.9).

A class has a few hundred training objects and the subspace has about a hundred
dimensions, so the sample covariance is noisy and may be singular. Two steps, both with the
amount of shrinkage estimated from the data rather than set by hand:

1. **Eigenvalue shrinkage** (Ledoit & Wolf, "A well-conditioned estimator for
   large-dimensional covariance matrices", J. Multivariate Anal. 2004, Theorem 1 / Lemmas
   3.2-3.4): ``S1 = delta * m I + (1 - delta) S``, pulling the eigenvalues towards their mean
   ``m`` while keeping the eigenvectors; positive definite whenever ``m > 0``.
2. **Convex combination with the two-parameter target** (Schafer & Strimmer, "A shrinkage
   approach to large-scale covariance matrix estimation", SAGMB 2005, Table 2 target "C":
   common variance ``v`` on the diagonal, common covariance ``c`` off it):
   ``Sigma = lambda T + (1 - lambda) S1`` with ``lambda* = sum Var(s_ij) /
   (sum_i (s_ii - v)^2 + sum_{i != j} (s_ij - c)^2)``, clipped to [0, 1].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Shrunk:
    """A shrinkage estimate and the amounts that produced it."""

    covariance: np.ndarray
    """(p, p) symmetric positive definite."""
    delta: float
    """Ledoit-Wolf eigenvalue shrinkage towards the mean eigenvalue, in [0, 1]."""
    lam: float
    """Schafer-Strimmer weight of the two-parameter target, in [0, 1]."""


def ledoit_wolf_delta(Xc: np.ndarray) -> float:
    """The Ledoit-Wolf (2004) shrinkage intensity towards ``m I`` for centred rows ``Xc``
    (n, p), with their normalised Frobenius norm ``|A|^2 = tr(A A^T) / p``."""
    n, p = Xc.shape
    S = Xc.T @ Xc / n
    m = np.trace(S) / p
    d2 = np.sum((S - m * np.eye(p)) ** 2) / p
    if d2 <= 0:
        return 1.0
    # b_bar^2 = 1/n^2 sum_k |x_k x_k^T - S|^2 = 1/n^2 sum_k (|x_k|^4 - 2 x_k^T S x_k + |S|^2)
    norms = np.sum(Xc**2, axis=1)
    b2 = (np.sum(norms**2) - 2 * np.sum((Xc @ S) * Xc) + n * np.sum(S**2)) / (n**2 * p)
    return float(np.clip(b2 / d2, 0.0, 1.0))


def schafer_strimmer_lambda(Xc: np.ndarray) -> tuple[float, np.ndarray]:
    """The Schafer-Strimmer (2005) optimal weight of target C for centred rows ``Xc`` (n, p),
    and the target itself."""
    n, p = Xc.shape
    if n < 2:
        raise ValueError("a covariance needs at least 2 samples")
    S = Xc.T @ Xc / (n - 1)
    v = float(np.mean(np.diag(S)))
    off = ~np.eye(p, dtype=bool)
    c = float(np.mean(S[off])) if p > 1 else 0.0
    target = np.full((p, p), c)
    np.fill_diagonal(target, v)
    # Var(s_ij) = n / (n - 1)^3 sum_k (w_kij - mean_k w_kij)^2, w_kij = x_ki x_kj (their eq. 11)
    W = Xc[:, :, None] * Xc[:, None, :]
    var_s = n / (n - 1) ** 3 * np.sum((W - W.mean(axis=0)) ** 2, axis=0)
    denom = float(np.sum((S - target) ** 2))
    lam = 1.0 if denom <= 0 else float(np.clip(np.sum(var_s) / denom, 0.0, 1.0))
    return lam, target


def shrinkage_covariance(X: np.ndarray) -> Shrunk:
    """Eq. 3.9's covariance of the rows of ``X`` (n >= 2, p)."""
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[0] < 2:
        raise ValueError(f"need an (n >= 2, p) sample matrix, got shape {X.shape}")
    n, p = X.shape
    Xc = X - X.mean(axis=0)
    S = Xc.T @ Xc / (n - 1)
    delta = ledoit_wolf_delta(Xc)
    S1 = delta * np.trace(S) / p * np.eye(p) + (1 - delta) * S
    lam, target = schafer_strimmer_lambda(Xc)
    cov = lam * target + (1 - lam) * S1
    cov = 0.5 * (cov + cov.T)
    # the two-parameter target is positive definite only for -v/(p-1) < c < v; guard the
    # combination with the smallest ridge that keeps a Cholesky factorisation possible
    lo = float(np.linalg.eigvalsh(cov)[0])
    floor = 1e-9 * max(np.trace(cov) / p, 1e-300)
    if lo < floor:
        cov += (floor - lo) * np.eye(p)
    return Shrunk(cov, delta, lam)
