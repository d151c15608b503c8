"""The regression gate end to end, as a CI job uses it: in a temporary git repository, a
third-party backend's run is written into a baseline file that is committed; later runs of
a backend that did not change and of one that regressed are gated against the committed
file through the command line (``beo-bench run``, ``baseline``, ``gate``), and the exit
statuses and the JUnit report are what a CI system reads. The plugins are installed as
entry points (``tests/plugins.py``) and answer from the truth they are handed (they declare
``privileged``; ``--allow-privileged``), so each item costs a render and nothing else: the
whole file takes seconds. The planted bug of issue 47 (``benchmarks/planted_bug.py``, a
plugin that turns and moves every estimate of the oracle) is gated the same way on
smoke-size runs, and its runs show that a plugin's changed code is not resumed."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from beo_bench import codedigest
from beo_bench.bench.suites import SMOKE_SIZES, Kind
from beo_bench.cli import main
from tests.plugins import install_plugin

PLUGIN = textwrap.dedent(
    """
    import numpy as np
    from beo_bench.backend import Backend, Capabilities
    from beo_bench.types import Estimate

    class _FromTruth(Backend):
        class_offset = 0

        def predict(self, view):
            gt = view.ground_truth
            probs = np.zeros(len(view.categories))
            probs[(gt.class_index + self.class_offset) % len(probs)] = 1.0
            return Estimate(probs, gt.R_cam, gt.t_cam, gt.size,
                            np.full((16, 16, 16), 0.5, np.float32))

    class Steady(_FromTruth):
        name = "gate-steady"
        capabilities = Capabilities(privileged=True)  # handed each view's truth

    class Worse(_FromTruth):
        # the regression: every class one off, the rest unchanged
        name = "gate-worse"
        capabilities = Capabilities(privileged=True)
        class_offset = 1

    class Broken(Backend):
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
    head = "beo-bench: gate failed: regression in gate-worse class acc. over known-pose"
    assert len(err) == 1 and err[0].startswith(head)
    root = ET.parse("out/worse.xml").getroot()
    assert (root.get("tests"), root.get("failures")) == ("3", "1")
    (suite,) = root.iter("testsuite")
    assert suite.get("name") == "gate-worse" and suite.get("failures") == "1"
    failing = [tc.get("name") for tc in suite.iter("testcase") if tc.find("failure") is not None]
    assert failing == ["class_acc"]
    message = suite.find("testcase/failure").get("message")
    assert "class acc. over known-pose: 100.0% -> 0.0%" in message and f"{ITEMS} items" in message
    assert "**regression**" in Path("out/worse.md").read_text()
    # the default, the primary metrics (known-pose measures the class accuracy), agrees
    assert main(["gate", "runs/worse", "--baseline", "ci/baseline.json"]) == 3
    assert main(["gate", "runs/steady", "--baseline", "runs/base"]) == 0  # a run as baseline

    # a metric no run measures: nothing to gate, a usage error, exit 2, no report written
    capsys.readouterr()
    argv = ["gate", "runs/worse", "--baseline", "ci/baseline.json", "--junit", "out/bad.xml"]
    assert main([*argv, "--metrics", "pick_success"]) == 2
    (err,) = errors(capsys)
    assert err.startswith("beo-bench: error: nothing to gate: no run measures pick_success")
    assert not Path("out/bad.xml").exists()
    # beside one it measures: skipped, and the JUnit report says so
    assert main([*argv, "--metrics", "pick_success", "class_acc"]) == 3
    root = ET.parse("out/bad.xml").getroot()
    assert (root.get("tests"), root.get("failures"), root.get("skipped")) == ("2", "1", "1")
    skipped = [tc.get("name") for tc in root.iter("testcase") if tc.find("skipped") is not None]
    assert skipped == ["pick_success"]


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
    from beo_bench.bench.gate.spec import FailureRateError

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


# -- the planted bug (issue 47) ---------------------------------------------------------------
PLANTED = Path(__file__).resolve().parents[2] / "benchmarks" / "planted_bug.py"
SMOKE = SMOKE_SIZES[Kind.ISOLATED]
"""An isolated suite's items in the smoke set."""


