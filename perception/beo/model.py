"""BEO's learned state: per-class VBPCA, the shared subspace and the class densities
(dissertation section 3.2), trained from the object library's ``train`` split, stored as a
directory and loaded by name.

Training (``beo-bench train beo``; the default model trains on first use):

1. Every training instance's solid voxel grid (D^3, canonical frame scaled into the unit
   cube) is flattened to t in {0, 1}^d, d = D^3.
2. Per class, VBPCA (:mod:`.vbpca`) gives ``W_i`` (the fewest principal directions capturing
   ``variance_fraction`` of the class's variance) and ``mu_i``.
3. The shared subspace: an orthonormal basis of ``[W_1 .. W_m, mu_1 .. mu_m]`` by SVD,
   keeping rank(...) columns (eq. 3.5). Objects are coded as ``o' = W^T (o - mu)`` with
   ``mu`` the mean of the class means (which lies in the span), and decoded as
   ``W o' + mu`` (eq. 3.6-3.7).
4. Per class, a Gaussian over the codes of its training objects with the shrinkage
   covariance of eq. 3.9 (:mod:`.shrinkage`); classification is MAP over them (eq. 3.10-3.11).

A model directory holds ``config.json`` (settings, categories, resolution, library and
format versions, training time, the digest of the arrays) and ``arrays.npz``; it is written
to a temporary directory and renamed into place, so a killed training leaves no half model
behind, and it replaces only a BEO model this package wrote (:mod:`.modeldir`). Models are
addressed by name under :func:`models_root`, never by a path.
"""

from __future__ import annotations

import functools
import hashlib
import json
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from beo_bench.atomic import atomic_dir
from beo_bench.errors import CheckpointError
from beo_bench.names import inside
from beo_bench.objects.datasets import Dataset, train_command
from beo_bench.perception import modeldir, published
from beo_bench.perception.beo.shrinkage import shrinkage_covariance
from beo_bench.perception.beo.vbpca import VBPCAConfig, fit_vbpca
from beo_bench.perception.digest import BEO_ARRAYS, beo_array_shapes, read_beo_arrays, state_digest
from beo_bench.perception.means import training_voxels

FORMAT_VERSION = 1
DEFAULT_NAME = "default"
FILES = frozenset({"config.json", "arrays.npz"})
"""Exactly what a BEO model directory holds."""
ARRAYS = BEO_ARRAYS
"""The arrays of ``arrays.npz`` (defined in :mod:`.digest`, which reads them too)."""


@dataclass(frozen=True)
class BEOConfig:
    """What a BEO model is trained on and how."""

    categories: tuple[str, ...]
    """Class list, in the order of ``class_probs``."""
    resolution: int = 32
    """D: voxels per edge (d = D^3)."""
    per_category: int | None = None
    """Training instances per class (None: the whole ``train`` split)."""
    variance_fraction: float = 0.6
    """Per-class VBPCA keeps the directions capturing this fraction of variance (sec. 3.3.1)."""
    max_components: int = 64
    """Latent dimension each VBPCA starts from (ARD switches off the excess)."""
    max_iter: int = 300
    """VBPCA iterations at most (it stops earlier once the bound settles)."""

    def __post_init__(self) -> None:
        # one class is allowed: its subspace is what a per-category HBEO network regresses
        # (Table 5.1's protocol); BEO's classification is then trivially that class
        if len(self.categories) < 1:
            raise ValueError("BEO needs at least one category")
        if self.resolution < 8:
            raise ValueError(f"resolution={self.resolution} is too coarse (use >= 8)")
        if not 0 < self.variance_fraction <= 1:
            raise ValueError(f"variance_fraction={self.variance_fraction} must be in (0, 1]")


