"""Perception backends: the contract, the registry and the conformance check.

A backend is a :class:`Backend` subclass, and the class is all there is to write: its
``name``, ``predict(view) -> Estimate`` and, when it has them, its options dataclass
(``Options``, :mod:`beo_bench.options`), its :class:`Capabilities` (class hint, privileged,
the model it loads), its :data:`Role` and a ``description``. ``prepare(ctx)`` and
``model_digest()`` have defaults. The registry's record of it, a :class:`BackendSpec`, is
derived from the class; the runner reads the options and capabilities from it without
building the backend.

Where a backend is declared, once:

- in-tree: one line of :data:`IN_TREE` (its class, role and description), so that listings
  and reports know every in-tree backend without importing its module (torch);
- a plugin: its class, which an entry point in the group ``beo_bench.backends`` names
  (``name = "pkg.module:MyBackend"``); :func:`load_plugins` loads them (the CLI and the
  runner call it explicitly, so importing ``beo_bench`` never imports foreign code). A
  plugin that fails to load is named in one :class:`PluginWarning` and skipped, so one
  broken package does not take the others down; asking for it by name then raises
  :class:`PluginError`;
- in-process (a test, a notebook): :func:`register` of the class.

The contract imports nothing of the runner: ``prepare`` is handed a :class:`PrepareContext`,
what a backend may read of its run, which the runner's ``RunContext`` satisfies.
"""

from __future__ import annotations

import dataclasses
import importlib
import multiprocessing
import warnings
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, replace
from enum import Enum
from importlib.metadata import EntryPoint, entry_points
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal, Protocol, get_args

import numpy as np

from beo_bench.errors import BackendError, BeoBenchError, EstimateError, PluginError, UsageError
from beo_bench.options import describe_options, parse_options
from beo_bench.types import Estimate, View

if TYPE_CHECKING:
    from beo_bench.objects.datasets import Dataset


ENTRY_POINT_GROUP = "beo_bench.backends"

Role = Literal["upper bound", "lower bound", "baseline", "method", "diagnostic"]
"""What a backend is to the reports: a bound (``oracle``, the upper; ``random``, the lower),
a baseline every method is paired against (``icp-plain``, ``icp``), a method (the default,
and every plugin's unless it says otherwise), or a diagnostic tool wrapping another backend
(``swap``: not one of "every backend", never paired)."""
ROLES: tuple[Role, ...] = get_args(Role)


@dataclass(frozen=True)
class InTree:
    """An in-tree backend's declaration: its class (``module:Class``, imported when the
    backend is first asked for), its role and the line listings show for it. Known without
    importing the module, so ``beo-bench --help`` lists every backend without loading torch
    (about 1.7 s), and reports know the bounds and baselines."""

    target: str
    role: Role
    description: str

    @property
    def module(self) -> str:
        return self.target.partition(":")[0]


IN_TREE: dict[str, InTree] = {
    "oracle": InTree(
        "beo_bench.perception.bounds:OracleBackend",
        "upper bound",
        "the ground truth (class, pose, size, shape, mesh): the upper bound",
    ),
    "random": InTree(
        "beo_bench.perception.bounds:RandomBackend",
        "lower bound",
        "chance: a random class and rotation, the class-mean shape: the lower bound",
    ),
    # the baselines in the order every method is paired against them
    "icp-plain": InTree(
        "beo_bench.perception.icp.backend:PlainICPBackend",
        "baseline",
        "the dissertation's ICP baseline: icp with its plain defaults",
    ),
    "icp": InTree(
        "beo_bench.perception.icp.backend:ICPBackend",
        "baseline",
        "multi-start trimmed ICP of the observed points to the class-mean surface",
    ),
    "beo": InTree(
        "beo_bench.perception.beo.backend:BEOBackend",
        "method",
        "Bayesian Eigenobjects (chapter 3): class, pose and shape by search",
    ),
    "hbeo": InTree(
        "beo_bench.perception.hbeo.backend:HBEOBackend",
        "method",
        "Hybrid Bayesian Eigenobjects (chapter 4): one network pass per view",
    ),
    "hbeo-mdn-likelihood": InTree(
        "beo_bench.perception.hbeo.backend:MDNLikelihoodBackend",
        "method",
        "HBEO-MDN (chapter 5): the rotation sample of highest mixture density",
    ),
    "hbeo-mdn-posterior": InTree(
        "beo_bench.perception.hbeo.backend:MDNPosteriorBackend",
        "method",
        "HBEO-MDN (chapter 5): rotation samples scored with the silhouette prior",
    ),
    "swap": InTree(
        "beo_bench.perception.swap:SwapBackend",
        "diagnostic",
        "diagnostic: a base backend with some of its estimate replaced by the truth",
    ),
}
"""The in-tree backends by name, in the order reports list them (a test checks that each
class is there, under its own name)."""


