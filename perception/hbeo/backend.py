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
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from scipy.spatial.transform import Rotation
from scipy.special import logsumexp

from beo_bench.backend import Backend, Capabilities, ClassHint, PrepareContext
from beo_bench.errors import UsageError, ViewError
from beo_bench.geometry import orthonormalise
from beo_bench.metrics import rotation_error
from beo_bench.names import check_name
from beo_bench.objects import instance_from_key
from beo_bench.options import option
from beo_bench.perception.digest import state_digest
from beo_bench.perception.hbeo.crop import Crop, make_crop
from beo_bench.perception.hbeo.model import HBEOModel
from beo_bench.perception.hbeo.net import Mixture, Output, point_rotation
from beo_bench.perception.hbeo.silhouette import (
    align_centroids,
    project_masks,
    sdf_errors,
    view_window,
)
from beo_bench.perception.hbeo.train import load_hbeo
from beo_bench.types import Estimate, GroundTruth, View

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset

Mode = Literal["hbeo", "likelihood", "posterior"]
DEVICES = ("cpu", "cuda", "auto")
PRIOR_EPS = 1e-6
"""eps of the silhouette prior 1 / (e^4 + eps) (eq. 5.8)."""


@dataclass(frozen=True)
class HBEOOptions:
    """The options of ``hbeo``, ``hbeo-mdn-likelihood`` and ``hbeo-mdn-posterior``
    (``beo-bench run --opt KEY=VALUE``)."""

    model: str | None = option(
        None,
        "a model name (beo-bench train hbeo|hbeo-mdn --name; a name under the cache's "
        "models, never a path); null: the default small model (the published reference "
        "one, or for the options below the one beo-bench train made)",
    )
    samples: int = option(25, "MDN modes: N, the rotation samples drawn per view")
    seed: int = option(0, "with the crop's bytes, seeds the sampling (same view, same estimate)")
    threads: int | None = option(
        1,
        "torch intra-op threads for this process (one image at a time is fastest on one "
        "thread); null leaves torch's setting alone",
    )
    instances: int | None = option(
        None,
        "the default model trained on this many instances per class by beo-bench train "
        "--per-category N (a run never trains it); null: the default's",
    )
    images: int | None = option(
        None, "the default model trained on this many crops (beo-bench train --images N)"
    )
    epochs: int | None = option(
        None, "the default model trained for this many epochs (beo-bench train --epochs N)"
    )
    device: str = option(
        "cpu",
        "where the network runs: cpu, cuda or auto (CUDA when available); the sampling and "
        "scoring stay on the CPU in float64",
    )
    size: Literal["small", "dissertation"] = option(
        "small",
        "with no model, the default network's size: small, or dissertation (Figure 4.2's "
        "widths, trained once on a GPU into the cache, never here)",
    )
    per_category: bool = option(
        False,
        "chapter 5's protocol (Tables 5.1/5.2): one network per category, chosen by the "
        "view's class hint (class-given track only; each is the per-category recipe's: "
        "the MDNs of car, airplane and sofa are published, any other is trained first with "
        "`beo-bench train`, never here)",
    )

    grasp: Literal["best", "robust"] = option(
        "best",
        "hbeo-mdn modes, pick only: plan the grasp on the chosen sample's pose (best), or "
        "choose the planned grasp most likely to hold across the N weighted pose samples "
        "(robust)",
    )

    # chapter 5's ablation (issue 48): what the silhouette prior could do with better
    # inputs, and the dissertation's two baselines; hbeo-mdn-posterior only
    select: Literal["score", "prior", "oracle"] = option(
        "score",
        "hbeo-mdn-posterior: how a sample is chosen: score (eq. 5.5-5.8, density x prior), "
        "prior (Random Sample + SDF Error: the silhouette prior alone) or oracle (Random "
        "Sample + Oracle: the sample nearest the truth; privileged, a diagnostic bound)",
    )
    prior_shape: Literal["estimate", "hbeo", "truth"] = option(
        "estimate",
        "hbeo-mdn-posterior: the shape the prior re-projects: the estimate, the hbeo "
        "network's (its shape and size, from its own forward pass of the same crop), or the "
        "instance's true voxels at its true size (privileged, a diagnostic ceiling)",
    )
    prior_translation: Literal["estimate", "hbeo", "aligned", "truth"] = option(
        "estimate",
        "hbeo-mdn-posterior: where the prior places the shape: the network's translation, "
        "the hbeo network's, aligned (the network's, each sample's silhouette then shifted "
        "so its centroid falls on the observed mask's), or the true one (privileged, a "
        "diagnostic)",
    )
    prior_grid: int = option(
        32,
        "hbeo-mdn-posterior: the grid the prior re-projects, 32 (the decode's) or 64 (the "
        "decode resampled trilinearly; with prior_shape=truth the true voxels at 64^3)",
    )
    prior_pixels: Literal["crop", "view"] = option(
        "crop",
        "hbeo-mdn-posterior: where the silhouettes are compared: the network's 64x64 crop, "
        "or the view's own pixels (the object's box, padded by a quarter)",
    )
    prior_occlusion: bool = option(
        False,
        "hbeo-mdn-posterior: compare only the pixels no other object covers (the view's "
        "segmentation; isolated views have none)",
    )

    def diagnostic_truth(self) -> bool:
        """Whether the options hand the backend the truth (a privileged diagnostic row)."""
        return (
            self.select == "oracle"
            or self.prior_shape == "truth"
            or self.prior_translation == "truth"
        )

    def prior_options(self) -> dict[str, object]:
        """The chapter-5 ablation options that differ from their defaults."""
        return {
            f.name: getattr(self, f.name)
            for f in fields(self)
            if f.name in PRIOR_OPTIONS and getattr(self, f.name) != f.default
        }

    def __post_init__(self) -> None:
        if self.select not in ("score", "prior", "oracle"):
            raise ValueError(f"select={self.select!r}: use score, prior or oracle")
        if self.prior_shape not in ("estimate", "hbeo", "truth"):
            raise ValueError(f"prior_shape={self.prior_shape!r}: use estimate, hbeo or truth")
        if self.prior_translation not in ("estimate", "hbeo", "aligned", "truth"):
            raise ValueError(
                f"prior_translation={self.prior_translation!r}: use estimate, hbeo, aligned "
                "or truth"
            )
        if self.prior_grid not in (32, 64):
            raise ValueError(f"prior_grid={self.prior_grid}: use 32 or 64")
        if self.prior_pixels not in ("crop", "view"):
            raise ValueError(f"prior_pixels={self.prior_pixels!r}: use crop or view")
        if self.model is not None:
            check_name(self.model, "model")
        if self.size not in ("small", "dissertation"):
            raise ValueError(f"size={self.size!r}: use 'small' or 'dissertation'")
        if self.per_category and self.model is not None:
            raise ValueError(
                "per_category=true picks each class's per-category network itself: leave "
                "model unset"
            )
        if self.samples < 1:
            raise ValueError(f"samples={self.samples}: draw at least one rotation sample")
        if self.grasp not in ("best", "robust"):
            raise ValueError(f"grasp={self.grasp!r}: use best or robust")
        if self.device not in DEVICES:
            raise ValueError(f"device {self.device!r}: use auto, cpu or cuda")


