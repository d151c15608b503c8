"""Generate a suite's items and score a backend on them (one worker's job).

A :class:`Evaluator` owns what is slow to create (a renderer or an env, the backend) and
turns item index ``i`` of a suite into result rows: plain JSON-serialisable dicts, one per
scored view (isolated, tabletop) or episode (pick). A backend that raises or returns
garbage is recorded as a failure with its reason and scored as wrong; the run goes on. One
that hangs or kills its worker is recorded the same way by the worker pool, from the rows
the evaluator announced before calling it (:func:`failed_rows`).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from beo_bench import metrics
from beo_bench.backend import (
    PerceptionBackend,
    check_privileged,
    get_backend,
    validate_estimate,
)
from beo_bench.bench.suites import Suite
from beo_bench.geometry import rigid
from beo_bench.objects import ObjectSet, instance_from_key
from beo_bench.objects.dataset import object_set
from beo_bench.types import Estimate, GroundTruth, View

FSCORE_TAU = metrics.FSCORE_TAU
"""F-score threshold: 1% of the unit cube's side, i.e. of the object's largest extent (the
canonical shapes are scaled into the unit cube; Tatarchenko et al. 2019)."""


def item_rng(suite: Suite, index: int) -> np.random.Generator:
    """The generator of item ``index``: depends on the suite's seed and the index only."""
    return np.random.default_rng(np.random.SeedSequence([suite.seed, index]))


def episode_seed(suite: Suite, index: int) -> int:
    """The BEOPick-v0 ``reset`` seed of item ``index`` of a tabletop or pick suite."""
    return int(item_rng(suite, index).integers(2**31))


ISO_EPS = 1e-6
"""Marching cubes runs just below the 0.5 level, so that a cell of exactly 0.5, which every
metric counts as filled (``>= 0.5``), lies inside the surface too."""
SURFACE_POINTS = 1024
"""Surface samples per shape for Chamfer-L1 and the F-score: the points whose distances to the
other surface are taken (each exact, see :class:`~beo_bench.metrics.Surface`), so they only
average the distance over the area: no sampling floor, and a standard error of at most 1.6%
on a view's precision and recall (sqrt(0.25 / 1024)), which averages out over a suite. (Sample
to sample, 2048 were too few by far: a surface scored F = 0.13-0.84 against itself.)"""


def grid_mesh(
    grid: np.ndarray, edge: float = 1.0, level: float = 0.5, mirror_outside: bool = False
) -> Any:
    """The ``level`` iso-surface of a (D, D, D) occupancy grid (marching cubes, sub-voxel
    where the grid holds probabilities) as a mesh in the canonical frame, the grid spanning
    the cube of side ``edge`` centred at the origin (1: the unit cube; the largest extent:
    metres). ``None`` when no cell reaches ``level``.

    Outside the grid is empty (0). With ``mirror_outside`` a filled border cell of value
    ``p`` faces ``2 level - p`` instead, so the surface leaves the grid half a voxel beyond
    it whatever ``p`` is, as it does for a 0/1 grid (against 0 it would sit ``(p - level)
    / p`` of a voxel out: a perfect estimate given as 0.6/0.4 would lie a third of a voxel
    inside the truth wherever the object touches the cube, which is everywhere along its
    largest extent). Empty border cells still face themselves (no surface)."""
    import trimesh
    from skimage.measure import marching_cubes

    inner = np.asarray(grid, dtype=np.float32)
    g = np.pad(inner, 1)
    if mirror_outside:
        e = np.pad(inner, 1, mode="edge")
        border = np.ones(g.shape, dtype=bool)
        border[1:-1, 1:-1, 1:-1] = False
        g[border] = np.minimum(e, 2.0 * level - e)[border]
    if g.max() < level or g.min() > level - ISO_EPS:
        # no cell crosses the level: nothing reaches it, or (a grid of exactly ``level``
        # with the outside mirrored) nothing falls below it; either way there is no surface
        return None
    verts, faces, _, _ = marching_cubes(g, level - ISO_EPS)
    D = g.shape[0] - 2
    unit = (verts - 0.5) / D - 0.5  # padded index j is voxel j - 1, centred at (j-1+0.5)/D
    return trimesh.Trimesh(unit * edge, faces, process=False)


