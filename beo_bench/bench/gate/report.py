"""A gate's report: its outcome as text, Markdown (the CI job summary), JUnit XML and JSON."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from beo_bench.atomic import atomic_write_bytes
from beo_bench.bench.gate.spec import REGRESSION
from beo_bench.bench.gate.verdicts import CannotFail, GateOptions, Skipped, Verdict
from beo_bench.stats import (
    EXACT_MAX_ITEMS,
    smallest_p,
)

REPORT_FORMAT = "beo-bench-gate"
REPORT_VERSION = 2
"""2: a verdict per (backend, metric) pooled over suites, with its margin, suites and
skipped metrics (1: a verdict per suite and metric)."""


@dataclass(frozen=True)
class GateReport:
    """What a gate found: a verdict per (backend, metric), in the order tested."""

    verdicts: tuple[Verdict, ...]
    options: GateOptions
    baseline: str
    """Where the baseline was read."""
    not_run: tuple[str, ...] = field(default=())
    """Labels of the baseline's runs that no run was gated against (skipped, not failed)."""
    skipped: tuple[Skipped, ...] = field(default=())
    """The ``--metrics`` a run's suite does not measure (left out of that test)."""

    @property
    def regressions(self) -> tuple[Verdict, ...]:
        return tuple(v for v in self.verdicts if v.regression)

    @property
    def passed(self) -> bool:
        return not self.regressions

    @property
    def cannot_fail(self) -> tuple[CannotFail, ...]:
        """The tests, and each test's suites, whose item count cannot reach significance
        after the correction (:class:`CannotFail`): a pass says nothing about them."""
        if not self.verdicts:
            return ()
        o = self.options
        threshold = o.alpha / len(self.verdicts)  # Holm's first (smallest) threshold
        out = []
        for v in self.verdicts:
            whole = smallest_p(v.n_items, o.permutations)
            if whole > threshold:
                out.append(CannotFail(v.backend, v.metric, f"{v.where()} (the whole test)",
                                      v.n_items, whole, threshold))  # fmt: skip
                continue
            for part in v.parts:
                p_min = max(whole, smallest_p(part.n_items, o.permutations))
                if p_min > threshold:
                    out.append(CannotFail(v.backend, v.metric, part.suite, part.n_items, p_min,
                                          threshold))  # fmt: skip
        return tuple(out)

    def method(self) -> str:
        o = self.options
        return (
            "one-sided paired sign-flip permutation test over items, each metric pooled over "
            "the suites that measure it, of the run's worsening less the metric's margin "
            f"(exact up to {EXACT_MAX_ITEMS} differing items, else {o.permutations} seeded "
            f"patterns), Holm-corrected over {len(self.verdicts)} tests at alpha {o.alpha:g}; "
            f"intervals: 95% paired bootstrap, {o.resamples} resamples of items"
        )

    def to_json(self) -> dict[str, Any]:
        o = self.options
        return {
            "format": REPORT_FORMAT,
            "version": REPORT_VERSION,
            "passed": self.passed,
            "baseline": self.baseline,
            "method": self.method(),
            "alpha": o.alpha,
            "seed": o.seed,
            "metrics": list(o.metrics) if o.metrics else "primary",
            "regressions": len(self.regressions),
            "verdicts": [v.to_json() for v in self.verdicts],
            "skipped": [s.to_json() for s in self.skipped],
            "not_run": list(self.not_run),
            "cannot_fail": [c.to_json() for c in self.cannot_fail],
        }

    def junit_xml(self) -> str:
        """JUnit XML: a ``testsuite`` per backend, a ``testcase`` per metric (a ``failure``
        element on a regression); the metrics a suite does not measure (``--metrics``) and
        the baseline's runs that were not gated as skipped test cases, so a job page shows
        what was not tested."""
        root = ET.Element("testsuites", name="beo-bench gate")
        by_backend: dict[str, list[Verdict]] = {}
        for v in self.verdicts:
            by_backend.setdefault(v.backend, []).append(v)
        for backend, vs in by_backend.items():
            fails = sum(v.regression for v in vs)
            ts = ET.SubElement(root, "testsuite", name=backend, tests=str(len(vs)),
                               failures=str(fails), errors="0", skipped="0")  # fmt: skip
            props = ET.SubElement(ts, "properties")
            ET.SubElement(props, "property", name="baseline", value=vs[0].baseline_backend)
            for v in vs:
                tc = ET.SubElement(ts, "testcase", classname=f"beo-bench.gate.{backend}",
                                   name=v.metric, time="0")  # fmt: skip
                if v.regression:
                    f = ET.SubElement(
                        tc, "failure", type=REGRESSION, message=f"regression: {v.line()}"
                    )
                    f.text = self.method() + "\n" + "\n".join(_part_lines(v))
                else:
                    ET.SubElement(tc, "system-out").text = f"{v.outcome}: {v.line()}"
        skips = [(s.suite, s.metric, s.why) for s in self.skipped]
        skips += [(label, "run", "the baseline has this suite; no run of it was gated")
                  for label in self.not_run]  # fmt: skip
        skips += [(c.suite, c.metric, f"cannot fail: {c.line()}") for c in self.cannot_fail]
        for suite, name, why in skips:
            ts = ET.SubElement(root, "testsuite", name=suite, tests="1", failures="0",
                               errors="0", skipped="1")  # fmt: skip
            tc = ET.SubElement(ts, "testcase", classname=f"beo-bench.gate.{suite}", name=name)
            ET.SubElement(tc, "skipped", message=why)
        root.set("tests", str(len(self.verdicts) + len(skips)))
        root.set("failures", str(len(self.regressions)))
        root.set("skipped", str(len(skips)))
        ET.indent(root)
        return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, "unicode") + "\n"

    def markdown(self) -> str:
        """A Markdown summary for a CI job's page (GitHub's step summary, a merge request
        note): the tests, then each suite's own difference, then what was not tested."""
        n = len(self.regressions)
        head = "pass" if self.passed else f"{n} regression{'s' * (n != 1)}"
        lines = [
            f"### beo-bench gate: {head}",
            "",
            f"Against the baseline `{self.baseline}`: {self.method()}. A regression is a "
            "metric worse than the baseline by more than its margin, with adjusted p at most "
            "alpha.",
            "",
            "| backend (baseline) | metric | suites | baseline | run | run - baseline | 95% "
            "interval | margin | p (Holm) | verdict |",
            "|---|---|---|---:|---:|---:|---|---:|---:|---|",
        ]
        for v in self.verdicts:
            m = v.spec
            verdict = f"**{v.outcome}**" if v.regression else v.outcome
            lines.append(
                f"| {v.backend} ({v.baseline_backend}) | {m.label} | {v.where()} | "
                f"{m.format(v.baseline)} | {m.format(v.value)} | {m.format_diff(v.diff)} | "
                f"[{m.format_diff(v.lo)}, {m.format_diff(v.hi)}] | {m.format(v.margin)} | "
                f"{v.p_holm:.3g} | {verdict} |"
            )
        lines += [
            "",
            "Each suite's own difference (not tested: the tests above pool them):",
            "",
            "| backend | metric | suite | baseline | run | run - baseline | items |",
            "|---|---|---|---:|---:|---:|---:|",
        ]
        for v in self.verdicts:
            m = v.spec
            lines += [
                f"| {v.backend} | {m.label} | {p.suite} | {m.format(p.baseline)} | "
                f"{m.format(p.value)} | {m.format_diff(p.diff)} | {p.n_items} |"
                for p in v.parts
            ]
        if self.skipped:
            said = "; ".join(f"{s.suite}: {s.metric} ({s.why})" for s in self.skipped)
            lines += ["", f"Skipped (the suite does not measure the metric): {said}."]
        if self.not_run:
            lines += ["", f"Not gated (in the baseline, no run given): {', '.join(self.not_run)}."]
        if self.cannot_fail:
            lines += ["", "**Cannot fail** (too few items for the corrected threshold; a pass "
                      "says nothing about them):", ""]  # fmt: skip
            lines += [f"- {c.line()}" for c in self.cannot_fail]
        return "\n".join(lines) + "\n"

    def text(self) -> str:
        """The terminal's report: a line per verdict (a regression's suites under it),
        what was skipped, then the outcome."""
        lines = [f"gate against {self.baseline}: {self.method()}"]
        for v in self.verdicts:
            lines.append(f"  {v.outcome:<13} {v.line()}")
            if v.regression:
                lines += [f"      {line}" for line in _part_lines(v)]
        lines += [f"  skipped        {s.suite}: {s.metric} ({s.why})" for s in self.skipped]
        if self.not_run:
            lines.append(f"  not gated (no run given): {', '.join(self.not_run)}")
        blind = self.cannot_fail
        lines += [f"  CANNOT FAIL   {c.line()}" for c in blind]
        n = len(self.regressions)
        lines.append(
            f"gate: pass ({len(self.verdicts)} tests, no regression)"
            if self.passed
            else f"gate: {n} regression{'s' * (n != 1)} in {len(self.verdicts)} tests"
        )
        if blind:
            lines[-1] += (
                f"; WARNING: {len(blind)} test{'s' * (len(blind) != 1)} or suite"
                f"{'s' * (len(blind) != 1)} cannot fail it (CANNOT FAIL above)"
            )
        return "\n".join(lines)


