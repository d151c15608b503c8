"""``beo``: Bayesian Eigenobjects (dissertation chapter 3): joint class, pose and 3D
completion from one segmented depth view, by search over pose hypotheses, all of a step's
hypotheses evaluated as one batched torch computation.

Per view (docs/design.md "Perception backends"):

1. *Start*: the cube (centre t, edge e) is first placed from the points alone, the same for
   every rotation: e = the largest extent of the points along their principal axes, t =
   their centroid pushed a quarter of e back along the viewing ray (a view sees the front).
2. *Coarse step* (eq. 3.20-3.21): every candidate rotation (1-DOF: every ``yaw_step_deg``
   about the known up; 3-DOF: ``so3_samples`` super-Fibonacci rotations, spread over the
   support of the pose prior P(R) when there is one, see 6.) voxelises the
   observation (:mod:`.beo_observe`: filled / known empty by free-space carving / unknown),
   projects it (:mod:`.beo_project`, eq. 3.14-3.19) and back-projects it (eq. 3.7), on a
   grid ``coarse_factor`` times coarser with the ``coarse_components`` leading directions,
   after ``coarse_box_rounds`` refits of its cube (step 3); its error is the RMS
   difference, over the known voxels, of the Euclidean distance transforms of the observed
   filled voxels and of the back-projection (thresholded at 0.5). The ``top_k`` best (at
   least 1.5 coarse steps apart) go on.
3. *Translation and size* of each survivor are refitted against its completed shape
   (``size_rounds`` times): the cube is re-centred on the bounding box, along the
   hypothesis's canonical axes, of the completion's occupied voxels together with the
   observed points, and its edge becomes that box's largest extent. The points fix the
   extents the camera sees across; the completion supplies the hidden depth.
4. *Fine step* (eq. 3.22): each survivor, or, when the class is given, its twin turned 180
   degrees about its up if that scores higher (``twins``: a partial view often fits its
   front-back twin as well, and the coarse step keeps only one of them); around each, a
   local search to ``fine_deg`` resolution (1-DOF: yaw steps of 3^j ``fine_deg`` down to
   ``fine_deg``; 3-DOF: ``refine_rounds`` rounds of a pattern search, +-step about each
   axis from half the coarse spacing, halving the step), each hypothesis scored at full
   resolution by the joint pose-class density max_c log p(o'_R | c) + log p(c) + log P(R)
   (eq. 3.10, 3.22). The best (rotation, class) wins.
5. The winner's translation and size are refined once more; its completion W o' + mu (eq.
   3.7), clipped to [0, 1], is resampled into the unit cube of its estimated bounding box;
   ``class_probs`` is the posterior over classes at that pose (eq. 3.11).
6. *Pose prior* P(R) (eq. 3.22, ``pose_prior``): the suite's published viewpoint
   distribution (``View.viewpoint_prior``: the isolated suites' rig, elevation 0-60 deg,
   roll within 25 deg; the same distribution the learned backends' training views come
   from). In 3-DOF the coarse candidates cover only its support (elevation within
   ``PRIOR_MARGIN_DEG`` of the range, roll within 3 sigma plus that margin: 7% of SO(3), so
   the same ``so3_samples`` are 2.4x denser per axis) and the fine step adds log P(R), its
   elevation edges softened by ``PRIOR_SOFT_DEG``. On a table (``View.world_up``: the
   ``tabletop`` and ``pick`` suites, whose protocol reveals the table plane), P(R) is the
   published rest prior (:class:`~beo_bench.types.RestPrior`, learned from the training
   split's tabletop scenes, as HBEO learns it from its tabletop crops): the coarse
   candidates are ``so3_samples`` rotations drawn from it (stratified yaws about the
   world's up, tilts as objects rest: nearly all upright, a few tipped as monitors and
   toilets rest), searched at the 1-DOF spacing ``yaw_step_deg``, and the fine step adds
   its log density. Without either (a user's views), or with ``pose_prior=False``, P(R)
   is uniform over SO(3). With ``View.up_hint`` (1-DOF) P(R) is constant over the yaw and
   changes nothing.

The class: ``View.class_hint`` when the view carries one (the ``class-given`` track), else
estimated jointly with the pose. With ``View.pose_hint`` (``known-pose``, Table 3.1) the
pose search is skipped: one voxelisation at the given pose, one projection,
classification and completion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import torch

from beo_bench.backend import Backend, Capabilities, ClassHint, PrepareContext
from beo_bench.geometry import orthonormalise, super_fibonacci, yaw_starts
from beo_bench.names import check_name
from beo_bench.options import option
from beo_bench.perception.beo.model import BEOModel, load_model
from beo_bench.perception.beo.observe import (
    Observation,
    distance_transform,
    occupied_box,
    prior_rotations,
    quantiles,
    recentre,
    so3_spacing,
    voxelise,
)
from beo_bench.perception.beo.project import (
    Completion,
    Subspace,
    known_gram,
    project,
    update_gram,
)
from beo_bench.perception.digest import state_digest
from beo_bench.types import Estimate, PosePrior, View

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset

PRIOR_SOFT_DEG = 5.0
"""Width of the Gaussian fall-off that replaces the elevation range's hard edges in the
fine step (a hypothesis a few degrees outside is unlikely, not impossible)."""


@dataclass
class Hypotheses:
    """B pose hypotheses: R (B, 3, 3) canonical -> camera, cube centres t (B, 3) in the
    camera frame and cube edges e (B,), all float32 tensors."""

    R: torch.Tensor
    t: torch.Tensor
    e: torch.Tensor

    def __len__(self) -> int:
        return int(self.R.shape[0])

    def take(self, idx: torch.Tensor) -> Hypotheses:
        return Hypotheses(self.R[idx], self.t[idx], self.e[idx])

    @classmethod
    def of(cls, R: np.ndarray | torch.Tensor, t: torch.Tensor, e: torch.Tensor) -> Hypotheses:
        R = torch.as_tensor(np.asarray(R), dtype=torch.float32)
        B = R.shape[0]
        return cls(R, t.reshape(-1, 3).expand(B, 3).clone(), e.reshape(-1).expand(B).clone())


@dataclass(frozen=True)
class BEOOptions:
    """The options of ``beo`` (``beo-bench run --opt KEY=VALUE``; the module docstring says
    what each step does)."""

    model: str | None = option(
        None,
        "a model name (beo-bench train beo --name; a name under the cache's models, never a "
        "path); null: the default model for the view's categories (the published one, or for "
        "another resolution or instances the one beo-bench train beo made)",
    )
    resolution: int = option(
        32,
        "D of the voxel grids (must match the model; with no model, another D than the "
        "published model's is the one beo-bench train beo --resolution D made)",
    )
    lasso: float = option(0.02, "weight of the L1 term of the partial projection (eq. 3.19)")
    coarse_factor: int = option(2, "the coarse step's grid is D / coarse_factor per edge")
    yaw_step_deg: float = option(10.0, "1-DOF coarse resolution (degrees)")
    fine_deg: float = option(1.0, "fine resolution (degrees)")
    so3_samples: int = option(512, "3-DOF coarse rotations")
    refine_rounds: int = option(4, "3-DOF pattern-search rounds of the fine step")
    top_k: int = option(3, "coarse hypotheses refined")
    size_rounds: int = option(2, "translation and size refinements per survivor")
    coarse_box_rounds: int = option(1, "cube refits of each coarse candidate")
    chunk: int = option(32, "hypotheses per batched computation (bounds memory)")
    fine: Literal["density", "edt"] = option(
        "density",
        "the fine step's score: the joint pose-class density of eq. 3.22, or edt (the "
        "coarse step's EDT error at full resolution)",
    )
    coarse_components: int = option(48, "leading subspace directions used by the coarse step")
    instances: int | None = option(
        None,
        "the default model trained on this many instances per class by beo-bench train beo "
        "--per-category N (a run never trains it); null: every training instance",
    )
    pose_prior: bool = option(
        True,
        "use the suite's viewpoint distribution (View.viewpoint_prior) or, on a table "
        "(View.world_up), the published rest prior as P(R) in the 3-DOF coarse and fine "
        "steps; false: uniform over SO(3)",
    )
    twins: bool = option(
        True,
        "when the class is given, also score each coarse survivor's twin turned 180 "
        "degrees about its up and keep the better of the two",
    )

    def __post_init__(self) -> None:
        if self.model is not None:
            check_name(self.model, "model")
        if self.lasso < 0:
            raise ValueError(f"lasso={self.lasso} must be >= 0")
        if self.resolution % self.coarse_factor:
            raise ValueError(
                f"coarse_factor={self.coarse_factor} must divide resolution={self.resolution}"
            )
        if min(self.top_k, self.so3_samples, self.chunk) < 1 or self.yaw_step_deg <= 0:
            raise ValueError("top_k, so3_samples and chunk must be >= 1, yaw_step_deg > 0")
        if not 0 < self.fine_deg <= self.yaw_step_deg:
            raise ValueError(f"fine_deg={self.fine_deg} must be in (0, yaw_step_deg]")


def _class_mask(logp: torch.Tensor, classes: list[int]) -> torch.Tensor:
    """(C,) 0 for the classes in ``classes``, -inf for the others: added to the (B, C) log
    densities ``logp``, it restricts eq. 3.22's max to the classes a view may be."""
    allowed = torch.full((logp.shape[1],), -math.inf, dtype=logp.dtype)
    allowed[classes] = 0.0
    return allowed