PRIOR_OPTIONS = (
    "select",
    "prior_shape",
    "prior_translation",
    "prior_grid",
    "prior_pixels",
    "prior_occlusion",
)
"""The options of chapter 5's ablation, which only ``hbeo-mdn-posterior`` takes."""

MODE_OPTIONS: dict[str, tuple[Mode, ...]] = {
    "samples": ("likelihood", "posterior"),
    "seed": ("likelihood", "posterior"),
    "grasp": ("likelihood", "posterior"),
    **{name: ("posterior",) for name in PRIOR_OPTIONS},
}
"""The options that only some modes use (the pose samples' and the silhouette prior's);
every other option is every mode's. A mode refuses the others (:meth:`HBEOBackend.parse`):
they would change nothing but the run's name."""


def mode_options(mode: Mode) -> tuple[str, ...]:
    """The options ``mode`` uses, in their declaration order."""
    return tuple(f.name for f in fields(HBEOOptions) if mode in MODE_OPTIONS.get(f.name, (mode,)))


class HBEOBackend(Backend):
    """HBEO (module docstring; options: :class:`HBEOOptions`); its subclasses are the
    HBEO-MDN modes. ``threads``: one image at a time is fastest on one thread: on 2 cores,
    two torch threads spinning beside numpy's BLAS threads made a prediction 2.4x slower
    (8.0 vs 3.3 ms, ``benchmarks/bench_hbeo.py``)."""

    name = "hbeo"
    mode: ClassVar[Mode] = "hbeo"
    Options = HBEOOptions
    options: HBEOOptions

    @classmethod
    def capabilities_for(cls, options: HBEOOptions) -> Capabilities:
        """With ``per_category`` the class hint chooses the network (no hint, no estimate:
        the class-given track only), otherwise it never reads the hint; an ablation option
        that hands it the truth makes it privileged, listed with the bounds."""
        return Capabilities(
            class_hint=ClassHint.REQUIRED if options.per_category else ClassHint.NONE,
            model=cls.kind(),
            privileged=options.diagnostic_truth(),
            grasp=options.grasp,
        )

    @classmethod
    def parse(cls, raw: Mapping[str, Any]) -> HBEOOptions:
        """``raw`` as options (:meth:`Backend.parse`); an option this mode does not use
        (``samples`` on ``hbeo``, the silhouette prior's off ``hbeo-mdn-posterior``) is a
        :class:`UsageError` naming the modes that use it and this mode's options."""
        unused = [k for k in raw if k in MODE_OPTIONS and cls.mode not in MODE_OPTIONS[k]]
        if unused:
            users = sorted({BY_MODE[m].name for k in unused for m in MODE_OPTIONS[k]})
            raise UsageError(
                f"backend {cls.name!r} does not use {', '.join(unused)} (an option of "
                f"{' and '.join(users)}); {cls.name} takes {', '.join(mode_options(cls.mode))}"
            )
        return super().parse(raw)

    @classmethod
    def kind(cls) -> Literal["hbeo", "hbeo-mdn"]:
        """The kind of trained model it loads."""
        return "hbeo" if cls.mode == "hbeo" else "hbeo-mdn"

    def __init__(self, options: HBEOOptions | None = None, **kwargs: Any) -> None:
        from beo_bench.perception.hbeo.train import resolve_device

        super().__init__(options, **kwargs)
        o = self.options
        if self.mode != "posterior" and o.prior_options():
            raise UsageError(
                f"{self.name} has no silhouette prior: "
                f"{', '.join(sorted(o.prior_options()))} are hbeo-mdn-posterior's options"
            )
        if self.mode == "hbeo" and o.grasp != "best":
            raise UsageError(
                "hbeo has no pose samples to plan over: grasp=robust is an hbeo-mdn option"
            )
        self.device = resolve_device(o.device)
        # the quick recipe's sizes (None: the default model's)
        self.small: dict[str, int | None] = {
            "instances": o.instances,
            "images": o.images,
            "epochs": o.epochs,
        }
        if o.threads is not None:
            torch.set_num_threads(max(1, o.threads))
        self._dataset: Dataset | None = None
        self._cache_root: Path | None = None  # the run's asset cache (prepare's)
        # class list -> (model, decoder A, b, the model's index of each class in the list)
        self._models: dict[
            tuple[str, ...], tuple[HBEOModel, np.ndarray, np.ndarray, np.ndarray]
        ] = {}
        self._digest: str | None = None
        self._digests: dict[int, str] = {}
        # prior_shape / prior_translation = hbeo: the hbeo network trained with the same
        # recipe and seed answers the same crop (chapter 4's shape head, not the MDN's)
        self._shape_net: HBEOBackend | None = None
        if "hbeo" in (o.prior_shape, o.prior_translation):
            # every other option (device, threads, size, per_category, the quick recipe's)
            # carries over; the ablation's own options are the posterior's alone
            plain: dict[str, Any] = {
                f.name: f.default for f in fields(o) if f.name in PRIOR_OPTIONS
            }
            self._shape_net = HBEOBackend(replace(o, model=companion_model(o.model), **plain))

    def prepare(self, ctx: PrepareContext) -> None:
        """Load the model for the run's classes and dataset (the published default, or one
        ``beo-bench train`` made; progress bars where ``ctx.progress``); with
        ``per_category``, each class's network (never trained here)."""
        # another dataset's models, or another cache's, are not these
        if ctx.dataset != self._dataset or ctx.cache_root != self._cache_root:
            self._dataset = ctx.dataset
            self._models.clear()
        self._cache_root = ctx.cache_root
        categories = tuple(ctx.categories)
        groups = [(c,) for c in categories] if self.options.per_category else [categories]
        digests = []
        for cats in groups:
            m = self._model(cats, progress=ctx.progress)[0]
            if id(m) not in self._digests:  # the weights as loaded (published or cached)
                self._digests[id(m)] = state_digest(m.state())
            digests.append(self._digests[id(m)])
        # per category: one digest naming the set of networks, in class order
        if self._shape_net is not None:  # the prior's shape network is part of the model
            self._shape_net.prepare(ctx)
            digests.append(str(self._shape_net.model_digest()))
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
                self.options.model,
                self.kind(),
                cats,
                progress,
                # the quick options select a trained model: never one trained here
                train_default=all(v is None for v in self.small.values()),
                size=self.options.size,
                recipe="per-category" if self.options.per_category else "default",
                dataset=self._dataset,
                cache_root=self._cache_root,
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
        from beo_bench.errors import TrainingInRunError
        from beo_bench.objects import pickable_categories
        from beo_bench.objects.datasets import train_command
        from beo_bench.perception.hbeo.model import (
            default_config,
            default_name,
            model_path,
            with_overrides,
        )

        given: dict[str, object] = {k: v for k, v in self.small.items() if v is not None}
        if not given or self.options.model is not None or self.options.per_category:
            return  # a named model, or per-category networks: load_hbeo never trains them
        if self._dataset is not None:
            return
        small = self.small
        base = default_config(
            self.kind(), cats, small["instances"], small["images"], small["epochs"]
        )
        cfg = with_overrides(base, size=self.options.size)
        if (model_path(default_name(cfg), self._cache_root) / "weights.pt").exists():
            return
        big = self.options.size != "small"
        how = train_command(
            self.kind(),
            () if cats == pickable_categories() else cats,
            per_category=given.get("instances"),
            images=given.get("images"),
            epochs=given.get("epochs"),
            size=self.options.size if big else None,
            device="cuda" if big else None,
        )
        raise TrainingInRunError.of(self.name, given, how)

    def _classes(self, view: View) -> tuple[str, ...]:
        """The class list of the network that answers ``view``: the view's, or with
        ``per_category`` its hinted class alone."""
        if not self.options.per_category:
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
        if self.options.per_category:  # a one-class network: the class is the hint
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
            select = self.options.select
            s = self.rotation_samples(
                view, f, prior=self.mode == "posterior" and select != "oracle"
            )
            score = s.log_likelihood.copy()
            if s.silhouette_error is not None:
                log_prior = -np.log(s.silhouette_error**4 + PRIOR_EPS)  # eq. 5.8: 1/(e^4 + eps)
                score = log_prior if select == "prior" else score + log_prior
            if select == "oracle":  # the dissertation's Random Sample + Oracle (Table 5.1)
                gt = _truth(view, self.name)
                score = -np.array([rotation_error(R, gt.R_cam, gt.symmetry) for R in s.R])
            best = int(np.argmax(score))  # eq. 5.7 (likelihood) or the posterior mode
            R, samples = s.R[best], s.R
            weights = np.exp(score - score[best])
            weights /= weights.sum()
            info["samples"] = self.options.samples
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
        seed = zlib.crc32(f.crop.image.tobytes()) ^ self.options.seed
        w = mix.sample(self.options.samples, np.random.default_rng(seed))[0]  # (N, 3)
        # eq. 5.7's density of each sample, in float64 numpy: N is small, and multi-threaded
        # float32 reductions could break ties differently from call to call
        lw, mu, var = (x[0].double().numpy() for x in (mix.log_weights, mix.means, mix.variances))
        d = w[:, None, :] - mu[None]
        comp = -0.5 * (d * d / var + np.log(2 * np.pi * var)).sum(-1)  # (N, M)
        R = f.crop.rotation_from(Rotation.from_rotvec(w).as_matrix())
        e = self.silhouette_errors(view, f, R) if prior else None
        return Samples(R=R, log_likelihood=logsumexp(comp + lw, axis=1), silhouette_error=e)

    def silhouette_errors(self, view: View, f: Forward, R: np.ndarray) -> np.ndarray:
        """e (eq. 5.6) of each rotation of ``R`` (N, 3, 3): the predicted shape re-projected
        at the network's translation and compared in the crop, or with the ablation's
        options (:data:`PRIOR_OPTIONS`) the true shape or translation, a 64^3 grid, the
        view's own pixels, or only the pixels no other object covers."""
        o = self.options
        shape, size, t = f.shape, f.size, f.translation
        if self._shape_net is not None:
            g = self._shape_net.forward(view)
            if o.prior_shape == "hbeo":
                shape, size = g.shape, g.size
            if o.prior_translation == "hbeo":
                t = g.translation
        if o.prior_shape == "truth" or o.prior_translation == "truth":
            gt = _truth(view, self.name)
            if o.prior_translation == "truth":
                t = np.asarray(gt.t_cam, dtype=np.float64)
            if o.prior_shape == "truth":
                inst = instance_from_key(gt.key, self._dataset, self._cache_root)
                shape, size = inst.voxels(o.prior_grid).astype(np.float32), np.asarray(gt.size)
        if shape.shape[0] != o.prior_grid:  # the decode, resampled (the basis is 32^3)
            grid = torch.from_numpy(np.ascontiguousarray(shape, dtype=np.float32))[None, None]
            shape = F.interpolate(grid, size=(o.prior_grid,) * 3, mode="trilinear")[0, 0].numpy()
        others = None
        if o.prior_occlusion and view.segmentation is not None:
            others = (np.asarray(view.segmentation) != 0) & ~np.asarray(view.mask, dtype=bool)
        if o.prior_pixels == "crop":
            S = f.crop.image.shape[-1]
            affine, hw, observed = np.asarray(f.crop.affine), (S, S), f.crop.mask
            if others is not None:
                warped = cv2.warpAffine(
                    others.astype(np.float32), affine, (S, S), flags=cv2.INTER_NEAREST
                )
                others = warped > 0.5
        else:
            affine, hw, box = view_window(view)
            y0, x0 = box
            d = np.asarray(view.depth)
            seen = np.asarray(view.mask, dtype=bool) & np.isfinite(d) & (d > 0)
            observed = seen[y0 : y0 + hw[0], x0 : x0 + hw[1]]
            if others is not None:
                others = others[y0 : y0 + hw[0], x0 : x0 + hw[1]]
        masks = project_masks(torch.from_numpy(shape), size, R, t, view.K, affine, hw)
        if o.prior_translation == "aligned":
            masks = align_centroids(masks, observed)
        return sdf_errors(observed, masks, None if others is None else ~others)


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


