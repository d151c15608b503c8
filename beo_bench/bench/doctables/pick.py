"""The pick tables: method pairs, sensitivity to each error, success against pose error, the
tolerances, the grasp audit and the robust grasp.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from beo_bench.bench.columns import verdict_cell
from beo_bench.bench.doctables.boards import Boards, PendingSuiteError, _diff, _shift, _table, pct
from beo_bench.bench.doctables.pose import options_of
from beo_bench.bench.pages.entries import BOUNDS
from beo_bench.bench.pages.pick import ROBUST_PAIRS
from beo_bench.bench.pages.plots import ERROR_BINS, error_bins, found_target_episodes
from beo_bench.bench.pages.verdicts import (
    primary_comparisons,
)
from beo_bench.bench.rundir import sensor_tag_of
from beo_bench.bench.runs import backend_label

PICK_CONTROLS: tuple[tuple[str, str], ...] = (
    ("beo (pose_prior=false)", "beo"),
    ("icp (pose_prior=false)", "icp"),
    ("icp-plain (pose_prior=false)", "icp-plain"),
    ("oracle (mesh=false)", "oracle"),
)
"""The pick page's controls docs/results.md quotes: the rest prior made uniform for each
method that takes it, and the oracle planning on voxels."""


def pick_pairs(b: Boards) -> str:
    """Pick's comparisons on the same episodes: the page's primary ones (Holm-corrected over
    the page's family), then the controls (uncorrected)."""
    head = ["method", "baseline", "episodes", "pick success, method - baseline [95%]",
            "verdict"]  # fmt: skip
    rows = []
    for pc in primary_comparisons("pick"):
        p = b.primary("pick", pc)
        if p is None:
            continue
        verdict = verdict_cell(p["verdict"])
        rows.append([f"`{pc.method}`", f"`{pc.baseline}`", str(p["items"]),
                     f"{_shift(p)} pts", f"{verdict} (Holm)"])  # fmt: skip
    for method, base in PICK_CONTROLS:
        if not b.has("pick", method):
            continue
        p = b.pair("pick", method, base, "pick_success", None)
        rows.append([f"`{method}`", f"`{base}`", str(p["items"]), f"{_shift(p)} pts",
                     f"{p['verdict']} (uncorrected)"])  # fmt: skip
    return _table(head, rows)


def pick_sensitivity(b: Boards) -> str:
    """What pick punishes (issue 49): the oracle with one controlled error of a known size
    (``oracle:rot_deg=D``, ``rot_axis=up``, ``trans_cm=T``, ``shape=class-mean``) against
    the oracle on the same episodes, pick success and its paired change."""
    from beo_bench.bench.ablations import SENSITIVITY_STEPS

    base = b.metric("pick", "oracle", "pick_success")
    rows = [["the truth (`oracle`)", pct(base), "-"]]
    for opts, what in SENSITIVITY_STEPS:
        method = backend_label("oracle", opts)
        if not b.has("pick", method):
            continue
        p = b.pair("pick", method, "oracle", "pick_success", None)
        rows.append([f"{what} (`{options_of(opts)}`)", pct(p["method_value"]), _diff(p, " pts")])
    if len(rows) == 1:
        raise PendingSuiteError("no sensitivity row is on the pick page")
    table = _table(["the oracle's estimate", "pick success", "- the oracle [95%]"], rows)
    # the tolerance of each kind of error: where success falls to half the oracle's
    tol = []
    for what, unit, levels in (
        ("rotation, random axis", "deg", [({"rot_deg": d}, d) for d in ROT_LEVELS]),
        ("rotation about the up axis (yaw)", "deg",
         [({"rot_axis": "up", "rot_deg": d}, d) for d in ROT_LEVELS]),
        ("translation", "cm", [({"trans_cm": t}, t) for t in TRANS_LEVELS]),
    ):  # fmt: skip
        pts = [(0.0, base)] + [
            (float(x), b.metric("pick", backend_label("oracle", o), "pick_success"))
            for o, x in levels
            if b.has("pick", backend_label("oracle", o))
        ]
        if len(pts) > 1:
            t = half_success_tolerance([x for x, _ in pts], [y for _, y in pts])
            tol.append([what, "beyond the largest error" if t is None else f"{t:.3g} {unit}"])
    head = ["error", "tolerance (success at half the oracle's)"]
    return table + "\n" + _table(head, tol) + "\n" + _sensitivity_per_category(b)


def _sensitivity_per_category(b: Boards) -> str:
    """Per category (about 28 episodes a level), the tolerance of each damage of
    :func:`pick_sensitivity`, from the rows' per-category success; ``-`` where the oracle
    itself picks under a third of the category's targets (no curve to halve)."""
    levels: dict[str, list[tuple[dict[str, Any], float]]] = {
        "rotation (deg)": [({"rot_deg": d}, d) for d in ROT_LEVELS],
        "yaw (deg)": [({"rot_axis": "up", "rot_deg": d}, d) for d in ROT_LEVELS],
        "translation (cm)": [({"trans_cm": t}, t) for t in TRANS_LEVELS],
    }
    base = b.row("pick", "oracle").get("per_category", {})
    rows = []
    for cat in sorted(base):
        y0 = base[cat].get("pick_success")
        cells = [cat, str(int(base[cat].get("n", 0))), "-" if y0 is None else pct(y0)]
        for steps in levels.values():
            pts = [(0.0, y0)] if y0 is not None else []
            for o, x in steps:
                name = backend_label("oracle", o)
                if pts and b.has("pick", name):
                    v = b.row("pick", name).get("per_category", {}).get(cat, {})
                    if v.get("pick_success") is not None:
                        pts.append((float(x), float(v["pick_success"])))
            if len(pts) < 2 or pts[0][1] < 1 / 3:
                cells.append("-")
                continue
            t = half_success_tolerance([x for x, _ in pts], [y for _, y in pts])
            cells.append("never halves" if t is None else f"{t:.3g}")
        rows.append(cells)
    return _table(["category", "episodes", "the oracle", *levels], rows)


def _found_target(b: Boards) -> dict[str, list[dict[str, Any]]]:
    """Each perception backend's ideal-sensor pick row (no options, no bounds, nothing
    privileged): its episodes that chose their target and record their errors."""
    per: dict[str, list[dict[str, Any]]] = {}
    for r in b.rows("pick"):
        if sensor_tag_of(r) is not None or r["provenance"].get("backend_kwargs"):
            continue
        if r["backend"] in BOUNDS or r.get("privileged"):
            continue
        eps = found_target_episodes(r)
        if eps:
            per[r["backend"]] = eps
    if not per:
        raise PendingSuiteError("no pick run records its estimates' errors yet")
    return per


def pick_vs_error(b: Boards) -> str:
    """Pick success against each error of the estimate the episode grasped, binned, over
    the episodes that chose their target (the committed per-episode records of
    ``leaderboards/pick.json``): every perception backend with records pooled, then each;
    the bounds and privileged rows left out. A cell is success (episodes)."""
    from itertools import pairwise

    per = _found_target(b)
    out = []
    for key, (what, unit, edges) in ERROR_BINS.items():
        head = [f"{what} ({unit})" if unit else what]
        head += [f"{lo:g}-{hi:g}" if hi < 100 else f">= {lo:g}" for lo, hi in pairwise(edges)]
        lines = []
        for name, eps in [
            ("every backend", [e for v in per.values() for e in v]),
            *sorted(per.items()),
        ]:
            cells = []
            for lo, hi in pairwise(edges):
                top = hi if hi == edges[-1] else np.nextafter(hi, -np.inf)  # last bin: hi in it
                sel = [e for e in eps if e.get(key) is not None and lo <= e[key] <= top]
                ok = sum(bool(e["success"]) for e in sel)
                cells.append(f"{pct(ok / len(sel))} ({len(sel)})" if sel else "-")
            lines.append([name if name == "every backend" else f"`{name}`", *cells])
        out.append(_table(head, lines))
    return "\n".join(out)


def _rate(eps: list[dict[str, Any]], key: str = "success") -> float:
    return sum(bool(e[key]) for e in eps) / len(eps)


def _audited(b: Boards) -> dict[str, list[dict[str, Any]]]:
    """Every ideal-sensor pick row whose episodes record the grasp audit, by row name: the
    episodes (all of them, as dicts)."""
    from beo_bench.bench.pages.pick import episodes

    out: dict[str, list[dict[str, Any]]] = {}
    for r in b.rows("pick"):
        if sensor_tag_of(r) is not None:
            continue
        eps = list(episodes(r).values())
        if any(e.get("force_closure") is not None for e in eps):
            out[backend_label(r["backend"], r["provenance"].get("backend_kwargs") or {})] = eps
    if not out:
        raise PendingSuiteError("no pick run records its grasps' audit yet")
    return dict(sorted(out.items()))


def pick_tolerance(b: Boards) -> str:
    """Each backend's own tolerance (issue 49): from its episodes that chose their target,
    binned by the grasped estimate's error (:data:`ERROR_BINS`), the error at which success
    falls to half its value in the first bin (:func:`half_success_tolerance` over the bins'
    median errors; IoU's bins read from 1 down)."""
    per = _found_target(b)
    head = ["backend", "episodes"]
    head += [f"{what} ({unit})" if unit else what for what, unit, _ in ERROR_BINS.values()]
    rows = []
    for name, eps in [
        ("every backend", [e for v in per.values() for e in v]),
        *sorted(per.items()),
    ]:
        cells = [name if name == "every backend" else f"`{name}`", str(len(eps))]
        for key in ERROR_BINS:
            pts = [(x, y) for x, y, _ in error_bins(eps, key)]
            if key == "iou_cam":  # better is larger: walk the bins from the top
                pts = [(1 - x, y) for x, y in reversed(pts)]
            t = half_success_tolerance([x for x, _ in pts], [y for _, y in pts]) if pts else None
            if t is not None and key == "iou_cam":
                t = 1 - t
            cells.append("never halves" if t is None else f"{t:.3g}")
        rows.append(cells)
    return _table(head, rows)


def _kappa(a: list[bool], b: list[bool]) -> float:
    """Cohen's kappa of two yes/no raters (Cohen 1960): agreement beyond chance."""
    n = len(a)
    po = sum(x == y for x, y in zip(a, b, strict=True)) / n
    pa, pb = sum(a) / n, sum(b) / n
    pe = pa * pb + (1 - pa) * (1 - pb)
    return 0.0 if pe == 1 else (po - pe) / (1 - pe)


def pick_audit(b: Boards) -> str:
    """The simulated grasp check against the analytic one (issue 49), over every executed
    grasp the ideal-sensor pick rows record: the simulator lifted the object the grasp was
    planned on, and the grasp is in force closure at mu = 0.4 on that object's true mesh
    (``closure_friction``); their agreement, Cohen's kappa and the two kinds of
    disagreement; then the shake's effect on each row's success."""
    from beo_bench.grasping import AUDIT_FRICTION
    from beo_bench.scenes.gripper import GRIPPER

    per = _audited(b)
    pads = GRIPPER.pad_friction
    head = ["row", "executed grasps", "lifted", f"force closure (mu {AUDIT_FRICTION:g})",
            "agree", "kappa", "lifted, no closure", "closure, not lifted",
            f"agree at the pads' mu {pads:g}"]  # fmt: skip
    rows = []
    pooled: list[dict[str, Any]] = []
    for name, eps in per.items():
        done = [e for e in eps if e.get("force_closure") is not None]
        pooled += done
        rows.append(_audit_row(f"`{name}`", done, pads))
    rows.insert(0, _audit_row("every row", pooled, pads))
    audit = _table(head, rows)
    head2 = ["row", "pick success", "held after the shake", "lost to the shake",
             "median slip of the held (cm)", "contacts per finger (median)"]  # fmt: skip
    rows2 = []
    for name, eps in per.items():
        won = [e for e in eps if e["success"]]
        held = [e for e in won if e.get("shake_held")]
        slips = [e["slip_cm"] for e in held if e.get("slip_cm") is not None]
        fingers = [
            min(e["contacts_left"], e["contacts_right"])
            for e in won
            if e.get("contacts_left") is not None and e.get("contacts_right") is not None
        ]
        rows2.append([
            f"`{name}`", pct(_rate(eps)), pct(len(held) / len(eps)), str(len(won) - len(held)),
            f"{np.median(slips):.2f}" if slips else "-",
            f"{np.median(fingers):g}" if fingers else "-",
        ])  # fmt: skip
    return audit + "\n" + _table(head2, rows2)


def _audit_row(name: str, done: list[dict[str, Any]], pads: float) -> list[str]:
    sim = [bool(e["lifted_chosen"]) for e in done]
    fc = [bool(e["force_closure"]) for e in done]
    # at the friction the simulated pads have (fc_mu: the least friction that closes)
    at_pads = [e["fc_mu"] is not None and e["fc_mu"] <= pads for e in done]
    n = len(done)
    agree = sum(x == y for x, y in zip(sim, fc, strict=True))
    return [
        name, str(n), pct(sum(sim) / n), pct(sum(fc) / n), pct(agree / n), f"{_kappa(sim, fc):.2f}",
        str(sum(x and not y for x, y in zip(sim, fc, strict=True))),
        str(sum(y and not x for x, y in zip(sim, fc, strict=True))),
        pct(sum(x == y for x, y in zip(sim, at_pads, strict=True)) / n),
    ]  # fmt: skip


def pick_robust(b: Boards) -> str:
    """The grasp planned over the MDN's pose samples against the one planned on its best
    sample, on the same episodes and estimates (issue 49): success, its share of the
    oracle's, the paired change, and the median planning time per decision (from the
    episodes' records: wall time in runs made at different times on a loaded machine, so
    their ratio is not the cost; ``benchmarks/bench_grasp.py`` pairs it)."""
    from beo_bench.bench.pages.pick import episodes

    oracle = b.metric("pick", "oracle", "pick_success")
    head = ["row", "pick success", "of the oracle's", "- best-sample grasp [95%]",
            "planning (ms, median, in the campaign)"]  # fmt: skip
    rows = []
    for base, robust in ROBUST_PAIRS:
        if not b.has("pick", robust):
            continue
        ms: dict[str, float | None] = {}
        for name in (base, robust):
            eps = episodes(b.row("pick", name)).values()
            t = [e["plan_ms"] for e in eps if e.get("plan_ms") is not None]
            ms[name] = float(np.median(t)) if t else None
        for name in (base, robust):
            v = b.metric("pick", name, "pick_success")
            shift = _diff(b.pair("pick", robust, base, "pick_success", None), " pts")
            rows.append([
                f"`{name}`", pct(v), pct(v / oracle) if oracle else "-",
                shift if name == robust else "-",
                f"{ms[name]:.0f}" if ms[name] is not None else "-",
            ])  # fmt: skip
    if not rows:
        raise PendingSuiteError("no grasp=robust row is on the pick page")
    return _table(head, rows)


ROT_LEVELS = (5, 15, 30, 60, 90)
TRANS_LEVELS = (0.5, 1, 2, 4)


def half_success_tolerance(errors: list[float], success: list[float]) -> float | None:
    """The error at which pick success first falls to half its value at the smallest error
    (issue 49's tolerance), linearly interpolated between the measured levels (``errors``
    ascending); None when it never does."""
    half = success[0] / 2
    from itertools import pairwise

    for (x0, y0), (x1, y1) in pairwise(zip(errors, success, strict=True)):
        if y1 <= half:
            return x0 if y0 == y1 else x0 + (x1 - x0) * (y0 - half) / (y0 - y1)
    return None
