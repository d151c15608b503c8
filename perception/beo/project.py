"""Partial projection into BEO's subspace, batched over pose hypotheses (dissertation eq.
3.14-3.19), and back-projection (eq. 3.7).

With S_b the selection of hypothesis b's known voxels (filled or known empty) and o_b its
observed values there (1 filled, 0 empty), the code is

    o'_b = argmin_x  1/2 |S_b (W x + mu) - o_b|^2 + lasso |x|_1

The quadratic part is ``1/2 x^T G_b x - c_b^T x`` with ``G_b = W^T S_b W`` (k x k) and
``c_b = W^T S_b (o_b - mu)``. The known voxels are most of the grid (everything the camera
saw through), so both are computed from the few *unknown* and *filled* voxels:
``G_b = W^T W - W_U^T W_U`` and ``c_b = W_F^T 1 - (W^T mu - W_U^T mu_U)`` (or directly
from the known voxels when those are fewer): gathers of the basis rows at padded index
lists, one batched matmul, O(min(|U|, |K|) k^2) per hypothesis instead of O(d k^2).
A hypothesis a few degrees from one already projected (the fine step's pattern search)
starts from that one's Gram matrix instead (:func:`update_gram`): only the voxels whose
state changed, 2-10% of them, are gathered.
The lasso problem is then solved in k dimensions for all hypotheses at once by iteratively
reweighted ridge steps (batched Cholesky solves). The lasso keeps the directions that the
visible part does not constrain at the mean, which is what the dissertation adds it for.

A :class:`Subspace` exists per grid resolution: the model's own (orthonormal W), and a
coarser one for the coarse pose search (the basis and mean average-pooled by an integer
factor; W^T W is then no longer the identity and is kept).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from beo_bench.perception.beo.model import BEOModel


@dataclass(frozen=True)
class Subspace:
    """The basis and mean at one resolution, as float32 tensors."""

    D: int
    W: torch.Tensor
    """(d, k) basis rows per voxel (flattened [x, y, z] C-order)."""
    mu: torch.Tensor
    """(d,) mean."""
    WtW: torch.Tensor
    """(k, k) W^T W."""
    Wmu: torch.Tensor
    """(k,) W^T mu."""
    lipschitz: float
    """Largest eigenvalue of W^T W."""
    rows: torch.Tensor
    """(d + 1, k + 1) [W, mu] with a zero row appended: one gather of a voxel's row gives
    its basis row and mean, and padding (index d) gathers zeros."""
    gram: torch.Tensor
    """(k + 1, k + 1) [W, mu]^T [W, mu] over the whole grid, assembled from ``WtW`` and
    ``Wmu`` (so that a Gram matrix subtracted from it is what subtracting from those gave)."""

    @classmethod
    def from_model(
        cls, model: BEOModel, factor: int = 1, components: int | None = None
    ) -> Subspace:
        """The model's subspace, average-pooled by ``factor`` along each axis, keeping its
        leading ``components`` columns (None: all; the columns come from an SVD, strongest
        first, so a prefix is the best subspace of that size)."""
        D = model.D
        if D % factor:
            raise ValueError(f"the pooling factor {factor} does not divide D={D}")
        W = torch.from_numpy(model.basis[:, :components]).float()
        mu = torch.from_numpy(model.mean).float()
        if factor > 1:
            k = W.shape[1]
            grid = torch.cat([W.T, mu[None]]).reshape(k + 1, 1, D, D, D)
            pooled = torch.nn.functional.avg_pool3d(grid, factor).reshape(k + 1, -1)
            W, mu = pooled[:k].T.contiguous(), pooled[k].contiguous()
        WtW = W.T @ W
        rows = torch.cat([torch.cat([W, mu[:, None]], 1), torch.zeros(1, W.shape[1] + 1)])
        Wmu = W.T @ mu
        gram = torch.empty(W.shape[1] + 1, W.shape[1] + 1)
        gram[:-1, :-1], gram[:-1, -1], gram[-1, :-1], gram[-1, -1] = WtW, Wmu, Wmu, mu @ mu
        return cls(
            D=D // factor,
            W=W,
            mu=mu,
            WtW=WtW,
            Wmu=Wmu,
            lipschitz=float(torch.linalg.eigvalsh(WtW)[-1]),
            rows=rows.contiguous(),
            gram=gram,
        )

    @property
    def k(self) -> int:
        return int(self.W.shape[1])

    def decode(self, codes: torch.Tensor) -> torch.Tensor:
        """(B, d) back-projections W o' + mu (eq. 3.7), not clipped."""
        return torch.addmm(self.mu, codes, self.W.T)


@dataclass
class Completion:
    """Codes and back-projections of hypotheses at full resolution."""

    codes: torch.Tensor
    """(B, k)."""
    grids: torch.Tensor
    """(B, d) back-projections W o' + mu (not clipped); (B, 0) where not asked for (the
    fine step's scores need only the codes)."""
    known: torch.Tensor
    """(B, d) the hypotheses' known voxels (filled or known empty)."""
    gram: torch.Tensor
    """(B, k + 1, k + 1) their :func:`known_gram`: what a hypothesis a few
    degrees away starts from (:meth:`BEOBackend.complete`'s ``near``)."""

    def take(self, idx: torch.Tensor) -> Completion:
        return Completion(self.codes[idx], self.grids[idx], self.known[idx], self.gram[idx])

    def where(self, moved: torch.Tensor, other: Completion) -> Completion:
        """``other``'s rows where ``moved`` (B,), these elsewhere."""
        mine = (self.codes, self.grids, self.known, self.gram)
        theirs = (other.codes, other.grids, other.known, other.gram)
        return Completion(
            *(
                torch.where(moved.reshape(-1, *[1] * (a.dim() - 1)), b, a)
                for a, b in zip(mine, theirs, strict=True)
            )
        )


