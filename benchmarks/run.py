"""Run every benchmark module (``bench_*.py``) in this folder: ``make bench``."""

from __future__ import annotations

import importlib.util
import os
import sys
import time
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv: list[str]) -> int:
    sys.path.insert(0, str(HERE))
    import harness

    wanted = argv[1:]
    for path in sorted(HERE.glob("bench_*.py")):
        if wanted and not any(w in path.stem for w in wanted):
            continue
        print(f"\n== {path.stem} ==", flush=True)
        spec = importlib.util.spec_from_file_location(path.stem, path)
        assert spec and spec.loader
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        t0 = time.perf_counter()
        environ = dict(os.environ)
        # each benchmark starts from the user's environment (e.g. the asset cache a
        # cold-cache figure replaced) and warning filters
        with warnings.catch_warnings():
            mod.main()
        os.environ.clear()
        os.environ.update(environ)
        print(f"  ({path.stem} took {time.perf_counter() - t0:.0f} s)")
    missed = [r for r in harness.RESULTS if r["ok"] is False]
    print(
        f"\n{len(harness.RESULTS)} figures, {len(missed)} missing their target"
        + ("".join(f"\n  - {r['name']}" for r in missed))
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
