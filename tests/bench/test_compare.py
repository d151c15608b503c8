"""Paired comparisons (``beo-bench compare A B``, ``bench.compare.paired``) and the one
table of metric specs every results table reads (``bench.columns``)."""

from __future__ import annotations

import numpy as np
import pytest

from beo_bench.bench import columns
from beo_bench.bench.compare import ComparisonWarning, paired
from beo_bench.cli import main
from beo_bench.cli.common import COLUMNS, format_runs
from beo_bench.errors import UsageError
from tests.bench.synthetic_runs import pose_row, write_run


def _by_key(results) -> dict:
    return {r.key: r for r in results}


def test_b_better_on_every_item_is_better(tmp_path) -> None:
    rng = np.random.default_rng(0)
    rot = rng.uniform(20, 90, 40)
    a = [pose_row(i, rot_err_deg=float(r), iou=0.4) for i, r in enumerate(rot)]
    b = [pose_row(i, rot_err_deg=float(r) - 5, iou=0.5) for i, r in enumerate(rot)]
    write_run(tmp_path / "a", "icp-plain", a)
    write_run(tmp_path / "b", "beo", b)
    res = _by_key(paired(tmp_path / "a", tmp_path / "b"))
    rot_mean = res["rot_err_deg_mean"]
    assert rot_mean.diff == pytest.approx(-5.0)
    assert rot_mean.hi < 0 and rot_mean.verdict == "better"  # lower error is better
    assert res["iou_mean"].diff == pytest.approx(0.1) and res["iou_mean"].verdict == "better"
    assert rot_mean.n_items == 40 and rot_mean.n_views == 40
    # and the other way round it is worse
    back = _by_key(paired(tmp_path / "b", tmp_path / "a"))
    assert back["rot_err_deg_mean"].verdict == "worse" and back["iou_mean"].verdict == "worse"


def test_identical_runs_differ_by_exactly_zero(tmp_path) -> None:
    rng = np.random.default_rng(1)
    rows = [pose_row(i, rot_err_deg=float(r)) for i, r in enumerate(rng.uniform(0, 180, 30))]
    write_run(tmp_path / "a", "beo", rows)
    write_run(tmp_path / "b", "beo", rows)
    results = paired(tmp_path / "a", tmp_path / "b")
    assert {r.key for r in results} >= {"rot_err_deg_mean", "gross_err_rate", "iou_mean"}
    for r in results:
        assert (r.diff, r.lo, r.hi, r.verdict) == (0.0, 0.0, 0.0, "no difference"), r.key


def test_noise_alone_is_no_difference(tmp_path) -> None:
    """Two backends drawing their errors from the same distribution: the paired interval
    holds 0 (a fixed seed: the test is deterministic)."""
    rng = np.random.default_rng(2)
    for name in ("a", "b"):
        rot = rng.exponential(30, 200)
        iou = rng.uniform(0.2, 0.8, 200)
        rows = [pose_row(i, rot_err_deg=float(r), iou=float(u)) for i, (r, u) in
                enumerate(zip(rot, iou, strict=True))]  # fmt: skip
        write_run(tmp_path / name, "beo", rows)
    res = _by_key(paired(tmp_path / "a", tmp_path / "b"))
    for key in ("rot_err_deg_mean", "gross_err_rate", "iou_mean"):
        assert res[key].lo < 0 < res[key].hi and res[key].verdict == "no difference", key