def padded_indices(mask: torch.Tensor, pad: int) -> torch.Tensor:
    """The True positions of each row of (B, d) ``mask`` as (B, n_max) indices, rows with
    fewer than n_max True padded with ``pad``."""
    B, d = mask.shape
    counts = mask.sum(dim=1)
    n_max = max(int(counts.max()), 1)
    # each True position goes to its rank among its row's True; the False to a spare slot
    slot = torch.where(mask, torch.cumsum(mask, dim=1) - 1, n_max)
    idx = torch.full((B, n_max + 1), pad, dtype=torch.long)
    idx.scatter_(1, slot, torch.arange(d).expand(B, d))
    return idx[:, :n_max]


def gather_rows(sub: Subspace, mask: torch.Tensor) -> torch.Tensor:
    """(B, n_max, k + 1) the rows [W, mu] of each hypothesis's True voxels of (B, d)
    ``mask``, padded with zero rows (one index_select of :attr:`Subspace.rows`: three times
    faster than advanced indexing, the same copy)."""
    idx = padded_indices(mask, sub.W.shape[0])
    return sub.rows.index_select(0, idx.reshape(-1)).reshape(*idx.shape, -1)


def known_gram(sub: Subspace, known: torch.Tensor) -> torch.Tensor:
    """(B, k + 1, k + 1) ``[W, mu]_K^T [W, mu]_K`` over each hypothesis's known voxels
    (``known`` (B, d)): its [:k, :k] block is G = W^T S W and its [:k, k] column W^T S mu.
    Gathered over whichever of the unknown or the known voxels are fewer (a view from far
    away, or an occluded one, leaves most of the cube unknown)."""
    if int(known.sum(dim=1).max()) < int((~known).sum(dim=1).max()):
        Rk = gather_rows(sub, known)  # (B, n_k, k + 1): [W_K, mu_K]
        return Rk.transpose(1, 2) @ Rk
    Ru = gather_rows(sub, ~known)  # (B, n_u, k + 1): [W_U, mu_U]
    return sub.gram - Ru.transpose(1, 2) @ Ru


def update_gram(
    sub: Subspace, gram: torch.Tensor, known_from: torch.Tensor, known_to: torch.Tensor
) -> torch.Tensor | None:
    """:func:`known_gram` of ``known_to`` from that of ``known_from`` (each (B, d); ``gram``
    (B, k + 1, k + 1)): plus the rows of the voxels that became known, minus those of the
    voxels no longer known. A hypothesis turned a few degrees from another sees nearly the
    same voxels (the fine step's pattern search: 2-10% of them change), so this gathers a
    tenth of the rows or fewer. Equal to :func:`known_gram` up to float32 rounding (a sum
    in another order). None where the change is not smaller than what :func:`known_gram`
    gathers (then call it)."""
    gained = known_to & ~known_from
    lost = known_from & ~known_to
    changed = int((gained.sum(dim=1) + lost.sum(dim=1)).max())
    direct = min(int(known_to.sum(dim=1).max()), int((~known_to).sum(dim=1).max()))
    if changed >= direct:
        return None
    Rg = gather_rows(sub, gained)
    Rl = gather_rows(sub, lost)
    return gram + Rg.transpose(1, 2) @ Rg - Rl.transpose(1, 2) @ Rl


def normal_equations(
    sub: Subspace, filled: torch.Tensor, empty: torch.Tensor, gram: torch.Tensor | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    """G (B, k, k) = W^T S W and c (B, k) = W^T S (o - mu) of the hypotheses' observations,
    from their :func:`known_gram` (computed here where ``gram`` is None)."""
    k = sub.k
    if gram is None:
        gram = known_gram(sub, filled | empty)
    G, W_mu = gram[:, :k, :k], gram[:, :k, k]
    Wf = gather_rows(sub, filled)[..., :k].sum(dim=1)
    return G, Wf - W_mu


def solve_lasso(
    G: torch.Tensor, c: torch.Tensor, lasso: float, lipschitz: float, iterations: int = 5
) -> torch.Tensor:
    """argmin_x 1/2 x^T G x - c^T x + lasso |x|_1 for every batch row (eq. 3.18-3.19).

    Iteratively reweighted ridge (a majorise-minimise scheme for the L1 term: |x_i| <=
    x_i^2 / (2 |x_i^t|) + |x_i^t| / 2), each step one batched k x k Cholesky solve; a few
    steps suffice because the lasso is gentle. A tiny Tikhonov term keeps directions that no
    known voxel constrains solvable (they stay at the mean)."""
    k = G.shape[-1]
    ridge = torch.full((k,), 1e-4 * lipschitz, dtype=G.dtype)
    x = _spd_solve(G, ridge, c)
    if lasso <= 0:
        return x
    for _ in range(iterations):
        x = _spd_solve(G, ridge + lasso / (x.abs() + 1e-3), c)
    return x


def _spd_solve(G: torch.Tensor, diag: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
    """(G + diag(diag)) x = c for symmetric positive definite systems, by Cholesky."""
    L = torch.linalg.cholesky(G + torch.diag_embed(diag))
    return torch.cholesky_solve(c[..., None], L)[..., 0]


def project(
    sub: Subspace,
    filled: torch.Tensor,
    empty: torch.Tensor,
    lasso: float,
    gram: torch.Tensor | None = None,
) -> torch.Tensor:
    """(B, k) codes of B partially observed grids (filled and known-empty masks (B, d));
    ``gram``: their :func:`known_gram` where the caller has it."""
    G, c = normal_equations(sub, filled, empty, gram)
    return solve_lasso(G, c, lasso, sub.lipschitz)
