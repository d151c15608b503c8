"""The sensor axis of the suites: a run's depth sensor names it and is part of its identity
(a run at the suite's own sensor keeps the name it always had, and an old record resumes),
``--sensor`` parses case-insensitively and refuses a typo with the closest name (exit 2),
and the leaderboard gives runs under another sensor their part of the suite's page and a
robustness table paired on the same items, leaving a page of the suite's own sensor as it
was."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from beo_bench.bench import rundir
from beo_bench.bench.pages.leaderboard import regenerate
from beo_bench.bench.runs import RunConfig, RunContext, RunUsageError, run_name
from beo_bench.bench.suites import SUITES, get_suite
from beo_bench.cli import build_parser, main
from beo_bench.cli.options import SENSOR_NAMES
from beo_bench.scenes.sensors import SENSORS, SensorError
from tests.bench.synthetic_runs import pose_row, write_run

ROT = np.random.default_rng(1).exponential(40, 16)
DIGEST = "0123456789abcdef"


def _rows(scale: float) -> list[dict]:
    return [pose_row(i, rot_err_deg=float(r * scale)) for i, r in enumerate(ROT)]


# -- the suite and the run's name and identity --------------------------------------------------
def test_tabletop_moves_to_kinect_v1_at_a_new_version_and_the_others_stay_ideal() -> None:
    tabletop = get_suite("tabletop")
    assert tabletop.sensor == "kinect-v1" and tabletop.version == 5
    assert "noise" not in tabletop.record() and tabletop.record()["sensor"] == "kinect-v1"
    others = {n: (s.sensor, s.version) for n, s in SUITES.items() if n != "tabletop"}
    assert {v[0] for v in others.values()} == {"ideal"}
    assert others["pose-3dof"][1] == 4  # its scores stand
    assert others["pick"][1] == 5  # its episodes' targets are balanced now, not the sensor


def test_a_sensor_other_than_the_suite_own_names_the_run() -> None:
    s = get_suite("pose-3dof").with_overrides(track="class-free")
    assert s.sensor_tag is None and s.label == "pose-3dof@class-free"
    d = s.with_sensor("d435")
    assert d.sensor == "d435" and d.label == "pose-3dof@class-free~d435"
    assert run_name(d.name, "icp", {}, None, d.track, d.sensor_tag) == (
        "pose-3dof@class-free~d435__icp"
    )
    # the suite's own sensor, named or not, keeps today's names
    assert s.with_sensor("ideal") == s and s.with_sensor(None) == s
    assert run_name(s.name, "icp", {"starts": 48}, 7, s.track, s.sensor_tag) == (
        "pose-3dof@class-free__icp__starts=48_suite_seed=7"
    )
    tabletop = get_suite("tabletop")
    assert tabletop.label == "tabletop" and tabletop.with_sensor("ideal").label == "tabletop~ideal"
    # a class subset and a dataset suite keep their base suite's own sensor
    assert get_suite("pose-3dof+modelnet10").with_sensor("kinect-v1").sensor_tag == "kinect-v1"
    with pytest.raises(SensorError, match="did you mean 'kinect-v1'"):
        s.with_sensor("kinect")


def test_the_sensor_is_part_of_the_identity_a_resume_checks(tmp_path) -> None:
    suite = get_suite("pose-1dof")
    ideal = rundir.run_identity(RunContext.of(RunConfig(suite, "oracle")))
    kinect = rundir.run_identity(RunContext.of(RunConfig(suite.with_sensor("kinect-v1"), "oracle")))
    assert ideal["suite"]["sensor"] == "ideal" and kinect["suite"]["sensor"] == "kinect-v1"
    rundir.check_same_run(ideal, ideal, tmp_path)
    with pytest.raises(RunUsageError, match="sensor"):
        rundir.check_same_run(ideal, kinect, tmp_path)
    # a run recorded before sensors existed (noise: false or true) is refused in one line
    legacy = json.loads(json.dumps(ideal))
    del legacy["suite"]["sensor"]
    for noise in (False, True):
        legacy["suite"]["noise"] = noise
        with pytest.raises(RunUsageError, match=r"older beo-bench.*new --out") as e:
            rundir.check_same_run(legacy, ideal, tmp_path)
        assert "\n" not in str(e.value)


# -- the command line -------------------------------------------------------------------------
def test_sensor_parses_in_any_case_on_run_all_and_train() -> None:
    p = build_parser()
    args = p.parse_args(["run", "--suite", "pose-1dof", "--backend", "oracle", "--sensor", "D435"])
    assert args.sensor == "d435"
    assert p.parse_args(["run", "--suite", "tabletop", "--backend", "oracle"]).sensor is None
    args = p.parse_args(["all", "--sensor", "ideal", "Kinect-V1"])
    assert args.sensor == ["ideal", "kinect-v1"]
    assert p.parse_args(["train", "hbeo", "--sensor", "kinect-v1"]).sensor == "kinect-v1"
    # the help, spelt out so that parsing imports no renderer, names every sensor
    assert all(s in SENSOR_NAMES for s in SENSORS)


@pytest.mark.parametrize(
    "command", [["run", "--suite", "pose-1dof", "--backend", "oracle"], ["all"]]
)
def test_a_bad_sensor_name_exits_2_with_the_closest_one(command, capsys) -> None:
    with pytest.raises(SystemExit) as e:
        main([*command, "--sensor", "kinect"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "did you mean 'kinect-v1'" in err and "--sensor" in err


def test_train_beo_refuses_a_sensor(capsys) -> None:
    assert main(["train", "beo", "--sensor", "d435"]) == 2
    assert "--sensor applies to hbeo" in capsys.readouterr().err


# -- the leaderboard ----------------------------------------------------------------------------
def _sensor_runs(runs, sensors=("ideal", "kinect-v1", "d435")) -> None:
    """beo, icp-plain and icp under each sensor, their errors growing with its noise."""
    for k, sensor in enumerate(sensors):
        grow = 1.0 + 0.5 * k
        write_run(runs / f"icp-plain-{sensor}", "icp-plain", _rows(grow), sensor=sensor)
        write_run(runs / f"icp-{sensor}", "icp", _rows(0.5 * grow), sensor=sensor)
        write_run(runs / f"beo-{sensor}", "beo", _rows(0.7 * grow), sensor=sensor, digest=DIGEST)


def test_runs_under_other_sensors_get_their_part_and_a_robustness_table(tmp_path) -> None:
    runs = tmp_path / "runs"
    _sensor_runs(runs)
    regenerate(runs, tmp_path / "board")
    md = (tmp_path / "board" / "pose-1dof.md").read_text()
    # the suite's own sensor first, then the robustness table, then the other sensors' parts
    own, rest = md.split("## Robustness across sensors")
    assert "## class-given track" in own and "sensor" not in own.split("\n", 3)[3]
    table, parts = rest.split("## sensor kinect-v1")
    assert "## sensor d435" in parts and parts.index("#### seed 2000, 16 items") > 0
    head = next(ln for ln in table.splitlines() if ln.startswith("| backend | rot."))
    assert "`ideal` -> `kinect-v1` -> `d435`" in head
    icp_plain = next(ln for ln in table.splitlines() if ln.startswith("| icp-plain | "))
    means = [np.minimum(g * ROT, 180).mean() for g in (1.0, 1.5, 2.0)]
    assert icp_plain.split(" | ")[1] == " -> ".join(f"{m:.1f}" for m in means)
    # each sensor's run paired with the ideal one, on the same 16 items
    paired = json.loads((tmp_path / "board" / "pose-1dof_paired.json").read_text())
    pairs = [p for p in paired if p["pairing"] == "sensor"]
    one = next(
        p
        for p in pairs
        if (p["method"], p["sensor"], p["metric"]) == ("icp-plain", "d435", "rot_err_deg_mean")
    )
    assert one["baseline_sensor"] == "ideal" and one["items"] == 16
    assert one["diff"] == pytest.approx(means[2] - means[0])
    assert one["ci95"][0] > 0 and one["verdict"] == "worse"
    assert "| icp-plain | `d435` | `ideal` | 16 | " in table and "**worse**" in table
    # the other sensors' parts have their own verdicts, marked with the sensor
    assert {p.get("sensor") for p in paired if p["pairing"] == "baseline"} == {
        None,
        "kinect-v1",
        "d435",
    }
    # their plots are their own, beside the suite's own sensor's
    assert (tmp_path / "board" / "pose-1dof_d435_class-given_rot_cdf.png").exists()
    assert (tmp_path / "board" / "pose-1dof_class-given_rot_cdf.png").exists()
    readme = (tmp_path / "board" / "README.md").read_text()
    assert "### pose-1dof: robustness across sensors" in readme


def test_a_sensor_run_over_fewer_items_puts_every_cell_on_the_common_items(tmp_path) -> None:
    """``pick``'s sensor sections run 200 of its 500 episodes: the robustness table's
    ``ideal -> kinect-v1`` cells are then both over the 200 (the paired rows' items), never
    the ideal run's 500 beside the sensor's 200, and a note says so."""
    runs = tmp_path / "runs"
    size = len(ROT)
    write_run(runs / "icp-ideal", "icp", _rows(1.0), size=size)
    short = [r for r in _rows(1.5) if r["item"] < 10]
    write_run(runs / "icp-kinect", "icp", short, sensor="kinect-v1", size=10)
    regenerate(runs, tmp_path / "board")
    table = (tmp_path / "board" / "pose-1dof.md").read_text().split("## Robustness")[1]
    row = next(ln for ln in table.splitlines() if ln.startswith("| icp | "))
    capped = np.minimum(ROT, 180)
    first, second = capped[:10].mean(), np.minimum(1.5 * ROT, 180)[:10].mean()
    assert capped.mean() != pytest.approx(first, abs=0.05)  # the test would tell them apart
    assert row.split(" | ")[1] == f"{first:.1f} -> {second:.1f}"
    assert "over the items all of its runs scored" in table


def test_a_page_of_the_suite_own_sensor_is_as_before_sensors(tmp_path) -> None:
    """The same runs, recorded as before sensors existed (``noise: false``, no ``sensor``)
    and as now, give the same pages byte for byte, with no word of sensors."""
    new, old = tmp_path / "new", tmp_path / "old"
    _sensor_runs(new, sensors=("ideal",))
    write_run(new / "hbeo", "hbeo", _rows(0.6), track="class-free", uses_hint=False)
    shutil.copytree(new, old)
    for f in old.rglob("summary.json"):
        s = json.loads(f.read_text())
        del s["sensor"]
        record = s["provenance"]["suite"]
        del record["sensor"]
        record["noise"] = False
        f.write_text(json.dumps(s))
    regenerate(new, tmp_path / "board-new")
    regenerate(old, tmp_path / "board-old")
    for name in ("pose-1dof.md", "README.md", "pose-1dof_paired.json"):
        a = (tmp_path / "board-new" / name).read_bytes()
        assert a == (tmp_path / "board-old" / name).read_bytes(), name
    md = (tmp_path / "board-new" / "pose-1dof.md").read_text()
    assert "Robustness" not in md and "## sensor" not in md and "sensor" not in md.lower()


# -- a tiny campaign under two sensors, end to end ---------------------------------------------
def test_a_tiny_campaign_under_two_sensors_pairs_its_runs(tmp_path) -> None:
    """``all --sensor ideal kinect-v1`` on three items: the runs are named by the sensor
    where it is not the suite's own, record it, resume, and the page pairs them."""
    from beo_bench.bench.campaign import Campaign, run_campaign
    from tests.bench.runs import FAST_RANDOM

    c = Campaign(
        {"known-pose": 3},
        [("oracle", {}), ("random", FAST_RANDOM)],
        runs=tmp_path / "runs",
        leaderboards=tmp_path / "board",
        workers=1,
        progress=False,
        sensors=("ideal", "kinect-v1"),
    )
    run_campaign(c)
    names = sorted(p.name for p in (tmp_path / "runs").iterdir())
    assert names == [
        "known-pose__oracle",
        "known-pose__random__mean_instances=4",
        "known-pose~kinect-v1__oracle",
        "known-pose~kinect-v1__random__mean_instances=4",
    ]
    summary = json.loads((tmp_path / "runs" / names[2] / "summary.json").read_text())
    assert summary["sensor"] == "kinect-v1" and summary["suite"] == "known-pose"
    assert summary["provenance"]["suite"]["sensor"] == "kinect-v1"
    # the sensor changed what random saw (its draws are seeded by the view's bytes)
    rows = {
        n: [json.loads(ln) for ln in (tmp_path / "runs" / n / "results.jsonl").open()]
        for n in names
    }
    assert [r["iou"] for r in rows[names[1]]] != [r["iou"] for r in rows[names[3]]]
    assert [r["key"] for r in rows[names[1]]] == [r["key"] for r in rows[names[3]]]
    md = (tmp_path / "board" / "known-pose.md").read_text()
    assert "## Robustness across sensors" in md and "## sensor kinect-v1" in md
    paired = json.loads((tmp_path / "board" / "known-pose_paired.json").read_text())
    pairs = {(p["method"], p["metric"]): p for p in paired if p["pairing"] == "sensor"}
    assert {m for m, _ in pairs} == {"oracle", "random (mean_instances=4)"}
    oracle = pairs[("oracle", "iou_mean")]
    assert (oracle["items"], oracle["diff"], oracle["verdict"]) == (3, 0.0, "no difference")
    assert all(
        p["sensor"] == "kinect-v1" and p["baseline_sensor"] == "ideal" for p in pairs.values()
    )
    # run again: every run resumes with nothing left to do
    before = {n: (tmp_path / "runs" / n / "results.jsonl").read_bytes() for n in names}
    run_campaign(c)
    assert before == {n: (tmp_path / "runs" / n / "results.jsonl").read_bytes() for n in names}


def test_the_doc_tables_read_the_suite_own_sensor(tmp_path) -> None:
    """docs/results.md's tables quote a suite's own sensor: a run under another one, even
    of more items, is not the row they read, nor are its pairings."""
    from beo_bench.bench.doctables.boards import Boards, MissingFigureError

    runs = tmp_path / "runs"
    write_run(runs / "icp", "icp", _rows(1.0)[:8], size=16)
    write_run(runs / "icp-d435", "icp", _rows(2.0), sensor="d435")
    write_run(runs / "beo", "beo", _rows(0.5)[:8], size=16)
    write_run(runs / "beo-d435", "beo", _rows(0.1), sensor="d435")
    write_run(runs / "hbeo-d435", "hbeo", _rows(0.1), sensor="d435")  # under d435 alone
    regenerate(runs, tmp_path / "board")
    b = Boards(tmp_path / "board")
    assert b.row("pose-1dof", "icp", "class-given")["n"] == 8
    assert "sensor" not in b.pair("pose-1dof", "beo", "icp", "rot_err_deg_mean", "class-given")
    with pytest.raises(MissingFigureError):
        b.pair("pose-1dof", "hbeo", "icp", "rot_err_deg_mean", "class-given")
