"""Tracks: the class hint is a property of the track a pose suite is
scored in, never of a backend's option. ``class-given`` gives the true class to every
backend that can use it, ``class-free`` to none; no backend changes track by default; the
track is part of a run's identity, its directory name and its summary; a campaign runs
hint-using backends in both tracks and the others in ``class-free`` only."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from beo_bench import backend as B
from beo_bench.bench.campaign import run_name
from beo_bench.bench.rows import read_rows
from beo_bench.bench.runner import RunConfig, RunError, run
from beo_bench.bench.suites import TRACKS, backend_tracks, get_suite, list_suites
from beo_bench.errors import UsageError
from beo_bench.types import Estimate, View

SPY = "test-hint-spy"


class HintSpy(B.Backend):
    """Says which class it was told: the hinted one, else class 0 (cheap and valid)."""

    name = SPY
    capabilities = B.Capabilities(class_hint=B.ClassHint.OPTIONAL)

    def predict(self, view: View) -> Estimate:
        probs = np.zeros(len(view.categories))
        probs[view.class_hint if view.class_hint is not None else 0] = 1.0
        shape = np.zeros((8, 8, 8), dtype=np.float32)
        shape[2:6, 2:6, 2:6] = 1.0
        pts = view.points()
        info = {"hint": view.class_hint}
        return Estimate(probs, np.eye(3), pts.mean(axis=0), np.full(3, 0.1), shape, info=info)


@pytest.fixture
def spy():
    B.register(HintSpy)  # scored in-process
    yield SPY
    B.unregister_backend(SPY)


def _run(out: Path, suite: str, backend: str, n: int, track: str | None = None, **kw) -> dict:
    s = get_suite(suite).with_overrides(size=n, track=track)
    return run(RunConfig(s, backend, kw.pop("opts", {})), out, progress=False, workers=1, **kw)


def test_pose_suites_have_two_tracks_and_default_to_class_free() -> None:
    tracked = [s for s in list_suites() if get_suite(s).class_hint]
    assert sorted(tracked) == [
        "modelnet10-1dof", "modelnet10-3dof", "pose-1dof", "pose-3dof", "pose-3dof-ood",
        "pose-3dof-percat",
    ]  # fmt: skip
    for name in list_suites():
        s = get_suite(name)
        if s.class_hint:
            assert s.track == "class-free" and s.tracks == TRACKS and not s.gives_class
            given = s.with_overrides(track="class-given")
            assert given.gives_class and given.label == f"{name}@class-given"
            assert given.with_overrides(size=3).track == "class-given"  # kept unless replaced
        else:
            assert s.track is None and s.tracks == (None,) and s.label == name


def test_a_track_on_a_suite_without_tracks_or_an_unknown_track_is_a_usage_error() -> None:
    with pytest.raises(UsageError, match=r"no tracks.*drop --track"):
        get_suite("known-pose").with_overrides(track="class-given")
    with pytest.raises(UsageError, match="class-given, class-free"):
        get_suite("pose-1dof").with_overrides(track="class-maybe")


def test_no_backend_takes_the_class_by_an_option() -> None:
    """The hint is the track's: the backends that can use it say so (their spec's
    capabilities) and have no option that turns it on or off."""

    def hint(name: str) -> B.ClassHint:
        spec = B.get_spec(name)
        return spec.capabilities_of(spec.parse({})).class_hint

    for name in ("icp", "icp-plain", "beo"):
        assert hint(name) is B.ClassHint.OPTIONAL
        assert "class_given" not in (B.backend_options(name) or {})
    with pytest.raises(UsageError, match="no option 'class_given'"):
        B.get_backend("icp", class_given=True)
    for name in ("oracle", "random"):
        assert hint(name) is B.ClassHint.NONE


def test_the_hint_is_given_in_the_class_given_track_only(tmp_path, spy) -> None:
    n = 4
    free = _run(tmp_path / "free", "pose-1dof", spy, n)  # the default track
    given = _run(tmp_path / "given", "pose-1dof", spy, n, track="class-given")
    free_rows = read_rows(tmp_path / "free" / "results.jsonl")
    given_rows = read_rows(tmp_path / "given" / "results.jsonl")
    # item i shows class i % 11: told it, the spy is right; not told, it says class 0
    assert [r["pred_class"] for r in given_rows] == [r["true_class"] for r in given_rows]
    assert all(r["class_given"] for r in given_rows)
    assert [r["pred_class"] for r in free_rows] == [0] * n
    assert not any(r["class_given"] for r in free_rows)
    # the summaries say which track and whether the backend can use the hint at all
    assert (free["track"], given["track"]) == ("class-free", "class-given")
    assert free["uses_class_hint"] is True and given["uses_class_hint"] is True
    assert "model_digest" in free and free["model_digest"] is None
    assert given["metrics"].get("class_given") is True and "class_acc" not in given["metrics"]
    assert free["metrics"]["class_acc"] == pytest.approx(1 / n)  # only item 0 is class 0
    on_disk = json.loads((tmp_path / "given" / "summary.json").read_text())
    assert on_disk["track"] == "class-given" and on_disk["uses_class_hint"] is True
    assert json.loads((tmp_path / "given" / "run.json").read_text())["suite"]["track"] == (
        "class-given"
    )


def test_suites_without_tracks_never_give_the_class(tmp_path, spy) -> None:
    s = _run(tmp_path / "kp", "known-pose", spy, 2)
    rows = read_rows(tmp_path / "kp" / "results.jsonl")
    assert s["track"] is None and not any(r["class_given"] for r in rows)


def test_the_track_is_part_of_a_runs_identity(tmp_path, spy) -> None:
    out = tmp_path / "run"
    _run(out, "pose-1dof", spy, 2, track="class-free")
    with pytest.raises(RunError, match="different run"):
        _run(out, "pose-1dof", spy, 3, track="class-given", resume=True)
    # and two tracks of one pair never share a directory
    names = {run_name("pose-1dof", "icp", {}, None, t) for t in TRACKS}
    assert names == {"pose-1dof@class-given__icp", "pose-1dof@class-free__icp"}
    assert run_name("known-pose", "icp", {"starts": 8}) == "known-pose__icp__starts=8"


def test_a_backend_that_cannot_use_the_hint_is_refused_the_class_given_track(tmp_path) -> None:
    with pytest.raises(UsageError, match=r"does not use the class hint.*--track class-free"):
        _run(tmp_path / "o", "pose-1dof", "oracle", 2, track="class-given")
    suite = get_suite("pose-3dof")
    assert backend_tracks(suite, True) == TRACKS
    assert backend_tracks(suite, False) == ("class-free",)
    assert backend_tracks(get_suite("tabletop"), True) == (None,)


def test_cli_run_takes_a_track_and_names_the_run_by_it(tmp_path, monkeypatch, capsys) -> None:
    from beo_bench.cli import main

    monkeypatch.chdir(tmp_path)
    base = ["run", "--suite", "pose-1dof", "--episodes", "2", "--workers", "1"]
    assert main([*base, "--backend", "oracle"]) == 0
    s = json.loads(
        (tmp_path / "runs" / "pose-1dof@class-free__oracle" / "summary.json").read_bytes()
    )
    assert s["track"] == "class-free" and s["uses_class_hint"] is False
    assert main([*base, "--backend", "oracle", "--track", "class-given"]) == 2
    assert "--track class-free" in capsys.readouterr().err
    kp = ["run", "--suite", "known-pose", "--backend", "oracle", "--track", "class-free"]
    assert main(kp) == 2
    assert "no tracks" in capsys.readouterr().err


def test_all_runs_hint_users_in_both_tracks_and_the_others_class_free(tmp_path) -> None:
    from beo_bench.cli import main

    runs = tmp_path / "runs"
    argv = ["all", "--suites", "pose-1dof", "known-pose", "--backends", "oracle",
            "icp-plain:mean_instances=4", "--episodes", "2", "--runs", str(runs),
            "--out", str(tmp_path / "board"), "--workers", "1"]  # fmt: skip
    assert main(argv) == 0
    made = sorted(p.parent.name for p in runs.glob("*/summary.json"))
    assert made == [
        "known-pose__icp-plain__mean_instances=4",
        "known-pose__oracle",
        "pose-1dof@class-free__icp-plain__mean_instances=4",
        "pose-1dof@class-free__oracle",
        "pose-1dof@class-given__icp-plain__mean_instances=4",
    ]
    for name in made:
        s = json.loads((runs / name / "summary.json").read_text())
        assert s["track"] == (name.split("@")[1].split("__")[0] if "@" in name else None)


class PerCategorySpy(HintSpy):
    """A backend that cannot answer without the class (per-category networks)."""

    name = "test-percat-spy"
    capabilities = B.Capabilities(class_hint=B.ClassHint.REQUIRED)


def test_a_backend_that_needs_the_hint_runs_in_the_class_given_track_only(tmp_path) -> None:
    """Per-category networks (Tables 5.1/5.2's protocol) choose the network by the class:
    the campaign runs them class-given only, and a class-free run of one is refused."""
    suite = get_suite("pose-3dof")
    assert backend_tracks(suite, True, needs_class_hint=True) == ("class-given",)
    B.register(PerCategorySpy)
    try:
        with pytest.raises(UsageError, match=r"needs the class hint.*--track class-given"):
            _run(tmp_path / "free", "pose-3dof", "test-percat-spy", 2, track="class-free")
        s = _run(tmp_path / "given", "pose-3dof", "test-percat-spy", 2, track="class-given")
        assert s["track"] == "class-given"
    finally:
        B.unregister_backend("test-percat-spy")


def test_the_per_category_suite_draws_only_its_classes(tmp_path, spy) -> None:
    """``pose-3dof-percat`` (Table 5.1's categories) holds car, airplane and sofa views only,
    and its views carry that class list."""
    suite = get_suite("pose-3dof-percat")
    assert suite.categories == ("airplane", "car", "sofa")
    _run(tmp_path / "p", "pose-3dof-percat", spy, 6, track="class-given")
    rows = read_rows(tmp_path / "p" / "results.jsonl")
    assert sorted({r["category"] for r in rows}) == ["airplane", "car", "sofa"]
    assert [r["true_class"] for r in rows] == [0, 1, 2, 0, 1, 2]
    with pytest.raises(UsageError, match="isolated suites only"):
        from dataclasses import replace

        replace(get_suite("tabletop"), categories=("car",))
