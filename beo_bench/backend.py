"""Perception backends: the protocol, the registry and the conformance check.

In-tree backends register with :func:`register_backend`; third-party packages declare an
entry point in the group ``beo_bench.backends`` whose object is a backend class or factory
(``name = "pkg.module:Factory"``); :func:`load_plugins` loads them (the CLI and the runner
call it explicitly, so importing ``beo_bench`` never imports foreign code).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from importlib.metadata import entry_points
from typing import Any, Protocol, runtime_checkable

import numpy as np

from beo_bench.errors import BackendError, EstimateError
from beo_bench.types import Estimate, View

ENTRY_POINT_GROUP = "beo_bench.backends"
_IN_TREE = (
    "beo_bench.perception.bounds",
    "beo_bench.perception.icp",
    "beo_bench.perception.beo",
    "beo_bench.perception.hbeo",
    "beo_bench.perception.swap",
)
"""Modules whose import registers the in-tree backends."""


@runtime_checkable
class PerceptionBackend(Protocol):
    """Estimates class, pose, size and shape of the object in one segmented depth view.

    Optional members the runner honours:

    - ``privileged`` (default False): the runner gives the view's ``ground_truth`` only to
      backends that set it (the ``oracle`` bound);
    - ``wants_class_hint`` (default False): ask for ``View.class_hint`` (given only by suites
      that allow it, see ``Suite.class_hint``);
    - ``prepare(categories)``: build or load what is slow (trained models, class means) for
      that class list, caching it on disk; the runner calls it once in its own process before
      workers start, so they do not all build it at once.
    """

    name: str

    def predict(self, view: View) -> Estimate: ...


Factory = Callable[..., PerceptionBackend]
_REGISTRY: dict[str, tuple[Factory, str]] = {}  # name -> (factory, origin)
_loaded_in_tree = False


def register_backend(name: str, origin: str = "in-tree") -> Callable[[Factory], Factory]:
    """Class/factory decorator: ``@register_backend("mine")``. A taken name raises."""

    def deco(factory: Factory) -> Factory:
        _add(name, factory, origin)
        return factory

    return deco


def _add(name: str, factory: Factory, origin: str) -> None:
    if name in _REGISTRY and _REGISTRY[name][0] is not factory:
        raise BackendError(
            f"a backend named {name!r} is already registered (from {_REGISTRY[name][1]}); "
            "choose another name"
        )
    _REGISTRY[name] = (factory, origin)


def _ensure_in_tree() -> None:
    global _loaded_in_tree
    if not _loaded_in_tree:
        _loaded_in_tree = True
        for mod in _IN_TREE:
            importlib.import_module(mod)


def load_plugins() -> list[str]:
    """Register every backend advertised in the ``beo_bench.backends`` entry-point group;
    returns their names. A plugin name that clashes with a registered one raises."""
    _ensure_in_tree()
    names = []
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        factory = ep.load()
        dist = getattr(ep, "dist", None)
        origin = f"plugin {dist.name if dist is not None else ep.value}"
        _add(ep.name, factory, origin)
        names.append(ep.name)
    return names


def list_backends(diagnostic: bool = True) -> list[str]:
    """Names of the registered backends, sorted; without the diagnostic tools that wrap
    another backend (a class attribute ``diagnostic = True``, e.g. ``swap``) when
    ``diagnostic`` is False."""
    _ensure_in_tree()
    return sorted(
        name
        for name, (f, _) in _REGISTRY.items()
        if diagnostic or not getattr(f, "diagnostic", False)
    )


def get_backend(name: str, **kwargs: Any) -> PerceptionBackend:
    """A new backend ``name`` built with ``kwargs``."""
    _ensure_in_tree()
    if name not in _REGISTRY:
        raise BackendError(
            f"unknown backend {name!r}; registered: {sorted(_REGISTRY)} (third-party backends "
            f"need their package installed and `load_plugins()`, which `beo-bench` calls)"
        )
    backend = _REGISTRY[name][0](**kwargs)
    if not isinstance(backend, PerceptionBackend):
        raise BackendError(f"backend {name!r} has no `name` attribute or `predict(view)` method")
    return backend


def as_bool(x: object) -> bool:
    """A boolean backend option, also from its command-line spelling (``--opt mesh=no``)."""
    if isinstance(x, str):
        if x.lower() in ("1", "true", "yes", "on"):
            return True
        if x.lower() in ("0", "false", "no", "off"):
            return False
        raise ValueError(f"expected a boolean (true/false), got {x!r}")
    return bool(x)


def prepare_backend(backend: PerceptionBackend, categories: tuple[str, ...]) -> None:
    """Call the backend's optional ``prepare(categories)`` (see :class:`PerceptionBackend`)."""
    prep = getattr(backend, "prepare", None)
    if callable(prep):
        prep(tuple(categories))


