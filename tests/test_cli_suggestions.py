"""The command line takes no abbreviations, and a misspelt name (a flag, a command, a
choice, a suite, a backend, a backend option) is a usage error (exit 2) naming the closest
known one, compared case-insensitively."""

from __future__ import annotations

import argparse

import pytest

from beo_bench.cli import build_parser, main
from beo_bench.names import closest, did_you_mean

RUN = ["run", "--suite", "pose-1dof", "--backend", "random"]


def _parsers(p: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    """``p`` and every command's parser below it."""
    out = [p]
    for a in p._actions:
        if isinstance(a.choices, dict):
            for sub in a.choices.values():
                out += _parsers(sub)
    return out


def test_no_parser_takes_an_abbreviation() -> None:
    parsers = _parsers(build_parser())
    assert len(parsers) > 10  # the top level and every command
    assert [p.prog for p in parsers if p.allow_abbrev] == []


def _usage_error(capsys, argv: list[str]) -> str:
    """argparse's usage error: SystemExit(2) and its last stderr line."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err.strip().splitlines()[-1]


def test_a_prefix_of_a_flag_is_refused_not_taken(capsys, tmp_path) -> None:
    out = tmp_path / "run"
    line = _usage_error(capsys, [*RUN, "--episode", "3", "--out", str(out)])
    assert line == (
        "beo-bench run: error: unrecognized arguments: --episode 3 "
        "(--episode: did you mean --episodes?)"
    )
    assert not out.exists()  # refused before anything ran


@pytest.mark.parametrize(
    "argv, hint",
    [
        ([*RUN, "--Episodes", "3"], "--Episodes: did you mean --episodes?"),
        ([*RUN, "--item-timout=5"], "--item-timout: did you mean --item-timeout?"),
        (["all", "--suite", "pose-1dof"], "--suite: did you mean --suites?"),
        (["rnu", *RUN[1:]], "invalid choice: 'rnu' (did you mean 'run'? choose from 'demo'"),
        ([*RUN, "--track", "Class-Free"], "(did you mean 'class-free'? choose from"),
        ([*RUN, "--sensor", "kinect"], "did you mean 'kinect-v1'?"),
    ],
)
def test_a_misspelt_flag_or_choice_names_the_closest(capsys, argv, hint) -> None:
    line = _usage_error(capsys, argv)
    assert hint in line, line


def _error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize(
    "argv, hint",
    [
        (["run", "--suite", "pose-3dfo", "--backend", "random"], "did you mean 'pose-3dof'?"),
        (["run", "--suite", "POSE-1DOF", "--backend", "random"], "did you mean 'pose-1dof'?"),
        (
            ["run", "--suite", "pose-3dfo+car", "--backend", "random"],
            "did you mean 'pose-3dof+car'?",
        ),
        (["all", "--suites", "Known-Pose", "--backends", "random"], "did you mean 'known-pose'?"),
        (["run", "--suite", "pose-1dof", "--backend", "ICP"], "backend 'ICP'; did you mean 'icp'?"),
        (["run", "--suite", "pose-1dof", "--backend", "oracel"], "did you mean 'oracle'?"),
        (["all", "--suites", "pose-1dof", "--backends", "radnom"], "did you mean 'random'?"),
        ([*RUN, "--opt", "Seed=1"], "no option 'Seed'; did you mean 'seed'? its options"),
        ([*RUN, "--opt", "mean_instance=2"], "did you mean 'mean_instances'?"),
        (["all", "--suites", "pose-1dof", "--backends", "icp:start=4"], "did you mean 'starts'?"),
    ],
)
def test_a_misspelt_suite_backend_or_option_names_the_closest(capsys, argv, hint) -> None:
    assert main(argv) == 2
    line = _error_line(capsys)
    assert line.startswith("beo-bench: error: ") and hint in line, line


def test_no_hint_when_nothing_is_close(capsys) -> None:
    assert main(["run", "--suite", "zzzz", "--backend", "random"]) == 2
    assert "unknown suite 'zzzz'; the suites are" in _error_line(capsys)
    assert did_you_mean("zzzz", ["pose-1dof"]) == ""


def test_closest_compares_case_insensitively() -> None:
    assert closest("D435", ["ideal", "kinect-v1", "d435"]) == "d435"
    assert closest("--EPISODES", ["--episodes", "--seed"]) == "--episodes"
    assert did_you_mean("icp", ["icp", "icp-plain"]) == ""  # the name itself: no hint


def test_a_runs_folder_that_does_not_exist_is_a_usage_error(capsys, tmp_path) -> None:
    argv = ["leaderboard", "--runs", str(tmp_path / "nope"), "--out", str(tmp_path / "lb")]
    assert main(argv) == 2
    assert "--runs " in _error_line(capsys) and not (tmp_path / "lb").exists()
