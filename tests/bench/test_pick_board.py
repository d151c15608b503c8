"""The pick page (issue 47): every run's episodes in the page's JSON, one short record each,
so that any two rows pair after the fact; every method paired with hbeo and the MDN's modes
with each other, episode by episode, with an interval, an exact McNemar p and a verdict, in
the page and in its ``_paired.json`` (``"pairing": "method"``), bounds never paired; and the
per-category successes with their counts."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.stats import binomtest

from beo_bench.bench.pages.entries import Row
from beo_bench.bench.pages.leaderboard import regenerate
from beo_bench.bench.pages.pick import (
    EPISODE_AUDIT,
    EPISODE_FIELDS,
    episodes,
    mcnemar_p,
    page_json,
    pick_category_table,
    pick_comparisons,
)
from beo_bench.bench.pages.verdicts import Section
from beo_bench.bench.scoring import PICK_ERRORS
from tests.bench.synthetic_runs import write_run

N = 60
CATS = ("bowl", "mug", "can")
HBEO = np.random.default_rng(1).random(N) < 0.5
"""hbeo's successes; the other rows are defined from it."""
FLIP = np.flatnonzero(~HBEO)[:12]
"""Episodes hbeo missed that icp picks (icp: hbeo's successes and these)."""


def pick_row(item: int, success: bool, found: bool | None = True) -> dict:
    """Episode ``item`` of a pick run (its target of class ``item mod 3``)."""
    c = item % len(CATS)
    return {
        "item": item,
        "view": 0,
        "category": CATS[c],
        "true_class": c,
        "views": 2,
        "failure": None,
        "success": bool(success),
        "reason": "success" if success else "nothing_lifted",
        "chosen_is_target": found,
        "ms": 5.0,
        "ms_decision": 10.0,
    }


def _rows(success: np.ndarray) -> list[dict]:
    return [pick_row(i, bool(s)) for i, s in enumerate(success)]


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pick")
    runs = tmp / "runs"
    icp = HBEO.copy()
    icp[FLIP] = True
    mdn = HBEO.copy()
    mdn[:4] = ~mdn[:4]  # four episodes differ from hbeo, both ways
    write_run(runs / "hbeo", "hbeo", _rows(HBEO), suite="pick", track=None, size=500)
    write_run(runs / "icp", "icp", _rows(icp), suite="pick", track=None, size=500)
    for mode in ("likelihood", "posterior"):
        write_run(runs / mode, f"hbeo-mdn-{mode}", _rows(mdn), suite="pick", track=None, size=500)
    # a nothing-chosen episode and a failed one: their records say so
    beo = _rows(HBEO)
    beo[0].update(success=False, reason="no_estimate", chosen_is_target=None)
    write_run(runs / "beo", "beo", beo, suite="pick", track=None, size=500)
    for name, kw in (("oracle", {}), ("random", {}), ("swap", {"base": "hbeo"})):
        every = _rows(np.ones(N, bool))
        write_run(runs / name, name, every, suite="pick", track=None, size=500, kwargs=kw,
                  privileged=name != "random")  # fmt: skip
    # the same backends under another sensor: their part gets its comparisons too
    write_run(runs / "hbeo-d435", "hbeo", _rows(HBEO), suite="pick", track=None, size=500,
              sensor="d435")  # fmt: skip
    write_run(runs / "icp-d435", "icp", _rows(HBEO), suite="pick", track=None, size=500,
              sensor="d435")  # fmt: skip
    regenerate(runs, tmp / "board")
    return tmp / "board"


