"""The runner's integrity: one run per directory, whole lines or a clear error, damaged files
read around, hung and crashing backends recorded as failures while the run finishes, workers
that exit with their driver, and a resume refused when the model changed."""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from dataclasses import replace
from pathlib import Path

import pytest

from beo_bench import backend as B
from beo_bench.bench.rows import ResultsWarning, read_rows, scan_rows
from beo_bench.bench.runner import RunConfig, RunError, WorkerPool, run
from beo_bench.bench.runs import CorruptRunError, RunUsageError
from beo_bench.bench.suites import get_suite
from beo_bench.bench.summary import TIMING_KEYS
from beo_bench.errors import CorruptDataError, UsageError

ROOT = Path(__file__).resolve().parents[2]
FAULTS = "tests.bench.runner_faults"


def _cfg(suite: str, backend: str, n: int, track: str | None = None, **opts) -> RunConfig:
    return RunConfig(get_suite(suite).with_overrides(size=n, track=track), backend, opts)


def _priv(cfg: RunConfig) -> RunConfig:
    """``cfg`` with ``--allow-privileged`` (a test backend that wraps the oracle)."""
    return replace(cfg, allow_privileged=True)


HINT = "class-given"
"""The track whose views carry ``View.class_hint``, by which ``test-fault`` picks its views."""
FAST = {"mean_instances": 4}
"""The ``random`` backend's option that keeps its class means quick to build."""


def _metrics(s: dict) -> dict:
    return {k: v for k, v in s["metrics"].items() if k not in TIMING_KEYS}


def _lines(path: Path) -> list[bytes]:
    return path.read_bytes().splitlines(keepends=True)


@pytest.fixture(scope="module")
def faults():
    """The misbehaving test backend, registered here and in the workers that import it."""
    import tests.bench.runner_faults as mod

    yield mod
    B.unregister_backend(mod.NAME)  # other test modules see the in-tree set
    sys.modules.pop(FAULTS, None)


@pytest.fixture(scope="module")
def one_worker(faults):
    with WorkerPool(1, imports=[FAULTS]) as pool:
        yield pool


# -- 4: one run per directory, one set of rows per item ------------------------------------
def test_a_second_run_into_a_locked_directory_is_refused_naming_the_holder(tmp_path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    holder = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent("""
            import sys
            from pathlib import Path
            from beo_bench.bench.rundir import lock_run_dir, open_run_dir
            # as a run does: claim the directory (its marker), then lock it
            with lock_run_dir(open_run_dir(Path(sys.argv[1]))):
                print("locked", flush=True)
                sys.stdin.read()
            """), str(out)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(RunError, match=f"in use by another run \\(PID {holder.pid}"):
            run(_cfg("pose-1dof", "oracle", 2), out, progress=False, workers=1)
        with pytest.raises(RunError, match=f"PID {holder.pid}"):
            run(_cfg("pose-1dof", "oracle", 2), out, resume=True, progress=False, workers=1)
        assert not (out / "results.jsonl").exists()  # nothing was written
    finally:
        holder.kill()
        holder.wait()
    # the holder died: its lock file stays, and blocks nothing
    s = run(_cfg("pose-1dof", "oracle", 2), out, progress=False, workers=1)
    assert s["n"] == 2 and (out / "run.lock").exists()


def test_a_resume_keeps_one_set_of_rows_per_item(tmp_path) -> None:
    # random: its scores differ item by item, so counting an item twice would show
    out = tmp_path / "out"
    ref = run(_cfg("pose-3dof", "random", 4, **FAST), out, progress=False, workers=1)
    results = out / "results.jsonl"
    lines = _lines(results)
    again = [line for line in lines if json.loads(line)["item"] in (0, 2)]
    results.write_bytes(b"".join(lines + again))  # what two runs into one --out left
    with pytest.warns(ResultsWarning, match=r"second set of rows of 2 item\(s\) \[0, 2\]"):
        s = run(_cfg("pose-3dof", "random", 4, **FAST), out, resume=True, progress=False, workers=1)
    assert s["n"] == 4 and _metrics(s) == _metrics(ref)


def test_scan_rows_keeps_the_first_complete_set_of_each_item(tmp_path) -> None:
    def rows(item: int, views: list[int], n: int) -> list[str]:
        out = []
        for v in views:
            r = {"item": item, "view": v, "tag": len(out)}
            if v == 0:
                r["item_rows"] = n
            out.append(json.dumps(r) + "\n")
        return out

    lines = [
        *rows(0, [0, 1, 2], 3),
        *rows(1, [0, 2], 3),  # view 1 lost: incomplete
        "{not json\n",
        *rows(2, [0, 1], 3),  # the last view lost: incomplete
        *rows(1, [0, 1, 2], 3),  # item 1 run again: its first complete set
        *rows(0, [0, 1, 2], 3),  # a second set of item 0: dropped
        '{"item": 3, "view": 0, "item_r',  # torn last line
    ]
    path = tmp_path / "results.jsonl"
    path.write_text("".join(lines))
    scan = scan_rows(path)
    kept = [(r.item, r.view) for r in scan.rows]
    assert kept == [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2)]
    assert scan.damaged == [6] and scan.torn_tail
    assert sorted(scan.incomplete) == [1, 2] and scan.duplicates == [0]
    assert path.read_text() == "".join(lines)  # reading alone changes nothing
    scan_rows(path, repair=True)
    assert path.read_text() == "".join(lines[:-1])  # only the torn tail is cut


