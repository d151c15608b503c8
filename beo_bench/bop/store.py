"""A BOP dataset root's ownership: the names of its files and folders, its marker, its lock,
and the ledger of the files an export wrote there.

Every file is written atomically (:mod:`beo_bench.atomic`), and only inside a dataset root
that :func:`claim_dataset_dir` created or marked: an existing non-empty folder that
beo-bench did not make is refused and left untouched (:class:`ForeignOutputError`), and so
is a symbolic link at any folder or file below the root that a writer would write (nothing
is written through a link). Inside :func:`export_dir` (what ``beo-bench export`` uses) one
process writes at a time, every file written is listed in the root's ledger, a file there
that the ledger does not list as unchanged since beo-bench wrote it is never overwritten,
and :meth:`ExportLedger.finish` removes the files of an earlier export that this one did not
write again (only those: a file the user changed or added is kept). The format's files
themselves are :mod:`beo_bench.bop.files` (models, targets, cameras) and
:mod:`beo_bench.bop.scenes` (the scenes' images and ground truth).
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from beo_bench import outdir
from beo_bench.atomic import atomic_write_bytes
from beo_bench.errors import BeoBenchError, UsageError

__all__ = [
    "CAMERA_NAME",
    "CATEGORY_MAP_NAME",
    "EMPTY_BBOX",
    "FILES_NAME",
    "LOCK_NAME",
    "MARKER_NAME",
    "MODELS_DIR",
    "MODELS_INFO_NAME",
    "SCENE_CAMERA_NAME",
    "SCENE_GT_INFO_NAME",
    "SCENE_GT_NAME",
    "TARGETS_NAME",
    "DatasetBusyError",
    "ExportLedger",
    "ForeignOutputError",
    "claim_dataset_dir",
    "export_dir",
    "write_file",
]


MARKER_NAME = ".beo_bench_bop"
"""The marker file of a dataset root this package created (see :func:`claim_dataset_dir`)."""
MARKER_TEXT = (
    "This BOP dataset folder was written by beo-bench (beo-bench export); beo-bench may\n"
    "overwrite the files it wrote here. Delete this file to make beo-bench refuse the folder.\n"
)
FILES_NAME = ".beo_bench_bop_files"
"""The ledger of an export (:class:`ExportLedger`): one JSON line per file written."""
LOCK_NAME = ".beo_bench_bop.lock"
"""Locked (``flock``, with the PID in it) by the export writing the folder."""
MODELS_DIR = "models"
"""The models folder (``models[_MODELTYPE]`` in the format documentation)."""
MODELS_INFO_NAME = "models_info.json"
TARGETS_NAME = "test_targets_bop19.json"
"""The test targets of the BOP 2019 localization task, at the dataset root."""
CATEGORY_MAP_NAME = "beo_bench_objects.json"
"""beo-bench's own file beside ``models_info.json``: obj_id -> category, split, key."""
CAMERA_NAME = "camera.json"
SCENE_CAMERA_NAME = "scene_camera.json"
SCENE_GT_NAME = "scene_gt.json"
SCENE_GT_INFO_NAME = "scene_gt_info.json"
EMPTY_BBOX = (-1, -1, -1, -1)
"""The box of an empty mask, as ``scripts/calc_gt_info.py`` of the toolkit writes it."""


class ForeignOutputError(UsageError):
    """An output folder or file that beo-bench did not create: a non-empty folder without
    the marker, or a file outside a folder that :func:`claim_dataset_dir` claimed. Nothing
    in it is touched."""


class DatasetBusyError(BeoBenchError):
    """Another process is exporting into the same folder (it holds :data:`LOCK_NAME`)."""