def surface_points(grid: np.ndarray, n: int = SURFACE_POINTS) -> np.ndarray:
    """``n`` area-uniform samples (seeded) of a grid's 0.5 iso-surface (:func:`grid_surface`)
    in the unit cube [-0.5, 0.5]^3; empty when the grid is."""
    return grid_surface(grid, n).samples


def grid_surface(grid: np.ndarray, n: int = SURFACE_POINTS) -> metrics.Surface:
    """A grid's 0.5 iso-surface (:func:`grid_mesh` with the outside mirrored, in the unit
    cube; a 0/1 grid's is the same either way) with ``n`` area-uniform samples of it
    (seeded), ready for exact distances (:class:`~beo_bench.metrics.Surface`) [Tatarchenko:
    F-score on surfaces]; empty when the grid is."""
    import trimesh

    mesh = grid_mesh(grid, mirror_outside=True)
    if mesh is None:
        return metrics.Surface(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), np.zeros((0, 3)))
    points, _ = trimesh.sample.sample_surface(mesh, n, seed=0)
    return metrics.Surface(mesh.vertices, mesh.faces, np.asarray(points, dtype=np.float64))


@dataclass(frozen=True)
class TruthShape:
    """What scoring needs of one instance's true shape at resolution D, computed once per
    process (0.1-1 MB at 32^3, mostly the surface's triangles; its EDT, 4x the voxels, is
    recomputed per view instead)."""

    voxels: np.ndarray
    """(D, D, D) bool occupancy."""
    surface: metrics.Surface
    """Its 0.5 iso-surface in the unit cube, with SURFACE_POINTS samples."""
    model_points: np.ndarray
    """(H, 3) the vertices of the true mesh's convex hull (canonical frame, metres): the
    model points of MSSD and MSPD (a distance affine in the point is largest at one of
    them, so they stand for the whole surface)."""


@functools.lru_cache(maxsize=256)
def truth_shape(key: str, D: int) -> TruthShape:
    """The true shape of instance ``key`` (voxels disk-cached; the rest kept per process)."""
    inst = instance_from_key(key)
    v = inst.voxels(D)
    out = TruthShape(v, grid_surface(v), np.array(inst.mesh.convex_hull.vertices, dtype=float))
    for a in (out.voxels, out.surface.triangles, out.surface.samples, out.model_points):
        a.setflags(write=False)
    return out


def score_shape(
    est: Estimate, gt: GroundTruth, truth: TruthShape, tau: float = FSCORE_TAU
) -> dict[str, Any]:
    """Completion metrics of one estimate against the truth, at the truth's resolution:
    voxel IoU, camera-frame IoU (shape, pose and size together: what a planner using the
    estimate sees), the EDT error (eq. 4.5), Chamfer-L1 and F-score at ``tau`` (exact
    distances from each surface's samples to the other surface: a perfect estimate scores
    F = 1 at any occupancy probability above 0.5)."""
    D = truth.voxels.shape[0]
    pred = _resample(est.shape, D)
    out: dict[str, Any] = {"iou": metrics.voxel_iou(pred, truth.voxels)}
    out["iou_cam"] = metrics.camera_frame_iou(
        pred,
        (est.rotation, est.translation),
        est.size,
        truth.voxels,
        (gt.R_cam, gt.t_cam),
        gt.size,
        resolution=D,
    )
    out["edt_err"] = metrics.edt_error(pred, truth.voxels)
    surf = metrics.surface_scores(grid_surface(pred), truth.surface, tau)
    out["fscore"] = surf["fscore"]
    out["chamfer_l1"] = surf["chamfer_l1"] if np.isfinite(surf["chamfer_l1"]) else None
    return out


