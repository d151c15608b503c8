"""``hbeo``, ``hbeo-mdn-likelihood`` and ``hbeo-mdn-posterior``: Hybrid Bayesian
Eigenobjects (dissertation chapter 4) and HBEO-MDN with the silhouette prior (chapter 5).

Per view: the object-centred crop (:mod:`.hbeo_crop`) goes through the network once
(:mod:`.hbeo_net`), giving class probabilities, the translation offset, the log size, the
subspace coefficients and the rotation (relative to the crop-centre ray). The shape is the
back-projection W o' + mu of the coefficients (eq. 4.2), clipped to [0, 1].

HBEO-MDN's rotation is chosen among N samples of its mixture (N = ``samples``, the any-time
knob of Figure 5.3):

- ``likelihood`` (eq. 5.7): the sample of highest mixture density;
- ``posterior`` (eq. 5.5-5.8): density x silhouette prior 1 / (e^4 + eps), where e is the
  Frobenius norm of the difference between the signed distance fields of the observed mask
  and of the predicted shape re-projected at that sample. All N re-projections are one
  batched computation (:func:`silhouettes`): the shape's surface voxels go through every
  sampled rotation and K at once and are splatted into N crop-sized masks.

``Estimate.pose_samples`` holds the N camera-frame rotations and ``pose_weights`` their
normalised scores (density, or density x prior).
"""

from __future__ import annotations

import hashlib
import inspect
import zlib
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Literal

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from scipy.spatial.transform import Rotation
from scipy.special import logsumexp

from beo_bench.backend import as_bool, register_backend
from beo_bench.errors import UsageError
from beo_bench.geometry import orthonormalise
from beo_bench.names import check_name
from beo_bench.perception.beo_observe import grid_centres
from beo_bench.perception.digest import state_digest
from beo_bench.perception.hbeo_crop import Crop, make_crop
from beo_bench.perception.hbeo_net import Mixture, Output, point_rotation
from beo_bench.perception.hbeo_train import HBEOModel, load_hbeo
from beo_bench.types import Estimate, View

Mode = Literal["hbeo", "likelihood", "posterior"]
PRIOR_EPS = 1e-6
"""eps of the silhouette prior 1 / (e^4 + eps) (eq. 5.8)."""


