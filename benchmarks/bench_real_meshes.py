"""Real meshes from a public robotics package: how many load with the
default settings, how long each takes with its collision parts, what ``beo-bench objects``
costs a mesh as a user runs it (wall time with 2 workers, start-up included, with the
default repair and with ``--repair voxel``), and the ground-truth grasp ceiling at their
native size.

The meshes are robosuite 1.5.2's object assets (textured OBJ and STL files of a bottle,
bread, a can, a cereal box, a lemon, a milk carton and a pair of handles), in metres. They
are not in this repository: set ``BEO_BENCH_REAL_MESHES=DIR`` to a folder dataset
(``DIR/<class>/<file>``), or ``BEO_BENCH_FETCH_ROBOSUITE=1`` to let this script download
the robosuite wheel once (157 MB, into the asset cache) and build the folder from it.
Without either, the figures are skipped.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
import zipfile
from pathlib import Path

from harness import report, use_fresh_cache

WHEEL = "robosuite==1.5.2"
MESHES = ("bottle", "bread", "can", "cereal", "lemon", "milk", "handles")
PREFIX = "robosuite/models/assets/objects/meshes/"


def _robosuite_folder() -> Path | None:
    from beo_bench.objects import cache

    root = cache.cache_root() / "downloads" / "robosuite-meshes"
    if (root / ".complete").exists():
        return root
    if os.environ.get("BEO_BENCH_FETCH_ROBOSUITE") != "1":
        return None
    wheels = cache.cache_root() / "downloads"
    wheels.mkdir(parents=True, exist_ok=True)
    subprocess.run(
        [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", WHEEL, "-d", str(wheels)],
        check=True,
    )
    (wheel,) = sorted(wheels.glob("robosuite-1.5.2-*.whl"))
    tmp = Path(tempfile.mkdtemp(dir=wheels, prefix=".robosuite-"))
    with zipfile.ZipFile(wheel) as zf:
        for name in MESHES:
            cls = "handle" if name == "handles" else name
            (tmp / cls).mkdir()
            for ext, tag in ((".obj", "a"), (".stl", "b")):
                member = f"{PREFIX}{name}{ext}"
                if member in zf.namelist():
                    (tmp / cls / f"{name}_{tag}{ext}").write_bytes(zf.read(member))
    (tmp / ".complete").touch()
    tmp.rename(root)  # appears whole or not at all
    return root


def _objects_command(root: Path, repair: str) -> float:
    """Wall seconds of ``beo-bench objects`` on every file of ``root`` with 2 workers and a
    cold cache of its own, as a user starts it (a new process: imports included)."""
    env = {**os.environ, "BEO_BENCH_CACHE": tempfile.mkdtemp(prefix="beo_bench_bench_")}
    argv = [sys.executable, "-m", "beo_bench.cli", "objects", "--objects", str(root)]
    argv += ["--split", "all", "--workers", "2", "--repair", repair]
    t0 = time.perf_counter()
    subprocess.run(argv, env=env, check=True, capture_output=True)
    return time.perf_counter() - t0


def main() -> None:
    given = os.environ.get("BEO_BENCH_REAL_MESHES")
    root = Path(given) if given else _robosuite_folder()
    if root is None:
        print(
            "  skipped: set BEO_BENCH_REAL_MESHES=DIR or BEO_BENCH_FETCH_ROBOSUITE=1 (downloads "
            "the robosuite wheel once, 157 MB)"
        )
        return
    from beo_bench.envs.pickcheck import ground_truth_pick_check
    from beo_bench.objects.datasets import open_dataset

    warnings.simplefilter("ignore")  # unknown-size warnings: the files carry their units
    use_fresh_cache()  # the figures are cold-cache ones (the download stays in the user's)
    loaded, failed, times = [], [], []
    dataset = open_dataset(root)
    for split in ("train", "val", "test"):
        for inst in dataset.objects(split):  # the defaults: repair="solid", units auto
            t0 = time.perf_counter()
            try:
                _ = inst.mesh, inst.collision_parts(), inst.voxels(32), inst.symmetry
            except Exception as e:  # a file the defaults cannot load: counted, named
                failed.append(f"{inst.key}: {type(e).__name__}")
                continue
            times.append(time.perf_counter() - t0)
            loaded.append(inst)
    share = len(loaded) / max(len(loaded) + len(failed), 1)
    report(
        "real meshes loading with the default settings",
        100 * share,
        "%",
        ">= 90%",
        share >= 0.9,
        f"{len(loaded)} of {len(loaded) + len(failed)}" + (f"; {failed}" if failed else ""),
    )
    worst = max(times) if times else float("nan")
    report(
        "slowest real mesh: load, repair, CoACD, voxels, symmetry",
        worst,
        "s",
        "< 20 s",
        worst < 20,
        f"median {statistics.median(times) if times else float('nan'):.2f} s, mean "
        f"{sum(times) / max(len(times), 1):.1f} s, cold cache, one process",
    )
    files = len(loaded) + len(failed)
    for repair in ("solid", "voxel"):
        wall = _objects_command(root, repair)
        report(
            f"`beo-bench objects --workers 2 --repair {repair}`, per mesh",
            wall / files,
            "s",
            "<= 2 s",
            wall / files <= 2.0,
            f"{wall:.1f} s wall for {files} files: start-up, check, CoACD, voxels, symmetry; "
            "cold cache",
        )
    objects = dataset.objects("train")
    r = ground_truth_pick_check(
        episodes=40, seed=0, objects=objects, num_objects=(1, min(4, len(objects.categories)))
    )
    rate = r.success_rate
    report(
        "ground-truth grasp ceiling on them, native size (40 episodes)",
        100 * rate,
        "%",
        ">= 85%",
        rate >= 0.85,
        "the train split's objects",
    )