def score_pose(
    est: Estimate, gt: GroundTruth, truth: TruthShape, K: np.ndarray | None
) -> dict[str, Any]:
    """Pose metrics of one estimate, each under the object's symmetry group: rotation
    error (deg), translation error (cm; at the symmetric pose nearest in translation), size
    error (%), MSSD (cm) and, where the camera ``K`` is known, MSPD (pixels; None when the
    estimate puts the object behind the camera) over the true model's hull vertices."""
    sym = gt.symmetry
    args = (est.rotation, est.translation, gt.R_cam, gt.t_cam)
    out: dict[str, Any] = {
        "rot_err_deg": metrics.rotation_error(est.rotation, gt.R_cam, sym),
        "trans_err_cm": metrics.translation_error(est.translation, gt.t_cam, gt.R_cam, sym),
        "size_err_pct": metrics.size_error(est.size, gt.size),
        "mssd_cm": 100.0 * metrics.mssd(*args, truth.model_points, sym),
    }
    if K is not None:
        px = metrics.mspd(*args, np.asarray(K, dtype=np.float64), truth.model_points, sym)
        out["mspd_px"] = px if np.isfinite(px) else None
    return out


def _resample(grid: np.ndarray, D: int) -> np.ndarray:
    g = np.asarray(grid, dtype=np.float32)
    if g.shape[0] == D:
        return g
    idx = ((np.arange(D) + 0.5) * g.shape[0] / D).astype(int)
    return g[np.ix_(idx, idx, idx)]


