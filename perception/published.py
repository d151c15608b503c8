"""The published reference models: checked-in weights the backends load by default.

``perception/published/`` holds, for each published model, ``<stem>.npz`` (its arrays,
read with ``allow_pickle=False``) and ``<stem>.json`` (its ``config.json``: config,
subspace fingerprint, training history, digest), plus ``MANIFEST.json`` with the SHA-256 of
every file. The stems:

- ``beo``: the default BEO model (18 classes, 32^3, every training instance), arrays as
  trained (float32, losslessly; the basis in ``beo-basis.npz``): the subspace (W, mu) every
  published HBEO model regresses, so
  those do not depend on retraining BEO, whose float reductions differ in the last bits
  from one CPU to another;
- ``rest-prior``: how objects rest on a table, learned from the training split's tabletop
  scenes (:func:`~beo_bench.perception.means.fit_rest_prior`): ``beo``'s pose prior and
  ``icp``'s starts on the ``tabletop`` and ``pick`` views;
- ``class-means``: the ``random`` and ``icp`` baselines' class means (every library class's
  mean occupancy and size over all its ``train`` instances,
  :func:`~beo_bench.perception.means.published_class_means`), stored losslessly as uint8
  counts, so that no run builds the 3,600 training instances for them;
- ``hbeo`` and ``hbeo-mdn``: the small networks of the ``reference`` recipe
  (:data:`~beo_bench.perception.hbeo.model.RECIPES`), weights stored in float16 (they are
  used in float32; ``make bench`` measures what the rounding costs: nothing measurable);
- ``hbeo-mdn-car``, ``hbeo-mdn-airplane``, ``hbeo-mdn-sofa``: chapter 5's per-category
  networks (the ``per-category`` recipe, Tables 5.1/5.2), weights stored in int8 with a
  float32 scale per output channel (:func:`quantise`), half float16's bytes, so that the
  set stays under :data:`TOTAL_LIMIT`; ``make bench`` measures what that costs.

A file whose SHA-256 does not match the manifest is refused with :class:`CheckpointError`
(never used silently), saying how to restore or retrain it. ``beo-bench publish`` writes
these files from trained models (``beo-bench train hbeo --recipe reference --name N``
reproduces the networks; see docs/reference-models.md). Larger networks (``--size
dissertation``, trained on a GPU) are not published: they stay in the asset cache, where
``beo-bench train ... --recipe reference --size dissertation --device cuda`` puts them.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from beo_bench.atomic import atomic_write_bytes
from beo_bench.errors import CheckpointError, UsageError

PUBLISHED_DIR = Path(__file__).resolve().parent / "published"
MANIFEST = "MANIFEST.json"
STEMS: tuple[str, ...] = ("beo", "hbeo", "hbeo-mdn", "rest-prior", "class-means")
PER_CATEGORY: tuple[str, ...] = ("car", "airplane", "sofa")
"""The classes whose one-class networks (``<kind>-<class>``) may be published: chapter 5's
Tables 5.1/5.2 (car, plane, couch)."""
NET_PREFIX = "net."
SPLIT: dict[str, tuple[str, ...]] = {"beo": ("basis",)}
"""Arrays stored in files of their own (``beo-basis.npz``, or ``beo-basis-0.npz``,
``beo-basis-1.npz``... when one would pass :data:`FILE_LIMIT`): no published file passes
10 MB."""
FILE_LIMIT = 10_000_000
"""Most bytes of one published file (the repository's cap: 10 MB a file, 20 MB in all)."""
TOTAL_LIMIT = 20_000_000
"""Most bytes of all published files together: :func:`write` refuses a set that passes it."""
SCALE = "__scale"
"""Suffix of an int8 weight's scale array (``net.<tensor>__scale``, :func:`quantise`)."""
STORAGE = ("float16", "int8", "float32")
INT8_MIN_SIZE = 100_000
"""``int8`` storage quantises the weight tensors of at least this many elements (the small
network's first fully connected layer, 524,288 of its 768,000 weights), the rest in float16:
0.9 MB a per-category MDN, whose rotation error this changes by 0.04 deg a view on average
(``make bench``; it allows 0.1). Quantising every matrix and kernel saves another 0.2 MB a
network and changes it by 0.19 deg."""
CHUNK = "@"
"""Joins a split array's name and its chunk's index inside a chunk file (``basis@0``)."""
PLANES, SHAPE, DTYPE = "__planes", "__shape", "__dtype"


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def manifest(root: Path | None = None) -> dict[str, str]:
    """File name -> SHA-256 of every published file under ``root`` (default
    :data:`PUBLISHED_DIR`; {} when nothing is published)."""
    root = PUBLISHED_DIR if root is None else root
    try:
        return dict(json.loads((root / MANIFEST).read_text())["files"])
    except FileNotFoundError:
        return {}
    except Exception as e:  # a damaged manifest
        raise CheckpointError(
            f"{root / MANIFEST} is unreadable ({type(e).__name__}: {e}); restore it with "
            "`git checkout -- perception/published`"
        ) from e


def read(stem: str, root: Path | None = None) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The (meta, arrays) of the published model ``stem``, each file checked against the
    manifest: :class:`CheckpointError` for a missing, altered or unreadable one."""
    root = PUBLISHED_DIR if root is None else root
    files = manifest(root)
    out: dict[str, bytes] = {}
    parts = [f"{stem}.npz", *(n for a in SPLIT.get(stem, ()) for n in _split_files(stem, a, files))]
    for name in (f"{stem}.json", *parts):
        want = files.get(name)
        if want is None:
            raise CheckpointError(f"{root} publishes no {name} (the manifest does not list it)")
        try:
            data = (root / name).read_bytes()
        except OSError as e:
            raise CheckpointError(
                f"the published {name} is missing ({e}); restore it with "
                "`git checkout -- perception/published`"
            ) from e
        got = _sha256(data)
        if got != want:
            raise CheckpointError(
                f"the published {root / name} has SHA-256 {got[:16]}..., the manifest says "
                f"{want[:16]}...: it was altered or is a Git LFS pointer. Restore it with "
                "`git checkout -- perception/published`, or train your own with `beo-bench "
                f"train {stem} --recipe reference --name NAME` and pass `--opt model=NAME`"
            )
        out[name] = data
    try:
        meta = json.loads(out[f"{stem}.json"])
        arrays: dict[str, np.ndarray] = {}
        for name in parts:
            arrays.update(_unpack(out[name]))
        for a in SPLIT.get(stem, ()):
            chunks = sorted((k for k in arrays if k.startswith(a + CHUNK)), key=_chunk_index)
            if chunks:
                arrays[a] = np.concatenate([arrays.pop(k) for k in chunks], axis=0)
    except Exception as e:
        raise CheckpointError(f"the published {stem} model is unreadable ({e})") from e
    return meta, arrays


def _split_files(stem: str, array: str, files: dict[str, str]) -> list[str]:
    """The files of a split array: ``<stem>-<array>.npz``, or its chunks
    ``<stem>-<array>-0.npz``, ``-1``... as the manifest lists them (the unsplit name when it
    lists neither, so that the error names the file)."""
    whole = f"{stem}-{array}.npz"
    chunks: list[str] = []
    while f"{stem}-{array}-{len(chunks)}.npz" in files:
        chunks.append(f"{stem}-{array}-{len(chunks)}.npz")
    return chunks if chunks and whole not in files else [whole]


def _chunk_index(key: str) -> int:
    return int(key.rsplit(CHUNK, 1)[1])


def _split_blobs(stem: str, name: str, a: np.ndarray) -> dict[str, bytes]:
    """``name``'s file, or, when it would pass :data:`FILE_LIMIT`, as few chunk files
    (row blocks of the array, concatenated again by :func:`read`) as keep each under it."""
    whole = _pack({name: a})
    if len(whole) <= FILE_LIMIT:
        return {f"{stem}-{name}.npz": whole}
    n = -(-len(whole) // int(0.9 * FILE_LIMIT))  # rows compress alike: a margin of 10%
    return {
        f"{stem}-{name}-{i}.npz": _pack({f"{name}{CHUNK}{i}": c})
        for i, c in enumerate(np.array_split(a, n, axis=0))
    }


def _pack(arrays: dict[str, np.ndarray]) -> bytes:
    """A zip of ``.npy`` members, LZMA-compressed, each float array stored as its byte planes
    (all first bytes, then all second bytes...): float bytes of one significance compress
    together. Lossless: the default BEO basis takes 9.3 MB this way, 13.4 MB as a plain
    compressed npz."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_LZMA) as zf:
        for name, a in sorted(arrays.items()):
            a = np.asarray(a, order="C")  # ascontiguousarray would make a 0-d array 1-d
            members: dict[str, np.ndarray]
            if a.dtype.kind == "f":
                planes = a.reshape(-1).view(np.uint8).reshape(-1, a.itemsize).T.copy()
                members = {
                    f"{name}{PLANES}": planes,
                    f"{name}{SHAPE}": np.asarray(a.shape, np.int64),
                    f"{name}{DTYPE}": np.frombuffer(a.dtype.str.encode(), np.uint8),
                }
            else:
                members = {name: a}
            for key, m in members.items():
                npy = io.BytesIO()
                np.lib.format.write_array(npy, m, allow_pickle=False)
                # a fixed timestamp: the same arrays give the same bytes (and SHA-256)
                info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                zf.writestr(info, npy.getvalue(), compress_type=zipfile.ZIP_LZMA)
    return buf.getvalue()


BUDGET = 256 << 20
"""Most bytes one published file may unpack to (the largest, the BEO basis, is 15 MB): the
manifest vouches for a file only as long as nobody edits it too, so the headers are
checked before anything is unpacked (:func:`beo_bench.safe_npz.read_npz`)."""


def _unpack(data: bytes) -> dict[str, np.ndarray]:
    """The arrays of :func:`_pack`'s bytes (read with ``allow_pickle=False``): real numbers
    only (a complex array would be cast to real by torch with a mere warning), each float
    array's planes, shape and dtype consistent; :class:`UnsafeArrayError` otherwise."""
    from beo_bench.safe_npz import UnsafeArrayError, read_npz

    def kind(key: str) -> str:
        # planes and dtype names are bytes, shapes integers; a float is always split into
        # planes by _pack, so a plain member is an integer or boolean array
        return "u" if key.endswith((PLANES, DTYPE)) else "i" if key.endswith(SHAPE) else "biu"

    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        keys = [i.filename.removesuffix(".npy") for i in zf.infolist()]
    raw = read_npz(data, budget=BUDGET, kinds={k: kind(k) for k in keys})
    out: dict[str, np.ndarray] = {}
    for key, a in raw.items():
        if key.endswith(PLANES):
            name = key[: -len(PLANES)]
            try:
                dtype = np.dtype(raw[name + DTYPE].tobytes().decode())
                shape = tuple(int(n) for n in raw[name + SHAPE])
            except (KeyError, TypeError, ValueError, UnicodeDecodeError) as e:
                raise UnsafeArrayError(f"{name}: no readable dtype or shape ({e})") from e
            if dtype.kind != "f" or dtype.itemsize not in (2, 4, 8) or min(shape, default=0) < 0:
                raise UnsafeArrayError(f"{name} is {dtype} {shape}, expected a real float array")
            if a.shape != (dtype.itemsize, int(np.prod(shape))):
                raise UnsafeArrayError(f"{name}'s planes {a.shape} do not fit {dtype} {shape}")
            out[name] = a.T.copy().view(dtype).reshape(shape)
        elif not key.endswith((SHAPE, DTYPE)):
            out[key] = a
    return out


def _restore(stem: str) -> str:
    how = stem + (" --recipe reference" if stem != "beo" else "")
    for c in PER_CATEGORY:
        if stem.endswith(f"-{c}"):  # a per-category network or its subspace
            kind = stem.removesuffix(f"-{c}")
            how = f"{'hbeo-mdn' if kind == 'beo' else kind} --categories {c} --recipe per-category"
    return (
        f"restore it with `git checkout -- perception/published` (or retrain: `beo-bench train "
        f"{how}`)"
    )


def _state(arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    """A published file's arrays as the tensor state ``weights.pt`` would hold (float32)."""
    import torch

    state: dict[str, Any] = {
        "net": {
            k[len(NET_PREFIX) :]: torch.from_numpy(_widen(v))
            for k, v in arrays.items()
            if k.startswith(NET_PREFIX) and not k.endswith(SCALE)
        }
    }
    for k in list(state["net"]):
        scale = arrays.get(NET_PREFIX + k + SCALE)
        if scale is not None:  # int8 storage: q * the row's scale (quantise's inverse)
            q = arrays[NET_PREFIX + k]
            if q.dtype != np.int8 or scale.shape != q.shape[:1]:
                raise ValueError(f"{k}: int8 weights {q.dtype} {q.shape}, scales {scale.shape}")
            w = q.astype(np.float32) * scale.astype(np.float32).reshape(-1, *[1] * (q.ndim - 1))
            state["net"][k] = torch.from_numpy(w)
    for k in ("coef_mean", "coef_std"):
        if k in arrays:
            state[k] = torch.from_numpy(_widen(arrays[k]))
    return state


def _widen(a: np.ndarray) -> np.ndarray:
    """float16 storage back to the float32 the network computes in."""
    return a.astype(np.float32) if a.dtype == np.float16 else a


# -- writing (beo-bench publish) ----------------------------------------------------------------
def quantise(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """float32 weights (output channels first) as int8 and a float32 scale per output
    channel: symmetric, round to nearest, ``w ~ q * scale`` with ``scale = max|w_row| /
    127`` (per-channel weight quantisation, Krishnamoorthi 2018, sec. 2.3)."""
    rows = w.reshape(w.shape[0], -1).astype(np.float32)
    scale = (np.abs(rows).max(axis=1) / 127).astype(np.float32)
    scale[scale == 0] = 1.0  # an all-zero row: any scale gives zeros
    q = np.clip(np.rint(rows / scale[:, None]), -127, 127).astype(np.int8)
    return q.reshape(w.shape), scale


def write(stem: str, meta: dict[str, Any], arrays: dict[str, np.ndarray], root: Path) -> str:
    """Write ``<stem>.json``, ``<stem>.npz`` and, for each array of :data:`SPLIT`,
    ``<stem>-<array>.npz`` under ``root`` (:func:`_pack`; atomically, each through a
    temporary file) and record their SHA-256 in the manifest; returns the npz's SHA-256.
    Only the stems of :data:`STEMS` (and :func:`per_category_stem`'s) are written: nothing
    else in ``root`` is touched. :class:`UsageError` when a file would pass
    :data:`FILE_LIMIT` or the set :data:`TOTAL_LIMIT`."""
    per_cat = {per_category_stem(k, c) for k in ("beo", "hbeo", "hbeo-mdn") for c in PER_CATEGORY}
    if stem not in STEMS and stem not in per_cat:
        raise ValueError(f"stem {stem!r}: one of {STEMS + tuple(sorted(per_cat))}")
    root.mkdir(parents=True, exist_ok=True)
    split = SPLIT.get(stem, ())
    blobs = {f"{stem}.npz": _pack({k: v for k, v in arrays.items() if k not in split})}
    for k in split:
        blobs.update(_split_blobs(stem, k, arrays[k]))
    blobs[f"{stem}.json"] = (json.dumps(meta, indent=1, sort_keys=True) + "\n").encode()
    for name, data in blobs.items():
        if len(data) > FILE_LIMIT:
            raise UsageError(
                f"{name} would take {len(data) / 1e6:.1f} MB, over the {FILE_LIMIT / 1e6:.0f} MB "
                "a published file may take: publish a smaller model"
            )
    files = manifest(root)
    # this stem's split files of an earlier publication that this one does not write (a
    # basis that was one file and is now chunks): listed in the manifest, so written here
    old = {n for k in split for n in _split_files(stem, k, files) if n in files} - set(blobs)
    others = sum(
        os.path.getsize(root / n)
        for n in files
        if n not in blobs and n not in old and (root / n).is_file()
    )
    total = others + sum(len(d) for d in blobs.values())
    if total > TOTAL_LIMIT:
        raise UsageError(
            f"publishing {stem} would make the published set {total / 1e6:.1f} MB, over its "
            f"{TOTAL_LIMIT / 1e6:.0f} MB: store it smaller (`beo-bench publish ... --storage "
            "int8`) or keep it in the cache and load it with --opt model=NAME"
        )
    for name, data in blobs.items():
        atomic_write_bytes(root / name, data)
        files[name] = _sha256(data)
    for name in sorted(old):
        del files[name]
    atomic_write_bytes(
        root / MANIFEST,
        (json.dumps({"files": dict(sorted(files.items()))}, indent=1) + "\n").encode(),
    )
    for name in sorted(old):  # after the manifest stops listing them
        (root / name).unlink(missing_ok=True)
    # the models read from these files (beo_model.published_model, hbeo.model.published_hbeo)
    # are cached by the manifest's digests: they are read again
    return files[f"{stem}.npz"]


BASIS_DROPPED_BITS = 8
"""Low mantissa bits of the BEO basis that publishing rounds away (of float32's 23): the
basis then keeps a relative precision of 2^-16 (1.5e-5; BEO's own training differs from one
CPU to another by about 1e-9 of it, the float16 networks that regress on it by 5e-4), and
its lowest byte plane, all zeros, costs nothing packed. Without the rounding the 18-class
basis (32^3 x 168) takes 16.9 MB and the published set passes its 20 MB."""


def round_mantissa(a: np.ndarray, bits: int) -> np.ndarray:
    """float32 ``a`` rounded to nearest with its ``bits`` lowest mantissa bits zero (a carry
    into the exponent is the correctly rounded value)."""
    u = np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)
    half = np.uint32(1 << (bits - 1))
    mask = np.uint32((0xFFFFFFFF << bits) & 0xFFFFFFFF)
    return ((u + half) & mask).view(np.float32)


def per_category_stem(kind: str, category: str) -> str:
    """The published name of ``kind``'s one-class network for ``category``."""
    return f"{kind}-{category}"


def files_table(root: Path | None = None) -> list[tuple[str, int, str]]:
    """(file, bytes, SHA-256) of every published file (docs/reference-models.md lists them)."""
    root = PUBLISHED_DIR if root is None else root
    return [(n, os.path.getsize(root / n), h) for n, h in sorted(manifest(root).items())]
