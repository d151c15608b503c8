"""Perception backends: the protocol, the registry and the conformance check.

In-tree backends register with :func:`register_backend`; third-party packages declare an
entry point in the group ``beo_bench.backends`` whose object is a backend class or factory
(``name = "pkg.module:Factory"``); :func:`load_plugins` loads them (the CLI and the runner
call it explicitly, so importing ``beo_bench`` never imports foreign code). A plugin that
fails to load is named in one :class:`PluginWarning` and skipped, so one broken package
does not take the others down; asking for it by name then raises :class:`PluginError`.
"""

from __future__ import annotations

import importlib
import inspect
import multiprocessing
import numbers
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import EntryPoint, entry_points
from typing import Any, Protocol, runtime_checkable

import numpy as np

from beo_bench.errors import BackendError, BeoBenchError, EstimateError, PluginError, UsageError
from beo_bench.types import Estimate, View

ENTRY_POINT_GROUP = "beo_bench.backends"


@dataclass(frozen=True)
class InTreeBackend:
    """Where an in-tree backend is registered and the line listings show for it: known
    without importing its module, so ``beo-bench --help`` lists every backend without
    loading torch (about 1.7 s). It is the one record of their ``description`` and
    ``diagnostic`` flag; a plugin sets them as attributes of its class or factory."""

    module: str
    description: str
    diagnostic: bool = False


IN_TREE: dict[str, InTreeBackend] = {
    "oracle": InTreeBackend(
        "beo_bench.perception.bounds",
        "the ground truth (class, pose, size, shape, mesh): the upper bound",
    ),
    "random": InTreeBackend(
        "beo_bench.perception.bounds",
        "chance: a random class and rotation, the class-mean shape: the lower bound",
    ),
    "icp": InTreeBackend(
        "beo_bench.perception.icp",
        "multi-start trimmed ICP of the observed points to the class-mean surface",
    ),
    "icp-plain": InTreeBackend(
        "beo_bench.perception.icp", "the dissertation's ICP baseline: icp with its plain defaults"
    ),
    "beo": InTreeBackend(
        "beo_bench.perception.beo",
        "Bayesian Eigenobjects (chapter 3): class, pose and shape by search",
    ),
    "hbeo": InTreeBackend(
        "beo_bench.perception.hbeo",
        "Hybrid Bayesian Eigenobjects (chapter 4): one network pass per view",
    ),
    "hbeo-mdn-likelihood": InTreeBackend(
        "beo_bench.perception.hbeo",
        "HBEO-MDN (chapter 5): the rotation sample of highest mixture density",
    ),
    "hbeo-mdn-posterior": InTreeBackend(
        "beo_bench.perception.hbeo",
        "HBEO-MDN (chapter 5): rotation samples scored with the silhouette prior",
    ),
    "swap": InTreeBackend(
        "beo_bench.perception.swap",
        "diagnostic: a base backend with some of its estimate replaced by the truth",
        # not one of "every backend": `beo-bench all` and the demo skip it
        diagnostic=True,
    ),
}
"""The in-tree backends by name (a test checks that importing the modules registers exactly
these, with these descriptions)."""

_IN_TREE = tuple(dict.fromkeys(b.module for b in IN_TREE.values()))
"""Modules whose import registers the in-tree backends."""


@runtime_checkable
class PerceptionBackend(Protocol):
    """Estimates class, pose, size and shape of the object in one segmented depth view.

    Optional members the runner honours:

    - ``privileged`` (default False): the runner gives the view's ``ground_truth`` only to
      backends that set it (the ``oracle`` bound);
    - ``wants_class_hint`` (default False): the backend can use ``View.class_hint``, which
      views carry only in a suite's ``class-given`` track (``Suite.track``);
    - ``description``: one line saying what it is, for listings (``beo-bench --help``;
      default: the first sentence of its docstring);
    - ``prepare(categories)``: build or load what is slow (trained models, class means) for
      that class list, caching it on disk; the runner calls it once in its own process before
      workers start, so they do not all build it at once.
    """

    name: str

    def predict(self, view: View) -> Estimate: ...


Factory = Callable[..., PerceptionBackend]
_REGISTRY: dict[str, tuple[Factory, str]] = {}  # name -> (factory, origin)
_BROKEN: dict[tuple[str, str], str] = {}  # (entry-point name, value) -> why it was skipped
_loaded_in_tree = False


