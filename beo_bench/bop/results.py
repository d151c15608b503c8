"""BOP results CSVs: the pose estimates a method submits to the BOP Challenge.

The format is the BOP Challenge's (``bop.felk.cvut.cz/challenges``, "Format of results",
since 2019; the toolkit's ``inout.load_bop_results`` / ``save_bop_results``): a header line
``scene_id,im_id,obj_id,score,R,t,time``, then one estimate a line:

- ``scene_id``, ``im_id``, ``obj_id``: the image (scene and image ids) and the object;
- ``score``: the confidence of the estimate;
- ``R``: the 3x3 rotation from the model to the camera frame, 9 numbers saved row-wise,
  separated by spaces;
- ``t``: the 3x1 translation, 3 numbers in mm separated by spaces;
- ``time``: the seconds the method took for the whole image, the same for every estimate
  of one image; ``-1`` when unknown.

The file is read as a stream, a line at a time, and refused at its first bad line (nothing
after it is read). Its documented limits: a line of at most :data:`MAX_LINE_CHARS`
characters, at most :data:`MAX_ESTIMATES` estimates, a time of -1 or within
[:data:`MIN_TIME_S`, :data:`MAX_TIME_S`] seconds, each entry of ``t`` within
:data:`MAX_T_MM` mm. ``R`` within :data:`ROTATION_TOL` of a rotation is accepted as
written; it is scored as its nearest rotation (:func:`nearest_rotation`).

Several estimates of one object in one image are legal (an image may show several
instances of it). :func:`read_results` checks each line and raises
:class:`~beo_bench.errors.BopFormatError` with the file and line number for anything that
breaks the format or cannot be scored.
"""

from __future__ import annotations

import csv
import hashlib
import io
import math
from collections.abc import Collection, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from beo_bench.atomic import atomic_write_bytes
from beo_bench.bop.store import ForeignOutputError
from beo_bench.errors import BopFormatError
from beo_bench.types import Mat3, Vec3

__all__ = [
    "HEADER",
    "MAX_ESTIMATES",
    "MAX_LINE_CHARS",
    "MAX_TIME_S",
    "MAX_T_MM",
    "MIN_TIME_S",
    "ROTATION_TOL",
    "TIME_TOL",
    "BopEstimate",
    "nearest_rotation",
    "read_results",
    "write_results",
]

HEADER = "scene_id,im_id,obj_id,score,R,t,time"
"""The first line of a BOP results CSV."""
ROTATION_TOL = 1e-3
"""How far ``R`` may be from a rotation: every entry of ``R R^T - I`` and ``det R - 1``
within this."""
TIME_TOL = 1e-3
"""How far (s) the times of one image's estimates may differ (the toolkit's
``check_consistent_timings``)."""
MIN_TIME_S = 1e-9
"""The shortest time (s) an image may take; -1 says unknown (0 would make its rate
infinite)."""
MAX_TIME_S = 1e6
"""The longest time (s) an image may take (about 11.6 days)."""
MAX_T_MM = 1e9
"""The largest ``|t|`` entry (mm, 1000 km): beyond it the projections overflow."""
MAX_ESTIMATES = 100_000
"""The most estimates a results file may hold (every estimate is kept in memory while the
file is scored: about 0.7 kB each). BOP's matching uses, per image and object, only as many
estimates as there are instances; keep the highest-scored ones."""
MAX_LINE_CHARS = 10_000
"""The longest line (characters) of a results file; a BOP line is about 250."""
_FIELDS = HEADER.split(",")


@dataclass(frozen=True, slots=True)
class BopEstimate:
    """One line of a results CSV: object ``obj_id`` in image ``im_id`` of scene
    ``scene_id`` at pose (``R``, ``t_mm``), model to camera frame."""

    scene_id: int
    im_id: int
    obj_id: int
    score: float
    R: Mat3
    """(3, 3) rotation, model to camera."""
    t_mm: Vec3
    """(3,) translation in mm."""
    time: float = -1.0
    """Seconds for the whole image; -1: unknown."""
    line: int = 0
    """The line of the file it was read from (0: not read from a file)."""


def _fail(path: Path, line: int, what: str) -> BopFormatError:
    return BopFormatError(f"{path}:{line}: {what}")


def _int(path: Path, line: int, name: str, text: str) -> int:
    s = text.strip()
    if not (s.isascii() and s.isdigit()):
        raise _fail(path, line, f"{name} {text!r} is not a non-negative integer")
    return int(s)


