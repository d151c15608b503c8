"""Reading ``.npz`` files without trusting them beyond their declared shape.

``np.load`` decompresses a member before anything can look at it, so a small file whose
member unpacks to gigabytes (a zip bomb, or just a tampered model) takes that much memory
before any check runs. :func:`read_npz` reads each member's ``.npy`` header first (a few
hundred bytes of the stream), and refuses, before a single array byte is unpacked:

- a member that is not an ``.npy`` array, or a name seen twice, or one not expected;
- an object dtype (pickled code, never data) or a dtype kind the reader does not expect
  (complex where real numbers are meant, strings where numbers are);
- a shape other than the expected one;
- a declared size (shape x itemsize) over the caller's byte budget, counted over all
  members together, or one that disagrees with the zip's own record of the member's
  unpacked size (``ZipInfo.file_size``), which a hand-made header could otherwise dodge.

Every refusal is an :class:`UnsafeArrayError` (a :class:`~beo_bench.errors.CorruptDataError`);
each reader turns it into its own answer (a cache entry is recomputed, a model refused).
"""

from __future__ import annotations

import io
import math
import zipfile
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import IO

import numpy as np

from beo_bench.errors import CorruptDataError

__all__ = ["REAL", "TEXT", "UnsafeArrayError", "read_npz"]

REAL = "biuf"
"""dtype kinds of real numbers (and booleans): what a model or a grid is made of."""
TEXT = "US"
"""dtype kinds of fixed-width strings (numpy's ``U`` and ``S``): never objects."""

MAX_MEMBERS = 10_000
"""More members than any file of this package has: a central directory of millions of
entries is itself a way to spend memory."""

Shape = tuple[int | None, ...]


class UnsafeArrayError(CorruptDataError):
    """An ``.npz`` member whose header declares something the reader does not expect."""


def _header(f: IO[bytes]) -> tuple[tuple[int, ...], bool, np.dtype]:
    version = np.lib.format.read_magic(f)
    if version == (1, 0):
        return np.lib.format.read_array_header_1_0(f)
    if version == (2, 0):
        return np.lib.format.read_array_header_2_0(f)
    # 3.0 exists only for structured dtypes with non-ASCII field names: none of ours
    raise UnsafeArrayError(f"npy format version {version} is not one this package writes")


def read_npz(
    source: Path | str | bytes,
    *,
    budget: int,
    kinds: str | Mapping[str, str] = REAL,
    shapes: Mapping[str, Shape] | None = None,
    names: Collection[str] | None = None,
) -> dict[str, np.ndarray]:
    """The arrays of the ``.npz`` ``source`` (a path or the file's bytes), each member's
    header checked before it is read: ``budget``: most bytes all arrays may unpack to;
    ``kinds``: the dtype kinds allowed (one string for every member, or one per name, a
    name missing there allowing :data:`REAL`); ``shapes``: per name, the expected shape
    (``None`` for any length on that axis); ``names``: the only member names allowed.
    :class:`UnsafeArrayError` for the first member that breaks one of these."""
    src: IO[bytes] | Path = io.BytesIO(source) if isinstance(source, bytes) else Path(source)
    with zipfile.ZipFile(src) as zf:
        infos = zf.infolist()
        if len(infos) > MAX_MEMBERS:
            raise UnsafeArrayError(f"{len(infos)} members, more than {MAX_MEMBERS}")
        seen: set[str] = set()
        total = 0
        for info in infos:  # every header first: nothing is unpacked from a refused file
            key = _key(info, seen, names)
            with zf.open(info) as f:
                shape, _, dtype = _header(f)
                offset = f.tell()
            _check_dtype(key, dtype, kinds if isinstance(kinds, str) else kinds.get(key, REAL))
            want = None if shapes is None else shapes.get(key)
            if want is not None and not _fits(shape, want):
                raise UnsafeArrayError(f"member {key!r} has shape {shape}, expected {want}")
            size = math.prod(shape) * dtype.itemsize
            total += size
            if total > budget:
                raise UnsafeArrayError(
                    f"member {key!r} declares {shape} {dtype} ({size} bytes): over the "
                    f"{budget}-byte budget of this file"
                )
            if info.file_size != offset + size:  # the zip's record and the header disagree
                raise UnsafeArrayError(
                    f"member {key!r} unpacks to {info.file_size} bytes, but its header "
                    f"declares {offset + size}"
                )
        out = {}
        for info in infos:
            with zf.open(info) as f:
                out[info.filename[: -len(".npy")]] = np.lib.format.read_array(f, allow_pickle=False)
    return out


def _key(info: zipfile.ZipInfo, seen: set[str], names: Collection[str] | None) -> str:
    if not info.filename.endswith(".npy"):
        raise UnsafeArrayError(f"member {info.filename!r} is not an .npy array")
    key = info.filename[: -len(".npy")]
    if key in seen:
        raise UnsafeArrayError(f"member {key!r} appears twice")
    if names is not None and key not in names:
        raise UnsafeArrayError(f"member {key!r} is not one of {sorted(names)}")
    seen.add(key)
    return key


def _check_dtype(key: str, dtype: np.dtype, kinds: str) -> None:
    if dtype.hasobject:
        raise UnsafeArrayError(f"member {key!r} has object dtype {dtype}: arrays only")
    if dtype.kind not in kinds or dtype.fields is not None or dtype.subdtype is not None:
        raise UnsafeArrayError(
            f"member {key!r} has dtype {dtype}, expected one of the kinds {kinds!r}"
        )


def _fits(shape: tuple[int, ...], want: Shape) -> bool:
    return len(shape) == len(want) and all(
        w is None or s == w for s, w in zip(shape, want, strict=True)
    )
