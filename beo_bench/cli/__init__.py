"""The ``beo-bench`` command.

Exit status: 0 on success, 1 on a failure (a run that cannot finish, a corrupt model, a
full or read-only disk), 2 on a usage error (an argument, option or setting out of range;
runs that do not pair with a gate's baseline) or a problem with your data or set-up (a bad
mesh file, a missing dataset folder, an unusable asset cache), 3 when results cross a limit
you set (`gate` found a regression, a run's failures exceed --max-failure-rate; the results
and reports are written first), 130 when interrupted. An error is one line on stderr,
``beo-bench: error: ...``, saying what was wrong and what to do; no traceback.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import sys
import warnings
from collections.abc import Collection, Sequence
from types import ModuleType
from typing import Any, NamedTuple

import beo_bench
from beo_bench.argparsing import SuggestingParser
from beo_bench.errors import BeoBenchError, ThresholdError


class Command(NamedTuple):
    """A command: its name, the module of this package that declares its options
    (``add(sub, help)``) and runs it (``run(args) -> int``), and its line in ``--help``."""

    name: str
    module: str
    help: str


COMMANDS = (
    Command("demo", "demo", "the main job on the embedded defaults"),
    Command("objects", "objects", "process and summarise an object set"),
    Command("view", "view", "write a BEOPick-v0 scene to a rerun .rrd and a PNG"),
    Command(
        "pick-check", "pick_check", "pick success of the ground-truth grasp planner (the ceiling)"
    ),
    Command("run", "run", "score a backend on a suite"),
    Command(
        "all",
        "run_all",
        "run every suite with every backend (resuming), then regenerate leaderboards/",
    ),
    Command("export", "export", "write a suite's items as a BOP-format dataset (docs/bop.md)"),
    Command("score", "score", "score a BOP results CSV on a suite as a run (docs/bop.md)"),
    Command(
        "compare",
        "compare",
        "runs side by side; each run paired with the first on their common items",
    ),
    Command("gate", "gate", "fail (exit 3) when runs got worse than a baseline, item by item"),
    Command(
        "baseline",
        "baseline",
        "write a baseline file for `gate` from runs (per-item values, to commit)",
    ),
    Command("leaderboard", "leaderboard", "regenerate leaderboards/ from run summaries"),
    Command("train", "train", "train a perception model (beo, hbeo, hbeo-mdn)"),
    Command(
        "publish",
        "publish",
        "write a trained model into the published models the backends load "
        "(rest-prior: fit the training split's rest prior and publish it; class-means: the "
        "baselines' class means over the training split)",
    ),
    Command("render-dataset", "render_dataset", "render HBEO's training crops (cached shards)"),
    Command("cache", "cache", "inspect or clear the asset cache"),
)
"""Every command, in the order ``--help`` lists them."""
_BY_NAME = {c.name: c for c in COMMANDS}


def command_module(name: str) -> ModuleType:
    """The module of command ``name`` (imported now: only the command that runs is)."""
    return importlib.import_module(f"{__name__}.{_BY_NAME[name].module}")


EXIT_STATUS = __doc__.split("\n\n", 1)[1]


class _MainParser(SuggestingParser):
    """The top-level parser: its help lists the registries (read only when help is shown,
    so that a command never pays for importing every backend)."""

    def format_help(self) -> str:
        from beo_bench.cli.listing import registry_listing  # the backends: only for help

        self.epilog = registry_listing() + "\n\n" + EXIT_STATUS
        return super().format_help()


def build_parser(commands: Collection[str] | None = None) -> argparse.ArgumentParser:
    """The command line's parser, declaring the options of ``commands`` (None: every
    command's); the others are names in its list, and their modules are not imported:
    ``main`` declares the one command it runs, none for ``--version`` and ``--help``."""
    p = _MainParser(
        prog="beo-bench",
        description="Benchmark object-centric perception (class, pose and full 3D shape from\n"
        "one segmented depth image) in simulation, and the grasps planned from it.",
        epilog=EXIT_STATUS,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"beo-bench {beo_bench.__version__}")
    # the commands' parsers take no abbreviations and suggest the closest flag on a typo, as
    # the top-level one does; only the top-level help lists the registries
    sub = p.add_subparsers(dest="command", required=True, parser_class=SuggestingParser)
    for c in COMMANDS:
        if commands is None or c.name in commands:
            command_module(c.name).add(sub, c.help)
        else:
            sub.add_parser(c.name, help=c.help)
    return p


def _command_in(argv: Sequence[str]) -> tuple[str, ...]:
    """The command ``argv`` names: its first argument that is not an option (the top-level
    options take no value); none when there is none or it is not a command."""
    first = next((a for a in argv if not a.startswith("-")), None)
    return (first,) if first in _BY_NAME else ()


RESUME_HINTS = {
    "run": "run the same command with --resume to continue",
    "all": "run the same command again to continue (finished runs are kept)",
    "demo": "run the same command again to continue (finished runs are kept)",
    "train": "run the same command again to continue from the last finished epoch",
    "render-dataset": "run the same command again to continue (finished shards are kept)",
}
"""What to tell a user who pressed Ctrl-C, per command (the others have nothing to resume)."""


CACHE_COMMANDS = ("demo", "objects", "view", "pick-check", "run", "all", "train", "render-dataset")
"""The commands that write the asset cache, whose directory is checked as they start
(``objects.cache.check_root``); ``cache`` checks it itself."""


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line ``argv``; returns the exit status (argparse's own usage errors
    exit 2 through ``SystemExit``)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    with warnings.catch_warnings():
        warnings.showwarning = show_warning
        # inside: `--help` loads the backend plugins, and a broken one is a warning line
        args = build_parser(_command_in(argv)).parse_args(argv)
        try:
            if args.command in CACHE_COMMANDS:  # once, before anything is computed
                from beo_bench.objects.cache import check_root  # not for --version

                check_root()
            return int(command_module(args.command).run(args))
        except ThresholdError as e:  # not an error of the command: what it found
            return _fail(str(e), e.exit_code, what="")
        except BeoBenchError as e:
            return _fail(str(e), e.exit_code)
        except OSError as e:
            return _fail(_os_error(e), 1)
        except KeyboardInterrupt:
            hint = RESUME_HINTS.get(args.command, "run the command again to start over")
            return _fail(f"interrupted; {hint}", 130, what="")


def _fail(message: str, code: int, what: str = "error: ") -> int:
    # one line: the message's own line breaks would read as several errors
    print(f"beo-bench: {what}{' '.join(message.split())}", file=sys.stderr)
    return code


def _os_error(e: OSError) -> str:
    """A line naming the path and what to do about a file-system failure."""
    paths = " -> ".join(str(f) for f in (e.filename, e.filename2) if f)
    why = e.strerror or str(e) or type(e).__name__
    if e.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        todo = "choose a writable place (e.g. --out) or fix its permissions"
    elif e.errno in (errno.ENOSPC, errno.EDQUOT):
        todo = "free some disk space or choose another place (e.g. --out), then resume"
    elif e.errno in (errno.ENOTDIR, errno.EISDIR, errno.EEXIST):
        todo = "a file or directory is in the way: choose another place (e.g. --out) or move it"
    elif e.errno == errno.ENOENT:
        todo = "check that the path exists"
    else:
        todo = "check the path and the disk"
    return f"{why}{': ' + paths if paths else ''}; {todo}"


def show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: Any = None,
    line: str | None = None,
) -> None:
    """Warnings as one line each, like the errors (no source file, no code line); a warning
    with a ``cli_text()`` (advice that differs for the command line, e.g.
    :class:`~beo_bench.objects.datasets.UnknownSizeWarning`) gives that."""
    cli_text = getattr(message, "cli_text", None)
    text = cli_text() if callable(cli_text) else message
    print(f"beo-bench: warning: {text}", file=sys.stderr)
