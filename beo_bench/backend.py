"""Perception backends: the contract, the registry and the conformance check.

A backend is registered as a :class:`BackendSpec`: its factory, its typed options
(a frozen dataclass, :mod:`beo_bench.options`) and its :class:`Capabilities` (class hint,
privileged, diagnostic, the model it loads), which the runner reads without building the
backend. The backend itself is a :class:`Backend`: ``name``, ``predict(view)``, and
``prepare(ctx)`` / ``model_digest()`` with defaults. In-tree backends register with
:func:`register`; third-party packages declare an entry point in the group
``beo_bench.backends`` whose object is the spec (``name = "pkg.module:SPEC"``);
:func:`load_plugins` loads them (the CLI and the runner call it explicitly, so importing
``beo_bench`` never imports foreign code). A plugin that fails to load is named in one
:class:`PluginWarning` and skipped, so one broken package does not take the others down;
asking for it by name then raises :class:`PluginError`.
"""

from __future__ import annotations

import dataclasses
import importlib
import multiprocessing
import warnings
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from enum import Enum
from importlib.metadata import EntryPoint, entry_points
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench.errors import BackendError, BeoBenchError, EstimateError, PluginError, UsageError
from beo_bench.options import describe_options, parse_options
from beo_bench.types import Estimate, View

if TYPE_CHECKING:
    from beo_bench.bench.runs import RunContext


ENTRY_POINT_GROUP = "beo_bench.backends"


@dataclass(frozen=True)
class InTreeBackend:
    """Where an in-tree backend is registered and the line listings show for it: known
    without importing its module, so ``beo-bench --help`` lists every backend without
    loading torch (about 1.7 s). It is the one record of their ``description`` and
    ``diagnostic`` flag; a plugin's spec has its own."""

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
    """What the runner must know about a backend before it builds one: read from its
    :class:`BackendSpec` (for its parsed options), never from a built instance."""

    class_hint: ClassHint = ClassHint.NONE
    privileged: bool = False
    """It is handed the view's ground truth (in-tree bounds; a plugin only with
    ``--allow-privileged``); its rows are listed with the bounds, never ranked."""
    diagnostic: bool = False
    """A tool wrapping another backend (``swap``): not one of "every backend"."""
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


class Backend(ABC):
    """The backend contract: ``name``, ``predict(view) -> Estimate``, and two members with
    defaults: ``prepare(ctx)``, called once in every process that will predict (the driver
    first, which may build what is slow and cache it on disk with progress bars; workers then
    load it), with the run's :class:`~beo_bench.bench.runs.RunContext` (its class list,
    dataset, suite); and ``model_digest()``, the content digest of the trained model the last
    ``prepare`` loaded (None: no learned model). What the runner needs before building it
    (class hint, privileged, ...) is the spec's :class:`Capabilities`."""

    name: str = ""

    def prepare(self, ctx: RunContext) -> None:  # noqa: B027 (a default: nothing to prepare)
        """Build or load what is slow for ``ctx`` (default: nothing)."""

    def model_digest(self) -> str | None:
        """The content digest of the loaded model (default: None, no learned model)."""
        return None

    @abstractmethod
    def predict(self, view: View) -> Estimate: ...


@dataclass(frozen=True)
class NoOptions:
    """The options of a backend that takes none."""