def _floats(path: Path, line: int, name: str, text: str, n: int, what: str) -> list[float]:
    parts = text.split()
    if len(parts) != n and n == 1:
        raise _fail(path, line, f"{name} {text.strip()!r} is not a number ({what})")
    if len(parts) != n:
        raise _fail(
            path, line, f"{name} has {len(parts)} numbers, must be {n} ({what}, space-separated)"
        )
    try:
        values = [float(p) for p in parts]
    except ValueError:
        kind = "a number" if n == 1 else f"{n} numbers"
        raise _fail(path, line, f"{name} {text.strip()!r} is not {kind} ({what})") from None
    if not all(math.isfinite(v) for v in values):
        raise _fail(path, line, f"{name} {text.strip()!r} has a NaN or infinite number")
    return values


def _rotation_problem(R: np.ndarray) -> str | None:
    off = float(np.abs(R @ R.T - np.eye(3)).max())
    det = float(np.linalg.det(R))
    if off > ROTATION_TOL:
        return f"|R R^T - I| = {off:.3g} > {ROTATION_TOL:g}"
    if abs(det - 1.0) > ROTATION_TOL:
        return f"det R = {det:.6g}, not +1 within {ROTATION_TOL:g}"
    return None


def nearest_rotation(R: np.ndarray) -> np.ndarray:
    """The rotation nearest to ``R`` in the Frobenius norm (``U V^T`` of its SVD, the last
    column of ``U`` flipped if need be to make the determinant +1): a rotation printed to a
    few decimals, within :data:`ROTATION_TOL`, as the renderer and the metrics take it."""
    M = np.asarray(R, dtype=np.float64).reshape(3, 3)
    U, _, Vt = np.linalg.svd(M)
    if np.linalg.det(U @ Vt) < 0:
        U[:, -1] = -U[:, -1]
    return np.asarray(U @ Vt, dtype=np.float64)


def _lines(f: io.TextIOBase, path: Path, limit: int | None = None) -> Iterator[str]:
    """The lines of ``f``, one at a time, each at most :data:`MAX_LINE_CHARS` long (a
    longer one is refused without reading the rest of it); at most ``limit`` of them."""
    number = 0
    while limit is None or number < limit:
        text = f.readline(MAX_LINE_CHARS + 1)
        if not text:
            return
        number += 1
        if len(text) > MAX_LINE_CHARS and not text.endswith(("\n", "\r")):
            raise _fail(
                path,
                number,
                f"line longer than {MAX_LINE_CHARS} characters (a BOP results line is about "
                "250): is this a results CSV?",
            )
        yield text


HEAD_LINES = 1000
"""How many lines :func:`check_head` reads."""


def check_head(path: Path | str) -> None:
    """Check the first :data:`HEAD_LINES` lines of a results CSV as :func:`read_results`
    does, less what needs the suite (object ids, images): ``score`` calls it before it
    builds the suite's items (seconds), so that a file broken near its top is refused at
    once."""
    path = Path(path)
    try:
        f = path.open(encoding="utf-8-sig", newline="")
    except OSError as e:
        raise BopFormatError(f"{path}: cannot be read as a UTF-8 CSV ({e})") from None
    with f:
        _read(f, path, None, None, "", limit=HEAD_LINES)


def read_results(
    path: Path | str,
    known_obj_ids: Collection[int] | None = None,
    known_images: Collection[tuple[int, int]] | None = None,
    scope: str = "the dataset's test targets",
) -> list[BopEstimate]:
    """The estimates of a BOP results CSV, in file order.

    A :class:`BopFormatError` naming the file and line for: a first line that is not
    :data:`HEADER`; a line without 7 comma-separated fields; an id that is not a
    non-negative integer; a score, ``R``, ``t`` or time that is not a (finite) number, or
    ``R``/``t`` of the wrong count; ``R`` that is not a rotation (:data:`ROTATION_TOL`); a
    ``t`` entry beyond :data:`MAX_T_MM`; a time other than -1 outside [:data:`MIN_TIME_S`,
    :data:`MAX_TIME_S`], or times of one image that differ (:data:`TIME_TOL`, both lines
    named); an ``obj_id`` not in ``known_obj_ids`` or an image (``scene_id``, ``im_id``)
    not in ``known_images`` (when given); a line repeating an earlier one's image, object,
    ``R`` and ``t`` (both lines named); a quoted field left open (named at the line where
    it starts); a line longer than :data:`MAX_LINE_CHARS`; more than :data:`MAX_ESTIMATES`
    estimates. Empty lines are skipped. The file is read a line at a time and the first
    bad line ends the reading: nothing after it is read."""
    path = Path(path)
    try:
        f = path.open(encoding="utf-8-sig", newline="")
    except FileNotFoundError:
        raise BopFormatError(f"{path}: results file missing") from None
    except OSError as e:
        raise BopFormatError(f"{path}: cannot be read as a UTF-8 CSV ({e})") from None
    with f:
        return _read(f, path, known_obj_ids, known_images, scope)