def companion_model(model: str | None) -> str | None:
    """The hbeo model trained beside an hbeo-mdn one: the published one for the published
    MDN, ``seed<k>-hbeo`` for the replicate ``seed<k>-hbeo-mdn``."""
    if model is None:
        return None
    if model.startswith("seed") and model.endswith("-hbeo-mdn"):
        return model.removesuffix("-mdn")
    raise UsageError(
        f"prior_shape/prior_translation=hbeo with model={model}: no hbeo network is known "
        "to be trained beside it (the published models and seed<k>-hbeo-mdn have one)"
    )


def _truth(view: View, name: str) -> GroundTruth:
    gt = view.ground_truth
    if gt is None:
        raise ViewError(f"{name} with the truth needs View.ground_truth (the runner fills it)")
    return gt


class MDNLikelihoodBackend(HBEOBackend):
    """HBEO-MDN keeping the rotation sample of highest mixture density (eq. 5.7)."""

    name = "hbeo-mdn-likelihood"
    mode = "likelihood"


class MDNPosteriorBackend(HBEOBackend):
    """HBEO-MDN scoring its rotation samples with the silhouette prior (eq. 5.5-5.8)."""

    name = "hbeo-mdn-posterior"
    mode = "posterior"


BY_MODE: dict[Mode, type[HBEOBackend]] = {
    "hbeo": HBEOBackend,
    "likelihood": MDNLikelihoodBackend,
    "posterior": MDNPosteriorBackend,
}
"""The backend class of each mode."""