class HBEOBackend:
    """HBEO / HBEO-MDN (module docstring). Keyword arguments (``--opt KEY=VALUE``):

    - ``model`` (None): a model name (``beo-bench train hbeo|hbeo-mdn --name``; a name
      under the cache's models, never a path); None uses the default small model: the
      published reference one, or for the options below the one ``beo-bench train`` made;
    - ``samples`` (25, MDN modes): N, the rotation samples drawn per view;
    - ``seed`` (0): with the crop's bytes, seeds the sampling (same view, same estimate);
    - ``size`` (``small``): with no ``model``, the default network's size: ``small`` or
      ``dissertation`` (Figure 4.2's widths: the ``reference`` recipe's, trained once on a GPU
      into the cache, never here; a missing one is an error naming the command);
    - ``per_category`` (False): chapter 5's protocol (Tables 5.1/5.2): one network per
      category, chosen by the view's class hint, so the backend runs in the class-given
      track only. Each class's network is the ``per-category`` recipe's (``beo-bench train
      hbeo-mdn --categories car --recipe per-category``), regressing that class's own BEO
      subspace; it is never trained here (a missing one is an error naming the command);
    - ``instances``, ``images``, ``epochs`` (None): the default model trained on this many
      instances per class, crops and epochs (quick checks; None: the default's) by
      ``beo-bench train hbeo|hbeo-mdn --per-category N --images N --epochs N``; a run never
      trains it (:class:`~beo_bench.errors.TrainingInRunError` names that command);
    - ``device`` (``cpu``): where the network runs: ``cpu``, ``cuda`` or ``auto`` (CUDA when
      available). The sampling and scoring stay on the CPU in float64;
    - ``threads`` (1): torch intra-op threads for this process. One image at a time is
      fastest on one thread: on 2 cores, two torch threads spinning beside numpy's BLAS
      threads made a prediction 2.4x slower (8.0 vs 3.3 ms, ``benchmarks/bench_hbeo.py``).
      None leaves torch's setting alone.
    """

    def __init__(
        self,
        mode: Mode,
        model: str | None = None,
        samples: int = 25,
        seed: int = 0,
        threads: int | None = 1,
        instances: int | None = None,
        images: int | None = None,
        epochs: int | None = None,
        device: str = "cpu",
        size: str = "small",
        per_category: bool = False,
    ) -> None:
        from beo_bench.perception.hbeo_train import resolve_device

        self.mode = mode
        self.device = resolve_device(str(device))
        self.name = "hbeo" if mode == "hbeo" else f"hbeo-mdn-{mode}"
        self.kind = "hbeo" if mode == "hbeo" else "hbeo-mdn"
        self.model_name = (
            None if model in (None, "", "None", "default") else check_name(str(model), "model")
        )
        if size not in ("small", "dissertation"):
            raise ValueError(f"size={size!r}: use 'small' or 'dissertation'")
        self.size = str(size)
        self.per_category = as_bool(per_category)
        if self.per_category and self.model_name is not None:
            raise ValueError(
                "per_category=true picks each class's per-category network itself: leave "
                "model unset"
            )
        # the class hint chooses the network: no hint, no estimate (class-given track only)
        self.wants_class_hint = self.needs_class_hint = self.per_category
        self.samples = int(samples)
        self.seed = int(seed)
        if self.samples < 1:
            raise ValueError(f"samples={samples}: draw at least one rotation sample")
        self.small = {
            k: None if v in (None, "None") else int(v)  # type: ignore[arg-type]
            for k, v in (("instances", instances), ("images", images), ("epochs", epochs))
        }
        self.threads = None if threads in (None, "None") else int(threads)  # type: ignore[arg-type]
        if self.threads is not None:
            torch.set_num_threads(max(1, self.threads))
        # class list -> (model, decoder A, b, the model's index of each class in the list)
        self._models: dict[
            tuple[str, ...], tuple[HBEOModel, np.ndarray, np.ndarray, np.ndarray]
        ] = {}
        self._digest: str | None = None
        self._digests: dict[int, str] = {}

    def prepare(self, categories: tuple[str, ...]) -> None:
        """Load (or train on first use, with progress bars) the model for ``categories``;
        with ``per_category``, each class's network (never trained here)."""
        groups = [(c,) for c in categories] if self.per_category else [tuple(categories)]
        digests = []
        for cats in groups:
            m = self._model(cats, progress=True)[0]
            if id(m) not in self._digests:  # the weights as loaded (published or cached)
                self._digests[id(m)] = state_digest(m.state())
            digests.append(self._digests[id(m)])
        # per category: one digest naming the set of networks, in class order
        self._digest = (
            digests[0]
            if len(digests) == 1
            else hashlib.sha256(" ".join(digests).encode()).hexdigest()[:16]
        )

    def model_digest(self) -> str | None:
        """The content digest (:func:`~beo_bench.perception.digest.state_digest`) of the
        model the last :meth:`prepare` loaded; None before any."""
        return self._digest

    def _model(
        self, cats: tuple[str, ...], progress: bool = False
    ) -> tuple[HBEOModel, np.ndarray, np.ndarray, np.ndarray]:
        if cats not in self._models:
            self._refuse_training(cats)
            m = load_hbeo(
                self.model_name,
                self.kind,  # type: ignore[arg-type]
                cats,
                progress,
                # the quick options select a trained model: never one trained here
                train_default=all(v is None for v in self.small.values()),
                size=self.size,
                recipe="per-category" if self.per_category else "default",
                **self.small,
            )
            m.net.to(self.device)
            # fold the coefficient standardisation into the decoder: shape = c_std A + b,
            # with A (k, d) row-major so the product streams it once (numpy's sgemv reads
            # the 15 MB of a 32^3 x 117 basis several times faster than torch's addmv)
            W = m.beo.basis.astype(np.float64)
            A = np.ascontiguousarray((W * m.coef_std[None]).T, dtype=np.float32)
            b = (m.beo.mean + W @ m.coef_mean).astype(np.float32)
            # the published network may know more classes than asked for (a suite on some
            # of them): its scores are read at theirs and renormalised
            idx = np.array([m.categories.index(c) for c in cats])
            self._models[cats] = (m, A, b, idx)
        return self._models[cats]

    def _refuse_training(self, cats: tuple[str, ...]) -> None:
        """With ``instances``, ``images`` or ``epochs`` and no model trained for them (on the
        library: a dataset's missing model is :func:`load_hbeo`'s error), the usage error
        that names the ``beo-bench train`` command making it: nothing trains in a run."""
        from beo_bench.envs.pick import default_categories
        from beo_bench.errors import TrainingInRunError
        from beo_bench.objects.dataset import active_dataset, train_command
        from beo_bench.perception.hbeo_train import (
            default_config,
            default_name,
            model_path,
            with_overrides,
        )

        given = {k: v for k, v in self.small.items() if v is not None}
        if not given or self.model_name is not None or self.per_category:
            return  # a named model, or per-category networks: load_hbeo never trains them
        if active_dataset() is not None:
            return
        cfg = with_overrides(default_config(self.kind, cats, **self.small), size=self.size)  # type: ignore[arg-type]
        if (model_path(default_name(cfg)) / "weights.pt").exists():
            return
        big = self.size != "small"
        how = train_command(
            self.kind,
            () if cats == default_categories() else cats,
            per_category=given.get("instances"),
            images=given.get("images"),
            epochs=given.get("epochs"),
            size=self.size if big else None,
            device="cuda" if big else None,
        )
        raise TrainingInRunError.of(self.name, given, how)

    def _classes(self, view: View) -> tuple[str, ...]:
        """The class list of the network that answers ``view``: the view's, or with
        ``per_category`` its hinted class alone."""
        if not self.per_category:
            return tuple(view.categories)
        if view.class_hint is None:
            raise UsageError(
                f"{self.name} with per_category=true chooses its network by the class hint, "
                "and this view has none: run it in a pose suite's class-given track"
            )
        return (view.categories[int(view.class_hint)],)

    def forward(self, view: View) -> Forward:
        """The network's outputs for ``view``, converted to the camera frame."""
        model, A, b, idx = self._model(self._classes(view))
        net, cfg = model.net, model.net.cfg
        crop = make_crop(view.depth, view.mask, view.K, cfg.crop)
        with torch.inference_mode():
            out = net(torch.from_numpy(crop.image)[None].to(self.device))
            if self.device.type != "cpu":  # the rest is numpy on the CPU
                out = Output(**{f.name: getattr(out, f.name).cpu() for f in fields(Output)})
            probs = torch.softmax(out.logits.double(), dim=1)[0].numpy()[idx]
        if self.per_category:  # a one-class network: the class is the hint
            probs = np.eye(len(view.categories))[int(view.class_hint)]  # type: ignore[arg-type]
        D = model.beo.D
        shape = out.coefficients[0].numpy() @ A + b  # eq. 4.2: W o' + mu
        np.clip(shape, 0.0, 1.0, out=shape)
        mdn = cfg.rotation == "mdn"
        if cfg.rotation == "axis-angle":
            w = out.rotation[0].double().numpy()
            R = crop.rotation_from(Rotation.from_rotvec(w).as_matrix())
        else:  # 6D, or the MDN's heaviest component
            R = crop.rotation_from(point_rotation(out, cfg)[0].double().numpy())
        return Forward(
            crop=crop,
            class_probs=probs / probs.sum(),
            rotation=R,
            translation=crop.translation_from(out.offset[0].numpy()),
            size=crop.size_from(out.log_size[0].numpy()),
            shape=shape.reshape(D, D, D),
            mixture=Mixture.from_raw(out.rotation, cfg.components) if mdn else None,
        )

    def predict(self, view: View) -> Estimate:
        f = self.forward(view)
        info: dict[str, object] = {"mode": self.mode}
        R, samples, weights = f.rotation, None, None
        if self.mode != "hbeo":
            s = self.rotation_samples(view, f, prior=self.mode == "posterior")
            score = s.log_likelihood.copy()
            if s.silhouette_error is not None:
                score -= np.log(s.silhouette_error**4 + PRIOR_EPS)  # eq. 5.8: x 1/(e^4 + eps)
            best = int(np.argmax(score))  # eq. 5.7 (likelihood) or the posterior mode
            R, samples = s.R[best], s.R
            weights = np.exp(score - score[best])
            weights /= weights.sum()
            info["samples"] = self.samples
            if s.silhouette_error is not None:
                info["silhouette_error"] = float(s.silhouette_error[best])
        return Estimate(
            class_probs=f.class_probs,
            rotation=orthonormalise(R),
            translation=f.translation,
            size=f.size,
            shape=f.shape,
            pose_samples=samples,
            pose_weights=weights,
            info=info,
        )

    def rotation_samples(self, view: View, f: Forward | None = None, prior: bool = True) -> Samples:
        """N = ``samples`` rotations drawn from the MDN's mixture for ``view`` (seeded by
        the crop), their log mixture density and (``prior``) their silhouette errors."""
        f = f if f is not None else self.forward(view)
        if f.mixture is None:
            raise ValueError(f"{self.name}: rotation samples need an hbeo-mdn model")
        mix = f.mixture
        seed = zlib.crc32(f.crop.image.tobytes()) ^ self.seed
        w = mix.sample(self.samples, np.random.default_rng(seed))[0]  # (N, 3)
        # eq. 5.7's density of each sample, in float64 numpy: N is small, and multi-threaded
        # float32 reductions could break ties differently from call to call
        lw, mu, var = (x[0].double().numpy() for x in (mix.log_weights, mix.means, mix.variances))
        d = w[:, None, :] - mu[None]
        comp = -0.5 * (d * d / var + np.log(2 * np.pi * var)).sum(-1)  # (N, M)
        R = f.crop.rotation_from(Rotation.from_rotvec(w).as_matrix())
        e = None
        if prior:
            shape = torch.from_numpy(f.shape)
            masks = silhouettes(shape, f.size, R, f.translation, view.K, f.crop)
            e = sdf_errors(f.crop.mask, masks)
        return Samples(R=R, log_likelihood=logsumexp(comp + lw, axis=1), silhouette_error=e)


