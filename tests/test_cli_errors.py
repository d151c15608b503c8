"""``beo-bench`` turns every bad argument into one line on stderr and an exit status (2 for
a usage error, 1 for a failure, 130 when interrupted), never a traceback."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from beo_bench import cli
from beo_bench.cli import main
from beo_bench.errors import CheckpointError
from beo_bench.objects import cache
from tests.plugins import install_plugin

RUN = ["run", "--suite", "pose-1dof", "--backend", "random"]


def _usage_error(capsys, argv: list[str]) -> str:
    """argparse's own usage error: SystemExit(2) and the reason on stderr."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err.strip().splitlines()[-1]


@pytest.mark.parametrize(
    "argv, match",
    [
        ([*RUN, "--episodes", "0"], "--episodes: 0 is out of range: give a whole number >= 1"),
        ([*RUN, "--episodes", "-1"], "--episodes: -1 is out of range"),
        ([*RUN, "--episodes", "ten"], "--episodes: 'ten' is not a whole number"),
        ([*RUN, "--workers", "0"], "--workers: 0 is out of range"),
        ([*RUN, "--workers", "-3"], "--workers: -3 is out of range"),
        ([*RUN, "--seed", "-1"], "--seed: -1 is out of range: .* non-negative"),
        ([*RUN, "--opt", "bogus"], "--opt: 'bogus': use KEY=VALUE"),
        ([*RUN, "--opt", "=1"], "--opt: '=1': use KEY=VALUE"),
        ([*RUN, "--item-timeout", "0"], "--item-timeout: 0 is out of range"),
        ([*RUN, "--item-timeout", "nan"], "--item-timeout: nan is out of range"),
        ([*RUN, "--item-timeout", "soon"], "--item-timeout: 'soon' is not a number"),
        (["all", "--episodes", "0"], "--episodes: 0 is out of range"),
        (["all", "--workers", "-3"], "--workers: -3 is out of range"),
        (["all", "--seed", "-1"], "--seed: -1 is out of range"),
        (["all", "--item-timeout", "-5"], "--item-timeout: -5 is out of range"),
        (["all", "--backends", "icp:starts"], "--backends: backend 'icp:starts': option"),
        (["pick-check", "--episodes", "-2"], "--episodes: -2 is out of range"),
        (["pick-check", "--seed", "-1"], "--seed: -1 is out of range"),
        (["objects", "--per-category", "-1"], "--per-category: -1 is out of range"),
        (["objects", "--resolution", "100000"], "--resolution: 100000 is out of range: .*8 to 128"),
        (["objects", "--resolution", "4"], "--resolution: 4 is out of range"),
        (["objects", "--workers", "0"], "--workers: 0 is out of range"),
        # the dataset is --objects on every command; --root, objects' older spelling, says so
        (
            ["objects", "--root", "data/m"],
            "--root: `objects` takes the dataset as every command"
            r" does: --objects data/m \(--root was its older spelling\)$",
        ),
        (["view", "--seed", "-1"], "--seed: -1 is out of range"),
        (["view", "--image-size", "0", "48"], "--image-size: 0 is out of range"),
        (["view", "--image-size", "20000", "100"], "--image-size: 20000 is out of range"),
        (["view", "--num-objects", "0"], "--num-objects: 0 is out of range"),
        (["demo", "--workers", "0"], "--workers: 0 is out of range"),
        (["demo", "--per-category", "0"], "--per-category: 0 is out of range"),
        (["train", "beo", "--resolution", "100000"], "--resolution: 100000 is out of range"),
        (["train", "beo", "--per-category", "0"], "--per-category: 0 is out of range"),
        (["train", "beo", "--variance-fraction", "1.5"], "--variance-fraction: 1.5 is out"),
        (["train", "beo", "--name", "../evil"], "--name: model name '../evil' is not a plain"),
        (["train", "beo", "--name", "/tmp/x"], "--name: model name '/tmp/x' is not a plain"),
        (["train", "hbeo", "--epochs", "0"], "--epochs: 0 is out of range"),
        (["train", "hbeo", "--batch-size", "0"], "--batch-size: 0 is out of range"),
        (["train", "hbeo", "--images", "0"], "--images: 0 is out of range"),
        (["train", "hbeo", "--val-images", "-1"], "--val-images: -1 is out of range"),
        (["render-dataset", "--workers", "0"], "--workers: 0 is out of range"),
        (["render-dataset", "--seed", "-1"], "--seed: -1 is out of range"),
        (["cache", "clear", "--kind", "../../etc"], "--kind: invalid choice: '../../etc'"),
        (["cache", "clear", "--kind", "/"], "--kind: invalid choice: '/'"),
    ],
)
def test_bad_arguments_are_usage_errors(capsys, argv, match) -> None:
    import re

    last = _usage_error(capsys, argv)
    assert re.search(match, last), last