def test_paired_mean_and_interval_by_hand(tmp_path) -> None:
    """A tabletop-like run: item 0 is a scene of two views, item 1 of one. B - A per view
    is -5, 0 and +30, so the paired mean difference over views is 25/3. Resampling *items*
    the statistic can only be -2.5 (item 0 twice), 25/3 or 30 (item 1 twice), each pair
    drawn with probability 1/4, so the 95% interval is exactly [-2.5, 30]; resampling views
    would reach -5 (all three draws the first view, 1/27 > 2.5%)."""
    a = [pose_row(0, 0, rot_err_deg=10.0), pose_row(0, 1, rot_err_deg=20.0),
         pose_row(1, 0, rot_err_deg=30.0)]  # fmt: skip
    b = [pose_row(0, 0, rot_err_deg=5.0), pose_row(0, 1, rot_err_deg=20.0),
         pose_row(1, 0, rot_err_deg=60.0)]  # fmt: skip
    write_run(tmp_path / "a", "icp", a)
    write_run(tmp_path / "b", "beo", b)
    r = _by_key(paired(tmp_path / "a", tmp_path / "b", keys=["rot_err_deg_mean"]))[
        "rot_err_deg_mean"
    ]
    assert (r.a, r.b) == (pytest.approx(20.0), pytest.approx(85 / 3))
    assert r.diff == pytest.approx(25 / 3)
    assert (r.lo, r.hi) == (pytest.approx(-2.5), pytest.approx(30.0))
    assert (r.n_items, r.n_views, r.verdict) == (2, 3, "no difference")


def test_a_failed_view_counts_at_its_worst(tmp_path) -> None:
    """B is 5 deg better on 9 views and fails the 10th: that view scores 180 deg (and IoU
    0), so B loses on the mean, as it does in its summary."""
    a = [pose_row(i, rot_err_deg=20.0) for i in range(10)]
    b = [pose_row(i, rot_err_deg=15.0) for i in range(9)] + [pose_row(9, failure="boom")]
    write_run(tmp_path / "a", "icp", a)
    sb = write_run(tmp_path / "b", "beo", b)
    res = _by_key(paired(tmp_path / "a", tmp_path / "b"))
    assert res["rot_err_deg_mean"].b == pytest.approx((9 * 15 + 180) / 10)
    assert res["rot_err_deg_mean"].diff == pytest.approx((9 * -5 + 160) / 10)
    assert res["iou_mean"].b == pytest.approx(0.45)
    # one definition: the paired means are the summary's
    for key in ("rot_err_deg_mean", "gross_err_rate", "iou_mean", "fscore_mean"):
        assert res[key].b == pytest.approx(sb["metrics"][key]), key


def test_paired_means_are_the_summary_means(tmp_path) -> None:
    """One definition: on runs over the same items, each paired metric's A and B means are
    the two summaries' values (failed views included at the summary's worst case), so a
    verdict never contradicts the tables it sits beside."""
    rng = np.random.default_rng(3)

    def rows(fail_every: int) -> list[dict]:
        return [
            pose_row(i, failure="boom")
            if i % fail_every == 0
            else pose_row(i, rot_err_deg=float(rng.uniform(0, 180)), trans_err_cm=float(
                rng.uniform(0, 8)), size_err_pct=float(rng.uniform(0, 30)), iou=float(
                rng.uniform()), iou_cam=float(rng.uniform()), edt_err=float(rng.uniform(0, 900)),
                fscore=float(rng.uniform()), chamfer_l1=float(rng.uniform(0, 0.1)),
                correct=bool(rng.uniform() < 0.7))
            for i in range(30)
        ]  # fmt: skip

    # failures count at their worst case in both (summary.view_values), so every paired
    # mean is the summary's, with failures on different views or none
    for fail_a, fail_b in ((4, 7), (99, 99)):
        sa = write_run(tmp_path / "a", "hbeo", rows(fail_a), track="class-free", uses_hint=False)
        sb = write_run(tmp_path / "b", "beo", rows(fail_b), track="class-free")
        results = paired(tmp_path / "a", tmp_path / "b")
        assert {r.key for r in results} >= {"rot_err_deg_mean", "class_acc", "fscore_mean"}
        for r in results:
            assert r.a == pytest.approx(sa["metrics"][r.key]), r.key
            assert r.b == pytest.approx(sb["metrics"][r.key]), r.key


