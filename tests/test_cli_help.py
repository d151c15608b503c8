"""``beo-bench --help`` lists what a user can name (suites, backends, cache kinds), from
the registries; the shared options keep each command's defaults and checks."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from beo_bench.backend import describe_backend, list_backends, load_plugins
from beo_bench.bench.suites import SUITES
from beo_bench.cli import build_parser, main
from beo_bench.cli.listing import registry_listing
from beo_bench.errors import BackendError
from beo_bench.objects.cache import KINDS
from tests.plugins import install_plugin


def _help(capsys, argv: list[str]) -> str:
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 0
    return capsys.readouterr().out


def _entry(out: str, name: str) -> str:
    """The one help line that lists ``name``."""
    lines = [ln for ln in out.splitlines() if ln.startswith(f"  {name} ")]
    assert len(lines) == 1, (name, lines)
    return lines[0]


def test_help_lists_every_suite_backend_and_cache_kind_one_line_each(capsys) -> None:
    out = _help(capsys, ["--help"])
    load_plugins()
    for name, suite in SUITES.items():
        assert suite.description.split()[0] in _entry(out, name)
    for name in list_backends():
        assert describe_backend(name) and describe_backend(name)[:20] in _entry(out, name)
    for kind, text in KINDS.items():
        assert text in _entry(out, kind)
    # the sections come before the exit statuses, which stay last
    assert out.index("suites (") < out.index("backends (") < out.index("cache kinds (")
    assert out.index("cache kinds (") < out.index("Exit status")


def test_listing_fits_the_width_it_is_given() -> None:
    text = registry_listing(width=60)
    assert max(len(line) for line in text.splitlines()) <= 60
    assert "..." in text  # long suite descriptions are cut at a word, and say so


@pytest.fixture
def plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """An installed third-party backend with a ``description`` attribute."""
    from beo_bench import backend as B

    site = tmp_path / "site"
    site.mkdir()
    (site / "beo_help_plugin_mod.py").write_text(
        "from beo_bench.backend import Backend\n"
        "class Help(Backend):\n"
        "    name = 'help-plugin'\n"
        "    description = 'a third-party backend, listed from its entry point'\n"
    )
    install_plugin(
        site, "beo-help-plugin", {"help-plugin": "beo_help_plugin_mod:Help"}, monkeypatch
    )
    yield
    B.unregister_backend("help-plugin")
    sys.modules.pop("beo_help_plugin_mod", None)


def test_help_lists_a_plugin_backend_with_its_description(capsys, plugin) -> None:
    out = _help(capsys, ["--help"])
    assert "a third-party backend, listed from its entry point" in _entry(out, "help-plugin")


def test_a_backend_is_described_by_its_spec_until_unregistered() -> None:
    from beo_bench import backend as B

    class DocOnly(B.Backend):
        name = "help-doc-only"
        description = "Guesses"

    B.register(DocOnly)
    try:
        assert describe_backend("help-doc-only") == "Guesses"
    finally:
        B.unregister_backend("help-doc-only")
    with pytest.raises(BackendError, match="help-doc-only"):
        describe_backend("help-doc-only")


def test_help_builds_nothing_and_commands_do_not_import_the_backends(tmp_path) -> None:
    """``--help`` leaves an empty cache empty, and neither it nor a command's parser
    (``run --help``) imports torch: the in-tree backends are listed from their catalogue
    (``backend.IN_TREE``), so help costs no 1.7 s of torch import."""
    cache = tmp_path / "cache"
    env = {**os.environ, "BEO_BENCH_CACHE": str(cache), "MUJOCO_GL": "egl"}
    code = (
        "import sys\n"
        "from beo_bench.cli import main\n"
        "for argv in (['run', '--help'], ['view', '--help']):\n"
        "    try:\n"
        "        main(argv)\n"
        "    except SystemExit as e:\n"
        "        assert e.code == 0\n"
        "assert 'torch' not in sys.modules, 'a command parser imported torch'\n"
        "try:\n"
        "    main(['--help'])\n"
        "except SystemExit as e:\n"
        "    assert e.code == 0\n"
        "assert 'torch' not in sys.modules, 'the top-level help imported torch'\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    assert "backends (" in done.stdout
    assert not cache.exists() or not any(cache.rglob("*.npz"))


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["view"], {"seed": 0, "out": Path("out/view"), "split": "test"}),
        (["pick-check"], {"seed": 0, "episodes": 100, "split": "test"}),
        (["objects"], {"workers": 2, "per_category": None, "split": "test"}),
        (["demo"], {"workers": None, "per_category": 6, "out": "out/demo"}),
        (
            ["run", "--suite", "s", "--backend", "b"],
            {"seed": None, "episodes": None, "workers": None, "out": None, "ray": False},
        ),
        (["all"], {"out": "leaderboards", "runs": "runs", "item_timeout": None}),
        (["leaderboard"], {"out": "leaderboards", "runs": "runs"}),
        (["render-dataset"], {"seed": None, "workers": None, "images": None}),
        (["train", "hbeo"], {"seed": None, "categories": None, "name": None}),
    ],
)
def test_shared_options_keep_each_commands_defaults(argv, expected) -> None:
    args = vars(build_parser().parse_args(argv))
    for key, value in expected.items():
        assert key in args and args[key] == value, (argv, key, args.get(key))


@pytest.mark.parametrize(
    "command, text",
    [
        (["run"], "replace the suite's base seed"),
        (["all"], "replace the suites' base seeds"),
        (["pick-check"], "first episode seed"),
        (["render-dataset"], "seeds rendering and training"),
        (["run"], "worker processes (default: one per core)"),
        (["objects"], "instances per category (default: the split's size)"),
        (["train", "beo"], "seeds rendering and training"),
    ],
)
def test_shared_options_keep_each_commands_help(capsys, command, text) -> None:
    out = _help(capsys, [*command, "--help"])
    assert text in " ".join(out.split())


def test_version_and_help_import_no_command_and_a_command_imports_its_own() -> None:
    """Each command's module is imported when that command runs: ``--version`` and the
    top-level ``--help`` import none, ``run --help`` imports ``run``'s alone."""
    code = (
        "import sys\n"
        "from beo_bench.cli import COMMANDS, main\n"
        "def loaded():\n"
        "    names = (c.name for c in COMMANDS if f'beo_bench.cli.{c.module}' in sys.modules)\n"
        "    return sorted(names)\n"
        "for argv, want in ((['--version'], []), (['--help'], []), (['run', '--help'], ['run'])):\n"
        "    try:\n"
        "        main(argv)\n"
        "    except SystemExit as e:\n"
        "        assert e.code == 0\n"
        "    assert loaded() == want, (argv, loaded())\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr


def test_train_options_are_the_train_requests_fields() -> None:
    """``train``'s flags for a :class:`TrainRequest` field carry the field's name and
    default, and the parsed options go back into the request by name: no flag given is
    the default request, every flag given reaches its field."""
    from dataclasses import fields

    from beo_bench.cli import train
    from beo_bench.training import TrainRequest

    parser = build_parser(["train"])
    assert train.train_request(parser.parse_args(["train", "hbeo"])) == TrainRequest()
    values = {
        "split": None,  # --split needs --objects
        "categories": ("mug",),
        "per_category": 3,
        "resolution": 16,
        "variance_fraction": 0.5,
        "images": 8,
        "val_images": 2,
        "epochs": 1,
        "recipe": "reference",
        "seed": 7,
        "crop": 32,
        "size": "dissertation",
        "rotation": "6d",
        "batch_size": 4,
        "projection_weighting": "variance",
        "sensor": "d435",
    }
    # every field but the dataset (built from --objects and its loading options) is a flag
    assert set(values) == {f.name for f in fields(TrainRequest)} - {"dataset"}
    argv = ["train", "hbeo"]
    for name, value in values.items():
        if value is not None:
            flag = "--" + name.replace("_", "-")
            argv += [flag, *(value if isinstance(value, tuple) else [str(value)])]
    assert train.train_request(parser.parse_args(argv)) == TrainRequest(**values)


def test_field_option_refuses_a_name_that_is_not_a_field() -> None:
    import argparse

    from beo_bench.argparsing import field_option
    from beo_bench.training import TrainRequest

    with pytest.raises(TypeError, match="no field 'epoch'"):
        field_option(argparse.ArgumentParser(), TrainRequest, "epoch")
