"""Variational Bayesian PCA (Bishop, "Variational principal components", ICANN 1999), written
for n << d.

Model (dissertation eq. 3.2-3.4): an object's flattened voxel grid t (d,) is
``t = W x + mu + eps`` with ``x ~ N(0, I_q)``, ``eps ~ N(0, tau^-1 I_d)``; priors
``w_i ~ N(0, alpha_i^-1 I_d)`` per column (ARD: a column whose ``alpha_i`` grows is switched
off), ``mu ~ N(0, beta^-1 I_d)``, ``alpha_i ~ Gamma(a, b)``, ``tau ~ Gamma(c, d_tau)``.
The posterior is approximated by the factorised ``q(X) q(mu) q(W) q(alpha) q(tau)``, each
factor updated in closed form in turn (coordinate ascent), so the lower bound ``F`` on the
log evidence never decreases.

**n << d.** Every posterior mean (of ``mu``, of the columns of ``W``) is a combination of the
training vectors, so all updates run in the data's own span: one thin SVD of the (n, d)
data matrix gives an orthonormal basis Q (d, r <= n) and coordinates y_n = Q^T t_n, after
which an iteration costs O(n^2 q), never O(d^2) nor even O(n d q). The d - r directions
outside the span keep only their posterior *variance*, which enters the traces through
``d * Sigma`` (exact, not an approximation). Nothing d x d is ever formed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.special import digamma, gammaln

LOG_2PI = float(np.log(2 * np.pi))


@dataclass(frozen=True)
class VBPCAConfig:
    """Settings of one VBPCA fit."""

    max_components: int | None = None
    """Latent dimension q to start from (ARD switches off what is not needed); None: n - 1."""
    variance_fraction: float = 0.6
    """Keep the fewest principal directions of the posterior ``W`` whose variance reaches this
    fraction of the data's total variance (60% in the dissertation, section 3.3.1)."""
    max_iter: int = 500
    tol: float = 1e-7
    """Stop when the bound's relative change falls below this."""
    a: float = 1e-3
    """Shape and rate of the Gamma priors on ``alpha`` and ``tau`` (broad, as in Bishop)."""
    b: float = 1e-3
    beta: float = 1e-3
    """Precision of the prior on ``mu``."""


@dataclass
class VBPCAResult:
    """A fitted model: the kept principal directions of ``W`` (scaled by their standard
    deviations), the mean, the noise variance and the bound's history."""

    W: np.ndarray
    """(d, k) the posterior-mean ``W`` in its principal axes, k kept columns (descending)."""
    mean: np.ndarray
    """(d,) posterior mean of ``mu``."""
    noise_var: float
    """1 / <tau>."""
    variances: np.ndarray
    """(q,) variance along every principal direction of the posterior ``W`` (descending),
    kept or not."""
    total_variance: float
    """Trace of the data's sample covariance."""
    bound: list[float] = field(default_factory=list)
    """The lower bound F after every iteration (never decreasing)."""
    alpha: np.ndarray | None = None
    """(q,) posterior-mean ARD precisions of the columns (large = switched off)."""

    @property
    def explained(self) -> float:
        """Fraction of the total variance that the kept columns capture."""
        return float(np.sum(self.W**2) / max(self.total_variance, 1e-300))

    def log_likelihood(self, T: np.ndarray) -> np.ndarray:
        """(m,) log density of rows of ``T`` under the fitted probabilistic PCA model
        ``N(mean, W W^T + noise_var I)`` (with every kept column), by the Woodbury identity
        and the matrix determinant lemma (no d x d matrix)."""
        return ppca_log_likelihood(T, self.W, self.mean, self.noise_var)