def _read(
    f: io.TextIOBase,
    path: Path,
    known_obj_ids: Collection[int] | None,
    known_images: Collection[tuple[int, int]] | None,
    scope: str,
    limit: int | None = None,
) -> list[BopEstimate]:
    """:func:`read_results` of the open file ``f``, a line at a time (its first ``limit``
    lines)."""
    reader = csv.reader(_lines(f, path, limit), strict=True)
    estimates: list[BopEstimate] = []
    header_seen = False
    seen: dict[bytes, int] = {}
    times: dict[tuple[int, int], tuple[float, int]] = {}
    obj_ids = None if known_obj_ids is None else set(known_obj_ids)
    images = None if known_images is None else set(known_images)
    line = 1
    while True:
        line = reader.line_num + 1  # where the next row starts (a quoted field may run on)
        try:
            row = next(reader, None)
        except csv.Error as err:
            raise _fail(
                path, line, f"not a valid CSV line ({err}){_quote_hint(line, reader, err)}"
            ) from None
        except UnicodeDecodeError as err:
            raise _fail(
                path,
                line,
                f"not UTF-8 text at or soon after this line ({err.reason}): save the CSV as UTF-8",
            ) from None
        except OSError as err:
            raise _fail(path, line, f"cannot be read ({err})") from None
        if row is None:
            break
        if reader.line_num > line:
            raise _fail(
                path,
                line,
                f"a quoted field starts on this line and runs on to line {reader.line_num}: "
                'close its quote (no field of a BOP results line holds a " or a line break)',
            )
        if not row or all(not x.strip() for x in row):
            continue
        if not header_seen:
            if [x.strip() for x in row] != _FIELDS:
                raise _fail(
                    path,
                    line,
                    f"header {','.join(row)!r}: the first line of a BOP results CSV must "
                    f"be {HEADER!r}",
                )
            header_seen = True
            continue
        if len(estimates) >= MAX_ESTIMATES:
            raise _fail(
                path,
                line,
                f"more than {MAX_ESTIMATES} estimates, the most a results file may hold "
                "(docs/bop.md): keep each image's highest-scored estimates of each object",
            )
        e = _estimate(path, line, row, obj_ids, images, scope)
        ids = np.array([e.scene_id, e.im_id, e.obj_id], dtype=np.float64)
        # + 0.0: -0.0 and 0.0 are one number, as they were when the key held floats
        # a 16-byte digest of it keeps the memory of a long file small
        key = hashlib.blake2b(
            (np.concatenate([ids, e.R.reshape(-1), e.t_mm]) + 0.0).tobytes(), digest_size=16
        ).digest()
        if key in seen:
            raise _fail(
                path,
                line,
                f"duplicate of line {seen[key]} (same scene_id, im_id, obj_id, R and t): "
                "remove one of them",
            )
        seen[key] = line
        first = times.setdefault((e.scene_id, e.im_id), (e.time, line))
        if abs(first[0] - e.time) > TIME_TOL:
            raise _fail(
                path,
                line,
                f"time {e.time:g} differs from {first[0]:g} on line {first[1]} for the same "
                f"image (scene_id {e.scene_id}, im_id {e.im_id}): the time is the image's, the "
                "same on each of its lines",
            )
        estimates.append(e)
    if not header_seen:
        raise BopFormatError(f"{path}: empty file; a BOP results CSV starts with {HEADER!r}")
    return estimates


def _quote_hint(line: int, reader: object, err: csv.Error) -> str:
    """What to fix when a CSV error ends a row that began on ``line``."""
    end = getattr(reader, "line_num", line)
    if end > line or "end of data" in str(err):
        return (
            f": a quoted field starts on this line and is not closed (read to line {end}): "
            'close its quote (no field of a BOP results line holds a " or a line break)'
        )
    return ""


