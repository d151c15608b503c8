"""Atomic writes (beo_bench.atomic): a failed or killed write leaves the old file whole and
no temporary of its own behind, a reader never sees half a file, and nothing a user put at
the target or at a temporary name is written through."""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from beo_bench import atomic
from beo_bench.atomic import atomic_dir, atomic_path, atomic_write, atomic_write_bytes
from beo_bench.errors import CheckpointError
from beo_bench.perception import modeldir


def _entries(d: Path) -> list[str]:
    return sorted(p.name for p in d.iterdir())


def test_a_write_replaces_the_file_by_a_rename(tmp_path: Path) -> None:
    target = tmp_path / "f.json"
    target.write_text("old")
    inode = target.stat().st_ino
    with atomic_write(target, "w") as f:
        f.write("new, first half;")
        f.flush()
        # a reader during the write still sees the whole old file
        assert target.read_text() == "old"
        f.write(" second half")
    assert target.read_text() == "new, first half; second half"
    assert target.stat().st_ino != inode  # a new file renamed over the old one
    assert _entries(tmp_path) == ["f.json"]
    with pytest.raises(ValueError, match="use 'wb'"), atomic_write(target, "a"):  # type: ignore[arg-type]
        pass  # appending cannot be atomic: refused before anything is created
    assert _entries(tmp_path) == ["f.json"]


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "f.npz"
    target.write_bytes(b"old")
    for error in (OSError("disk full"), KeyboardInterrupt()):
        with pytest.raises(type(error)), atomic_write(target) as f:
            f.write(b"partial")
            raise error
        assert target.read_bytes() == b"old"
        assert _entries(tmp_path) == ["f.npz"]
    with pytest.raises(ValueError), atomic_path(tmp_path / "new.png") as tmp:
        tmp.write_bytes(b"half a figure")
        raise ValueError("the plotting library failed")
    assert _entries(tmp_path) == ["f.npz"]


def test_a_killed_writer_leaves_the_old_file_whole(tmp_path: Path) -> None:
    target = tmp_path / "checkpoint.json"
    target.write_text("old")
    code = (
        "import os, signal, sys\n"
        "from beo_bench.atomic import atomic_write\n"
        "with atomic_write(sys.argv[1], 'w') as f:\n"
        "    f.write('half of the new')\n"
        "    f.flush()\n"
        "    os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code, str(target)], check=False)
    assert proc.returncode == -signal.SIGKILL
    assert target.read_text() == "old"
    # the one thing a kill can leave is a hidden temporary that model directories know as
    # ours (so they can still be replaced), never a partial file under the real name
    left = [n for n in _entries(tmp_path) if n != "checkpoint.json"]
    assert len(left) == 1 and left[0].startswith(".checkpoint.json.")
    assert modeldir.TEMP_FILE.fullmatch(left[0])


def test_concurrent_readers_see_a_whole_file(tmp_path: Path) -> None:
    target = tmp_path / "summary.json"
    versions = [bytes([65 + i]) * 200_000 for i in range(4)]
    atomic_write_bytes(target, versions[0])
    seen: set[bytes] = set()
    done = threading.Event()

    def read() -> None:
        while not done.is_set():
            seen.add(target.read_bytes())

    reader = threading.Thread(target=read)
    reader.start()
    try:
        for i in range(40):
            atomic_write_bytes(target, versions[i % len(versions)], durable=False)
    finally:
        done.set()
        reader.join()
    assert seen <= set(versions)


def test_a_link_at_the_target_is_replaced_never_written_through(tmp_path: Path) -> None:
    users = tmp_path / "users_file.txt"
    users.write_text("the user's data")
    target = tmp_path / "results.json"
    target.symlink_to(users)
    atomic_write_bytes(target, "new")
    assert users.read_text() == "the user's data"
    assert not target.is_symlink() and target.read_text() == "new"


def test_a_file_or_link_at_the_temporary_name_is_never_written_through(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    users = tmp_path / "users_file.txt"
    users.write_text("the user's data")
    target = tmp_path / "f.bin"
    draws = iter(["planted", "fresh"])
    monkeypatch.setattr(atomic.secrets, "token_hex", lambda n: next(draws))
    planted = tmp_path / f".f.bin.planted.{os.getpid()}.tmp"
    planted.symlink_to(users)
    atomic_write_bytes(target, b"new")
    assert target.read_bytes() == b"new"
    assert users.read_text() == "the user's data"
    assert planted.is_symlink()  # not ours: left alone


def test_new_files_get_the_permissions_of_a_plain_open(tmp_path: Path) -> None:
    plain = tmp_path / "plain"
    plain.write_bytes(b"")
    atomic_write_bytes(tmp_path / "atomic", b"")
    mode = stat.S_IMODE((tmp_path / "atomic").stat().st_mode)
    assert mode == stat.S_IMODE(plain.stat().st_mode)
    with atomic_write(tmp_path / "private", perms=0o600) as f:
        f.write(b"")
    assert stat.S_IMODE((tmp_path / "private").stat().st_mode) == 0o600


def test_a_directory_is_installed_whole_or_not_at_all(tmp_path: Path) -> None:
    target = tmp_path / "model"
    with atomic_dir(target) as tmp:
        (tmp / "config.json").write_text("{}")
        assert not target.exists()
    assert _entries(target) == ["config.json"]
    with pytest.raises(RuntimeError), atomic_dir(tmp_path / "other") as tmp:
        (tmp / "config.json").write_text("{}")
        raise RuntimeError("serialising the weights failed")
    assert _entries(tmp_path) == ["model"]


def test_a_directory_install_that_refuses_leaves_the_target_untouched(tmp_path: Path) -> None:
    """Model directories keep their rule: a directory this package did not write is never
    replaced, and the refused temporary directory is removed."""
    target = tmp_path / "mine"
    target.mkdir()
    (target / "thesis.tex").write_text("not a model")
    files = frozenset({"config.json"})

    def install(tmp: Path, to: Path) -> None:
        modeldir.install(tmp, to, files, ("beo",))

    with pytest.raises(CheckpointError, match="refusing"), atomic_dir(target, install) as tmp:
        (tmp / "config.json").write_text('{"kind": "beo"}')
    assert _entries(target) == ["thesis.tex"]
    assert _entries(tmp_path) == ["mine"]
