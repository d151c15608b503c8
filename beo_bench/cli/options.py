"""The options several commands declare alike: one parent parser (``parents=[...]``) per
option, and the argument types that check a name against a registry.

Each factory takes what differs between commands (the default and the help text), so a
command's ``--help`` reads as before while the option's flag, type and checks live here once.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from typing import Any

from beo_bench.argparsing import field_option, nonneg_int, positive_float, positive_int, seed_int
from beo_bench.bench.runs import REPORT_VIEWS
from beo_bench.errors import InvalidNameError
from beo_bench.names import check_name
from beo_bench.objects.datasets import DEFAULT_REPAIR, MAX_INPUT_FACES, REPAIR_MODES, UNIT_MODES
from beo_bench.scenes.sensors import SENSORS, SensorError, check_sensor_name
from beo_bench.training import TrainRequest

SENSOR_NAMES = "ideal, kinect-v1 or d435"
"""How ``--sensor``'s help names the sensors (``beo_bench.scenes.sensors.SENSORS``; spelt
out so that the help reads as a sentence: tests/bench/test_sensor_axis.py checks that it
names every one)."""
MODELS = ["beo", "hbeo", "hbeo-mdn"]
"""The perception models ``train`` and ``publish`` know."""
SPLITS_ALL = ["train", "val", "test", "all"]
"""Splits of a user's dataset (``all``: every model, whatever its hash split)."""
SCENE_SPLITS = ["train", "val", "test", "ood", "all"]
"""Splits of a scene's objects: the library's four, or ``all`` of a user's dataset."""
RENDER_GROUP = "rendering the training crops (hbeo and hbeo-mdn)"
MAX_FAILURE_HELP = (
    "exit with status 3 (after writing the results) when the run's share of failed views is "
    "above X, in [0, 1] (0: any failure)"
)
FORCE_RERUN_HELP = (
    "discard and run again a run whose results a plugin backend scored with other code or "
    "options than it has now (its recorded code digest differs); without it such a run is "
    "refused"
)


# -- argument types that check a name ----------------------------------------------------
def key_value(text: str) -> str:
    """An argparse ``type`` for ``--opt``: ``KEY=VALUE`` with a non-empty key."""
    if "=" not in text or not text.split("=", 1)[0].strip():
        raise argparse.ArgumentTypeError(f"{text!r}: use KEY=VALUE (e.g. samples=25)")
    return text


def sensor_name(text: str) -> str:
    """An argparse ``type`` for ``--sensor``: a registered sensor's name, in any case
    (``D435``); another name is a usage error (exit 2) naming the closest ones."""
    by_lower = {s.lower(): s for s in SENSORS}
    try:
        return check_sensor_name(by_lower.get(text.strip().lower(), text))
    except SensorError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def model_name(text: str) -> str:
    """An argparse ``type`` for ``train --name``: a plain name, never a path (the model is
    stored under the cache's models directory, and training may replace a checkpoint
    there)."""
    try:
        return check_name(text, "model name")
    except InvalidNameError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def size_option(text: str) -> float | str:
    """An argparse ``type`` for ``--size``: metres (a number > 0) or ``native``."""
    return "native" if text == "native" else positive_float(text)


