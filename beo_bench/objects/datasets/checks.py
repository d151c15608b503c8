"""The dataset check: every file of a user's dataset is built once (read, repaired,
scaled, checked), in the driver, before a command uses the dataset, so that a bad file is
found up front, named, with what is wrong and the flag that fixes it, instead of failing
a worker in the middle of a run.

:func:`check_dataset` builds every mesh file of a :class:`~.dataset.Dataset`
(all splits and classes: which files are skipped is part of the dataset's identity, so it
must not depend on the split a command uses) with its loading options, within a face budget
(``--max-faces``, :data:`~.meshfile.MAX_INPUT_FACES`), and returns a
:class:`DatasetCheck`: per file (:class:`FileCheck`) its faces, its largest extent in file
units, the units assumed and the resulting size, or what is wrong and the CLI flag that
fixes it. A file that loads but ends within a factor :data:`NEAR_LIMIT` of the size limits
(:data:`~.meshfile.MIN_EXTENT`, :data:`~.meshfile.MAX_DIAGONAL`)
with a size read from its units is flagged: a 1.0-unit soccer ball read as centimetres is a
1 cm ball, and nothing else would say so.

Verdicts are cached on disk by file content hash and loading options, so only new or
changed files are built again; the first check of a large dataset builds every file once
(cheaper than ``beo-bench objects``, which adds voxels, collision parts and symmetry), with
``workers`` processes.

:func:`vet` is what the CLI does with it (``--objects`` and ``--skip-bad``).
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing as mp
import sys
import warnings
from collections.abc import Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from tqdm import tqdm

from beo_bench.atomic import atomic_write_bytes
from beo_bench.errors import BadObjectsError, EmptyMeshError, MeshError, TooManyFacesError
from beo_bench.objects.datasets.dataset import Dataset, file_hashes, memo_file
from beo_bench.objects.datasets.layouts import dataset_entries, entry_options
from beo_bench.objects.datasets.load import (
    MANIFEST_NAME,
    LoadOptions,
    Manifest,
    build_mesh,
)
from beo_bench.objects.datasets.meshfile import (
    DETECTED_UNITS,
    MAX_DIAGONAL,
    MIN_EXTENT,
    UNITS,
    recorded_unknown_sizes,
    sideways_up,
    toml_key,
    warn_unknown_size,
)
from beo_bench.objects.registry import LIBRARY_VERSION

CHECK_VERSION = 3
"""Version of the verdicts' cache: bumped when loading (repair, scaling) changes what a file
gives, so that no verdict of an older rule is reused (2: a file whose extent is outside
:data:`~.meshfile.FILE_EXTENT_LIMITS` is a size error before the repair; 3: verdicts say
whether a file looks Y-up, :attr:`FileCheck.sideways`)."""

NEAR_LIMIT = 3.0
"""A loaded object whose largest extent is under this many times
:data:`~.meshfile.MIN_EXTENT` (3 cm), or whose diagonal is over
:data:`~.meshfile.MAX_DIAGONAL` divided by it (23 cm), with a size read from
its file's units, is flagged: unit readings are 10x apart, so a real object read in the
wrong units lands within this factor of a limit (a 30 cm tray read as 1 cm-3 cm, a 5 cm
lemon as 50 cm). Real objects of those sizes are flagged too: the flag says what to pass
if the size is wrong, and nothing changes if it is right."""

NEAR_LINES = 10
"""Flagged files a command other than ``objects`` names one line each; the rest are
counted (``beo-bench objects`` lists them all)."""

PARALLEL_FROM = 16
"""Files to build from which the check uses worker processes (below it their start-up,
about two seconds, costs more than it saves)."""

UNITS_FLAG = "--units mm|cm|m|in"
SIZE_FLAG = "--size M"
SKIP = "--skip-bad to run without it"


class SizeWarning(UserWarning):
    """A file that loads within a factor :data:`NEAR_LIMIT` of the size limits."""


class SidewaysWarning(UserWarning):
    """A file of a folder dataset that looks modelled Y-up (:attr:`FileCheck.sideways`)."""


class SkippedFileWarning(UserWarning):
    """A bad file left out of the dataset (``--skip-bad``)."""


@dataclass(frozen=True)
class FileCheck:
    """The check of one file of a dataset."""

    path: str
    """Relative to the dataset's root."""
    category: str
    kind: str = "ok"
    """``ok``, or where it failed: ``read`` (missing, unreadable, corrupt, no faces),
    ``faces`` (over the face budget), ``repair`` (no solid could be made), ``size`` (no
    tabletop object at its scale)."""
    faces: int | None = None
    """Faces of the file as read (a header's count when refused over budget)."""
    native_extent: float | None = None
    """Largest extent in file units."""
    units: str | None = None
    """The units its size was read in (a key of :data:`~.meshfile.UNITS`),
    ``normalised`` (scaled to its class's size), or None (``--size`` set it)."""
    detected: bool = False
    """Whether :attr:`units` were detected (``--units auto``, the folders' default)."""
    scaled: bool = False
    """Whether it got as far as being scaled (:attr:`units` None then means ``--size``)."""
    extents: tuple[float, float, float] | None = None
    """Loaded bounding-box size (x, y, z), metres."""
    problem: str | None = None
    """What is wrong (None: the file loads)."""
    fix: str | None = None
    """The CLI flags that fix it."""
    sideways: bool = False
    """Whether it loads looking modelled Y-up (:func:`~.meshfile.sideways_up`): a bottle
    or mug lying on its side."""

    @property
    def ok(self) -> bool:
        return self.problem is None

    def scale(self) -> str:
        """How its size was set, for the report."""
        if not self.scaled:
            return "-"
        if self.units is None:
            return "--size"
        return f"{self.units} (detected)" if self.detected else self.units

    def near_limit(self) -> str | None:
        """Why the loaded size is within :data:`NEAR_LIMIT` of a limit (None: it is not, or
        the scale did not come from the file's units)."""
        if not self.ok or self.extents is None or self.units not in UNITS:
            return None
        largest, diagonal = max(self.extents), float(np.linalg.norm(self.extents))
        read = f"its largest extent, {self.native_extent:.4g} file units read as {self.scale()},"
        if largest < NEAR_LIMIT * MIN_EXTENT:
            return (
                f"{read} makes it {_length(largest)} across, within {NEAR_LIMIT:g}x of the "
                f"{_length(MIN_EXTENT)} minimum: if it is larger, pass {UNITS_FLAG} for the "
                f"files' units or {SIZE_FLAG} for its largest extent in metres"
            )
        if diagonal > MAX_DIAGONAL / NEAR_LIMIT:
            return (
                f"{read} makes its diagonal {_length(diagonal)}, within {NEAR_LIMIT:g}x of the "
                f"{_length(MAX_DIAGONAL)} maximum (the table's depth): if it is smaller, pass "
                f"{UNITS_FLAG} for the files' units or {SIZE_FLAG} for its largest extent in "
                f"metres"
            )
        return None


