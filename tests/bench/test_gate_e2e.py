"""The regression gate end to end, as a CI job uses it: in a temporary git repository, a
third-party backend's run is written into a baseline file that is committed; later runs of
a backend that did not change and of one that regressed are gated against the committed
file through the command line (``beo-bench run``, ``baseline``, ``gate``), and the exit
statuses and the JUnit report are what a CI system reads. The plugins are installed as
entry points (``tests/plugins.py``) and answer from the truth they are handed (they declare
``privileged``; ``--allow-privileged``), so each item costs a render and nothing else: the
whole file takes seconds."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from beo_bench.cli import main
from tests.plugins import install_plugin

PLUGIN = textwrap.dedent(
    """
    import numpy as np
    from beo_bench.types import Estimate

    class _FromTruth:
        privileged = True  # handed each view's truth: a render per item, nothing more
        class_offset = 0

        def predict(self, view):
            gt = view.ground_truth
            probs = np.zeros(len(view.categories))
            probs[(gt.class_index + self.class_offset) % len(probs)] = 1.0
            return Estimate(probs, gt.R_cam, gt.t_cam, gt.size,
                            np.full((16, 16, 16), 0.5, np.float32))

    class Steady(_FromTruth):
        name = "gate-steady"

    class Worse(_FromTruth):
        # the regression: every class one off, the rest unchanged
        name = "gate-worse"
        class_offset = 1

    class Broken:
        name = "gate-broken"

        def predict(self, view):
            raise RuntimeError("broken on purpose")
    """
)
ITEMS = 8
"""known-pose items: the exact sign-flip p of 8 items all worse is 2/2^8 = 0.008."""


@pytest.fixture
def repo(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A git repository as the working directory, with the plugins installed."""
    from beo_bench import backend as B

    root = tmp_path / "repo"
    root.mkdir()
    git(root, "init", "-q")
    site = tmp_path / "site"
    site.mkdir()
    (site / "beo_gate_plugins.py").write_text(PLUGIN)
    names = {"gate-steady": "Steady", "gate-worse": "Worse", "gate-broken": "Broken"}
    install_plugin(
        site, "beo-gate-plugins", {n: f"beo_gate_plugins:{c}" for n, c in names.items()},
        monkeypatch,
    )  # fmt: skip
    monkeypatch.chdir(root)
    yield root
    for name in names:
        B.unregister_backend(name)
    sys.modules.pop("beo_gate_plugins", None)


def git(root: Path, *args: str) -> str:
    ident = ["-c", "user.name=gate test", "-c", "user.email=gate@example.invalid"]
    done = subprocess.run(["git", "-C", str(root), *ident, *args], capture_output=True,
                          text=True, check=True)  # fmt: skip
    return done.stdout


def errors(capsys: pytest.CaptureFixture[str]) -> list[str]:
    """The CLI's own stderr lines (the progress bars aside)."""
    return [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("beo-bench:")]


def run(backend: str, out: str, *extra: str) -> int:
    argv = ["run", "--suite", "known-pose", "--backend", backend, "--allow-privileged"]
    return main([*argv, "--episodes", str(ITEMS), "--workers", "1", "--out", out, *extra])