class ItemViews:
    """Generates a suite's items (views with their truth) without a backend: what a failed
    item's rows need when its backend hung or crashed (:meth:`templates`)."""

    def __init__(self, suite: Suite) -> None:
        from beo_bench.objects.dataset import activate

        self.suite = suite
        # in a worker process too: the backend built here loads its model for this dataset
        activate(suite.dataset)
        self.class_hint = False
        self._renderer: Any = None
        self._env: Any = None
        self._objects: ObjectSet | None = None
        self._noise: Any = None

    # -- resources -------------------------------------------------------------------------
    def _isolated(self) -> Any:
        if self._renderer is None:
            from beo_bench.scenes.camera import Intrinsics
            from beo_bench.scenes.isolated import IsolatedRenderer
            from beo_bench.scenes.noise import DepthNoise

            w, h = self.suite.image_size
            self._renderer = IsolatedRenderer(Intrinsics(w, h, self.suite.fovy_deg))
            s = self.suite
            self._objects = object_set(s.dataset, s.split, s.categories)
            self._noise = DepthNoise() if self.suite.noise else None
        return self._renderer

    def _pick_env(self) -> Any:
        if self._env is None:
            from beo_bench.envs.pick import BEOPickEnv

            s = self.suite
            kw: dict[str, Any] = {}
            if s.dataset is not None:  # scenes of the user's objects (distinct classes each)
                objects = s.dataset.objects(s.split, s.categories)
                kw = {"objects": objects, "num_objects": (1, min(4, len(objects.categories)))}
            self._env = BEOPickEnv(
                split=s.split, image_size=s.image_size, fovy_deg=s.fovy_deg, noise=s.noise, **kw
            )
        return self._env

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._env is not None:
            self._env.close()
            self._env = None

    # -- items -----------------------------------------------------------------------------
    # A backend sees a View and nothing else (docs/benchmark.md, "What a backend is told"):
    # the functions that build views return only the views, and the truth is computed
    # after the backend has answered (privileged bounds aside), so it is not a local of any
    # frame on predict's call stack.
    def _draw(self, index: int) -> tuple[np.random.Generator, Any, np.ndarray]:
        """Item ``index``'s instance and camera pose (``cam_to_world`` with the object at the
        origin in its canonical frame), with the generator left where they were drawn."""
        self._isolated()
        assert self._objects is not None
        rng = item_rng(self.suite, index)
        cats = self._objects.categories
        cat = cats[index % len(cats)]  # classes balanced over items
        inst = self._objects.get(cat, int(rng.integers(self._objects.count(cat))))
        return rng, inst, self._renderer.rig.sample(rng, np.zeros(3))

    def isolated_view_only(self, index: int) -> View:
        """The view of isolated item ``index``: exactly what its protocol reveals."""
        from beo_bench.types import ViewpointPrior

        s = self.suite
        rng, inst, T = self._draw(index)
        iv = self._renderer.render(inst, T, self._noise, rng)
        # The world frame is a random rigid frame drawn after the image, so cam_to_world
        # tells a backend no more than the protocol does: up (1-DOF) or nothing (3-DOF,
        # known-pose), and never where the object is (the renderer puts it at the origin).
        cam_to_world = world_frame(rng, s.protocol) @ iv.cam_to_world
        return View(
            # the rig's viewpoint distribution is part of the protocol (a pose prior any
            # backend may use); it reveals nothing about this view's pose
            viewpoint_prior=ViewpointPrior.of_rig(self._renderer.rig),
            depth=iv.depth,
            mask=iv.mask,
            K=iv.K,
            cam_to_world=cam_to_world,
            categories=inst_categories(self._objects),
            up_hint=iv.R_cam[:, 2].copy() if s.protocol == "1dof" else None,
            pose_hint=(iv.R_cam, iv.t_cam, np.asarray(inst.size, dtype=np.float64))
            if s.protocol == "known-pose"
            else None,
        )

    def isolated_truth(self, index: int) -> GroundTruth:
        """The truth about isolated item ``index``, drawn again without rendering: the
        renderer's object sits at the origin in its canonical frame, so its pose in the
        camera is the inverse of the rig's ``cam_to_world``."""
        _, inst, T = self._draw(index)
        inv = np.linalg.inv(T)
        assert self._objects is not None
        return GroundTruth.of(inst, self._objects.categories, inv[:3, :3], inv[:3, 3])

    def isolated_view(self, index: int) -> tuple[View, GroundTruth]:
        """Item ``index``'s view and its truth (for tests, recordings and benchmarks; the
        evaluator itself asks for the truth only after the backend has answered)."""
        return self.isolated_view_only(index), self.isolated_truth(index)

    def views(self, index: int) -> list[View]:
        """The views item ``index`` scores (one for isolated suites, every object with
        ``min_pixels`` visible pixels for tabletop and pick scenes), without their truth."""
        if self.suite.kind == "isolated":
            return [self.isolated_view_only(index)]
        env = self._pick_env()
        obs, _ = env.reset(seed=episode_seed(self.suite, index))
        return self._scene_views(obs, env)

    def truths(self, index: int, views: list[View]) -> list[GroundTruth]:
        """The truth of each of item ``index``'s ``views`` (after :meth:`views`; a scene's
        env must still hold that item's episode)."""
        if self.suite.kind == "isolated":
            return [self.isolated_truth(index)]
        env = self._pick_env()
        return self._scene_truths(env, views)

    def cases(self, index: int) -> list[tuple[View, GroundTruth]]:
        """The views (with their truth) that item ``index`` scores."""
        views = self.views(index)
        return list(zip(views, self.truths(index, views), strict=True))

    def _scene_views(self, obs: dict[str, Any], env: Any) -> list[View]:
        cats = env.categories
        labels = [g.label for g in env.ground_truth() if g.pixels >= self.suite.min_pixels]
        return [View.from_observation(obs, label, cats) for label in labels]

    @staticmethod
    def _scene_truths(env: Any, views: list[View]) -> list[GroundTruth]:
        by_label = {g.label: g for g in env.ground_truth()}
        cats = env.categories
        out = []
        for v in views:
            g = by_label[view_label(v)]
            out.append(GroundTruth.of(g, cats, g.R_cam, g.t_cam))
        return out

    def base_row(self, index: int, j: int, view: View, gt: GroundTruth) -> dict[str, Any]:
        """The row of view ``j`` of item ``index`` as far as it is known without the backend."""
        return {
            "item": index,
            "view": j,
            "key": gt.key,
            "category": gt.category,
            "true_class": gt.class_index,
            "pixels": int(np.count_nonzero(view.mask)),
            "class_given": self.class_hint,
        }

    def pick_row(self, index: int, obs: dict[str, Any], env: Any, n_views: int) -> dict[str, Any]:
        """The row of pick episode ``index`` as far as it is known without the backend (the
        asked class is the task, not a secret)."""
        target = int(obs["target_class"])
        return {
            "item": index,
            "view": 0,
            "category": env.categories[target],
            "true_class": target,
            "views": n_views,
        }

    def templates(self, index: int) -> list[dict[str, Any]]:
        """Item ``index``'s rows before any backend call (see :func:`failed_rows`)."""
        if self.suite.kind != "pick":
            return self._base_rows(index, self.views(index))
        env = self._pick_env()
        obs, _ = env.reset(seed=episode_seed(self.suite, index))
        return [self.pick_row(index, obs, env, len(self._scene_views(obs, env)))]

    def _base_rows(self, index: int, views: list[View]) -> list[dict[str, Any]]:
        truths = self.truths(index, views)
        return [
            self.base_row(index, j, v, gt)
            for j, (v, gt) in enumerate(zip(views, truths, strict=True))
        ]