# -- the Estimate contract ------------------------------------------------------------------
def validate_estimate(est: Any, view: View, atol: float = 1e-4) -> Estimate:
    """Check ``est`` against the ``Estimate`` contract for ``view``; raise
    :class:`EstimateError` naming the first violation. Returns ``est``."""
    if not isinstance(est, Estimate):
        raise EstimateError(f"predict() must return an Estimate, got {type(est).__name__}")
    C = len(view.categories)
    p = np.asarray(est.class_probs, dtype=np.float64)
    if p.shape != (C,):
        raise EstimateError(f"class_probs must have shape ({C},), got {p.shape}")
    if not np.all(np.isfinite(p)) or p.min() < -atol or abs(p.sum() - 1.0) > atol:
        raise EstimateError(f"class_probs must be probabilities summing to 1, got {p}")
    R = np.asarray(est.rotation, dtype=np.float64)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise EstimateError(f"rotation must be a finite (3, 3) matrix, got shape {R.shape}")
    if np.abs(R @ R.T - np.eye(3)).max() > 1e-3 or np.linalg.det(R) < 0.999:
        raise EstimateError("rotation is not a proper rotation (R R^T != I or det != 1)")
    t = np.asarray(est.translation, dtype=np.float64)
    if t.shape != (3,) or not np.all(np.isfinite(t)):
        raise EstimateError(f"translation must be a finite (3,) vector, got {t}")
    s = np.asarray(est.size, dtype=np.float64)
    if s.shape != (3,) or not np.all(np.isfinite(s)) or s.min() <= 0:
        raise EstimateError(f"size must be 3 positive extents (m), got {s}")
    g = np.asarray(est.shape)
    if g.ndim != 3 or len(set(g.shape)) != 1 or g.shape[0] < 2:
        raise EstimateError(f"shape must be a (D, D, D) grid, got {g.shape}")
    if not np.all(np.isfinite(g)) or g.min() < 0 or g.max() > 1:
        raise EstimateError("shape must hold occupancy probabilities in [0, 1]")
    if est.pose_samples is not None:
        S = np.asarray(est.pose_samples)
        w = np.asarray(est.pose_weights) if est.pose_weights is not None else None
        if S.ndim != 3 or S.shape[1:] != (3, 3):
            raise EstimateError(f"pose_samples must be (N, 3, 3), got {S.shape}")
        if w is None or w.shape != (len(S),) or abs(w.sum() - 1) > atol or w.min() < -atol:
            raise EstimateError("pose_weights must be (N,) non-negative and sum to 1")
    if est.mesh is not None:
        V = np.asarray(getattr(est.mesh, "vertices", np.zeros((0, 3))))
        F = np.asarray(getattr(est.mesh, "faces", np.zeros((0, 3))))
        if V.ndim != 2 or V.shape[1:] != (3,) or len(V) == 0 or len(F) == 0:
            raise EstimateError("mesh must be a trimesh.Trimesh with vertices and faces, or None")
        if not np.all(np.isfinite(V)):
            raise EstimateError("mesh vertices must be finite")
    return est


def _arrays(e: Estimate) -> list[np.ndarray]:
    out = [np.asarray(getattr(e, f)) for f in ("class_probs", "rotation", "translation", "size")]
    out.append(np.asarray(e.shape))
    for f in ("pose_samples", "pose_weights"):
        if getattr(e, f) is not None:
            out.append(np.asarray(getattr(e, f)))
    if e.mesh is not None:
        out += [np.asarray(e.mesh.vertices), np.asarray(e.mesh.faces)]
    return out


def _same(a: Estimate, b: Estimate) -> bool:
    A, B = _arrays(a), _arrays(b)
    return len(A) == len(B) and all(np.array_equal(x, y) for x, y in zip(A, B, strict=True))


def check_backend(backend: PerceptionBackend, views: list[View] | None = None) -> None:
    """The conformance test: on each view, ``predict`` returns an ``Estimate`` obeying the
    contract (types, shapes, ranges, a proper rotation, probabilities summing to 1), and the
    same input gives the same output. Raises :class:`EstimateError` on the first failure.
    Without ``views``, two rendered views of test-split instances are used."""
    if not isinstance(backend, PerceptionBackend):
        raise EstimateError("a backend needs a `name` attribute and a `predict(view)` method")
    views = views if views is not None else sample_views()
    privileged = bool(getattr(backend, "privileged", False))
    for view in views:
        if not privileged and view.ground_truth is not None:
            view = _without_truth(view)
        first = validate_estimate(backend.predict(view), view)
        again = validate_estimate(backend.predict(view), view)
        if not _same(first, again):
            raise EstimateError(
                f"backend {backend.name!r} is not deterministic: same view, "
                "different estimates (seed any randomness from the input)"
            )


def _without_truth(view: View) -> View:
    from dataclasses import replace

    return replace(view, ground_truth=None)


def sample_views(
    n: int = 2,
    categories: tuple[str, ...] | None = None,
    split: str = "test",
    seed: int = 0,
    picks: list[tuple[str, int]] | None = None,
) -> list[View]:
    """Isolated 128x128 views with their ground truth and class hint (for ``check_backend``
    and smoke tests): of ``picks`` ((category, index) pairs of ``split``), or of ``n``
    instances cycling through the categories; camera poses drawn from the object rig with
    ``seed``."""
    from beo_bench.objects import ObjectSet
    from beo_bench.scenes.camera import OBJECT_RIG
    from beo_bench.scenes.isolated import IsolatedRenderer
    from beo_bench.types import GroundTruth

    objects = ObjectSet(split, categories)
    cats = objects.categories
    if picks is None:
        picks = [(cats[i % len(cats)], i) for i in range(n)]
    rng = np.random.default_rng(seed)
    out = []
    with IsolatedRenderer() as r:
        for cat, i in picks:
            inst = objects.get(cat, i)
            v = r.render(inst, OBJECT_RIG.sample(rng, np.zeros(3)))
            gt = GroundTruth.of(inst, cats, v.R_cam, v.t_cam)
            out.append(
                View(
                    v.depth,
                    v.mask,
                    v.K,
                    v.cam_to_world,
                    cats,
                    class_hint=gt.class_index,
                    ground_truth=gt,
                )
            )
    return out