def test_the_page_json_holds_every_runs_episodes_one_line_each(board) -> None:
    text = (board / "pick.json").read_text()
    rows = json.loads(text)
    assert len(rows) == 10
    for s in rows:
        assert s["episode_fields"] == list(EPISODE_FIELDS)
        assert [r[0] for r in s["episodes"]] == list(range(N))
    icp = next(s for s in rows if s["backend"] == "icp" and s["sensor"] == "ideal")
    # these synthetic runs predate the error and audit records
    errors = [None] * (len(PICK_ERRORS) + len(EPISODE_AUDIT))
    assert icp["episodes"][FLIP[0]] == [
        int(FLIP[0]), CATS[FLIP[0] % 3], True, "success", True, *errors,
    ]  # fmt: skip
    beo = episodes(next(s for s in rows if s["backend"] == "beo"))
    assert beo[0] == {"item": 0, "category": "bowl", "success": False, "reason": "no_estimate",
                      "chosen_is_target": None, **dict.fromkeys(PICK_ERRORS),
                      **dict.fromkeys(EPISODE_AUDIT)}  # fmt: skip
    # one line per record: 10 runs of 60 episodes are 600 lines of the file, not 4,200
    assert sum(ln.startswith("      [") for ln in text.splitlines()) == 10 * N


def test_page_json_is_plain_json_without_episodes_and_keeps_a_record_a_line() -> None:
    plain = [{"b": 1, "a": [1, 2]}]
    assert page_json(plain) == json.dumps(plain, indent=2, sort_keys=True) + "\n"
    shown = [{"backend": "x", "episodes": [[0, "mug", True, "success", True]]}, {"episodes": []}]
    text = page_json(shown)
    assert json.loads(text) == shown
    assert '      [0, "mug", true, "success", true]\n' in text


def test_every_method_is_paired_with_hbeo_and_the_mdn_modes_with_each_other(board) -> None:
    paired = json.loads((board / "pick_paired.json").read_text())
    method = [p for p in paired if p["pairing"] == "method" and "sensor" not in p]
    pairs = {(p["method"], p["baseline"]) for p in method}
    assert pairs == {
        ("beo", "hbeo"),
        ("icp", "hbeo"),
        ("hbeo-mdn-likelihood", "hbeo"),
        ("hbeo-mdn-posterior", "hbeo"),
        ("hbeo-mdn-posterior", "hbeo-mdn-likelihood"),
    }  # no oracle, random or swap: bounds and privileged rows are never paired
    icp = next(p for p in method if p["method"] == "icp")
    assert icp["metric"] == "pick_success" and icp["items"] == N
    assert icp["diff"] == pytest.approx(len(FLIP) / N)
    assert (icp["method_only"], icp["baseline_only"]) == (len(FLIP), 0)
    assert icp["p_value"] == pytest.approx(2 / 2 ** len(FLIP))
    assert icp["ci95"][0] > 0 and icp["verdict"] == "better"
    modes = next(p for p in method if p["baseline"] == "hbeo-mdn-likelihood")
    assert modes["diff"] == 0 and modes["p_value"] == 1 and modes["verdict"] == "no difference"
    beo = next(p for p in method if p["method"] == "beo")
    assert (beo["method_only"], beo["baseline_only"]) == (0, int(HBEO[0]))
    # the d435 part pairs its own runs, marked with their sensor
    d435 = [p for p in paired if p["pairing"] == "method" and p.get("sensor") == "d435"]
    assert [(p["method"], p["baseline"], p["diff"]) for p in d435] == [("icp", "hbeo", 0.0)]