class BEOBackend(Backend):
    """Bayesian Eigenobjects: joint class, pose and completion by search (module docstring;
    options: :class:`BEOOptions`). It uses ``View.class_hint`` (given in the
    ``class-given`` track) to fix the class."""

    name = "beo"
    Options = BEOOptions
    capabilities = Capabilities(class_hint=ClassHint.OPTIONAL, model="beo")
    options: BEOOptions
    gram_updates = True
    """The fine step updates each neighbour's Gram matrix from its seed's (:meth:`complete`'s
    ``near``); False gathers each afresh (the reference the tests and benchmark compare to)."""

    def __init__(self, options: BEOOptions | None = None, **kwargs: Any) -> None:
        super().__init__(options, **kwargs)
        self._dataset: Dataset | None = None
        self._cache_root: Path | None = None  # the run's asset cache (prepare's)
        self._models: dict[tuple[str, ...], tuple[BEOModel, Subspace, Subspace]] = {}
        self._digest: str | None = None
        self._digests: dict[tuple[int, bool], str] = {}

    # -- model ----------------------------------------------------------------------------
    def prepare(self, ctx: PrepareContext) -> None:
        """Load the model for the run's classes and dataset (the published default, or one
        ``beo-bench train beo`` made; a default model of the library's for other settings
        trains on first use, with progress bars where ``ctx.progress``)."""
        # another dataset's models, or another cache's, are not these
        if ctx.dataset != self._dataset or ctx.cache_root != self._cache_root:
            self._dataset = ctx.dataset
            self._cache_root = ctx.cache_root
            self._models.clear()
        cats = tuple(ctx.categories)
        m = self._model(cats, progress=ctx.progress)[0]
        # on a table the rest prior is part of the model the run uses (a refit moves its
        # scores): the digest covers both
        rest = self.options.pose_prior and ctx.suite.protocol.world_frame == "robot"
        key = (id(m), rest)
        if key not in self._digests:  # the weights as loaded (published or cached)
            state: dict[str, Any] = {"model": m.arrays()} if rest else m.arrays()
            if rest:
                from beo_bench.perception.means import rest_prior, rest_prior_arrays

                state["rest_prior"] = rest_prior_arrays(rest_prior()[0])
            self._digests[key] = state_digest(state)
        self._digest = self._digests[key]

    def model_digest(self) -> str | None:
        """The content digest (:func:`~beo_bench.perception.digest.state_digest`) of the
        model the last :meth:`prepare` loaded; None before any."""
        return self._digest

    def _model(
        self, cats: tuple[str, ...], progress: bool = False
    ) -> tuple[BEOModel, Subspace, Subspace]:
        if cats not in self._models:
            self._refuse_training(cats)
            m = load_model(
                self.options.model,
                cats,
                self.options.resolution,
                progress,
                # the published default, or one trained with `beo-bench train`: not here
                train_default=not self._training_options(),
                per_category=self.options.instances,
                dataset=self._dataset,
                cache_root=self._cache_root,
            )
            self._models[cats] = (
                m,
                Subspace.from_model(m),
                Subspace.from_model(m, self.options.coarse_factor, self.options.coarse_components),
            )
        return self._models[cats]

    def _training_options(self) -> dict[str, int]:
        """The options that select a default model other than the published one (32^3, every
        training instance): ``resolution`` and ``instances``, where given."""
        given = {"resolution": self.options.resolution} if self.options.resolution != 32 else {}
        return given | (
            {"instances": self.options.instances} if self.options.instances is not None else {}
        )

    def _refuse_training(self, cats: tuple[str, ...]) -> None:
        """With :meth:`_training_options` and no default model trained for them (on the
        library: a dataset's missing model is :func:`load_model`'s error), the usage error
        that names the ``beo-bench train beo`` command making it: nothing trains in a run."""
        from beo_bench.errors import TrainingInRunError
        from beo_bench.objects import pickable_categories
        from beo_bench.objects.datasets import train_command
        from beo_bench.perception.beo.model import model_dir

        given: dict[str, object] = dict(self._training_options())
        if not given or self.options.model is not None or self._dataset is not None:
            return
        o = self.options
        path = model_dir(None, cats, o.resolution, o.instances, None, self._cache_root)
        if (path / "config.json").exists():
            return
        how = train_command(
            "beo",
            () if cats == pickable_categories() else cats,
            resolution=given.get("resolution"),
            per_category=self.options.instances,
        )
        raise TrainingInRunError.of(self.name, given, how)

    # -- batched evaluation ---------------------------------------------------------------
    def _chunks(self, n: int) -> list[slice]:
        return [slice(s, min(s + self.options.chunk, n)) for s in range(0, n, self.options.chunk)]

    def coarse_errors(self, obs: Observation, sub: Subspace, hyp: Hypotheses) -> torch.Tensor:
        """(B,) eq. 3.21 errors (voxels of the coarse grid) of the hypotheses."""
        D = sub.D
        out = []
        for s in self._chunks(len(hyp)):
            h = hyp.take(torch.arange(len(hyp))[s])
            filled, empty = voxelise(obs, h.R, h.t, h.e, D)
            recon = sub.decode(project(sub, filled, empty, self.options.lasso)) > 0.5
            shape = (-1, D, D, D)
            diff = distance_transform(filled.reshape(shape)) - distance_transform(
                recon.reshape(shape)
            )
            known = (filled | empty).reshape(shape).float()
            err = torch.sum(known * diff**2, dim=(1, 2, 3)) / known.sum(dim=(1, 2, 3)).clamp(min=1)
            # a hypothesis that sees none of the points explains nothing
            err = torch.where(filled.any(dim=1), err.sqrt(), torch.full_like(err, math.inf))
            out.append(err)
        return torch.cat(out)

    def complete(
        self,
        obs: Observation,
        sub: Subspace,
        hyp: Hypotheses,
        near: tuple[Completion, torch.Tensor] | None = None,
        grids: bool = True,
    ) -> Completion:
        """Codes and back-projections (where ``grids``) of the hypotheses. ``near``: the
        completion of hypotheses with the same cubes and nearly the same rotations, and the
        row of it each hypothesis is near (the fine step's pattern search): each Gram matrix
        is then updated from its neighbour's (:func:`~.beo_project.update_gram`)."""
        codes, backs, knowns, grams = [], [], [], []
        for s in self._chunks(len(hyp)):
            rows = torch.arange(len(hyp))[s]
            h = hyp.take(rows)
            filled, empty = voxelise(obs, h.R, h.t, h.e, sub.D)
            known = filled | empty
            gram = None
            if near is not None:
                base = near[0].take(near[1][rows])
                gram = update_gram(sub, base.gram, base.known, known)
            if gram is None:
                gram = known_gram(sub, known)
            x = project(sub, filled, empty, self.options.lasso, gram)
            codes.append(x)
            backs.append(sub.decode(x) if grids else x[:, :0])
            knowns.append(known)
            grams.append(gram)
        return Completion(torch.cat(codes), torch.cat(backs), torch.cat(knowns), torch.cat(grams))

    def joint_scores(
        self, model: BEOModel, codes: torch.Tensor, classes: list[int]
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(B,) best joint log density max_c log p(o'|c) + log p(c) (uniform prior) over
        ``classes``, and the (B, C) log densities (eq. 3.10, 3.22)."""
        logp = torch.from_numpy(model.log_density(codes.numpy()))
        return (logp + _class_mask(logp, classes)).amax(dim=1), logp

    def fine_scores(
        self,
        obs: Observation,
        model: BEOModel,
        sub: Subspace,
        hyp: Hypotheses,
        classes: list[int],
        prior: PosePrior | None = None,
    ) -> torch.Tensor:
        """(B,) the fine step's score of each hypothesis (higher is better): the joint
        pose-class log density plus log P(R) under ``prior`` (eq. 3.22; None: uniform)."""
        if self.options.fine == "edt":
            return -self.coarse_errors(obs, sub, hyp)
        return self.class_scores(obs, model, sub, hyp, classes, prior).amax(dim=1)

    def class_scores(
        self,
        obs: Observation,
        model: BEOModel,
        sub: Subspace,
        hyp: Hypotheses,
        classes: list[int],
        prior: PosePrior | None = None,
    ) -> torch.Tensor:
        """(B, C) log p(o'_R | c) + log p(c) + log P(R) per class (-inf for the classes
        not in ``classes``): the terms of eq. 3.22 before the max over classes."""
        return self._class_scores(obs, model, sub, hyp, classes, prior)[0]

    def _class_scores(
        self,
        obs: Observation,
        model: BEOModel,
        sub: Subspace,
        hyp: Hypotheses,
        classes: list[int],
        prior: PosePrior | None,
        near: tuple[Completion, torch.Tensor] | None = None,
    ) -> tuple[torch.Tensor, Completion]:
        """:meth:`class_scores` and their completion (``near``: see :meth:`complete`)."""
        comp = self.complete(obs, sub, hyp, near if self.gram_updates else None, grids=False)
        logp = torch.from_numpy(model.log_density(comp.codes.numpy()))
        score = logp + _class_mask(logp, classes)
        if prior is not None:
            log_p = prior.log_prob(hyp.R.double().numpy(), soft_deg=PRIOR_SOFT_DEG)
            score = score + torch.from_numpy(log_p).to(score.dtype)[:, None]
        return score, comp

    # -- translation and size -------------------------------------------------------------
    def refine_box(
        self, obs: Observation, hyp: Hypotheses, grids: torch.Tensor, D: int
    ) -> Hypotheses:
        """Re-fit each hypothesis's cube to its completed shape: the new cube is centred on
        the bounding box (along the hypothesis's canonical axes) of the completion's voxels
        above 0.5 together with the observed points (their 1-99% range), and its edge is
        that box's largest extent. The points fix the extents the camera sees across; the
        completion supplies the hidden depth. A round or two settle it."""
        lo_f, hi_f = occupied_box(grids, D)  # (B, 3) unit-cube units
        q = torch.einsum("bji,bnj->bni", hyp.R, obs.points[None] - hyp.t[:, None, :])
        qlo, qhi = quantiles(q, (0.01, 0.99))
        e = hyp.e[:, None]
        lo = torch.minimum(lo_f * e, qlo)
        hi = torch.maximum(hi_f * e, qhi)
        t_new = hyp.t + torch.einsum("bij,bj->bi", hyp.R, 0.5 * (lo + hi))
        e_new = (hi - lo).amax(dim=1).clamp(min=1e-3)
        return Hypotheses(hyp.R, t_new, e_new)

    def fit_box(self, obs: Observation, sub: Subspace, hyp: Hypotheses, rounds: int) -> Hypotheses:
        for _ in range(rounds):
            comp = self.complete(obs, sub, hyp)
            hyp = self.refine_box(obs, hyp, comp.grids, sub.D)
        return hyp

    # -- search ---------------------------------------------------------------------------
    @staticmethod
    def start_box(obs: Observation) -> tuple[torch.Tensor, torch.Tensor]:
        """R-independent initial cube centre (3,) and edge () from the points alone."""
        P = obs.points.double()
        c = P.mean(dim=0)
        if len(P) >= 3:
            _, _, Vt = torch.linalg.svd(P - c, full_matrices=False)
            proj = (P - c) @ Vt.T
            ext = torch.quantile(proj, 0.98, dim=0) - torch.quantile(proj, 0.02, dim=0)
            e = float(ext.max())
        else:
            e = 0.0
        e = max(e, 0.01)
        ray = c / c.norm().clamp(min=1e-9)
        return (c + ray * e / 4).float(), torch.tensor(e, dtype=torch.float32)

    def _top(self, errors: torch.Tensor, R: torch.Tensor, min_angle: float) -> torch.Tensor:
        """Indices of the ``top_k`` lowest errors, each at least ``min_angle`` (rad) from
        the ones chosen before (non-maximum suppression)."""
        order = torch.argsort(errors, stable=True)
        chosen: list[int] = []
        for i in order.tolist():
            if not math.isfinite(float(errors[i])):
                break
            ok = True
            for j in chosen:
                cosang = (torch.trace(R[i].T @ R[j]) - 1) / 2
                if math.acos(float(cosang.clamp(-1, 1))) < min_angle:
                    ok = False
                    break
            if ok:
                chosen.append(i)
            if len(chosen) == self.options.top_k:
                break
        if not chosen:
            chosen = [int(order[0])]
        return torch.tensor(chosen)

    def search(
        self,
        obs: Observation,
        cats: tuple[str, ...],
        classes: list[int],
        up: np.ndarray | None,
        prior: PosePrior | None = None,
    ) -> tuple[Hypotheses, dict]:
        """The best hypothesis (B = 1) by the coarse and fine steps, and search statistics.
        ``prior``: the pose prior P(R) of the 3-DOF search (None: uniform over SO(3))."""
        model, full, coarse = self._model(cats)
        t0, e0 = self.start_box(obs)
        if up is not None:
            n = max(1, round(360.0 / self.options.yaw_step_deg))
            R0 = yaw_starts(up, n)
            spacing = 2 * math.pi / n
            prior = None  # constant over the yaw about a known up
        elif prior is not None:
            # the candidates of the prior's reference frame (cached), turned into the view's
            # (the rig's prior is in the camera's already; a rest prior's up is the world's)
            R0, spacing = prior_rotations(
                prior.canonical(), self.options.so3_samples, self.options.yaw_step_deg
            )
            R0 = prior.frame() @ R0  # a new array: the cached set stays read-only
        else:
            R0 = super_fibonacci(self.options.so3_samples)
            spacing = so3_spacing(self.options.so3_samples)
        hyp = Hypotheses.of(R0, t0, e0)
        hyp = self.fit_box(obs, coarse, hyp, self.options.coarse_box_rounds)
        errors = self.coarse_errors(obs, coarse, hyp)
        keep = self._top(errors, hyp.R, 1.5 * spacing)
        seeds = self.fit_box(obs, full, hyp.take(keep), self.options.size_rounds)
        # the seeds' completions (density score): their neighbours' Gram matrices start there
        state: Completion | None = None
        seed_scores: torch.Tensor | None = None
        if self.options.fine == "density":
            seed_scores, state = self._class_scores(obs, model, full, seeds, classes, prior)
            score = seed_scores.amax(dim=1)
        else:
            score = self.fine_scores(obs, model, full, seeds, classes, prior)
        n_fine = len(seeds)
        if self.options.twins and len(classes) == 1:
            seeds, score, state = self._better_twins(
                obs, model, full, seeds, score, classes, prior, seed_scores, state
            )
            n_fine += len(seeds)
        if up is not None:
            # yaw steps of 3^j * fine_deg within half a coarse step, then fine_deg: a
            # ternary hill climb that reaches fine_deg resolution in a few rounds
            steps = [self.options.fine_deg]
            while steps[-1] * 3 <= 0.5 * math.degrees(spacing):
                steps.append(steps[-1] * 3)
            axis = torch.tensor([0.0, 0.0, 1.0])
            moves = [torch.stack([-axis, axis]) * math.radians(st) for st in reversed(steps)]
            local = True  # yaw moves act in the canonical frame (about canonical +z = up)
        else:
            # pattern search over SO(3): +-step about each camera axis, halving the step
            axes = torch.cat([torch.eye(3), -torch.eye(3)])
            step = 0.5 * spacing
            moves = []
            for _ in range(max(1, self.options.refine_rounds)):
                moves.append(axes * step)
                step /= 2
            local = False
        for mv in moves:
            dR = _rotvec(mv)  # (M, 3, 3)
            if local:
                cand_R = (seeds.R[:, None] @ dR[None]).reshape(-1, 3, 3)
            else:
                cand_R = (dR[None] @ seeds.R[:, None]).reshape(-1, 3, 3)
            parent = torch.arange(len(seeds)).repeat_interleave(len(mv))
            cand = Hypotheses(cand_R, seeds.t[parent], seeds.e[parent])
            if state is not None:
                cand_scores, cand_comp = self._class_scores(
                    obs, model, full, cand, classes, prior, near=(state, parent)
                )
                cand_score = cand_scores.amax(dim=1)
            else:
                cand_score = self.fine_scores(obs, model, full, cand, classes, prior)
            n_fine += len(cand)
            # each seed moves to its best neighbour if that beats it (eq. 3.22)
            per = torch.cat([score[:, None], cand_score.reshape(len(seeds), len(mv))], 1)
            j = torch.argmax(per, dim=1)
            moved = j > 0
            pick = (j - 1).clamp(min=0) + torch.arange(len(seeds)) * len(mv)
            new = cand.take(pick)
            seeds = Hypotheses(
                torch.where(moved[:, None, None], new.R, seeds.R),
                torch.where(moved[:, None], new.t, seeds.t),
                torch.where(moved, new.e, seeds.e),
            )
            if state is not None:
                state = state.where(moved, cand_comp.take(pick))
            score = per.amax(dim=1)
        best = seeds.take(torch.argmax(score).reshape(1))
        stats = {
            "coarse_hypotheses": len(hyp),
            "fine_hypotheses": n_fine,
            "coarse_error": float(errors[keep[0]]),
        }
        return best, stats

    def _better_twins(
        self,
        obs: Observation,
        model: BEOModel,
        sub: Subspace,
        seeds: Hypotheses,
        score: torch.Tensor,
        classes: list[int],
        prior: PosePrior | None,
        seed_scores: torch.Tensor | None = None,
        seed_comp: Completion | None = None,
    ) -> tuple[Hypotheses, torch.Tensor, Completion | None]:
        """Each seed, or its twin turned 180 degrees about its own up (canonical +z) when
        the twin scores higher under the seed's best class. A partial view of a car or an
        airplane fits its front-back twin nearly as well, so the coarse EDT error often
        keeps one of the two and drops the other; the fine score is what tells them apart
        (on 110 ``pose-3dof`` views a third of the 180-degree errors were twins the fine
        step never saw). The search calls it only when the class is known (given): with
        the class estimated, a misclassified view's density cannot tell front from back,
        and twins made the class-free estimates worse (110 views, mean rotation error 44 ->
        55 degrees in 3-DOF, 33 -> 40 in 1-DOF, nearly all of it on misclassified chairs
        and sofas), while given the class they made them better (44 -> 33, 23 -> 21).
        ``seed_scores`` and ``seed_comp``: the seeds' :meth:`class_scores` and completion
        where the caller has them (else computed here); the completion returned is the
        chosen hypotheses' (density score; None with the EDT score)."""
        flip = torch.diag(torch.tensor([-1.0, -1.0, 1.0]))
        turned = Hypotheses(seeds.R @ flip, seeds.t, seeds.e)
        twins = self.fit_box(obs, sub, turned, self.options.size_rounds)
        comp: Completion | None = None
        if self.options.fine == "edt":
            twin_score = self.fine_scores(obs, model, sub, twins, classes, prior)
            better = twin_score > score
        else:
            if seed_scores is None or seed_comp is None:
                seed_scores, seed_comp = self._class_scores(obs, model, sub, seeds, classes, prior)
            mine, comp = seed_scores, seed_comp
            theirs, twin_comp = self._class_scores(obs, model, sub, twins, classes, prior)
            rows = torch.arange(len(seeds))
            c = mine.argmax(dim=1)
            better = theirs[rows, c] > mine[rows, c]
            twin_score = theirs.amax(dim=1)
            comp = comp.where(better, twin_comp)
        out = Hypotheses(
            torch.where(better[:, None, None], twins.R, seeds.R),
            torch.where(better[:, None], twins.t, seeds.t),
            torch.where(better, twins.e, seeds.e),
        )
        return out, torch.where(better, twin_score, score), comp

    # -- predict --------------------------------------------------------------------------
    @staticmethod
    def prior_of(view: View) -> PosePrior | None:
        """The pose prior P(R) of a view: its suite's viewpoint distribution, or on a table
        (``View.world_up``) the published rest prior placed by the world's up; None where
        the view comes with neither."""
        if view.viewpoint_prior is not None:
            return view.viewpoint_prior
        if view.world_up is not None:
            from beo_bench.perception.means import rest_prior

            return rest_prior()[0].in_view(np.asarray(view.world_up, dtype=np.float64))
        return None

    def predict(self, view: View) -> Estimate:
        cats = tuple(view.categories)
        model, full, _ = self._model(cats)
        obs = Observation.from_view(view)
        classes = view.candidate_classes(use_hint=True)
        info: dict = {}
        if view.pose_hint is not None:
            R, t, size = (np.asarray(a, dtype=np.float64) for a in view.pose_hint)
            hyp = Hypotheses.of(
                R[None],
                torch.tensor(t, dtype=torch.float32),
                torch.tensor(float(np.max(size)), dtype=torch.float32),
            )
            comp = self.complete(obs, full, hyp)
            est_size = size
            t_out = t
            grid = comp.grids[0].reshape((model.D,) * 3).clamp(0, 1).numpy()
            protocol = "known-pose"
        else:
            up = view.unit_up()
            prior = self.prior_of(view) if self.options.pose_prior else None
            best, info = self.search(obs, cats, classes, up, prior)
            best = self.fit_box(obs, full, best, 1)
            comp = self.complete(obs, full, best)
            flo, fhi = occupied_box(comp.grids, model.D)
            lo, hi = flo[0].double().numpy(), fhi[0].double().numpy()
            e = float(best.e[0])
            est_size = np.maximum((hi - lo) * e, 1e-3)
            R = best.R[0].double().numpy()
            t_out = best.t[0].double().numpy() + R @ (0.5 * (lo + hi) * e)
            grid = recentre(comp.grids[0].reshape((model.D,) * 3).clamp(0, 1), lo, hi)
            protocol = "1dof" if up is not None else "3dof"
        logp = torch.from_numpy(model.log_density(comp.codes.numpy()))[0].double()
        probs = np.zeros(len(cats))
        lp = logp[classes]
        probs[classes] = torch.softmax(lp, dim=0).numpy()
        info.update({"protocol": protocol, "log_density": float(lp.max())})
        return Estimate(
            class_probs=probs,
            rotation=orthonormalise(R),
            translation=np.asarray(t_out, dtype=np.float64),
            size=np.asarray(est_size, dtype=np.float64),
            shape=np.asarray(grid, dtype=np.float32),
            info=info,
        )


def _rotvec(w: torch.Tensor) -> torch.Tensor:
    """(n, 3) rotation vectors -> (n, 3, 3) matrices."""
    return torch.linalg.matrix_exp(
        torch.stack(
            [
                torch.stack([torch.zeros_like(w[:, 0]), -w[:, 2], w[:, 1]], 1),
                torch.stack([w[:, 2], torch.zeros_like(w[:, 0]), -w[:, 0]], 1),
                torch.stack([-w[:, 1], w[:, 0], torch.zeros_like(w[:, 0])], 1),
            ],
            1,
        )
    )