def world_frame(rng: np.random.Generator, protocol: str) -> np.ndarray:
    """A random rigid world frame for an isolated view (4x4, applied on the left of the
    rig's ``cam_to_world``): a yaw about +z in 1-DOF (up stays up, which that protocol
    reveals), a uniformly random rotation otherwise; and a translation uniform in a 2 m
    cube, so the camera's position says nothing about where the object is."""
    if protocol == "1dof":
        yaw = rng.uniform(0.0, 2 * np.pi)
        Q = Rotation.from_rotvec([0.0, 0.0, yaw]).as_matrix()
    else:
        Q = Rotation.random(random_state=rng).as_matrix()
    return rigid(Q, rng.uniform(-WORLD_OFFSET_M, WORLD_OFFSET_M, 3))


WORLD_OFFSET_M = 1.0
"""Half the side of the cube an isolated view's world origin is drawn from (m): larger than
the rig's camera distance (0.45-0.8 m), so the camera's world position hides the object's."""


def inst_categories(objects: ObjectSet | None) -> tuple[str, ...]:
    assert objects is not None  # set by ItemViews._isolated
    return objects.categories


def view_label(view: View) -> int:
    """The segmentation label of the object a scene view shows."""
    return int(np.asarray(view.segmentation)[np.asarray(view.mask)][0])


Announce = Callable[[list[dict[str, Any]]], None]
"""Told an item's rows as far as they are known before the backend is called (the
worker pool's ``begin`` message)."""


def _no_announce(rows: list[dict[str, Any]]) -> None:
    pass


