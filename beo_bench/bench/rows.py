"""A run's rows and its results file (``results.jsonl``): the typed :class:`Row`, the scan that
reads a file a crash or a second writer may have left torn (:func:`scan_rows`), and the
writer that appends to it (:class:`ResultsWriter`).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import time
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from beo_bench.bench.runs import (
    CorruptRunError,
    RunError,
)


class ResultsWarning(UserWarning):
    """Lines of a results file that were skipped (damaged, incomplete, duplicated)."""


# -- errors from the file system -------------------------------------------------------------
def io_error(e: OSError, path: Path, doing: str) -> RunError:
    """A :class:`RunError` saying what failed on ``path`` and what to do about it."""
    if e.errno in (errno.ENOSPC, errno.EDQUOT):
        return RunError(
            f"no space left on the device of {path} while {doing}: the complete items "
            "written so far are kept; free some space, then run again with --resume"
        )
    if e.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        return RunError(
            f"cannot write {path} while {doing} ({e.strerror}): a run needs a writable "
            "directory; choose another --out or make this one writable"
        )
    return RunError(f"{path}: {e.strerror or e} while {doing}")


# -- rows ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Row:
    """One line of ``results.jsonl``: a scored view (or episode) of an item. ``item`` and
    ``view`` are always there; the keys every kind writes are read through the typed
    properties; the kind's own metrics stay in :attr:`data`, the line's whole JSON object
    (written back as it was read: :meth:`to_json`)."""

    item: int
    view: int
    data: Mapping[str, Any]
    """The row's JSON object, every key (``item`` and ``view`` included)."""

    @classmethod
    def of(cls, obj: Mapping[str, Any]) -> Row:
        """The row of a JSON object that has ``item`` and ``view``."""
        return cls(int(obj["item"]), int(obj["view"]), obj)

    @classmethod
    def parse(cls, line: bytes) -> Row | None:
        """The row a results line holds, or None if it holds none (not JSON, not an object,
        no non-negative integer ``item`` and ``view``)."""
        try:
            obj = json.loads(line)
        except (ValueError, UnicodeDecodeError):
            return None
        ok = isinstance(obj, dict) and all(
            isinstance(obj.get(k), int) and not isinstance(obj.get(k), bool) and obj[k] >= 0
            for k in ("item", "view")
        )
        return cls.of(obj) if ok else None

    def to_json(self) -> dict[str, Any]:
        """The JSON object the row was made from."""
        return dict(self.data)

    @property
    def item_rows(self) -> int | None:
        """How many rows the item has (on its first row; None: not recorded)."""
        n = self.data.get("item_rows")
        return int(n) if n is not None else None

    @property
    def category(self) -> str:
        return str(self.data["category"])

    @property
    def true_class(self) -> int:
        return int(self.data["true_class"])

    @property
    def failure(self) -> str | None:
        """Why the view failed (None: it was answered)."""
        f = self.data.get("failure")
        return str(f) if f else None

    @property
    def ms(self) -> float | None:
        """The backend's time on the view (None: failed, or not timed)."""
        ms = self.data.get("ms")
        return None if ms is None else float(ms)


def rows_of(objs: Iterable[Mapping[str, Any]]) -> list[Row]:
    """Rows of JSON objects (as a kind or a scorer makes them)."""
    return [Row.of(o) for o in objs]


def json_rows(rows: Iterable[Row]) -> list[dict[str, Any]]:
    """The JSON objects of ``rows`` (what an item kind's metrics read)."""
    return [r.to_json() for r in rows]


@dataclass
class RowScan:
    """What :func:`scan_rows` found in a results file."""

    rows: list[Row] = field(default_factory=list)
    """Each item's first complete set of rows, in file order."""
    damaged: list[int] = field(default_factory=list)
    """Line numbers (1-based) that are not result rows (torn, corrupt)."""
    torn_tail: bool = False
    """The file ended in an unfinished line (cut off when repairing)."""
    incomplete: list[int] = field(default_factory=list)
    """Items with a set of rows that misses some (a damaged line): that set is ignored."""
    duplicates: list[int] = field(default_factory=list)
    """Items with more than one complete set of rows (two runs into one directory): all
    but the first are ignored."""

    def report(self, path: Path) -> str:
        """One sentence per kind of damage ("" when the file is clean)."""
        parts = []
        if self.damaged:
            n = len(self.damaged)
            parts.append(f"skipped {n} damaged line(s) (lines {_items(self.damaged)})")
        if self.torn_tail:
            parts.append("cut off a torn last line (a run stopped mid-write)")
        if self.incomplete:
            parts.append(
                f"ignored incomplete rows of {len(self.incomplete)} item(s) "
                f"{_items(self.incomplete)} (an item without a complete set is run again)"
            )
        if self.duplicates:
            parts.append(
                f"dropped a second set of rows of {len(self.duplicates)} item(s) "
                f"{_items(self.duplicates)}, keeping the first (two runs wrote into one "
                "directory?)"
            )
        return f"{path}: " + "; ".join(parts) if parts else ""


def _items(items: list[int]) -> str:
    shown = sorted(set(items))
    return str(shown[:10])[:-1] + (", ...]" if len(shown) > 10 else "]")


def span(items: Iterable[int]) -> str:
    """``first..last`` of a set of items (``none`` when empty), for messages."""
    items = set(items)
    return f"{min(items)}..{max(items)}" if items else "none"