def ppca_log_likelihood(T: np.ndarray, W: np.ndarray, mean: np.ndarray, var: float) -> np.ndarray:
    """(m,) log N(t; mean, W W^T + var I) for the rows t of ``T`` (m, d); W (d, k)."""
    T = np.atleast_2d(np.asarray(T, dtype=np.float64)) - mean
    d, k = W.shape
    M = np.eye(k) * var + W.T @ W  # (k, k)
    L = np.linalg.cholesky(M)
    Z = np.linalg.solve(L, W.T @ T.T)  # (k, m)
    quad = (np.sum(T**2, axis=1) - np.sum(Z**2, axis=0)) / var
    # log|W W^T + var I| = (d - k) log var + log|M|
    logdet = (d - k) * np.log(var) + 2 * np.sum(np.log(np.diag(L)))
    return -0.5 * (d * LOG_2PI + logdet + quad)


def fit_vbpca(T: np.ndarray, config: VBPCAConfig | None = None) -> VBPCAResult:
    """Fit VBPCA to the rows of ``T`` (n, d), n >= 2. Deterministic (PCA initialisation)."""
    cfg = config or VBPCAConfig()
    T = np.asarray(T, dtype=np.float64)
    if T.ndim != 2 or T.shape[0] < 2:
        raise ValueError(f"VBPCA needs an (n >= 2, d) data matrix, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise ValueError("VBPCA data holds NaN or inf")
    n, d = T.shape
    # the data's span: T = U S Vt, t_n = Q y_n with Q = Vt.T (d, r)
    U, S, Vt = np.linalg.svd(T, full_matrices=False)
    r = int(np.sum(S > S[0] * 1e-10)) if S[0] > 0 else 1
    Y = U[:, :r] * S[:r]  # (n, r)
    q = min(cfg.max_components or n - 1, n - 1, r)

    # PCA initialisation (Bishop 1999b initialises from PCA too)
    mu = Y.mean(axis=0)
    _, Sc, Vc = np.linalg.svd(Y - mu, full_matrices=False)
    ev = Sc**2 / n
    total_var = float(np.sum(ev))
    noise0 = max(float(np.sum(ev[q:]) + total_var * 1e-3) / max(d - q, 1), 1e-12)
    M = Vc[:q].T * np.sqrt(np.maximum(ev[:q] - noise0, noise0))  # (r, q) mean of W
    Sw = np.zeros((q, q))
    alpha = d / np.maximum(np.sum(M**2, axis=0), 1e-12)
    tau = 1.0 / noise0
    Smu = 0.0
    a, b, beta = cfg.a, cfg.b, cfg.beta
    a_alpha = a + d / 2
    a_tau = a + n * d / 2
    sum_yy = float(np.sum(Y**2))
    bounds: list[float] = []
    for _ in range(cfg.max_iter):
        # q(X): Sigma_x = (I + <tau> <W^T W>)^-1, m_x = <tau> Sigma_x <W>^T (t - <mu>)
        WtW = d * Sw + M.T @ M
        Sx = np.linalg.inv(np.eye(q) + tau * WtW)
        Sx = 0.5 * (Sx + Sx.T)
        Mx = tau * (Y - mu) @ M @ Sx  # (n, q)
        # q(mu): Sigma_mu = (beta + n <tau>)^-1 I, m_mu = <tau> Sigma_mu sum (t - <W> <x>)
        Smu = 1.0 / (beta + n * tau)
        mu = tau * Smu * np.sum(Y - Mx @ M.T, axis=0)
        # q(W): rows ~ N(., Sigma_w), Sigma_w = (diag<alpha> + <tau> sum <x x^T>)^-1
        XX = n * Sx + Mx.T @ Mx
        Sw = np.linalg.inv(np.diag(alpha) + tau * XX)
        Sw = 0.5 * (Sw + Sw.T)
        M = tau * (Y - mu).T @ Mx @ Sw  # (r, q)
        # q(alpha_i) = Gamma(a + d/2, b + <|w_i|^2>/2)
        w2 = d * np.diag(Sw) + np.sum(M**2, axis=0)
        b_alpha = b + w2 / 2
        alpha = a_alpha / b_alpha
        # q(tau) = Gamma(c + n d/2, d_tau + <sum_n |t_n - W x_n - mu|^2>/2)
        WtW = d * Sw + M.T @ M
        E = (
            sum_yy
            + n * (d * Smu + float(mu @ mu))
            + float(np.sum(WtW * XX))
            + 2 * float(mu @ M @ Mx.sum(axis=0))
            - 2 * float(np.sum((Y @ M) * Mx))
            - 2 * float(np.sum(Y @ mu))
        )
        b_tau = b + E / 2
        tau = a_tau / b_tau
        bounds.append(
            _bound(n, d, q, a, b, beta, E, Sx, Mx, Sw, M, Smu, mu, a_alpha, b_alpha, a_tau, b_tau)
        )
        if len(bounds) > 1 and abs(bounds[-1] - bounds[-2]) <= cfg.tol * abs(bounds[-1]):
            break

    # principal axes of the posterior mean of W: M = Uw sw Vw^T
    Uw, sw, _ = np.linalg.svd(M, full_matrices=False)
    variances = sw**2
    cum = np.cumsum(variances) / max(total_var, 1e-300)
    alive = int(np.sum(variances > variances[0] * 1e-6)) if variances[0] > 0 else 0
    k = int(np.searchsorted(cum, cfg.variance_fraction) + 1)
    k = max(1, min(k, alive if alive else 1))
    Q = Vt[:r].T  # (d, r)
    W = Q @ (Uw[:, :k] * sw[:k])
    return VBPCAResult(
        W=W,
        mean=Q @ mu,
        noise_var=1.0 / tau,
        variances=variances,
        total_variance=total_var,
        bound=bounds,
        alpha=alpha,
    )


def _gamma_entropy(a: float | np.ndarray, b: float | np.ndarray) -> np.ndarray:
    return a - np.log(b) + gammaln(a) + (1 - a) * digamma(a)


def _bound(
    n: int,
    d: int,
    q: int,
    a: float,
    b: float,
    beta: float,
    E: float,
    Sx: np.ndarray,
    Mx: np.ndarray,
    Sw: np.ndarray,
    M: np.ndarray,
    Smu: float,
    mu: np.ndarray,
    a_alpha: float,
    b_alpha: np.ndarray,
    a_tau: float,
    b_tau: float,
) -> float:
    """The variational lower bound F = <ln p(T, X, W, mu, alpha, tau)> - <ln q> (Bishop
    1999b, section 3), every expectation under the current factors."""
    tau = a_tau / b_tau
    ln_tau = digamma(a_tau) - np.log(b_tau)
    alpha = a_alpha / b_alpha
    ln_alpha = digamma(a_alpha) - np.log(b_alpha)
    w2 = d * np.diag(Sw) + np.sum(M**2, axis=0)
    _, logdet_x = np.linalg.slogdet(Sx)
    _, logdet_w = np.linalg.slogdet(Sw)
    lik = n * d / 2 * (ln_tau - LOG_2PI) - tau / 2 * E
    p_x = -n * q / 2 * LOG_2PI - 0.5 * (n * np.trace(Sx) + np.sum(Mx**2))
    p_w = np.sum(d / 2 * ln_alpha - d / 2 * LOG_2PI - alpha / 2 * w2)
    p_mu = d / 2 * (np.log(beta) - LOG_2PI) - beta / 2 * (d * Smu + float(mu @ mu))
    p_alpha = np.sum(a * np.log(b) - gammaln(a) + (a - 1) * ln_alpha - b * alpha)
    p_tau = a * np.log(b) - gammaln(a) + (a - 1) * ln_tau - b * tau
    h_x = n * (q / 2 * (1 + LOG_2PI) + 0.5 * logdet_x)
    h_w = d * (q / 2 * (1 + LOG_2PI) + 0.5 * logdet_w)
    h_mu = d / 2 * (1 + LOG_2PI + np.log(Smu))
    h_alpha = np.sum(_gamma_entropy(a_alpha, b_alpha))
    h_tau = _gamma_entropy(a_tau, b_tau)
    return float(lik + p_x + p_w + p_mu + p_alpha + p_tau + h_x + h_w + h_mu + h_alpha + h_tau)
