"""Scenes and BEOPick-v0 figures: reset beside one raw depth + segmentation render of the
same scene, that render against a plain ``mujoco.Renderer`` depth render, one full grasp
execution, and isolated-instance views at 128x128.

Pinned to one core (``sched_setaffinity``) because the targets are per core: the benchmark
parallelises over worker processes, each owning one renderer.
"""

from __future__ import annotations

import os
import statistics
import time
from typing import Any

import gymnasium as gym
import numpy as np
from harness import median_time, report

import beo_bench  # noqa: F401  (registers BEOPick-v0)
from beo_bench.objects import ObjectSet
from beo_bench.scenes import OBJECT_RIG, IsolatedRenderer
from beo_bench.scenes.gl import load_mujoco
from beo_bench.scenes.layout import rest_pose
from beo_bench.scenes.renderer import CAMERA_NAME

mujoco = load_mujoco()


def _pin_one_core() -> str:
    if hasattr(os, "sched_setaffinity"):
        cpu = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpu})
        return f"pinned to cpu {cpu}"
    return "not pinned"


def main() -> None:
    pinned = _pin_one_core()
    env = gym.make("BEOPick-v0")  # 640x480, 1-4 objects, test split
    u = env.unwrapped
    # Warm the object library first: generating an instance's mesh (about 25 ms) and its
    # rest pose and collision parts (disk-cached) is the library's cost, paid once per
    # instance per process, not the scene's; reported separately.
    t0 = time.perf_counter()
    insts = [i for i in u.config.object_set if i.category in u.categories]
    for inst in insts:
        rest_pose(inst)
        inst.collision_parts()
    report(
        "  object library warm-up (mesh, rest pose, parts), per instance",
        1000 * (time.perf_counter() - t0) / len(insts),
        "ms",
        note=f"{len(insts)} test-split instances, once per process",
    )
    for s in range(6):
        env.reset(seed=s)  # GL context, first compile

    seeds = iter(range(100, 10_000))
    t_reset = median_time(lambda: env.reset(seed=next(seeds)), repeat=40)
    # the raw render of the same (last) scene, through the env's own renderer
    scene, cam = u.scene, u._cam
    t_render = median_time(lambda: u._renderer.render(scene.data, cam), repeat=40)
    report(
        "reset: new scene + settle + depth/seg 640x480 (median)",
        1000 * t_reset,
        "ms",
        "< 50 ms",
        t_reset < 0.050,
        pinned,
    )
    report(
        "  raw depth + segmentation render 640x480, same scene",
        1000 * t_render,
        "ms",
        note=f"reset / render = {t_reset / t_render:.1f}x",
    )

    render_vs_mujoco(u)

    # step: one full scripted grasp (approach, close, lift 15 cm, hold 1 s) with the
    # ground-truth planner's best grasp; planning is timed separately (it is not the env's)
    plans: list[np.ndarray] = []
    plan_times: list[float] = []

    def setup() -> None:
        while True:
            env.reset(seed=next(seeds))
            t0 = time.perf_counter()
            grasps = u.ground_truth_grasps()
            plan_times.append(time.perf_counter() - t0)
            if grasps:
                plans.append(grasps[0].action)
                return

    t_step = median_time(lambda: env.step(plans[-1]), repeat=30, setup=setup)
    report(
        "step: one full grasp execution (median)", 1000 * t_step, "ms", "< 250 ms", t_step < 0.25
    )
    report(
        "  ground-truth grasp planning, target object (median)",
        1000 * float(np.median(plan_times)),
        "ms",
    )
    env.close()

    # isolated instance views at 128x128, cycling over instances of several categories
    objs = ObjectSet("test")
    insts = [objs.get(c, i) for c in objs.categories[:4] for i in range(2)]
    rng = np.random.default_rng(0)
    with IsolatedRenderer(cache_models=len(insts)) as r:
        cams = [OBJECT_RIG.sample(rng, np.zeros(3)) for _ in range(64)]
        for inst in insts:
            r.render(inst, cams[0])  # compile each model once (cached, LRU)
        n = 0
        t0 = time.perf_counter()
        for k in range(1000):
            r.render(insts[(k // 50) % len(insts)], cams[k % len(cams)])
            n += 1
        rate = n / (time.perf_counter() - t0)
    report(
        "isolated instance render 128x128 (depth + mask + pose)",
        rate,
        "views/s",
        ">= 500 views/s per core",
        rate >= 500,
        "50 views per instance, 8 instances",
    )


def render_vs_mujoco(u: Any, rounds: int = 60) -> None:
    """Our depth + segmentation render against ``mujoco.Renderer``'s depth-only render of
    the same scene and camera at 640x480: the cost of everything the benchmark adds on top
    of MuJoCo's own image path (labels, float32 depth, its reused GL context). The two are
    interleaved, alternating which goes first, so that load from other processes falls on
    both alike; the ratio is of the medians."""
    ours = u._renderer
    data, cam = u.scene.data, u._cam
    ours.render(data, cam)  # writes the camera pose and fovy the raw renderer reads
    h, w = int(ours.intrinsics.height), int(ours.intrinsics.width)
    raw = mujoco.Renderer(u.model, h, w)
    raw.enable_depth_rendering()

    def raw_render() -> None:
        raw.update_scene(data, camera=CAMERA_NAME)
        raw.render()

    def our_render() -> None:
        ours.render(data, cam)

    t_raw: list[float] = []
    t_ours: list[float] = []
    for fn in (raw_render, our_render):  # warm both contexts
        fn()
    for k in range(rounds):
        pair = ((raw_render, t_raw), (our_render, t_ours))
        for fn, times in pair if k % 2 else pair[::-1]:
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
    raw.close()
    m_raw, m_ours = statistics.median(t_raw), statistics.median(t_ours)
    ratio = m_ours / m_raw
    report(
        "  mujoco.Renderer depth render 640x480, same scene/camera",
        1000 * m_raw,
        "ms",
        note=f"median of {rounds}, interleaved",
    )
    report(
        "  Renderer.render (depth + labels) / mujoco.Renderer depth",
        ratio,
        "x",
        "<= 1.15",
        ratio <= 1.15,
        f"ours {1000 * m_ours:.2f} ms, median of {rounds}",
    )
