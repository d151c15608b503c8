"""The check of a user's dataset before a command uses it (``beo_bench.objects.datasets.checks``):
each bad file is one line with its path, what is wrong and the CLI flag that fixes it;
``--skip-bad`` runs on the rest; sizes near the limits are flagged; links out of the root
are never followed; the scan and the faces are bounded; the cache is checked as a command
starts; and user-data errors are never reported as a bug in beo-bench."""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh

from beo_bench import cli
from beo_bench.cli import main
from beo_bench.errors import (
    BadObjectsError,
    CacheDirError,
    DatasetLayoutError,
    DatasetTooLargeError,
    EmptyMeshError,
    TooManyFacesError,
)
from beo_bench.objects import cache
from beo_bench.objects.datasets import (
    SizeWarning,
    check_dataset,
    checks,
    load,
    open_dataset,
    vet,
    walk,
)
from beo_bench.objects.datasets.meshfile import count_faces, read_mesh


@pytest.fixture(autouse=True)
def own_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A fresh cache per test: the checks' verdicts are cached, and a test must build."""
    root = tmp_path / "cache"
    monkeypatch.setenv(cache.CACHE_ENV, str(root))
    return root


def _sheet(extent: float = 0.2) -> trimesh.Trimesh:
    """A single open sheet: what ``--repair solid`` cannot close and ``voxel`` can."""
    v = [[0, 0, 0], [extent, 0, 0], [extent, 0.75 * extent, 0], [0, 0.75 * extent, 0]]
    return trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]])


def make_folder(root: Path, *, junk: bool = False, sheet: bool = False, ball: float = 0.1) -> Path:
    """Boxes of 10 cm (metres), a ball of largest extent ``ball`` file units, and the bad
    files asked for: a text file named ``.obj`` and an open sheet."""
    (root / "block").mkdir(parents=True)
    (root / "ball").mkdir()
    for i in range(2):
        trimesh.creation.box(extents=(0.1, 0.06 + 0.01 * i, 0.04)).export(root / f"block/b{i}.stl")
    trimesh.creation.icosphere(1, radius=ball / 2).export(root / "ball" / "ball.obj")
    if junk:
        (root / "junk").mkdir()
        (root / "junk" / "notes.obj").write_text("my notes on the meshes\nnot a mesh at all\n")
        trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(root / "junk" / "ok.obj")
    if sheet:
        (root / "paper").mkdir()
        _sheet().export(root / "paper" / "sheet.obj")
        trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(root / "paper" / "ok.obj")
    return root


def _errors(err: str) -> list[str]:
    assert "Traceback" not in err and "bug in beo-bench" not in err, err
    return [ln for ln in err.splitlines() if ln.startswith("beo-bench: error: ")]


# -- bad files: one line each, with the fixing flag -----------------------------------------
def test_a_text_file_named_obj_is_one_line_with_its_fix(tmp_path, capsys) -> None:
    root = make_folder(tmp_path / "data", junk=True)
    out = tmp_path / "run"
    argv = ["run", "--suite", "pose-1dof", "--backend", "oracle", "--objects", str(root)]
    assert main([*argv, "--split", "all", "--out", str(out)]) == 2
    lines = _errors(capsys.readouterr().err)
    bad = f"beo-bench: error: {root / 'junk' / 'notes.obj'}: the file has no faces"
    assert len(lines) == 2 and lines[0].startswith(bad), lines
    assert lines[0].endswith("re-export or replace the file, or pass --skip-bad to run without it")
    assert "1 of 5 files" in lines[1] and "--skip-bad to run on the other 4" in lines[1]
    assert not out.exists()  # refused before the run's first item (and its directory)


def test_an_open_mesh_names_repair_voxel_which_fixes_it(tmp_path, capsys) -> None:
    root = make_folder(tmp_path / "data", sheet=True)
    with pytest.raises(BadObjectsError):
        vet(open_dataset(root), workers=1)
    (line,) = _errors(capsys.readouterr().err)[:1]
    assert line.startswith(f"beo-bench: error: {root / 'paper' / 'sheet.obj'}: the mesh is open")
    assert "--repair solid cannot close it" in line and "pass --repair voxel" in line
    assert "repair=" not in line  # CLI syntax, never the Python option
    voxel = check_dataset(open_dataset(root, repair="voxel"))
    assert voxel.bad == () and len(voxel.files) == 5