@dataclass
class BEOModel:
    """A trained BEO model: the shared subspace and one Gaussian per class in it."""

    config: BEOConfig
    basis: np.ndarray
    """(d, k) float32, orthonormal columns W."""
    mean: np.ndarray
    """(d,) float32, mu."""
    class_mean: np.ndarray
    """(C, k) mean code of each class."""
    class_cov: np.ndarray
    """(C, k, k) shrinkage covariance of each class's codes (eq. 3.9)."""
    class_size: np.ndarray
    """(C, 3) mean bounding-box extents (m) of each class's training instances."""
    components: np.ndarray
    """(C,) VBPCA columns kept per class."""
    shrinkage: np.ndarray
    """(C, 2) the estimated (Ledoit-Wolf delta, Schafer-Strimmer lambda) per class."""
    info: dict = field(default_factory=dict)
    """Provenance: library version, training time, instances per class."""

    def __post_init__(self) -> None:
        # log N(o'; m_c, S_c) = -1/2 |L_c^-1 (o' - m_c)|^2 - log|L_c| - k/2 log 2 pi
        L = np.linalg.cholesky(self.class_cov)
        eye = np.broadcast_to(np.eye(self.k), L.shape)
        self.chol_inv = np.linalg.solve(L, eye).astype(np.float32)  # (C, k, k)
        self.log_norm = (
            -np.sum(np.log(np.diagonal(L, axis1=1, axis2=2)), axis=1)
            - 0.5 * self.k * np.log(2 * np.pi)
        ).astype(np.float32)

    @property
    def k(self) -> int:
        return int(self.basis.shape[1])

    @property
    def D(self) -> int:
        return self.config.resolution

    @property
    def categories(self) -> tuple[str, ...]:
        return self.config.categories

    def log_density(self, codes: np.ndarray) -> np.ndarray:
        """(n, C) log N(o'; m_c, Sigma_c) of codes (n, k) under every class (eq. 3.10)."""
        diff = np.asarray(codes, dtype=np.float32)[:, None, :] - self.class_mean[None]
        z = np.einsum("cij,ncj->nci", self.chol_inv, diff.astype(np.float32))
        return self.log_norm[None] - 0.5 * np.sum(z**2, axis=2)

    # -- storage --------------------------------------------------------------------------
    def arrays(self) -> dict[str, np.ndarray]:
        """The stored arrays, by name (:data:`ARRAYS`)."""
        return {name: getattr(self, name) for name in ARRAYS}

    def save(self, path: Path, cache_root: Path | None = None) -> Path:
        """Write the model to the directory ``path`` atomically. An existing ``path`` is
        replaced only when it is a BEO model this package wrote (:class:`CheckpointError`
        otherwise, leaving it untouched), and only after the new model is complete."""
        from beo_bench.objects import cache

        path = Path(path)
        modeldir.check_replaceable(path, FILES, ("beo",))  # fail before writing anything
        cache.claim_for(path, cache_root)  # tags the asset cache it lies in (None: the env's)
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_dir(path, lambda tmp, to: modeldir.install(tmp, to, FILES, ("beo",))) as tmp:
            meta = self.stored_meta()
            (tmp / "config.json").write_text(json.dumps(meta, indent=2) + "\n")
            with open(tmp / "arrays.npz", "wb") as f:
                # numpy's stubs read the names as savez's allow_pickle (numpy >= 2.1)
                savez: Any = np.savez
                savez(f, **self.arrays())
        return path

    @classmethod
    def load(cls, path: Path) -> BEOModel:
        """Read a model directory written by :meth:`save`; :class:`CheckpointError` for a
        missing, torn, empty, damaged or foreign one, saying how to get a good one."""
        path = Path(path)
        retrain = (
            f"delete {path} and train it again with `beo-bench train beo --name {path.name}` "
            "(a run retrains a default model by itself)"
        )
        try:
            meta = json.loads((path / "config.json").read_text())
            arrays = read_beo_arrays(path, meta)  # headers checked first
        except FileNotFoundError as e:
            raise CheckpointError(
                f"no BEO model at {path}: train one with `beo-bench train beo` "
                "(or let the backend train the default model on first use)"
            ) from e
        except Exception as e:  # zip, zlib, EOF, JSON and OS errors: a torn or damaged file
            raise CheckpointError(
                f"the BEO model at {path} is unreadable ({type(e).__name__}: {e}); {retrain}"
            ) from e
        return cls.from_stored(meta, arrays, str(path), retrain)

    @classmethod
    def from_stored(
        cls, meta: Any, arrays: dict[str, np.ndarray], where: str, retrain: str
    ) -> BEOModel:
        """The model from its ``config.json`` contents and arrays, checked (kind, format,
        names, shapes, values, digest); :class:`CheckpointError` naming ``where`` and what to
        do (``retrain``) otherwise."""
        if not isinstance(meta, dict) or meta.get("kind") != "beo":
            kind = meta.get("kind") if isinstance(meta, dict) else None
            raise CheckpointError(
                f"{where} holds a {kind!r} model, not a BEO model; retrain with "
                "`beo-bench train beo`"
            )
        if meta.get("format") != FORMAT_VERSION:
            raise CheckpointError(
                f"{where} holds a BEO model of format {meta.get('format')}, not "
                f"{FORMAT_VERSION}; retrain with `beo-bench train beo`"
            )
        problem = _array_problem(arrays, meta)
        if problem is not None:
            raise CheckpointError(f"the BEO model at {where} is damaged ({problem}); {retrain}")
        try:
            c = dict(meta["config"])
            c["categories"] = tuple(c["categories"])
            # __post_init__ factors the covariances: a damaged one fails here
            return cls(config=BEOConfig(**c), info=meta.get("info", {}), **arrays)
        except Exception as e:
            raise CheckpointError(
                f"the BEO model at {where} is damaged ({type(e).__name__}: {e}); {retrain}"
            ) from e

    def stored_meta(self) -> dict[str, Any]:
        """What ``config.json`` holds (:meth:`save`; the published copy's JSON too)."""
        return {
            "kind": "beo",
            "format": FORMAT_VERSION,
            "config": {**asdict(self.config), "categories": list(self.categories)},
            "k": self.k,
            "digest": state_digest(self.arrays()),
            "info": self.info,
        }

    def check_matches(self, categories: tuple[str, ...], resolution: int, where: str) -> None:
        """Raise :class:`CheckpointError` unless the model was trained for exactly these
        categories (in this order) and this resolution."""
        problems = []
        if tuple(categories) != self.categories:
            problems.append(f"categories {list(self.categories)} (asked: {list(categories)})")
        if int(resolution) != self.D:
            problems.append(f"resolution {self.D} (asked: {resolution})")
        if problems:
            raise CheckpointError(
                f"the BEO model {where} was trained for " + " and ".join(problems) + "; train "
                "one for these settings with `beo-bench train beo --name NAME --categories "
                f"{' '.join(categories)} --resolution {resolution}` and pass `--opt model=NAME`"
            )


