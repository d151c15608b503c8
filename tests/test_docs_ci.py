"""docs/ci.md's CI jobs do what the page says: each YAML file parses, installs the
Makefile's way, keeps ``BEO_BENCH_CACHE`` in the CI system's cache, runs the smoke set,
gates against the committed baseline the page tells how to write, and uploads the JUnit and
Markdown reports the gate writes and each run's ``report.html``; every ``beo-bench`` command
in them passes the real parser and registries (``tests/docs_blocks.py``, as a check block's
commands do)."""

from __future__ import annotations

from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any

import yaml  # the dev extra's (pyproject.toml): a missing PyYAML fails here, never skips

from beo_bench.bench.rundir import REPORT_NAME
from beo_bench.bench.runs import run_name
from beo_bench.bench.suites import expand_suites
from tests.docs_blocks import ROOT, YAML_LANGS, blocks, check_command, shell_commands, yaml_commands

PAGE = ROOT / "docs" / "ci.md"


def _jobs() -> dict[str, Any]:
    """The page's YAML files by CI system (GitHub Actions has ``jobs``; a GitLab file's top
    level holds the jobs)."""
    out = {}
    for b in blocks(PAGE):
        if b.lang in YAML_LANGS:
            doc = yaml.safe_load(b.code)
            out["github" if "jobs" in doc else "gitlab"] = doc
    return out


def _flag(argv: list[str], flag: str) -> str:
    assert flag in argv, f"{flag} missing from beo-bench {' '.join(argv)}"
    return argv[argv.index(flag) + 1]


_CHECKED: set[tuple[str, ...]] = set()


def _commands(doc: Any) -> dict[str, list[str]]:
    cmds = yaml_commands(doc)
    for argv in cmds:
        if tuple(argv) not in _CHECKED:  # once: checking builds the backend it names
            check_command(argv)  # the real parser: a wrong flag, suite or backend fails here
            _CHECKED.add(tuple(argv))
    return {argv[0]: argv for argv in cmds}


def _baseline_the_page_writes() -> str:
    """Where the page's "The baseline" commands write the baseline file."""
    for b in blocks(PAGE):
        for argv in shell_commands(b.code) if b.lang == "bash" else []:
            if argv[0] == "baseline":
                _commands({"run": "beo-bench " + " ".join(argv)})
                return _flag(argv, "--out")
    raise AssertionError("docs/ci.md does not say how to write the baseline")


def _gate_and_smoke(doc: Any) -> tuple[list[str], list[str]]:
    cmds = _commands(doc)
    assert set(cmds) == {"all", "gate"}, sorted(cmds)
    smoke, gate = cmds["all"], cmds["gate"]
    assert _flag(smoke, "--suites") == "smoke" and _flag(smoke, "--backends")
    assert _flag(gate, "--baseline") == _baseline_the_page_writes()
    assert gate[1] == _flag(smoke, "--runs")  # it gates the runs the smoke set made
    return smoke, gate


def _uploaded(path: str, patterns: list[str]) -> bool:
    """Whether a CI upload of ``patterns`` takes the file ``path`` (relative to the checkout):
    a pattern ending in ``/`` takes its folder; a glob's ``*`` matches within one folder."""
    parts = path.split("/")
    for p in patterns:
        if p.endswith("/") and path.startswith(p):
            return True
        globs = p.rstrip("/").split("/")
        if len(globs) == len(parts) and all(map(fnmatchcase, parts, globs)):
            return True
    return False


def _uploads_every_runs_report(smoke: list[str], patterns: list[str]) -> None:
    """The smoke set's runs each write ``report.html`` (``all`` does unless told
    ``--report-views 0``), and the upload takes every one of them."""
    if "--report-views" in smoke:
        assert int(_flag(smoke, "--report-views")) > 0, "the runs write no report.html"
    runs = _flag(smoke, "--runs").rstrip("/")
    backend = _flag(smoke, "--backends")
    suites = expand_suites([_flag(smoke, "--suites")])
    assert len(suites) > 3
    for suite in suites:  # a run directory of each suite of the set (tracks: names alike)
        report = f"{runs}/{run_name(suite, backend, {}, track='class-free')}/{REPORT_NAME}"
        assert _uploaded(report, patterns), f"{report} is not uploaded by {patterns}"


def test_the_upload_checker_reads_globs_and_folders() -> None:
    report = "runs/pose-1dof@class-free__hbeo/report.html"
    assert _uploaded(report, ["out/", "runs/*/report.html"])
    assert _uploaded(report, ["runs/"])
    assert not _uploaded(report, ["out/", "runs/report.html", "runs/*/summary.json"])
    assert not _uploaded(report, ["runs/*.html"])  # a glob's * stays in one folder


def test_the_page_has_a_github_and_a_gitlab_job() -> None:
    assert set(_jobs()) == {"github", "gitlab"}


def test_the_github_job_installs_caches_runs_gates_and_uploads() -> None:
    doc = _jobs()["github"]
    (job,) = doc["jobs"].values()
    steps = job["steps"]
    runs = [s.get("run", "") for s in steps]
    assert "make setup" in runs  # the Makefile's install, through constraints.txt
    cache_dir = job["env"]["BEO_BENCH_CACHE"]
    (cache,) = [s for s in steps if str(s.get("uses", "")).startswith("actions/cache@")]
    assert cache["with"]["path"] in cache_dir and cache["with"]["restore-keys"]
    smoke, gate = _gate_and_smoke(doc)
    (upload,) = [s for s in steps if str(s.get("uses", "")).startswith("actions/upload-artifact@")]
    assert upload["if"] == "always()"  # the report is wanted most when the gate fails
    uploaded = upload["with"]["path"].split()
    assert _flag(gate, "--junit") in uploaded and _flag(gate, "--markdown") in uploaded
    _uploads_every_runs_report(smoke, uploaded)
    order = [i for i, r in enumerate(runs) if "make setup" in r or "beo-bench" in r]
    assert order == sorted(order) and steps.index(cache) < order[1]  # cache before the runs


def test_the_gitlab_job_installs_caches_runs_gates_and_uploads() -> None:
    (job,) = _jobs()["gitlab"].values()
    assert job["script"][0] == "make setup"
    cache_dir = job["variables"]["BEO_BENCH_CACHE"].replace("$CI_PROJECT_DIR/", "")
    assert any(p.rstrip("/") == cache_dir for p in job["cache"]["paths"])
    smoke, gate = _gate_and_smoke(job)
    artifacts = job["artifacts"]
    assert artifacts["when"] == "always"
    assert artifacts["reports"]["junit"] == _flag(gate, "--junit")
    assert _uploaded(_flag(gate, "--markdown"), artifacts["paths"])
    _uploads_every_runs_report(smoke, artifacts["paths"])


def test_shell_commands_are_found_where_a_ci_file_puts_them() -> None:
    """What ``yaml_commands`` reads: a step's string, a list of strings, a folded block,
    continuation lines, after ``&&``; not a word ``beo-bench`` in an argument or comment."""
    doc = yaml.safe_load(
        "a:\n  steps:\n    - run: |\n        make setup && .venv/bin/beo-bench gate r \\\n"
        "          --baseline b.json  # beo-bench run\n"
        "b:\n  script:\n    - echo beo-bench\n    - beo-bench baseline r --out b.json\n"
        "name: beo-bench all\n"
    )
    assert yaml_commands(doc) == [
        ["gate", "r", "--baseline", "b.json"],
        ["baseline", "r", "--out", "b.json"],
    ]
    assert Path(PAGE).is_file()