@dataclass(frozen=True)
class BackendSpec:
    """A registered backend: how to build one from its typed options, the options'
    dataclass (:mod:`beo_bench.options`), and its capabilities (a value, or a function of
    the parsed options when they change them: ``hbeo``'s ``per_category``).

    ``build(options)`` returns a :class:`Backend`. Plugins register one through the
    ``beo_bench.backends`` entry-point group (its object is the spec)."""

    name: str
    build: Callable[[Any], Backend]
    options: type = NoOptions
    capabilities: Capabilities | Callable[[Any], Capabilities] = Capabilities()
    description: str = ""
    origin: str = "in-tree"
    module: str = ""
    """Where the spec is defined (a spawned worker imports it to find the backend again);
    default: the module of ``build``."""
    parser: Callable[[Mapping[str, Any]], Any] | None = None
    """Parses the options instead of :func:`~beo_bench.options.parse_options` (``swap``,
    whose options include its base backend's)."""

    def __post_init__(self) -> None:
        # an in-tree backend's line is IN_TREE's (listed without importing its module)
        if not self.description and self.name in IN_TREE:
            object.__setattr__(self, "description", IN_TREE[self.name].description)
        if not self.module:
            object.__setattr__(self, "module", getattr(self.build, "__module__", "") or "")

    def parse(self, raw: Mapping[str, Any] | None = None) -> Any:
        """``raw`` (``--opt`` values) as this backend's options; a :class:`UsageError`
        listing the valid options for an unknown key or a bad value."""
        if self.parser is not None:
            return self.parser(dict(raw or {}))
        return parse_options(self.options, dict(raw or {}), self.name)

    def capabilities_of(self, options: Any) -> Capabilities:
        caps = self.capabilities
        return caps(options) if callable(caps) else caps

    def make(self, options: Any) -> Backend:
        """A new backend built with parsed ``options``; a ``ValueError`` of its own checks
        is a :class:`UsageError`."""
        try:
            backend = self.build(options)
        except BeoBenchError:
            raise
        except ValueError as e:  # the backend's own check of an option value
            raise UsageError(f"backend {self.name!r}: {e} ({self.options_hint()})") from e
        if not isinstance(backend, Backend):
            raise BackendError(
                f"backend {self.name!r} built a {type(backend).__name__}, not a "
                'beo_bench.backend.Backend (subclass it: docs/backends.md, "Writing a backend")'
            )
        return backend

    def options_hint(self) -> str:
        return describe_options(self.options)


_REGISTRY: dict[str, BackendSpec] = {}
_BROKEN: dict[tuple[str, str], str] = {}  # (entry-point name, value) -> why it was skipped
_ENTRY: dict[str, EntryPoint] = {}  # a plugin's name -> its entry point (code_digest reads it)
_loaded_in_tree = False


class PluginWarning(UserWarning):
    """A third-party backend plugin that was skipped (it failed to import, is not a
    backend, or takes a name already registered); the other backends still load."""


def register(spec: BackendSpec) -> BackendSpec:
    """Register ``spec`` under its name; a taken name raises :class:`BackendError`."""
    _add(spec)
    return spec


def unregister_backend(name: str) -> None:
    """Forget backend ``name`` (one registered at run time: a test, a notebook)."""
    _REGISTRY.pop(name, None)
    _ENTRY.pop(name, None)


def _add(spec: BackendSpec) -> None:
    name = spec.name
    old = _REGISTRY.get(name)
    if old is not None and old.build is not spec.build:
        raise BackendError(
            f"a backend named {name!r} is already registered (from {old.origin}); "
            "choose another name"
        )
    listed = IN_TREE.get(name)
    if listed is not None and spec.module != listed.module:
        # an in-tree name is taken whether or not its module has been imported yet
        raise BackendError(
            f"a backend named {name!r} is already registered (in-tree, {listed.module}); "
            "choose another name"
        )
    _REGISTRY[name] = spec


def _ensure_in_tree() -> None:
    global _loaded_in_tree
    if not _loaded_in_tree:
        _loaded_in_tree = True
        for mod in _IN_TREE:
            importlib.import_module(mod)


