"""HBEONet (dissertation Figure 4.2) and the HBEO-MDN pose head (chapter 5).

The trunk is four strided 3x3 convolutions (each halving the crop) and three shared fully
connected layers; separate linear heads give class logits, the rotation, the translation
offset, the log size and the subspace coefficients. The rotation head is either

- ``axis-angle`` (3 numbers, the dissertation's choice) regressed with L2 (eq. 4.3), or
- ``6d``: the first two columns of the matrix, made orthonormal by Gram-Schmidt (Zhou et
  al., CVPR 2019, continuous where axis-angle jumps at pi), regressed with L2 on them, or
- ``mdn``: a ``components``-component Gaussian mixture over the axis-angle parameters with
  diagonal covariances (eq. 5.1-5.2): means, variances through a translated ELU
  (elu(x) + 1 + eps > 0, eq. 5.3) and weights through a softmax; loss = its negative log
  likelihood (eq. 5.4).

Loss = class cross-entropy + pose + projection L2 on the coefficients (eq. 4.3, weights 1),
plus L2 on the translation offset and log size, which the dissertation's crops did not
need (its objects were centred) and ours do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal, cast

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

RotationHead = Literal["axis-angle", "6d", "mdn"]
ELU_SHIFT = 1.0 + 1e-4
"""sigma^2 = elu(x) + ELU_SHIFT: positive and smooth (the translated ELU of eq. 5.3)."""


@dataclass(frozen=True)
class NetConfig:
    """The network's shape. ``small`` (the default) trains in minutes on 2 CPU cores;
    ``dissertation`` has the widths of Figure 4.2's network."""

    classes: int
    coefficients: int
    crop: int = 64
    channels: tuple[int, ...] = (16, 32, 64, 128)
    hidden: tuple[int, int, int] = (256, 256, 256)
    rotation: RotationHead = "axis-angle"
    components: int = 5

    def __post_init__(self) -> None:
        if len(self.channels) != 4 or len(self.hidden) != 3:
            raise ValueError("HBEONet has four convolutions and three shared FC layers")
        if self.crop % 16:
            raise ValueError(f"crop={self.crop}: four stride-2 convolutions need a multiple of 16")
        if self.rotation not in ("axis-angle", "6d", "mdn"):
            raise ValueError(f"rotation={self.rotation!r}: use 'axis-angle', '6d' or 'mdn'")

    @classmethod
    def preset(cls, size: str, **kw: Any) -> NetConfig:
        if size == "small":
            return cls(**kw)
        if size == "dissertation":
            return cls(channels=(64, 128, 256, 512), hidden=(1024, 1024, 512), **kw)
        raise ValueError(f"network size {size!r}: use 'small' or 'dissertation'")

    @property
    def rotation_dim(self) -> int:
        if self.rotation == "mdn":
            return self.components * 7  # weight logit, 3 means, 3 variances
        return 6 if self.rotation == "6d" else 3


@dataclass
class Output:
    """Network outputs for a batch of B crops."""

    logits: torch.Tensor  # (B, C)
    rotation: torch.Tensor  # (B, 3) axis-angle, (B, 6) 6D, or the MDN's raw (B, 7M)
    offset: torch.Tensor  # (B, 3)
    log_size: torch.Tensor  # (B, 3)
    coefficients: torch.Tensor  # (B, k), standardised


