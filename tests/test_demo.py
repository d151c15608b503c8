"""``beo-bench demo``'s pieces: the scene it shows is one the ground-truth planner picks
(and the picture shows that grasp), and the library functions it shares with ``objects``,
``view``, ``pick-check`` and ``cache info`` run on small sizes."""

from __future__ import annotations

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


def test_run_demo_calls_the_pieces_in_order(chosen, tmp_path, monkeypatch, capsys) -> None:
    """The whole demo but the suites (minutes; the campaign has its own tests), on small
    sizes: the objects, the picked scene, the pick check, the cache."""
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
    demo.run_demo(tmp_path, per_category=1, workers=1, say=lines.append)
    text = "\n".join(lines)
    assert (tmp_path / "objects.png").exists() and (tmp_path / f"scene_{chosen.seed}.png").exists()
    assert (tmp_path / f"scene_{chosen.seed}.rrd").exists()
    assert f"seed {chosen.seed}: the first seed whose target ({chosen.target})" in text
    assert seen == {
        "pick_check": (demo.DEMO_PICK_EPISODES, 0, "test"),
        "suites": (Path(tmp_path), 1),
    }
    order = [text.index(s) for s in ("object library", "one BEOPick-v0 scene", "ceiling", "cache:")]
    assert order == sorted(order)


def test_demo_command_forwards_its_options(monkeypatch, tmp_path) -> None:
    seen = {}
    monkeypatch.setattr(demo, "run_demo", lambda out, **kw: seen.update(out=out, **kw))
    assert main(["demo", "--out", str(tmp_path), "--per-category", "3", "--workers", "2"]) == 0
    assert seen == {"out": str(tmp_path), "per_category": 3, "workers": 2}