def test_gate_passes_an_unchanged_backend_and_fails_a_regression(repo, capsys) -> None:
    assert run("gate-steady", "runs/base") == 0
    assert main(["baseline", "runs/base", "--out", "ci/baseline.json"]) == 0
    git(repo, "add", "ci/baseline.json")
    git(repo, "commit", "-q", "-m", "baseline")
    committed = git(repo, "show", "HEAD:ci/baseline.json")
    assert json.loads(committed)["runs"][0]["label"] == "known-pose"

    # the backend that did not change: exit 0, every test case passes
    assert run("gate-steady", "runs/steady") == 0
    metrics = ["--metrics", "class_acc", "iou_mean", "failure_rate"]
    report = ["--junit", "out/steady.xml", "--json", "out/steady.json"]
    capsys.readouterr()
    assert main(["gate", "runs/steady", "--baseline", "ci/baseline.json", *metrics, *report]) == 0
    assert "gate: pass (3 tests, no regression)" in capsys.readouterr().out
    root = ET.parse("out/steady.xml").getroot()
    assert (root.get("tests"), root.get("failures")) == ("3", "0")
    assert [tc.get("name") for tc in root.iter("testcase")] == [
        "class_acc", "iou_mean", "failure_rate",
    ]  # fmt: skip
    assert not list(root.iter("failure"))
    assert json.loads(Path("out/steady.json").read_text())["passed"] is True

    # the backend that regressed: exit 3, one failure element, on the class accuracy
    assert run("gate-worse", "runs/worse") == 0
    argv = ["gate", "runs/worse", "--baseline", "ci/baseline.json", *metrics]
    assert main([*argv, "--junit", "out/worse.xml", "--markdown", "out/worse.md"]) == 3
    err = errors(capsys)
    assert len(err) == 1 and err[0].startswith("beo-bench: gate failed: regression in known-pose")
    root = ET.parse("out/worse.xml").getroot()
    assert (root.get("tests"), root.get("failures")) == ("3", "1")
    (suite,) = root.iter("testsuite")
    assert suite.get("name") == "known-pose" and suite.get("failures") == "1"
    failing = [tc.get("name") for tc in suite.iter("testcase") if tc.find("failure") is not None]
    assert failing == ["class_acc"]
    message = suite.find("testcase/failure").get("message")
    assert "class acc.: 100.0% -> 0.0%" in message and f"{ITEMS} items" in message
    assert "**regression**" in Path("out/worse.md").read_text()
    # the default, the suite's primary metric (known-pose: the class accuracy), agrees
    assert main(["gate", "runs/worse", "--baseline", "ci/baseline.json"]) == 3
    assert main(["gate", "runs/steady", "--baseline", "runs/base"]) == 0  # a run as baseline

    # what the suite does not measure: a usage error, exit 2, and no report written
    capsys.readouterr()
    argv = ["gate", "runs/worse", "--baseline", "ci/baseline.json", "--junit", "out/bad.xml"]
    assert main([*argv, "--metrics", "pick_success"]) == 2
    (err,) = errors(capsys)
    assert err.startswith("beo-bench: error: ") and "has no metric 'pick_success'" in err
    assert not Path("out/bad.xml").exists()


def test_max_failure_rate_exits_3_after_writing_the_results(repo, capsys) -> None:
    argv = ["run", "--suite", "known-pose", "--backend", "gate-broken", "--episodes", "2"]
    argv += ["--workers", "1", "--out", "runs/broken"]
    assert main([*argv, "--max-failure-rate", "0.5"]) == 3
    # the run's own warning that every view failed comes first (issue 30, point 4)
    err = [ln for ln in errors(capsys) if not ln.startswith("beo-bench: warning:")]
    assert len(err) == 1 and "failure rate above --max-failure-rate 0.5" in err[0]
    assert "runs/broken (2 of 2 views failed, 100.0%)" in err[0]
    summary = json.loads(Path("runs/broken/summary.json").read_text())
    assert summary["n"] == 2 and summary["failures"] == 2  # written before the exit
    assert main([*argv, "--resume", "--max-failure-rate", "1"]) == 0  # 100% is not above 1


def test_a_campaign_finishes_then_exits_3_on_its_failure_rate(repo) -> None:
    from beo_bench.bench.campaign import Campaign, run_campaign
    from beo_bench.bench.gate import FailureRateError

    c = Campaign(
        {"known-pose": 2},
        [("gate-broken", {}), ("gate-steady", {})],
        runs=Path("runs"),
        leaderboards=Path("boards"),
        workers=1,
        progress=False,
        allow_privileged=True,
        max_failure_rate=0.0,
    )
    with pytest.raises(FailureRateError, match="known-pose__gate-broken") as e:
        run_campaign(c)
    assert "gate-steady" not in str(e.value)
    assert Path("runs/known-pose__gate-steady/summary.json").is_file()  # it ran on
    assert Path("boards/known-pose.md").is_file()  # and the leaderboard was written
