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

from beo_bench.bench import gate
from beo_bench.bench.gate import GateOptions, GateUsageError, holm, sign_flip_p
from beo_bench.cli import main
from tests.bench.synthetic_runs import pose_row, write_run

ROT = [float(x) for x in np.random.default_rng(0).uniform(0, 40, 30)]


def _run(path: Path, shift: float = 0.0, n: int = 30, **kw) -> Path:
    """A pose-1dof class-free run whose rotation errors are ``ROT + shift``."""
    rows = [pose_row(i, rot_err_deg=ROT[i] + shift) for i in range(n)]
    write_run(path, kw.pop("backend", "beo"), rows, track=kw.pop("track", "class-free"), **kw)
    return path


# -- the test and the correction -------------------------------------------------------------
def test_sign_flip_is_exact_on_few_items() -> None:
    d = np.array([1.0, 2.0, 3.0, 4.0, -0.5])
    every = [abs(sum(s * x for s, x in zip(signs, d, strict=True)))
             for signs in itertools.product((1, -1), repeat=len(d))]  # fmt: skip
    expected = np.mean([t >= abs(d.sum()) - 1e-12 for t in every])
    assert sign_flip_p(d) == pytest.approx(expected)
    assert sign_flip_p(np.array([1.0, 1.0, 1.0])) == pytest.approx(2 / 8)
    # items that do not differ change nothing under a flip: the same p
    assert sign_flip_p(np.array([1.0, 1.0, 1.0, 0.0, 0.0])) == pytest.approx(2 / 8)
    assert sign_flip_p(np.zeros(5)) == 1.0


def test_sign_flip_samples_many_items_deterministically() -> None:
    d = np.ones(40)  # only the two all-equal patterns reach |sum| = 40: p = 2 / 2^40
    p = sign_flip_p(d, permutations=2000, seed=3)
    assert p == pytest.approx(1 / 2001)  # nothing sampled reaches it; the observed counts
    noise = np.random.default_rng(1).normal(size=40)
    assert sign_flip_p(noise, 2000, 5) == sign_flip_p(noise, 2000, 5)  # seeded
    assert 0.05 < sign_flip_p(noise, 2000, 5) <= 1


