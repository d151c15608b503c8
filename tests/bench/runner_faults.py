"""A backend that misbehaves on purpose, for the runner's fault tests (test-only).

Importing this module registers ``test-fault``. Spawned workers know only in-tree and
entry-point backends, so the tests hand it to them explicitly:
``WorkerPool(n, imports=["tests.bench.runner_faults"])`` (spawned children inherit ``sys.path``,
which holds the repository root under pytest). Nothing in the package imports it.

On the views whose class (``View.class_hint``, given by ``pose-1dof``; item ``i`` shows
class ``i % 11``) is in ``classes`` it does ``mode``: ``sleep`` (an hour), ``abort``
(``os.abort``: signal 6), ``segfault`` (signal 11), ``exit`` (``sys.exit(3)``), ``raise``;
before that it writes its PID to ``marker`` when given. Other views get a cheap valid
estimate (the true class, an identity pose, a half-full grid).
"""

from __future__ import annotations

import ctypes
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from beo_bench.backend import Backend, Capabilities, ClassHint, register
from beo_bench.options import option
from beo_bench.types import Estimate, View

NAME = "test-fault"


def _misbehave(mode: str) -> None:
    if mode == "sleep":
        time.sleep(3600)
    elif mode == "abort":
        os.abort()
    elif mode == "segfault":
        ctypes.string_at(0)
    elif mode == "exit":
        sys.exit(3)
    elif mode == "raise":
        raise RuntimeError("asked to fail")
    else:
        raise ValueError(f"unknown mode {mode!r}")


@dataclass(frozen=True)
class FaultOptions:
    mode: str = option("sleep", "sleep, abort, segfault, exit or raise")
    classes: tuple[int, ...] | None = option(None, "the classes it misbehaves on (null: all)")
    marker: str = option("", "a file to write its PID to before it misbehaves")


class FaultBackend(Backend):
    """See the module docstring."""

    name = NAME
    Options = FaultOptions
    capabilities = Capabilities(class_hint=ClassHint.OPTIONAL)
    role = "diagnostic"  # never among the default backends of `beo-bench all` or `demo`
    options: FaultOptions

    def __init__(self, options: FaultOptions | None = None) -> None:
        super().__init__(options)
        self.classes = None if self.options.classes is None else set(self.options.classes)

    def predict(self, view: View) -> Estimate:
        if self.classes is None or view.class_hint in self.classes:
            if self.options.marker:
                Path(self.options.marker).write_text(f"{os.getpid()}\n")
            _misbehave(self.options.mode)
        C = len(view.categories)
        probs = np.full(C, 0.0)
        probs[view.class_hint if view.class_hint is not None else 0] = 1.0
        pts = view.points()
        shape = np.zeros((16, 16, 16), dtype=np.float32)
        shape[4:12, 4:12, 4:12] = 1.0
        return Estimate(probs, np.eye(3), pts.mean(axis=0), np.full(3, 0.1), shape)


register(FaultBackend)
