"""What every generated doc table reads: the committed leaderboards (:class:`Boards`), the
methods a table lists, the cell formats, and the declared tables (:class:`Table`: a header,
rows and cells of figures, drawn by one renderer) that most tables are.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from beo_bench.backend import in_tree
from beo_bench.bench.columns import markdown_table, verdict_cell
from beo_bench.bench.pages.verdicts import (
    Primary,
)
from beo_bench.bench.rundir import sensor_tag_of
from beo_bench.bench.runs import backend_label
from beo_bench.bench.suites import get_suite

MARK = re.compile(r"(<!-- table: ([a-z0-9-]+) -->\n)(.*?)(<!-- /table -->)", re.S)
PRIMARY = "primary"
"""The ``pairing`` of a page's primary comparisons in ``<suite>_paired.json``."""


class MissingFigureError(LookupError):
    """A table asks for a row or metric the leaderboards do not have."""


class PendingSuiteError(MissingFigureError):
    """A table asks for a suite the leaderboards do not hold yet (a campaign run suite by
    suite, ``all --update``): the table says so instead of failing. A row missing from a
    suite that is there stays an error."""


@dataclass(frozen=True)
class Boards:
    """The committed leaderboards: each suite's run summaries and paired results."""

    root: Path

    def rows(self, suite: str) -> list[dict[str, Any]]:
        path = self.root / f"{suite}.json"
        if not path.is_file():
            raise PendingSuiteError(f"leaderboards/{suite}.json is not there")
        return json.loads(path.read_text())

    def paired(self, suite: str) -> list[dict[str, Any]]:
        if not (self.root / f"{suite}.json").is_file():
            raise PendingSuiteError(f"leaderboards/{suite}.json is not there")
        path = self.root / f"{suite}_paired.json"
        return json.loads(path.read_text()) if path.exists() else []

    def row(self, suite: str, name: str, track: str | None = None) -> dict[str, Any]:
        """The row labelled ``name`` (``hbeo``, ``beo (pose_prior=false)``) of the suite's own
        seed and track (default: ``class-free`` where the suite has tracks), with the most
        items."""
        s = get_suite(suite)
        if track is None and s.class_hint:
            track = "class-free"
        found = [
            r
            for r in self.rows(suite)
            if backend_label(r["backend"], r["provenance"].get("backend_kwargs") or {}) == name
            and r.get("track") == track
            and r.get("seed") == s.seed
            and sensor_tag_of(r) is None  # the suite's own sensor: its robustness is apart
        ]
        if not found:
            raise MissingFigureError(f"leaderboards/{suite}.json has no row {name!r} ({track})")
        return max(found, key=lambda r: r["n"])

    def has(self, suite: str, name: str, track: str | None = None) -> bool:
        """Whether the leaderboards have the row (tables leave out rows of runs this
        version's leaderboards do not hold)."""
        try:
            self.row(suite, name, track)
        except MissingFigureError:
            return False
        return True

    def metric(self, suite: str, name: str, key: str, track: str | None = None) -> float:
        v = self.row(suite, name, track)["metrics"].get(key)
        if v is None:
            raise MissingFigureError(f"leaderboards/{suite}.json: {name!r} has no {key}")
        return float(v)

    def pair(
        self,
        suite: str,
        method: str,
        baseline: str,
        metric: str,
        track: str | None,
        sensor: str | None = None,
    ) -> dict[str, Any]:
        """The paired entry of ``method`` against ``baseline``; ``sensor``: in the part of
        that sensor (not the suite's own), else the suite's own sensor's."""
        for p in self.paired(suite):
            if p.get("sensor") != sensor:  # another sensor's part, or a pair across sensors
                continue
            if p.get("pairing") == "sensor":
                continue
            if p.get("pairing") == PRIMARY:  # the same pair, Holm-corrected: self.primary
                continue
            if (p["method"], p["baseline"], p["metric"], p["track"]) == (
                method,
                baseline,
                metric,
                track,
            ):
                return p
        raise MissingFigureError(
            f"leaderboards/{suite}_paired.json has no {method} - {baseline} on {metric} ({track})"
        )

    def primary(self, suite: str, pc: Primary) -> dict[str, Any] | None:
        """The page's primary comparison ``pc``, Holm-corrected over the page's family
        (``"pairing": "primary"``, :func:`beo_bench.bench.pages.verdicts.primary_results`);
        None on a page made before pages carried them."""
        for p in self.paired(suite):
            if p.get("pairing") == PRIMARY and "sensor" not in p:
                key = (p["method"], p["baseline"], p["metric"], p["track"])
                if key == (pc.method, pc.baseline, pc.metric, pc.track):
                    return p
        return None


