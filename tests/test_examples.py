"""The example third-party backend package (``examples/beo_bench_example``), installed
as a user would install it and run through ``beo-bench run``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "beo_bench_example"


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    target = tmp_path_factory.mktemp("site")
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
         "--no-build-isolation", "--target", str(target), str(EXAMPLE)],
        check=True,
    )  # fmt: skip
    return target


def test_example_backend_runs_through_the_cli(installed, tmp_path) -> None:
    env = {**os.environ, "PYTHONPATH": str(installed)}
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "beo_bench.cli", "run", "--suite", "pose-1dof",
           "--backend", "box-fit", "--episodes", "11", "--workers", "1",
           "--opt", "instances=5", "--out", str(out)]  # fmt: skip
    done = subprocess.run(cmd, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["backend"] == "box-fit"
    assert summary["n"] == 11 and summary["failures"] == 0
    assert summary["provenance"]["backend_kwargs"] == {"instances": 5}
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert len(rows) == 11 and all(r["rot_err_deg"] is not None for r in rows)


def test_example_backend_passes_check_backend(installed, monkeypatch) -> None:
    monkeypatch.syspath_prepend(str(installed))
    from beo_bench import backend as B

    try:
        assert "box-fit" in B.load_plugins()
        b = B.get_backend("box-fit", instances=5)
        B.check_backend(b, B.sample_views(3))
    finally:
        B.unregister_backend("box-fit")  # other tests see the in-tree set