def test_the_page_shows_the_comparisons_and_counts_per_category(board) -> None:
    md = (board / "pick.md").read_text()
    own, d435 = md.split("## sensor d435")
    # the suite's own sensor: the pairs once, as the page's Holm-corrected primary family
    line = next(ln for ln in own.splitlines() if "| icp | hbeo | pick success |" in ln)
    assert f"| icp | hbeo | pick success | {N} | +{100 * len(FLIP) / N:.1f}% [" in line
    assert line.endswith("| **better** | - |")
    assert "| hbeo-mdn-posterior | hbeo-mdn-likelihood | pick success | 60 |" in own
    assert "Method against method (exploratory" not in own
    # under another sensor they are exploratory, with the discordant episodes and McNemar's p
    assert "Method against method (exploratory" in d435
    assert "| icp | hbeo | 60 | " in d435
    assert "pick success per category (successes / episodes):" in md
    bowl = next(ln for ln in md.split("## Robustness")[0].splitlines() if ln.startswith("| bowl |"))
    hbeo_bowl = int(HBEO[0::3].sum())
    beo_bowl = hbeo_bowl - int(HBEO[0])  # beo missed episode 0, a bowl
    cells = bowl.strip("| ").split(" | ")  # category, beo, hbeo, ... (bounds last)
    assert cells[2] == f"{hbeo_bowl}/20 ({100 * hbeo_bowl / 20:.0f}%)"
    assert cells[1] == f"{beo_bowl}/20 ({100 * beo_bowl / 20:.0f}%)"
    # the index shows them too
    assert "| icp | hbeo | pick success | 60 |" in (board / "README.md").read_text()


def test_a_category_table_without_per_category_figures_is_empty() -> None:
    assert pick_category_table([Row({"backend": "x", "metrics": {}})]) == ""


def test_rows_without_episodes_are_not_paired() -> None:
    """A row whose records are not there (a kept page's, written before the records) gets
    no comparison rather than one over nothing."""
    rows = [Row({"backend": b, "metrics": {}, "provenance": {}}) for b in ("hbeo", "icp")]
    assert pick_comparisons(Section("pick", 5, None, 5000, 500, rows)) == []


@pytest.mark.parametrize("b_only, a_only", [(0, 6), (12, 0), (3, 9), (7, 7), (40, 61), (0, 0)])
def test_mcnemar_p_is_the_exact_two_sided_sign_test(b_only, a_only) -> None:
    n = b_only + a_only
    want = 1.0 if n == 0 else binomtest(b_only, n, 0.5).pvalue
    assert mcnemar_p(b_only, a_only) == pytest.approx(want, rel=1e-9)
    assert mcnemar_p(a_only, b_only) == mcnemar_p(b_only, a_only)


def test_a_pose_prior_control_pairs_on_pick_success_over_its_prefix(tmp_path) -> None:
    """A control (``beo:pose_prior=false``) run on the first 30 episodes pairs with ``beo``
    on those, on pick success and target found (pick has no pose metric to pair on)."""
    runs = tmp_path / "runs"
    write_run(runs / "beo", "beo", _rows(HBEO), suite="pick", track=None, size=500)
    control = HBEO[:30].copy()
    control[np.flatnonzero(HBEO[:30])[:5]] = False  # five of beo's successes lost
    write_run(runs / "beo-flat", "beo", _rows(control), suite="pick", track=None, size=500,
              kwargs={"pose_prior": False})  # fmt: skip
    regenerate(runs, tmp_path / "board")
    paired = json.loads((tmp_path / "board" / "pick_paired.json").read_text())
    abl = {p["metric"]: p for p in paired if p["pairing"] == "ablation"}
    assert set(abl) == {"pick_success", "target_found_rate"}
    assert abl["pick_success"]["items"] == 30
    assert abl["pick_success"]["diff"] == pytest.approx(-5 / 30)  # control - beo
    assert "Ablations" in (tmp_path / "board" / "pick.md").read_text()


