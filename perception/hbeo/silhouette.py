"""HBEO-MDN's silhouette check of pose samples (dissertation chapter 5, the posterior's
likelihood term): a sample's shape projected at its pose into the crop's or the view's
pixels, and its signed-distance error against the observed mask."""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np
import torch
import torch.nn.functional as F

from beo_bench.errors import ViewError
from beo_bench.perception.beo.observe import grid_centres
from beo_bench.perception.hbeo.crop import Crop
from beo_bench.types import View

if TYPE_CHECKING:
    pass


def _cross() -> torch.Tensor:
    k = torch.zeros(1, 1, 3, 3, 3)
    k[0, 0, 1, 1, :] = k[0, 0, 1, :, 1] = k[0, 0, :, 1, 1] = 1
    return k


_CROSS = _cross()
"""The 3x3x3 6-neighbourhood (with the centre), built once for :func:`surface_points`."""


def surface_points(shape: torch.Tensor, edge: float) -> torch.Tensor:
    """(P, 3) canonical-frame centres (m) of the surface voxels of ``shape`` > 0.5 (above
    half its maximum when nothing is): occupied voxels with an empty 6-neighbour."""
    D = shape.shape[0]
    thr = 0.5 if bool((shape > 0.5).any()) else 0.5 * float(shape.max())
    occ = (shape >= thr) & (shape > 0)
    empty = (~occ).float()[None, None]
    # a voxel is interior when its 6 neighbours are occupied: dilate the empty set by a cross
    near_empty = F.conv3d(F.pad(empty, (1,) * 6, value=1.0), _CROSS)[0, 0] > 0
    surf = (occ & near_empty).reshape(-1)
    return grid_centres(D)[surf] * edge


VIEW_PAD = 0.25
"""``prior_pixels=view``: the observed mask's box, padded by this fraction of its side on
every side, is where the silhouettes are compared (a re-projection may reach past it)."""


def view_window(view: View) -> tuple[np.ndarray, tuple[int, int], tuple[int, int]]:
    """The (2, 3) affine from image pixels to the window's, its (h, w) and its top-left
    (row, column): the observed mask's bounding box padded by :data:`VIEW_PAD`, within the
    image."""
    m = np.asarray(view.mask, dtype=bool)
    vs, us = np.nonzero(m)
    if len(vs) == 0:
        raise ViewError("the view's mask is empty: the silhouette prior has nothing to compare")
    H, W = m.shape
    ph = int(np.ceil(VIEW_PAD * (vs.max() - vs.min() + 1)))
    pw = int(np.ceil(VIEW_PAD * (us.max() - us.min() + 1)))
    y0, y1 = max(0, int(vs.min()) - ph), min(H, int(vs.max()) + ph + 1)
    x0, x1 = max(0, int(us.min()) - pw), min(W, int(us.max()) + pw + 1)
    affine = np.array([[1.0, 0.0, -x0], [0.0, 1.0, -y0]])
    return affine, (y1 - y0, x1 - x0), (y0, x0)


def silhouettes(
    shape: torch.Tensor, size: np.ndarray, R: np.ndarray, t: np.ndarray, K: np.ndarray, crop: Crop
) -> np.ndarray:
    """(N, S, S) bool masks, in the crop's pixels, of ``shape`` (the estimate's unit-cube
    grid, edge = the largest extent) placed at each of the N rotations ``R`` (N, 3, 3) and
    translation ``t`` (:func:`project_masks` into the crop)."""
    S = crop.image.shape[-1]
    return project_masks(shape, size, R, t, K, np.asarray(crop.affine), (S, S))