# -- ownership --------------------------------------------------------------------------------
def claim_dataset_dir(root: Path | str) -> Path:
    """Make ``root`` a dataset root the writers of this module may write into: create it
    (with its parents) when missing, mark it when empty, accept it when it carries the
    marker (:data:`MARKER_NAME`) of an earlier export. A non-empty folder without the
    marker is the user's: :class:`ForeignOutputError`, and nothing in it is touched."""
    root = Path(root)
    if root.exists() and not root.is_dir():
        raise ForeignOutputError(
            f"{root} is a file, not a folder: give the BOP export a new or empty folder"
        )
    root.mkdir(parents=True, exist_ok=True)
    held = outdir.foreign_files(root, MARKER_NAME)
    if held:
        raise ForeignOutputError(
            f"{root} is a non-empty folder that beo-bench did not create (it holds "
            f"{outdir.shown(held)} and no {MARKER_NAME}): give the BOP export a new or empty "
            "folder; nothing in this one is touched"
        )
    if held is not None:
        outdir.mark(root, MARKER_NAME, MARKER_TEXT)
    return root


def _claimed_root(path: Path) -> Path | None:
    """The nearest folder above ``path`` that carries the marker, if any."""
    for d in path.absolute().parents:
        m = d / MARKER_NAME
        if m.is_file() and not m.is_symlink():
            return d
    return None


def _link_error(link: Path) -> ForeignOutputError:
    try:
        to = f" (to {os.readlink(link)})"
    except OSError:  # pragma: no cover - it was a link a moment ago
        to = ""
    return ForeignOutputError(
        f"{link} is a symbolic link{to}: the BOP export never writes through a link, and "
        "nothing was written through this one; remove the link, or export into a new DIR"
    )


def _inside(root: Path, path: Path) -> None:
    """Create ``path``'s folders below ``root`` one at a time, refusing a symbolic link (or
    a file) at any of them and a symbolic link at ``path``; and refuse a ``path`` that
    resolves outside ``root``."""
    rel = path.relative_to(root)
    d = root
    for part in rel.parts[:-1]:
        d = d / part
        if d.is_symlink():
            raise _link_error(d)
        if not d.exists():
            d.mkdir(exist_ok=True)
        elif not d.is_dir():
            raise ForeignOutputError(
                f"{d} is a file where the BOP export writes a folder: move it away, or "
                "export into a new DIR"
            )
    if path.is_symlink():
        raise _link_error(path)
    real = root.resolve()
    if real != path.parent.resolve() and real not in path.parent.resolve().parents:
        raise ForeignOutputError(  # pragma: no cover - a link on the way is refused above
            f"{path} resolves outside the export folder {root}: nothing written there"
        )


def _target(path: Path | str) -> tuple[Path, Path]:
    """``path`` (absolute) with its folders created, and its claimed dataset root, after
    checking it lies in that root and no link is on the way (:func:`_inside`)."""
    path = Path(path).absolute()
    root = _claimed_root(path)
    if root is None:
        raise ForeignOutputError(
            f"{path} is not inside a BOP dataset folder that beo-bench created: claim the "
            "dataset root with claim_dataset_dir() first (it refuses a non-empty folder that "
            "beo-bench did not create)"
        )
    _inside(root, path)
    return path, root


def _writable(path: Path | str) -> Path:
    """``path``, with its folder created, after checking it lies in a claimed dataset root."""
    return _target(path)[0]


def _store(path: Path | str, data: bytes | str) -> None:
    """Write ``path`` atomically inside its claimed root; inside :func:`export_dir`, only
    where its ledger allows, and listed there."""
    target, root = _target(path)
    ledger = _LEDGERS.get(root)
    if ledger is not None:
        ledger.before(target)
    atomic_write_bytes(target, data)
    if ledger is not None:
        ledger.after(target)


def write_file(path: Path | str, data: bytes | str) -> None:
    """Write one more file of a dataset root (``data``: bytes, or text as UTF-8) as the
    writers of this module write theirs: atomically, checked and listed (:func:`_store`)."""
    _store(path, data)


# -- the ledger of an export --------------------------------------------------------------------
_LEDGERS: dict[Path, ExportLedger] = {}
"""The open ledger of each dataset root this process is exporting into."""
_OWN_NAMES = (MARKER_NAME, FILES_NAME, LOCK_NAME)