# -- formats ---------------------------------------------------------------------------------
def pct(v: float) -> str:
    return f"{100 * v:.1f}%"


def deg(v: float) -> str:
    return f"{v:.1f} deg"


def num(v: float, digits: int = 3) -> str:
    return f"{v:.{digits}f}"


def _diff(p: dict[str, Any], unit: str, digits: int = 1, sign: int = 1) -> str:
    """A paired difference with its interval and verdict; ``unit`` `` pts`` for a rate
    (shown in percentage points), else the value's own unit (`` deg``, or ``""``); ``sign``
    -1: baseline - method, without the verdict (which reads method - baseline)."""
    scale = sign * (100.0 if unit == " pts" else 1.0)
    ci = sorted(scale * x for x in p["ci95"])
    d, lo, hi = (f"{x:+.{digits}f}" for x in (scale * p["diff"], *ci))
    return f"{d}{unit} [{lo}, {hi}]" + (f" {verdict_cell(p['verdict'])}" if sign > 0 else "")


def _table(head: list[str], rows: list[list[str]]) -> str:
    """A doc table: every column left-aligned, a line break after it."""
    return markdown_table(head, rows, "l") + "\n"


METHODS = (*in_tree("method"), *sorted(in_tree("baseline")))


# -- a declared table ------------------------------------------------------------------------
Fmt = Callable[[float], str]
FORMATS: dict[str, Fmt] = {
    "rot_err_deg_mean": deg, "rot_err_deg_median": deg, "sample_best_err_deg_mean": deg,
    "sample_spread_deg_mean": deg, "iou_mean": num, "fscore_mean": num, "n": str,
}  # fmt: skip
"""A figure's format where a cell names none (any other metric: a rate, :func:`pct`)."""


def fmt_unit(key: str, fmt: Fmt | None = None) -> tuple[Fmt, str]:
    """A metric's format (``fmt``, else :data:`FORMATS`'s) and its paired difference's unit."""
    fmt = fmt or FORMATS.get(key, pct)
    return fmt, " deg" if fmt is deg else (" pts" if fmt is pct else "")


def with_ci(row: dict[str, Any], key: str, fmt: Fmt = pct) -> str:
    """A row's rate with its 95% interval, in points (``81.8% [78.1, 85.2]``)."""
    lo, hi = row["ci95"][key]
    return f"{fmt(row['metrics'][key])} [{100 * lo:.1f}, {100 * hi:.1f}]"


def _shift(p: dict[str, Any]) -> str:
    """A paired change in a rate, in points with its interval (``+14.4 [+10.2, +18.4]``)."""
    lo, hi = p["ci95"]
    return f"{100 * p['diff']:+.1f} [{100 * lo:+.1f}, {100 * hi:+.1f}]"


@dataclass(frozen=True)
class Fig:
    """A metric of one leaderboard row (``n``: its items) in ``fmt`` (``value`` ``ci``: with
    its 95% interval, a rate's): the row of ``name`` on ``suite`` and ``track``, each left
    out for the table row's own."""

    key: str
    fmt: Fmt | None = None
    suite: str = ""
    name: str = ""
    track: str | None = None
    value: str = ""