def test_each_kind_of_bad_file_says_what_and_which_flag(tmp_path) -> None:
    root = tmp_path / "data"
    (root / "thing").mkdir(parents=True)
    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(root / "thing" / "good.stl")
    trimesh.creation.box(extents=(68.0, 50.0, 40.0)).export(root / "thing" / "huge.stl")
    (root / "thing" / "cut.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2")
    (root / "thing" / "binary.obj").write_bytes(bytes(range(256)) * 4)
    check = check_dataset(open_dataset(root, units="m"))
    got = {f.path: (f.kind, f.problem, f.fix) for f in check.bad}
    assert set(got) == {"thing/binary.obj", "thing/cut.obj", "thing/huge.stl"}
    assert got["thing/cut.obj"][:2] == ("read", got["thing/cut.obj"][1])
    assert "truncated" in str(got["thing/cut.obj"][1])
    assert "not a text .obj file" in str(got["thing/binary.obj"][1])
    kind, problem, fix = got["thing/huge.stl"]
    assert kind == "size" and "it loads at 68 x 50 x 40 m (read as m)" in str(problem)
    assert "--units mm makes it 6.8 cm" in str(fix) and "--size M" in str(fix)
    # the line a user sees: path, what, the flags (and --skip-bad), in CLI syntax
    line = check.line(next(f for f in check.bad if f.path == "thing/huge.stl"))
    assert line.startswith(f"{root / 'thing' / 'huge.stl'}: it loads at")
    assert line.endswith("or pass --skip-bad to run without it") and "units=" not in line


def test_an_unreadable_file_says_make_it_readable(tmp_path, monkeypatch) -> None:
    root = make_folder(tmp_path / "data")
    target = root / "ball" / "ball.obj"
    real = Path.read_bytes

    def refuse(self: Path) -> bytes:  # as chmod 000 would for anyone but root
        if self == target:
            raise PermissionError(errno.EACCES, "Permission denied", str(self))
        return real(self)

    monkeypatch.setattr(Path, "read_bytes", refuse)
    (bad,) = check_dataset(open_dataset(root)).bad
    assert bad.path == "ball/ball.obj" and "cannot read the file" in str(bad.problem)
    assert bad.fix == "make it readable (check its permissions)"


# -- --skip-bad ---------------------------------------------------------------------------------
def test_skip_bad_leaves_them_out_and_names_them(tmp_path, capsys) -> None:
    root = make_folder(tmp_path / "data", junk=True, sheet=True)
    d = open_dataset(root)
    with pytest.warns(checks.SkippedFileWarning) as caught:
        kept = vet(d, skip_bad=True, workers=1)
    said = [str(w.message) for w in caught]
    assert said[0].startswith(f"skipping {root / 'junk' / 'notes.obj'} (--skip-bad): the file")
    assert "to use it, pass --repair voxel" in said[1]
    assert [p for p, _ in kept.skipped] == ["junk/notes.obj", "paper/sheet.obj"]
    everything = kept.objects("all")
    assert len(everything) == 5 and "paper/sheet.obj" not in {
        i.path.relative_to(root).as_posix() for i in everything if i.path
    }
    # another set of objects is another dataset: never one run directory or model
    assert kept.short != d.short and kept.identity()["skipped"] == [p for p, _ in kept.skipped]
    assert "skipped" not in d.identity() and "units" not in d.identity()
    assert "--skip-bad" in checks.skipped_text(kept) and "junk/notes.obj: the file" in (
        checks.skipped_text(kept)
    )


def test_skip_bad_refuses_a_dataset_of_only_bad_files(tmp_path) -> None:
    root = tmp_path / "data"
    (root / "junk").mkdir(parents=True)
    (root / "junk" / "a.obj").write_text("nothing\n")
    with pytest.raises(BadObjectsError, match="leaves nothing"):
        vet(open_dataset(root), skip_bad=True)


