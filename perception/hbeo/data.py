"""HBEO's training set: crops rendered by the scenes API, cached as compressed shards.

Two kinds of shard (docs/design.md "Perception backends"; dissertation section 4.3):

- *isolated*: instances of the split at the origin, cameras from ``OBJECT_RIG`` (azimuth
  over the full circle, elevation 0-60 degrees, roll zero-mean Gaussian with 99% within 25
  degrees) and, for a share ``top_down_share``, from straight above (``TOP_DOWN_RIG``),
  128x128 like the pose suites; ``views_per_instance`` views per instance so a
  compiled model serves several renders;
- *tabletop*: BEOPick-v0 scenes of the split (1-4 objects, clutter, occlusion by each
  other and the table edge; ``beo_bench.scenes.tabletop``, which the env runs too), 640x480;
  every object with at least ``min_pixels`` visible pixels is one crop.

A share ``noise_share`` of the images get the depth-noise augmentation
(``beo_bench.scenes.noise.DepthNoise``: HBEO's training recipe, not a suite's sensor), or,
with ``DatasetConfig.sensor`` set, are captured by that depth sensor instead
(``beo_bench.scenes.sensors``: ``kinect-v1``, ``d435``). Shard ``i`` is
generated from ``SeedSequence([seed, i])`` alone, by whichever worker renders it, so a
dataset is the same however it is split over processes and a killed run resumes at the
first missing shard. Shards are ``np.savez_compressed`` files written through a temporary
file and a rename, with a checksum of their arrays (the asset cache's ``__checksum__``): a
shard that is truncated, altered, lacks rows or has no checksum is re-rendered by
:func:`render_dataset` and refused by :func:`load_split` with :class:`CorruptDataError`.

Each crop is stored with the targets that do not depend on a subspace: class, the
instance's key (the shape coefficients of eq. 4.1 are computed at training time from the
subspace in use), the rotation relative to the crop-centre ray (made canonical over the
object's symmetry group, see :func:`canonical_rotation`), translation offset and log size.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import multiprocessing as mp
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from beo_bench.atomic import atomic_write, atomic_write_bytes
from beo_bench.errors import CorruptDataError
from beo_bench.objects import cache
from beo_bench.perception.hbeo.crop import CROP_SIZE, make_crop
from beo_bench.safe_npz import read_npz
from beo_bench.types import Mat3, Symmetry

if TYPE_CHECKING:
    from beo_bench.objects import ObjectSet
    from beo_bench.objects.datasets import Dataset

DATA_VERSION = 2
"""2: tabletop shards come first in every split, and the validation split is cut into enough
shards to hold its share of them (version 1's validation shards held none)."""
FIELDS = ("depth", "label", "instance", "keys", "rotation", "offset", "log_size", "noisy")
"""The arrays of a shard file (besides its checksum)."""

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class DatasetConfig:
    """What a training set holds. ``images`` counts crops over all training shards;
    ``val_images`` are rendered the same way from the ``val`` split (held-out instances)."""

    categories: tuple[str, ...]
    images: int = 16000
    val_images: int = 1000
    split: str = "train"
    val_split: str = "val"
    per_category: int | None = None
    """Instances per class drawn from (None: the whole split)."""
    crop: int = CROP_SIZE
    shard_size: int = 500
    views_per_instance: int = 10
    tabletop_share: float = 0.2
    noise_share: float = 0.3
    top_down_share: float = 0.15
    """Of the isolated crops, the share seen from straight above (``TOP_DOWN_RIG``: the
    ``modelnet10-known-pose`` and ``-1dof`` suites' view, chapter 3's), the rest from
    ``OBJECT_RIG``: training views cover every isolated suite's viewpoints, as the
    dissertation's networks were trained on each experiment's own renders."""
    min_pixels: int = 50
    seed: int = 0
    objects: Dataset | None = None
    """A user's dataset the crops are rendered from (``--objects``; None: the procedural
    library). Its identity, not its path, names the shards."""
    sensor: str | None = None
    """None: the published recipe, the share ``noise_share`` of the crops with the
    ``DepthNoise`` augmentation (what the published models were trained on, byte for
    byte). A sensor's name (``beo_bench.scenes.sensors.SENSORS``; ``--sensor``): that share
    is captured by the sensor instead (its noise drawn from the shard's generator), the
    rest rendered ideal; ``noise_share=1`` captures every crop by it. Part of the shards'
    digest (and so of the model's default name) only when set."""

    def object_set(self, split: str, cache_root: Path | None = None) -> ObjectSet:
        """The instances of ``split`` the crops of that split are rendered from, kept in the
        asset cache ``cache_root`` (None: the environment's)."""
        from beo_bench.objects.datasets import object_set

        return object_set(self.objects, split, self.categories, self.per_category, cache_root)

    def __post_init__(self) -> None:
        if not self.categories:
            raise ValueError("DatasetConfig.categories is empty")
        if self.images < 1 or self.val_images < 0 or self.shard_size < 1:
            raise ValueError("images >= 1, val_images >= 0 and shard_size >= 1 are required")
        if not all(
            0 <= f <= 1 for f in (self.tabletop_share, self.noise_share, self.top_down_share)
        ):
            raise ValueError(
                "tabletop_share, noise_share and top_down_share are fractions in [0, 1]"
            )
        if self.sensor is not None:
            from beo_bench.scenes.sensors import check_sensor_name

            check_sensor_name(self.sensor)  # a SensorError with the closest names

    def shards(self) -> list[tuple[str, int, str, int]]:
        """(split, shard index, kind, crops) of every shard; the kinds interleave, starting
        with a tabletop shard, so that any prefix of k shards holds ceil(k * tabletop_share)
        tabletop ones. A small split is cut into shards small enough for it to hold its
        share too (version 1 gave the 1,000 validation crops two shards of 500 and no
        tabletop one: validation did not cover the tabletop crops training sees)."""
        out = []
        for split, n in ((self.split, self.images), (self.val_split, self.val_images)):
            size = self._shard_size(n)
            for i in range(-(-n // size)):
                out.append((split, i, self._kind(i), min(size, n - i * size)))
        return out

    def _kind(self, i: int) -> str:
        s = self.tabletop_share
        # rounded: 15 * 0.2 is 3.0000000000000004 in floating point
        first = math.ceil(round((i + 1) * s, 9)) > math.ceil(round(i * s, 9))
        return "tabletop" if first else "isolated"

    def _shard_size(self, n: int) -> int:
        s = self.tabletop_share
        if not 0 < s < 1 or n < 1:
            return self.shard_size
        shards = math.ceil(round(1 / s, 9))  # one tabletop shard in every ceil(1/s)
        return max(1, min(self.shard_size, -(-n // shards)))

    def digest(self) -> str:
        """Names the shard directory. The image counts are left out: shard i's crops do
        not depend on how many shards there are, so a larger set reuses a smaller one's."""
        from beo_bench.objects import LIBRARY_VERSION

        fields = {k: v for k, v in asdict(self).items() if k not in ("images", "val_images")}
        # without a dataset or a sensor the library's shard names stay as they were
        del fields["objects"]
        if fields["sensor"] is None:
            del fields["sensor"]
        if self.objects is not None:
            fields["objects"] = self.objects.identity()
        key = json.dumps([fields, DATA_VERSION, LIBRARY_VERSION], sort_keys=True)
        return hashlib.sha256(key.encode()).hexdigest()[:12]


def datasets_root(cache_root: Path | None = None) -> Path:
    """Where rendered training sets live: ``<asset cache>/datasets/hbeo`` (None: the
    environment's cache)."""
    from beo_bench.objects import cache

    return cache.resolve_root(cache_root) / "datasets" / "hbeo"


def dataset_dir(config: DatasetConfig, cache_root: Path | None = None) -> Path:
    return datasets_root(cache_root) / config.digest()


def canonical_rotation(R_rel: Mat3, symmetry: Symmetry | None) -> Mat3:
    """The member of ``R_rel``'s symmetry class closest to the identity.

    Rotations that differ by a symmetry of the object look the same, so an L2 regression
    target must pick one of them (else it learns their average). For a continuous symmetry
    about the canonical z axis, R Rz(theta) maximises its trace, i.e. is closest to the
    identity, at theta = atan2(R01 - R10, R00 + R11); discrete symmetries are enumerated.
    """
    R = np.asarray(R_rel, dtype=np.float64)
    if not symmetry:
        return R
    cands = [R]
    for t in symmetry.get("discrete", []):
        cands.append(R @ np.asarray(t, dtype=np.float64)[:3, :3])
    if symmetry.get("continuous"):
        axis = np.asarray(symmetry["continuous"][0]["axis"], dtype=np.float64)
        if abs(abs(axis[2]) - 1) < 1e-6:  # the library's continuous symmetries are about z
            out = []
            for C in cands:
                th = np.arctan2(C[0, 1] - C[1, 0], C[0, 0] + C[1, 1])
                c, s = np.cos(th), np.sin(th)
                out.append(C @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]))
            cands = out
    return max(cands, key=lambda C: float(np.trace(C)))


@dataclass
class Shard:
    """Crops and targets of one shard (n items)."""

    depth: np.ndarray
    """(n, S, S) float16 normalised depth, NaN off the mask."""
    label: np.ndarray
    """(n,) int16 class index."""
    instance: np.ndarray
    """(n,) int32 index into ``keys``."""
    keys: list[str]
    rotation: np.ndarray
    """(n, 3, 3) float32 canonical rotation relative to the crop-centre ray."""
    offset: np.ndarray
    """(n, 3) float32 translation target."""
    log_size: np.ndarray
    """(n, 3) float32 size target."""
    noisy: np.ndarray
    """(n,) bool."""

    def __len__(self) -> int:
        return int(self.label.shape[0])

    def arrays(self) -> dict[str, np.ndarray]:
        """The shard as the arrays of its file (:data:`FIELDS`)."""
        return {
            "depth": self.depth,
            "label": self.label,
            "instance": self.instance,
            "keys": np.array(self.keys),
            "rotation": self.rotation,
            "offset": self.offset,
            "log_size": self.log_size,
            "noisy": self.noisy,
        }

    def save(self, path: Path) -> None:
        """Write the shard with its checksum, atomically (temporary file, then rename)."""
        with atomic_write(path) as f:
            # allow_pickle is numpy's default, given by name so that the type checker does not
            # take an array of the ** mapping for it
            np.savez_compressed(f, allow_pickle=True, **cache.with_checksum(self.arrays()))

    @classmethod
    def load(cls, path: Path, n: int | None = None) -> Shard:
        """Read a shard written by :meth:`save` (of ``n`` crops, if given).
        :class:`CorruptDataError` when it is truncated, altered or incomplete."""
        arrays, why = _read_shard(path, n)
        if why is not None:
            raise CorruptDataError(
                f"training shard {path} is {why}; run `beo-bench render-dataset` (or train "
                "again) to render it anew"
            )
        return cls(
            depth=arrays["depth"],
            label=arrays["label"],
            instance=arrays["instance"],
            keys=[str(k) for k in arrays["keys"]],
            rotation=arrays["rotation"],
            offset=arrays["offset"],
            log_size=arrays["log_size"],
            noisy=arrays["noisy"],
        )


SHARD_BUDGET = 1 << 30
"""Most bytes one shard may unpack to (500 crops of a few channels at 64 x 64 take tens of
MB; the largest crops of a dissertation-size network stay well under this)."""


def _read_shard(path: Path, n: int | None) -> tuple[dict[str, np.ndarray], str | None]:
    """A shard file's arrays and None, or ({}, what is wrong with it)."""
    if not path.exists():
        return {}, "missing"
    try:
        # each member's header checked before it is unpacked: no zip bomb is unpacked
        arrays = read_npz(
            path,
            budget=SHARD_BUDGET,
            kinds={"keys": "U", cache.CHECKSUM_KEY: "U"},
            names={*FIELDS, cache.CHECKSUM_KEY},
        )
    except Exception as e:  # zip, zlib, EOF and OS errors: a torn or damaged file
        return {}, f"damaged (unreadable: {type(e).__name__}: {e})"
    why = _shard_problem(arrays, n)
    return (arrays, None) if why is None else ({}, f"damaged ({why})")


def _shard_problem(arrays: dict[str, np.ndarray], n: int | None) -> str | None:
    """Why a shard's arrays cannot be trusted (checksum, fields, row counts), or None."""
    problem = cache.checksum_problem(arrays)
    if problem is not None:
        return problem
    if set(arrays) != {*FIELDS, cache.CHECKSUM_KEY}:
        return f"fields {sorted(arrays)}, expected {sorted(FIELDS)}"
    rows = {k: len(arrays[k]) for k in FIELDS if k != "keys"}
    if len(set(rows.values())) != 1 or (n is not None and rows["label"] != n):
        return f"row counts {rows}, expected {n if n is not None else 'equal ones'}"
    if len(arrays["instance"]) and int(arrays["instance"].max()) >= len(arrays["keys"]):
        return "an instance index beyond its keys"
    return None


def shard_problem(path: Path, n: int) -> str | None:
    """Why the shard file ``path`` of ``n`` crops must be (re-)rendered (``"missing"`` or
    ``"damaged (...)"``), or None when it is complete and matches its checksum."""
    return _read_shard(path, n)[1]


class _Collector:
    def __init__(self, categories: tuple[str, ...], crop: int) -> None:
        self.categories = categories
        self.crop = crop
        self.rows: list[tuple[Any, ...]] = []
        self.keys: dict[str, int] = {}

    def add(
        self, depth: np.ndarray, mask: np.ndarray, K: Mat3, truth: Any, R_cam: Mat3, t_cam: Any
    ) -> None:
        c = make_crop(depth, mask, K, self.crop)
        R_rel = canonical_rotation(c.rotation_target(R_cam), truth.symmetry)
        img = np.where(c.image[1] > 0.5, c.image[0], np.nan).astype(np.float16)
        idx = self.keys.setdefault(truth.key, len(self.keys))
        self.rows.append(
            (
                img,
                self.categories.index(truth.category),
                idx,
                R_rel,
                c.translation_target(t_cam),
                c.size_target(truth.size),
            )
        )

    def shard(self, noisy: list[bool]) -> Shard:
        cols = list(zip(*self.rows, strict=True))
        return Shard(
            depth=np.stack(cols[0]),
            label=np.asarray(cols[1], dtype=np.int16),
            instance=np.asarray(cols[2], dtype=np.int32),
            keys=list(self.keys),
            rotation=np.stack(cols[3]).astype(np.float32),
            offset=np.stack(cols[4]).astype(np.float32),
            log_size=np.stack(cols[5]).astype(np.float32),
            noisy=np.asarray(noisy, dtype=bool),
        )


_WORKER: dict[str, Any] = {}


def _isolated_shard(
    config: DatasetConfig, split: str, rng: np.random.Generator, n: int, cache_root: Path | None
) -> Shard:
    from beo_bench.scenes.camera import TOP_DOWN_RIG
    from beo_bench.scenes.isolated import IsolatedRenderer
    from beo_bench.scenes.noise import DepthNoise, apply_noise

    if "isolated" not in _WORKER:
        _WORKER["isolated"] = IsolatedRenderer(cache_models=2)
    r = _WORKER["isolated"]
    objects = config.object_set(split, cache_root)
    col = _Collector(config.categories, config.crop)
    noisy: list[bool] = []
    if config.sensor is not None:
        return _isolated_sensor_shard(config, r, objects, col, rng, n)
    noise = DepthNoise()
    while len(col.rows) < n:
        cat = config.categories[int(rng.integers(len(config.categories)))]
        inst = objects.get(cat, int(rng.integers(objects.count(cat))))
        for _ in range(min(config.views_per_instance, n - len(col.rows))):
            rig = TOP_DOWN_RIG if rng.random() < config.top_down_share else r.rig
            v = r.render(inst, rig.sample(rng, np.zeros(3)))
            depth = v.depth
            is_noisy = bool(rng.random() < config.noise_share)
            if is_noisy:
                depth = apply_noise(depth, rng, noise)
            mask = v.mask & (depth > 0)
            if mask.sum() < 8:  # noise can drop a tiny far object entirely
                continue
            col.add(depth, mask, v.K, inst, v.R_cam, v.t_cam)
            noisy.append(is_noisy)
    return col.shard(noisy)


def _isolated_sensor_shard(
    config: DatasetConfig,
    r: Any,
    objects: ObjectSet,
    col: _Collector,
    rng: np.random.Generator,
    n: int,
) -> Shard:
    """An isolated shard whose ``noise_share`` is captured by ``config.sensor``: the draws
    of the published recipe (class, instance, rig), then whether the crop is the sensor's,
    then the render (the sensor's noise drawn from ``rng`` after it)."""
    from beo_bench.scenes.camera import TOP_DOWN_RIG

    noisy: list[bool] = []
    assert config.sensor is not None
    while len(col.rows) < n:
        cat = config.categories[int(rng.integers(len(config.categories)))]
        inst = objects.get(cat, int(rng.integers(objects.count(cat))))
        for _ in range(min(config.views_per_instance, n - len(col.rows))):
            rig = TOP_DOWN_RIG if rng.random() < config.top_down_share else r.rig
            T = rig.sample(rng, np.zeros(3))
            is_noisy = bool(rng.random() < config.noise_share)
            v = r.render(inst, T, rng=rng, sensor=config.sensor if is_noisy else "ideal")
            if v.mask.sum() < 8:  # a sensor can drop a tiny far object entirely
                continue
            col.add(v.depth, v.mask, v.K, inst, v.R_cam, v.t_cam)
            noisy.append(is_noisy)
    return col.shard(noisy)


def _tabletop_shard(
    config: DatasetConfig, split: str, rng: np.random.Generator, n: int, cache_root: Path | None
) -> Shard:
    from beo_bench.scenes.noise import DepthNoise, apply_noise
    from beo_bench.scenes.pickconfig import PickConfig
    from beo_bench.scenes.renderer import Frame
    from beo_bench.scenes.tabletop import TabletopScenes

    # the dataset's content and loading options (the same files loaded another way are
    # other objects)
    digest = config.objects.short if config.objects is not None else ""
    key = f"tabletop-{split}-{config.categories}-{config.per_category}-{digest}-{cache_root}"
    if key not in _WORKER:
        # BEOPick-v0's scenes (640x480, its camera rig and table), without sensor noise
        _WORKER[key] = TabletopScenes(
            PickConfig(
                objects=config.object_set(split, cache_root),
                categories=tuple(config.categories),
                num_objects=(1, min(4, len(config.categories))),
            )
        )
    scenes: TabletopScenes = _WORKER[key]
    col = _Collector(config.categories, config.crop)
    noisy: list[bool] = []
    noise = DepthNoise()
    sensor = None
    if config.sensor is not None:
        from beo_bench.scenes.sensors import make_sensor

        sensor = make_sensor(config.sensor, scenes.config.intrinsics)
    while len(col.rows) < n:
        obs, truths = scenes.reset(seed=int(rng.integers(2**31)))
        depth = obs["depth"]
        is_noisy = bool(rng.random() < config.noise_share)
        if is_noisy and sensor is not None:
            # the scene as the sensor captures it (the ideal frame reused, not rendered again)
            ideal = Frame(depth=depth, segmentation=obs["segmentation"])
            depth = scenes.capture(sensor, rng, ideal).depth
        elif is_noisy:
            depth = apply_noise(depth, rng, noise)
        for g in truths:
            mask = (obs["segmentation"] == g.label) & (depth > 0)
            if g.pixels < config.min_pixels or mask.sum() < config.min_pixels // 2:
                continue
            if len(col.rows) < n:
                col.add(depth, mask, obs["intrinsics"], g, g.R_cam, g.t_cam)
                noisy.append(is_noisy)
    return col.shard(noisy)


def render_shard(
    config: DatasetConfig,
    split: str,
    index: int,
    kind: str,
    n: int,
    path: Path,
    cache_root: Path | None = None,
) -> int:
    """Render the ``n`` crops of shard ``index`` of ``split`` to ``path``; returns ``n``.
    The first m crops of a shard are the same for any n >= m. ``cache_root``: the asset
    cache the objects are kept in (None: the environment's)."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    tag = 0 if split == config.split else 1
    rng = np.random.default_rng(np.random.SeedSequence([config.seed, tag, index]))
    make = _tabletop_shard if kind == "tabletop" else _isolated_shard
    shard = make(config, split, rng, n, cache_root)
    shard.save(path)
    return len(shard)


def shard_path(root: Path, split: str, index: int, n: int) -> Path:
    return root / f"{split}-{index:05d}-{n}.npz"


def render_dataset(
    config: DatasetConfig,
    workers: int | None = None,
    progress: bool = True,
    cache_root: Path | None = None,
) -> tuple[Path, dict[str, float]]:
    """Render the shards of ``config`` that are not on disk yet or are damaged (in
    ``workers`` processes, default one per core) and return the dataset's directory and
    figures: ``images``, ``seconds``, ``images_per_s`` over the shards rendered now, and
    ``repaired``, how many of them were on disk but damaged (or from an older version).
    The shards and their objects are kept in the asset cache ``cache_root`` (None: the
    environment's)."""
    from tqdm import tqdm

    from beo_bench.objects.prepare import prepare

    root = dataset_dir(config, cache_root)
    cache.claim_for(root, cache_root)
    root.mkdir(parents=True, exist_ok=True)
    meta = root / "config.json"
    if not meta.exists():
        described = asdict(config)
        if config.sensor is None:  # the published recipe's description, as it always was
            del described["sensor"]
        atomic_write_bytes(meta, json.dumps(described, indent=2) + "\n")
    todo, repaired = [], 0
    for s in config.shards():
        path = shard_path(root, *_where(s))
        why = shard_problem(path, s[3])
        if why is not None:
            todo.append(s)
        if why is not None and why != "missing":
            repaired += 1
            _log.warning("training shard %s is %s; re-rendering it", path, why)
    stats = {"images": 0.0, "seconds": 0.0, "images_per_s": 0.0, "repaired": float(repaired)}
    if not todo:
        return root, stats
    # the objects' meshes and collision parts first, in parallel (cached on disk)
    for split in {config.split, config.val_split}:
        prepare(config.object_set(split, cache_root), workers=workers, progress=progress)
    workers = (os.cpu_count() or 1) if workers is None else max(1, workers)
    if mp.current_process().daemon:
        workers = 1
    t0 = time.perf_counter()
    images = 0
    bar = tqdm(
        total=len(todo),
        desc="rendering training shards",
        unit="shard",
        disable=None if progress else True,
    )
    if workers == 1:
        for split, i, kind, n in todo:
            path = shard_path(root, split, i, n)
            images += render_shard(config, split, i, kind, n, path, cache_root)
            bar.update()
            bar.set_postfix(img_s=f"{images / (time.perf_counter() - t0):.0f}")
    else:
        ctx = mp.get_context("forkserver")
        with ProcessPoolExecutor(workers, mp_context=ctx, initializer=_worker_init) as ex:
            futs = [
                ex.submit(render_shard, config, s, i, k, n, shard_path(root, s, i, n), cache_root)
                for s, i, k, n in todo
            ]
            for f in as_completed(futs):
                images += f.result()
                bar.update()
                bar.set_postfix(img_s=f"{images / (time.perf_counter() - t0):.0f}")
    bar.close()
    dt = time.perf_counter() - t0
    stats = {
        "images": float(images),
        "seconds": dt,
        "images_per_s": images / max(dt, 1e-9),
        "repaired": float(repaired),
    }
    return root, stats


def _where(shard: tuple[str, int, str, int]) -> tuple[str, int, int]:
    return shard[0], shard[1], shard[3]


def _worker_init() -> None:
    # one renderer process per core: keep torch and BLAS from oversubscribing the cores
    os.environ.setdefault("MUJOCO_GL", "egl")
    os.environ["OMP_NUM_THREADS"] = "1"


def load_split(config: DatasetConfig, split: str, cache_root: Path | None = None) -> Shard:
    """Every shard of ``split`` concatenated into one (call :func:`render_dataset` first);
    the float16 crops stay compact in memory. :class:`CorruptDataError` for a damaged shard.
    ``cache_root``: the asset cache the shards are in (None: the environment's)."""
    root = dataset_dir(config, cache_root)
    shards = [
        Shard.load(shard_path(root, s, i, n), n) for s, i, _, n in config.shards() if s == split
    ]
    if not shards:  # e.g. val_images=0: an empty split, not a crash in np.concatenate
        S = config.crop
        return Shard(
            depth=np.zeros((0, S, S), np.float16),
            label=np.zeros(0, np.int64),
            instance=np.zeros(0, np.int32),
            keys=[],
            rotation=np.zeros((0, 3, 3), np.float32),
            offset=np.zeros((0, 3), np.float32),
            log_size=np.zeros((0, 3), np.float32),
            noisy=np.zeros(0, bool),
        )
    keys: dict[str, int] = {}
    inst = []
    for sh in shards:
        remap = np.array([keys.setdefault(k, len(keys)) for k in sh.keys], dtype=np.int32)
        inst.append(remap[sh.instance])

    def cat(name: str) -> np.ndarray:
        return np.concatenate([getattr(s, name) for s in shards])

    return Shard(
        depth=cat("depth"),
        label=cat("label").astype(np.int64),
        keys=list(keys),
        instance=np.concatenate(inst),
        rotation=cat("rotation"),
        offset=cat("offset"),
        log_size=cat("log_size"),
        noisy=cat("noisy"),
    )
