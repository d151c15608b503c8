"""The regression gate (``beo-bench gate``, ``beo-bench baseline``, ``bench.gate``) on
synthetic runs (rows written by hand, summaries computed by the package: milliseconds), and
the ``smoke`` suite set. The end-to-end gate with real runs of plugin backends is in
``tests/bench/test_gate_e2e.py``."""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from beo_bench import stats
from beo_bench.bench.gate.baseline import load_baseline, load_runs, write_baseline
from beo_bench.bench.gate.check import check_failure_rate, gate
from beo_bench.bench.gate.spec import (
    FailureRateError,
    GateUsageError,
    margin,
    primary_keys,
    primary_metric,
)
from beo_bench.bench.gate.verdicts import GateOptions
from beo_bench.cli import main
from tests.bench.synthetic_runs import pose_row, write_run

ROT = [float(x) for x in np.random.default_rng(0).uniform(0, 40, 30)]


def _run(path: Path, shift: float = 0.0, n: int = 30, **kw) -> Path:
    """A pose-1dof class-free run whose rotation errors are ``ROT + shift``."""
    rows = [pose_row(i, rot_err_deg=ROT[i] + shift) for i in range(n)]
    write_run(path, kw.pop("backend", "beo"), rows, track=kw.pop("track", "class-free"), **kw)
    return path


# -- the correction, in a gate ----------------------------------------------------------------
def test_holm_keeps_a_metric_that_alone_would_fail_from_failing_among_three(tmp_path) -> None:
    """Five items, every one worse by more than the metric's margin: the exact one-sided p
    is 1/32 = 0.031 on each metric. Alone it fails the gate; three such tests at once,
    Holm-corrected, do not."""
    keys = ("rot_err_deg_mean", "trans_err_cm_mean", "size_err_pct_mean")
    a = [pose_row(i) for i in range(5)]
    b = [pose_row(i, rot_err_deg=16.0, trans_err_cm=2.5, size_err_pct=11.0) for i in range(5)]
    write_run(tmp_path / "a", "beo", a, track="class-free")
    write_run(tmp_path / "b", "beo", b, track="class-free")
    runs, base = load_runs([tmp_path / "b"]), load_baseline(tmp_path / "a")
    alone = gate(runs, base, GateOptions(metrics=keys[:1]))
    assert [v.outcome for v in alone.verdicts] == ["regression"]
    assert alone.verdicts[0].p == pytest.approx(1 / 32) == alone.verdicts[0].p_holm
    three = gate(runs, base, GateOptions(metrics=keys))
    assert three.passed and {v.outcome for v in three.verdicts} == {"worse, within the margin"}
    assert all(v.p_holm == pytest.approx(3 / 32) for v in three.verdicts)


# -- verdicts -----------------------------------------------------------------------------------
def test_direction_comes_from_the_metric_spec(tmp_path) -> None:
    """Lower is better for the rotation error, higher for IoU: a rotation error up and an
    IoU up are a regression and an improvement; only the regression fails."""
    a = [pose_row(i, rot_err_deg=ROT[i], iou=0.4) for i in range(30)]
    b = [pose_row(i, rot_err_deg=ROT[i] + 8, iou=0.6) for i in range(30)]
    write_run(tmp_path / "a", "beo", a, track="class-free")
    write_run(tmp_path / "b", "beo", b, track="class-free")
    opts = GateOptions(metrics=("rot_err_deg_mean", "iou_mean"))
    r = gate(load_runs([tmp_path / "b"]), load_baseline(tmp_path / "a"), opts)
    by = {v.metric: v for v in r.verdicts}
    assert by["rot_err_deg_mean"].outcome == "regression" and by["rot_err_deg_mean"].diff == 8
    assert by["iou_mean"].outcome == "improvement"
    assert not r.passed and r.regressions == (by["rot_err_deg_mean"],)
    # the other way round the rotation improves and IoU regresses
    back = gate(load_runs([tmp_path / "a"]), load_baseline(tmp_path / "b"), opts)
    assert {v.metric: v.outcome for v in back.verdicts} == {
        "rot_err_deg_mean": "improvement",
        "iou_mean": "regression",
    }