def test_cache_clear_of_a_path_deletes_nothing(capsys, tmp_path) -> None:
    keep = tmp_path / "keep.txt"
    keep.write_text("not the cache's")
    _usage_error(capsys, ["cache", "clear", "--kind", str(tmp_path)])
    assert keep.read_text() == "not the cache's"
    assert set(cache.KINDS) >= {"models", "voxels"}  # the choices are the cache's own kinds


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("beo-bench: "), err
    return lines[0]


@pytest.mark.parametrize(
    "opts, match",
    [
        (
            ["bogus=1"],
            r"backend 'random' has no option 'bogus'; its options: seed \(an integer, default 0\)",
        ),
        (["seed=abc"], r"option seed='abc': expected an integer"),
        (["mean_instances=2", "x=1"], "no option 'x'"),
    ],
)
def test_bad_backend_options_exit_2_listing_the_options(capsys, opts, match) -> None:
    import re

    argv = [*RUN, *(a for o in opts for a in ("--opt", o))]
    assert main(argv) == 2
    line = _one_error_line(capsys)
    assert re.search(match, line), line


def test_a_non_boolean_option_says_the_accepted_values(capsys) -> None:
    argv = ["run", "--suite", "pose-1dof", "--backend", "icp", "--opt", "point_to_plane=maybe"]
    assert main(argv) == 2
    assert "expected a boolean (true/false, yes/no, on/off, 1/0)" in _one_error_line(capsys)


def test_unknown_suite_is_a_usage_error(capsys) -> None:
    assert main(["run", "--suite", "nope", "--backend", "random"]) == 2
    assert "unknown suite 'nope'; the suites are" in _one_error_line(capsys)
    assert main(["all", "--suites", "pose-1dof", "nope", "--backends", "random"]) == 2
    assert "unknown suite 'nope'" in _one_error_line(capsys)


def test_compare_of_missing_and_corrupt_summaries(capsys, tmp_path) -> None:
    assert main(["compare", str(tmp_path / "none")]) == 2
    assert "does not exist" in _one_error_line(capsys)
    bad = tmp_path / "run"
    bad.mkdir()
    (bad / "summary.json").write_text('{"suite": "pose-1d')  # cut off mid-write
    assert main(["compare", str(bad)]) == 1
    assert "is not a readable summary" in _one_error_line(capsys)


def _failing_command(monkeypatch, exc: BaseException) -> None:
    def boom(args) -> int:
        raise exc

    monkeypatch.setattr(cli.command_module("compare"), "run", boom)


@pytest.mark.parametrize(
    "exc, code, match",
    [
        (
            OSError(errno.ENOSPC, "No space left on device", "/data/runs/x/results.jsonl"),
            1,
            r"error: No space left on device: /data/runs/x/results.jsonl; free some disk",
        ),
        (
            PermissionError(errno.EACCES, "Permission denied", "/ro/out"),
            1,
            r"error: Permission denied: /ro/out; choose a writable place",
        ),
        (
            OSError(errno.EROFS, "Read-only file system", "/ro/a.tmp", None, "/ro/a"),
            1,
            r"Read-only file system: /ro/a.tmp -> /ro/a; choose a writable",
        ),
        (CheckpointError("model 'x' is corrupt;\nretrain it"), 1, "error: model 'x' is corrupt"),
        (KeyboardInterrupt(), 130, r"^beo-bench: interrupted; "),
    ],
)
def test_failures_are_one_line_with_their_exit_code(capsys, monkeypatch, exc, code, match):
    import re

    _failing_command(monkeypatch, exc)
    assert main(["compare", "x"]) == code
    line = _one_error_line(capsys)
    assert re.search(match, line), line


def test_interrupted_run_says_how_to_resume(capsys, monkeypatch) -> None:
    def interrupted(args) -> int:
        raise KeyboardInterrupt

    monkeypatch.setattr(cli.command_module("run"), "run", interrupted)
    assert main(RUN) == 130
    assert _one_error_line(capsys) == (
        "beo-bench: interrupted; run the same command with --resume to continue"
    )