def in_tree(*roles: Role) -> tuple[str, ...]:
    """The in-tree backends of ``roles``, in :data:`IN_TREE`'s order (what reports derive
    their bounds, baselines and methods from)."""
    return tuple(n for n, b in IN_TREE.items() if b.role in roles)


class ClassHint(Enum):
    """Whether a backend uses the true class that a suite's ``class-given`` track hands out
    (``View.class_hint``; the hint belongs to the track, never to an option)."""

    NONE = "none"
    """It never reads the hint: it runs in the ``class-free`` track only."""
    OPTIONAL = "optional"
    """It uses the hint when a view carries one: it runs in both tracks."""
    REQUIRED = "required"
    """It cannot work without it (per-category networks): ``class-given`` only."""


@dataclass(frozen=True)
class Capabilities:
    """What the runner must know about a backend before it builds one: read from its class
    (for its parsed options, :meth:`Backend.capabilities_for`), never from an instance."""

    class_hint: ClassHint = ClassHint.NONE
    privileged: bool = False
    """It is handed the view's ground truth (in-tree bounds; a plugin only with
    ``--allow-privileged``); its rows are listed with the bounds, never ranked."""
    model: str | None = None
    """The kind of trained model it loads (``beo``, ``hbeo``, ``hbeo-mdn``; None: none),
    whose content digest every run records."""
    grasp: str = "best"
    """How ``pick`` plans from its estimates: ``best``, on the estimate's own pose; or
    ``robust``, the grasp most likely to hold across ``Estimate.pose_samples`` weighted by
    ``pose_weights`` (:func:`beo_bench.grasping.robust_order`)."""

    @property
    def wants_class_hint(self) -> bool:
        return self.class_hint is not ClassHint.NONE

    @property
    def needs_class_hint(self) -> bool:
        return self.class_hint is ClassHint.REQUIRED


# -- what prepare may read of its run ---------------------------------------------------------
class ProtocolInfo(Protocol):
    """What a backend may read of its suite's protocol."""

    @property
    def world_frame(self) -> str:
        """What ``View.cam_to_world`` says: ``random``, ``random-yaw`` or ``robot`` (the
        camera and the table plane in the robot's frame: a table suite)."""
        ...


class SuiteInfo(Protocol):
    """What a backend may read of its run's suite."""

    @property
    def name(self) -> str: ...

    @property
    def protocol(self) -> ProtocolInfo: ...


class PrepareContext(Protocol):
    """What :meth:`Backend.prepare` is handed: its run's class list, dataset, suite and
    asset cache, and whether it may show progress bars. The runner's ``RunContext`` is one;
    a plugin types its ``prepare`` with this and imports nothing of the runner."""

    @property
    def categories(self) -> tuple[str, ...]:
        """The class list the views carry (``View.categories``)."""
        ...

    @property
    def dataset(self) -> Dataset | None:
        """The user's dataset the objects come from (None: the procedural library)."""
        ...

    @property
    def suite(self) -> SuiteInfo: ...

    @property
    def cache_root(self) -> Path:
        """The asset cache the run keeps derived data in (pass it on to
        ``beo_bench.objects``' functions: ``instance_from_key(key, dataset, cache_root)``)."""
        ...

    @property
    def progress(self) -> bool:
        """Whether ``prepare`` may show progress bars (the driver's; workers get False)."""
        ...


@dataclass(frozen=True)
class NoOptions:
    """The options of a backend that takes none."""