def test_holm_by_hand() -> None:
    # sorted: 0.005 x 4 = 0.02, 0.01 x 3 = 0.03, 0.03 x 2 = 0.06, 0.04 x 1 -> max 0.06
    assert holm([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert holm([0.5]) == [0.5] and holm([0.9, 0.8]) == [1.0, 1.0]
    assert holm([0.2, 0.01]) == pytest.approx([0.2, 0.02]) and holm([]) == []


def test_holm_keeps_a_metric_that_alone_would_fail_from_failing_among_three(tmp_path) -> None:
    """Six items, every one worse by the same amount: the exact p is 2/64 = 0.031 on each
    metric. Alone it fails the gate; three such tests at once, Holm-corrected, do not."""
    keys = ("rot_err_deg_mean", "trans_err_cm_mean", "size_err_pct_mean")
    a = [pose_row(i) for i in range(6)]
    b = [pose_row(i, rot_err_deg=11.0, trans_err_cm=2.0, size_err_pct=6.0) for i in range(6)]
    write_run(tmp_path / "a", "beo", a, track="class-free")
    write_run(tmp_path / "b", "beo", b, track="class-free")
    runs, base = gate.load_runs([tmp_path / "b"]), gate.load_baseline(tmp_path / "a")
    alone = gate.gate(runs, base, GateOptions(metrics=keys[:1]))
    assert [v.outcome for v in alone.verdicts] == ["regression"]
    assert alone.verdicts[0].p == pytest.approx(2 / 64) == alone.verdicts[0].p_holm
    three = gate.gate(runs, base, GateOptions(metrics=keys))
    assert three.passed and {v.outcome for v in three.verdicts} == {"no difference"}
    assert all(v.p_holm == pytest.approx(3 * 2 / 64) for v in three.verdicts)


# -- verdicts -----------------------------------------------------------------------------------
def test_direction_comes_from_the_metric_spec(tmp_path) -> None:
    """Lower is better for the rotation error, higher for IoU: a rotation error up and an
    IoU up are a regression and an improvement; only the regression fails."""
    a = [pose_row(i, rot_err_deg=ROT[i], iou=0.4) for i in range(30)]
    b = [pose_row(i, rot_err_deg=ROT[i] + 5, iou=0.6) for i in range(30)]
    write_run(tmp_path / "a", "beo", a, track="class-free")
    write_run(tmp_path / "b", "beo", b, track="class-free")
    opts = GateOptions(metrics=("rot_err_deg_mean", "iou_mean"))
    r = gate.gate(gate.load_runs([tmp_path / "b"]), gate.load_baseline(tmp_path / "a"), opts)
    by = {v.metric: v for v in r.verdicts}
    assert by["rot_err_deg_mean"].outcome == "regression" and by["rot_err_deg_mean"].diff == 5
    assert by["iou_mean"].outcome == "improvement"
    assert not r.passed and r.regressions == (by["rot_err_deg_mean"],)
    # the other way round the rotation improves and IoU regresses
    back = gate.gate(gate.load_runs([tmp_path / "a"]), gate.load_baseline(tmp_path / "b"), opts)
    assert {v.metric: v.outcome for v in back.verdicts} == {
        "rot_err_deg_mean": "improvement",
        "iou_mean": "regression",
    }


def test_the_primary_metric_is_the_default(tmp_path) -> None:
    r = gate.gate(
        gate.load_runs([_run(tmp_path / "b", 30)]), gate.load_baseline(_run(tmp_path / "a"))
    )
    assert [v.metric for v in r.verdicts] == ["gross_err_rate"]
    assert gate.primary_metric("known-pose") == "class_acc"
    assert gate.primary_metric("pose-3dof+modelnet10") == "gross_err_rate"
    assert gate.primary_metric("tabletop") == "class_acc"
    assert gate.primary_metric("pick") == "pick_success"


def test_identical_runs_pass_with_p_one(tmp_path) -> None:
    r = gate.gate(gate.load_runs([_run(tmp_path / "b")]), gate.load_baseline(_run(tmp_path / "a")))
    assert r.passed and r.verdicts[0].p == 1.0 and r.verdicts[0].diff == 0.0


# -- the baseline file ------------------------------------------------------------------------
def test_a_baseline_file_gates_as_its_run_does(tmp_path) -> None:
    """Written from a run, the file gives the same verdicts as the run directory, NaN
    values (the class of a view told its class) included."""
    a = [pose_row(i, rot_err_deg=ROT[i]) for i in range(30)]
    b = [pose_row(i, rot_err_deg=ROT[i] + 3 * (i % 2)) for i in range(30)]
    write_run(tmp_path / "a", "beo", a)  # class-given: class_acc is NaN on every view
    write_run(tmp_path / "b", "beo", b)
    gate.write_baseline(gate.load_runs([tmp_path / "a"]), tmp_path / "base.json")
    obj = json.loads((tmp_path / "base.json").read_text())
    assert (obj["format"], obj["version"]) == ("beo-bench-baseline", 1)
    entry = obj["runs"][0]
    assert entry["label"] == "pose-1dof@class-given" and entry["views"]["3"] == [0]
    assert entry["values"]["class_acc"]["0"] == [None]
    assert entry["values"]["rot_err_deg_mean"]["4"] == [ROT[4]]
    opts = GateOptions(metrics=("rot_err_deg_mean", "gross_err_rate", "iou_mean"))
    runs = gate.load_runs([tmp_path / "b"])
    from_file = gate.gate(runs, gate.load_baseline(tmp_path / "base.json"), opts)
    from_dir = gate.gate(runs, gate.load_baseline(tmp_path / "a"), opts)
    assert [v.to_json() for v in from_file.verdicts] == [v.to_json() for v in from_dir.verdicts]
    with pytest.raises(GateUsageError, match="no view scored on 'class_acc'"):
        gate.gate(runs, gate.load_baseline(tmp_path / "base.json"), GateOptions(("class_acc",)))


def test_a_baseline_of_another_format_version_or_damaged_is_refused(tmp_path) -> None:
    gate.write_baseline(gate.load_runs([_run(tmp_path / "a")]), tmp_path / "base.json")
    obj = json.loads((tmp_path / "base.json").read_text())
    (tmp_path / "v2.json").write_text(json.dumps({**obj, "version": 2}))
    with pytest.raises(GateUsageError, match="format version 2; this beo-bench reads version 1"):
        gate.load_baseline(tmp_path / "v2.json")
    obj["runs"][0]["values"]["iou_mean"]["0"] = [0.5, 0.5]  # two values for one view
    (tmp_path / "bad.json").write_text(json.dumps(obj))
    with pytest.raises(GateUsageError, match=r"not a readable beo-bench baseline.*--out"):
        gate.load_baseline(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text('{"format": "something-else"}')
    with pytest.raises(GateUsageError, match="not a readable beo-bench baseline"):
        gate.load_baseline(tmp_path / "other.json")


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
        gate.gate(gate.load_runs([other]), gate.load_baseline(base))
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
    assert "has no metric 'pick_success'" in capsys.readouterr().err


# -- several suites, the reports ---------------------------------------------------------------
def test_runs_pair_with_their_suites_baseline_and_the_reports_say_it(
    tmp_path, capsys, monkeypatch
) -> None:
    """A directory of runs against a baseline of three: each run finds its suite label's
    entry; the one without a run is a skipped test case; the JUnit file has a test case per
    (suite, metric) and a failure element for the regression; the Markdown summary is
    written and appended to $GITHUB_STEP_SUMMARY."""
    _run(tmp_path / "base" / "one")
    _run(tmp_path / "base" / "two", track="class-given")
    write_run(tmp_path / "base" / "three", "beo", [pose_row(i) for i in range(6)], "known-pose",
              track=None)  # fmt: skip
    main(["baseline", str(tmp_path / "base"), "--out", str(tmp_path / "base.json")])
    _run(tmp_path / "runs" / "one", 30)  # class-free: every view now a gross error
    _run(tmp_path / "runs" / "two", track="class-given")
    step = tmp_path / "step.md"
    step.write_text("earlier step\n")
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(step))
    out = {k: tmp_path / f"gate.{k}" for k in ("json", "junit", "markdown")}
    argv = ["gate", str(tmp_path / "runs"), "--baseline", str(tmp_path / "base.json")]
    argv += [*itertools.chain.from_iterable((f"--{k}", str(p)) for k, p in out.items())]
    capsys.readouterr()
    assert main([*argv, "--metrics", "gross_err_rate", "iou_mean"]) == 3
    io = capsys.readouterr()
    assert io.err.startswith("beo-bench: gate failed: regression in pose-1dof@class-free")
    assert len(io.err.strip().splitlines()) == 1
    assert "gate: 1 regression in 4 tests" in io.out

    root = ET.parse(out["junit"]).getroot()
    assert (root.get("tests"), root.get("failures"), root.get("skipped")) == ("5", "1", "1")
    cases = {(ts.get("name"), tc.get("name")): tc for ts in root for tc in ts.iter("testcase")}
    assert set(cases) == {
        ("pose-1dof@class-free", "gross_err_rate"),
        ("pose-1dof@class-free", "iou_mean"),
        ("pose-1dof@class-given", "gross_err_rate"),
        ("pose-1dof@class-given", "iou_mean"),
        ("known-pose", "run"),
    }
    failed = [k for k, tc in cases.items() if tc.find("failure") is not None]
    assert failed == [("pose-1dof@class-free", "gross_err_rate")]
    assert cases[failed[0]].find("failure").get("message").startswith("regression: ")
    assert cases[("known-pose", "run")].find("skipped") is not None

    report = json.loads(out["json"].read_text())
    assert report["passed"] is False and report["regressions"] == 1
    assert report["not_run"] == ["known-pose"]
    md = out["markdown"].read_text()
    assert md.startswith("### beo-bench gate: 1 regression") and "**regression**" in md
    assert step.read_text() == "earlier step\n" + md


def test_two_runs_of_one_baseline_suite_are_refused(tmp_path) -> None:
    base = gate.load_baseline(_run(tmp_path / "a"))
    runs = gate.load_runs([_run(tmp_path / "b"), _run(tmp_path / "c")])
    with pytest.raises(GateUsageError, match="both gated against"):
        gate.gate(runs, base)


# -- --max-failure-rate ------------------------------------------------------------------------
def test_failure_rate_check_names_each_run_above_the_limit(tmp_path) -> None:
    ok = {"n": 10, "failures": 1}
    bad = {"n": 10, "failures": 4}
    gate.check_failure_rate([(tmp_path / "ok", ok)], 0.1)  # 10% is not above 10%
    with pytest.raises(gate.FailureRateError, match=r"bad \(4 of 10 views failed, 40.0%\)") as e:
        gate.check_failure_rate([(tmp_path / "ok", ok), (tmp_path / "bad", bad)], 0.3)
    assert "ok (" not in str(e.value) and e.value.exit_code == 3
    gate.check_failure_rate([(tmp_path / "empty", {"n": 0, "failures": 0})], 0.0)


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
    assert (hi - lo) / 2 == pytest.approx(gate.rate_half_width(rate, n), rel=0.15)

    # 30% of the items right in one run and wrong in the other, as many each way
    a = {(i, 0): float(i % 20 < 6 and i % 2 == 1) for i in range(n)}
    b = {(i, 0): float(i % 20 < 6 and i % 2 == 0) for i in range(n)}
    r = paired_metric(a, b, "class_acc", n_resamples=2000)
    assert (r.hi - r.lo) / 2 == pytest.approx(gate.paired_half_width(0.3, n), rel=0.15)

    n, q = 100, 0.3
    delta = gate.detectable_difference(q, n)
    assert 0.14 < delta < 0.16 and gate.detectable_difference(q, 20) == float("inf")
    found = 0
    for k in range(200):
        u = np.random.default_rng(100 + k).random(n)
        d = np.where(u < (q + delta) / 2, 1.0, np.where(u < q, -1.0, 0.0))
        found += sign_flip_p(d, permutations=999, seed=k) <= 0.05
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