def _array_problem(arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> str | None:
    """What is wrong with a model's arrays (names, shapes, values, digest), or None."""
    if set(arrays) != set(ARRAYS):
        return f"arrays {sorted(arrays)}, expected {sorted(ARRAYS)}"
    want = beo_array_shapes(meta)
    if want is None:
        return "config.json lacks categories, resolution or k"
    for name, shape in want.items():
        a = arrays[name]
        if a.shape != shape or a.dtype.kind not in "fiu":
            return f"{name} is {a.dtype} {a.shape}, expected numbers of shape {shape}"
        if not np.isfinite(a).all():
            return f"{name} holds NaN or inf"
    # models written before the digest was stored have none: their arrays were checked above
    if "digest" in meta and meta["digest"] != state_digest(arrays):
        return "its arrays do not match the digest in config.json"
    return None


def models_root(cache_root: Path | None = None) -> Path:
    """Where named BEO models live: ``<asset cache>/models/beo``, in the run's asset cache
    (``PrepareContext.cache_root``; None: the environment's)."""
    from beo_bench.objects import cache

    return cache.resolve_root(cache_root) / "models" / "beo"


def model_path(name: str, cache_root: Path | None = None) -> Path:
    """The directory of the BEO model called ``name``: a plain name under
    :func:`models_root` (:class:`~beo_bench.errors.InvalidNameError` for a path, ``..``
    or a leading dot)."""
    return inside(models_root(cache_root), name, "BEO model name")


def model_dir(
    name: str | None,
    categories: tuple[str, ...],
    resolution: int = 32,
    per_category: int | None = None,
    dataset: Dataset | None = None,
    cache_root: Path | None = None,
) -> Path:
    """Where :func:`load_model` looks: the named model's directory, or with ``name=None``
    the default model's for these settings (and ``dataset``), in the asset cache
    ``cache_root`` (None: the environment's)."""
    if name is None:
        name = default_name(categories, resolution, per_category, dataset)
    return model_path(name, cache_root)


def default_name(
    categories: tuple[str, ...],
    resolution: int,
    per_category: int | None = None,
    dataset: Dataset | None = None,
) -> str:
    """The name of the default model for a class list, resolution and training-set size,
    and for a user's ``dataset`` its content and loading options (so a mug of the built-in
    library and a mug of a scan folder never share a model)."""
    key: list[Any] = [list(categories), int(resolution), per_category]
    if dataset is not None:  # appended: the built-in library's names stay as they were
        key.append(dataset.identity())
    h = hashlib.sha256(json.dumps(key).encode()).hexdigest()
    return f"{DEFAULT_NAME}-{resolution}-{h[:8]}"


@threadpool_limits.wrap(limits=1)
def train_beo(
    config: BEOConfig,
    progress: bool = False,
    dataset: Dataset | None = None,
    split: str = "train",
    cache_root: Path | None = None,
) -> BEOModel:
    """Train a BEO model (section 3.2) on the ``train`` split (or ``split``) of the
    procedural library, or of a user's ``dataset`` (``beo-bench train beo --objects``; its
    digest and the split are recorded in ``info``); the instances are kept in the asset
    cache ``cache_root`` (None: the environment's).

    The fit runs on one BLAS thread, so its float reductions happen in the same order on
    every machine and a retrained default model is bitwise the published one. With the
    machine's thread count it differs in the last bits (about 1e-9 in the basis), and so
    does every HBEO model trained against it, whose fingerprint then changes.
    """
    from tqdm import tqdm

    from beo_bench.objects import LIBRARY_VERSION

    t0 = time.perf_counter()
    grids, size_rows = training_voxels(
        config.categories,
        config.resolution,
        config.per_category,
        progress,
        dataset,
        split,
        cache_root,
    )
    sizes = {c: size_rows[c].mean(axis=0) for c in config.categories}
    t_data = time.perf_counter() - t0
    vb = VBPCAConfig(
        max_components=config.max_components,
        variance_fraction=config.variance_fraction,
        max_iter=config.max_iter,
    )
    columns, comps, fits = [], [], {}
    for c in tqdm(config.categories, desc="VBPCA per class", disable=None if progress else True):
        X = grids[c].reshape(len(grids[c]), -1).astype(np.float64)
        fit = fit_vbpca(X, vb)
        fits[c] = fit
        columns.append(fit.W)
        comps.append(fit.W.shape[1])
    means = np.stack([fits[c].mean for c in config.categories], axis=1)  # (d, C)
    # eq. 3.5: the shared subspace spans every class's W_i and mu_i
    A = np.concatenate([*columns, means], axis=1)
    U, s, _ = np.linalg.svd(A, full_matrices=False)
    rank = int(np.sum(s > s[0] * max(A.shape) * np.finfo(np.float64).eps))
    basis = U[:, :rank]
    mu = means.mean(axis=1)
    codes = {c: (grids[c].reshape(len(grids[c]), -1) - mu) @ basis for c in config.categories}
    shrunk = [shrinkage_covariance(codes[c]) for c in config.categories]
    model = BEOModel(
        config=config,
        basis=basis.astype(np.float32),
        mean=mu.astype(np.float32),
        class_mean=np.stack([codes[c].mean(axis=0) for c in config.categories]).astype(np.float32),
        class_cov=np.stack([s.covariance for s in shrunk]),
        class_size=np.stack([sizes[c] for c in config.categories]),
        components=np.asarray(comps, dtype=np.int64),
        shrinkage=np.array([[s.delta, s.lam] for s in shrunk]),
        info={
            "library_version": LIBRARY_VERSION,
            "instances": {c: len(grids[c]) for c in config.categories},
            "explained": {c: round(fits[c].explained, 4) for c in config.categories},
            "vbpca_iterations": {c: len(fits[c].bound) for c in config.categories},
            **({"dataset": dataset.identity(), "split": split} if dataset else {}),
            "data_s": round(t_data, 2),
            "train_s": round(time.perf_counter() - t0, 2),
        },
    )
    return model


def published_model(stem: str = "beo") -> BEOModel | None:
    """The published BEO model ``stem`` (:mod:`.published`: ``beo``, the subspace every
    published 18-class HBEO model regresses, or ``beo-<class>``, a per-category network's),
    read and checked once per version of the published files; None when none is published.
    :class:`CheckpointError` for an altered or unreadable file."""

    files = published.manifest()
    if f"{stem}.npz" not in files:
        return None
    return _read_published(published.PUBLISHED_DIR, tuple(sorted(files.items())), stem)


@functools.cache
def _read_published(root: Path, files: tuple[tuple[str, str], ...], stem: str = "beo") -> BEOModel:
    """The published BEO model ``stem`` under ``root``; ``files`` (the manifest: name,
    SHA-256) is part of the cache key, so publishing anew (:func:`.published.write`) reads
    it again."""

    meta, arrays = published.read(stem, root)
    return BEOModel.from_stored(meta, arrays, f"{root}/{stem}", published._restore(stem))


def published_for(
    categories: tuple[str, ...], resolution: int, per_category: int | None
) -> BEOModel | None:
    """The published BEO model when it is the default model for these settings (the
    default training configuration on these categories, resolution and instances): the
    18-class one, or a per-category network's one-class subspace; else None (the caller
    trains its own)."""
    from beo_bench.objects import LIBRARY_VERSION

    want = BEOConfig(categories=tuple(categories), resolution=resolution, per_category=per_category)
    stems = ["beo"]
    if len(categories) == 1 and categories[0] in published.PER_CATEGORY:
        stems.append(published.per_category_stem("beo", categories[0]))
    for stem in stems:
        model = published_model(stem)
        if model is None or model.config != want:
            continue
        if model.info.get("library_version") != LIBRARY_VERSION:
            return None  # published for another object library: the default is retrained
        return model
    return None


def load_model(
    name: str | None,
    categories: tuple[str, ...],
    resolution: int = 32,
    progress: bool = False,
    train_default: bool = True,
    per_category: int | None = None,
    dataset: Dataset | None = None,
    cache_root: Path | None = None,
) -> BEOModel:
    """The model called ``name`` (a plain name under :func:`models_root`; a path is refused
    with :class:`~beo_bench.errors.InvalidNameError`), or with ``name=None`` the default
    model for ``categories`` and ``resolution``: the published one (:mod:`.published`) where
    it was trained for these settings, otherwise trained and stored on first use (on the
    first ``per_category`` training instances of each class, or all of them). On a user's
    ``dataset`` (None: the procedural library) the default model is the one ``beo-bench
    train beo --objects ROOT`` stored, never trained here (a :class:`CheckpointError` names
    that command). Models, and the instances a default one trains on, are kept in the asset
    cache ``cache_root`` (None: the environment's). Raises :class:`CheckpointError` for a
    missing, damaged or mismatched model."""
    from beo_bench.objects import LIBRARY_VERSION

    if name is None and dataset is None:
        model = published_for(tuple(categories), int(resolution), per_category)
        if model is not None:  # the published default: nothing to train
            return model
    path = model_dir(name, categories, resolution, per_category, dataset, cache_root)
    if name is None and not (path / "config.json").exists():
        if dataset is not None:
            how = train_command(
                "beo",
                categories,
                dataset,
                resolution=resolution if resolution != 32 else None,
                per_category=per_category,
            )
            raise CheckpointError(
                f"no BEO model for the dataset {dataset.root} (digest {dataset.short}, classes "
                f"{', '.join(categories)}) at {path}: train it first with `{how}` "
                "(models for a dataset are never trained implicitly)"
            )
        if not train_default:
            raise CheckpointError(f"no default BEO model at {path}")
        cfg = BEOConfig(
            categories=tuple(categories), resolution=int(resolution), per_category=per_category
        )
        train_beo(cfg, progress=progress, cache_root=cache_root).save(path, cache_root)
    model = BEOModel.load(path)
    model.check_matches(tuple(categories), resolution, f"at {path}")
    if model.info.get("library_version") != LIBRARY_VERSION:
        raise CheckpointError(
            f"the BEO model at {path} was trained on object library version "
            f"{model.info.get('library_version')}, this is version {LIBRARY_VERSION}; "
            "retrain it with `beo-bench train beo`"
        )
    return model


def storable_beo(model: BEOModel) -> BEOModel:
    """The BEO model as it is published: the basis rounded (:data:`BASIS_DROPPED_BITS`), the
    class covariances rounded to float32's precision (kept in float64, so their low 29 bits
    are zeros). What the published HBEO networks are trained against and the backends load;
    ``make bench`` measures what the rounding costs."""

    return replace(
        model,
        basis=published.round_mantissa(model.basis, published.BASIS_DROPPED_BITS),
        class_cov=model.class_cov.astype(np.float32).astype(np.float64),
    )


def publish_beo(model: BEOModel, root: Path | None = None) -> str:
    stored = storable_beo(model)
    return published.write(
        "beo", stored.stored_meta(), stored.arrays(), root or published.PUBLISHED_DIR
    )