@dataclass(frozen=True)
class DatasetCheck:
    """The checks of every file of a dataset (:func:`check_dataset`)."""

    root: str
    files: tuple[FileCheck, ...]
    max_faces: int

    @property
    def bad(self) -> tuple[FileCheck, ...]:
        return tuple(f for f in self.files if not f.ok)

    def near_limit(self) -> list[tuple[FileCheck, str]]:
        """The files that load within :data:`NEAR_LIMIT` of a size limit, with why."""
        return [(f, why) for f in self.files if (why := f.near_limit()) is not None]

    def where(self, f: FileCheck) -> str:
        return str(Path(self.root) / f.path)

    def sideways(self) -> list[tuple[FileCheck, str]]:
        """The files that look modelled Y-up, with the advice (call only for layouts whose
        files' axes are an option: folders)."""
        manifest = Path(self.root) / MANIFEST_NAME
        return [
            (
                f,
                f"it looks modelled Y-up (flat ends along y, nothing flat below: it would lie "
                f"on its side); if y is its up axis, pass --up y for every file, or set "
                f'up = "y" under [files.{toml_key(f.path)}] or [classes.{toml_key(f.category)}]'
                f" in {manifest} (-y if it then stands upside down)",
            )
            for f in self.files
            if f.ok and f.sideways
        ]

    def line(self, f: FileCheck) -> str:
        """One line about a bad file: its path, what is wrong, the flags that fix it."""
        return f"{self.where(f)}: {f.problem}; {f.fix}, or pass {SKIP}"

    def skip_line(self, f: FileCheck) -> str:
        """One line about a bad file that ``--skip-bad`` leaves out."""
        return f"skipping {self.where(f)} (--skip-bad): {f.problem}; to use it, {f.fix}"

    def summary(self) -> str:
        """The one-line error for a dataset with bad files and no ``--skip-bad``."""
        n, good = len(self.bad), len(self.files) - len(self.bad)
        rest = f"or pass --skip-bad to run on the other {good}" if good else "none is usable"
        return (
            f"{n} of {len(self.files)} files of {self.root} cannot be used as objects (each "
            f"is named above with the flag that fixes it): fix them, {rest}"
        )

    def raise_if_bad(self) -> None:
        """:class:`~beo_bench.errors.BadObjectsError` listing every bad file, if any."""
        if self.bad:
            lines = "\n".join(f"  {self.line(f)}" for f in self.bad)
            raise BadObjectsError(f"{self.summary()}\n{lines}")

    def table(self, paths: Iterable[str] | None = None) -> str:
        """The per-file unit and scale report (of ``paths``, relative to the root; default:
        every file): faces, largest extent in file units, the units assumed, the loaded
        largest extent and diagonal, and a note for bad and flagged files."""
        keep = None if paths is None else set(paths)
        rows = [f for f in self.files if keep is None or f.path in keep]
        width = max([len("file"), *(len(f.path) for f in rows)])
        head = (
            f"  {'file':<{width}}  {'faces':>9}  {'extent':>9}  {'units':<14}  "
            f"{'largest':>9}  {'diagonal':>9}  note"
        )
        out = [
            f"{len(rows)} files: the units each is read in and the size it gets (extent: "
            f"largest, in file units)",
            head,
        ]
        for f in rows:
            faces = f"{f.faces:,}" if f.faces is not None else "-"
            native = f"{f.native_extent:.4g}" if f.native_extent is not None else "-"
            largest = diagonal = "-"
            if f.ok and f.extents is not None:
                largest = _length(max(f.extents))
                diagonal = _length(float(np.linalg.norm(f.extents)))
            note = f"BAD: {f.problem}" if not f.ok else ""
            if f.near_limit() is not None:
                note = f"near the size limits ({_length(MIN_EXTENT)} to {_length(MAX_DIAGONAL)})"
            out.append(
                f"  {f.path:<{width}}  {faces:>9}  {native:>9}  {f.scale():<14}  {largest:>9}  "
                f"{diagonal:>9}  {note}".rstrip()
            )
        return "\n".join(out)