@dataclass
class Forward:
    """One forward pass, in the camera frame: ``rotation`` is the regression (HBEO) or the
    heaviest component's mean (MDN); ``mixture`` the MDN's rotation mixture (ray frame)."""

    crop: Crop
    class_probs: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    size: np.ndarray
    shape: np.ndarray
    mixture: Mixture | None


@dataclass
class Samples:
    """N rotation samples (camera frame, (N, 3, 3)), their log mixture density (eq. 5.7)
    and their silhouette errors e (eq. 5.6; None when not computed)."""

    R: np.ndarray
    log_likelihood: np.ndarray
    silhouette_error: np.ndarray | None


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


def silhouettes(
    shape: torch.Tensor, size: np.ndarray, R: np.ndarray, t: np.ndarray, K: np.ndarray, crop: Crop
) -> np.ndarray:
    """(N, S, S) bool masks, in the crop's pixels, of ``shape`` (the estimate's unit-cube
    grid, edge = the largest extent) placed at each of the N rotations ``R`` (N, 3, 3) and
    translation ``t``: every surface voxel of every sample projected in one batched step,
    splatted, and closed (3x3) to fill the gaps between voxel centres."""
    S = crop.image.shape[-1]
    P = surface_points(shape, float(np.max(size))).double()
    Rt = torch.from_numpy(np.asarray(R, dtype=np.float64))
    X = torch.einsum("nij,pj->npi", Rt, P) + torch.from_numpy(np.asarray(t, dtype=np.float64))
    # image pixels through K, then the crop's affine map; one matrix does both
    M = torch.from_numpy(np.asarray(crop.affine, dtype=np.float64)) @ torch.from_numpy(
        np.asarray(K, dtype=np.float64)
    )
    z = X[..., 2].clamp_min(1e-6)
    xy = torch.einsum("ij,npj->npi", M, X) / z[..., None]
    ij = torch.floor(xy + 0.5).long()
    ok = (X[..., 2] > 1e-6) & (ij >= 0).all(-1) & (ij < S).all(-1)
    N = Rt.shape[0]
    flat = torch.arange(N)[:, None] * S * S + ij[..., 1] * S + ij[..., 0]
    canvas = torch.zeros(N * S * S + 1)
    canvas[torch.where(ok, flat, torch.full_like(flat, N * S * S)).reshape(-1)] = 1.0
    m = canvas[:-1].reshape(N, 1, S, S)
    m = F.max_pool2d(m, 3, stride=1, padding=1)  # closing: dilate ...
    m = -F.max_pool2d(-m, 3, stride=1, padding=1)  # ... then erode
    return m[:, 0].numpy() > 0.5


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