class Evaluator(ItemViews):
    """Scores ``backend`` on items of ``suite``. Create one per worker process."""

    def __init__(
        self,
        suite: Suite,
        backend: str,
        backend_kwargs: dict[str, Any] | None = None,
        allow_privileged: bool = False,
    ):
        super().__init__(suite)
        self.backend: PerceptionBackend = get_backend(backend, **(backend_kwargs or {}))
        # the truth goes to an in-tree bound, or to a plugin run with --allow-privileged
        self.privileged = check_privileged(backend, self.backend, allow_privileged)
        # the true class goes only to a backend that can use it, and only in the class-given
        # track (Suite.track): the hint is the track's, never a backend option's
        self.class_hint = suite.gives_class and bool(
            getattr(self.backend, "wants_class_hint", False)
        )

    def run_item(self, index: int, announce: Announce = _no_announce) -> list[dict[str, Any]]:
        """The result rows of item ``index``. The first row carries ``item_ms`` (the whole
        item's time in this worker: rendering, every prediction, scoring, grasping) and
        ``item_rows`` (how many rows the item has: a reader can tell a complete item from one
        that lost a line). ``announce`` gets the rows known before the backend is called."""
        t0 = time.perf_counter()
        if self.suite.kind == "pick":
            rows = [self._pick(index, announce)]
        else:
            views = self.views(index)
            announce(self._base_rows(index, views))
            answers = [self.predict(index, j, v) for j, v in enumerate(views)]
            truths = self.truths(index, views)
            rows = [
                self._score(index, j, v, gt, answer)
                for j, (v, gt, answer) in enumerate(zip(views, truths, answers, strict=True))
            ]
        if rows:
            rows[0]["item_ms"] = 1000 * (time.perf_counter() - t0)
            rows[0]["item_rows"] = len(rows)
        return rows

    # -- backend calls ---------------------------------------------------------------------
    def predict(self, index: int, j: int, view: View) -> tuple[Estimate | None, float, str | None]:
        """The backend's answer for view ``j`` of item ``index``. Only a privileged bound
        is handed the truth; the class hint goes only to a backend in the class-given track
        that uses it (both fetched here, for this call alone)."""
        if self.privileged or self.class_hint:
            gt = self._truth_of(index, view)
            if self.privileged:
                view = replace(view, ground_truth=gt)
            if self.class_hint:
                view = replace(view, class_hint=gt.class_index)
            del gt
        t0 = time.perf_counter()
        try:
            est = validate_estimate(self.backend.predict(view), view)
            failure = None
        except Exception as e:  # recorded, scored as wrong; the run goes on
            est, failure = None, f"{type(e).__name__}: {e}"[:500]
        return est, time.perf_counter() - t0, failure

    def _truth_of(self, index: int, view: View) -> GroundTruth:
        if self.suite.kind == "isolated":
            return self.isolated_truth(index)
        return self._scene_truths(self._pick_env(), [view])[0]

    def _score(
        self,
        index: int,
        j: int,
        view: View,
        gt: GroundTruth,
        answer: tuple[Estimate | None, float, str | None],
    ) -> dict[str, Any]:
        est, seconds, failure = answer
        row = self.base_row(index, j, view, gt)
        row.update(ms=1000 * seconds, failure=failure)
        if est is None:
            row.update(pred_class=-1, correct=False)
            return row
        row["pred_class"] = est.class_index
        row["correct"] = est.class_index == gt.class_index
        row["class_prob_true"] = float(est.class_probs[gt.class_index])
        truth = truth_shape(gt.key, self.suite.resolution)
        if self.suite.protocol != "known-pose":
            row.update(score_pose(est, gt, truth, view.K))
            # Pix3D viewpoints, against the symmetric truth nearest to the estimate
            R_sym = metrics.closest_symmetric_pose(est.rotation, gt.R_cam, gt.symmetry)
            row["viewpoint_est"] = list(metrics.viewpoint(est.rotation))
            row["viewpoint_gt"] = list(metrics.viewpoint(R_sym))
        row.update(score_shape(est, gt, truth))
        return row

    # -- pick ------------------------------------------------------------------------------
    def _pick(self, index: int, announce: Announce = _no_announce) -> dict[str, Any]:
        """One BEOPick-v0 episode decided from the backend's estimates of every visible
        object: the target is the object with the highest probability of the asked class;
        the grasp is planned on its estimated surface (``Estimate.mesh``, else marching cubes
        on ``shape``) placed by its estimated pose and size, with the other objects'
        estimated surfaces as obstacles (their observed points where the backend failed);
        the env executes the best grasp once."""
        from beo_bench.grasping import plan_grasps

        env = self._pick_env()
        obs, _ = env.reset(seed=episode_seed(self.suite, index))
        target = int(obs["target_class"])
        views = self._scene_views(obs, env)
        row = self.pick_row(index, obs, env, len(views))
        announce([dict(row)])
        row["failure"] = None
        estimates, total, failures = [], 0.0, []
        for j, v in enumerate(views):
            est, seconds, failure = self.predict(index, j, v)
            estimates.append(est)
            total += seconds
            if failure:
                failures.append(failure)
        row["ms"] = 1000 * total / max(len(views), 1)  # per view, as in the other suites
        row["ms_decision"] = 1000 * total  # every view of the scene: one pick decision
        scores = [-1.0 if e is None else float(e.class_probs[target]) for e in estimates]
        if not views or max(scores) < 0:
            row.update(success=False, reason="no_estimate", failure=(failures or [None])[0])
            return row
        k = int(np.argmax(scores))  # ties: the first, in label order
        best, chosen = estimates[k], views[k]
        assert best is not None
        label = view_label(chosen)
        row["chosen_label"] = label
        row["chosen_is_target"] = label == env.target_label
        row["chosen_category"] = self._scene_truths(env, [chosen])[0].category
        cam_to_world = np.asarray(obs["cam_to_world"], dtype=np.float64)
        mesh = estimate_mesh(best, cam_to_world)
        if mesh is None:
            row.update(success=False, reason="empty_shape")
            return row
        obstacles = [
            obstacle_points(e, v, cam_to_world)
            for j, (e, v) in enumerate(zip(estimates, views, strict=True))
            if j != k
        ]
        grasps = plan_grasps(
            mesh, env.table.table_height, np.concatenate(obstacles) if obstacles else None
        )
        if not grasps:
            row.update(success=False, reason="no_grasp")
            return row
        _, reward, _, _, info = env.step(grasps[0].action)
        row.update(success=bool(reward > 0), reason=str(info["reason"]))
        return row