@pytest.mark.slow
def test_run_with_skip_bad_runs_the_rest_and_its_summary_lists_them(tmp_path, capsys) -> None:
    root = make_folder(tmp_path / "data", junk=True)
    out = tmp_path / "run"
    argv = ["run", "--suite", "pose-1dof", "--backend", "oracle", "--objects", str(root)]
    argv += ["--split", "all", "--skip-bad", "--episodes", "3", "--workers", "1"]
    assert main([*argv, "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "skipped 1 bad files" in captured.out and "junk/notes.obj: the file" in captured.out
    summary = json.loads((out / "summary.json").read_text())
    skipped = summary["provenance"]["dataset_skipped"]
    assert [s["path"] for s in skipped] == ["junk/notes.obj"]
    assert "no faces" in skipped[0]["why"] and summary["n"] == 3
    assert summary["provenance"]["suite"]["dataset"]["skipped"] == ["junk/notes.obj"]


# -- units and sizes ------------------------------------------------------------------------
def test_a_mis_scaled_mesh_is_flagged_and_size_or_units_fix_it(tmp_path) -> None:
    root = make_folder(tmp_path / "data", ball=1.0)  # a soccer ball of extent 1.0: "1 cm"
    trimesh.creation.box(extents=(2.0, 1.5, 1.0)).export(root / "block" / "inch.stl")
    with pytest.warns(SizeWarning) as caught:
        vet(open_dataset(root), workers=1)
    said = {str(w.message).split(":")[0]: str(w.message) for w in caught}
    ball = said[str(root / "ball" / "ball.obj")]
    assert "1 file units read as cm (detected), makes it 1 cm across" in ball
    assert "within 3x of the 1 cm minimum" in ball
    assert "--units mm|cm|m|in" in ball and "--size M" in ball
    assert "2 cm across" in said[str(root / "block" / "inch.stl")]
    sized = {f.path: f for f in check_dataset(open_dataset(root, size=0.22)).files}
    assert np.isclose(max(sized["ball/ball.obj"].extents or ()), 0.22)
    assert sized["ball/ball.obj"].near_limit() is None  # --size set it: nothing to flag
    inches = {f.path: f for f in check_dataset(open_dataset(root, units="in")).files}
    assert np.isclose(max(inches["block/inch.stl"].extents or ()), 0.0508)
    assert (
        inches["block/inch.stl"].near_limit() is None and inches["block/inch.stl"].scale() == "in"
    )


def test_near_the_upper_limit_is_flagged_too(tmp_path) -> None:
    root = make_folder(tmp_path / "data")
    trimesh.creation.box(extents=(0.3, 0.2, 0.1)).export(root / "block" / "tray.stl")
    flagged = {f.path: why for f, why in check_dataset(open_dataset(root)).near_limit()}
    assert list(flagged) == ["block/tray.stl"]
    assert "makes its diagonal 37.4 cm, within 3x of the 70 cm maximum" in flagged["block/tray.stl"]


def test_objects_prints_the_unit_and_scale_report(tmp_path, capsys, monkeypatch) -> None:
    root = make_folder(tmp_path / "data", ball=1.0, junk=True)
    monkeypatch.setattr(cli.command_module("objects"), "print_skipped", lambda d: None)
    # the report and the error come before any object is processed
    assert main(["objects", "--objects", str(root), "--split", "all", "--workers", "1"]) == 2
    captured = capsys.readouterr()
    rows = {ln.split()[0]: ln for ln in captured.out.splitlines()[2:]}
    assert re.search(
        r"ball/ball.obj\s+80\s+1\s+cm \(detected\)\s+1 cm\s+1.73 cm\s+near", rows["ball/ball.obj"]
    )
    assert re.search(r"block/b0.stl\s+12\s+0.1\s+m \(detected\)\s+10 cm", rows["block/b0.stl"])
    assert "BAD: the file has no faces" in rows["junk/notes.obj"]
    assert "beo-bench: warning: " + str(root / "ball" / "ball.obj") in captured.err
    assert len(_errors(captured.err)) == 2


def test_units_flag_reaches_the_dataset(tmp_path) -> None:
    parser = cli.build_parser()
    args = parser.parse_args(["objects", "--objects", "x", "--units", "in", "--max-faces", "9"])
    assert (args.units, args.max_faces, args.skip_bad) == ("in", 9, False)
    with pytest.raises(SystemExit):
        parser.parse_args(["objects", "--units", "inch"])
    root = make_folder(tmp_path / "data")
    assert open_dataset(root, units="auto").units is None  # the folders' default: one identity
    assert open_dataset(root, units="cm").identity()["units"] == "cm"


# -- links out of the root, and the scan's bounds ------------------------------------------------
def test_links_out_of_the_root_are_skipped_and_never_read(tmp_path, monkeypatch) -> None:
    root = make_folder(tmp_path / "data")
    outside = tmp_path / "elsewhere"
    (outside / "deep").mkdir(parents=True)
    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(outside / "deep" / "secret.obj")
    (outside / "passwd.obj").write_text("root:x:0:0:root:/root:/bin/bash\n")
    os.symlink(outside, root / "evil")  # a class folder that is a link out
    os.symlink(outside / "passwd.obj", root / "block" / "x.obj")  # a file link out
    os.symlink(outside / "deep", root / "ball" / "more")  # a folder link out, inside a class
    from beo_bench.objects.datasets import dataset as ds

    opened: list[str] = []
    real_sha, real_read = ds._file_sha256, load.read_mesh

    def sha(p: Path) -> str:
        opened.append(str(p))
        return real_sha(p)

    def read(p: str, *args: object) -> trimesh.Trimesh:
        opened.append(str(p))
        return real_read(p, *args)

    real_scandir = os.scandir

    def scandir(path: object) -> object:  # a folder listed is a folder followed
        opened.append(str(path))
        return real_scandir(path)  # type: ignore[call-overload]

    monkeypatch.setattr(ds, "_file_sha256", sha)
    monkeypatch.setattr(load, "read_mesh", read)
    monkeypatch.setattr(walk.os, "scandir", scandir)
    with pytest.warns(walk.DatasetScanWarning) as caught:
        d = open_dataset(root)
        check = check_dataset(d)
    said = " | ".join(str(w.message) for w in caught)
    for link in (root / "evil", root / "block" / "x.obj", root / "ball" / "more"):
        assert f"{link} is a symbolic link to" in said, said
    assert "outside the dataset root" in said and "never followed" in said
    assert d.categories() == ("ball", "block")
    assert [f.path for f in check.files] == ["ball/ball.obj", "block/b0.stl", "block/b1.stl"]
    far = os.path.realpath(outside)
    touched = [p for p in opened if Path(os.path.realpath(p)).is_relative_to(far)]
    assert opened and not touched, touched


def test_a_modelnet_file_link_out_of_the_root_is_never_read(tmp_path, monkeypatch) -> None:
    """Layouts that do not search folders (ModelNet, ShapeNet) drop such links too."""
    root = tmp_path / "ModelNet10"
    for split in ("train", "test"):
        (root / "chair" / split).mkdir(parents=True)
        trimesh.creation.box(extents=(1, 1, 1)).export(root / "chair" / split / "chair_1.off")
    outside = tmp_path / "secret.off"
    trimesh.creation.box(extents=(1, 2, 3)).export(outside)
    os.symlink(outside, root / "chair" / "test" / "chair_2.off")
    from beo_bench.objects.datasets import dataset as ds

    hashed: list[str] = []
    real_sha = ds._file_sha256
    monkeypatch.setattr(ds, "_file_sha256", lambda p: hashed.append(str(p)) or real_sha(p))
    with pytest.warns(walk.DatasetScanWarning, match="chair_2.off is a symbolic link to"):
        d = open_dataset(root)
    assert d.layout == "modelnet" and len(hashed) == 2 and not any("chair_2" in p for p in hashed)
    assert [f.path for f in check_dataset(d).files] == [
        "chair/test/chair_1.off",
        "chair/train/chair_1.off",
    ]


def test_a_folder_link_inside_the_root_is_skipped_and_said(tmp_path) -> None:
    """Issue 50, attack 15: ``ball/loop_up -> ..`` made the block files ball instances (and
    ``ball/loop -> ../block`` likewise); a link to a folder inside the category is reached
    anyway. Each is skipped with a warning naming it; a file link inside the root is still
    taken."""
    root = make_folder(tmp_path / "data")
    os.symlink("..", root / "ball" / "loop_up")
    os.symlink(root / "block", root / "ball" / "loop")
    os.symlink(root / "ball", root / "ball" / "self")
    os.symlink(root / "block" / "b0.stl", root / "ball" / "linked.stl")
    with pytest.warns(walk.DatasetScanWarning) as caught:
        files = [f.path for f in check_dataset(open_dataset(root)).files]
    said = " | ".join(str(w.message) for w in caught)
    for link in ("loop_up", "loop", "self"):
        assert f"{root / 'ball' / link} is a symbolic link to the folder" in said, said
    assert "outside its category folder" in said and "whose own scan reaches it" in said
    assert files == ["ball/ball.obj", "ball/linked.stl", "block/b0.stl", "block/b1.stl"]
    assert f"{root / 'ball' / 'loop_up'} is a symbolic link to the folder .. (outside" in said


def test_the_scan_is_bounded(tmp_path, monkeypatch) -> None:
    root = make_folder(tmp_path / "data")
    deep = root / "ball" / "a" / "b"
    deep.mkdir(parents=True)
    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(deep / "deep.obj")
    monkeypatch.setattr(walk, "MAX_DEPTH", 1)
    with pytest.warns(walk.DatasetScanWarning, match=r"more than 1 folders below .* not searched"):
        assert [f.path for f in check_dataset(open_dataset(root)).files] == [
            "ball/ball.obj",
            "block/b0.stl",
            "block/b1.stl",
        ]
    monkeypatch.setenv(walk.MAX_FILES_ENV, "1")
    other = make_folder(tmp_path / "other")
    with pytest.raises(
        DatasetTooLargeError, match=r"more than 1 files and folders .* BEO_BENCH_MAX_FILES=N"
    ):
        open_dataset(other)


def test_a_missing_objects_folder_exits_2_in_one_line(tmp_path, capsys) -> None:
    argv = ["run", "--suite", "pose-1dof", "--backend", "oracle", "--objects", str(tmp_path / "no")]
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith(f"beo-bench: error: {tmp_path / 'no'}: no such directory")
    assert DatasetLayoutError.exit_code == 2


# -- the face budget ------------------------------------------------------------------------------
def test_a_mesh_over_the_face_budget_is_refused_before_parsing(tmp_path, monkeypatch) -> None:
    root = make_folder(tmp_path / "data")  # the ball: an icosphere of 80 faces
    parsed: list[str] = []
    real_load = trimesh.load
    monkeypatch.setattr(trimesh, "load", lambda p, **k: parsed.append(str(p)) or real_load(p, **k))
    (bad,) = check_dataset(open_dataset(root, max_faces=50)).bad
    assert (bad.path, bad.kind, bad.faces) == ("ball/ball.obj", "faces", 80)
    assert bad.problem == "80 faces, over the face budget of 50"
    assert "pass --max-faces 80 to load it anyway" in str(bad.fix)
    assert not any(p.endswith("ball.obj") for p in parsed)  # counted from its lines
    assert check_dataset(open_dataset(root, max_faces=80)).bad == ()  # the override
    with pytest.raises(TooManyFacesError, match="80 faces, over the face budget of 79"):
        read_mesh(root / "ball" / "ball.obj", max_faces=79)


def test_face_counts_are_read_from_the_files(tmp_path) -> None:
    mesh = trimesh.creation.icosphere(1)  # 80 faces
    for suffix in ("obj", "off", "ply", "stl"):
        path = tmp_path / f"m.{suffix}"
        mesh.export(path)
        assert count_faces(path.read_bytes(), f".{suffix}") == 80, suffix
    ascii_stl = trimesh.exchange.stl.export_stl_ascii(mesh).encode()
    assert count_faces(ascii_stl, ".stl") == 80
    assert count_faces(b"glTF...", ".glb") is None  # no cheap count: checked once parsed


# -- the cache ------------------------------------------------------------------------------
def test_a_cache_that_is_a_file_exits_2_in_one_line(
    tmp_path, capsys, monkeypatch, own_cache
) -> None:
    own_cache.write_text("not a directory")
    assert main(["cache", "info"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line == (
        f"beo-bench: error: the asset cache {own_cache} ($BEO_BENCH_CACHE) is not a directory; "
        "set BEO_BENCH_CACHE to a writable directory with free space"
    )
    root = make_folder(tmp_path / "data")
    assert main(["objects", "--objects", str(root), "--split", "all"]) == 2
    assert "is not a directory" in capsys.readouterr().err


def test_a_read_only_cache_exits_2_before_anything_runs(
    tmp_path, capsys, monkeypatch, own_cache
) -> None:
    own_cache.mkdir()
    real_open = os.open

    def read_only(path, flags, *args, **kw):  # as on a read-only mount (root ignores chmod)
        if str(path).startswith(str(own_cache)) and flags & os.O_CREAT:
            raise OSError(errno.EROFS, "Read-only file system", str(path))
        return real_open(path, flags, *args, **kw)

    monkeypatch.setattr(os, "open", read_only)
    out = tmp_path / "run"
    assert main(["run", "--suite", "pose-1dof", "--backend", "icp", "--out", str(out)]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line == (
        f"beo-bench: error: the asset cache {own_cache} ($BEO_BENCH_CACHE) is not writable "
        "(Read-only file system); set BEO_BENCH_CACHE to a writable directory with free space"
    )
    assert not out.exists()
    assert main(["cache", "info"]) == 0  # reading it needs no write access


def test_a_full_cache_disk_exits_2(capsys, monkeypatch) -> None:
    usage = shutil.disk_usage("/")._replace(free=10 << 20)
    monkeypatch.setattr(shutil, "disk_usage", lambda p: usage)
    assert main(["pick-check", "--episodes", "1"]) == 2
    assert "has 10 MiB free, under the 256 MiB a run needs" in capsys.readouterr().err


def test_an_entry_that_cannot_be_written_is_a_cache_error(monkeypatch) -> None:
    def refuse(path, **arrays):
        raise OSError(errno.EACCES, "Permission denied", str(path))

    monkeypatch.setattr(cache, "atomic_save_npz", refuse)
    with pytest.raises(CacheDirError, match=r"cannot write the asset cache entry .*set BEO_BENCH"):
        cache.cached("voxels", "ab" * 16, {"D": 8, "v": 2}, lambda: {"occ": np.zeros(64, np.uint8)})
    assert CacheDirError.exit_code == 2


# -- user-data errors from a worker are not bugs ---------------------------------------------
@pytest.mark.slow
def test_a_bad_file_in_a_worker_is_raised_as_itself(tmp_path) -> None:
    """Without the check (the Python API's run), a worker that builds a bad file passes the
    error on as it is: its class and message, never "a bug in beo-bench"."""
    from beo_bench.bench.runner import run
    from beo_bench.bench.runs import RunConfig
    from beo_bench.bench.suites import get_suite

    root = tmp_path / "data"
    (root / "junk").mkdir(parents=True)
    (root / "junk" / "notes.obj").write_text("not a mesh\n")
    suite = get_suite("pose-1dof").with_overrides(size=2).with_dataset(open_dataset(root), "all")
    with pytest.raises(EmptyMeshError) as e:
        run(RunConfig(suite, "oracle"), tmp_path / "run", workers=2, progress=False)
    assert "notes.obj: the file has no faces" in str(e.value) and "bug" not in str(e.value)


# -- the docs show what a user sees -------------------------------------------------------------
def _doc_block() -> list[str]:
    page = Path(__file__).resolve().parents[2] / "docs" / "own-dataset.md"
    text = page.read_text()
    start = text.index("  ```text\n", text.index("## Checks before anything runs")) + 10
    return [ln.strip() for ln in text[start : text.index("  ```\n", start)].splitlines()]


def test_the_docs_show_the_lines_a_user_sees(tmp_path, capsys) -> None:
    """docs/own-dataset.md's example of the error lines is the real output."""
    root = make_folder(tmp_path / "ROOT", junk=True, sheet=True)
    (root / "tray").mkdir()
    for i in range(2):
        trimesh.creation.cylinder(radius=0.03, height=0.1 + 0.01 * i).export(
            root / f"tray/c{i}.stl"
        )
    trimesh.creation.box(extents=(68.0, 50.0, 40.0)).export(root / "tray" / "tray.stl")
    with pytest.raises(BadObjectsError) as e:
        vet(open_dataset(root, units="m"), workers=1)
    # the lines vet prints, then the error the CLI prints for what it raises
    lines = [*_errors(capsys.readouterr().err), f"beo-bench: error: {e.value}"]
    assert [ln.replace(str(root), "ROOT") for ln in lines] == _doc_block()


# -- the verdicts' cache and the check's processes ----------------------------------------------
def test_verdicts_are_cached_by_content(tmp_path, monkeypatch) -> None:
    from beo_bench.objects.datasets import dataset as ds

    monkeypatch.setattr(ds, "RACY_NS", 0)  # the files were written just now
    root = make_folder(tmp_path / "data", junk=True)
    first = check_dataset(open_dataset(root))
    built: list[str] = []
    real = checks.build_mesh

    def counting(path: str, *args: object, **kw: object) -> object:
        built.append(Path(path).name)
        return real(path, *args, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(checks, "build_mesh", counting)
    assert check_dataset(open_dataset(root)) == first and built == []  # nothing built again
    edited = root / "ball" / "ball.obj"
    trimesh.creation.icosphere(2, radius=0.04).export(edited)
    stamp = edited.stat().st_mtime_ns + 5_000_000_000  # a later edit, whatever the clock's grain
    os.utime(edited, ns=(stamp, stamp))
    again = check_dataset(open_dataset(root))
    assert built == ["ball.obj"] and again.files != first.files  # only the edited file
    assert check_dataset(open_dataset(root, repair="voxel")).files and len(built) == 6


@pytest.mark.slow
def test_worker_processes_give_the_same_verdicts(tmp_path) -> None:
    root = make_folder(tmp_path / "data", junk=True, sheet=True)
    for i in range(checks.PARALLEL_FROM):
        trimesh.creation.box(extents=(0.05 + 0.01 * i, 0.05, 0.05)).export(root / f"block/x{i}.stl")
    d = open_dataset(root)
    parallel = check_dataset(d, workers=2)
    shutil.rmtree(Path(os.environ[cache.CACHE_ENV]) / "datasets")  # build them all again
    assert check_dataset(d, workers=1) == parallel
    assert [f.path for f in parallel.bad] == ["junk/notes.obj", "paper/sheet.obj"]


def test_with_no_usable_file_skip_bad_is_not_suggested(tmp_path) -> None:
    root = tmp_path / "data"
    (root / "junk").mkdir(parents=True)
    (root / "junk" / "a.obj").write_text("nothing\n")
    summary = check_dataset(open_dataset(root)).summary()
    assert summary.endswith("fix them, none is usable") and "run on the other" not in summary


def test_a_name_that_is_not_utf8_is_skipped_with_its_name_escaped(tmp_path, capsys) -> None:
    """Issue 50, attack 16: a file name with the byte 0xff gave a UnicodeEncodeError
    traceback in `objects` and `run` (its key was hashed as text)."""
    root = make_folder(tmp_path / "data")
    box = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    box.export(os.fsdecode(bytes(root / "block") + b"/b\xff.stl"))
    (root / os.fsdecode(b"ca\xfft")).mkdir()
    box.export(os.fsdecode(bytes(root) + b"/ca\xfft/c.stl"))
    with pytest.warns(walk.DatasetScanWarning) as caught:
        d = open_dataset(root)
        files = [f.path for f in check_dataset(d).files]
    said = " | ".join(str(w.message) for w in caught)
    assert f"{root}/block/b\\xff.stl has a name that is not valid UTF-8: skipped" in said, said
    assert f"{root}/ca\\xfft has a name that is not valid UTF-8" in said
    assert d.categories() == ("ball", "block")
    assert files == ["ball/ball.obj", "block/b0.stl", "block/b1.stl"]
    walk._warn_undecodable.cache_clear()
    from beo_bench.objects.datasets import layouts

    layouts.top_dirs.cache_clear()
    layouts.dir_entries.cache_clear()
    assert main(["objects", "--objects", str(root), "--categories", "ball"]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and "b\\xff.stl has a name that is not valid UTF-8" in err


def test_an_absurdly_scaled_mesh_is_a_size_error_naming_units_and_size(tmp_path) -> None:
    """Issue 50, attack 17: a mesh scaled by 1e30 said "repairing it failed (TypeError...)"
    and advised --repair voxel, which advised --repair solid. Its extent is checked first:
    a size error naming --units and --size, and --size loads it."""
    root = tmp_path / "data"
    (root / "thing").mkdir(parents=True)
    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(root / "thing" / "good.stl")
    huge = trimesh.creation.icosphere(2, radius=0.05)
    huge.apply_scale(1e30)
    huge.export(root / "thing" / "huge.stl")
    for repair in ("basic", "voxel", "solid"):
        (bad,) = check_dataset(open_dataset(root, units="m", repair=repair)).bad
        assert bad.kind == "size", (repair, bad)
        assert "e+28 file units" in str(bad.problem) and "repair" not in str(bad.problem)
        assert (
            "--units" in str(bad.fix)
            and "--size" in str(bad.fix)
            and "--repair" not in str(bad.fix)
        )
    fixed = check_dataset(open_dataset(root, size=0.1))
    assert fixed.bad == () and len(fixed.files) == 2
