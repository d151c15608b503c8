"""``beo-bench export`` against the attacks of issue 50 (7 to 10): a symbolic link in an
earlier export is never written through; a re-export removes the earlier export's stale
files and only those (never a file the user put or changed there); two exports into one
folder cannot run at once; ``--withhold-gt`` ships no test poses, and ``beo-bench score``
still scores against the truth."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from beo_bench.bench.bopscore import score_results
from beo_bench.bench.export import export_bop, image_of, object_ids, open_items
from beo_bench.bench.suites import get_suite
from beo_bench.bop.files import read_models_info
from beo_bench.bop.results import BopEstimate, write_results
from beo_bench.bop.scenes import read_scene
from beo_bench.cli import main


def export(out: Path, n: int, train: int = 0, *extra: str) -> int:
    args = ["export", "--suite", "pose-3dof", "--episodes", str(n), "--train-items", str(train)]
    return main([*args, *extra, str(out)])


def one_error_line(capsys) -> str:
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("beo-bench:")]
    assert len(err) == 1, err
    assert err[0].startswith("beo-bench: error:")
    return err[0]


def tree(d: Path) -> dict[str, bytes]:
    """Every file under ``d`` (links not followed) with its content."""
    out = {}
    for p in sorted(d.rglob("*")):
        if p.is_symlink():
            out[str(p.relative_to(d))] = f"-> {os.readlink(p)}".encode()
        elif p.is_file():
            out[str(p.relative_to(d))] = p.read_bytes()
    return out


# -- 7. never through a link ---------------------------------------------------------------------
@pytest.mark.parametrize("link", ["models", "test/000000/rgb"])
def test_an_export_never_writes_through_a_link(tmp_path, capsys, link) -> None:
    out, user = tmp_path / "bop", tmp_path / "user"
    assert export(out, 2) == 0
    user.mkdir()
    (user / "models_info.json").write_text('{"mine": 1}\n')
    (user / "000000.png").write_bytes(b"my picture")
    target = out / link
    for p in sorted(target.rglob("*"), reverse=True):
        p.unlink() if p.is_file() else p.rmdir()
    target.rmdir()
    target.symlink_to(user)
    before = tree(user), tree(out)
    capsys.readouterr()
    assert export(out, 2) == 2
    line = one_error_line(capsys)
    assert str(target) in line and "symbolic link" in line
    assert (tree(user), tree(out)) == before  # nothing written there, nor anywhere


# -- 8. a re-export replaces its own files only ------------------------------------------------
def test_a_reexport_removes_its_stale_files_and_keeps_the_users(tmp_path, capsys) -> None:
    out = tmp_path / "bop"
    assert export(out, 3, 2) == 0
    (out / "models" / "notes.txt").write_text("my notes\n")
    (out / "test" / "000000" / "rgb" / "mine.png").write_bytes(b"mine")
    assert export(out, 1, 0) == 0
    assert not (out / "train").exists()
    scene = out / "test" / "000000"
    for sub in ("rgb", "depth"):
        names = sorted(p.name for p in (scene / sub).iterdir())
        assert names == (["000000.png", "mine.png"] if sub == "rgb" else ["000000.png"])
    for sub in ("mask", "mask_visib"):
        assert sorted(p.name for p in (scene / sub).iterdir()) == ["000000_000000.png"]
    plys = sorted(p.name for p in (out / "models").glob("*.ply"))
    assert plys == [f"obj_{i:06d}.ply" for i in sorted(read_models_info(out))] == ["obj_000001.ply"]
    assert (out / "models" / "notes.txt").read_text() == "my notes\n"
    assert (scene / "rgb" / "mine.png").read_bytes() == b"mine"
    assert "removed" in capsys.readouterr().out


def test_a_reexport_after_a_killed_export_removes_what_that_one_wrote(
    tmp_path, monkeypatch
) -> None:
    from beo_bench.bop import scenes

    out = tmp_path / "bop"
    assert export(out, 1) == 0
    real = scenes.SceneWriter.add_image

    def dies_at_the_third(self, im_id, **kw):
        if im_id == 2:
            raise KeyboardInterrupt
        real(self, im_id, **kw)

    monkeypatch.setattr(scenes.SceneWriter, "add_image", dies_at_the_third)
    with pytest.raises(KeyboardInterrupt):
        export_bop(get_suite("pose-3dof").with_overrides(size=4), out)
    assert (out / "test" / "000000" / "rgb" / "000001.png").exists()
    monkeypatch.setattr(scenes.SceneWriter, "add_image", real)
    assert export(out, 1) == 0
    assert sorted(p.name for p in (out / "test" / "000000" / "rgb").iterdir()) == ["000000.png"]


def test_a_reexport_never_overwrites_a_file_the_user_changed(tmp_path, capsys) -> None:
    out = tmp_path / "bop"
    assert export(out, 1) == 0
    info = out / "models" / "models_info.json"
    info.write_text('{"edited": true}\n')
    before = tree(out)
    capsys.readouterr()
    assert export(out, 1) == 2
    line = one_error_line(capsys)
    assert str(info) in line and "changed" in line
    assert tree(out) == before


def test_an_export_of_an_older_version_without_a_ledger_is_refused(tmp_path, capsys) -> None:
    out = tmp_path / "bop"
    assert export(out, 1) == 0
    (out / ".beo_bench_bop_files").unlink()
    before = tree(out)
    capsys.readouterr()
    assert export(out, 1) == 2
    assert str(out) in one_error_line(capsys)
    assert tree(out) == before


# -- 9. one writer ------------------------------------------------------------------------------
HOLD = """
import fcntl, os, sys, time
fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT, 0o644)
fcntl.flock(fd, fcntl.LOCK_EX)
os.pwrite(fd, f"{os.getpid()}\\n".encode(), 0)
print("held", flush=True)
time.sleep(60)
"""


def test_a_second_export_into_a_folder_in_use_is_refused(tmp_path, capsys) -> None:
    out = tmp_path / "bop"
    assert export(out, 1) == 0
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(out / ".beo_bench_bop.lock")],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        before = tree(out)
        capsys.readouterr()
        t0 = time.monotonic()
        assert export(out, 2, 0, "--sensor", "kinect-v1") == 1
        assert time.monotonic() - t0 < 30  # refused at once, not waiting
        line = one_error_line(capsys)
        assert f"PID {holder.pid}" in line and str(out) in line
        assert tree(out) == before
    finally:
        holder.kill()
        holder.wait()
    assert export(out, 1) == 0  # the holder gone, its lock is gone with it


# -- 10. withheld ground truth --------------------------------------------------------------------
def test_withhold_gt_ships_no_test_poses_and_score_still_scores(tmp_path, capsys) -> None:
    out = tmp_path / "bop"
    assert export(out, 3, 1, "--withhold-gt") == 0
    assert "withheld" in capsys.readouterr().out
    test_files = {p.name for p in (out / "test").rglob("*")}
    assert not {"scene_gt.json", "scene_gt_info.json", "mask", "mask_visib"} & test_files
    assert b"cam_R_m2c" not in b"".join(p.read_bytes() for p in (out / "test").rglob("*.json"))
    assert (out / "train" / "000000" / "scene_gt.json").is_file()  # training keeps its truth
    assert json.loads((out / "beo_bench_export.json").read_text())["withhold_gt"] is True
    scene = read_scene(out, "test", 0, require_gt=False)
    assert sorted(scene.images) == [0, 1, 2] and all(not im.gt for im in scene.images.values())

    # a results file of the true poses (from the suite, not the export) still scores perfectly
    suite = get_suite("pose-3dof").with_overrides(size=3)
    ids = object_ids(suite)
    items = open_items(suite)
    ests = []
    try:
        for i in range(3):
            gt = items.isolated_truth(i)
            sid, im = image_of(i)
            t_mm = np.asarray(gt.t_cam) * 1000.0
            ests.append(BopEstimate(sid, im, ids.ids[gt.key], 1.0, np.asarray(gt.R_cam), t_mm))
    finally:
        items.close()
    csv = tmp_path / "truth_beo-test.csv"
    write_results(csv, ests)
    summary = score_results(suite, csv, tmp_path / "run").to_json()
    assert summary["n"] == 3 and summary["metrics"]["ar_bop"] == 1.0