def test_a_real_write_failure_names_the_path(capsys, tmp_path) -> None:
    """``--out`` below a regular file: the OS refuses the write, the CLI says where."""
    (tmp_path / "file").write_text("a file, not a directory")
    out = tmp_path / "file" / "view"
    argv = ["view", "--out", str(out), "--no-rrd", "--image-size", "64", "48"]
    assert main([*argv, "--num-objects", "1"]) == 1
    line = _one_error_line(capsys)
    assert line.startswith("beo-bench: error: ") and str(tmp_path / "file") in line, line


def _entry_point() -> list[str]:
    exe = Path(sys.executable).with_name("beo-bench")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "beo_bench.cli"]


def test_entry_point_exit_status_and_one_line(tmp_path) -> None:
    """The installed ``beo-bench`` script: status 2 and exactly one stderr line."""
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    cmd = [*_entry_point(), *RUN, "--opt", "bogus=1", "--out", str(tmp_path / "r")]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert lines[0].startswith("beo-bench: error: backend 'random' has no option 'bogus'")
    assert not (tmp_path / "r").exists()  # refused before anything was written


# -- a broken third-party plugin --------------------------------------------------------
@pytest.fixture
def broken_plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    from beo_bench import backend as B

    site = tmp_path / "site"
    site.mkdir()
    (site / "beo_cli_broken_mod.py").write_text("raise RuntimeError('half-installed')\n")
    install_plugin(
        site, "beo-cli-broken", {"cli-broken": "beo_cli_broken_mod:Backend"}, monkeypatch
    )
    monkeypatch.setattr(B, "_BROKEN", {})
    yield site
    sys.modules.pop("beo_cli_broken_mod", None)


def test_asking_for_a_broken_plugin_exits_1_naming_it(capsys, broken_plugin) -> None:
    argv = ["run", "--suite", "pose-1dof", "--backend", "cli-broken"]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    warning, error = err.strip().splitlines()
    assert warning.startswith("beo-bench: warning: backend plugin beo-cli-broken")
    assert "RuntimeError: half-installed" in warning
    assert error.startswith("beo-bench: error: backend 'cli-broken': plugin beo-cli-broken")
    assert "half-installed" in error


def test_a_broken_plugin_does_not_stop_the_other_backends(capfd, broken_plugin, tmp_path):
    out = tmp_path / "run"
    argv = [*RUN, "--episodes", "2", "--workers", "2", "--opt", "mean_instances=2"]
    assert main([*argv, "--out", str(out)]) == 0
    err = capfd.readouterr().err  # the workers' stderr too: they load the plugins again
    assert err.count("backend plugin beo-cli-broken") == 1  # warned once, by the CLI
    assert "beo-bench: warning: backend plugin beo-cli-broken" in err
    assert "Traceback" not in err
    assert json.loads((out / "summary.json").read_text())["n"] == 2


def test_item_timeout_reaches_the_runner_and_the_campaign(monkeypatch, tmp_path) -> None:
    import beo_bench.bench.campaign as campaign
    import beo_bench.bench.runner as runner

    seen: dict[str, object] = {}

    def fake_run(cfg, out, **kw):
        seen["run"] = kw.get("item_timeout")
        return {"suite": "pose-1dof", "backend": "random", "n": 0, "failures": 0, "metrics": {}}

    def fake_campaign(c):
        seen["campaign"] = c.item_timeout
        return []

    monkeypatch.setattr(runner, "run", fake_run)
    monkeypatch.setattr(campaign, "run_campaign", fake_campaign)
    monkeypatch.setattr(
        campaign, "Campaign", lambda *a, **kw: type("C", (), {"leaderboards": tmp_path, **kw})
    )
    assert main([*RUN, "--item-timeout", "2.5", "--out", str(tmp_path / "r")]) == 0
    argv = ["all", "--suites", "pose-1dof", "--backends", "random", "--item-timeout", "7"]
    assert main([*argv, "--runs", str(tmp_path / "runs"), "--out", str(tmp_path)]) == 0
    assert seen == {"run": 2.5, "campaign": 7.0}


def test_version_and_help_say_what_the_command_is(capsys) -> None:
    import beo_bench
    from beo_bench.cli import main

    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == (
        f"beo-bench {beo_bench.__version__}"
    )
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "Benchmark object-centric perception" in out and "Exit status" in out