class Backend(ABC):
    """The backend contract, written as one class.

    - ``name``: what ``--backend`` calls it;
    - ``predict(view) -> Estimate``;
    - ``Options``: its options dataclass (:mod:`beo_bench.options`; default: none), parsed
      from ``--opt`` values once; the instance keeps them as ``self.options``;
    - ``capabilities``: what the runner must know before building it (:class:`Capabilities`;
      :meth:`capabilities_for` when they depend on the options);
    - ``role`` and ``description``: a plugin's (an in-tree backend's are its
      :data:`IN_TREE` line);
    - ``prepare(ctx)``, called once in every process that will predict (the driver first,
      which may build what is slow and cache it on disk with progress bars; workers then
      load it), with a :class:`PrepareContext`; and ``model_digest()``, the content digest
      of the trained model the last ``prepare`` loaded (None: no learned model). Both have
      defaults.

    ``MyBackend()`` builds one with its default options, ``MyBackend(options)`` with parsed
    ones, ``MyBackend(key=value)`` parses those (as ``--opt`` does)."""

    name: ClassVar[str] = ""
    Options: ClassVar[type] = NoOptions
    capabilities: ClassVar[Capabilities] = Capabilities()
    role: ClassVar[Role] = "method"
    description: ClassVar[str] = ""

    options: Any
    """The parsed options (an instance of ``Options``)."""

    def __init__(self, options: Any = None, **kwargs: Any) -> None:
        if options is not None and kwargs:
            raise TypeError(f"{type(self).__name__}: give options or keyword options, not both")
        self.options = options if options is not None else type(self).parse(kwargs)

    @classmethod
    def parse(cls, raw: Mapping[str, Any]) -> Any:
        """``raw`` (``--opt`` values) as this backend's options; a :class:`UsageError`
        listing the valid options for an unknown key or a bad value."""
        return parse_options(cls.Options, dict(raw), cls.name)

    @classmethod
    def capabilities_for(cls, options: Any) -> Capabilities:
        """The capabilities with parsed ``options`` (default: :attr:`capabilities`)."""
        return cls.capabilities

    def prepare(self, ctx: PrepareContext) -> None:  # noqa: B027 (a default: nothing to prepare)
        """Build or load what is slow for ``ctx`` (default: nothing)."""

    def model_digest(self) -> str | None:
        """The content digest of the loaded model (default: None, no learned model)."""
        return None

    @abstractmethod
    def predict(self, view: View) -> Estimate: ...


@dataclass(frozen=True)
class BackendSpec:
    """The registry's record of a backend, derived from its class (and, in-tree, its
    :data:`IN_TREE` line): what the runner reads before building it."""

    name: str
    cls: type[Backend]
    role: Role = "method"
    description: str = ""
    origin: str = "in-tree"

    @classmethod
    def of(cls, backend: object, origin: str) -> BackendSpec:
        """The spec of ``backend``, a :class:`Backend` subclass, from its class attributes."""
        if not (isinstance(backend, type) and issubclass(backend, Backend)):
            raise BackendError(
                f"{backend!r} is not a beo_bench.backend.Backend subclass (docs/backends.md, "
                '"Writing a backend")'
            )
        if not backend.name:
            raise BackendError(f"backend class {backend.__qualname__} has no name")
        if backend.role not in ROLES:
            raise BackendError(
                f"backend {backend.name!r}: role {backend.role!r} is not one of {ROLES}"
            )
        return cls(backend.name, backend, backend.role, backend.description, origin)

    @property
    def options(self) -> type:
        """Its options dataclass."""
        return self.cls.Options

    @property
    def module(self) -> str:
        """Where its class is defined (a spawned worker imports it to find it again)."""
        return self.cls.__module__

    def parse(self, raw: Mapping[str, Any] | None = None) -> Any:
        """``raw`` (``--opt`` values) as this backend's options (:meth:`Backend.parse`)."""
        return self.cls.parse(dict(raw or {}))

    def capabilities_of(self, options: Any) -> Capabilities:
        return self.cls.capabilities_for(options)

    def make(self, options: Any) -> Backend:
        """A new backend built with parsed ``options``; a ``ValueError`` of its own checks
        is a :class:`UsageError`."""
        try:
            return self.cls(options)
        except BeoBenchError:
            raise
        except ValueError as e:  # the backend's own check of an option value
            raise UsageError(f"backend {self.name!r}: {e} ({self.options_hint()})") from e

    def options_hint(self) -> str:
        return describe_options(self.options)


_REGISTRY: dict[str, BackendSpec] = {}
_BROKEN: dict[tuple[str, str], str] = {}  # (entry-point name, value) -> why it was skipped
_ENTRY: dict[str, EntryPoint] = {}  # a plugin's name -> its entry point (its code digest)


class PluginWarning(UserWarning):
    """A third-party backend plugin that was skipped (it failed to import, is not a
    backend, or takes a name already registered); the other backends still load."""


def register(cls: type[Backend]) -> type[Backend]:
    """Register backend class ``cls`` under its ``name`` (a test's, a notebook's; usable as
    a class decorator); a taken name raises :class:`BackendError`."""
    _add(BackendSpec.of(cls, "in-process"))
    return cls


def unregister_backend(name: str) -> None:
    """Forget backend ``name`` (one registered at run time: a test, a notebook)."""
    _REGISTRY.pop(name, None)
    _ENTRY.pop(name, None)


def _target(cls: type) -> str:
    return f"{cls.__module__}:{cls.__qualname__}"


