"""A pick page's episodes (one short record each in its JSON), its method comparisons episode by
episode (interval, exact McNemar p, verdict) and its per-category successes.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from beo_bench.bench import compare
from beo_bench.bench.columns import (
    markdown_table,
    spec,
    verdict_cell,
)
from beo_bench.bench.kinds.pick import AUDIT_FIELDS
from beo_bench.bench.pages.entries import DIAGNOSTIC, Row, is_bound, label
from beo_bench.bench.pages.tables import _category_table, _ordered
from beo_bench.bench.pages.verdicts import ROBUST, UNCORRECTED, Section, _run
from beo_bench.bench.scoring import PICK_ERRORS

# -- pick: its episodes, method against method, counts per category ----------------------------
PICK_REFERENCE = "hbeo"
"""The row every other method of a pick page is paired against, episode by episode (issue
47: the page says whether hbeo, the MDN and icp differ at picking)."""
ROBUST_PAIRS: tuple[tuple[str, str], ...] = tuple(
    (m, f"{m} ({ROBUST})") for m in ("hbeo-mdn-likelihood", "hbeo-mdn-posterior")
)
"""Each MDN row and its twin planning over its pose samples (the same estimates)."""
PICK_MODE_PAIRS: tuple[tuple[str, str], ...] = (
    ("hbeo-mdn-likelihood", "hbeo-mdn-posterior"),
    *ROBUST_PAIRS,
)
"""Further (A, B) pairs of a pick page: the MDN's two modes against each other."""
PICK_METRIC = "pick_success"
EPISODE_AUDIT: tuple[str, ...] = (*AUDIT_FIELDS, "plan_ms", "grasp_share")
"""What an episode records of its executed grasp (:data:`~beo_bench.bench.kinds.pick.
AUDIT_FIELDS`: the shake, the contacts, the analytic force-closure check) and of planning
it (milliseconds; the robust planner's share of pose samples the grasp holds in)."""
EPISODE_FIELDS: tuple[str, ...] = (
    "item", "category", "success", "reason", "chosen_is_target", *PICK_ERRORS, *EPISODE_AUDIT,
)  # fmt: skip
"""A pick run's per-episode record in its page's JSON: one short list per episode, in this
order (the summary's ``episode_fields`` names them, ``episodes`` holds the lists), so that
any two rows pair on the same episodes from the committed JSON alone, and anyone can draw
success against the grasped estimate's errors (:data:`~beo_bench.bench.scoring.
PICK_ERRORS`, to 3 decimals; null where the episode chose nothing or its run predates
them)."""
PICK_METHOD_NOTE = (
    "Method against method (exploratory: every method against hbeo and the MDN's two modes "
    "against each other, on pick success over the same episodes, B - A; 95% bootstrap "
    "intervals that resample episodes; *better* / *worse* when the interval excludes 0, "
    "uncorrected for the page's many comparisons; `B only` / `A only`: the episodes only one "
    "of the two picked, whose split gives p, the exact McNemar test; bounds and privileged "
    "rows are never paired):"
)


def is_pick_suite(suite: str) -> bool:
    """Whether ``suite`` is a pick suite (``pick``, also on a user's dataset)."""
    from beo_bench.bench.suites import Kind, UnknownSuiteError, base_suite

    try:
        return base_suite(suite).kind is Kind.PICK
    except UnknownSuiteError:
        return False


def episode_records(rows: Iterable[dict[str, Any]]) -> list[list[Any]]:
    """A pick run's result rows as its per-episode records (:data:`EPISODE_FIELDS`), by
    item: what pairs it with another run of the same items after the fact."""
    out = []
    for r in sorted(rows, key=lambda r: int(r["item"])):
        if int(r.get("view", 0)) != 0:
            continue  # an episode is one row; a later view would be another record
        found = r.get("chosen_is_target")
        out.append(
            [
                int(r["item"]),
                r.get("category"),
                bool(r.get("success")),  # a failed episode did not pick (as the summary)
                r.get("reason"),
                None if found is None else bool(found),  # None: nothing was chosen
                *(None if r.get(k) is None else round(float(r[k]), 3) for k in PICK_ERRORS),
                *(_record(r.get(k)) for k in EPISODE_AUDIT),
            ]
        )
    return out