def test_seed_replicates_give_each_learned_row_its_spread_and_judge_the_gap(tmp_path) -> None:
    """``hbeo:model=seed1-hbeo`` and ``seed2-hbeo`` are hbeo trained from other seeds: the
    page gives hbeo's pick success at seed 0, at 1 and 2, and the spread; a gap to the MDN
    smaller than that spread is said to be within it, a larger one to exceed it."""
    runs = tmp_path / "runs"
    rate = {0: 30, 1: 24, 2: 36}  # hbeo's successes of 60 at each seed: spread 12 (20 pts)
    for seed, k in rate.items():
        kw = {"model": f"seed{seed}-hbeo"} if seed else {}
        ok = np.arange(N) < k
        write_run(runs / f"hbeo{seed}", "hbeo", _rows(ok), suite="pick", track=None, size=500,
                  kwargs=kw)  # fmt: skip
    for seed, k in {0: 33, 1: 32}.items():  # the MDN: 3 more than hbeo, spread 1
        kw = {"model": f"seed{seed}-hbeo-mdn"} if seed else {}
        write_run(runs / f"mdn{seed}", "hbeo-mdn-likelihood", _rows(np.arange(N) < k),
                  suite="pick", track=None, size=500, kwargs=kw)  # fmt: skip
    write_run(runs / "icp", "icp", _rows(np.arange(N) < 10), suite="pick", track=None, size=500)
    regenerate(runs, tmp_path / "board")
    page = (tmp_path / "board" / "pick.md").read_text()
    assert "| hbeo | pick success | 50.0% | 1: 40.0%, 2: 60.0% | 20.0% |" in page
    assert "| hbeo-mdn-likelihood | pick success | 55.0% | 1: 53.3% | 1.7% |" in page
    gap = "| hbeo-mdn-likelihood | hbeo | pick success | +5.0% | 20.0% | the seeds spread as far"
    assert gap in page
    assert "| icp | pick success" not in page  # no replicates: no spread


def test_an_episode_record_carries_the_grasped_estimates_errors() -> None:
    """Issue 49: the page's JSON holds each episode's estimate errors (to 3 decimals), so
    that anyone can draw success against them from the committed file alone."""
    from beo_bench.bench.pages.pick import episode_records

    errs = dict(zip(PICK_ERRORS, (31.41592, 2.71828, 5.0, 0.5, 0.25, 1.23456), strict=True))
    audit = {"lifted_chosen": True, "shake_held": False, "slip_cm": 12.34567,
             "contacts_left": 4, "contacts_right": 2, "fc_mu": 0.45678, "force_closure": False,
             "plan_ms": 61.23456, "grasp_share": None}  # fmt: skip
    assert set(audit) == set(EPISODE_AUDIT)
    row = {"item": 3, "category": "mug", "success": True, "reason": "success",
           "chosen_is_target": True, **errs, **audit}  # fmt: skip
    (rec,) = episode_records([row])
    got = dict(zip(EPISODE_FIELDS, rec, strict=True))
    assert got == {
        **{k: row[k] for k in ("item", "category", "success", "reason", "chosen_is_target")},
        **{k: round(v, 3) for k, v in errs.items()},
        **{k: v if v is None or isinstance(v, bool) else round(v, 3) for k, v in audit.items()},
    }
    assert got["shake_held"] is False and got["contacts_left"] == 4


def test_success_against_error_bins_the_episodes_that_found_their_target(tmp_path) -> None:
    """Issue 49's curve from the committed records: each backend's episodes that chose
    their target, binned by the grasped estimate's error, success (episodes) per bin, and
    every backend pooled; episodes without records (older runs) and bounds are left out."""
    from beo_bench.bench.doctables.boards import Boards
    from beo_bench.bench.doctables.pick import pick_vs_error

    def rec(item: int, ok: bool, rot: float | None, found: bool = True) -> list:
        errs = [rot, 0.3, 1.0, 0.9, 0.8, 0.2] if rot is not None else [None] * 6
        audit = [None] * len(EPISODE_AUDIT)
        return [item, "mug", ok, "success" if ok else "nothing_lifted", found, *errs, *audit]

    def row(backend: str, recs: list) -> dict:
        return {"backend": backend, "suite": "pick", "sensor": "ideal",
                "provenance": {"backend_kwargs": {}}, "episode_fields": list(EPISODE_FIELDS),
                "episodes": recs}  # fmt: skip

    rows = [
        row("hbeo", [rec(0, True, 2.0), rec(1, False, 40.0), rec(2, True, 3.0),
                     rec(3, False, 2.0, found=False)]),
        row("beo", [rec(0, True, 50.0), rec(1, False, 70.0), rec(2, True, None)]),
        row("oracle", [rec(0, True, 0.0)]),
    ]  # fmt: skip
    (tmp_path / "pick.json").write_text(json.dumps(rows))
    text = pick_vs_error(Boards(tmp_path))
    rot = text.split("\n\n")[0].splitlines()
    assert rot[0].startswith("| rotation error (deg) | 0-5 | 5-15 | 15-30 | 30-60 | >= 60 |")
    assert rot[2] == "| every backend | 100.0% (2) | - | - | 50.0% (2) | 0.0% (1) |"
    assert rot[3] == "| `beo` | - | - | - | 100.0% (1) | 0.0% (1) |"
    assert rot[4] == "| `hbeo` | 100.0% (2) | - | - | 0.0% (1) | - |"