def _add(spec: BackendSpec) -> None:
    name = spec.name
    old = _REGISTRY.get(name)
    if old is not None and old.cls is not spec.cls:
        raise BackendError(
            f"a backend named {name!r} is already registered (from {old.origin}); "
            "choose another name"
        )
    listed = IN_TREE.get(name)
    if listed is not None and _target(spec.cls) != listed.target:
        # an in-tree name is taken whether or not its module has been imported yet
        raise BackendError(
            f"a backend named {name!r} is already registered (in-tree, {listed.module}); "
            "choose another name"
        )
    _REGISTRY[name] = spec


def _ensure_in_tree() -> None:
    for name in IN_TREE:  # each imported once (a registered name returns at once)
        _ensure_one(name)


def _ensure_one(name: str) -> None:
    """Import and register in-tree backend ``name`` alone: the bounds and ICP need no torch,
    whose import cost 2-6 s of each worker's start."""
    if name in _REGISTRY:
        return
    module, _, qualname = (b := IN_TREE[name]).target.partition(":")
    cls = getattr(importlib.import_module(module), qualname)
    if cls.name != name:
        raise BackendError(f"IN_TREE[{name!r}] names {b.target}, whose name is {cls.name!r}")
    _add(BackendSpec(name, cls, b.role, b.description))


def load_plugins() -> list[str]:
    """Register every backend advertised in the ``beo_bench.backends`` entry-point group;
    returns the names registered. An entry point's object is a :class:`Backend` subclass
    (whose name must be the entry point's). A plugin that fails to import, whose object is
    not a backend class, or whose name is taken is skipped with one
    :class:`PluginWarning` naming it (the runner calls this in every worker: a broken
    package must not stop the others); :func:`get_backend` of its name says why. The
    in-tree backends are not imported here: their names are known (:data:`IN_TREE`)."""
    names = []
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if (ep.name, ep.value) in _BROKEN:
            continue  # already warned about in this process
        try:
            obj = ep.load()
            _add(_plugin_spec(ep, obj))
        except Exception as e:  # whatever a foreign import raises: skip that plugin only
            _skip_plugin(ep, e)
            continue
        _ENTRY[ep.name] = ep
        names.append(ep.name)
    return names


def entry_point(name: str) -> EntryPoint | None:
    """The entry point plugin ``name`` was loaded from (None: not a loaded plugin)."""
    return _ENTRY.get(name)


def _plugin_spec(ep: EntryPoint, obj: object) -> BackendSpec:
    """The :class:`BackendSpec` of the backend class an entry point names (renamed to
    nothing: the names must agree)."""
    if not (isinstance(obj, type) and issubclass(obj, Backend)):
        what = type(obj).__name__ if not isinstance(obj, type) else f"class {obj.__name__}"
        raise PluginError(
            f"{ep.value} is a {what}, not a beo_bench.backend.Backend subclass: a plugin's "
            'entry point names its backend class (docs/backends.md, "Writing a backend")'
        )
    if obj.name != ep.name:
        raise PluginError(
            f"{ep.value} is the class of backend {obj.name!r}, but its entry point is named "
            f"{ep.name!r}: give both the same name"
        )
    return BackendSpec.of(obj, _plugin_origin(ep))


def _skip_plugin(ep: EntryPoint, e: Exception) -> None:
    """Remember why ``ep`` was skipped (for :func:`get_backend`) and warn, once."""
    why = str(e) if isinstance(e, BeoBenchError) else f"{type(e).__name__}: {e}"
    key = (ep.name, ep.value)
    _BROKEN[key] = f"{_plugin_origin(ep)} (entry point {ep.name} = {ep.value}) was skipped: {why}"
    if multiprocessing.parent_process() is not None:
        return  # a runner worker: the main process loaded the plugins first and warned
    warnings.warn(
        f"backend {_BROKEN[key]}; fix, reinstall or uninstall that package (the other "
        "backends are available)",
        PluginWarning,
        stacklevel=3,
    )


def _plugin_origin(ep: EntryPoint) -> str:
    dist = getattr(ep, "dist", None)
    return f"plugin {dist.name if dist is not None else ep.value}"


def buildable_in_fresh_process(name: str, imports: tuple[str, ...] = ()) -> bool:
    """Whether a fresh process (a spawned runner worker, which imports the in-tree backends,
    the entry points and ``imports``) can build backend ``name``. A backend registered at
    run time in this process (a test, a notebook, a function defined inside another) exists
    only here. An unknown name counts as buildable: the fresh process then says it is
    unknown."""
    spec = _REGISTRY.get(name)
    if spec is None:
        return True
    if "<locals>" in spec.cls.__qualname__:
        return False
    return spec.origin != "in-process" or spec.module in imports