def failed_rows(kind: str, templates: list[dict[str, Any]], reason: str) -> list[dict[str, Any]]:
    """The rows of an item whose backend never answered (``reason``: ``timeout after 60 s``,
    ``worker died: signal 6``), from its rows as known before the backend was called. They
    are scored as a backend's exception is: class wrong, no pose or shape (the summary counts
    a rotation error of 180 degrees, IoU 0), the pick unsuccessful (its ``reason`` is
    ``timeout`` or ``worker_died``). No time is recorded: the backend gave none."""
    rows = []
    for t in templates:
        row = {**t, "failure": reason}
        if kind == "pick":
            why = "timeout" if reason.startswith("timeout") else "worker_died"
            row.update(success=False, reason=why)
        else:
            row.update(pred_class=-1, correct=False)
        rows.append(row)
    if rows:
        rows[0]["item_rows"] = len(rows)
    return rows


def local_mesh(est: Estimate) -> Any:
    """The estimate's surface in its canonical frame (metres): ``Estimate.mesh`` when given,
    else :func:`grid_mesh` of its occupancy scaled by the estimated size (the grid's cube
    edge is the largest extent). ``None`` when the grid is empty."""
    if est.mesh is not None:
        return est.mesh
    return grid_mesh(est.shape, edge=float(np.max(est.size)))


def _to_world(points: np.ndarray, est: Estimate, cam_to_world: np.ndarray) -> np.ndarray:
    cam = points @ np.asarray(est.rotation).T + np.asarray(est.translation)
    return cam @ cam_to_world[:3, :3].T + cam_to_world[:3, 3]


def estimate_mesh(est: Estimate, cam_to_world: np.ndarray) -> Any:
    """The estimate's surface (:func:`local_mesh`) placed by its pose, then by
    ``cam_to_world``: a world-frame mesh (``None`` when the shape is empty)."""
    import trimesh

    mesh = local_mesh(est)
    if mesh is None:
        return None
    world = _to_world(np.asarray(mesh.vertices), est, cam_to_world)
    return trimesh.Trimesh(world, mesh.faces, process=False)  # the planner fixes orientation


def obstacle_points(est: Estimate | None, view: View, cam_to_world: np.ndarray) -> np.ndarray:
    """World points that a grasp of another object must avoid: ``SURFACE_SAMPLES`` samples
    of this object's estimated surface, placed by its estimate (the same samples the
    ground-truth planner takes of a true mesh), or its observed points when there is no
    estimate or the shape is empty."""
    from beo_bench.objects.instance import SURFACE_SAMPLES
    from beo_bench.objects.processing import surface_samples

    mesh = local_mesh(est) if est is not None else None
    if est is None or mesh is None:
        return view.points() @ cam_to_world[:3, :3].T + cam_to_world[:3, 3]
    points, _ = surface_samples(mesh, SURFACE_SAMPLES, seed=0)
    return _to_world(points, est, cam_to_world)