def _length(metres: float) -> str:
    return f"{metres * 100:.3g} cm" if metres < 1 else f"{metres:.3g} m"


# -- checking -----------------------------------------------------------------------------
def check_dataset(
    dataset: Dataset, workers: int | None = 1, progress: bool = False
) -> DatasetCheck:
    """Build every mesh file of ``dataset`` with its loading options and face budget
    (:attr:`~beo_bench.objects.datasets.dataset.Dataset.max_faces`), with ``workers`` processes
    (None: one per core; small checks run here), and say what each gives. Files checked
    before with the same content and options are not built again (the verdicts are cached
    under the asset cache's ``datasets/``)."""
    layout = dataset.layout_spec
    opts = dataset.options()
    rotation = tuple(map(tuple, np.asarray(layout.rotation(opts)).tolist()))
    units = opts.units or layout.default_units
    hashes = file_hashes(dataset.root, dataset.layout)
    root = Path(dataset.root)
    entries = sorted(dataset_entries(layout, dataset.root), key=lambda e: str(e.path))
    settings = _settings_key(opts, units, rotation, dataset.manifest)
    memo_path = memo_file(dataset.root, f"checks-v{CHECK_VERSION}")
    memo = _read_memo(memo_path)
    known: dict[str, list[Any]] = memo.setdefault(settings, {})
    results: dict[str, FileCheck] = {}
    todo = []
    for e in entries:
        rel = e.path.relative_to(root).as_posix()
        file_hash = hashes.get(rel, "")
        old = known.get(rel)
        if old is not None and old[0] == file_hash and not file_hash.startswith("unreadable"):
            check = FileCheck(**{**old[1], "extents": _tuple(old[1].get("extents"))})
            # refused over an older budget, and within this one: build it now
            if not (check.kind == "faces" and (check.faces or 0) <= dataset.max_faces):
                results[rel] = check
                continue
        o = entry_options(layout, dataset.root, e, opts, dataset.manifest)  # its manifest entry
        r = rotation if o.up == opts.up else tuple(map(tuple, layout.rotation(o).tolist()))
        todo.append(
            (str(e.path), rel, e.category, r, o, o.units or layout.default_units, dataset.max_faces)
        )
    for (_, rel, *_), (check, notes) in zip(todo, _run(todo, workers, progress), strict=True):
        for category in notes:  # shown once, here, as loading would have shown it
            warn_unknown_size(category)
        results[rel] = check
        if not hashes.get(rel, "").startswith("unreadable"):
            known[rel] = [hashes.get(rel, ""), asdict(check)]
    if todo:
        live = {e.path.relative_to(root).as_posix() for e in entries}
        memo[settings] = {rel: v for rel, v in known.items() if rel in live}
        try:
            memo_path.parent.mkdir(parents=True, exist_ok=True)
            # not fsync-ed: a lost memo only costs building the files again
            atomic_write_bytes(memo_path, json.dumps(memo), durable=False)
        except OSError:
            pass  # the cache was checked writable at start; losing the memo costs time only
    files = tuple(_budgeted(results[r], dataset.max_faces) for r in sorted(results))
    return DatasetCheck(dataset.root, files, dataset.max_faces)