class PluginWarning(UserWarning):
    """A third-party backend plugin that was skipped (it failed to import, is not a
    backend, or takes a name already registered); the other backends still load."""


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
    listed = IN_TREE.get(name)
    if listed is not None and getattr(factory, "__module__", None) != listed.module:
        # an in-tree name is taken whether or not its module has been imported yet
        raise BackendError(
            f"a backend named {name!r} is already registered (in-tree, {listed.module}); "
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
    returns the names registered. A plugin that fails to import, whose object is not a
    backend class or factory, or whose name is taken is skipped with one
    :class:`PluginWarning` naming it (the runner calls this in every worker: a broken
    package must not stop the others); :func:`get_backend` of its name says why. The
    in-tree backends are not imported here: their names are known (:data:`IN_TREE`)."""
    names = []
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if (ep.name, ep.value) in _BROKEN:
            continue  # already warned about in this process
        try:
            factory = ep.load()
            _check_plugin_object(ep, factory)
            _add(ep.name, factory, _plugin_origin(ep))
        except Exception as e:  # whatever a foreign import raises: skip that plugin only
            _skip_plugin(ep, e)
            continue
        names.append(ep.name)
    return names


def _skip_plugin(ep: EntryPoint, e: Exception) -> None:
    """Remember why ``ep`` was skipped (for :func:`get_backend`) and warn, once."""
    why = str(e) if isinstance(e, BeoBenchError) else f"{type(e).__name__}: {e}"
    key = (ep.name, ep.value)
    _BROKEN[key] = f"{_plugin_origin(ep)} (entry point {ep.name} = {ep.value}) was skipped: {why}"
    if multiprocessing.parent_process() is not None:
        return  # a runner worker: the main process loaded the plugins first and warned
    warnings.warn(
        f"backend {_BROKEN[key]}; fix or uninstall that package (the other backends are available)",
        PluginWarning,
        stacklevel=3,
    )


def _plugin_origin(ep: EntryPoint) -> str:
    dist = getattr(ep, "dist", None)
    return f"plugin {dist.name if dist is not None else ep.value}"


def _check_plugin_object(ep: EntryPoint, obj: object) -> None:
    """Refuse what cannot be a backend factory, without calling it (a call may be slow): a
    non-callable, or a class without ``predict``."""
    if not callable(obj) or (inspect.isclass(obj) and not callable(getattr(obj, "predict", 0))):
        raise PluginError(
            f"{ep.value} is a {type(obj).__name__}, not a backend class or factory (a class "
            "with `name` and `predict(view)`, or a function returning such an object)"
        )


def buildable_in_fresh_process(name: str, imports: tuple[str, ...] = ()) -> bool:
    """Whether a fresh process (a spawned runner worker, which imports the in-tree backends,
    the entry points and ``imports``) can build backend ``name``. A backend registered at
    run time in this process (a test, a notebook, a function defined inside another) exists
    only here. An unknown name counts as buildable: the fresh process then says it is
    unknown."""
    entry = _REGISTRY.get(name)
    if entry is None:
        return True
    factory, origin = entry
    if "<locals>" in getattr(factory, "__qualname__", ""):
        return False
    module = getattr(factory, "__module__", "") or ""
    return origin.startswith("plugin") or module in (*_IN_TREE, *imports)


def list_backends(diagnostic: bool = True) -> list[str]:
    """Names of the registered backends, sorted; without the diagnostic tools that wrap
    another backend (a class attribute ``diagnostic = True``, e.g. ``swap``) when
    ``diagnostic`` is False. The in-tree backends come from :data:`IN_TREE` without
    importing their modules (plugins are in the registry once :func:`load_plugins` ran)."""
    names = {n for n, b in IN_TREE.items() if diagnostic or not b.diagnostic}
    names |= {
        name
        for name, (f, _) in _REGISTRY.items()
        if name not in IN_TREE and (diagnostic or not getattr(f, "diagnostic", False))
    }
    return sorted(names)


def describe_backend(name: str) -> str:
    """One line saying what backend ``name`` is, for listings (``beo-bench --help``): its
    factory's ``description`` attribute (in-tree backends and plugins may set one), else the
    first sentence of the factory's docstring, else ``""``. Builds nothing, and imports
    nothing for an in-tree backend (:data:`IN_TREE`)."""
    if name in IN_TREE:
        return IN_TREE[name].description
    if name not in _REGISTRY:
        _ensure_in_tree()  # only so that the error lists them: they cannot add ``name``
        raise _unknown_backend(name)
    factory = _REGISTRY[name][0]
    text = getattr(factory, "description", None) or inspect.getdoc(factory) or ""
    first = " ".join(str(text).split("\n\n", 1)[0].split())
    return first.split(". ", 1)[0].rstrip(".")


def get_backend(name: str, **kwargs: Any) -> PerceptionBackend:
    """A new backend ``name`` built with ``kwargs``. An unknown option, or a value of the
    wrong type for an option whose default says its type, raises :class:`UsageError`
    listing the backend's options; so does a ``ValueError`` of the backend's own checks."""
    _ensure_in_tree()
    if name not in _REGISTRY:
        raise _unknown_backend(name)
    factory = _REGISTRY[name][0]
    _check_options(name, factory, kwargs)
    try:
        backend = factory(**kwargs)
    except BeoBenchError:
        raise
    except ValueError as e:  # the backend's own check of an option value
        raise UsageError(f"backend {name!r}: {e} ({_options_hint(factory)})") from e
    except TypeError as e:
        if "keyword argument" not in str(e):
            raise  # a bug in the backend, not an option the user gave
        raise UsageError(f"backend {name!r}: {e} ({_options_hint(factory)})") from e
    if not isinstance(backend, PerceptionBackend):
        raise BackendError(f"backend {name!r} has no `name` attribute or `predict(view)` method")
    return backend


def _unknown_backend(name: str) -> BackendError:
    broken = [why for (ep_name, _), why in _BROKEN.items() if ep_name == name]
    if broken:
        return PluginError(f"backend {name!r}: {broken[0]}; fix or reinstall that package")
    return BackendError(
        f"unknown backend {name!r}; registered: {sorted(_REGISTRY)} (third-party backends "
        f"need their package installed and `load_plugins()`, which `beo-bench` calls)"
    )


def backend_options(name: str) -> dict[str, Any] | None:
    """The options of backend ``name`` with their defaults (``inspect.Parameter.empty``
    for a required one), or None when its factory takes arbitrary ``**kwargs``."""
    _ensure_in_tree()
    if name not in _REGISTRY:
        raise _unknown_backend(name)
    return _signature_options(_REGISTRY[name][0])


def _signature_options(factory: Factory) -> dict[str, Any] | None:
    try:
        params = inspect.signature(factory).parameters.values()
    except (TypeError, ValueError):  # a builtin or C callable: nothing to read
        return None
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return None  # passes options on (swap, hbeo): the receiver checks them
    keyword = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    return {p.name: p.default for p in params if p.kind in keyword}


def _options_hint(factory: Factory) -> str:
    opts = _signature_options(factory)
    if opts is None:
        return "see the backend's documentation for its options"
    if not opts:
        return "it takes no options"
    shown = ", ".join(k if v is inspect.Parameter.empty else f"{k}={v!r}" for k, v in opts.items())
    return f"its options, with their defaults: {shown}"


def _check_options(name: str, factory: Factory, kwargs: dict[str, Any]) -> None:
    opts = _signature_options(factory)
    if opts is None:
        return
    unknown = sorted(set(kwargs) - set(opts))
    if unknown:
        raise UsageError(
            f"backend {name!r} has no option {', '.join(map(repr, unknown))}; "
            f"{_options_hint(factory)} (on the command line: --opt KEY=VALUE)"
        )
    for key, value in kwargs.items():
        expected = _type_mismatch(opts[key], value)
        if expected:
            raise UsageError(
                f"backend {name!r} option {key}={value!r}: expected {expected} (default "
                f"{opts[key]!r})"
            )


def _type_mismatch(default: Any, value: Any) -> str | None:
    """What ``value`` should have been when the option's default shows its type and the
    value cannot be one (booleans, integers, reals); else None. A None default or any other
    type is left to the backend, and so is a None value (``--opt threads=null``: several
    options take None for "the default" or "leave it alone")."""
    if value is None:
        return None
    if isinstance(default, bool):
        try:
            as_bool(value)
        except UsageError:
            return "a boolean (true/false, yes/no, on/off, 1/0)"
        return None
    real = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if isinstance(default, numbers.Integral):
        if not real or float(value) != int(value):
            return "an integer"
    elif isinstance(default, numbers.Real) and not real:
        return "a number"
    return None


_TRUE = ("1", "true", "yes", "on")
_FALSE = ("0", "false", "no", "off")


def as_bool(x: object) -> bool:
    """A boolean backend option, also from its command-line spelling (``--opt mesh=no``).
    Anything else (``"maybe"``, ``2``, a list) raises :class:`UsageError` (a ValueError)."""
    if isinstance(x, str) and x.lower() in _TRUE + _FALSE:
        return x.lower() in _TRUE
    if isinstance(x, (bool, np.bool_)) or (isinstance(x, numbers.Integral) and x in (0, 1)):
        return bool(x)
    raise UsageError(
        f"expected a boolean, got {x!r}: use one of {', '.join(_TRUE)} (true) or "
        f"{', '.join(_FALSE)} (false)"
    )


class PrivilegeError(UsageError):
    """A plugin that declares ``privileged = True`` run without ``--allow-privileged``."""


def check_privileged(name: str, backend: PerceptionBackend, allow: bool = False) -> bool:
    """Whether ``backend`` is privileged (handed the ground truth). An in-tree bound
    (``oracle``, ``swap``) may be; any other backend only with ``allow`` (``--allow-privileged``),
    because a privileged backend is given the answer: its rows are then listed with the
    bounds and never ranked (docs/benchmark.md, "What a backend is told")."""
    privileged = bool(getattr(backend, "privileged", False))
    if privileged and not allow and name not in IN_TREE:
        raise PrivilegeError(
            f"backend {name!r} declares privileged = True, so the runner would hand it the "
            "ground truth of every view: pass --allow-privileged to run it as a bound (its "
            "rows are listed with the bounds and never ranked), or drop `privileged`"
        )
    return privileged


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