@pytest.fixture
def planted(repo: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The planted-bug plugin installed as distribution ``beo-planted`` (its module copied
    into a site folder, entry point ``planted``); returns the installed module's path."""
    from beo_bench import backend as B

    site = tmp_path / "planted-site"
    site.mkdir()
    shutil.copy(PLANTED, site / "planted_bug.py")
    install_plugin(site, "beo-planted", {"planted": "planted_bug:PlantedBackend"}, monkeypatch)
    yield site / "planted_bug.py"
    B.unregister_backend("planted")
    sys.modules.pop("planted_bug", None)


def smoke_run(backend: str, out: str) -> int:
    """``beo-bench run`` of pose-1dof at its smoke size (``all --suites smoke`` runs it so,
    and draws a leaderboard besides), with ``backend`` (``NAME[:K=V,...]``)."""
    name, _, opts = backend.partition(":")
    argv = ["run", "--suite", "pose-1dof", "--episodes", str(SMOKE), "--backend", name]
    argv += [x for o in opts.split(",") if o for x in ("--opt", o)]
    return main([*argv, "--out", out, "--workers", "1", "--allow-privileged"])


def test_the_default_gate_fails_the_planted_bug_and_passes_a_no_op(repo, planted, capsys) -> None:
    """The oracle's smoke-size runs as the baseline; the plugin on them with the defaults
    (every estimate moved 5 cm and turned 90 deg about its up axis) and with the 5 cm shift
    alone fails the default gate (exit 3, translation among the regressions), and with
    neither it passes (exit 0). Before issue 47 the default gate tested the > 15 deg rate
    alone and passed the shift."""
    assert smoke_run("oracle", "runs/base") == 0
    assert main(["baseline", "runs/base", "--out", "ci/baseline.json"]) == 0
    outcome = {}
    for name, spec in (
        ("both", "planted"),
        ("shift", "planted:yaw_deg=0"),
        ("no-op", "planted:yaw_deg=0,shift_cm=0"),
    ):
        assert smoke_run(spec, f"runs/{name}") == 0
        capsys.readouterr()
        status = main(["gate", f"runs/{name}", "--baseline", "ci/baseline.json",
                       "--json", f"out/{name}.json"])  # fmt: skip
        report = json.loads(Path(f"out/{name}.json").read_text())
        outcome[name] = (status, sorted(v["metric"] for v in report["verdicts"]
                                        if v["outcome"] == "regression"))  # fmt: skip
        assert [v["metric"] for v in report["verdicts"]] == [
            "rot_err_deg_mean", "gross_err_rate", "trans_err_cm_mean", "class_acc",
        ]  # fmt: skip
        assert all(v["items"] == SMOKE for v in report["verdicts"])
    assert outcome == {
        "both": (3, ["gross_err_rate", "rot_err_deg_mean", "trans_err_cm_mean"]),
        "shift": (3, ["trans_err_cm_mean"]),
        "no-op": (0, []),
    }


def test_a_plugin_whose_code_changed_is_refused_or_run_again(repo, planted, capsys) -> None:
    """A plugin's run records the digest of its distribution's code and its options. With
    the code unchanged, `run --resume` and `all` reuse the run; changed (one comment
    added), both refuse it with exit 2 naming --force-rerun, which discards it and runs it
    again under the new digest."""
    argv = ["run", "--suite", "known-pose", "--backend", "planted", "--allow-privileged"]
    argv += ["--episodes", "2", "--workers", "1", "--out", "runs/known-pose__planted"]
    assert main(argv) == 0
    record = json.loads(Path("runs/known-pose__planted/run.json").read_text())
    first = record["code_digest"]
    assert isinstance(first, str) and len(first) == 64
    summary = json.loads(Path("runs/known-pose__planted/summary.json").read_text())
    assert summary["provenance"]["code_digest"] == first
    all_argv = ["all", "--suites", "known-pose", "--episodes", "2", "--backends", "planted"]
    all_argv += ["--runs", "runs", "--out", "boards", "--workers", "1", "--allow-privileged"]
    results = Path("runs/known-pose__planted/results.jsonl")
    scored = results.read_text()
    assert main([*argv, "--resume"]) == 0 and main(all_argv) == 0
    assert results.read_text() == scored  # reused: nothing scored again

    planted.write_text(planted.read_text() + "\n# a change a resume must notice\n")
    for again in ([*argv, "--resume"], all_argv):
        capsys.readouterr()
        assert main(again) == 2, again
        (err,) = errors(capsys)
        assert "scored by other code or options" in err and "--force-rerun" in err
        assert f"code digest {first}, now " in err
    results.write_text(scored.replace('"correct": true', '"correct": false'))  # a marker
    assert main([*all_argv, "--force-rerun"]) == 0
    second = json.loads(Path("runs/known-pose__planted/run.json").read_text())["code_digest"]
    assert second not in (first, None)
    assert '"correct": true' in results.read_text()  # scored again, not resumed
    assert main([*argv, "--resume"]) == 0  # the new digest is the run's now


def test_a_backend_registered_in_process_digests_its_module(tmp_path) -> None:
    """Without a distribution, a backend's code is the file of the module that registered
    it (here, this test file), with its options; an in-tree backend records none (the
    package's version and git commit name its code)."""
    import hashlib

    from beo_bench import backend as B
    from beo_bench.perception.bounds import OracleOptions, RandomBackend, RandomOptions

    class DigestLocal(RandomBackend):
        name = "digest-local"

    assert codedigest.code_digest("oracle", OracleOptions()) is None
    B.register(DigestLocal)
    spec = B.get_spec("digest-local")
    try:
        one, two = (codedigest.code_digest("digest-local", RandomOptions(seed=s)) for s in (0, 1))
        assert one is not None and two is not None and one != two
        mine = codedigest._code_files("digest-local", spec)
        assert list(mine.values()) == [Path(__file__)]
        h = hashlib.sha256(f"module {__name__}".encode() + b"\0")
        h.update(hashlib.sha256(Path(__file__).read_bytes()).digest())
        h.update(b"options\0" + codedigest._options_text(RandomOptions(seed=0)).encode())
        assert one == h.hexdigest()
    finally:
        B.unregister_backend("digest-local")


def test_a_plugins_digest_covers_its_distributions_files_and_options(repo, planted) -> None:
    """A file that only the distribution's RECORD lists (data beside the module) changes
    the digest, as an option does; how it was installed (RECORD, INSTALLER) does not."""
    from beo_bench import backend as B

    B.load_plugins()
    spec = B.get_spec("planted")
    site, info = planted.parent, planted.parent / "beo_planted-0.1.dist-info"
    (site / "planted_data.json").write_text("{}")
    listed = ["planted_bug.py", "planted_data.json", f"{info.name}/METADATA", f"{info.name}/RECORD"]
    (info / "RECORD").write_text("".join(f"{f},,\n" for f in listed))
    first = codedigest.code_digest("planted", spec.parse({}))
    assert f"dist beo-planted:{info.name}/METADATA" in codedigest._code_files("planted", spec)
    (site / "planted_data.json").write_text('{"changed": true}')
    assert codedigest.code_digest("planted", spec.parse({})) != first
    (site / "planted_data.json").write_text("{}")
    (info / "INSTALLER").write_text("pip\n")
    (info / "RECORD").write_text("".join(f"{f},,\n" for f in [*listed, f"{info.name}/INSTALLER"]))
    assert codedigest.code_digest("planted", spec.parse({})) == first
    assert codedigest.code_digest("planted", spec.parse({"shift_cm": 1})) != first


def test_an_editable_plugins_digest_covers_its_package(tmp_path, monkeypatch) -> None:
    """An editable install's RECORD lists a .pth file, not the code: the digest also hashes
    the package its entry point imports, where Python imports it from, so an edit of the
    checkout changes it."""
    from beo_bench import backend as B

    src, site = tmp_path / "src", tmp_path / "site"
    pkg = src / "planted_pkg"
    pkg.mkdir(parents=True)
    site.mkdir()
    shutil.copy(PLANTED, pkg / "bug.py")
    (pkg / "__init__.py").write_text(
        "from planted_pkg.bug import PlantedBackend\n"
        "class PkgBackend(PlantedBackend):\n    name = 'planted-pkg'\n"
    )
    install_plugin(site, "beo-planted-pkg", {"planted-pkg": "planted_pkg:PkgBackend"}, monkeypatch)
    info = site / "beo_planted_pkg-0.1.dist-info"
    pth = "__editable__.beo_planted_pkg.pth"
    (site / pth).write_text(f"{src}\n")
    (info / "RECORD").write_text(f"{pth},,\n{info.name}/METADATA,,\n{info.name}/RECORD,,\n")
    monkeypatch.syspath_prepend(str(src))  # what the .pth does when Python starts
    try:
        assert "planted-pkg" in B.load_plugins()
        spec = B.get_spec("planted-pkg")
        files = codedigest._code_files("planted-pkg", spec)
        assert {f"dist beo-planted-pkg:{pth}", "package planted_pkg:bug.py"} <= set(files)
        first = codedigest.code_digest("planted-pkg", spec.parse({}))
        (pkg / "bug.py").write_text((pkg / "bug.py").read_text() + "\n# edited in place\n")
        assert codedigest.code_digest("planted-pkg", spec.parse({})) != first
    finally:
        B.unregister_backend("planted-pkg")
        for name in ("planted_pkg", "planted_pkg.bug"):
            sys.modules.pop(name, None)