def test_class_accuracy_is_paired_only_where_both_were_scored(tmp_path) -> None:
    a = [pose_row(i, correct=i % 2 == 0) for i in range(8)]
    b = [pose_row(i, correct=True) for i in range(8)]
    sa = write_run(tmp_path / "a", "hbeo", a, track="class-free", uses_hint=False)
    write_run(tmp_path / "b", "beo", b, track="class-free")
    res = _by_key(paired(tmp_path / "a", tmp_path / "b"))
    assert res["class_acc"].a == pytest.approx(sa["metrics"]["class_acc"]) == 0.5
    assert res["class_acc"].diff == pytest.approx(0.5)
    # a class-given run is not scored on the class: nothing to pair
    write_run(tmp_path / "c", "beo", b, track="class-given")
    write_run(tmp_path / "d", "icp", b, track="class-given")
    assert "class_acc" not in _by_key(paired(tmp_path / "c", tmp_path / "d"))


@pytest.mark.parametrize(
    "other, why",
    [
        ({"suite": "pose-3dof"}, "suite 'pose-1dof' vs 'pose-3dof'"),
        ({"version": 99}, "suite version"),
        ({"track": "class-free"}, "track 'class-given' vs 'class-free'"),
        ({"seed": 7}, "seed 2000 vs 7"),
        # the sensor is part of what a run scored (rundir.ItemsIdentity), as for the gate
        ({"sensor": "kinect-v1"}, "sensor 'ideal' vs 'kinect-v1'"),
    ],
)
def test_runs_of_different_suites_versions_tracks_or_seeds_are_refused(
    tmp_path, capsys, other, why
) -> None:
    rows = [pose_row(i) for i in range(4)]
    write_run(tmp_path / "a", "icp", rows)
    write_run(tmp_path / "b", "beo", rows, **other)
    with pytest.raises(UsageError, match=why):
        paired(tmp_path / "a", tmp_path / "b")
    assert main(["compare", str(tmp_path / "a"), str(tmp_path / "b")]) == 2
    err = capsys.readouterr()
    assert "cannot pair" in err.err and "--table" in err.err and err.out == ""
    # the side-by-side table still lists them
    assert main(["compare", "--table", str(tmp_path / "a"), str(tmp_path / "b")]) == 0


def test_a_backend_without_the_hint_pairs_with_either_track(tmp_path) -> None:
    """hbeo cannot use the class hint, so its class-free run stands in the class-given
    track: it may be paired with a class-given icp run (the same items, the same rules)."""
    rows = [pose_row(i) for i in range(4)]
    write_run(tmp_path / "hbeo", "hbeo", rows, track="class-free", uses_hint=False)
    write_run(tmp_path / "icp", "icp", rows, track="class-given")
    assert paired(tmp_path / "icp", tmp_path / "hbeo")
    # a class-free run of a backend that does use the hint is not class-given
    write_run(tmp_path / "beo", "beo", rows, track="class-free", uses_hint=True)
    with pytest.raises(UsageError, match="track"):
        paired(tmp_path / "icp", tmp_path / "beo")


def test_different_items_warn_and_pair_the_common_ones(tmp_path) -> None:
    write_run(tmp_path / "a", "icp", [pose_row(i, rot_err_deg=20.0) for i in range(10)])
    write_run(tmp_path / "b", "beo", [pose_row(i, rot_err_deg=10.0) for i in range(4)])
    with pytest.warns(ComparisonWarning, match="comparing the 4 they have in common"):
        res = _by_key(paired(tmp_path / "a", tmp_path / "b"))
    assert res["rot_err_deg_mean"].n_items == 4
    write_run(tmp_path / "c", "beo", [pose_row(i) for i in range(20, 24)])
    with pytest.raises(UsageError, match="no item in common"):
        paired(tmp_path / "a", tmp_path / "c")


