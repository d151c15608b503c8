"""BOP results CSVs (beo_bench.bop.results): the BOP Challenge format read and written, and a
BopFormatError naming the file and line for each kind of bad input."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from beo_bench.bop import files as bf
from beo_bench.bop.results import HEADER, BopEstimate, read_results, write_results
from beo_bench.errors import BopFormatError
from beo_bench.geometry import axis_angle

R0 = axis_angle([0.3, -0.2, 0.9], 1.1)
R1 = axis_angle([1.0, 0.0, 0.0], -0.4)


def _row(
    scene: object = 1,
    im: int = 0,
    obj: int = 5,
    score: str = "0.9",
    R: np.ndarray = R0,
    t: str = "10 -20 500.5",
    time: str = "0.25",
) -> str:
    return (
        f"{scene},{im},{obj},{score},{' '.join(repr(float(x)) for x in R.reshape(-1))},{t},{time}"
    )


def _csv(tmp_path: Path, *lines: str) -> Path:
    path = tmp_path / "method_dataset-test.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_two_instances_of_one_object_read_back(tmp_path: Path) -> None:
    path = _csv(tmp_path, HEADER, _row(), "  ", _row(R=R1, t="1 2 3"), _row(im=1, time="-1"))
    est = read_results(path, known_obj_ids={5}, known_images={(1, 0), (1, 1)})
    assert [e.line for e in est] == [2, 4, 5]  # the blank line 3 is skipped
    a, b, c = est
    assert (a.scene_id, a.im_id, a.obj_id, b.obj_id) == (1, 0, 5, 5)
    assert a.score == 0.9 and a.time == 0.25 and c.time == -1.0
    np.testing.assert_array_equal(a.R, R0)  # row-wise, exact
    np.testing.assert_array_equal(b.R, R1)
    np.testing.assert_array_equal(a.t_mm, [10.0, -20.0, 500.5])
    assert a.R.dtype == np.float64 and a.t_mm.shape == (3,)


def test_write_then_read_is_exact(tmp_path: Path) -> None:
    est = [
        BopEstimate(2, 7, 1, 0.123456789, R0, np.array([1e-3, -250.125, 812.0]), time=0.5),
        BopEstimate(2, 7, 1, 0.5, R1, np.array([0.1, 0.2, 0.3]), time=0.5),
        BopEstimate(3, 0, 4, 1.0, np.eye(3), np.zeros(3)),
    ]
    path = tmp_path / "r.csv"
    write_results(path, est)
    text = path.read_text()
    assert text.splitlines()[0] == HEADER and text.endswith("\n")
    assert text.splitlines()[3] == "3,0,4,1.0,1.0 0.0 0.0 0.0 1.0 0.0 0.0 0.0 1.0,0.0 0.0 0.0,-1.0"
    back = read_results(path)
    for e, b in zip(est, back, strict=True):
        assert (b.scene_id, b.im_id, b.obj_id, b.score, b.time) == (
            e.scene_id,
            e.im_id,
            e.obj_id,
            e.score,
            e.time,
        )
        np.testing.assert_array_equal(b.R, e.R)
        np.testing.assert_array_equal(b.t_mm, e.t_mm)
    with pytest.raises(bf.ForeignOutputError, match="exists"):
        write_results(path, est)
    write_results(path, est[:1], overwrite=True)
    assert len(read_results(path)) == 1
    assert not list(tmp_path.glob(".*.tmp"))


def test_write_refuses_bad_estimates(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="non-finite"):
        write_results(tmp_path / "a.csv", [BopEstimate(0, 0, 1, np.nan, R0, np.zeros(3))])
    with pytest.raises(ValueError, match="R:"):
        write_results(tmp_path / "b.csv", [BopEstimate(0, 0, 1, 1.0, 2 * R0, np.zeros(3))])
    assert not list(tmp_path.iterdir())


NOT_ROTATION = np.diag([1.0, 1.0, 1.01])
REFLECTION = np.diag([1.0, 1.0, -1.0])

BAD = {
    # name: (lines after the header, the bad line's number, what the message says)
    "header": (None, 1, r"must be 'scene_id,im_id,obj_id,score,R,t,time'"),
    "field count": ([_row(), "", _row() + ",7"], 4, r"8 comma-separated fields, must be 7"),
    "missing field": ([_row().rsplit(",", 1)[0]], 2, r"6 comma-separated fields"),
    "scene_id text": ([_row(), _row(scene="one")], 3, r"scene_id 'one' is not a non-neg"),
    "negative obj_id": ([_row(obj=-2)], 2, r"obj_id '-2' is not a non-negative integer"),
    "score text": ([_row(score="high")], 2, r"score 'high' is not a number"),
    "R count": ([_row(R=np.eye(3)).replace("1.0,10", "1.0 4.0,10")], 2, r"R has 10 numbers"),
    "t text": ([_row(t="1 2 x")], 2, r"t '1 2 x' is not 3 numbers"),
    "t count": ([_row(t="1 2")], 2, r"t has 2 numbers, must be 3"),
    "nan": ([_row(), _row(t="1 nan 3")], 3, r"NaN or infinite"),
    "inf score": ([_row(score="inf")], 2, r"NaN or infinite"),
    "not orthonormal": (
        [_row(R=NOT_ROTATION)],
        2,
        r"not a rotation matrix: \|R R\^T - I\| = "
        r"0\.0201 > 0\.001",
    ),
    "reflection": ([_row(R=REFLECTION)], 2, r"det R = -1, not \+1 within 0\.001"),
    "negative time": ([_row(time="-2")], 2, r"time -2: must be seconds >= 0, or -1"),
    "time differs": (
        [_row(), _row(R=R1, time="0.5")],
        3,
        r"time 0\.5 differs from 0\.25 on "
        r"line 2",
    ),
    "unknown obj_id": ([_row(), _row(obj=9)], 3, r"obj_id 9 is not an object of the dataset"),
    "unknown image": ([_row(), _row(im=3)], 3, r"scene_id 1, im_id 3 is not an image"),
    "duplicate": ([_row(), _row(R=R1), "", _row(score="0.1")], 5, r"duplicate of line 2"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_names_the_line(tmp_path: Path, case: str) -> None:
    rows, line, message = BAD[case]
    lines = ["scene_id,im_id,obj_id,score,R,t", _row()] if rows is None else [HEADER, *rows]
    path = _csv(tmp_path, *lines)
    with pytest.raises(BopFormatError) as info:
        read_results(path, known_obj_ids={5}, known_images={(1, 0)})
    msg = str(info.value)
    assert msg.startswith(f"{path}:{line}: "), msg
    assert re.search(message, msg), msg
    assert "\n" not in msg


def test_empty_and_missing_files(tmp_path: Path) -> None:
    with pytest.raises(BopFormatError, match="empty file"):
        read_results(_csv(tmp_path, "", ""))
    with pytest.raises(BopFormatError, match="results file missing"):
        read_results(tmp_path / "none.csv")


def test_header_only_and_crlf(tmp_path: Path) -> None:
    assert read_results(_csv(tmp_path, HEADER)) == []
    path = tmp_path / "crlf.csv"
    path.write_bytes(("\ufeff" + HEADER + "\r\n" + _row() + "\r\n").encode())
    (e,) = read_results(path)
    assert e.line == 2


def test_rotation_tolerance(tmp_path: Path) -> None:
    # R printed with 5 decimals is off by ~1e-5: within the tolerance of 1e-3
    rounded = " ".join(f"{x:.5f}" for x in R0.reshape(-1))
    row = _row().split(",")
    row[4] = rounded
    (e,) = read_results(_csv(tmp_path, HEADER, ",".join(row)))
    np.testing.assert_allclose(e.R, R0, atol=1e-5)
    with pytest.raises(BopFormatError, match=r":2: R is not a rotation"):
        read_results(_csv(tmp_path, HEADER, _row(R=np.diag([1.0, 1.0, 1.002]))))