def test_the_primary_metrics_are_the_default(tmp_path) -> None:
    """Rotation (its mean and the > 15 deg rate), translation and class for a pose run
    (pick where a suite measures it): a translation-only regression fails the default gate,
    as a rotation one does."""
    r = gate(load_runs([_run(tmp_path / "b", 30)]), load_baseline(_run(tmp_path / "a")))
    assert [v.metric for v in r.verdicts] == [
        "rot_err_deg_mean", "gross_err_rate", "trans_err_cm_mean", "class_acc",
    ]  # fmt: skip
    assert [v.outcome for v in r.verdicts] == ["regression"] * 2 + ["no difference"] * 2
    assert primary_keys() == ("rot_err_deg_mean", "gross_err_rate", "trans_err_cm_mean",
                                   "class_acc", "pick_success")  # fmt: skip
    shifted = [pose_row(i, rot_err_deg=ROT[i], trans_err_cm=6.0) for i in range(30)]
    write_run(tmp_path / "t", "beo", shifted, track="class-free")
    t = gate(load_runs([tmp_path / "t"]), load_baseline(tmp_path / "a"))
    assert [v.metric for v in t.regressions] == ["trans_err_cm_mean"]
    assert t.regressions[0].diff == pytest.approx(5.0) and t.regressions[0].margin == 1.0
    assert primary_metric("known-pose") == "class_acc"  # a suite's headline metric
    assert primary_metric("pose-3dof+modelnet10") == "gross_err_rate"
    assert primary_metric("pick") == "pick_success"


def test_each_rotation_metric_sees_what_the_other_misses(tmp_path) -> None:
    """Views right at 12 deg turned to 16: the mean grows by 4 deg (within its margin), the
    > 15 deg rate by every view. Views wrong at 60 deg turned to 120: the rate does not
    move, the mean grows by 60 deg."""
    found = {}
    for name, before, after in (("bias", 12.0, 16.0), ("far", 60.0, 120.0)):
        write_run(tmp_path / name / "a", "beo", [pose_row(i, rot_err_deg=before)
                  for i in range(20)], track="class-free")  # fmt: skip
        write_run(tmp_path / name / "b", "beo", [pose_row(i, rot_err_deg=after)
                  for i in range(20)], track="class-free")  # fmt: skip
        r = gate(load_runs([tmp_path / name / "b"]), load_baseline(tmp_path / name / "a"))
        found[name] = [v.metric for v in r.regressions]
    assert found == {"bias": ["gross_err_rate"], "far": ["rot_err_deg_mean"]}


def test_a_worsening_within_the_margin_passes_however_many_items(tmp_path) -> None:
    """Every one of 30 items 4 deg worse: certain, but within the 5 deg margin, so not a
    regression; 6 deg worse is one."""
    a = [pose_row(i, rot_err_deg=ROT[i]) for i in range(30)]
    write_run(tmp_path / "a", "beo", a, track="class-free")
    opts = GateOptions(metrics=("rot_err_deg_mean",))
    for shift, outcome in ((4.0, "worse, within the margin"), (6.0, "regression")):
        b = [pose_row(i, rot_err_deg=ROT[i] + shift) for i in range(30)]
        write_run(tmp_path / f"b{shift}", "beo", b, track="class-free")
        runs = load_runs([tmp_path / f"b{shift}"])
        (v,) = gate(runs, load_baseline(tmp_path / "a"), opts).verdicts
        assert (v.outcome, v.margin, v.diff) == (outcome, 5.0, pytest.approx(shift))
    assert margin("rot_err_deg_mean") == 5.0 and margin("edt_err_mean") == 0.0