@dataclass(frozen=True)
class Pair(Fig):
    """The paired entry of ``name`` against ``baseline`` on ``key`` (:meth:`Boards.pair`):
    its difference with interval and verdict (:func:`_diff`, in the metric's unit), or
    with ``value`` its ``shift`` (:func:`_shift`) or one of its figures
    (``baseline_value``, ``method_value``, ``items``); ``sign``: as :func:`_diff`'s."""

    baseline: str = ""
    value: str = "diff"
    sign: int = 1
    sensor: str | None = None


@dataclass(frozen=True)
class Cell:
    """A cell: its figures in ``text`` (a format string; none: joined by ``, ``), or ``-``
    where a figure of ``when`` is not on the pages."""

    figs: tuple[Fig, ...]
    text: str = ""
    when: tuple[Fig, ...] = ()


@dataclass(frozen=True)
class Row:
    """A line: its label and cells (none: the table's columns), whose figures read the row
    of ``name`` on ``suite`` and ``track``; shown only where every figure of ``when`` is."""

    label: str | Cell
    name: str = ""
    suite: str = ""
    track: str | None = None
    cells: tuple[Cell | Fig | str, ...] | None = None
    when: tuple[Fig, ...] = ()


def backends(names: tuple[str, ...], *when: Fig, **kw: Any) -> tuple[Row, ...]:
    """A row per backend, labelled with its name."""
    return tuple(Row(f"`{n}`", n, when=when, **kw) for n in names)


@dataclass(frozen=True)
class Table:
    """A doc table as data, drawn by calling it on the :class:`Boards`: ``head``, then each
    row's label and cells (a figure, a :class:`Cell` of several, or text). It waits for its
    ``suite`` and ``needs``, and with ``empty`` (why) where no row is shown; ``note``: the
    paragraph after it."""

    head: tuple[str, ...]
    rows: tuple[Row, ...]
    cols: tuple[Cell | Fig | str, ...] = ()
    suite: str = ""
    needs: tuple[str, ...] = ()
    empty: str = ""
    note: Callable[[Boards], str] | None = None

    def __call__(self, b: Boards) -> str:
        for suite in filter(None, (self.suite, *self.needs)):
            b.rows(suite)  # the page, or the table is pending

        def text(c: Cell | Fig | str, r: Row) -> str:
            if isinstance(c, str):
                return c
            c = Cell((c,)) if isinstance(c, Fig) else c
            if not self._has(b, c.when, r):
                return "-"
            figs = [self._figure(b, f, r) for f in c.figs]
            return c.text.format(*figs) if c.text else ", ".join(figs)

        lines = [
            [text(c, r) for c in (r.label, *(self.cols if r.cells is None else r.cells))]
            for r in self.rows
            if self._has(b, r.when, r)
        ]
        if self.empty and not lines:  # a table of headers alone would read as a broken page
            raise PendingSuiteError(self.empty)
        out = _table(list(self.head), lines)
        return out if self.note is None else out + "\n" + self.note(b) + "\n"

    def _has(self, b: Boards, figs: tuple[Fig, ...], r: Row) -> bool:
        """Whether the pages have the figures (not on this version's pages, nor the page)."""
        try:
            return all(self._figure(b, f, r) for f in figs)  # (no figure reads "")
        except MissingFigureError:
            return False

    def _figure(self, b: Boards, f: Fig, r: Row) -> str:
        suite, name, track = f.suite or r.suite or self.suite, f.name or r.name, f.track or r.track
        fmt, unit = fmt_unit(f.key, f.fmt)
        if isinstance(f, Pair):
            p = b.pair(suite, name, f.baseline, f.key, track, f.sensor)
            if f.value in ("diff", "shift"):
                return _diff(p, unit, sign=f.sign) if f.value == "diff" else _shift(p)
            return fmt(p[f.value])
        row = b.row(suite, name, track)
        v = row["n"] if f.key == "n" else row["metrics"].get(f.key)
        if v is None:
            raise MissingFigureError(f"leaderboards/{suite}.json: {name!r} has no {f.key}")
        return with_ci(row, f.key, fmt) if f.value == "ci" else fmt(v)