class HBEONet(nn.Module):
    def __init__(self, cfg: NetConfig) -> None:
        super().__init__()
        self.cfg = cfg
        layers: list[nn.Module] = []
        cin = 2
        for c in cfg.channels:
            layers += [nn.Conv2d(cin, c, 3, stride=2, padding=1), nn.BatchNorm2d(c), nn.ReLU()]
            cin = c
        self.conv = nn.Sequential(*layers)
        flat = cin * (cfg.crop // 16) ** 2
        h1, h2, h3 = cfg.hidden
        self.fc = nn.Sequential(
            nn.Linear(flat, h1),
            nn.ReLU(),
            nn.Linear(h1, h2),
            nn.ReLU(),
            nn.Linear(h2, h3),
            nn.ReLU(),
        )
        self.head_class = nn.Linear(h3, cfg.classes)
        self.head_rotation = nn.Linear(h3, cfg.rotation_dim)
        self.head_offset = nn.Linear(h3, 3)
        self.head_size = nn.Linear(h3, 3)
        self.head_coef = nn.Linear(h3, cfg.coefficients)

    def forward(self, x: torch.Tensor) -> Output:
        h = self.fc(self.conv(x).flatten(1))
        return Output(
            logits=self.head_class(h),
            rotation=self.head_rotation(h),
            offset=self.head_offset(h),
            log_size=self.head_size(h),
            coefficients=self.head_coef(h),
        )


# -- rotation parametrisations ---------------------------------------------------------------
def rotvec_to_matrix(w: torch.Tensor) -> torch.Tensor:
    """(..., 3) axis-angle -> (..., 3, 3) (Rodrigues, stable at 0)."""
    th2 = (w * w).sum(-1, keepdim=True)
    th = th2.clamp_min(1e-12).sqrt()
    small = th2 < 1e-8
    a = torch.where(small, 1 - th2 / 6, torch.sin(th) / th)[..., None]
    b = torch.where(small, 0.5 - th2 / 24, (1 - torch.cos(th)) / th2.clamp_min(1e-12))[..., None]
    z = torch.zeros_like(w[..., 0])
    K = torch.stack(
        [
            torch.stack([z, -w[..., 2], w[..., 1]], -1),
            torch.stack([w[..., 2], z, -w[..., 0]], -1),
            torch.stack([-w[..., 1], w[..., 0], z], -1),
        ],
        -2,
    )
    eye = torch.eye(3, dtype=w.dtype, device=w.device).expand(K.shape)
    return eye + a * K + b * (K @ K)


def sixd_to_matrix(x: torch.Tensor) -> torch.Tensor:
    """(..., 6) two columns -> (..., 3, 3) by Gram-Schmidt (Zhou et al. 2019)."""
    a, b = x[..., :3], x[..., 3:]
    c1 = F.normalize(a, dim=-1)
    c2 = F.normalize(b - (c1 * b).sum(-1, keepdim=True) * c1, dim=-1)
    return torch.stack([c1, c2, torch.cross(c1, c2, dim=-1)], -1)


def matrix_to_sixd(R: torch.Tensor) -> torch.Tensor:
    return torch.cat([R[..., :, 0], R[..., :, 1]], -1)


# -- the mixture density head ----------------------------------------------------------------
@dataclass
class Mixture:
    """A batch of diagonal Gaussian mixtures over R^3: ``log_weights`` (B, M),
    ``means`` (B, M, 3), ``variances`` (B, M, 3)."""

    log_weights: torch.Tensor
    means: torch.Tensor
    variances: torch.Tensor

    @classmethod
    def from_raw(cls, raw: torch.Tensor, components: int) -> Mixture:
        r = raw.reshape(raw.shape[0], components, 7)
        return cls(
            log_weights=F.log_softmax(r[..., 0], dim=-1),
            means=r[..., 1:4],
            variances=F.elu(r[..., 4:7]) + ELU_SHIFT,
        )

    def log_prob(self, y: torch.Tensor) -> torch.Tensor:
        """log p(y) for y (B, S, 3) (S points per mixture) -> (B, S) (eq. 5.1-5.2)."""
        d = y[:, :, None, :] - self.means[:, None]  # (B, S, M, 3)
        v = self.variances[:, None]
        comp = -0.5 * (d * d / v + torch.log(2 * math.pi * v)).sum(-1)  # (B, S, M)
        return torch.logsumexp(comp + self.log_weights[:, None], dim=-1)

    def nll(self, y: torch.Tensor) -> torch.Tensor:
        """Mean negative log likelihood of y (B, 3) (eq. 5.4)."""
        return -self.log_prob(y[:, None]).mean()

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(B, n, 3) draws: a component by its weight, then its Gaussian."""
        w = self.log_weights.exp().double().cpu().numpy()
        mu = self.means.double().cpu().numpy()
        sd = np.sqrt(self.variances.double().cpu().numpy())
        B, M = w.shape
        u = rng.random((B, n))
        comp = np.minimum((u[..., None] > np.cumsum(w, axis=1)[:, None]).sum(-1), M - 1)
        bi = np.arange(B)[:, None]
        eps = rng.standard_normal((B, n, 3))
        return mu[bi, comp] + sd[bi, comp] * eps


def losses(out: Output, cfg: NetConfig, target: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The loss terms of a batch (eq. 4.3 / 5.4); ``total`` is their sum (weights 1). With
    ``target["coef_weight"]`` (k weights of mean 1) the projection term weights each
    standardised coefficient's squared error, e.g. by its variance: then it is the voxel-space
    L2 of the reconstruction, since W has orthonormal columns."""
    sq = (out.coefficients - target["coefficients"]) ** 2
    if "coef_weight" in target:  # the variance-weighted ablation (HBEOConfig.projection_weighting)
        sq = sq * target["coef_weight"]
    terms = {
        "class": F.cross_entropy(out.logits, target["label"]),
        "projection": sq.sum(-1).mean() / target["coefficients"].shape[-1],
        "offset": ((out.offset - target["offset"]) ** 2).sum(-1).mean(),
        "size": ((out.log_size - target["log_size"]) ** 2).sum(-1).mean(),
    }
    if cfg.rotation == "mdn":
        terms["pose"] = Mixture.from_raw(out.rotation, cfg.components).nll(target["rotvec"])
    elif cfg.rotation == "6d":
        terms["pose"] = ((out.rotation - matrix_to_sixd(target["R"])) ** 2).sum(-1).mean()
    else:
        terms["pose"] = ((out.rotation - target["rotvec"]) ** 2).sum(-1).mean()
    # a sum of tensors is a tensor (the stubs' int is the empty sum's 0)
    terms["total"] = cast(torch.Tensor, sum(terms.values()))
    return terms


def point_rotation(out: Output, cfg: NetConfig) -> torch.Tensor:
    """(B, 3, 3) one rotation per crop: the regression, or the MDN's heaviest mean."""
    if cfg.rotation == "6d":
        return sixd_to_matrix(out.rotation)
    if cfg.rotation == "mdn":
        m = Mixture.from_raw(out.rotation, cfg.components)
        best = m.log_weights.argmax(-1)
        return rotvec_to_matrix(m.means[torch.arange(len(best), device=best.device), best])
    return rotvec_to_matrix(out.rotation)


def geodesic_deg(A: torch.Tensor, B: torch.Tensor) -> torch.Tensor:
    """(B,) angle between rotation batches, degrees."""
    c = ((A.transpose(-1, -2) @ B).diagonal(dim1=-2, dim2=-1).sum(-1) - 1) / 2
    return torch.rad2deg(torch.arccos(c.clamp(-1, 1)))