def _audit_page(tmp_path):
    """A pick page whose rows record the grasp audit: hbeo with 4 executed grasps (two
    disagreements, one at each side) and one never executed, the oracle with 2."""

    def rec(item, ok, lifted, mu, held=None, slip=None, found=True, rot=5.0) -> list:
        fc = None if lifted is None else (mu is not None and mu <= 0.4)
        audit = dict.fromkeys(EPISODE_AUDIT)
        touch = 4 if ok else None
        audit.update(lifted_chosen=lifted, force_closure=fc, fc_mu=mu, shake_held=held,
                     slip_cm=slip, contacts_left=touch, contacts_right=touch and 2)  # fmt: skip
        errs = [rot, 0.3, 1.0, 0.9, 0.8, 0.2]
        return [item, "mug", ok, "success" if ok else "nothing_lifted", found, *errs,
                *(audit[k] for k in EPISODE_AUDIT)]  # fmt: skip

    def row(backend: str, recs: list) -> dict:
        return {"backend": backend, "suite": "pick", "sensor": "ideal",
                "provenance": {"backend_kwargs": {}}, "episode_fields": list(EPISODE_FIELDS),
                "episodes": recs}  # fmt: skip

    rows = [
        row("hbeo", [rec(0, True, True, 0.1, True, 0.02), rec(1, True, True, 0.9, False, 9.0),
                     rec(2, False, False, 0.2), rec(3, False, False, None),
                     rec(4, False, None, None)]),
        row("oracle", [rec(0, True, True, 0.0, True, 0.5), rec(1, True, True, 0.3, True, 0.1)]),
    ]  # fmt: skip
    (tmp_path / "pick.json").write_text(json.dumps(rows))
    return tmp_path


def test_the_audit_table_counts_agreement_and_the_shake_from_the_records(tmp_path) -> None:
    from beo_bench.bench.doctables.boards import Boards
    from beo_bench.bench.doctables.pick import pick_audit

    audit, shake = pick_audit(Boards(_audit_page(tmp_path))).split("\n\n")
    lines = audit.splitlines()
    # every row: 6 executed grasps, 4 lifted, 4 in closure at 0.4, 4 agree; at the pads'
    # 1.2 the 0.9 grasp closes too: 5 agree
    assert lines[2] == "| every row | 6 | 66.7% | 66.7% | 66.7% | 0.25 | 1 | 1 | 83.3% |"
    assert lines[3] == "| `hbeo` | 4 | 50.0% | 50.0% | 50.0% | 0.00 | 1 | 1 | 75.0% |"
    assert lines[4] == "| `oracle` | 2 | 100.0% | 100.0% | 100.0% | 0.00 | 0 | 0 | 100.0% |"
    s = shake.splitlines()
    assert s[2] == "| `hbeo` | 40.0% | 20.0% | 1 | 0.02 | 2 |"
    assert s[3] == "| `oracle` | 100.0% | 100.0% | 0 | 0.30 | 2 |"