def test_all_takes_categories_as_run_does(monkeypatch, tmp_path, capsys) -> None:
    """`all --categories` makes each suite SUITE+SET as `run --categories` names it (by
    default the isolated suites of every class), and refuses what `run` refuses with the
    same line, before any run."""
    import beo_bench.bench.campaign as campaign
    from beo_bench.bench.suites import SUITES, Kind

    seen = {}

    def fake_campaign(c):
        seen["suites"] = c.suites
        return []

    monkeypatch.setattr(campaign, "run_campaign", fake_campaign)
    where = ["--runs", str(tmp_path / "runs"), "--out", str(tmp_path / "boards")]
    argv = ["all", "--backends", "random", "--categories", "mug", "car", *where]
    assert main(argv) == 0
    every_class = [n for n, s in SUITES.items() if s.kind is Kind.ISOLATED and not s.categories]
    assert "pose-3dof" in every_class and "tabletop" not in every_class
    assert sorted(seen["suites"]) == sorted(f"{n}+mug+car" for n in every_class)
    argv = ["all", "--suites", "pose-1dof", "known-pose", "--categories", "modelnet10"]
    assert main([*argv, "--episodes", "3", "--backends", "random", *where]) == 0
    assert seen["suites"] == {"pose-1dof+modelnet10": 3, "known-pose+modelnet10": 3}
    capsys.readouterr()
    for suite, cats in (("tabletop", "mug"), ("pose-1dof", "spaceship"),
                        ("pose-3dof-percat", "mug")):  # fmt: skip
        assert main(["run", "--suite", suite, "--backend", "random", "--categories", cats]) == 2
        refused = _one_error_line(capsys)
        seen.clear()
        argv = ["all", "--suites", suite, "--backends", "random", "--categories", cats, *where]
        assert main(argv) == 2
        assert _one_error_line(capsys) == refused and not seen


@pytest.mark.parametrize(
    "backend, opt, used_by",
    [
        ("hbeo", "samples=3", "hbeo-mdn-likelihood and hbeo-mdn-posterior"),
        ("hbeo", "seed=1", "hbeo-mdn-likelihood and hbeo-mdn-posterior"),
        ("hbeo", "grasp=best", "hbeo-mdn-likelihood and hbeo-mdn-posterior"),
        ("hbeo-mdn-likelihood", "prior_grid=32", "hbeo-mdn-posterior"),
    ],
)
def test_an_option_the_backend_mode_does_not_use_is_refused(
    capsys, tmp_path, backend, opt, used_by
) -> None:
    """`--backend hbeo --opt samples=3` would change nothing but the run's name (a run
    `hbeo__samples=3` beside `hbeo`): refused in one line naming the modes that use it and
    the options this one takes, even at the option's default value, before any run."""
    from beo_bench.backend import get_spec
    from beo_bench.errors import UsageError
    from beo_bench.perception.hbeo.backend import mode_options

    key, value = opt.split("=")
    with pytest.raises(UsageError, match=f"does not use {key} "):  # before any run starts
        get_spec(backend).parse({key: int(value) if value.isdigit() else value})
    out = tmp_path / "run"
    argv = ["run", "--suite", "pose-1dof", "--backend", backend, "--opt", opt, "--out", str(out)]
    assert main(argv) == 2
    mode = {"hbeo": "hbeo", "hbeo-mdn-likelihood": "likelihood"}[backend]
    line = _one_error_line(capsys)
    assert line == (
        f"beo-bench: error: backend {backend!r} does not use {key} (an option of {used_by}); "
        f"{backend} takes {', '.join(mode_options(mode))}"
    )
    assert key not in mode_options(mode) and "model" in mode_options(mode)
    assert not out.exists()
    argv = ["all", "--suites", "pose-1dof", "--backends", f"{backend}:{opt}"]
    assert main([*argv, "--runs", str(tmp_path / "runs"), "--out", str(tmp_path / "b")]) == 2
    assert _one_error_line(capsys) == line


def test_the_modes_that_use_an_option_take_it() -> None:
    from beo_bench.backend import get_spec

    assert get_spec("hbeo-mdn-likelihood").parse({"samples": 3, "seed": 2}).samples == 3
    assert get_spec("hbeo-mdn-posterior").parse({"prior_grid": 64}).prior_grid == 64
    assert get_spec("hbeo").parse({"threads": 2, "size": "small"}).threads == 2


def test_objects_takes_its_dataset_as_objects_only() -> None:
    """One spelling of the dataset: `--objects`, as every command; `--root` is in no help."""
    from beo_bench.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a.choices, dict))
    for name, parser in sub.choices.items():
        assert "--root" not in parser.format_help(), name
    objects = sub.choices["objects"]
    assert "--objects" in objects.format_help()
    assert objects.parse_args(["--objects", "data/m"]).objects == "data/m"