# -- a user's dataset --------------------------------------------------------------------
def dataset_parent(
    size_flags: tuple[str, ...] = ("--size", "--object-size"),
) -> argparse.ArgumentParser:
    """The options that point a command at a user's dataset (``--objects`` and how its
    files are loaded), shared by every command that reads objects. ``size_flags``: the
    spellings of the object-size option (``train`` has its own ``--size``, the network's,
    so there it is ``--object-size`` only)."""
    p = argparse.ArgumentParser(add_help=False)
    g = p.add_argument_group("your own dataset")
    g.add_argument(
        "--objects",
        metavar="ROOT",
        default=None,
        help="a dataset instead of the built-in library: ShapeNetCore.v2, ModelNet10/40 or "
        "a folder with one sub-folder of meshes per category (the layout is detected)",
    )
    g.add_argument(
        "--repair",
        choices=list(REPAIR_MODES),
        default=DEFAULT_REPAIR,
        help="with --objects: how meshes are made watertight (default solid: a clean-up, "
        "and a watertight rebuild of what stays open; basic: the clean-up only)",
    )
    g.add_argument(
        "--up",
        default="z",
        help="with --objects (folders): the files' up axis, e.g. y or -z (default z)",
    )
    g.add_argument(
        *size_flags,
        dest="object_size",
        type=size_option,
        default=None,
        metavar="M|native",
        help="with --objects: largest extent in metres, or native (the files' units); "
        "default: the category's size",
    )
    # how a dataset's files are read and what its check (objects.datasets.checks, before the command
    # uses it) does with bad ones
    g.add_argument(
        "--units",
        choices=list(UNIT_MODES),
        default=None,
        help="with --objects: the files' units (in: inches); default: auto (detected) for "
        "folders, normalised (the class's size) for ShapeNet and ModelNet",
    )
    g.add_argument(
        "--skip-bad",
        action="store_true",
        help="with --objects: leave out the files that cannot be used (each is named with "
        "why) and run on the rest; the summary lists them",
    )
    g.add_argument(
        "--max-faces",
        type=positive_int,
        default=MAX_INPUT_FACES,
        metavar="N",
        help=f"with --objects: refuse mesh files of more faces (default {MAX_INPUT_FACES:,}: "
        "beyond it, loading takes minutes and gigabytes)",
    )
    return p


DATASET_DEFAULTS = (
    ("repair", DEFAULT_REPAIR),
    ("up", "z"),
    ("object-size", None),
    ("units", None),
    ("skip-bad", False),
    ("max-faces", MAX_INPUT_FACES),
)
"""The loading options of :func:`dataset_parent` with their defaults: one given without
``--objects`` is a usage error (``common.dataset_of``)."""


# -- one option each -----------------------------------------------------------------------
def option_parent(*flags: str, title: str | None = None, **kwargs: Any) -> argparse.ArgumentParser:
    """A parent parser (``parents=[...]``) holding one option; in argument group ``title``
    when given (parents whose groups share a title fill one group of the command)."""
    p = argparse.ArgumentParser(add_help=False)
    (p.add_argument_group(title) if title else p).add_argument(*flags, **kwargs)
    return p


def seed_parent(
    default: int | None = None, help: str | None = None, title: str | None = None
) -> argparse.ArgumentParser:
    """``--seed``: a non-negative numpy seed."""
    return option_parent("--seed", type=seed_int, default=default, help=help, title=title)


def workers_parent(
    default: int | None = None, help: str | None = "default: one per core", title: str | None = None
) -> argparse.ArgumentParser:
    """``--workers``: processes, at least one."""
    return option_parent("--workers", type=positive_int, default=default, help=help, title=title)


def privileged_parent() -> argparse.ArgumentParser:
    """``--allow-privileged``: a plugin that declares ``privileged`` may be handed the truth."""
    return option_parent(
        "--allow-privileged",
        action="store_true",
        help="let a plugin whose spec declares it privileged be handed the ground truth (its "
        "rows are listed with the bounds, never ranked)",
    )


def episodes_parent(default: int | None = None, help: str | None = None) -> argparse.ArgumentParser:
    """``--episodes``: items or episodes, at least one."""
    return option_parent("--episodes", type=positive_int, default=default, help=help)


def per_category_parent(
    default: int | None = None, help: str | None = None
) -> argparse.ArgumentParser:
    """``--per-category``: instances per class, at least one."""
    return option_parent("--per-category", type=positive_int, default=default, help=help)


def split_parent(
    choices: Sequence[str], default: str | None, help: str | None = None
) -> argparse.ArgumentParser:
    """``--split``: one of ``choices``."""
    return option_parent("--split", choices=list(choices), default=default, help=help)


def update_parent() -> argparse.ArgumentParser:
    """``--update``: keep the current pages of suites that have no runs."""
    return option_parent(
        "--update",
        action="store_true",
        help="keep the pages of suites with no runs under --runs (when of the current suite "
        "version): run a long campaign suite by suite",
    )


def categories_parent(help: str | None = None) -> argparse.ArgumentParser:
    """``--categories C [C ...]``: class and set names (checked where they are used)."""
    return option_parent(
        "--categories",
        nargs="+",
        default=None,
        help=help or "classes or sets (modelnet10, shapenet-ch5, library)",
    )