def test_each_backends_tolerance_comes_from_its_own_binned_episodes(tmp_path) -> None:
    from beo_bench.bench.doctables.boards import Boards
    from beo_bench.bench.doctables.pick import half_success_tolerance, pick_tolerance

    text = pick_tolerance(Boards(_audit_page(tmp_path)))
    # hbeo: every episode that found its target sits in the 0-5 deg bin: success never
    # falls from the first bin, so no tolerance; the oracle is left out
    assert "| `hbeo` | 5 | never halves | never halves | never halves |" in text
    assert "oracle" not in text
    assert half_success_tolerance([2.0, 10.0, 40.0], [0.8, 0.6, 0.2]) == pytest.approx(
        10.0 + 30.0 * (0.6 - 0.4) / 0.4
    )


def test_the_sensitivity_tolerance_per_category_reads_each_rows_categories(tmp_path) -> None:
    """Issue 49, per category where n allows: the mug loses half of the oracle's success
    between 15 and 30 deg of rotation; the can's oracle picks under a third (no curve)."""
    from beo_bench.bench.doctables.boards import Boards
    from beo_bench.bench.doctables.pick import _sensitivity_per_category
    from beo_bench.bench.suites import get_suite

    seed = get_suite("pick").seed

    def row(kwargs: dict, mug: float, can: float) -> dict:
        per = {"mug": {"pick_success": mug, "n": 28}, "can": {"pick_success": can, "n": 28}}
        return {"backend": "oracle", "suite": "pick", "sensor": "ideal", "seed": seed,
                "track": None, "n": 56, "provenance": {"backend_kwargs": kwargs},
                "per_category": per}  # fmt: skip

    rows = [row({}, 1.0, 0.25)] + [
        row({"rot_deg": d}, m, 0.2) for d, m in ((5, 1.0), (15, 0.8), (30, 0.2), (60, 0.1))
    ]
    (tmp_path / "pick.json").write_text(json.dumps(rows))
    lines = _sensitivity_per_category(Boards(tmp_path)).splitlines()
    assert (
        lines[0]
        == "| category | episodes | the oracle | rotation (deg) | yaw (deg) | translation (cm) |"
    )
    assert lines[2] == "| can | 28 | 25.0% | - | - | - |"
    # 0.8 at 15 deg, 0.2 at 30: 0.5 at 15 + 15 * 0.3 / 0.6 = 22.5 deg; no yaw rows: "-"
    assert lines[3] == "| mug | 28 | 100.0% | 22.5 | - | - |"


def test_the_pick_page_plots_success_against_error_from_the_records(tmp_path) -> None:
    """The page's plot reads the same records as results.md's tables: a PNG of three
    panels, drawn only from episodes that chose their target and record their errors."""
    from beo_bench.bench.pages.plots import _pick_error_plot, error_bins, found_target_episodes

    rows = json.loads((_audit_page(tmp_path) / "pick.json").read_text())
    hbeo = found_target_episodes(rows[0])
    assert len(hbeo) == 5  # every record chose its target and has a rotation error
    assert error_bins(hbeo, "rot_err_deg") == [(5.0, 0.4, 5)]  # all in the 5-15 deg bin
    name = _pick_error_plot(tmp_path, "pick", "pick", rows)
    assert name == "pick_success_vs_error.png"
    assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_robust_planners_primary_names_the_rows_label() -> None:
    """The primary declared for the robust planner must name the row as the page labels
    it (``grasp="robust"``, quoted), or the page says "not run" beside the very row."""
    from beo_bench.bench.pages.verdicts import primary_comparisons
    from beo_bench.bench.runs import backend_label

    robust = backend_label("hbeo-mdn-posterior", {"grasp": "robust"})
    assert robust == 'hbeo-mdn-posterior (grasp="robust")'
    assert any(pc.method == robust for pc in primary_comparisons("pick"))