def test_pooled_over_suites_the_gate_finds_what_no_suite_alone_shows(tmp_path) -> None:
    """Three suites of 20 items, each 3/4 of its items 14 deg worse and 1/4 10 deg better
    (+8 deg on the mean): one suite alone is within its noise, the three pooled are a
    regression. A suite's two tracks score the same items: one unit each, not two."""
    suites = ("pose-1dof", "pose-3dof", "pose-3dof-ood")
    opts = GateOptions(metrics=("rot_err_deg_mean",))
    for suite in suites:
        a = [pose_row(i, rot_err_deg=ROT[i]) for i in range(20)]
        b = [pose_row(i, rot_err_deg=ROT[i] + (-10.0 if i % 4 == 0 else 14.0)) for i in range(20)]
        write_run(tmp_path / "base" / suite, "beo", a, suite, track="class-free")
        write_run(tmp_path / "runs" / suite, "beo", b, suite, track="class-free")
        alone = gate(
            load_runs([tmp_path / "runs" / suite]),
            load_baseline(tmp_path / "base" / suite),
            opts,
        )
        assert alone.passed and alone.verdicts[0].p > 0.05, suite
    pooled = gate(load_runs([tmp_path / "runs"]), load_baseline(tmp_path / "base"), opts)
    (v,) = pooled.verdicts
    assert v.regression and v.p < 0.05 and v.diff == pytest.approx(8.0)
    assert (v.n_items, v.n_views, v.suites) == (60, 60, tuple(f"{s}@class-free" for s in suites))
    assert [p.diff for p in v.parts] == pytest.approx([8.0] * 3)

    # the class-given track of pose-1dof too: the same 20 items, so still 60 units
    write_run(tmp_path / "base" / "given", "beo", [pose_row(i) for i in range(20)])
    write_run(tmp_path / "runs" / "given", "beo", [pose_row(i) for i in range(20)])
    both = gate(load_runs([tmp_path / "runs"]), load_baseline(tmp_path / "base"), opts)
    assert (both.verdicts[0].n_items, both.verdicts[0].n_views) == (60, 80)


def test_identical_runs_pass_with_p_one(tmp_path) -> None:
    r = gate(load_runs([_run(tmp_path / "b")]), load_baseline(_run(tmp_path / "a")))
    assert r.passed and r.verdicts[0].p == 1.0 and r.verdicts[0].diff == 0.0


# -- the baseline file ------------------------------------------------------------------------
def test_a_baseline_file_gates_as_its_run_does(tmp_path) -> None:
    """Written from a run, the file gives the same verdicts as the run directory, NaN
    values (the class of a view told its class) included."""
    a = [pose_row(i, rot_err_deg=ROT[i]) for i in range(30)]
    b = [pose_row(i, rot_err_deg=ROT[i] + 3 * (i % 2)) for i in range(30)]
    write_run(tmp_path / "a", "beo", a)  # class-given: class_acc is NaN on every view
    write_run(tmp_path / "b", "beo", b)
    write_baseline(load_runs([tmp_path / "a"]), tmp_path / "base.json")
    obj = json.loads((tmp_path / "base.json").read_text())
    assert (obj["format"], obj["version"]) == ("beo-bench-baseline", 1)
    entry = obj["runs"][0]
    assert entry["label"] == "pose-1dof@class-given" and entry["views"]["3"] == [0]
    assert entry["values"]["class_acc"]["0"] == [None]
    assert entry["values"]["rot_err_deg_mean"]["4"] == [ROT[4]]
    opts = GateOptions(metrics=("rot_err_deg_mean", "gross_err_rate", "iou_mean"))
    runs = load_runs([tmp_path / "b"])
    from_file = gate(runs, load_baseline(tmp_path / "base.json"), opts)
    from_dir = gate(runs, load_baseline(tmp_path / "a"), opts)
    assert [v.to_json() for v in from_file.verdicts] == [v.to_json() for v in from_dir.verdicts]
    with pytest.raises(GateUsageError, match=r"nothing to gate.*no view scored on it in both"):
        gate(runs, load_baseline(tmp_path / "base.json"), GateOptions(("class_acc",)))