def project_masks(
    shape: torch.Tensor,
    size: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    K: np.ndarray,
    affine: np.ndarray,
    hw: tuple[int, int],
) -> np.ndarray:
    """(N, h, w) bool masks of ``shape`` at each rotation of ``R`` and translation ``t``, in
    the pixels ``affine`` (2, 3) maps the image's to: every surface voxel of every sample
    projected in one batched step, splatted, and closed (3x3) to fill the gaps between
    voxel centres."""
    h, w = hw
    P = surface_points(shape, float(np.max(size))).double()
    Rt = torch.from_numpy(np.asarray(R, dtype=np.float64))
    X = torch.einsum("nij,pj->npi", Rt, P) + torch.from_numpy(np.asarray(t, dtype=np.float64))
    # image pixels through K, then the crop's affine map; one matrix does both
    M = torch.from_numpy(np.asarray(affine, dtype=np.float64)) @ torch.from_numpy(
        np.asarray(K, dtype=np.float64)
    )
    z = X[..., 2].clamp_min(1e-6)
    xy = torch.einsum("ij,npj->npi", M, X) / z[..., None]
    ij = torch.floor(xy + 0.5).long()
    ok = (X[..., 2] > 1e-6) & (ij >= 0).all(-1) & (ij[..., 0] < w) & (ij[..., 1] < h)
    N = Rt.shape[0]
    flat = torch.arange(N)[:, None] * h * w + ij[..., 1] * w + ij[..., 0]
    canvas = torch.zeros(N * h * w + 1)
    canvas[torch.where(ok, flat, torch.full_like(flat, N * h * w)).reshape(-1)] = 1.0
    m = canvas[:-1].reshape(N, 1, h, w)
    m = F.max_pool2d(m, 3, stride=1, padding=1)  # closing: dilate ...
    m = -F.max_pool2d(-m, 3, stride=1, padding=1)  # ... then erode
    return m[:, 0].numpy() > 0.5


def align_centroids(masks: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """Each of ``masks`` (N, h, w) shifted by whole pixels so that its centroid falls on the
    observed mask's (what leaves the frame is lost; an empty mask stays empty): the
    silhouettes compared at the observed position, whatever the translation's error."""
    out = np.zeros_like(masks)
    obs = np.argwhere(observed)
    if not len(obs):
        return masks
    target = obs.mean(0)
    h, w = masks.shape[1:]
    for i, m in enumerate(masks):
        px = np.argwhere(m)
        if not len(px):
            continue
        dy, dx = (int(v) for v in np.rint(target - px.mean(0)))
        ys, xs = px[:, 0] + dy, px[:, 1] + dx
        ok = (ys >= 0) & (ys < h) & (xs >= 0) & (xs < w)
        out[i, ys[ok], xs[ok]] = True
    return out


def signed_distance(mask: np.ndarray) -> np.ndarray:
    """2D signed distance field (pixels): positive outside the mask, negative inside."""
    m = np.asarray(mask, dtype=np.uint8)

    def exact(x: np.ndarray) -> np.ndarray:
        # the precise transform is exact Euclidean (squared distances are integers), but its
        # float32 result differs in the last bit from call to call: round d^2 to recover
        # the exact value, so the same view always gives the same estimate
        d = cv2.distanceTransform(x, cv2.DIST_L2, cv2.DIST_MASK_PRECISE).astype(np.float64)
        return np.sqrt(np.rint(d * d))

    return exact(1 - m) - exact(m)


def sdf_errors(
    observed: np.ndarray, masks: np.ndarray, valid: np.ndarray | None = None
) -> np.ndarray:
    """(N,) e_n = ||SDF(observed) - SDF(mask_n)||_F (eq. 5.6), over the ``valid`` pixels
    only when given (those no other object covers); an empty mask's SDF is its distance to
    nothing, so it gets the largest error of any present one times two."""
    ref = signed_distance(observed).astype(np.float64)
    e = np.empty(len(masks))
    empty = np.asarray(~masks.reshape(len(masks), -1).any(1))
    keep = None if valid is None else np.asarray(valid, dtype=np.float64)
    for i, m in enumerate(masks):
        # numpy's pairwise sum, not BLAS: a threaded dot product is not bit-reproducible
        diff = ref - signed_distance(m)
        if keep is not None:
            diff *= keep
        e[i] = np.inf if empty[i] else np.sqrt(np.sum(diff * diff))
    finite = e[np.isfinite(e)]
    e[~np.isfinite(e)] = 2 * finite.max() if len(finite) else 1.0
    return e