def _estimate(
    path: Path,
    line: int,
    row: list[str],
    obj_ids: set[int] | None,
    images: set[tuple[int, int]] | None,
    scope: str,
) -> BopEstimate:
    """The estimate of one line's fields, every field checked."""
    if len(row) != len(_FIELDS):
        raise _fail(
            path,
            line,
            f"{len(row)} comma-separated fields, must be {len(_FIELDS)} ({HEADER})",
        )
    scene_id = _int(path, line, "scene_id", row[0])
    im_id = _int(path, line, "im_id", row[1])
    obj_id = _int(path, line, "obj_id", row[2])
    (score,) = _floats(path, line, "score", row[3], 1, "a confidence")
    R = np.array(_floats(path, line, "R", row[4], 9, "a 3x3 rotation row-wise"))
    t = np.array(_floats(path, line, "t", row[5], 3, "a translation in mm"))
    (time,) = _floats(path, line, "time", row[6], 1, "seconds, or -1 for unknown")
    R = R.reshape(3, 3)
    problem = _rotation_problem(R)
    if problem is not None:
        raise _fail(path, line, f"R is not a rotation matrix: {problem}")
    if np.abs(t).max() > MAX_T_MM:
        raise _fail(
            path, line, f"t {row[5].strip()!r}: each entry must be within +-{MAX_T_MM:g} mm"
        )
    if time != -1 and not MIN_TIME_S <= time <= MAX_TIME_S:
        raise _fail(
            path,
            line,
            f"time {time:g}: must be seconds within [{MIN_TIME_S:g}, {MAX_TIME_S:g}], or -1 "
            "for unknown",
        )
    if obj_ids is not None and obj_id not in obj_ids:
        raise _fail(
            path,
            line,
            f"obj_id {obj_id} is not an object of {scope} (its obj_ids: {_shown(sorted(obj_ids))})",
        )
    if images is not None and (scene_id, im_id) not in images:
        raise _fail(
            path,
            line,
            f"scene_id {scene_id}, im_id {im_id} is not an image of {scope}",
        )
    return BopEstimate(scene_id, im_id, obj_id, score, R, t, time=time, line=line)


def _shown(ids: list[int]) -> str:
    return ", ".join(map(str, ids[:5])) + (", ..." if len(ids) > 5 else "")


def _number(x: float) -> str:
    """The shortest text that reads back as the same float."""
    return repr(float(x))


def write_results(
    path: Path | str, estimates: Iterable[BopEstimate], *, overwrite: bool = False
) -> None:
    """Write ``estimates`` as a BOP results CSV (atomically), in the order given; every
    number printed so that it reads back exactly. A ValueError for an estimate that
    :func:`read_results` would refuse (non-finite numbers, ``R`` not a rotation, a time
    other than -1 outside [:data:`MIN_TIME_S`, :data:`MAX_TIME_S`], ``t`` beyond
    :data:`MAX_T_MM`). An existing file is replaced only with ``overwrite``
    (pass it only for a file beo-bench wrote); otherwise :class:`ForeignOutputError`."""
    path = Path(path)
    if not overwrite and (path.exists() or path.is_symlink()):
        raise ForeignOutputError(
            f"{path} exists: choose a new file name for the results (an existing file is "
            "replaced only when beo-bench wrote it)"
        )
    path.parent.mkdir(parents=True, exist_ok=True)  # a new folder for the results is fine
    lines = [HEADER]
    for e in estimates:
        R = np.asarray(e.R, dtype=np.float64)
        t = np.asarray(e.t_mm, dtype=np.float64).reshape(-1)
        if R.shape != (3, 3) or t.shape != (3,):
            raise ValueError(f"estimate {e.scene_id}/{e.im_id}/{e.obj_id}: R (3, 3), t (3,)")
        values = [e.score, e.time, *R.reshape(-1), *t]
        if not all(math.isfinite(float(v)) for v in values):
            raise ValueError(f"estimate {e.scene_id}/{e.im_id}/{e.obj_id}: non-finite number")
        problem = _rotation_problem(R)
        if problem is not None:
            raise ValueError(f"estimate {e.scene_id}/{e.im_id}/{e.obj_id}: R: {problem}")
        if e.time != -1 and not MIN_TIME_S <= e.time <= MAX_TIME_S:
            raise ValueError(f"estimate {e.scene_id}/{e.im_id}/{e.obj_id}: time {e.time}")
        if np.abs(t).max() > MAX_T_MM:
            raise ValueError(f"estimate {e.scene_id}/{e.im_id}/{e.obj_id}: |t| > {MAX_T_MM:g}")
        ids = [int(e.scene_id), int(e.im_id), int(e.obj_id)]
        if min(ids) < 0:
            raise ValueError(f"estimate {ids}: ids must be non-negative")
        lines.append(
            ",".join(
                [
                    *map(str, ids),
                    _number(e.score),
                    " ".join(_number(x) for x in R.reshape(-1)),
                    " ".join(_number(x) for x in t),
                    _number(e.time),
                ]
            )
        )
    atomic_write_bytes(path, "\n".join(lines) + "\n")
