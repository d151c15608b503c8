"""What went wrong in a run, said where a user looks: at the end of its output.

A backend that raises on a view is recorded as a failure and scored at its worst case, and
the run goes on (docs/benchmark.md, "Runs"). That keeps a run's numbers honest, but it once
hid a plugin that raised on every view: the run exited 0 and printed "fail 5", and the
exception was only in ``results.jsonl``. So every run ends with its failures grouped and
counted (``5 x RuntimeError: asked to fail``), a pick run with its episodes' reasons
(docs/env.md, "Why a pick fails"), and a run in which every view failed with a warning on
stderr too. :func:`summarise_failures` works on a run's rows (the runner's
:func:`~beo_bench.bench.runner.run_end` reads them from a run directory).
"""

from __future__ import annotations

import re
import warnings
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

TOP_GROUPS = 5
"""How many kinds of failure a run's output lists (the rest are counted in one line)."""

_NUMBER = re.compile(r"\d+(?:\.\d+)?")


class FailureWarning(UserWarning):
    """Every view (or episode) of a run failed: its scores are the worst cases, not the
    backend's quality (the CLI prints it as one ``beo-bench: warning:`` line)."""


@dataclass(frozen=True)
class FailureGroup:
    """Failures with one exception type and the same message up to its numbers."""

    count: int
    kind: str
    """The exception's type name (``RuntimeError``), or ``timeout`` / ``worker died``."""
    message: str
    """The first message of the group, as recorded (without the type)."""
    variants: int = 1
    """How many different messages the group holds (they differ only in numbers)."""

    def text(self) -> str:
        """``5 x RuntimeError: asked to fail`` (``(3 messages differing in numbers)``)."""
        what = f"{self.kind}: {self.message}" if self.message else self.kind
        more = f" ({self.variants} messages differing in numbers)" if self.variants > 1 else ""
        return f"{self.count} x {what}{more}"


@dataclass(frozen=True)
class FailureSummary:
    """A run's failures: how many of its rows failed, grouped by exception type and
    message, and (pick runs) every episode's reason with its count."""

    n: int
    """Rows (views or episodes) of the run."""
    failures: int
    groups: tuple[FailureGroup, ...] = ()
    """Most frequent first."""
    pick_reasons: tuple[tuple[str, int], ...] = ()
    """(reason, episodes), most frequent first, ``success`` among them; empty for runs
    whose rows have no pick reason."""
    unit: str = "views"
    label: str = ""
    """What the run is (``pose-1dof / random``), for output that lists several runs."""

    @property
    def all_failed(self) -> bool:
        return self.n > 0 and self.failures == self.n

    def lines(self, top: int = TOP_GROUPS) -> list[str]:
        """What a run prints at its end: the failures (or that there were none), the top
        ``top`` groups, then the pick reasons."""
        head = f"{self.label}: " if self.label else ""
        if not self.failures:
            out = [f"{head}failures: none ({self.n} {self.unit})"]
        else:
            pct = 100.0 * self.failures / self.n
            out = [f"{head}failures: {self.failures} of {self.n} {self.unit} ({pct:.0f}%)"]
            if self.all_failed:
                out[0] += f": EVERY ONE OF THE {self.n} {self.unit.upper()} FAILED"
            out += [f"  {g.text()}" for g in self.groups[:top]]
            rest = self.groups[top:]
            if rest:
                n = sum(g.count for g in rest)
                out.append(f"  ... and {n} more in {len(rest)} other kinds (results.jsonl)")
        if self.pick_reasons:
            out.append(f"{head}pick reasons: {reasons_text(self.pick_reasons)}")
        return out

    def text(self) -> str:
        return "\n".join(self.lines())

    def warning(self) -> str | None:
        """One line for stderr when every view failed (None otherwise): the scores then
        measure nothing of the backend."""
        if not self.all_failed:
            return None
        top = self.groups[0].text() if self.groups else "no reason recorded"
        what = f"run {self.label}" if self.label else "the run"
        return (
            f"every one of the {self.n} {self.unit} of {what} failed ({top}): its scores are "
            "the worst cases, not the backend's quality; fix the backend and run again "
            "(results.jsonl holds each failure)"
        )


def _split(failure: str) -> tuple[str, str]:
    """(kind, message) of a row's ``failure`` text (``"RuntimeError: asked to fail"``,
    ``"timeout after 60 s"``, ``"worker died: signal 6"``)."""
    from beo_bench.bench.tally import failure_kind

    kind = failure_kind(failure)
    if kind != "backend error":  # the runner's own texts: the kind is the whole story
        return kind, failure
    name, sep, message = failure.partition(": ")
    if sep and name.isidentifier():  # the evaluator writes "Type: message"
        return name, message
    return "error", failure


def group_failures(failures: Sequence[str]) -> tuple[FailureGroup, ...]:
    """The failure texts grouped by exception type and message, numbers masked (``item 3
    has 0 points`` and ``item 7 has 0 points`` are one group); most frequent first, ties
    in the order first seen."""
    groups: dict[tuple[str, str], list[str]] = {}
    for f in failures:
        kind, message = _split(f)
        groups.setdefault((kind, _NUMBER.sub("#", message)), []).append(message)
    made = [
        FailureGroup(len(msgs), kind, msgs[0], len(set(msgs))) for (kind, _), msgs in groups.items()
    ]
    return tuple(sorted(made, key=lambda g: -g.count))  # stable: ties keep their order


def reasons_text(reasons: Sequence[tuple[str, int]]) -> str:
    """``success 3, nothing_lifted 1, no_grasp 1``."""
    return ", ".join(f"{why} {n}" for why, n in reasons)


def summarise_failures(rows: Sequence[Mapping[str, Any]], label: str = "") -> FailureSummary:
    """The failures of a run's ``rows`` (``results.jsonl``'s)."""
    texts = [str(r["failure"]) for r in rows if r.get("failure")]
    picks = [r for r in rows if "reason" in r]
    reasons = Counter(str(r.get("reason") or "unknown") for r in picks)
    return FailureSummary(
        n=len(rows),
        failures=len(texts),
        groups=group_failures(texts),
        pick_reasons=tuple(reasons.most_common()),
        unit="episodes" if picks else "views",
        label=label,
    )


def summary_pick_reasons(summary: Mapping[str, Any]) -> tuple[tuple[str, int], ...]:
    """Every episode's reason with its count, from a summary (``summary.json``): its
    ``pick_failure_reasons`` and, for the rest of its ``n`` episodes, ``success``; empty
    for a summary of a suite without picks."""
    failed = dict(summary.get("metrics", {}).get("pick_failure_reasons") or {})
    if "pick_success" not in summary.get("metrics", {}):
        return ()
    succeeded = int(summary.get("n", 0)) - sum(int(v) for v in failed.values())
    counts = Counter({k: int(v) for k, v in failed.items()})
    if succeeded > 0:
        counts["success"] = succeeded
    return tuple(counts.most_common())


@dataclass(frozen=True)
class RunEnd:
    """What a run's last lines say: its failures, and where its report is."""

    failures: FailureSummary
    report: Path | None = None

    def text(self) -> str:
        lines = self.failures.lines()
        if self.report is not None:
            lines.append(f"report: {self.report}  (its worst views, offline HTML)")
        return "\n".join(lines)

    def warn(self) -> None:
        """A :class:`FailureWarning` when every view failed, so stderr says it too."""
        alarm = self.failures.warning()
        if alarm:
            warnings.warn(alarm, FailureWarning, stacklevel=3)
