"""Does a change leave every score where it was? Short runs of every in-tree backend on every
suite (both tracks where a suite has them) and on a small folder dataset, recorded by one
checkout and compared with another's, row by row.

    python benchmarks/same_results.py record OUT [--bin BEO_BENCH]   # e.g. before a refactor
    python benchmarks/same_results.py compare BEFORE AFTER

``record`` runs each command (``--episodes 2 --seed 11``, one worker) into ``OUT/<name>``
with its exit status and error line in ``OUT/<name>.log``, two commands at a time (a run
already recorded is kept; one stopped before its log is resumed). ``--bin`` is the
``beo-bench`` of the checkout to record (another worktree's venv: the editable install of
this one follows its files while they change).
``compare`` checks that every ``results.jsonl`` row is the same without its timings (``ms``,
``item_ms``, ``ms_decision``, pick's ``plan_ms``), every exit status is the same, and every
summary's metrics, intervals and per-class table are the same without the timing metrics; it
prints each difference and exits 1 if there is one.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

SUITES = (
    "known-pose",
    "pose-1dof",
    "pose-3dof",
    "pose-3dof-ood",
    "pose-3dof-percat",
    "tabletop",
    "pick",
)
BACKENDS = (
    ["oracle"],
    ["random"],
    ["icp"],
    ["icp-plain"],
    ["beo"],
    ["hbeo"],
    ["hbeo-mdn-likelihood"],
    ["hbeo-mdn-posterior"],
    ["swap", "--opt", "base=icp", "--opt", "truth=pose"],
)
ROW_TIMING = ("ms", "item_ms", "ms_decision", "plan_ms")
SUMMARY_TIMING = ("ms_per_view_median", "ms_per_view_p95", "views_per_s", "ms_per_decision_median")


def folder_dataset(root: Path) -> Path:
    """Three procedural classes exported as a folder dataset of nine OBJ files."""
    from beo_bench.objects import ObjectSet

    if not root.exists():
        for cat in ("mug", "bowl", "bottle"):
            objects = ObjectSet("test", [cat])
            (root / cat).mkdir(parents=True)
            for i in range(3):
                objects.get(cat, i).mesh.export(root / cat / f"{cat}_{i}.obj")
    return root


def commands(out: Path) -> dict[str, list[str]]:
    """Run name -> ``beo-bench`` arguments."""
    cmds: dict[str, list[str]] = {}
    short = ["--episodes", "2", "--seed", "11", "--workers", "1"]
    for suite in SUITES:
        tracks = ("class-free", "class-given") if suite.startswith("pose-") else (None,)
        for backend in BACKENDS:
            for track in tracks:
                name = f"{suite}@{track}" if track else suite
                name += "__" + "_".join(a for a in backend if a != "--opt")
                cmds[name] = ["run", "--suite", suite, "--backend", *backend, *short]
                if track:
                    cmds[name] += ["--track", track]
    folder = str(folder_dataset(out / "folder"))
    for backend in ("oracle", "random", "icp", "beo"):
        cmds[f"folder__{backend}"] = [
            *("run", "--suite", "pose-3dof", "--objects", folder, "--split", "all"),
            *("--backend", backend, "--episodes", "3", "--seed", "5", "--workers", "1"),
        ]
    cmds["folder-tabletop__icp"] = [
        *("run", "--suite", "tabletop", "--objects", folder, "--split", "all"),
        *("--backend", "icp", "--episodes", "2", "--seed", "3", "--workers", "1"),
    ]
    cmds["pose-3dof-percat__hbeo_per-category"] = [
        *("run", "--suite", "pose-3dof-percat", "--track", "class-given", "--backend", "hbeo"),
        *("--opt", "per_category=true", *short),
    ]
    cmds["pick__oracle_mesh-false"] = ["run", "--suite", "pick", "--backend", "oracle"]
    cmds["pick__oracle_mesh-false"] += ["--opt", "mesh=false", *short]
    cmds["pose-3dof__mdn-posterior_samples-100_2-workers"] = [
        *("run", "--suite", "pose-3dof", "--backend", "hbeo-mdn-posterior"),
        *("--opt", "samples=100", "--episodes", "3", "--seed", "11", "--workers", "2"),
    ]
    cmds["bad-option"] = ["run", "--suite", "pose-3dof", "--backend", "icp", "--opt", "bogus=1"]
    return cmds


def record(out: Path, binary: str) -> None:
    out.mkdir(parents=True, exist_ok=True)

    def one(item: tuple[str, list[str]]) -> None:
        name, args = item
        log = out / f"{name}.log"
        if log.exists():
            return
        run_dir = out / name
        resume = ["--resume"] if run_dir.exists() else []  # a run stopped before its log
        p = subprocess.run(
            [binary, *args, "--out", str(run_dir), *resume],
            capture_output=True,
            text=True,
            check=False,
        )
        errors = [line for line in p.stderr.splitlines() if line.startswith("beo-bench: error")]
        tmp = log.with_suffix(".tmp")
        tmp.write_text(json.dumps({"rc": p.returncode, "error": errors[-1] if errors else ""}))
        tmp.replace(log)
        print(f"{p.returncode:3d} {name}", flush=True)

    with ThreadPoolExecutor(2) as pool:
        list(pool.map(one, commands(out).items()))


def _rows(d: Path) -> list[str] | None:
    p = d / "results.jsonl"
    if not p.exists():
        return None
    out = []
    for line in p.read_text().splitlines():
        row = json.loads(line)
        for k in ROW_TIMING:
            row.pop(k, None)
        out.append(json.dumps(row, sort_keys=True))
    return sorted(out)


def _summary(d: Path) -> dict | None:
    p = d / "summary.json"
    if not p.exists():
        return None
    s = json.loads(p.read_text())
    keep = ("metrics", "ci95", "per_category", "n", "failures", "categories", "track")
    out = {k: s.get(k) for k in keep}
    for k in ("metrics", "ci95"):
        out[k] = {m: v for m, v in (out[k] or {}).items() if m not in SUMMARY_TIMING}
    return out


def compare(before: Path, after: Path) -> int:
    same, different = 0, 0
    for log in sorted(before.glob("*.log")):
        name = log.stem
        a, b = json.loads(log.read_text()), json.loads((after / log.name).read_text())
        checks = {
            "exit status": (a["rc"], b["rc"]),
            "rows": (_rows(before / name), _rows(after / name)),
            "summary": (_summary(before / name), _summary(after / name)),
        }
        bad = [what for what, (x, y) in checks.items() if x != y]
        if bad:
            different += 1
            print(f"DIFFERENT {name}: {', '.join(bad)}")
        else:
            same += 1
    print(f"{same} runs the same, {different} different")
    return 1 if different else 0


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("out", type=Path)
    r.add_argument("--bin", default=shutil.which("beo-bench") or "beo-bench")
    c = sub.add_parser("compare")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    args = p.parse_args(argv)
    if args.cmd == "record":
        record(args.out, args.bin)
        return 0
    return compare(args.before, args.after)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