def _settings_key(
    opts: LoadOptions,
    units: str,
    rotation: tuple[tuple[float, ...], ...],
    manifest: Manifest | None = None,
) -> str:
    blob: dict[str, object] = {
        "v": CHECK_VERSION,
        "library": LIBRARY_VERSION,
        "repair": opts.repair,
        "size": opts.size,
        "units": units,
        "rotation": rotation,
    }
    if manifest is not None:  # (absent without one: the verdicts cached before it stay valid)
        blob["manifest"] = manifest.identity()
    return hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()[:16]


def _read_memo(path: Path) -> dict[str, dict[str, list[Any]]]:
    try:
        memo = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return memo if isinstance(memo, dict) else {}


def _tuple(v: Any) -> tuple[float, float, float] | None:
    return None if v is None else (float(v[0]), float(v[1]), float(v[2]))


def _run(
    todo: Sequence[tuple[Any, ...]], workers: int | None, progress: bool
) -> list[tuple[FileCheck, list[str]]]:
    """:func:`check_file` of each of ``todo``, in order: here, or with worker processes."""
    bar = tqdm(
        total=len(todo),
        desc="checking dataset files",
        unit="file",
        disable=None if progress and len(todo) >= PARALLEL_FROM else True,
    )
    workers = (mp.cpu_count() or 1) if workers is None else workers
    out: list[tuple[FileCheck, list[str]]] = []
    with bar:
        if workers <= 1 or len(todo) < PARALLEL_FROM:
            for args in todo:
                out.append(check_file(*args))
                bar.update()
        else:
            # forkserver: workers start clean (as objects.prepare's, for the same reasons)
            ctx = mp.get_context("forkserver")
            with ProcessPoolExecutor(min(workers, len(todo)), mp_context=ctx) as pool:
                for result in pool.map(_check_args, todo, chunksize=4):
                    out.append(result)
                    bar.update()
    return out


def _check_args(args: tuple[Any, ...]) -> tuple[FileCheck, list[str]]:
    return check_file(*args)


