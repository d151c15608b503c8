"""What a run's episodes add up to besides their errors: pick attempts' success and
failure reasons, and per-view times."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from beo_bench.metrics._arrays import _vector


def pick_summary(
    successes: Iterable[bool], reasons: Iterable[str | None] | None = None
) -> dict[str, Any]:
    """``{"n", "successes", "success_rate", "failure_reasons"}`` of pick attempts.

    ``failure_reasons`` counts the reason of each failed attempt (None or "" as
    ``"unknown"``), most frequent first; reasons of successful attempts are ignored.
    ``success_rate`` is NaN for no attempts.
    """
    ok = [bool(s) for s in successes]
    why = list(reasons) if reasons is not None else [None] * len(ok)
    if len(why) != len(ok):
        raise ValueError(f"successes and reasons must have equal lengths: {len(ok)}, {len(why)}")
    counts = Counter(str(r) if r else "unknown" for s, r in zip(ok, why, strict=True) if not s)
    return {
        "n": len(ok),
        "successes": sum(ok),
        "success_rate": sum(ok) / len(ok) if ok else float("nan"),
        "failure_reasons": dict(counts.most_common()),
    }


def runtime_stats(seconds: ArrayLike) -> dict[str, float]:
    """``{"n", "ms_median", "ms_p95", "ms_mean", "hz"}`` of per-view times given in seconds.

    ``hz = 1000 / ms_median`` (views per second at the median time); p95 uses numpy's
    linear interpolation. NaNs dropped; no times -> NaNs.
    """
    s = _vector(seconds, "seconds")
    s = s[~np.isnan(s)]
    if s.size == 0:
        nan = float("nan")
        return {"n": 0, "ms_median": nan, "ms_p95": nan, "ms_mean": nan, "hz": nan}
    ms = s * 1000.0
    med = float(np.median(ms))
    return {
        "n": int(s.size),
        "ms_median": med,
        "ms_p95": float(np.percentile(ms, 95)),
        "ms_mean": float(ms.mean()),
        "hz": 1000.0 / med if med > 0 else float("inf"),
    }