def _blocks(rows: list[Row]) -> list[list[Row]]:
    """Rows cut into the sets that items were written as: one item's consecutive views."""
    out: list[list[Row]] = []
    for r in rows:
        last = out[-1][-1] if out else None
        if last is None or r.view == 0 or r.item != last.item or r.view != last.view + 1:
            out.append([r])
        else:
            out[-1].append(r)
    return out


def _complete(block: list[Row]) -> bool:
    """Views 0..n-1 of one item, n as its first row says (``item_rows``; rows written before
    it was recorded count as complete when their views start at 0)."""
    n = block[0].item_rows
    return block[0].view == 0 and len(block) == (len(block) if n is None else n)


def scan_rows(path: Path, repair: bool = False) -> RowScan:
    """Read a results file: keep each item's first complete set of rows, skip the rest and
    say what was skipped. ``repair`` cuts a torn last line off the file (only when this
    process holds the run's lock: the next append would be glued to it)."""
    scan = RowScan()
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return scan
    end = data.rfind(b"\n") + 1
    if end < len(data):
        scan.torn_tail = True
        if repair:
            with open(path, "r+b") as f:
                f.truncate(end)
    rows = []
    for n, line in enumerate(data[:end].split(b"\n")[:-1], start=1):
        if not line.strip():
            continue
        row = Row.parse(line)
        if row is None:
            scan.damaged.append(n)
        else:
            rows.append(row)
    kept: set[int] = set()
    for block in _blocks(rows):
        item = block[0].item
        if not _complete(block):
            if item not in scan.incomplete:
                scan.incomplete.append(item)
        elif item in kept:
            if item not in scan.duplicates:
                scan.duplicates.append(item)
        else:
            kept.add(item)
            scan.rows.extend(block)
    return scan


def read_rows(path: Path, repair: bool = False, report: bool = True) -> list[dict[str, Any]]:
    """The rows of a results file as JSON objects: each item's first complete set (see
    :func:`scan_rows`). Whatever was skipped is reported as a :class:`ResultsWarning` when
    ``report``."""
    scan = scan_rows(Path(path), repair)
    message = scan.report(Path(path))
    if report and message:
        warnings.warn(message, ResultsWarning, stacklevel=2)
    return json_rows(scan.rows)


def scan_run(results: Path, repair: bool, report: bool = True) -> RowScan:
    """A run's results file as a run reads it: a file with damaged lines and no row is
    refused (:class:`CorruptRunError`); what was skipped is reported (``report``)."""
    try:
        scan = scan_rows(results, repair)
    except OSError as e:
        raise io_error(e, results, "reading the results") from e
    if scan.damaged and not scan.rows:
        raise CorruptRunError(
            f"{results} holds no result rows ({len(scan.damaged)} damaged lines): it is not "
            "a beo-bench results file or it is destroyed, and it is not appended to: choose "
            "another --out (or move this directory away)"
        )
    message = scan.report(results)
    if report and message:
        warnings.warn(message, ResultsWarning, stacklevel=5)  # run()'s caller
    return scan


def _write_all(fd: int, data: bytes) -> None:
    """``os.write`` until every byte is written (a write may take fewer bytes than asked)."""
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        if n <= 0:  # no progress and no error: treat as a failed write
            raise OSError(errno.EIO, "write made no progress")
        view = view[n:]


def row_line(row: Mapping[str, Any]) -> str:
    """A row as its line of ``results.jsonl`` (keys sorted)."""
    return json.dumps(row, sort_keys=True) + "\n"


class ResultsWriter:
    """Appends each item's rows as whole lines to a file opened with ``O_APPEND`` (this run
    holds the directory's lock, so it is the only writer). Once written, the lines survive
    the process being killed (they are in the kernel's page cache); ``fsync`` (against power
    loss) runs at most every ``sync_every_s`` and on close, because one fsync per item
    (~20 ms here) capped the runner at ~50 items/s. A write that fails part-way (a full
    disk) is cut back off, so the file never holds a torn line before complete ones."""

    def __init__(self, path: Path, sync_every_s: float = 1.0) -> None:
        self.path = path
        flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC
        try:
            self.fd = os.open(path, flags, 0o644)
            self._size = os.fstat(self.fd).st_size
        except OSError as e:
            raise io_error(e, path, "opening the results file") from e
        self.sync_every_s = sync_every_s
        self._last_sync = time.monotonic()

    def append(self, rows: list[dict[str, Any]]) -> None:
        payload = "".join(row_line(r) for r in rows).encode()
        try:
            _write_all(self.fd, payload)
        except OSError as e:
            self._cut_back()
            raise io_error(e, self.path, "writing results") from e
        self._size += len(payload)
        if time.monotonic() - self._last_sync > self.sync_every_s:
            self._sync()
            self._last_sync = time.monotonic()

    def _cut_back(self) -> None:
        """Remove the part of an item that a failed write left (best effort: a reader skips
        a damaged line anyway)."""
        with contextlib.suppress(OSError):
            os.ftruncate(self.fd, self._size)

    def _sync(self) -> None:
        try:
            os.fsync(self.fd)
        except OSError as e:  # a full disk can surface here, on delayed allocation
            raise io_error(e, self.path, "flushing results to disk") from e

    def close(self) -> None:
        if self.fd >= 0:
            fd, self.fd = self.fd, -1
            try:
                os.fsync(fd)
            except OSError as e:
                raise io_error(e, self.path, "flushing results to disk") from e
            finally:
                os.close(fd)

    def __enter__(self) -> ResultsWriter:
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        if exc_type is None:
            self.close()
        else:  # do not hide the error that stopped the run behind one of closing
            with contextlib.suppress(RunError):
                self.close()