def _record(value: Any) -> Any:
    """A recorded value as the page's JSON keeps it: bools as bools, numbers to 3 decimals."""
    if value is None or isinstance(value, bool):
        return value
    return round(float(value), 3)


def attach_episodes(rows: list[Row]) -> None:
    """Give each pick row's summary its per-episode records (``episode_fields``,
    ``episodes``: :func:`episode_records` of its ``results.jsonl``), which the page's JSON
    then holds. A row without its run (a kept page's) keeps what it has."""
    loaded: dict[Path, compare.Run | None] = {}
    for r in rows:
        run = _run(r, loaded) if r.path is not None else None
        if run is not None:
            r.summary["episode_fields"] = list(EPISODE_FIELDS)
            r.summary["episodes"] = episode_records(run.rows)


def episodes(summary: dict[str, Any]) -> dict[int, dict[str, Any]]:
    """A pick row's per-episode records by item, each as a dict of its fields; ``{}`` for a
    row without them."""
    fields = summary.get("episode_fields", EPISODE_FIELDS)
    records = (dict(zip(fields, rec, strict=True)) for rec in summary.get("episodes", []))
    return {int(d["item"]): d for d in records}


def mcnemar_p(b_only: int, a_only: int) -> float:
    """The exact two-sided McNemar p-value of two methods' successes on the same episodes:
    under no difference each of the ``b_only + a_only`` discordant episodes goes either way
    with probability 1/2 (a sign test; the episodes both or neither picked say nothing).
    1 without discordant episodes."""
    n = b_only + a_only
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, i) for i in range(min(b_only, a_only) + 1))
    return min(1.0, 2 * tail / 2**n)  # exact integers: no underflow at n in the hundreds


@dataclass(frozen=True)
class MethodComparison:
    """Method B against method A on a pick page: B - A on :data:`PICK_METRIC` over the
    episodes both ran (one entry of the page's primary comparisons)."""

    suite: str
    track: str | None
    a: str
    """The reference's row name (``hbeo``, ``hbeo-mdn-likelihood``)."""
    b: str
    metric: str
    a_value: float
    b_value: float
    diff: float
    """``b_value - a_value``."""
    ci95: tuple[float, float]
    """The paired bootstrap interval of ``diff`` (episodes resampled,
    :func:`beo_bench.bench.compare.paired_metric`)."""
    p_value: float
    """:func:`mcnemar_p` of the discordant episodes (what a Holm correction takes)."""
    verdict: str
    """For B: ``better`` / ``worse`` when ``ci95`` excludes 0, else ``no difference``."""
    episodes: int
    b_only: int
    """Episodes B picked and A did not."""
    a_only: int
    sensor: str | None = None
    """The runs' sensor when it is not the suite's own."""


def compare_picks(
    section: Section, a: dict[str, Any], b: dict[str, Any], sensor: str | None = None
) -> MethodComparison | None:
    """B - A on the episodes both rows' records hold (None when they share none)."""
    ea, eb = episodes(a), episodes(b)
    common = sorted(ea.keys() & eb.keys())
    if not common:
        return None
    va = {(i, 0): float(bool(ea[i]["success"])) for i in common}
    vb = {(i, 0): float(bool(eb[i]["success"])) for i in common}
    r = compare.paired_metric(va, vb, PICK_METRIC)
    assert r is not None  # every common episode has a value
    b_only = sum(vb[k] > va[k] for k in va)
    a_only = sum(va[k] > vb[k] for k in va)
    return MethodComparison(
        section.suite,
        section.track,
        label(a),
        label(b),
        PICK_METRIC,
        r.a,
        r.b,
        r.diff,
        (r.lo, r.hi),
        mcnemar_p(b_only, a_only),
        r.verdict,
        len(common),
        b_only,
        a_only,
        sensor,
    )