def load_plugins() -> list[str]:
    """Register every backend advertised in the ``beo_bench.backends`` entry-point group;
    returns the names registered. An entry point's object is a :class:`BackendSpec` (whose
    name must be the entry point's). A plugin that fails to import, whose object is not a
    spec, or whose name is taken is skipped with one
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


# -- a plugin's code digest -------------------------------------------------------------------
_INSTALL_RECORDS = frozenset({"RECORD", "INSTALLER", "REQUESTED", "direct_url.json"})
"""A distribution's files that say how it was installed, not what it runs (``pip`` writes
them; ``direct_url.json`` holds the path it was installed from): left out of its digest."""


def code_digest(name: str, options: Any) -> str | None:
    """The SHA-256 of the code backend ``name`` runs and of its parsed ``options``, which
    every run records (``run.json``, ``code_digest``) so that ``run --resume`` and ``all``
    notice a plugin that changed since its results were scored (issue 47). Its code is:

    - a plugin's: every file of the distribution that provides its entry point
      (``importlib.metadata``, its ``RECORD``; byte-code and the install records left out),
      and every file of the top-level package (or module) its entry point imports, found
      where Python imports it from: that covers an editable install, whose ``RECORD`` lists
      only a ``.pth`` file, and a distribution with no ``RECORD``;
    - a backend registered in-process, without a distribution (a notebook, a test, a
      script's ``register``): the source file of the module that registered it; None when it
      has none (defined at an interactive prompt), and nothing can be checked;
    - an in-tree backend's: None. Its code is the package's, which the run's provenance
      names (version and git commit), and its trained model has its own digest
      (``model_digest``).

    Files are hashed by their content and their path inside the distribution or package,
    so the same code installed elsewhere has the same digest."""
    import hashlib

    spec = get_spec(name)
    if name in IN_TREE and spec.module == IN_TREE[name].module:
        return None
    files = _code_files(name, spec)
    if not files:
        return None
    h = hashlib.sha256()
    for label, path in sorted(files.items()):
        h.update(label.encode() + b"\0")
        try:
            h.update(hashlib.sha256(path.read_bytes()).digest())
        except OSError as e:  # a listed file that is gone or unreadable changes the digest
            h.update(f"unreadable: {type(e).__name__}".encode())
    text = _options_text(options)
    h.update(b"options\0" + text.encode())
    return h.hexdigest()


def _options_text(options: Any) -> str:
    """Parsed options as canonical JSON (a dataclass's fields; anything else by repr)."""
    import json

    is_instance = dataclasses.is_dataclass(options) and not isinstance(options, type)
    value = dataclasses.asdict(options) if is_instance else options
    return json.dumps(value, sort_keys=True, default=repr)


def _code_files(name: str, spec: BackendSpec) -> dict[str, Path]:
    """The files whose content is backend ``name``'s code (:func:`code_digest`), by a label
    that does not depend on where they are installed."""
    import importlib.util
    import sys

    out: dict[str, Path] = {}
    ep = _ENTRY.get(name)
    if ep is None:  # registered in-process: the module that registered it
        where = getattr(sys.modules.get(spec.module), "__file__", None)
        return {f"module {spec.module}": Path(where)} if where else {}
    dist = getattr(ep, "dist", None)
    dist_name = str(getattr(dist, "name", ""))
    for f in (dist.files if dist is not None else None) or []:
        parts = Path(str(f)).parts
        if "__pycache__" in parts or f.name.endswith(".pyc"):
            continue
        if len(parts) > 1 and parts[0].endswith(".dist-info") and f.name in _INSTALL_RECORDS:
            continue
        out[f"dist {dist_name}:{Path(str(f)).as_posix()}"] = Path(str(f.locate()))
    top = ep.module.split(".")[0]
    try:
        found = importlib.util.find_spec(top)
    except (ImportError, ValueError):
        found = None
    if found is not None:
        roots = list(found.submodule_search_locations or [])
        if roots:
            for root in map(Path, roots):
                for p in sorted(root.rglob("*")):
                    if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc":
                        out[f"package {top}:{p.relative_to(root).as_posix()}"] = p
        elif found.origin and Path(found.origin).is_file():
            out[f"module {top}"] = Path(found.origin)
    return out


def _plugin_spec(ep: EntryPoint, obj: object) -> BackendSpec:
    """The :class:`BackendSpec` an entry point advertises (renamed to nothing: the names
    must agree)."""
    if not isinstance(obj, BackendSpec):
        raise PluginError(
            f"{ep.value} is a {type(obj).__name__}, not a BackendSpec: a plugin's entry point "
            'names its backend\'s spec (docs/backends.md, "Writing a backend")'
        )
    if obj.name != ep.name:
        raise PluginError(
            f"{ep.value} is the spec of backend {obj.name!r}, but its entry point is named "
            f"{ep.name!r}: give both the same name"
        )
    return replace(obj, origin=_plugin_origin(ep))


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
    if "<locals>" in getattr(spec.build, "__qualname__", ""):
        return False
    return spec.origin.startswith("plugin") or spec.module in (*_IN_TREE, *imports)


def list_backends(diagnostic: bool = True) -> list[str]:
    """Names of the registered backends, sorted; without the diagnostic tools that wrap
    another backend (``Capabilities.diagnostic``, e.g. ``swap``) when ``diagnostic`` is
    False. The in-tree backends come from :data:`IN_TREE` without importing their modules
    (plugins are in the registry once :func:`load_plugins` ran)."""
    names = {n for n, b in IN_TREE.items() if diagnostic or not b.diagnostic}
    names |= {
        name
        for name, spec in _REGISTRY.items()
        if name not in IN_TREE and (diagnostic or not _static_caps(spec).diagnostic)
    }
    return sorted(names)


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
    _ensure_in_tree()
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
    spec = get_spec(name)
    return {f.name: f.default for f in dataclasses.fields(spec.options)}


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