def test_only_the_items_the_summary_covers_are_paired(tmp_path) -> None:
    """A results file may hold more items than its summary (a run summarised over its first
    items): those extra items are not compared."""
    write_run(tmp_path / "a", "icp", [pose_row(i, rot_err_deg=20.0) for i in range(6)], size=3)
    write_run(tmp_path / "b", "beo", [pose_row(i, rot_err_deg=10.0) for i in range(3)])
    res = _by_key(paired(tmp_path / "a", tmp_path / "b"))
    assert res["rot_err_deg_mean"].n_items == 3


def test_cli_compare_prints_the_paired_verdicts(tmp_path, capsys) -> None:
    a = [pose_row(i, rot_err_deg=30.0 + i) for i in range(12)]
    b = [pose_row(i, rot_err_deg=10.0 + i) for i in range(12)]
    write_run(tmp_path / "a", "icp-plain", a)
    write_run(tmp_path / "b", "beo", b, digest="0123456789abcdef")
    write_run(tmp_path / "c", "icp", a, kwargs={"starts": 48})
    assert main(["compare", str(tmp_path / "a"), str(tmp_path / "b"), str(tmp_path / "c")]) == 0
    out = capsys.readouterr().out
    table, first, second = out.split("\n\n")
    assert "pose-1dof@class-given" in table and "icp (starts=48)" in table
    assert "paired: B = beo" in first and "12 items in common" in first
    line = next(x for x in first.splitlines() if "rot. error mean" in x)
    assert line.split()[-1] == "better" and "-20.0" in line
    line = next(x for x in second.splitlines() if "rot. error mean" in x)
    assert line.endswith("no difference") and "[+0.0, +0.0]" in line
    # one footnote, right under the last verdict table: the verdicts are not a gate
    note = [x for x in out.splitlines() if "multiple comparisons" in x]
    assert note == [second.rstrip("\n").splitlines()[-1]], out
    assert "per metric" in note[0] and "NOT corrected" in note[0]
    assert "beo-bench gate" in note[0] and "Holm" in note[0] and "exit status 3" in note[0]


def test_cli_compare_help_says_its_verdicts_are_uncorrected_and_points_to_gate(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["compare", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "not corrected for multiple comparisons" in out
    assert "beo-bench gate" in out and "Holm-corrected" in out and "exit status 3" in out


def test_cli_compare_table_only_has_no_verdicts_and_no_footnote(tmp_path, capsys) -> None:
    write_run(tmp_path / "a", "icp", [pose_row(i) for i in range(3)])
    write_run(tmp_path / "b", "beo", [pose_row(i) for i in range(3)])
    assert main(["compare", "--table", str(tmp_path / "a"), str(tmp_path / "b")]) == 0
    assert "multiple comparisons" not in capsys.readouterr().out


def test_compare_needs_the_results_beside_the_summary(tmp_path, capsys) -> None:
    write_run(tmp_path / "a", "icp", [pose_row(i) for i in range(3)])
    write_run(tmp_path / "b", "beo", [pose_row(i) for i in range(3)])
    (tmp_path / "b" / "results.jsonl").unlink()
    assert main(["compare", str(tmp_path / "a"), str(tmp_path / "b" / "summary.json")]) == 2
    assert "has no results.jsonl" in capsys.readouterr().err


def test_every_table_reads_the_one_metric_spec_table() -> None:
    """The plain-text table's columns are the specs."""
    assert all(isinstance(c, columns.MetricSpec) for c in COLUMNS)
    assert [c.key for c in COLUMNS] == [m.key for m in columns.METRICS if m.brief]
    s = {"suite": "pose-1dof", "track": "class-free", "backend": "beo", "n": 2, "failures": 0,
         "metrics": {"rot_err_deg_mean": 12.3, "gross_err_rate": 0.5}}  # fmt: skip
    head, _, row = format_runs([s]).splitlines()
    assert head.endswith("rot mean    >15deg")
    assert row.split()[-2:] == ["12.3", "50.0%"] and row.startswith("pose-1dof@class-free beo")
    for m in columns.METRICS:
        assert len(m.short) <= 9, m.key