def list_backends(diagnostic: bool = True) -> list[str]:
    """Names of the registered backends, sorted; without the diagnostic tools that wrap
    another backend (role ``diagnostic``, e.g. ``swap``) when ``diagnostic`` is False. The
    in-tree backends come from :data:`IN_TREE` without importing their modules (plugins
    are in the registry once :func:`load_plugins` ran)."""
    roles = {n: b.role for n, b in IN_TREE.items()}
    roles |= {n: s.role for n, s in _REGISTRY.items() if n not in IN_TREE}
    return sorted(n for n, role in roles.items() if diagnostic or role != "diagnostic")


def _static_caps(spec: BackendSpec) -> Capabilities:
    """The spec's capabilities at its default options."""
    return spec.capabilities_of(spec.parse({}))


def describe_backend(name: str) -> str:
    """One line saying what backend ``name`` is, for listings (``beo-bench --help``): its
    spec's ``description``, else ``""``. Builds nothing, and imports nothing for an
    in-tree backend (:data:`IN_TREE`)."""
    if name in IN_TREE:
        return IN_TREE[name].description
    return get_spec(name).description


def get_spec(name: str) -> BackendSpec:
    """The registered spec of backend ``name`` (importing the in-tree backends first); a
    :class:`BackendError` listing the registered names for an unknown one."""
    _ensure_one(name) if name in IN_TREE else _ensure_in_tree()
    if name not in _REGISTRY:
        raise _unknown_backend(name)
    return _REGISTRY[name]


def get_backend(name: str, **kwargs: Any) -> Backend:
    """A new backend ``name`` built with options ``kwargs`` (parsed into its options
    dataclass). An unknown option, or a value not of the option's type, raises
    :class:`UsageError` listing the backend's options; so does a ``ValueError`` of the
    backend's own checks."""
    spec = get_spec(name)
    return spec.make(spec.parse(kwargs))


def _unknown_backend(name: str) -> BackendError:
    broken = [why for (ep_name, _), why in _BROKEN.items() if ep_name == name]
    if broken:
        return PluginError(
            f"backend {name!r}: {broken[0]}; fix, reinstall or uninstall that package"
        )
    from beo_bench.names import did_you_mean

    hint = did_you_mean(name, _REGISTRY)
    return BackendError(
        f"unknown backend {name!r}; {hint}registered: {sorted(_REGISTRY)} (third-party backends "
        f"need their package installed and `load_plugins()`, which `beo-bench` calls)"
    )


def backend_options(name: str) -> dict[str, Any]:
    """The options of backend ``name`` with their defaults."""
    return {f.name: f.default for f in dataclasses.fields(get_spec(name).options)}


class PrivilegeError(UsageError):
    """A plugin that declares ``privileged`` run without ``--allow-privileged``."""


def check_privileged(name: str, caps: Capabilities, allow: bool = False) -> bool:
    """Whether backend ``name`` with capabilities ``caps`` is privileged (handed the ground
    truth). An in-tree bound (``oracle``, ``swap``) may be; any other backend only with
    ``allow`` (``--allow-privileged``), because a privileged backend is given the answer:
    its rows are then listed with the bounds and never ranked (docs/benchmark.md, "What a
    backend is told")."""
    if caps.privileged and not allow and name not in IN_TREE:
        raise PrivilegeError(
            f"backend {name!r} declares the privileged capability, so the runner would hand it "
            "the ground truth of every view: pass --allow-privileged to run it as a bound (its "
            "rows are listed with the bounds and never ranked), or drop it from its spec"
        )
    return caps.privileged


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


def check_backend(
    backend: Backend, views: list[View] | None = None, privileged: bool | None = None
) -> None:
    """The conformance test: on each view, ``predict`` returns an ``Estimate`` obeying the
    contract (types, shapes, ranges, a proper rotation, probabilities summing to 1), and the
    same input gives the same output. Raises :class:`EstimateError` on the first failure.
    Without ``views``, two rendered views of test-split instances are used. Views keep
    their ground truth only for a privileged backend (``privileged``; default: as its
    registered spec says)."""
    if not isinstance(backend, Backend):
        raise EstimateError(
            f"check_backend checks a beo_bench.backend.Backend, got a {type(backend).__name__}"
        )
    views = views if views is not None else sample_views()
    if privileged is None:  # a registered backend's spec says; anything else is not
        spec = _REGISTRY.get(backend.name)
        privileged = spec is not None and _static_caps(spec).privileged
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