def test_a_baseline_of_another_format_version_or_damaged_is_refused(tmp_path) -> None:
    write_baseline(load_runs([_run(tmp_path / "a")]), tmp_path / "base.json")
    obj = json.loads((tmp_path / "base.json").read_text())
    (tmp_path / "v2.json").write_text(json.dumps({**obj, "version": 2}))
    with pytest.raises(GateUsageError, match="format version 2; this beo-bench reads version 1"):
        load_baseline(tmp_path / "v2.json")
    obj["runs"][0]["values"]["iou_mean"]["0"] = [0.5, 0.5]  # two values for one view
    (tmp_path / "bad.json").write_text(json.dumps(obj))
    with pytest.raises(GateUsageError, match=r"not a readable beo-bench baseline.*--out"):
        load_baseline(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text('{"format": "something-else"}')
    with pytest.raises(GateUsageError, match="not a readable beo-bench baseline"):
        load_baseline(tmp_path / "other.json")


# -- refusals --------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kw", "why"),
    [
        ({"seed": 7}, "seed 2000 (baseline) vs 7"),
        ({"version": 3}, "suite version 4 (baseline) vs 3"),
        ({"track": "class-given"}, "track 'class-free' (baseline) vs 'class-given'"),
        ({"sensor": "d435"}, "sensor 'ideal' (baseline) vs 'd435'"),
        ({"n": 20}, "items 0..19 (20) and the baseline 0..29 (30): run it with --episodes 30"),
    ],
)
def test_runs_that_do_not_pair_are_refused_with_exit_2(tmp_path, capsys, kw, why) -> None:
    base = _run(tmp_path / "a")
    other = _run(tmp_path / "b", **kw)
    with pytest.raises(GateUsageError, match="cannot gate") as e:
        gate(load_runs([other]), load_baseline(base))
    assert why in str(e.value)
    assert main(["gate", str(other), "--baseline", str(base), "--junit", str(tmp_path / "j")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and why in err[0], err
    assert not (tmp_path / "j").exists()  # a refused gate writes no report


def test_bad_arguments_exit_2(tmp_path, capsys) -> None:
    a = str(_run(tmp_path / "a"))
    for argv in (
        ["gate", a, "--baseline", a, "--metrics", "rot_err_deg_median"],  # a median
        ["gate", a, "--baseline", a, "--alpha", "1.5"],
        ["gate", a],  # no baseline
        ["run", "--suite", "pose-1dof", "--backend", "oracle", "--max-failure-rate", "2"],
    ):
        with pytest.raises(SystemExit) as e:
            main(argv)
        assert e.value.code == 2, argv
    assert main(["gate", str(tmp_path / "none"), "--baseline", a]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["gate", a, "--baseline", str(tmp_path / "none.json")]) == 2
    assert "--baseline " in capsys.readouterr().err
    assert main(["gate", a, "--baseline", a, "--metrics", "pick_success"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nothing to gate: no run measures pick_success" in err[0]
    assert "give --metrics among" in err[0]


# -- several suites, the reports ---------------------------------------------------------------
def test_runs_pair_with_their_suites_baseline_and_the_reports_say_it(
    tmp_path, capsys, monkeypatch
) -> None:
    """A directory of runs against a baseline of four: each run finds its suite label's
    entry and each metric is one test pooled over the runs that measure it; a suite that
    does not measure a metric given by --metrics is skipped, not refused, and so is the
    baseline run no run was gated against; every report says so (JUnit skipped test
    cases), the JUnit failure is on the regression, the Markdown summary is written and
    appended to $GITHUB_STEP_SUMMARY."""
    _run(tmp_path / "base" / "one")
    _run(tmp_path / "base" / "two", track="class-given")
    known = [pose_row(i) for i in range(6)]
    write_run(tmp_path / "base" / "three", "beo", known, "known-pose", track=None)
    write_run(tmp_path / "base" / "four", "beo", known, "pose-3dof", track="class-free")
    main(["baseline", str(tmp_path / "base"), "--out", str(tmp_path / "base.json")])
    _run(tmp_path / "runs" / "one", 30)  # class-free: every view now a gross error
    _run(tmp_path / "runs" / "two", track="class-given")
    write_run(tmp_path / "runs" / "three", "beo", known, "known-pose", track=None)
    step = tmp_path / "step.md"
    step.write_text("earlier step\n")
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(step))
    out = {k: tmp_path / f"gate.{k}" for k in ("json", "junit", "markdown")}
    argv = ["gate", str(tmp_path / "runs"), "--baseline", str(tmp_path / "base.json")]
    argv += [*itertools.chain.from_iterable((f"--{k}", str(p)) for k, p in out.items())]
    capsys.readouterr()
    assert main([*argv, "--metrics", "gross_err_rate", "iou_mean"]) == 3
    io = capsys.readouterr()
    assert io.err.startswith("beo-bench: gate failed: regression in beo > 15 deg over 2 runs")
    assert len(io.err.strip().splitlines()) == 1
    assert "gate: 1 regression in 2 tests" in io.out
    assert "skipped        known-pose: gross_err_rate" in io.out
    assert "pose-1dof@class-free: " in io.out  # the regression's suites, under it

    root = ET.parse(out["junit"]).getroot()
    assert (root.get("tests"), root.get("failures"), root.get("skipped")) == ("4", "1", "2")
    cases = {(ts.get("name"), tc.get("name")): tc for ts in root for tc in ts.iter("testcase")}
    assert set(cases) == {
        ("beo", "gross_err_rate"),
        ("beo", "iou_mean"),
        ("known-pose", "gross_err_rate"),
        ("pose-3dof@class-free", "run"),
    }
    failed = [k for k, tc in cases.items() if tc.find("failure") is not None]
    assert failed == [("beo", "gross_err_rate")]
    assert cases[failed[0]].find("failure").get("message").startswith("regression: ")
    assert cases[("known-pose", "gross_err_rate")].find("skipped") is not None
    assert cases[("pose-3dof@class-free", "run")].find("skipped") is not None

    report = json.loads(out["json"].read_text())
    assert report["passed"] is False and report["regressions"] == 1
    assert report["not_run"] == ["pose-3dof@class-free"]
    assert [(s["suite"], s["metric"]) for s in report["skipped"]] == [
        ("known-pose", "gross_err_rate")
    ]
    by = {v["metric"]: v for v in report["verdicts"]}
    assert by["gross_err_rate"]["suites"] == ["pose-1dof@class-free", "pose-1dof@class-given"]
    assert by["gross_err_rate"]["items"] == 30 and by["gross_err_rate"]["views"] == 60
    assert len(by["iou_mean"]["suites"]) == 3 and by["iou_mean"]["outcome"] == "no difference"
    md = out["markdown"].read_text()
    assert md.startswith("### beo-bench gate: 1 regression") and "**regression**" in md
    assert "Skipped (the suite does not measure the metric): known-pose: gross_err_rate" in md
    assert step.read_text() == "earlier step\n" + md


def test_two_runs_of_one_baseline_suite_are_refused(tmp_path) -> None:
    base = load_baseline(_run(tmp_path / "a"))
    runs = load_runs([_run(tmp_path / "b"), _run(tmp_path / "c")])
    with pytest.raises(GateUsageError, match="both gated against"):
        gate(runs, base)


# -- --max-failure-rate ------------------------------------------------------------------------
def test_failure_rate_check_names_each_run_above_the_limit(tmp_path) -> None:
    ok = {"n": 10, "failures": 1}
    bad = {"n": 10, "failures": 4}
    check_failure_rate([(tmp_path / "ok", ok)], 0.1)  # 10% is not above 10%
    with pytest.raises(FailureRateError, match=r"bad \(4 of 10 views failed, 40.0%\)") as e:
        check_failure_rate([(tmp_path / "ok", ok), (tmp_path / "bad", bad)], 0.3)
    assert "ok (" not in str(e.value) and e.value.exit_code == 3
    check_failure_rate([(tmp_path / "empty", {"n": 0, "failures": 0})], 0.0)


# -- what n items can tell (docs/benchmark.md's table) --------------------------------------------
def test_the_interval_formulas_agree_with_the_bootstrap_and_the_gate(tmp_path) -> None:
    """The table's normal approximations against what the package computes: a summary's
    bootstrap interval of a rate, ``compare``'s paired bootstrap interval, and the power of
    the gate's sign-flip test at the smallest difference the table says it finds."""
    from beo_bench.bench.compare import paired_metric

    n, rng = 200, np.random.default_rng(4)
    gross = rng.random(n) < 0.2  # a > 15 deg rate near 20%
    summary = write_run(tmp_path / "r", "beo", [pose_row(i, rot_err_deg=30.0 if g else 5.0)
                        for i, g in enumerate(gross)], track="class-free")  # fmt: skip
    lo, hi = summary["ci95"]["gross_err_rate"]
    rate = float(gross.mean())
    assert (hi - lo) / 2 == pytest.approx(stats.rate_half_width(rate, n), rel=0.15)

    # 30% of the items right in one run and wrong in the other, as many each way
    a = {(i, 0): float(i % 20 < 6 and i % 2 == 1) for i in range(n)}
    b = {(i, 0): float(i % 20 < 6 and i % 2 == 0) for i in range(n)}
    r = paired_metric(a, b, "class_acc", n_resamples=2000)
    assert (r.hi - r.lo) / 2 == pytest.approx(stats.paired_half_width(0.3, n), rel=0.15)

    n, q = 100, 0.3
    delta = stats.detectable_difference(q, n)
    assert 0.14 < delta < 0.16 and stats.detectable_difference(q, 20) == float("inf")
    found = 0
    for k in range(200):
        u = np.random.default_rng(100 + k).random(n)
        d = np.where(u < (q + delta) / 2, 1.0, np.where(u < q, -1.0, 0.0))
        found += stats.sign_flip_p(d, permutations=999, seed=k) <= 0.05
    assert 0.7 <= found / 200 <= 0.9  # the table's 80% power, within sampling error


# -- the smoke set -------------------------------------------------------------------------------
def test_the_smoke_set_holds_every_suite_small() -> None:
    from beo_bench.bench.suites import SUITE_SETS, SUITES, expand_suites, get_suite

    smoke = SUITE_SETS["smoke"]
    assert set(smoke) == set(SUITES)
    assert all(0 < n <= 20 and n < get_suite(s).size for s, n in smoke.items())
    assert expand_suites(["smoke"]) == smoke
    assert expand_suites(["pick", "smoke", "known-pose"])["known-pose"] is None  # named last
    assert expand_suites(["pose-3dof+modelnet10"]) == {"pose-3dof+modelnet10": None}
    with pytest.raises(KeyError, match="suite sets \\['smoke'\\]"):
        expand_suites(["smok"])


def test_all_runs_the_smoke_set_at_its_sizes_unless_episodes_is_given(
    monkeypatch, tmp_path, capsys
) -> None:
    import beo_bench.bench.campaign as campaign
    from beo_bench.bench.suites import SUITE_SETS

    seen = []
    monkeypatch.setattr(campaign, "run_campaign", lambda c: [])

    def fake_campaign(suites, *a, **kw):
        seen.append((suites, kw))
        return type("C", (), {"leaderboards": tmp_path})

    monkeypatch.setattr(campaign, "Campaign", fake_campaign)
    argv = ["all", "--suites", "smoke", "--backends", "oracle", "--out", str(tmp_path)]
    assert main([*argv, "--max-failure-rate", "0.2"]) == 0
    assert main([*argv, "--episodes", "3"]) == 0
    assert seen[0][0] == SUITE_SETS["smoke"] and seen[0][1]["max_failure_rate"] == 0.2
    assert set(seen[1][0].values()) == {3} and seen[1][1]["max_failure_rate"] is None
    assert main(["all", "--suites", "smok", "--out", str(tmp_path)]) == 2
    assert "suite sets ['smoke']" in capsys.readouterr().err


def test_each_backend_is_tested_apart(tmp_path) -> None:
    """Runs of two backends against a baseline of both: each backend's metric is its own
    test (one backend's regression is not diluted by the other's runs)."""
    for backend, shift in (("beo", 30.0), ("icp", 0.0)):
        _run(tmp_path / "base" / backend, backend=backend)
        _run(tmp_path / "runs" / backend, shift, backend=backend)
    opts = GateOptions(metrics=("rot_err_deg_mean",))
    r = gate(load_runs([tmp_path / "runs"]), load_baseline(tmp_path / "base"), opts)
    assert [(v.backend, v.outcome, v.n_items) for v in r.verdicts] == [
        ("beo", "regression", 30),
        ("icp", "no difference", 30),
    ]


# -- tests too small to fail (issue 50, attack 11) ---------------------------------------------
def _collapse(tmp_path: Path, n: int) -> tuple[Path, Path]:
    """IoU and F-score falling from 1 to 0 on every one of ``n`` items."""
    a, b = tmp_path / f"a{n}", tmp_path / f"b{n}"
    write_run(a, "beo", [pose_row(i, iou=1.0, fscore=1.0) for i in range(n)], track="class-free")
    write_run(b, "beo", [pose_row(i, iou=0.0, fscore=0.0) for i in range(n)], track="class-free")
    return a, b


def test_a_gate_whose_items_cannot_reach_the_corrected_threshold_says_so(tmp_path, capsys) -> None:
    """The smallest p of n items is 2^-n; Holm's smallest threshold alpha / tests. Six items
    and two metrics: 1/64 <= 0.025, the collapse fails (3) and nothing is said. Five items
    and two metrics: 1/32 > 0.025, the same collapse cannot fail: it fails alone (3) and
    passes with two (0) -- loudly, on stderr and in every report."""
    assert stats.smallest_p(6) == 1 / 64 and stats.smallest_p(40, 999) == 1 / 1000
    two = ["--metrics", "iou_mean", "fscore_mean"]
    a6, b6 = _collapse(tmp_path, 6)
    assert main(["gate", str(b6), "--baseline", str(a6), *two]) == 3
    out = capsys.readouterr()
    assert "CANNOT FAIL" not in out.out and "cannot fail" not in out.err
    r6 = gate(load_runs([b6]), load_baseline(a6), GateOptions(("iou_mean",
                   "fscore_mean")))  # fmt: skip
    assert r6.cannot_fail == ()

    a5, b5 = _collapse(tmp_path, 5)
    assert main(["gate", str(b5), "--baseline", str(a5), "--metrics", "iou_mean"]) == 3
    capsys.readouterr()
    files = [str(tmp_path / f) for f in ("g.json", "g.xml", "g.md")]
    argv = ["gate", str(b5), "--baseline", str(a5), *two, "--json", files[0], "--junit",
            files[1], "--markdown", files[2]]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr()
    warned = [ln for ln in out.err.splitlines() if "gate cannot fail" in ln]
    assert len(warned) == 2 and all("5 items allow p >= 0.0312" in w for w in warned), out.err
    assert "above the corrected threshold 0.025" in warned[0] and "--episodes" in warned[0]
    assert out.out.count("  CANNOT FAIL   ") == 2 and "WARNING: 2 tests or suites" in out.out
    report = json.loads(Path(files[0]).read_text())
    assert report["passed"]
    assert [c["metric"] for c in report["cannot_fail"]] == ["iou_mean", "fscore_mean"]
    assert report["cannot_fail"][0]["p_min"] == 1 / 32
    skipped = [s.get("message", "") for s in ET.parse(files[1]).iter("skipped")]
    assert sum(m.startswith("cannot fail") for m in skipped) == 2
    assert "**Cannot fail**" in Path(files[2]).read_text()


def test_a_small_suite_pooled_with_large_ones_is_named_as_unable_to_fail(tmp_path) -> None:
    """Pooled with a 30-item suite, the 6-item suite's own collapse cannot reach 1/64 on
    its own under four tests (threshold 0.0125): the report names it; the pooled test and
    the large suite can fail."""
    for suite, n in (("pose-1dof", 30), ("pose-3dof", 6)):
        write_run(tmp_path / "base" / suite, "beo", [pose_row(i) for i in range(n)], suite,
                  track="class-free")  # fmt: skip
        write_run(tmp_path / "runs" / suite, "beo", [pose_row(i) for i in range(n)], suite,
                  track="class-free")  # fmt: skip
    r = gate(load_runs([tmp_path / "runs"]), load_baseline(tmp_path / "base"))
    assert len(r.verdicts) == 4 and r.passed
    assert {(c.suite, c.n_items) for c in r.cannot_fail} == {("pose-3dof@class-free", 6)}
    assert len(r.cannot_fail) == 4  # once per test it joins


# -- damaged inputs (issue 50, attacks 12-14) ---------------------------------------------------
def _collapsed_baseline(tmp_path: Path) -> tuple[Path, Path, dict]:
    """A baseline file of 6 items and a run whose IoU collapsed on every item (exit 3)."""
    a, b = _collapse(tmp_path, 6)
    write_baseline(load_runs([a]), tmp_path / "base.json")
    return b, tmp_path / "base.json", json.loads((tmp_path / "base.json").read_text())


def test_a_baseline_missing_an_items_value_is_refused_not_dropped(tmp_path, capsys) -> None:
    """Deleting one item's value used to drop the item from the test silently: 5 items,
    p = 1/32 > 0.025, and the verdict flipped from 3 to 0."""
    b, path, obj = _collapsed_baseline(tmp_path)
    two = ["--metrics", "iou_mean", "fscore_mean"]
    assert main(["gate", str(b), "--baseline", str(path), *two]) == 3
    capsys.readouterr()
    del obj["runs"][0]["values"]["iou_mean"]["3"]
    path.write_text(json.dumps(obj))
    assert main(["gate", str(b), "--baseline", str(path), *two]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "iou_mean has no values for item 3" in err[0], err
    assert str(path) in err[0] and "beo-bench baseline" in err[0]


@pytest.mark.parametrize(
    ("key", "value", "said"),
    [
        ("iou_mean", 7.5, "iou_mean of item 2 is 7.5, outside its range [0, 1]"),
        ("trans_err_cm_mean", 1e308, "trans_err_cm_mean of item 2 is 1e+308, outside"),
        ("rot_err_deg_mean", -3.0, "rot_err_deg_mean of item 2 is -3.0, outside its range"),
        ("edt_err_mean", 1e999, "edt_err_mean of item 2 is inf, outside"),
        ("class_acc", "1", "class_acc of item 2 is '1', not a number"),
    ],
)
def test_a_baseline_value_out_of_its_range_is_refused(tmp_path, capsys, key, value, said) -> None:
    b, path, obj = _collapsed_baseline(tmp_path)
    obj["runs"][0]["values"][key]["2"] = [value]
    path.write_text(json.dumps(obj))
    assert main(["gate", str(b), "--baseline", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and said in err[0] and str(path) in err[0], err


def test_the_ranges_agree_with_the_caps_a_view_is_clipped_at() -> None:
    from beo_bench.bench import tally
    from beo_bench.bench.columns import value_range

    assert value_range("trans_err_cm_mean")[1] == tally.TRANSLATION_CAP_CM
    assert value_range("size_err_pct_mean")[1] == tally.SIZE_CAP_PCT
    assert value_range("mssd_cm_mean")[1] == tally.MSSD_CAP_CM
    assert value_range("chamfer_l1_mean")[1] == tally.CHAMFER_CAP
    assert value_range("rot_err_deg_mean")[1] == tally.WORST_ROTATION_DEG
    assert value_range("pick_success") == (0.0, 1.0)


@pytest.mark.parametrize("side", ["run", "baseline"])
@pytest.mark.parametrize(
    "damage",
    [
        lambda text: text.replace("\n", "\n{not json\n", 1),  # a damaged line
        lambda text: "".join(text.splitlines(keepends=True)[:-1]),  # an item's rows lost
        lambda text: text + '{"item": 2',  # a torn last line
    ],
)
def test_a_damaged_results_file_exits_1_saying_so(tmp_path, capsys, side, damage) -> None:
    """It used to exit 2 with "run it with --episodes 20"; the help says 1 for a damaged
    results file."""
    a, b = _run(tmp_path / "a"), _run(tmp_path / "b")
    results = (b if side == "run" else a) / "results.jsonl"
    results.write_text(damage(results.read_text()))
    assert main(["gate", str(b), "--baseline", str(a)]) == 1
    err = [ln for ln in capsys.readouterr().err.strip().splitlines() if "warning" not in ln]
    assert len(err) == 1 and "the results file is damaged" in err[0], err
    assert str(results) in err[0] and "--resume" in err[0] and "--episodes" not in err[0]