# -- 5: short writes, full disks, damaged lines ----------------------------------------------
def _results_fd(fd: int) -> bool:
    try:
        return os.readlink(f"/proc/self/fd/{fd}").endswith("results.jsonl")
    except OSError:
        return False


def test_short_writes_are_completed(tmp_path, monkeypatch) -> None:
    real = os.write

    def short(fd, data):  # the kernel may take fewer bytes than asked
        return real(fd, bytes(data[:7]) if _results_fd(fd) else data)

    monkeypatch.setattr(os, "write", short)
    s = run(_cfg("pose-3dof", "oracle", 4), tmp_path / "out", progress=False, workers=1)
    monkeypatch.undo()
    scan = scan_rows(tmp_path / "out" / "results.jsonl")
    assert s["n"] == 4 and len(scan.rows) == 4 and not scan.damaged and not scan.torn_tail


def test_a_full_disk_stops_the_run_with_only_complete_items_and_resume_finishes(
    tmp_path, monkeypatch
) -> None:
    ref = run(_cfg("pose-3dof", "random", 6, **FAST), tmp_path / "ref", progress=False, workers=1)
    real, appends = os.write, []

    def full(fd, data):  # the third item: half written, then the disk is full
        if not _results_fd(fd):
            return real(fd, data)
        appends.append(len(data))
        if len(appends) == 3:
            return real(fd, bytes(data[: len(data) // 2]))
        if len(appends) > 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(fd, data)

    out = tmp_path / "out"
    monkeypatch.setattr(os, "write", full)
    with pytest.raises(RunError, match=r"no space left .* free some space, then run again with"):
        run(_cfg("pose-3dof", "random", 6, **FAST), out, progress=False, workers=1)
    monkeypatch.undo()
    data = (out / "results.jsonl").read_bytes()
    assert data.endswith(b"\n") and len(data.splitlines()) == 2  # no torn third item
    s = run(_cfg("pose-3dof", "random", 6, **FAST), out, resume=True, progress=False, workers=1)
    assert s["n"] == 6 and _metrics(s) == _metrics(ref)


def test_damaged_lines_anywhere_are_skipped_reported_and_their_items_run_again(tmp_path) -> None:
    out = tmp_path / "out"
    ref = run(_cfg("pose-3dof", "random", 6, **FAST), out, progress=False, workers=1)
    results = out / "results.jsonl"
    lines = _lines(results)
    lines[1] = lines[1][:25] + b"\n"  # a torn line mid-file
    lines.insert(3, b"\x00\x00 garbage\n")
    results.write_bytes(b"".join(lines))
    with pytest.warns(ResultsWarning, match=r"skipped 2 damaged line\(s\) \(lines \[2, 4\]\)"):
        s = run(_cfg("pose-3dof", "random", 6, **FAST), out, resume=True, progress=False, workers=1)
    assert s["n"] == 6 and _metrics(s) == _metrics(ref)
    assert len(read_rows(results, report=False)) == 6


# -- 6: hangs and dead workers ---------------------------------------------------------------
def _failed(out: Path) -> list[dict]:
    return [r for r in read_rows(out / "results.jsonl") if r["failure"]]


@pytest.mark.parametrize(
    ("mode", "reason"),
    [
        ("abort", "worker died: signal 6"),
        ("segfault", "worker died: signal 11"),
        ("exit", "worker exited with status 3"),
    ],
)
def test_a_backend_that_kills_its_worker_is_recorded_and_the_run_finishes(
    tmp_path, one_worker, mode, reason
) -> None:
    # one worker: before, the crash took the whole run with it
    cfg = _cfg("pose-1dof", "test-fault", 4, HINT, mode=mode, classes=[1])
    s = run(cfg, tmp_path / "out", pool=one_worker, progress=False)
    assert s["n"] == 4 and s["failures"] == 1
    [row] = _failed(tmp_path / "out")
    assert (row["item"], row["failure"], row["correct"], row["pred_class"]) == (
        1,
        reason,
        False,
        -1,
    )
    assert sorted(s["metrics"]["rot_err_deg"])[-1] == 180.0  # scored as wrong
    assert s["failure_kinds"] == {"worker died": 1}
    # a resume does not run it again (nor crash again)
    before = (tmp_path / "out" / "results.jsonl").read_bytes()
    run(cfg, tmp_path / "out", pool=one_worker, progress=False, resume=True)
    assert (tmp_path / "out" / "results.jsonl").read_bytes() == before


def test_a_hung_backend_times_out_and_the_run_finishes(tmp_path, faults) -> None:
    # two workers: before, the pool waited for the hung one forever
    cfg = _cfg("pose-1dof", "test-fault", 5, HINT, mode="sleep", classes=[2])
    t0 = time.monotonic()
    with WorkerPool(2, imports=[FAULTS]) as pool:
        s = run(cfg, tmp_path / "out", pool=pool, progress=False, item_timeout=5)
        assert pool.restarts == 1
    assert time.monotonic() - t0 < 120
    assert s["n"] == 5 and s["failure_kinds"] == {"timeout": 1}
    assert s["provenance"]["item_timeout_s"] == 5
    [row] = _failed(tmp_path / "out")
    assert (row["item"], row["failure"], row["correct"]) == (2, "timeout after 5 s", False)


def test_a_pick_episode_whose_backend_dies_is_an_unsuccessful_pick(tmp_path, one_worker) -> None:
    cfg = _cfg("pick", "test-fault", 1, mode="abort")
    s = run(cfg, tmp_path / "out", pool=one_worker, progress=False)
    [row] = _failed(tmp_path / "out")
    assert row["failure"] == "worker died: signal 6" and row["success"] is False
    assert row["category"] == s["categories"][row["true_class"]] and row["views"] >= 1
    assert s["metrics"]["pick_success"] == 0.0
    assert s["metrics"]["pick_failure_reasons"] == {"worker_died": 1}


@pytest.mark.slow
def test_ray_actors_that_hang_or_die_are_recorded_and_the_run_finishes(
    tmp_path, faults, monkeypatch
) -> None:
    ray = pytest.importorskip("ray", reason="ray is an optional extra (make installs it)")
    if ray.is_initialized():
        ray.shutdown()
    # Ray's workers find the test backend through the path they inherit
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    pool = WorkerPool(2, imports=[FAULTS])  # with use_ray, only its imports are used
    try:
        for mode, reason in [("sleep", "timeout after 5 s"), ("abort", "worker died")]:
            cfg = _cfg("pose-1dof", "test-fault", 4, HINT, mode=mode, classes=[2])
            out = tmp_path / mode
            s = run(cfg, out, use_ray=True, workers=2, pool=pool, progress=False, item_timeout=5)
            assert s["n"] == 4 and s["failures"] == 1 and s["provenance"]["ray"] is True
            [row] = _failed(out)
            assert row["item"] == 2 and row["failure"].startswith(reason) and not row["correct"]
    finally:
        ray.shutdown()


def _gone(pid: int) -> bool:
    """The process has exited (a zombie waiting for its new parent to reap it counts)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return True
    return stat.rsplit(")", 1)[1].split()[0] in ("Z", "X")


@pytest.mark.parametrize("thread", [False, True], ids=["main-thread", "other-thread"])
def test_workers_exit_when_their_driver_is_killed(tmp_path, thread) -> None:
    # from another thread the kernel's parent-death signal is not used: the watch thread acts
    marker, out = tmp_path / "busy", tmp_path / "out"
    driver = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(f"""
            import sys
            sys.path.insert(0, {str(ROOT)!r})
            import {FAULTS}
            from beo_bench.bench.runner import RunConfig, WorkerPool, run
            from beo_bench.bench.suites import get_suite
            import threading
            def main():
                cfg = RunConfig(get_suite("pose-1dof").with_overrides(size=2), "test-fault",
                                {{"mode": "sleep", "marker": {str(marker)!r}}})
                with WorkerPool(1, imports=[{FAULTS!r}]) as pool:
                    run(cfg, {str(out)!r}, pool=pool, progress=False)
            if {thread!r}:
                t = threading.Thread(target=main)
                t.start()
                t.join()
            else:
                main()
            """)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 180
        while not marker.exists() and driver.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        assert marker.exists(), "the worker should be busy in the backend"
        worker = int(marker.read_text())
    finally:
        driver.send_signal(signal.SIGKILL)
        driver.wait()
    deadline = time.monotonic() + 10
    while not _gone(worker) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _gone(worker), "a worker outlived its driver"


# -- 7: the run directory ----------------------------------------------------------------------
def test_out_that_is_a_file_is_refused_and_left_alone(tmp_path) -> None:
    f = tmp_path / "notes.txt"
    f.write_text("precious")
    with pytest.raises(RunUsageError, match="is a file, not a directory"):
        run(_cfg("pose-1dof", "oracle", 2), f, progress=False, workers=1)
    with pytest.raises(RunUsageError, match=r"notes.txt is a file"):
        run(_cfg("pose-1dof", "oracle", 2), f / "run", progress=False, workers=1)
    assert f.read_text() == "precious"


def test_a_read_only_out_is_a_clear_error(tmp_path, monkeypatch) -> None:
    out = tmp_path / "ro"
    out.mkdir()
    real = os.open

    def read_only(path, flags, *args, **kw):  # as on a read-only mount
        if str(path).startswith(str(out)) and flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT):
            raise OSError(errno.EROFS, "Read-only file system", str(path))
        return real(path, flags, *args, **kw)

    monkeypatch.setattr(os, "open", read_only)
    with pytest.raises(RunError, match=r"Read-only file system.*choose another --out"):
        run(_cfg("pose-1dof", "oracle", 2), out, progress=False, workers=1)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only directories")
def test_a_directory_without_write_permission_is_a_clear_error(tmp_path) -> None:
    out = tmp_path / "ro"
    out.mkdir()
    out.chmod(0o555)
    try:
        with pytest.raises(RunError, match=r"Permission denied.*choose another --out"):
            run(_cfg("pose-1dof", "oracle", 2), out, progress=False, workers=1)
    finally:
        out.chmod(0o755)


def test_a_damaged_run_record_or_results_file_is_refused_and_left_alone(tmp_path) -> None:
    out = tmp_path / "out"
    run(_cfg("pose-1dof", "oracle", 2), out, progress=False, workers=1)
    record, results = out / "run.json", out / "results.jsonl"
    record.write_text('{"suite": {"name": "pose-1d')
    before = results.read_bytes()
    with pytest.raises(CorruptRunError, match=r"run.json is damaged") as e:
        run(_cfg("pose-1dof", "oracle", 4), out, resume=True, progress=False, workers=1)
    assert isinstance(e.value, CorruptDataError)
    assert record.read_text() == '{"suite": {"name": "pose-1d' and results.read_bytes() == before

    out2 = tmp_path / "garbage"
    run(_cfg("pose-1dof", "oracle", 2), out2, progress=False, workers=1)
    (out2 / "results.jsonl").write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00 not results\n")
    with pytest.raises(CorruptRunError, match="holds no result rows"):
        run(_cfg("pose-1dof", "oracle", 4), out2, resume=True, progress=False, workers=1)
    assert (out2 / "results.jsonl").read_bytes().startswith(b"\x89PNG")


# -- 8: provenance -------------------------------------------------------------------------------
def test_a_resume_with_another_model_is_refused(tmp_path) -> None:
    from beo_bench.objects import LIBRARY_VERSION

    model = {"digest": "aaaa1111"}

    class Learned(B.Backend):
        name = "test-digest"
        capabilities = B.Capabilities(privileged=True)

        def __init__(self, options=None) -> None:
            super().__init__(options)
            self.inner = B.get_backend("oracle")

        def model_digest(self) -> str:
            return model["digest"]

        def predict(self, view):
            return self.inner.predict(view)

    B.register(Learned)
    out = tmp_path / "out"
    try:
        s = run(_priv(_cfg("pose-1dof", "test-digest", 2)), out, progress=False, workers=1)
        record = json.loads((out / "run.json").read_text())
        assert record["model_digest"] == "aaaa1111"
        assert record["library_version"] == LIBRARY_VERSION
        assert s["provenance"]["model_digest"] == "aaaa1111"
        model["digest"] = "bbbb2222"  # retrained
        before = (out / "results.jsonl").read_bytes()
        with pytest.raises(RunUsageError, match=r"model aaaa1111.*now loads model bbbb2222"):
            run(_priv(_cfg("pose-1dof", "test-digest", 4)), out, resume=True, progress=False,
                workers=1)  # fmt: skip
        assert (out / "results.jsonl").read_bytes() == before
        model["digest"] = "aaaa1111"  # restored: the run goes on
        s = run(
            _priv(_cfg("pose-1dof", "test-digest", 4)), out, resume=True, progress=False, workers=1
        )
        assert s["n"] == 4
        # a record from before digests were recorded cannot be checked: refused too
        del record["model_digest"], record["library_version"]
        (out / "run.json").write_text(json.dumps(record))
        with pytest.raises(RunUsageError, match="older beo-bench"):
            run(
                _priv(_cfg("pose-1dof", "test-digest", 6)),
                out,
                resume=True,
                progress=False,
                workers=1,
            )
    finally:
        B.unregister_backend("test-digest")


def test_the_item_timeout_does_not_identify_a_run_and_must_be_positive(tmp_path) -> None:
    from beo_bench.bench.campaign import Campaign, run_campaign

    out = tmp_path / "out"
    run(_cfg("pose-1dof", "oracle", 2), out, progress=False, workers=1, item_timeout=100)
    assert "item_timeout_s" not in json.loads((out / "run.json").read_text())["suite"]
    s = run(
        _cfg("pose-1dof", "oracle", 3), out, resume=True, progress=False, workers=1, item_timeout=7
    )
    assert s["n"] == 3 and s["provenance"]["item_timeout_s"] == 7
    for bad in (0, -1, float("nan"), "soon"):
        with pytest.raises(UsageError, match="positive number of seconds"):
            run(_cfg("pose-1dof", "oracle", 2), tmp_path / "x", progress=False, item_timeout=bad)
    c = Campaign({"pose-1dof": 2}, [("oracle", {})], runs=tmp_path / "runs", item_timeout=-5)
    with pytest.raises(UsageError, match="positive number of seconds"):
        run_campaign(c)
    assert not (tmp_path / "runs").exists()  # refused before anything ran


def test_the_in_process_path_is_only_for_backends_workers_cannot_build(faults) -> None:
    from beo_bench.backend import buildable_in_fresh_process  # what the runner asks

    assert buildable_in_fresh_process("oracle", ())
    assert not buildable_in_fresh_process(faults.NAME, ())
    assert buildable_in_fresh_process(faults.NAME, (FAULTS,))