def check_file(
    path: str,
    rel: str,
    category: str,
    rotation: tuple[tuple[float, ...], ...],
    opts: LoadOptions,
    units: str,
    max_faces: int,
) -> tuple[FileCheck, list[str]]:
    """Build one file as an instance would (:func:`~beo_bench.objects.datasets.load.build_mesh`)
    and say what it gives; with the categories of the
    :class:`~.meshfile.UnknownSizeWarning` loading it raised."""
    trace: dict[str, Any] = {}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            built = build_mesh(
                path, category, rotation, opts, units, max_faces=max_faces, trace=trace
            )
            sideways = sideways_up(built.mesh)
            failure: tuple[str, str, str] | None = None
        except TooManyFacesError as e:  # refused before it was parsed: its count is the error's
            sideways = False
            trace["faces"] = e.faces
            failure = _diagnose(e, path, trace, opts, max_faces)
        except MeshError as e:
            sideways = False
            failure = _diagnose(e, path, trace, opts, max_faces)
        except Exception as e:  # from trimesh or manifold3d on a mesh they cannot handle
            if trace.get("stage") != "repair":
                raise
            sideways = False
            failure = (
                "repair",
                f"repairing it failed ({type(e).__name__}: {e}; if the file is a sound mesh, "
                f"please report it to beo-bench)",
                f"pass {_repair_fix(opts.repair)}",
            )
    notes = recorded_unknown_sizes(caught)
    native = trace.get("native_extents")
    check = FileCheck(
        path=rel,
        category=category,
        faces=trace.get("faces"),
        native_extent=None if native is None else max(native),
        units=trace.get("units"),
        detected=bool(trace.get("detected")),
        scaled="units" in trace,
        extents=trace.get("extents"),
        sideways=sideways,
    )
    if failure is not None:
        kind, problem, fix = failure
        check = replace(check, kind=kind, problem=problem, fix=fix)
    return check, notes


def _budgeted(check: FileCheck, max_faces: int) -> FileCheck:
    """``check`` under the face budget ``max_faces`` (a verdict may come from a check with
    another budget: a file over this one is refused, whatever it gave then)."""
    if check.faces is not None and check.faces > max_faces and check.kind in ("ok", "faces"):
        problem = _faces_problem(check.faces, max_faces)
        fix = _FACES_FIX.format(n=_round_up(check.faces))
        return replace(check, kind="faces", problem=problem, fix=fix)
    return check


_FACES_FIX = (
    "simplify it in a mesh tool, or pass --max-faces {n} to load it anyway (minutes and "
    "gigabytes for millions of faces)"
)


def _faces_problem(faces: int, max_faces: int) -> str:
    return f"{faces:,} faces, over the face budget of {max_faces:,}"


