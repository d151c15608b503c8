"""Nothing trains inside a run: the backend options that choose a default model other than
the published one (``instances``, ``images``, ``epochs``; ``beo``'s ``resolution``) select
the model ``beo-bench train`` made with the matching flags, and without it the run stops
with a usage error naming that command (docs/backends.md)."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest

from beo_bench import cli
from beo_bench.backend import get_backend
from beo_bench.cli import main
from beo_bench.cli import train as train_command
from beo_bench.errors import TrainingInRunError, UsageError
from beo_bench.objects.cache import cache_root
from beo_bench.scenes.pickconfig import default_categories
from tests.perception.contexts import run_context

TWO = ("mug", "bowl")


def _models() -> list[Path]:
    """Every file under the cache's models: nothing may be trained by a refused run."""
    root = cache_root() / "models"
    return sorted(p for p in root.rglob("*") if p.is_file()) if root.exists() else []


def _command(e: pytest.ExceptionInfo) -> list[str]:
    """The ``beo-bench train`` command quoted in the error's message, as argv."""
    msg = str(e.value)
    assert "\n" not in msg
    return shlex.split(msg.split("`")[1])


@pytest.mark.parametrize(
    "name, opts, cats, want",
    [
        (
            "hbeo",
            {"instances": 4, "images": 200, "epochs": 1},
            default_categories(),
            "beo-bench train hbeo --per-category 4 --images 200 --epochs 1",
        ),
        (
            "hbeo-mdn-posterior",
            {"images": 200},
            TWO,
            "beo-bench train hbeo-mdn --categories mug bowl --images 200",
        ),
        (
            "hbeo-mdn-likelihood",
            {"epochs": 2, "size": "dissertation"},
            TWO,
            "beo-bench train hbeo-mdn --categories mug bowl --epochs 2 --size dissertation "
            "--device cuda",
        ),
        (
            "beo",
            {"instances": 3},
            TWO,
            "beo-bench train beo --categories mug bowl --per-category 3",
        ),
        ("beo", {"resolution": 16}, default_categories(), "beo-bench train beo --resolution 16"),
    ],
)
def test_training_options_refuse_naming_the_train_command(name, opts, cats, want) -> None:
    before = _models()
    b = get_backend(name, **opts)
    with pytest.raises(TrainingInRunError) as e:
        b.prepare(run_context(name, cats, **opts))
    assert isinstance(e.value, UsageError) and e.value.exit_code == 2
    assert f"`{want}`" in str(e.value)
    assert all(f"--opt {k}={v}" in str(e.value) for k, v in opts.items() if k != "size")
    assert _models() == before  # nothing was trained, not even a BEO subspace


def _trained_by(argv: list[str]) -> Path:
    """Where the model that ``argv`` (a ``beo-bench train`` command) trains is stored, by
    the CLI's own reading of its flags (no training)."""
    args = cli.build_parser().parse_args(argv[1:])
    if args.model == "beo":
        from beo_bench.perception.beo.model import default_name, model_path
        from beo_bench.training import beo_config

        req = train_command.train_request(args)
        cats = beo_config(req).categories
        name = default_name(cats, args.resolution, args.per_category, req.dataset)
        return model_path(name) / "config.json"
    from beo_bench.perception.hbeo.model import default_name, model_path

    return model_path(default_name(train_command.hbeo_config(args, args.model))) / "weights.pt"


@pytest.mark.parametrize(
    "name, opts, cats",
    [
        ("hbeo", {"instances": 2, "epochs": 1}, TWO),
        ("hbeo-mdn-posterior", {"images": 64}, default_categories()),
        ("beo", {"instances": 2, "resolution": 16}, TWO),
    ],
)
def test_the_named_command_makes_the_model_the_options_select(
    name, opts, cats, monkeypatch, tmp_path
) -> None:
    """The command in the message stores its model where the same options look: once
    something is there, the backend stops refusing (and goes on to load it)."""
    monkeypatch.setenv("BEO_BENCH_CACHE", str(tmp_path))
    b = get_backend(name, **opts)
    with pytest.raises(TrainingInRunError) as e:
        b._refuse_training(cats)
    made = _trained_by(_command(e))
    made.parent.mkdir(parents=True)
    made.write_text("stand-in")
    b._refuse_training(cats)  # no longer refused


def test_a_run_with_training_options_exits_2_naming_the_command(capsys, tmp_path) -> None:
    before = _models()
    argv = ["run", "--suite", "pose-1dof", "--backend", "hbeo", "--opt", "epochs=1"]
    argv += ["--episodes", "1", "--workers", "1", "--out", str(tmp_path / "run")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert "`beo-bench train hbeo --epochs 1`" in lines[0]
    assert _models() == before
