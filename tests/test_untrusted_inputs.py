"""Nothing the program did not create is overwritten; nothing it reads is trusted beyond its
declared shape. Each test replays one attack on the landed code (issue 26, "Attacks")."""

from __future__ import annotations

import io
import json
import shutil
import time
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest

from beo_bench.bench import rundir
from beo_bench.bench.pages import leaderboard
from beo_bench.bench.runs import RunUsageError
from beo_bench.cli import main
from beo_bench.errors import CheckpointError, InvalidKeyError
from beo_bench.objects import cache, instance_from_key
from beo_bench.objects.processing import pack_parts
from beo_bench.safe_npz import UnsafeArrayError, read_npz

REPO = Path(__file__).resolve().parent.parent
RUN = ["run", "--suite", "pose-1dof", "--backend", "random", "--workers", "1"]


def _error(capsys, argv: list[str], code: int = 2) -> str:
    assert main(argv) == code
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err.strip().splitlines()[-1]


def _npy_header(shape: tuple[int, ...], descr: str = "<f4") -> bytes:
    h = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        h, {"descr": descr, "fortran_order": False, "shape": shape}
    )
    return h.getvalue()


def _crafted_npz(path: Path, members: dict[str, bytes]) -> Path:
    """An ``.npz`` of raw members (hand-written ``.npy`` headers with whatever body)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(f"{name}.npy", data)
    return path


def _bomb(path: Path, name: str, nbytes: int) -> Path:
    """A real zip bomb: a float32 member of ``nbytes`` zeros, deflated to ~1/1000 of that."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        with zf.open(f"{name}.npy", "w", force_zip64=True) as f:
            f.write(_npy_header((nbytes // 4,)))
            chunk = bytes(1 << 22)
            for _ in range(nbytes >> 22):
                f.write(chunk)
    return path


# -- 1. output directories the program did not create ----------------------------------------
def test_run_refuses_a_users_folder_and_leaves_it_alone(capsys, tmp_path) -> None:
    d = tmp_path / "mine"
    d.mkdir()
    (d / "summary.json").write_text('{"my": "numbers"}')
    (d / "run.lock").write_text("my lock\n")
    err = _error(capsys, [*RUN, "--episodes", "2", "--out", str(d)])
    assert "did not create" in err and "--out" in err and "new or empty directory" in err
    assert (d / "summary.json").read_text() == '{"my": "numbers"}'
    assert (d / "run.lock").read_text() == "my lock\n"
    assert sorted(p.name for p in d.iterdir()) == ["run.lock", "summary.json"]


def test_a_run_marks_its_directory_and_an_older_run_directory_still_resumes(tmp_path) -> None:
    d = rundir.open_run_dir(tmp_path / "run")  # what `run` does first (a real run: minutes cold)
    assert (d / rundir.MARKER_NAME).read_text() == rundir.MARKER_TEXT
    (d / "results.jsonl").write_text("")
    rundir.open_run_dir(d)  # its own directory: taken again
    # a run directory of a version before the marker: its valid run.json vouches for it
    (d / rundir.MARKER_NAME).unlink()
    record = {"suite": {"name": "pose-1dof"}, "backend": "random", "backend_kwargs": {}}
    (d / "run.json").write_text(json.dumps(record))
    rundir.open_run_dir(d)
    assert (d / rundir.MARKER_NAME).read_text() == rundir.MARKER_TEXT
    # ... but a run.json another program wrote does not
    (d / rundir.MARKER_NAME).unlink()
    (d / "run.json").write_text('{"not": "ours"}')
    with pytest.raises(RunUsageError, match="did not create"):
        rundir.open_run_dir(d)
    assert not (d / rundir.MARKER_NAME).exists()


@pytest.mark.parametrize("files", [["README.md"], ["README.md", "pose-1dof.md", "pose-1dof.json"]])
def test_leaderboard_refuses_a_folder_without_its_marker(capsys, tmp_path, files) -> None:
    """Even files named as a leaderboard's own may be the user's: marker or empty."""
    u = tmp_path / "u"
    u.mkdir()
    for name in files:
        (u / name).write_text(f"my {name}")
    runs = tmp_path / "runs"
    runs.mkdir()
    err = _error(capsys, ["leaderboard", "--runs", str(runs), "--out", str(u)])
    assert "did not create" in err and "--out" in err
    assert all((u / n).read_text() == f"my {n}" for n in files)
    assert sorted(p.name for p in u.iterdir()) == sorted(files)


def test_all_refuses_a_users_folder_before_any_run(capsys, tmp_path) -> None:
    u = tmp_path / "u"
    u.mkdir()
    (u / "README.md").write_text("mine")
    runs = tmp_path / "runs"
    argv = ["all", "--suites", "pose-1dof", "--backends", "random", "--episodes", "2"]
    err = _error(capsys, [*argv, "--workers", "1", "--runs", str(runs), "--out", str(u)])
    assert "did not create" in err and "--out" in err
    assert (u / "README.md").read_text() == "mine"
    assert not runs.exists()  # refused before the first run, not after all of them


def test_regenerate_marks_new_leaderboards_and_the_committed_one_is_marked(tmp_path) -> None:
    runs = tmp_path / "runs"
    runs.mkdir()
    leaderboard.regenerate(runs, tmp_path / "board")
    marker = (tmp_path / "board" / leaderboard.MARKER_NAME).read_text()
    assert marker == leaderboard.MARKER_TEXT
    leaderboard.regenerate(runs, tmp_path / "board")  # its own directory: rewritten
    # the repository's leaderboards/ is the default --out: it must carry the same marker
    assert (REPO / "leaderboards" / leaderboard.MARKER_NAME).read_text() == marker
    leaderboard.check_out(REPO / "leaderboards")


# -- 2. npz members checked before they are unpacked ------------------------------------------
def test_a_declared_huge_member_is_refused_before_reading(tmp_path) -> None:
    # 4 GiB declared, 16 bytes of body: np.load would allocate first and read after
    f = _crafted_npz(tmp_path / "a.npz", {"occ": _npy_header((1 << 30,)) + bytes(16)})
    with pytest.raises(UnsafeArrayError, match="over the 1048576-byte budget"):
        read_npz(f, budget=1 << 20)
    # within budget, but the header and the zip's unpacked size disagree
    f = _crafted_npz(tmp_path / "b.npz", {"occ": _npy_header((1000,)) + bytes(16)})
    with pytest.raises(UnsafeArrayError, match="its header declares"):
        read_npz(f, budget=1 << 20)


@pytest.mark.parametrize(
    "descr, kinds, match",
    [("|O", "biuf", "object dtype"), ("<c8", "biuf", "dtype complex64"), ("<f8", "u", "float64")],
)
def test_dtypes_outside_the_expected_kinds_are_refused(tmp_path, descr, kinds, match) -> None:
    f = _crafted_npz(tmp_path / "a.npz", {"x": _npy_header((2,), descr) + bytes(16)})
    with pytest.raises(UnsafeArrayError, match=match):
        read_npz(f, budget=1 << 20, kinds=kinds)


def test_a_shape_other_than_expected_is_refused(tmp_path) -> None:
    buf = io.BytesIO()
    np.savez(buf, occ=np.zeros((4, 4), np.uint8))
    with pytest.raises(UnsafeArrayError, match=r"shape \(4, 4\), expected \(16,\)"):
        read_npz(buf.getvalue(), budget=1 << 20, shapes={"occ": (16,)})
    assert read_npz(buf.getvalue(), budget=1 << 20, shapes={"occ": (4, None)})["occ"].shape


def test_members_read_as_numpy_reads_them_whatever_their_header(tmp_path) -> None:
    """read_npz parses numpy's own headers itself (a pattern, not ``ast.literal_eval``) and
    reads the bytes after them: every dtype, shape and order comes back as ``np.load`` gives
    it, writable; a header in another form (keys reordered) goes to numpy's parser, whose
    answer is the same; one that is no header at all is refused."""
    arrays = {
        "scalar": np.float32(3.5),
        "empty": np.zeros((0, 3)),
        "fortran": np.asfortranarray(np.arange(12.0).reshape(3, 4)),
        "text": np.array(["ab", "c"]),
        "bools": np.array([True, False, True]),
        "big_endian": np.arange(5, dtype=">i4"),
        "one": np.arange(1),
        "cube": np.arange(24, dtype=np.uint8).reshape(2, 3, 4),
    }
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    got = read_npz(buf.getvalue(), budget=1 << 20, kinds="biufUS")
    with np.load(io.BytesIO(buf.getvalue())) as z:
        for name in arrays:
            want, have = z[name], got[name]
            assert (have.dtype, have.shape) == (want.dtype, want.shape), name
            np.testing.assert_array_equal(have, want)
            assert have.flags.f_contiguous == want.flags.f_contiguous and have.flags.writeable
    # the same header with its keys in another order: not numpy's form, read by numpy
    body = np.arange(3, dtype="<f4").tobytes()
    text = "{'shape': (3,), 'fortran_order': False, 'descr': '<f4', }".ljust(117) + "\n"
    odd = b"\x93NUMPY\x01\x00" + len(text).to_bytes(2, "little") + text.encode() + body
    f = _crafted_npz(tmp_path / "odd.npz", {"x": odd})
    np.testing.assert_array_equal(read_npz(f, budget=1 << 20)["x"], [0.0, 1.0, 2.0])
    junk = b"\x93NUMPY\x01\x00" + (8).to_bytes(2, "little") + b"not dict" + body
    with pytest.raises((UnsafeArrayError, ValueError)):
        read_npz(_crafted_npz(tmp_path / "junk.npz", {"x": junk}), budget=1 << 20)


def test_a_zip_bomb_as_cache_entry_costs_no_memory_and_is_rebuilt(tmp_path) -> None:
    settings = {"D": 8, "v": 2}
    path = cache.entry_path("voxels", "bomb" + "0" * 28, settings)
    path.parent.mkdir(parents=True, exist_ok=True)
    _bomb(path, "occ", 256 << 20)  # 256 MiB of zeros in a ~256 kB file
    assert path.stat().st_size < 2 << 20
    good = {"occ": np.packbits(np.ones(512, bool))}
    tracemalloc.start()
    try:
        got = cache.cached("voxels", "bomb" + "0" * 28, settings, lambda: good)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 32 << 20, f"{peak / 2**20:.0f} MiB taken by reading a refused entry"
    assert np.array_equal(got["occ"], good["occ"])
    assert cache._read_entry(path, "voxels", settings) is not None  # rewritten whole


def _beo_dir(tmp_path: Path) -> tuple[Path, dict]:
    meta = {"kind": "beo", "format": 1, "config": {"categories": ["mug"], "resolution": 8}, "k": 2}
    d = tmp_path / "model"
    d.mkdir()
    (d / "config.json").write_text(json.dumps(meta))
    return d, meta


def test_a_zip_bomb_as_a_models_arrays_is_refused_before_unpacking(tmp_path) -> None:
    from beo_bench.perception.beo.model import BEOModel
    from beo_bench.perception.digest import model_digest

    d, _ = _beo_dir(tmp_path)
    _crafted_npz(d / "arrays.npz", {"basis": _npy_header((1 << 30,)) + bytes(16)})
    with pytest.raises(CheckpointError, match=r"unreadable.*UnsafeArrayError"):
        BEOModel.load(d)
    with pytest.raises(CheckpointError, match="UnsafeArrayError"):
        model_digest(d)  # a run digests the model before it loads it
    # the expected shapes come from config.json: basis (D^3, k) = (512, 2)
    _crafted_npz(d / "arrays.npz", {"basis": _npy_header((512, 3)) + bytes(512 * 3 * 4)})
    with pytest.raises(CheckpointError, match=r"shape \(512, 3\), expected \(512, 2\)"):
        BEOModel.load(d)


def _published_copy(tmp_path: Path, stem: str, arrays: dict[str, np.ndarray]) -> Path:
    """A copy of the published files with ``stem``'s arrays replaced and the manifest edited
    to match (what the SHA-256 check alone cannot catch)."""
    from beo_bench.perception import published

    root = tmp_path / "published"
    shutil.copytree(published.PUBLISHED_DIR, root)
    data = published._pack(arrays)
    (root / f"{stem}.npz").write_bytes(data)
    m = json.loads((root / published.MANIFEST).read_text())
    m["files"][f"{stem}.npz"] = published._sha256(data)
    (root / published.MANIFEST).write_text(json.dumps(m))
    return root


def test_published_weights_of_a_complex_dtype_are_refused(tmp_path) -> None:
    from beo_bench.perception import published

    _, arrays = published.read("hbeo")
    name = next(k for k in arrays if k.startswith(published.NET_PREFIX))
    # complex weights as published writes them (a plain member): torch would cast them
    root = _published_copy(tmp_path, "hbeo", {**arrays, name: arrays[name].astype(np.complex64)})
    with pytest.raises(CheckpointError, match="dtype complex64"):
        published.read("hbeo", root)
    # a float array's planes declaring a complex dtype
    fake = {k: v for k, v in arrays.items() if k != name}
    data = published._pack({**fake, name: arrays[name]})
    with zipfile.ZipFile(io.BytesIO(data)) as zin:
        members = {i.filename: zin.read(i) for i in zin.infolist()}
    dtype_member = io.BytesIO()
    np.lib.format.write_array(dtype_member, np.frombuffer(b"<c8", np.uint8))
    members[f"{name}{published.DTYPE}.npy"] = dtype_member.getvalue()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zout:
        for n, b in members.items():
            zout.writestr(n, b)
    with pytest.raises(UnsafeArrayError, match="expected a real float array"):
        published._unpack(buf.getvalue())


def test_a_published_zip_bomb_is_refused_when_the_manifest_is_edited(tmp_path) -> None:
    from beo_bench.perception import published

    root = _published_copy(tmp_path, "hbeo", {"x": np.zeros(1, np.int8)})
    bomb = _crafted_npz(tmp_path / "b.npz", {"x": _npy_header((1 << 30,), "|u1") + bytes(16)})
    data = bomb.read_bytes()
    (root / "hbeo.npz").write_bytes(data)
    m = json.loads((root / published.MANIFEST).read_text())
    m["files"]["hbeo.npz"] = published._sha256(data)
    (root / published.MANIFEST).write_text(json.dumps(m))
    with pytest.raises(CheckpointError, match="budget"):
        published.read("hbeo", root)


# -- 3. cache entries validated on read --------------------------------------------------------
@pytest.mark.parametrize(
    "bad",
    [
        np.zeros(3, np.uint8),  # short: unpacks to an all-empty grid
        np.zeros((8, 8), np.uint8),  # 2-D: the right bytes in the wrong shape
        np.zeros(64, np.float32),  # float: a raw TypeError in unpackbits
    ],
    ids=["short", "2-D", "float"],
)
def test_a_tampered_voxel_entry_with_a_valid_checksum_is_rebuilt(bad) -> None:
    inst = instance_from_key("proc/v2/mug/test/0")
    truth = inst.voxels(8)
    path = cache.entry_path("voxels", inst.content_hash, {"D": 8, "v": 2})
    cache.atomic_save_npz(path, **cache.with_checksum({"occ": bad}))
    assert cache.checksum_problem(dict(np.load(path))) is None  # the checksum is valid
    assert np.array_equal(inst.voxels(8), truth)  # rebuilt, never used
    assert np.array_equal(np.load(path)["occ"], np.packbits(truth))


@pytest.mark.parametrize(
    "kind, settings, arrays",
    [
        ("surface", {"n": 2}, {"points": np.zeros((2, 3)), "normals": np.zeros((2, 3))}),
        ("surface", {"n": 2}, {"points": np.full((2, 3), np.nan), "normals": np.eye(3)[:2]}),
        (
            "generated",
            {"v": 1},
            {
                "vertices": np.zeros((3, 3)),
                "faces": np.array([[0, 1, 7]]),
                "symmetry": np.array("{}"),
                **{f"part_{k}": v for k, v in pack_parts([]).items()},
            },
        ),
        (
            "classmeans",
            {"categories": ["mug"], "D": 2},
            {"shape": np.full((1, 2, 2, 2), 3.0, np.float32), "size": np.ones((1, 3))},
        ),
    ],
    ids=["zero-normals", "nan-points", "face-out-of-range", "occupancy-over-1"],
)
def test_entries_with_values_their_writer_never_makes_are_rebuilt(kind, settings, arrays) -> None:
    content = f"{kind}-tampered".ljust(32, "0")
    path = cache.entry_path(kind, content, settings)
    cache.atomic_save_npz(path, **cache.with_checksum(arrays))
    assert cache._read_entry(path) is not None  # whole, with a valid checksum
    assert cache._read_entry(path, kind, settings) is None  # but not what its writer makes
    calls = []
    cache.cached(kind, content, settings, lambda: calls.append(1) or arrays)
    assert calls == [1]


# -- 4. training that would run no step ---------------------------------------------------------
def test_training_refuses_zero_steps_before_rendering(capsys, monkeypatch) -> None:
    from beo_bench.perception.hbeo import model as hbeo_model
    from beo_bench.perception.hbeo import train as hbeo_train

    def never(*a, **kw):
        raise AssertionError("rendered or trained although no step can run")

    monkeypatch.setattr(hbeo_train, "_train", never)
    t0 = time.perf_counter()
    argv = ["train", "hbeo", "--images", "100", "--batch-size", "128", "--name", "zero-steps"]
    err = _error(capsys, argv)
    assert "--images 100" in err and "--batch-size 128" in err and "no step" in err
    assert time.perf_counter() - t0 < 10
    assert not hbeo_model.model_path("zero-steps").exists()


# -- 5. odd arguments ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "argv",
    [[*RUN, "--out", ""], ["all", "--out", ""], ["leaderboard", "--out", " "]],
    ids=["run", "all", "leaderboard"],
)
def test_an_empty_out_is_a_usage_error(capsys, argv, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert "--out: is empty" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # nothing written under ./runs or ./leaderboards


@pytest.mark.parametrize(
    "key, match",
    [
        ("proc/v2/mug/test/99999999999999999999999", "out of range, split 'test' has 50"),
        ("proc/v2/mug/test/50", "out of range"),
        ("proc/v2/mug/test/\uff11", "ASCII digits"),  # fullwidth 1
        ("proc/v2/mug/test/\u0661", "ASCII digits"),  # Arabic-Indic 1
        ("proc/v2/mug/test/01", "leading zeros"),
    ],
)
def test_out_of_range_and_non_ascii_instance_keys_are_usage_errors(key, match) -> None:
    with pytest.raises(InvalidKeyError, match=match) as e:
        instance_from_key(key)
    assert e.value.exit_code == 2  # a usage error: the CLI exits 2
    assert instance_from_key("proc/v2/mug/test/49").key == "proc/v2/mug/test/49"


def test_a_library_set_larger_than_its_split_is_refused() -> None:
    """The library's splits have fixed sizes; a set of more instances a class would hold
    keys that ``instance_from_key`` refuses, so it is refused where it is asked for."""
    from beo_bench.errors import UsageError
    from beo_bench.objects import ObjectSet

    assert ObjectSet("test", ("mug",), per_category=50).count("mug") == 50
    with pytest.raises(UsageError, match=r"holds 50 instances a class; give 1 to 50"):
        ObjectSet("test", ("mug",), per_category=51)