def _stat_key(path: Path) -> list[int]:
    st = path.lstat()
    return [st.st_ino, st.st_size, st.st_mtime_ns]


class ExportLedger:
    """The files beo-bench wrote into a dataset root, in ``ROOT/.beo_bench_bop_files``: a
    journal of JSON lines (``{"path": REL}`` before a file is written, ``{"path": REL,
    "stat": [inode, size, mtime_ns]}`` after, ``{"path": REL, "gone": true}`` when removed),
    appended as the export goes, so an export cut short leaves a ledger that still lists
    every file it wrote; :meth:`finish` rewrites it (atomically) to the files of this
    export. A file is beo-bench's to overwrite or remove only while it is listed with the
    inode, size and modification time it had when written (a file the user replaced or
    edited is theirs)."""

    def __init__(self, root: Path) -> None:
        self.root = root.absolute()
        self.path = self.root / FILES_NAME
        self.old = self._read()
        self.new: dict[str, list[int]] = {}
        self._fd: int | None = None

    def _read(self) -> dict[str, list[int] | None]:
        if self.path.is_symlink():
            raise _link_error(self.path)
        try:
            text = self.path.read_text()
        except FileNotFoundError:
            held = [
                n for n in outdir.foreign_files(self.root, MARKER_NAME) or [] if n not in _OWN_NAMES
            ]
            if held:
                raise ForeignOutputError(
                    f"{self.root} was exported by an earlier beo-bench, which kept no list of "
                    f"the files it wrote ({FILES_NAME}), so an export cannot tell its stale "
                    f"files from yours (it holds {outdir.shown(held)}): export into a new or "
                    "empty DIR; nothing in this one is touched"
                ) from None
            return {}
        entries: dict[str, list[int] | None] = {}
        for line in text.splitlines():
            try:
                e = json.loads(line)
                rel = e["path"]
                stat = e.get("stat")
            except (ValueError, TypeError, KeyError):
                continue  # a line cut short by a killed export: its file is still listed
            if not isinstance(rel, str) or not self._valid(rel):
                continue
            if e.get("gone"):
                entries.pop(rel, None)
            elif isinstance(stat, list) and len(stat) == 3:
                entries[rel] = [int(v) for v in stat]
            else:
                entries[rel] = None  # being written: unknown until its stat line
        return entries

    @staticmethod
    def _valid(rel: str) -> bool:
        p = Path(rel)
        own = p.name in _OWN_NAMES
        return bool(rel) and not p.is_absolute() and ".." not in p.parts and not own

    def _rel(self, path: Path) -> str:
        return path.relative_to(self.root).as_posix()

    def _append(self, entry: dict[str, Any]) -> None:
        if self._fd is None:
            flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC
            self._fd = os.open(self.path, flags, 0o644)
        data = (json.dumps(entry, sort_keys=True) + "\n").encode()
        while data:
            data = data[os.write(self._fd, data) :]

    def owns(self, path: Path) -> bool:
        """Whether ``path`` is a file this export or an earlier one wrote and nobody has
        changed since (a missing ``path`` is nobody's)."""
        rel = self._rel(path)
        if rel in self.new:
            return True
        if rel not in self.old:
            return False
        try:
            return self.old[rel] in (None, _stat_key(path))
        except FileNotFoundError:
            return False

    def check(self, path: Path) -> None:
        """Refuse (:class:`ForeignOutputError`) when ``path`` is a file that is not
        beo-bench's (:meth:`owns`), which an export must not overwrite."""
        rel = self._rel(path)
        if os.path.lexists(path) and not self.owns(path):
            changed = "was changed after beo-bench wrote it"
            why = changed if rel in self.old else "is not a file beo-bench wrote"
            raise ForeignOutputError(
                f"{path} {why}, and the export would overwrite it: move it out of the "
                "export, or export into a new DIR; it is left as it is"
            )

    def before(self, path: Path) -> None:
        """Refuse to overwrite a file that is not beo-bench's; note the write to come."""
        self.check(path)
        self._append({"path": self._rel(path)})

    def after(self, path: Path) -> None:
        """List the file just written."""
        rel = self._rel(path)
        self.new[rel] = _stat_key(path)
        self._append({"path": rel, "stat": self.new[rel]})

    def remove(self, path: Path) -> bool:
        """Remove ``path`` when it is beo-bench's (:meth:`owns`); whether it was."""
        rel = self._rel(path)
        for d in list(path.relative_to(self.root).parents)[:-1]:
            if (self.root / d).is_symlink() or not (self.root / d).is_dir():
                return False  # never remove through a link (or a folder that is not one)
        try:
            if path.is_symlink() or not path.is_file() or not self.owns(path):
                return False
        except OSError:
            return False
        path.unlink()
        self.new.pop(rel, None)
        self.old.pop(rel, None)
        self._append({"path": rel, "gone": True})
        return True

    def finish(self) -> tuple[int, list[str]]:
        """Remove the files of earlier exports this one did not write again (only those
        still as beo-bench wrote them), and the folders that leaves empty; rewrite the
        ledger to this export's files. Returns the files removed and the ones kept (changed
        or replaced by someone else, or of unknown state)."""
        removed, kept = 0, []
        folders: set[Path] = set()
        for rel in sorted(set(self.old) - set(self.new)):
            path = self.root / rel
            if not os.path.lexists(path):
                continue
            if self.remove(path):
                removed += 1
                folders.update(p for p in Path(rel).parents if p != Path("."))
            else:
                kept.append(rel)
        for d in sorted(folders, key=lambda p: len(p.parts), reverse=True):
            full = self.root / d
            if full.is_dir() and not full.is_symlink():
                with contextlib.suppress(OSError):
                    full.rmdir()  # only when empty: a user's file keeps its folder
        self.close()
        text = "".join(
            json.dumps({"path": rel, "stat": st}, sort_keys=True) + "\n"
            for rel, st in sorted(self.new.items())
        )
        atomic_write_bytes(self.path, text)
        self.old = dict(self.new)
        return removed, kept

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


