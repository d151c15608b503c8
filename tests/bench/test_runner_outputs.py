"""What runs write: ``beo-bench run``'s results, summary and recording, and ``beo-bench
all``'s runs and leaderboard (its degradation and pick-gap tables)."""

from __future__ import annotations

import json

from beo_bench.bench.runner import RunConfig, run
from beo_bench.bench.suites import get_suite
from tests.bench.runs import FAST_RANDOM


def test_cli_run_writes_results_summary_and_recording(tmp_path, capsys) -> None:
    from beo_bench.cli import main

    out, rrd = tmp_path / "run", tmp_path / "views.rrd"
    argv = ["run", "--suite", "pose-1dof", "--backend", "random", "--episodes", "3",
            "--opt", "mean_instances=4", "--out", str(out), "--rerun", str(rrd)]  # fmt: skip
    assert main(argv) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["suite"] == "pose-1dof" and s["n"] == 3 and "rot_err_deg_mean" in s["metrics"]
    assert s["provenance"]["suite"]["seed"] == get_suite("pose-1dof").seed
    assert rrd.read_bytes()[:4] == b"RRF2"
    assert "pose-1dof" in capsys.readouterr().out
    assert main(["compare", str(out), str(out)]) == 0
    assert main(["run", "--suite", "nope", "--backend", "random"]) == 2  # a clear error


def test_all_runs_every_pair_and_writes_the_leaderboard(tmp_path) -> None:
    from beo_bench.cli import main

    runs, board = tmp_path / "runs", tmp_path / "board"
    argv = ["all", "--suites", "pose-1dof", "known-pose", "--backends", "oracle",
            "random:mean_instances=4", "icp:mean_instances=4", "--episodes", "11",
            "--runs", str(runs), "--out", str(board), "--workers", "1"]  # fmt: skip
    assert main(argv) == 0
    # icp can use the class hint: both tracks; the bounds cannot: class-free only
    for track in ("class-given", "class-free"):
        assert (runs / f"pose-1dof@{track}__icp__mean_instances=4" / "summary.json").exists()
    assert not (runs / "pose-1dof@class-given__oracle").exists()
    md = (board / "pose-1dof.md").read_text()
    lines = [line for line in md.splitlines() if line.startswith("| ")]
    assert lines[0].startswith("| backend |")
    # methods first, bounds last and marked
    assert lines[1].startswith("| icp (mean_instances=4) |")
    assert any(line.startswith("| oracle *(upper bound)*") for line in lines)
    assert "| airplane | 1 |" in md  # the per-category table
    cdf = sorted(board.glob("pose-1dof*rot_cdf.png"))
    assert cdf and cdf[0].read_bytes()[:4] == b"\x89PNG"
    assert (board / "known-pose_confusion_oracle.png").exists()
    summaries = json.loads((board / "known-pose.json").read_text())
    assert {s["backend"] for s in summaries} == {"oracle", "random", "icp"}
    assert "known-pose" in (board / "README.md").read_text()
    # re-running resumes everything: nothing new is computed, the tables are the same
    before = (runs / "pose-1dof@class-free__oracle" / "results.jsonl").read_bytes()
    assert main(argv) == 0
    assert (runs / "pose-1dof@class-free__oracle" / "results.jsonl").read_bytes() == before
    assert (board / "pose-1dof.md").read_text().split("ms/view")[0] == md.split("ms/view")[0]


def test_ood_suite_gets_a_degradation_table(tmp_path) -> None:
    """Runs of ``pose-3dof`` and ``pose-3dof-ood`` (the ood split) are compared backend by
    backend in the ood suite's leaderboard."""
    from beo_bench.bench.pages.leaderboard import regenerate

    runs = tmp_path / "runs"
    for suite in ("pose-3dof", "pose-3dof-ood"):
        for opts in ({"seed": 1, **FAST_RANDOM}, {"seed": 2, **FAST_RANDOM}):
            cfg = RunConfig(get_suite(suite).with_overrides(size=4), "random", opts)
            run(cfg, runs / f"{suite}-{opts['seed']}", progress=False, workers=1)
    assert get_suite("pose-3dof-ood").split == "ood"
    regenerate(runs, tmp_path / "board")
    md = (tmp_path / "board" / "pose-3dof-ood.md").read_text()
    assert "In distribution (`pose-3dof`) -> out of distribution (`pose-3dof-ood`)" in md
    row = next(
        line
        for line in md.splitlines()
        if line.startswith("| random (mean_instances=4, seed=1)") and "->" in line
    )
    assert row.count("->") == 4


def test_pick_gap_table_reads_the_swap_runs() -> None:
    from beo_bench.bench.pages.verdicts import gap_table

    def row(backend: str, success: float, **kw) -> dict:
        return {"backend": backend, "metrics": {"pick_success": success},
                "provenance": {"backend_kwargs": kw}}  # fmt: skip

    rows = [
        row("icp", 0.5),
        row("swap", 0.7, base="icp", truth="class"),
        row("swap", 0.6, base="icp", truth="pose"),
        row("oracle", 0.9),
        row("oracle", 0.85, mesh=False),
    ]
    lines = gap_table(rows).splitlines()
    assert lines[-1] == "| icp | 50% | 70% | 60% | - | 85% | 90% |"
    assert gap_table(rows[:1]) == ""


def test_provenance_names_the_uncommitted_code_a_run_used(tmp_path) -> None:
    """A clean checkout records its commit; a dirty one also the SHA-256 of its diff, so a
    row scored on uncommitted code says exactly which code."""
    import hashlib
    import subprocess

    from beo_bench.bench.runner import git_state

    def git(*args: str) -> bytes:
        return subprocess.run(
            ["git", "-c", "user.name=t", "-c", "user.email=t@example.org", *args],
            cwd=tmp_path, check=True, capture_output=True,
        ).stdout  # fmt: skip

    assert git_state(tmp_path) == {"git_commit": None, "git_dirty": None}  # no repository
    git("init", "-q")
    (tmp_path / "a.py").write_text("x = 1\n")
    git("add", "a.py")
    git("commit", "-q", "-m", "one")
    head = git("rev-parse", "HEAD").decode().strip()
    assert git_state(tmp_path) == {"git_commit": head, "git_dirty": False}
    (tmp_path / "a.py").write_text("x = 2\n")
    state = git_state(tmp_path)
    diff = git("diff", "HEAD", "--binary")
    assert state["git_dirty"] is True and state["git_commit"] == head
    assert state["git_diff_sha256"] == hashlib.sha256(diff).hexdigest()