def _part_lines(v: Verdict) -> list[str]:
    """Each suite's own difference in a test, a line each."""
    m = v.spec
    return [
        f"{p.suite}: {m.format(p.baseline)} -> {m.format(p.value)} ({m.format_diff(p.diff)}, "
        f"{p.n_items} items)"
        for p in v.parts
    ]


# -- writing the reports ------------------------------------------------------------------------
STEP_SUMMARY_ENV = "GITHUB_STEP_SUMMARY"
"""The file GitHub Actions shows on a job's page: the Markdown summary is appended to it."""


def write_reports(
    report: GateReport,
    json_path: Path | str | None = None,
    junit_path: Path | str | None = None,
    markdown_path: Path | str | None = None,
) -> list[Path]:
    """Write the asked-for reports (each atomically) and append the Markdown summary to
    ``$GITHUB_STEP_SUMMARY`` when it is set; returns the files written."""
    written = []
    for path, text in (
        (json_path, lambda: json.dumps(report.to_json(), indent=1) + "\n"),
        (junit_path, report.junit_xml),
        (markdown_path, report.markdown),
    ):
        if path is not None:
            Path(path).parent.mkdir(parents=True, exist_ok=True)  # out/gate.xml: out/ may be new
            atomic_write_bytes(Path(path), text())
            written.append(Path(path))
    summary = os.environ.get(STEP_SUMMARY_ENV)
    if summary:
        # appended, not replaced: the file is the job's, and other steps write to it too
        with open(summary, "a", encoding="utf-8") as f:
            f.write(report.markdown())
        written.append(Path(summary))
    return written
