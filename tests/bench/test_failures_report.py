"""Failures a user can see: a run ends by printing its failures grouped by exception (and a
pick run its reasons), a run in which every view failed says so on stderr too, and
``report.html`` shows the worst views offline (docs/benchmark.md, "Failures and the
report")."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest

from beo_bench.bench.failures import group_failures, summarise_failures
from beo_bench.bench.worstviews import silhouette
from beo_bench.cli import main
from tests.plugins import install_plugin

PLUGIN = '''
from dataclasses import dataclass

import numpy as np
from beo_bench.backend import Backend
from beo_bench.options import option
from beo_bench.types import Estimate


class ModelMissingError(Exception):
    pass


@dataclass(frozen=True)
class ReportOptions:
    mode: str = option("raise", "raise, mixed or anything else: fine")


class Report(Backend):
    """A plugin that misbehaves as its mode says (a test's)."""

    name = "test-report"
    Options = ReportOptions

    def predict(self, view):
        pixels = int(np.count_nonzero(view.mask))
        if self.options.mode == "raise" or (self.options.mode == "mixed" and pixels % 2):
            raise ModelMissingError(f"no model file at /models/x.pt ({pixels} px seen)")
        probs = np.full(len(view.categories), 1.0 / len(view.categories))
        shape = np.zeros((16, 16, 16), dtype=np.float32)
        if self.options.mode != "mixed":  # mixed: an empty shape, nothing to grasp
            shape[3:13, 3:13, 3:13] = 1.0
        pts = view.points()
        return Estimate(probs, np.eye(3), pts.mean(axis=0), np.full(3, 0.2), shape)

'''


@pytest.fixture
def plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """``test-report``, a backend package installed as users install one."""
    import sys

    site = tmp_path / "site"
    site.mkdir()
    (site / "beo_report_plugin.py").write_text(PLUGIN)
    install_plugin(
        site, "beo-report-plugin", {"test-report": "beo_report_plugin:Report"}, monkeypatch
    )
    yield "test-report"
    from beo_bench import backend as B

    B.unregister_backend("test-report")
    sys.modules.pop("beo_report_plugin", None)


def _run(capfd, out: Path, *args: str) -> tuple[int, str, str]:
    code = main(["run", *args, "--workers", "1", "--out", str(out)])
    captured = capfd.readouterr()
    return code, captured.out, captured.err


def _rows(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]


def test_a_plugin_that_raises_on_every_view_is_impossible_to_miss(capfd, tmp_path, plugin):
    out = tmp_path / "run"
    args = ["--suite", "pose-1dof", "--backend", plugin, "--episodes", "5", "--opt", "mode=raise"]
    code, stdout, stderr = _run(capfd, out, *args)
    assert code == 0  # scored as failures, as documented; --max-failure-rate gates on them
    # the run ends with the exception, its message and its count (the numbers in the
    # messages differ, the group is one)
    tail = stdout.strip().splitlines()[-3:]
    assert tail[0] == "failures: 5 of 5 views (100%): EVERY ONE OF THE 5 VIEWS FAILED", tail
    assert re.fullmatch(
        r"  5 x ModelMissingError: no model file at /models/x\.pt \(\d+ px seen\) "
        r"\(5 messages differing in numbers\)",
        tail[1],
    ), tail[1]
    assert tail[2].startswith(f"report: {out / 'report.html'}")
    warning = [line for line in stderr.splitlines() if "every one of the 5 views" in line]
    assert len(warning) == 1 and warning[0].startswith("beo-bench: warning: "), stderr
    assert "5 x ModelMissingError: no model file" in warning[0]
    page = (out / "report.html").read_text()
    assert 'class="alarm"' in page and "5 x ModelMissingError" in page


def test_failures_are_grouped_by_type_and_message_up_to_numbers() -> None:
    groups = group_failures(
        [
            "ValueError: item 3 has 0 points",
            "RuntimeError: boom",
            "ValueError: item 7 has 0 points",
            "timeout after 60 s",
            "ValueError: item 7 has 0 points",
        ]
    )
    assert [g.text() for g in groups] == [
        "3 x ValueError: item 3 has 0 points (2 messages differing in numbers)",
        "1 x RuntimeError: boom",
        "1 x timeout: timeout after 60 s",
    ]
    fs = summarise_failures([{"failure": None}, {"failure": "RuntimeError: boom"}])
    assert fs.lines() == ["failures: 1 of 2 views (50%)", "  1 x RuntimeError: boom"]
    assert fs.warning() is None  # only a run in which every view failed warns


def _cards(page: str) -> list[str]:
    return page.split('<div class="card')[1:]


def _check_self_contained(page: str) -> None:
    assert "<script" not in page.lower()
    assert not re.search(r"https?://", page), "the report must name no address"
    srcs = re.findall(r'src="([^"]*)"', page)
    assert srcs and all(s.startswith("data:image/png;base64,") for s in srcs)
    for s in srcs:  # each image is a PNG
        assert base64.b64decode(s.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_report_shows_the_worst_views_offline(capfd, tmp_path, plugin) -> None:
    out = tmp_path / "run"
    args = ["--episodes", "5", "--opt", "mode=cube", "--report-views", "3"]
    code, stdout, _ = _run(capfd, out, "--suite", "pose-1dof", "--backend", plugin, *args)
    assert code == 0 and "failures: none (5 views)" in stdout
    page = (out / "report.html").read_text()
    _check_self_contained(page)
    cards = _cards(page)
    assert len(cards) == 3
    assert all(c.count("<img ") == 3 for c in cards)  # depth, mask, silhouettes
    # the worst three by rotation error, largest first, each with its errors
    rows = sorted(_rows(out), key=lambda r: -r["rot_err_deg"])[:3]
    for card, row in zip(cards, rows, strict=True):
        assert f"item {row['item']} view 0: {row['category']}" in card
        assert f"<td>{row['rot_err_deg']:.1f} deg</td>" in card and "voxel IoU" in card
        assert "does not answer the same" not in card  # predicted again: the same estimate


def test_report_views_0_writes_no_report(capfd, tmp_path, plugin) -> None:
    out = tmp_path / "run"
    args = ["--suite", "pose-1dof", "--backend", plugin, "--episodes", "2", "--report-views", "0"]
    code, stdout, _ = _run(capfd, out, *args)
    assert code == 0 and not (out / "report.html").exists() and "report:" not in stdout


def test_a_pick_run_prints_its_reasons_and_its_report_shows_them(capfd, tmp_path, plugin):
    out = tmp_path / "pick"
    args = ["--suite", "pick", "--backend", plugin, "--episodes", "3", "--opt", "mode=mixed"]
    code, stdout, _ = _run(capfd, out, *args)
    assert code == 0
    rows = _rows(out)
    counts: dict[str, int] = {}
    for r in rows:
        counts[r["reason"]] = counts.get(r["reason"], 0) + 1
    assert set(counts) <= {"no_estimate", "empty_shape"}  # raised, or an empty shape
    expected = ", ".join(f"{k} {v}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))
    lines = stdout.splitlines()
    assert f'pick reasons, pick {plugin} (mode="mixed"): {expected}' in lines  # the table
    assert f"pick reasons: {expected}" in lines  # the run's end
    page = (out / "report.html").read_text()
    _check_self_contained(page)
    cards = _cards(page)
    assert len(cards) == len(rows)
    for r in rows:  # every episode shows its reason
        card = next(c for c in cards if f"episode {r['item']}:" in c)
        assert f'<td class="k">reason</td><td>{r["reason"]}</td>' in card


def test_the_pick_reasons_the_report_orders_are_the_documented_ones() -> None:
    from beo_bench.bench.kinds.pick import REASON_ORDER
    from tests.envs.test_pick_reasons_doc import _documented_reasons

    assert set(REASON_ORDER) == _documented_reasons() - {"success"}


def test_a_silhouette_projects_the_true_voxels_onto_the_mask() -> None:
    """The truth's voxels placed by its pose and projected with the view's intrinsics cover
    the object's mask (the rendering of its mesh): the geometry the report draws with."""
    from beo_bench.bench.kinds.isolated import IsolatedItems
    from beo_bench.bench.scoring import truth_shape
    from beo_bench.bench.suites import get_suite

    items = IsolatedItems(get_suite("pose-3dof"))
    try:
        for index in (1, 6, 13):  # a bathtub, a can, a mug (no part thinner than a voxel)
            view, gt = items.isolated_view(index)
            voxels = truth_shape(gt.key, 32).voxels
            sil = silhouette(voxels, gt.R_cam, gt.t_cam, gt.size, view.K, view.depth.shape)
            iou = np.count_nonzero(sil & view.mask) / np.count_nonzero(sil | view.mask)
            assert iou > 0.85, (index, gt.key, iou)
            # moved 5 cm sideways, it no longer does
            t = gt.t_cam + np.array([0.05, 0.0, 0.0])
            off = silhouette(voxels, gt.R_cam, t, gt.size, view.K, view.depth.shape)
            assert np.count_nonzero(off & view.mask) / np.count_nonzero(off | view.mask) < iou
    finally:
        items.close()


def test_each_run_of_all_ends_with_its_failures(capfd, tmp_path, plugin) -> None:
    where = ["--runs", str(tmp_path / "runs"), "--out", str(tmp_path / "lb")]
    what = ["--suites", "pose-1dof", "--backends", f"{plugin}:mode=raise", "--episodes", "2"]
    assert main(["all", *what, "--workers", "1", *where]) == 0
    captured = capfd.readouterr()
    lines = captured.out.splitlines()
    head = f'pose-1dof@class-free / {plugin} (mode="raise"): failures: 2 of 2 views (100%)'
    at = next(i for i, line in enumerate(lines) if line.startswith(head))
    assert lines[at + 1].startswith("  2 x ModelMissingError: no model file at /models/x.pt")
    assert "every one of the 2 views of run pose-1dof@class-free" in captured.err


def test_the_pick_report_shows_the_grasp_audits_disagreements_first() -> None:
    """Issue 49: episodes whose simulated outcome and force-closure check disagree lead
    the pick report (either way round), then failures by reason, then successes; the card
    says both checks and the shake."""
    from beo_bench.bench.kinds.pick import rank_rows
    from beo_bench.bench.suites import get_suite
    from beo_bench.bench.worstviews import row_errors

    rows = [
        {"item": 0, "success": True, "reason": "success", "lifted_chosen": True,
         "force_closure": True, "fc_mu": 0.1, "shake_held": True, "slip_cm": 0.01},
        {"item": 1, "success": False, "reason": "nothing_lifted", "lifted_chosen": False,
         "force_closure": False, "fc_mu": None},
        {"item": 2, "success": True, "reason": "success", "lifted_chosen": True,
         "force_closure": False, "fc_mu": 0.9, "shake_held": False, "slip_cm": 12.0},
        {"item": 3, "success": False, "reason": "no_grasp"},
        {"item": 4, "success": False, "reason": "nothing_lifted", "lifted_chosen": False,
         "force_closure": True, "fc_mu": 0.2},
    ]  # fmt: skip
    assert rank_rows(get_suite("pick"), rows).order == [2, 4, 3, 1, 0]
    shown = dict(row_errors(rows[2], ["mug"]))
    assert shown["force closure at mu 0.4"] == "no (mu >= 0.90)"
    assert shown["lifted what it aimed at"] == "yes"
    assert shown["after the shake"] == "dropped, slipped 12.0 cm"
