"""The dissertation's orderings, checked on the pages (paired where the pages pair them), the
declared primary comparisons and the widths of their intervals.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beo_bench.bench.columns import markdown_table, spec
from beo_bench.bench.doctables.boards import (
    Boards,
    MissingFigureError,
    PendingSuiteError,
    _diff,
    _table,
    fmt_unit,
)
from beo_bench.bench.doctables.dissertation import _unpaired
from beo_bench.bench.pages.verdicts import (
    DISSERTATION_PROTOCOL,
    NOT_RUN,
    PRIMARY_COMPARISONS,
    Primary,
    ordering_verdict,
    primary_comparisons,
)

# -- the dissertation's orderings and the primary comparisons (issue 47) ---------------------
ORDERING_SUITES: tuple[str, ...] = (
    *DISSERTATION_PROTOCOL,
    "known-pose",
    "known-pose+modelnet10",
    "pose-1dof",
    "pose-1dof+modelnet10",
    "pose-3dof",
    "pose-3dof-ood",
    "tabletop",
)
"""The pages whose primary comparisons hold the dissertation's orderings: the suites of its
own protocol first (:data:`~beo_bench.bench.pages.verdicts.DISSERTATION_PROTOCOL`), then ours."""
THE_DISSERTATIONS, OURS = "the dissertation's", "ours"
ORDERINGS_SAID: dict[str, str] = {
    "Table 3.1": "at a known pose BEO reads the class better than 3DShapeNets (here the "
    "nearest class-mean shape, `icp`, stands in)",
    "Figure 3.6": "at 1-DOF, every method told the class, BEO errs less in rotation than plain ICP",
    "Table 4.1": "HBEO reads the class better than BEO",
    "Figure 4.3": "at 3-DOF, every method told the class, BEO errs less in rotation than plain ICP",
    "Table 4.2": "HBEO takes a fraction of BEO's time per view",
    "Table 5.1": "each MDN mode's mean rotation error is below HBEO's",
    "Table 5.2": "each MDN mode errs by more than 15 deg less often than HBEO",
    "Table 5.1 (eq. 5.6's prior)": "the posterior (the silhouette prior) errs less than the "
    "likelihood",
    "Table 5.1 (eq. 5.6's prior, per-category networks)": "with each category's own network, "
    "the posterior errs less than the likelihood",
    "Table 5.2 (eq. 5.6's prior, per-category networks)": "with each category's own network, "
    "the posterior errs by more than 15 deg less often than the likelihood",
}
"""Each ordering of the dissertation that docs/results.md quotes, in its words, in the order
of the dissertation; the key is the ``source`` of its primary comparisons."""


@dataclass(frozen=True)
class Check:
    """One dissertation ordering on one suite (or pair of suites): what was compared, the
    figures and whether it ``holds``, ``fails`` or shows ``no difference`` (``not run``: a
    run is missing; ``waits``: the page is not in the leaderboards yet)."""

    source: str
    protocol: str
    suite: str
    claim: str
    figures: str
    verdict: str


def _claim(pc: Primary) -> str:
    m = spec(pc.metric)
    side = "above" if m.higher_is_better else "below"
    track = {"class-given": ", class given", "class-free": ", class-free"}.get(pc.track or "", "")
    return f"`{pc.method}` {side} `{pc.baseline}` on {m.label}{track}"


def _paired_check(b: Boards, suite: str, pc: Primary) -> tuple[str, str]:
    """The figures and the verdict of a declared ordering on a page: its Holm-corrected
    primary comparison where the page has it, else the page's paired interval
    (uncorrected), else (class accuracy, no pairing committed) the two rows' intervals,
    unpaired."""
    fmt, unit = fmt_unit(pc.metric)
    got = b.primary(suite, pc)
    if got is not None:
        figures = f"{fmt(got['method_value'])} vs {fmt(got['baseline_value'])}: "
        return figures + _diff(got, unit) + " (Holm)", str(got["ordering"])
    try:
        p = b.pair(suite, pc.method, pc.baseline, pc.metric, pc.track)
    except MissingFigureError:
        if pc.metric != "class_acc" or not (b.has(suite, pc.method) and b.has(suite, pc.baseline)):
            return "-", NOT_RUN
        return _unpaired(b, (suite, pc.method), (suite, pc.baseline))
    figures = f"{fmt(p['method_value'])} vs {fmt(p['baseline_value'])}: {_diff(p, unit)}"
    return figures, str(ordering_verdict(pc.expected, p["verdict"]))


def _protocol(suite: str) -> str:
    return THE_DISSERTATIONS if suite in DISSERTATION_PROTOCOL else OURS


def ordering_checks(b: Boards) -> list[Check]:
    """Every ordering of :data:`ORDERINGS_SAID` on every page that tests it: the paired ones
    from the pages' primary comparisons (:data:`~beo_bench.bench.pages.verdicts.
    PRIMARY_COMPARISONS`), HBEO at 3-DOF against BEO at 1-DOF (Table 4.1's two rows, other
    views: unpaired) and the time per view (Table 4.2: medians, not resampled); in the
    order of :data:`ORDERINGS_SAID`, the dissertation's protocol first."""
    checks = []
    for suite in ORDERING_SUITES:
        for pc in primary_comparisons(suite):
            if pc.expected is None:
                continue
            try:
                figures, verdict = _paired_check(b, suite, pc)
            except PendingSuiteError:
                figures, verdict = "-", WAITS
            checks.append(Check(pc.source, _protocol(suite), suite, _claim(pc), figures, verdict))
    claim = "`hbeo` at 3-DOF above `beo` at 1-DOF on class acc., class-free (other views)"
    for three, one in (("modelnet10-3dof", "modelnet10-1dof"), ("pose-3dof", "pose-1dof")):
        try:
            figures, verdict = _unpaired(b, (three, "hbeo"), (one, "beo"))
        except PendingSuiteError:
            figures, verdict = "-", WAITS
        checks.append(Check("Table 4.1", _protocol(three), f"{three} / {one}", claim, figures,
                            verdict))  # fmt: skip
    claim = "`hbeo` below `beo` on the median time per view, class-free (not resampled)"
    for suite in ("modelnet10-1dof", "modelnet10-3dof", "pose-1dof", "pose-3dof"):
        try:
            hbeo, beo = (b.metric(suite, n, "ms_per_view_median") for n in ("hbeo", "beo"))
            figures = f"{hbeo:.1f} ms vs {beo:.1f} ms"
            verdict = "holds" if hbeo < beo else "fails"
        except PendingSuiteError:
            figures, verdict = "-", WAITS
        except MissingFigureError:
            figures, verdict = "-", NOT_RUN
        checks.append(Check("Table 4.2", _protocol(suite), suite, claim, figures, verdict))
    order = list(ORDERINGS_SAID)
    return sorted(checks, key=lambda c: (order.index(c.source), c.protocol != THE_DISSERTATIONS))


WAITS = "waits"
VERDICTS: tuple[str, ...] = ("holds", "fails", "no difference", NOT_RUN, WAITS)


def ordering_counts(checks: list[Check]) -> dict[str, dict[str, int]]:
    """Per protocol (the dissertation's, then ours), how many checks have each verdict."""
    out = {p: dict.fromkeys(VERDICTS, 0) for p in (THE_DISSERTATIONS, OURS)}
    for c in checks:
        out[c.protocol][c.verdict] += 1
    return out


def orderings(b: Boards) -> str:
    """docs/results.md's table of every ordering of the dissertation it quotes, on the
    dissertation's protocol and then on ours, each ``holds``, ``fails`` or ``no
    difference`` (an ordering a paired interval cannot show does not hold), and the counts."""
    checks = ordering_checks(b)
    if all(c.verdict == WAITS for c in checks):
        raise PendingSuiteError(f"none of {', '.join(ORDERING_SUITES)} is in leaderboards/")
    said = _table(["source", "the dissertation's ordering"],
                  [[s, ORDERINGS_SAID[s]] for s in ORDERINGS_SAID])  # fmt: skip
    rows = [
        [c.source, c.protocol, f"`{c.suite}`", c.claim, c.figures,
         "**fails**" if c.verdict == "fails" else c.verdict]
        for c in checks
    ]  # fmt: skip
    head = ["source", "protocol", "suite", "compared", "figures", "verdict"]
    counts = ordering_counts(checks)
    shown = [v for v in VERDICTS if any(n[v] for n in counts.values())]
    tally = [[p, str(sum(n.values())), *(str(n[v]) for v in shown)] for p, n in counts.items()]
    return "\n".join([said, _table(head, rows), _table(["protocol", "checks", *shown], tally)])


def primary_declared(boards: Boards) -> str:
    """docs/benchmark.md's table of the primary comparisons each leaderboard page declares
    (:data:`~beo_bench.bench.pages.verdicts.PRIMARY_COMPARISONS`; ``boards`` is not read: the
    declaration comes before the runs)."""
    head = ["page", "method (B)", "baseline (A)", "metric", "track", "why", "expected"]
    rows = [
        [f"`{suite}`", f"`{pc.method}`", f"`{pc.baseline}`", spec(pc.metric).label,
         pc.track or "-", pc.source, "B better" if pc.expected else "none: a question"]
        for suite, declared in PRIMARY_COMPARISONS.items()
        for pc in declared
    ]  # fmt: skip
    return _table(head, rows)


INTERVAL_ITEMS = (20, 50, 100, 200, 500, 1000)
"""From the smoke set's 20 items an isolated suite (``SMOKE_SIZES``) to a full suite."""
INTERVAL_RATES = (0.5, 0.8, 0.95)
INTERVAL_DISCORDANT = (0.1, 0.3)


def interval_widths(boards: Boards) -> str:
    """docs/benchmark.md's table of what n items can tell: the 95% half-width of a rate
    near 50% (the widest), 80% and 95%, of a paired difference of two rates when 10% or
    30% of the items differ between the runs, and the smallest such difference a gate
    finds with 80% power (:mod:`beo_bench.stats`' formulas; ``boards`` is not
    read: these figures follow from n alone)."""
    from beo_bench.stats import detectable_difference, paired_half_width, rate_half_width

    head = (
        ["items n"]
        + [f"a rate near {r:.0%}" for r in INTERVAL_RATES]
        + [f"paired, {q:.0%} of items differ" for q in INTERVAL_DISCORDANT]
        + [f"smallest difference found, {INTERVAL_DISCORDANT[-1]:.0%} differ"]
    )
    lines = []
    for n in INTERVAL_ITEMS:
        cells = [f"{n}"]
        cells += [f"{100 * rate_half_width(r, n):.1f}" for r in INTERVAL_RATES]
        cells += [f"{100 * paired_half_width(q, n):.1f}" for q in INTERVAL_DISCORDANT]
        found = detectable_difference(INTERVAL_DISCORDANT[-1], n)
        cells.append(f"{100 * found:.1f}" if np.isfinite(found) else "-")
        lines.append(cells)
    return markdown_table(head, lines, "r") + "\n"