_LAYOUT = (MODELS_DIR, "test", "train", TARGETS_NAME, CAMERA_NAME, *_OWN_NAMES)


def _links_in(root: Path) -> Path | None:
    """A symbolic link at a path of the layout below ``root`` (or anywhere under its
    ``models``, ``test`` and ``train`` folders), if any."""
    for name in _LAYOUT:
        top = root / name
        if top.is_symlink():
            return top
        if top.is_dir():
            for d, dirs, files in os.walk(top):
                for n in dirs + files:
                    if (Path(d) / n).is_symlink():
                        return Path(d) / n
    return None


@contextlib.contextmanager
def export_dir(root: Path | str, extra: Sequence[str] = ()) -> Iterator[ExportLedger]:
    """Claim ``root`` (:func:`claim_dataset_dir`), lock it (``ROOT/.beo_bench_bop.lock``:
    a second export gets a :class:`DatasetBusyError` naming the holder's PID), refuse it
    when a symbolic link stands where the export writes (``extra``: more names at the root
    it writes), and open its :class:`ExportLedger`, which the writers of this module use
    inside the ``with`` block."""
    root = claim_dataset_dir(root).absolute()
    link = _links_in(root) or next((root / n for n in extra if (root / n).is_symlink()), None)
    if link is not None:
        raise _link_error(link)

    def busy(pid: str) -> DatasetBusyError:
        return DatasetBusyError(
            f"{root} is being exported into by another process (PID {pid}, holding "
            f"{root / LOCK_NAME}): wait for it to finish or stop it, or export into another "
            "DIR (two exports into one folder would mix their images)"
        )

    with outdir.locked(root / LOCK_NAME, busy):
        ledger = ExportLedger(root)
        _LEDGERS[root] = ledger
        try:
            yield ledger
        finally:
            _LEDGERS.pop(root, None)
            ledger.close()
