"""Shared test set-up: every test session gets its own asset cache, so tests never read
or write the user's ``~/.cache/beo_bench`` and always exercise the cold path once."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile

# Set before anything imports the package, so worker processes inherit it too.
os.environ.setdefault("MUJOCO_GL", "egl")
if "BEO_BENCH_TEST_CACHE" not in os.environ:
    os.environ["BEO_BENCH_TEST_CACHE"] = tempfile.mkdtemp(prefix="beo_bench_test_cache_")
    # the session that made the cache removes it (xdist's workers inherit it and end first)
    atexit.register(shutil.rmtree, os.environ["BEO_BENCH_TEST_CACHE"], ignore_errors=True)
os.environ["BEO_BENCH_CACHE"] = os.environ["BEO_BENCH_TEST_CACHE"]