def _round_up(n: int) -> int:
    """``n`` rounded up to two significant digits: a budget to suggest."""
    step = 10 ** max(0, len(str(n)) - 2)
    return -(-n // step) * step


def _what(e: Exception, path: str) -> str:
    """What an error says is wrong, without the file's path in front and the advice after
    (the library's messages are ``<path>: <what>; <advice>``, the advice in Python terms)."""
    text = str(e)
    if text.startswith(f"{path}: "):
        text = text[len(path) + 2 :]
    return text.split("; ", 1)[0]


def _repair_fix(mode: str) -> str:
    if mode in ("none", "basic"):
        return "--repair solid (a watertight rebuild) or --repair voxel"
    if mode == "solid":
        return "--repair voxel (a voxel remesh, which also closes single sheets)"
    return "--repair solid, or close it in a mesh tool"


def _diagnose(
    e: MeshError, path: str, trace: dict[str, Any], opts: LoadOptions, max_faces: int
) -> tuple[str, str, str]:
    """(kind, what is wrong, the CLI flags that fix it) of a file that failed to load."""
    stage = trace.get("stage", "read")
    if isinstance(e, TooManyFacesError):
        faces = int(trace.get("faces") or 0)
        return "faces", _faces_problem(faces, max_faces), _FACES_FIX.format(n=_round_up(faces))
    if stage == "read":
        what = _what(e, path)
        if isinstance(e, EmptyMeshError):
            what = "the file has no faces (it is no mesh: a text file or a point cloud?)"
        fix = "re-export or replace the file"
        if what.startswith("cannot read"):
            fix = "make it readable (check its permissions)"
        return "read", what, fix
    if stage == "repair":
        return (
            "repair",
            f"the mesh is open or not a solid and --repair {opts.repair} cannot close it: "
            f"{_what(e, path)}",
            f"pass {_repair_fix(opts.repair)}",
        )
    return "size", _size_problem(trace), _size_fix(trace)


def _size_problem(trace: dict[str, Any]) -> str:
    native = trace.get("native_extents")
    if trace.get("stage") == "scale" or trace.get("extents") is None:
        largest = max(native) if native else float("nan")
        return (
            f"its largest extent, {largest:.4g} file units, is no tabletop object in metres, "
            f"centimetres or millimetres (each reading is outside {_length(MIN_EXTENT)} to "
            f"{_length(MAX_DIAGONAL)})"
        )
    ext = trace["extents"]
    unit, per = ("cm", 100.0) if max(ext) < 1 else ("m", 1.0)
    dims = " x ".join(f"{e * per:.3g}" for e in ext) + f" {unit}"
    units = trace.get("units")
    how = (
        "at --size"
        if units is None
        else f"read as {units}" + (" (detected)" if trace.get("detected") else "")
    )
    largest, diagonal = max(ext), float(np.linalg.norm(ext))
    if largest < MIN_EXTENT:
        why = f"under the {_length(MIN_EXTENT)} minimum, too small to see or grasp"
    else:
        why = f"its diagonal {_length(diagonal)} is over the {_length(MAX_DIAGONAL)} table depth"
    return f"it loads at {dims} ({how}): {why}"


def _size_fix(trace: dict[str, Any]) -> str:
    native = trace.get("native_extents")
    hints = []
    for u in (*DETECTED_UNITS, "in"):
        if native is None or u == trace.get("units"):
            continue
        ext = np.asarray(native) * UNITS[u]
        if max(ext) >= MIN_EXTENT and np.linalg.norm(ext) <= MAX_DIAGONAL:
            hints.append(f"--units {u} makes it {_length(max(ext))}")
    hint = f" ({'; '.join(hints)})" if hints else ""
    return (
        f"pass {UNITS_FLAG} for the files' units{hint} or {SIZE_FLAG} for its largest "
        f"extent in metres"
    )


# -- what the CLI does --------------------------------------------------------------------
def vet(
    dataset: Dataset,
    skip_bad: bool = False,
    workers: int | None = 1,
    table: bool = False,
    paths: Iterable[str] | None = None,
    out: TextIO | None = None,
    err: TextIO | None = None,
) -> Dataset:
    """Check ``dataset`` (:func:`check_dataset`) as a command starts: print the per-file
    report to ``out`` when ``table`` (of ``paths``, default every file), warn about files
    near the size limits (one :class:`SizeWarning` each: every one with ``table``, else up
    to :data:`NEAR_LINES`), and then either return the dataset (no bad file), return it
    with the bad files :attr:`~beo_bench.objects.datasets.dataset.Dataset.skipped` (``skip_bad``,
    one :class:`SkippedFileWarning` each), or print one ``beo-bench: error:`` line per bad
    file to ``err`` and raise :class:`~beo_bench.errors.BadObjectsError`."""
    out = sys.stdout if out is None else out
    err = sys.stderr if err is None else err
    check = check_dataset(dataset, workers, progress=True)
    if table:
        print(check.table(paths), file=out)
    near = check.near_limit()
    shown = near if table else near[:NEAR_LINES]
    for f, why in shown:
        warnings.warn(f"{check.where(f)}: {why}", SizeWarning, stacklevel=2)
    if len(near) > len(shown):
        warnings.warn(
            f"{len(near) - len(shown)} more files of {check.root} load near the size limits: "
            f"`beo-bench objects --objects {check.root} --split all` lists them",
            SizeWarning,
            stacklevel=2,
        )
    if dataset.layout_spec.axes_option:  # (ShapeNet's and ModelNet's axes are known)
        for f, why in check.sideways():
            warnings.warn(f"{check.where(f)}: {why}", SidewaysWarning, stacklevel=2)
    bad = check.bad
    if not bad:
        return dataset
    if not skip_bad:
        for f in bad:
            print(f"beo-bench: error: {check.line(f)}", file=err)
        raise BadObjectsError(check.summary())
    if len(bad) == len(check.files):
        raise BadObjectsError(
            f"every one of the {len(bad)} files of {check.root} is bad (see above), so "
            f"--skip-bad leaves nothing to run on: fix them as each line says"
        )
    for f in bad:
        warnings.warn(check.skip_line(f), SkippedFileWarning, stacklevel=2)
    skipped = tuple((f.path, f.problem or "") for f in bad)
    return replace(dataset, skipped=skipped)


def skipped_text(dataset: Dataset | None) -> str:
    """The lines a command's summary ends with when ``--skip-bad`` left files out ('' when
    none were)."""
    if dataset is None or not dataset.skipped:
        return ""
    lines = [f"skipped {len(dataset.skipped)} bad files of {dataset.root} (--skip-bad):"]
    lines += [f"  {rel}: {why}" for rel, why in dataset.skipped]
    return "\n".join(lines)
