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
import re
import struct
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


MAX_HEADER = 10_000
"""The longest ``.npy`` header read (numpy's own limit for headers it parses safely)."""
_CANONICAL = re.compile(
    r"\{'descr': '([<>|=][a-zA-Z][0-9]{0,4})', 'fortran_order': (True|False), "
    r"'shape': \(((?:[0-9]{1,19}, )*[0-9]{1,19},?)?\), \} *\n?"
)
"""The header numpy writes for a plain dtype (``{'descr': '<f8', 'fortran_order': False,
'shape': (3, 4), }`` padded with spaces): read by this pattern, a few microseconds; any
other header is left to numpy's parser (``ast.literal_eval``, a millisecond each, which the
cache's many-member entries paid on every read)."""


def _header(f: IO[bytes]) -> tuple[tuple[int, ...], bool, np.dtype]:
    version = np.lib.format.read_magic(f)
    if version not in ((1, 0), (2, 0)):
        # 3.0 exists only for structured dtypes with non-ASCII field names: none of ours
        raise UnsafeArrayError(f"npy format version {version} is not one this package writes")
    size = f.read(2 if version == (1, 0) else 4)
    (n,) = (
        struct.unpack("<H" if version == (1, 0) else "<I", size) if len(size) in (2, 4) else (-1,)
    )
    if not 0 <= n <= MAX_HEADER:
        raise UnsafeArrayError(f"npy header of {n} bytes: not one this package writes")
    raw = f.read(n)
    m = _CANONICAL.fullmatch(raw.decode("latin1"))
    if m is None:  # numpy's parser, on the same bytes: its answer, or its refusal
        parse = np.lib.format.read_array_header_1_0
        if version == (2, 0):
            parse = np.lib.format.read_array_header_2_0
        return parse(io.BytesIO(size + raw))
    descr, fortran, dims = m.groups()
    shape = tuple(int(d) for d in dims.replace(",", " ").split()) if dims else ()
    return shape, fortran == "True", np.dtype(descr)


def _read(
    f: IO[bytes], offset: int, shape: tuple[int, ...], fortran: bool, dtype: np.dtype
) -> np.ndarray:
    """A member's array, its header (``offset`` bytes, checked by the first pass) skipped,
    as ``np.lib.format.read_array`` gives it (writable; Fortran order kept)."""
    f.read(offset)
    out = np.empty(math.prod(shape), dtype=dtype)
    view = out.data.cast("B")
    got = 0
    while got < len(view):  # a zip stream may return less than asked
        k = f.readinto(view[got:])  # type: ignore[attr-defined]
        if not k:
            raise UnsafeArrayError(f"member ends after {got} of {len(view)} array bytes")
        got += k
    if fortran:
        return out.reshape(shape[::-1]).transpose()
    return out.reshape(shape)


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
        headers = []
        for info in infos:  # every header first: nothing is unpacked from a refused file
            key = _key(info, seen, names)
            with zf.open(info) as f:
                shape, fortran, dtype = _header(f)
                offset = f.tell()
            headers.append((offset, shape, fortran, dtype))
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
        for info, header in zip(infos, headers, strict=True):
            with zf.open(info) as f:
                out[info.filename[: -len(".npy")]] = _read(f, *header)
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
