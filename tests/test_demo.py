"""``beo-bench demo``'s pieces: the scene it shows is one the ground-truth planner picks
(and the picture shows that grasp), and the library functions it shares with ``objects``,
``view``, ``pick-check`` and ``cache info`` run on small sizes."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest

from beo_bench import demo, inspection
from beo_bench.cli import main
from beo_bench.envs.pickcheck import ground_truth_pick_check
from beo_bench.errors import BeoBenchError
from beo_bench.sceneview import grasp_outline, view_scene


@pytest.fixture(scope="module")
def chosen() -> demo.PickedSeed:
    return demo.picked_seed("test")


def test_the_demo_scene_is_the_first_seed_the_planner_picks(chosen) -> None:
    # the seeds passed over are every earlier one, each a failure, and the chosen one lifts
    assert [s for s, _ in chosen.skipped] == list(range(chosen.seed))
    assert all(why != "success" for _, why in chosen.skipped)
    episode = ground_truth_pick_check(episodes=1, seed=chosen.seed).episodes[0]
    assert episode.success and episode.category == chosen.target
    # deterministic: searching again from it finds it at once
    again = demo.picked_seed("test", start=chosen.seed)
    assert (again.seed, again.target, again.skipped) == (chosen.seed, chosen.target, ())


def test_no_picked_seed_in_range_is_an_error_saying_what_to_run(monkeypatch) -> None:
    from beo_bench.envs import pickcheck

    def never(episodes, seed, **kw):
        ep = pickcheck.PickEpisode(seed, "box", "k", 1, False, "no_grasp")
        return pickcheck.PickCheck([ep])

    monkeypatch.setattr(pickcheck, "ground_truth_pick_check", never)
    with pytest.raises(BeoBenchError, match=r"seeds 0\.\.2 .*beo-bench pick-check"):
        demo.picked_seed("test", limit=3)


def test_the_scene_picture_outlines_the_planners_grasp(chosen, tmp_path) -> None:
    r = view_scene(chosen.seed, tmp_path, rrd=False, image_size=(160, 120))
    assert (
        r.grasps > 0
        and r.target == chosen.target
        and r.png == tmp_path / (f"scene_{chosen.seed}.png")
    )
    assert f"seed {chosen.seed}:" in r.text() and "recording" not in r.text()
    img = mpimg.imread(r.png)[..., :3]
    # the outline's yellow (#ffc800) is on the picture (no object colour is that yellow)
    yellow = (img[..., 0] > 0.9) & (np.abs(img[..., 1] - 0.784) < 0.08) & (img[..., 2] < 0.2)
    assert yellow.sum() > 20


def test_grasp_outline_projects_the_gripper_into_the_image(chosen) -> None:
    import gymnasium as gym

    env = gym.make("BEOPick-v0", split="test", image_size=(160, 120))
    try:
        obs, _ = env.reset(seed=chosen.seed)
        best = env.unwrapped.ground_truth_grasps()[0]
    finally:
        env.close()
    lines = grasp_outline(best, obs)
    assert len(lines) == 3 * 12  # palm and two fingers, 12 edges each, all in front
    pts = np.concatenate(lines)
    inside = (pts[:, 0] >= 0) & (pts[:, 0] < 160) & (pts[:, 1] >= 0) & (pts[:, 1] < 120)
    assert inside.mean() > 0.5  # the gripper is over the target, in view


def test_objects_report_on_a_small_set(tmp_path) -> None:
    objects, counts = inspection.select_objects("test", ["box", "mug"], per_category=1)
    r = inspection.summarise_objects(
        objects, "test", resolution=8, workers=1, sheet=tmp_path / "sheet.png"
    )
    assert counts is None and len(r.stats) == 2 and r.sheet == tmp_path / "sheet.png"
    assert r.sheet.stat().st_size > 0
    text = r.text()
    assert text.splitlines()[0].startswith("category") and "box" in text and "mug" in text
    assert "2 instances processed" in text and "voxels 8^3" in text
    assert f"contact sheet: {tmp_path / 'sheet.png'}" in text


def test_pick_check_report_names_its_seeds() -> None:
    r = inspection.pick_check(episodes=2, seed=3, split="test", progress=False)
    assert r.episodes == 2 and len(r.result.episodes) == 2
    assert "split test, seeds 3..4" in r.text() and "| **all** | 2 |" in r.text()


def test_cache_report_lists_kinds_and_models(tmp_path, monkeypatch) -> None:
    from beo_bench.objects import cache

    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path))
    (tmp_path / "voxels").mkdir()
    (tmp_path / "voxels" / "a.npz").write_bytes(b"x" * 2048)
    (tmp_path / "models" / "beo" / "broken").mkdir(parents=True)
    r = inspection.cache_report()
    voxels = next(k for k in r.kinds if k.kind == "voxels")
    assert (voxels.entries, voxels.bytes) == (1, 2048) and r.root == tmp_path
    assert r.models[0][0] == "beo/broken" and r.models[0][1].startswith("unusable: ")
    assert "voxels" in r.text() and "2.0 KB" in r.text() and "models (content digest):" in r.text()


def test_run_demo_calls_the_pieces_in_order(chosen, tmp_path, monkeypatch) -> None:
    """The whole demo but the suites (minutes; the campaign has its own tests), on small
    sizes: the objects, the picked scene, the pick check, the cache; a line each on the
    terminal, the long tables in OUT/demo.md, the headline last."""
    seen: dict[str, object] = {}

    def small_pick_check(episodes, seed, split, progress=True):
        seen["pick_check"] = (episodes, seed, split)
        return real_pick_check(2, seed, split, progress=False)

    def suites(out, workers, say=print):
        seen["suites"] = (out, workers)
        return []

    real_pick_check = inspection.pick_check
    monkeypatch.setattr(inspection, "pick_check", small_pick_check)
    monkeypatch.setattr(demo, "demo_suites", suites)
    monkeypatch.setattr(demo, "picked_seed", lambda split: chosen)
    lines: list[str] = []
    report = demo.run_demo(tmp_path, per_category=1, workers=1, say=lines.append)
    text = "\n".join(lines)
    assert (tmp_path / "objects.png").exists() and (tmp_path / f"scene_{chosen.seed}.png").exists()
    assert (tmp_path / f"scene_{chosen.seed}.rrd").exists()
    assert seen == {
        "pick_check": (demo.DEMO_PICK_EPISODES, 0, "test"),
        "suites": (Path(tmp_path), 1),
    }
    # the long texts are in the report, in order; the terminal has a line for each step
    assert report == tmp_path / demo.DEMO_REPORT
    long = report.read_text()
    assert f"seed {chosen.seed}" in long and f"target ({chosen.target})" in long
    order = [long.index(s) for s in ("object library", "BEOPick-v0 scene", "ceiling", "cache:")]
    assert order == sorted(order)
    assert "| category | episodes |" in long and "| category |" not in text
    assert "category    train/val/test" in long and "train/val/test" not in text
    for step in ("objects:", "scene:", "grasp ceiling:", "cache:"):
        assert sum(line.startswith(step) for line in lines) == 1, step
    assert lines[-1] == demo.headline(tmp_path, inspection.every_backend())


def _board(out: Path, suite: str, rows: list[tuple[str, str | None, dict]]) -> None:
    boards = out / "leaderboards"
    boards.mkdir(parents=True, exist_ok=True)
    data = [{"backend": b, "track": t, "metrics": m} for b, t, m in rows]
    (boards / f"{suite}.json").write_text(json.dumps(data))


def test_the_headline_shows_every_backend_on_every_suite_on_one_screen(tmp_path) -> None:
    backends = inspection.every_backend()
    for i, (suite, key) in enumerate(demo.DEMO_FIGURES.items()):
        rows = [(b, None, {key: 0.25 + 0.01 * j + i}) for j, b in enumerate(backends)]
        if suite == "pose-3dof":  # a tracked suite: the class-free row is the one shown
            rows = [(b, "class-given", {key: 99.0}) for b in backends] + [
                (b, "class-free", {key: 0.5 + j}) for j, b in enumerate(backends)
            ]
        _board(tmp_path, suite, rows)
    text = demo.headline(tmp_path, backends)
    lines = text.splitlines()
    assert len(lines) <= demo.HEADLINE_MAX_LINES
    head = next(line for line in lines if line.startswith("backend"))
    assert all(s in head for s in demo.DEMO_SIZES) and set(demo.DEMO_FIGURES) == set(
        demo.DEMO_SIZES
    )
    for j, b in enumerate(backends):
        row = next(line for line in lines if line.split()[:1] == [b])
        cells = row.split()[1:]
        assert len(cells) == len(demo.DEMO_FIGURES) and "-" not in cells, row
        assert cells[list(demo.DEMO_FIGURES).index("pose-3dof")] == f"{0.5 + j:.1f}"
    for path in ("leaderboards", demo.DEMO_REPORT, "objects.png", "scene_<seed>.png", "runs"):
        assert str(tmp_path / path) in text, path


def test_the_headline_marks_what_did_not_run(tmp_path) -> None:
    _board(tmp_path, "pick", [("oracle", None, {"pick_success": 0.8})])
    lines = demo.headline(tmp_path, ["oracle", "random"]).splitlines()
    oracle = next(line for line in lines if line.startswith("oracle")).split()
    assert oracle[-1] == "80.0%" and set(oracle[1:-1]) == {"-"}
    assert set(next(line for line in lines if line.startswith("random")).split()[1:]) == {"-"}


def test_a_finished_run_is_one_line(tmp_path) -> None:
    from beo_bench.bench.runner import run
    from beo_bench.bench.runs import RunConfig, RunContext
    from beo_bench.bench.suites import get_suite

    ctx = RunContext.of(RunConfig(get_suite("known-pose").with_overrides(size=2), "oracle", {}))
    run(ctx, tmp_path / "r", workers=1, progress=False)
    line = demo.run_line("known-pose", "oracle", tmp_path / "r", 3.2)
    assert "\n" not in line and line.startswith("  known-pose / oracle: 2 views, 0 failed, IoU ")
    assert line.endswith("(3 s)")


def test_no_progress_bar_draws_off_a_terminal(tmp_path, capfd) -> None:
    """With progress on, a run's bar draws only on a terminal: here stdout and stderr are
    pipes (pytest's capture), so nothing of the bar reaches them."""
    from beo_bench.bench.runner import run
    from beo_bench.bench.runs import RunConfig, RunContext
    from beo_bench.bench.suites import get_suite
    from beo_bench.objects.prepare import prepare

    assert not sys.stdout.isatty() and not sys.stderr.isatty()
    ctx = RunContext.of(RunConfig(get_suite("known-pose").with_overrides(size=2), "oracle", {}))
    run(ctx, tmp_path / "r", workers=1, progress=True)
    objects, _ = inspection.select_objects("test", ["box"], per_category=1)
    prepare(objects, D=8, workers=1, progress=True)
    out, err = capfd.readouterr()
    assert "it/s" not in out + err and "item/s" not in out + err and "%|" not in out + err


def test_demo_command_forwards_its_options(monkeypatch, tmp_path) -> None:
    seen = {}
    monkeypatch.setattr(demo, "run_demo", lambda out, **kw: seen.update(out=out, **kw))
    assert main(["demo", "--out", str(tmp_path), "--per-category", "3", "--workers", "2"]) == 0
    assert seen == {"out": str(tmp_path), "per_category": 3, "workers": 2}