def out_parent(
    default: Any, help: str | None = None, type: Callable[[str], Any] | None = None
) -> argparse.ArgumentParser:
    """``--out``: where a command writes (``type``: e.g. ``Path``; default: the string). An
    empty value is a usage error: it would read as "not given" (``run`` then writes under
    ``runs/``) or as the current directory, neither of which the user named."""

    def checked(text: str) -> Any:
        if not text.strip():
            raise argparse.ArgumentTypeError("is empty: give a directory, or leave --out out")
        return text if type is None else type(text)

    return option_parent("--out", type=checked, default=default, help=help)


def runs_parent(help: str | None = None) -> argparse.ArgumentParser:
    """``--runs``: the directory of run directories."""
    return option_parent("--runs", default="runs", help=help)


def report_views_parent() -> argparse.ArgumentParser:
    """``--report-views N``: the worst views a run's ``report.html`` shows (0: no report)."""
    return option_parent(
        "--report-views",
        type=nonneg_int,
        default=REPORT_VIEWS,
        metavar="N",
        help=f"write OUT/report.html, an offline page of the run's failures and its N worst "
        f"views by the suite's primary error (default {REPORT_VIEWS}; 0: no report)",
    )


def ray_parent() -> argparse.ArgumentParser:
    """``--ray``: items as Ray tasks instead of worker processes."""
    return option_parent("--ray", action="store_true", help="run the items as Ray tasks")


def item_timeout_parent() -> argparse.ArgumentParser:
    """``--item-timeout``: seconds one item may take (a finite number > 0)."""
    return option_parent(
        "--item-timeout",
        type=positive_float,
        default=None,
        metavar="S",
        help="seconds one item may take before it is recorded as failed (default: the runner's)",
    )


def sensor_parent(
    help: str, many: bool = False, title: str | None = None
) -> argparse.ArgumentParser:
    """``--sensor NAME`` (``many``: one or more names): the depth sensor, checked
    case-insensitively with the closest names on a typo."""
    return option_parent(
        "--sensor",
        type=sensor_name,
        nargs="+" if many else None,
        default=None,
        metavar="NAME",
        help=help,
        title=title,
    )


def model_name_parent(help: str) -> argparse.ArgumentParser:
    """``--name``: a trained model's plain name (never a path)."""
    return option_parent("--name", type=model_name, default=None, help=help)


def bop_suite_parents(what: str) -> list[argparse.ArgumentParser]:
    """The options of ``export`` and ``score``: which suite's items (``what``: the verb
    their ``--episodes`` help starts with)."""
    return [
        dataset_parent(),
        split_parent(SPLITS_ALL, None, "with --objects: the dataset's split (default: test)"),
        episodes_parent(None, f"{what} the suite's first N items (default: all of them)"),
        seed_parent(None, "replace the suite's base seed"),
        categories_parent("isolated suites: only these classes or sets (suite SUITE+SET)"),
        sensor_parent(
            f"the depth sensor the depth images are captured by ({SENSOR_NAMES}; "
            "docs/sensors.md; default: the suite's own)"
        ),
    ]


def render_parents(title: str) -> list[argparse.ArgumentParser]:
    """The options of rendering HBEO's training crops (``train`` and ``render-dataset``),
    in one argument group ``title``; those of a :class:`~beo_bench.training.TrainRequest`
    are its fields'."""
    crops = argparse.ArgumentParser(add_help=False)
    g = crops.add_argument_group(title)
    field_option(g, TrainRequest, "images", type=positive_int, help="training crops")
    field_option(
        g, TrainRequest, "val_images", type=nonneg_int, help="validation crops (val split)"
    )
    return [
        crops,
        seed_parent(help="seeds rendering and training", title=title),
        workers_parent(help="render processes (default: cores)", title=title),
        sensor_parent(
            f"capture the noisy share of the crops by this depth sensor ({SENSOR_NAMES}; "
            "docs/sensors.md) instead of the DepthNoise augmentation (default: the published "
            "recipe's augmentation)",
            title=title,
        ),
    ]