def pick_comparisons(section: Section, sensor: str | None = None) -> list[MethodComparison]:
    """A pick section's method comparisons, as data: every method against
    :data:`PICK_REFERENCE`, then the pairs of :data:`PICK_MODE_PAIRS`, each on the episodes
    both rows' records hold (:func:`attach_episodes`). Bounds, privileged and diagnostic
    rows are never paired; a pair whose rows are not both there, or share no episode's
    record, is left out."""
    rows = {
        label(r.summary): r.summary
        for r in section.rows
        if not is_bound(r.summary) and r.summary["backend"] not in DIAGNOSTIC
    }
    pairs = [(PICK_REFERENCE, m) for m in rows if m != PICK_REFERENCE and PICK_REFERENCE in rows]
    pairs += [(a, b) for a, b in PICK_MODE_PAIRS if a in rows and b in rows]
    found = (compare_picks(section, rows[a], rows[b], sensor) for a, b in pairs)
    return [c for c in found if c is not None]


def _p_text(p: float) -> str:
    return "<0.001" if p < 0.001 else f"{p:.3f}"


def pick_comparison_table(comparisons: list[MethodComparison]) -> str:
    """The Markdown table of a pick section's method comparisons; "" without any."""
    if not comparisons:
        return ""
    m = spec(PICK_METRIC)
    body = [
        [c.b, c.a, c.episodes, m.format(c.a_value), m.format(c.b_value),
         m.format_interval(c.diff, *c.ci95), c.b_only, c.a_only, _p_text(c.p_value),
         verdict_cell(c.verdict)]
        for c in comparisons
    ]  # fmt: skip
    head = ["method (B)", "against (A)", "episodes", "A", "B", "B - A [95%]", "B only",
            "A only", "p", f"verdict, {UNCORRECTED}"]  # fmt: skip
    return f"{PICK_METHOD_NOTE}\n\n" + markdown_table(head, body, "llrrrrrrrl")


def pick_comparison_json(c: MethodComparison) -> dict[str, Any]:
    """One method comparison as ``<suite>_paired.json`` holds it (``"pairing": "method"``,
    the keys of the other pairings plus the p-value and the discordant counts)."""
    out = {
        "pairing": "method",
        "track": c.track,
        "method": c.b,
        "baseline": c.a,
        "metric": c.metric,
        "baseline_value": c.a_value,
        "method_value": c.b_value,
        "diff": c.diff,
        "ci95": list(c.ci95),
        "verdict": c.verdict,
        "items": c.episodes,
        "views": c.episodes,
        "p_value": c.p_value,
        "test": "exact McNemar",
        "method_only": c.b_only,
        "baseline_only": c.a_only,
    }
    if c.sensor is not None:  # as the verdicts of a sensor's part
        out["sensor"] = c.sensor
    return out


def pick_category_table(rows: list[Row]) -> str:
    """Pick success per category with its counts (successes / episodes, then the rate):
    categories as rows, backends as columns; "" without per-category figures."""
    summaries = [r.summary for r in _ordered(rows)]
    if not any(s.get("per_category") for s in summaries):
        return ""

    def cell(d: dict[str, Any]) -> str:
        rate, n = d.get(PICK_METRIC), int(d.get("n", 0))
        if rate is None or not n:
            return "-"
        k = round(rate * n)  # a mean over n episodes of 0 or 1: exactly k / n
        return f"{k}/{n} ({100 * k / n:.0f}%)"

    title = "pick success per category (successes / episodes):"
    return _category_table(summaries, title, cell, counts=False)


_EPISODES_MARK = "\x00episodes of row {}"


def page_json(shown: list[dict[str, Any]]) -> str:
    """A page's JSON (its rows' summaries, indented, keys sorted) with each per-episode
    record on one line: 500 episodes a row stay 500 lines, not 3,500."""
    held, records = [], {}
    for i, s in enumerate(shown):
        if "episodes" in s:
            mark = _EPISODES_MARK.format(i)
            records[json.dumps(mark)] = s["episodes"]
            s = {**s, "episodes": mark}
        held.append(s)
    text = json.dumps(held, indent=2, sort_keys=True)
    for mark, recs in records.items():  # a row's keys sit 4 deep, their list items 6
        lines = ",\n".join(" " * 6 + json.dumps(rec) for rec in recs)
        text = text.replace(mark, "[\n" + lines + "\n" + " " * 4 + "]" if recs else "[]", 1)
    return text + "\n"