def sdf_errors(observed: np.ndarray, masks: np.ndarray) -> np.ndarray:
    """(N,) e_n = ||SDF(observed) - SDF(mask_n)||_F (eq. 5.6); an empty mask's SDF is its
    distance to nothing, so it gets the largest error of any present one times two."""
    ref = signed_distance(observed).astype(np.float64)
    e = np.empty(len(masks))
    empty = ~masks.reshape(len(masks), -1).any(1)
    for i, m in enumerate(masks):
        # numpy's pairwise sum, not BLAS: a threaded dot product is not bit-reproducible
        diff = ref - signed_distance(m)
        e[i] = np.inf if empty[i] else np.sqrt(np.sum(diff * diff))
    finite = e[np.isfinite(e)]
    e[~np.isfinite(e)] = 2 * finite.max() if len(finite) else 1.0
    return e


def _factory(mode: Mode) -> Callable[..., HBEOBackend]:
    def make(**kw: object) -> HBEOBackend:
        return HBEOBackend(mode, **kw)  # type: ignore[arg-type]

    # the options a user may pass are HBEOBackend's without ``mode``: published as the
    # factory's signature, `beo-bench run --opt bogus=1` lists them and type-checks values
    params = list(inspect.signature(HBEOBackend.__init__).parameters.values())
    make.__signature__ = inspect.Signature(  # type: ignore[attr-defined]
        [p for p in params if p.name not in ("self", "mode")]
    )
    return make


register_backend("hbeo")(_factory("hbeo"))
register_backend("hbeo-mdn-likelihood")(_factory("likelihood"))
register_backend("hbeo-mdn-posterior")(_factory("posterior"))
