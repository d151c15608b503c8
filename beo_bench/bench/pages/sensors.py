"""A page's parts per depth sensor and its robustness table: each backend's headline metrics under
each sensor, paired with the suite's own sensor on the same items.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from beo_bench.bench import compare, rundir
from beo_bench.bench.columns import (
    ROBUSTNESS_KEYS,
    markdown_table,
    spec,
)
from beo_bench.bench.pages.entries import DIAGNOSTIC, Row, is_bound, items, label
from beo_bench.bench.pages.tables import _name, _value
from beo_bench.bench.pages.verdicts import (
    UNCORRECTED_NOTE,
    Section,
    _run,
    _track_key,
    _verdict_cells,
    _verdict_head,
)
from beo_bench.errors import UsageError

# -- sensors -------------------------------------------------------------------------------------
SENSOR_NOTE = (
    "The same items as the suite's own sections, the depth captured by the `{sensor}` sensor "
    "(docs/sensors.md) instead of the suite's own `{own}`."
)


def _order_of(sensor: str) -> tuple[int, str]:
    """Sensors in the order of ``SENSORS`` (ideal, kinect-v1, d435), others after them."""
    from beo_bench.scenes.sensors import SENSORS

    return (SENSORS.index(sensor) if sensor in SENSORS else len(SENSORS), sensor)


def _sensor_key(tag: str | None) -> tuple[int, str]:
    """Sensor parts: the suite's own (None) first, then the others in ``SENSORS`` order."""
    return (-1, "") if tag is None else _order_of(tag)


def sensor_rows(rows: list[Row]) -> dict[str | None, list[Row]]:
    """The rows by the sensor they were captured by: None for the suite's own
    (:func:`~beo_bench.bench.rundir.sensor_tag_of`), then each other sensor, in the order
    of ``SENSORS``."""
    groups: dict[str | None, list[Row]] = {}
    for r in rows:
        groups.setdefault(rundir.sensor_tag_of(r.summary), []).append(r)
    return {k: groups[k] for k in sorted(groups, key=_sensor_key)}


@dataclass(frozen=True)
class SensorPair:
    """One backend's run under ``sensor`` against its run under ``baseline_sensor`` (the
    first sensor with a run of it, in the order of ``SENSORS``), on one metric."""

    track: str | None
    backend: str
    sensor: str
    baseline_sensor: str
    result: compare.PairedResult


def _sensor_json(p: SensorPair) -> dict[str, Any]:
    out = compare.paired_json(p.result, "sensor", p.track, p.backend, p.backend)
    return {**out, "sensor": p.sensor, "baseline_sensor": p.baseline_sensor}


ROBUSTNESS_NOTE = (
    "Each backend under each depth sensor (docs/sensors.md) it was run with, from each "
    "sensor's first section: item i is the same scene under every sensor, so the runs pair "
    "item by item."
)


@dataclass(frozen=True)
class Robustness:
    """A suite's robustness table: per track (None on a suite without tracks) its tables,
    and the pairings behind them."""

    tracks: list[tuple[str | None, str]]
    pairs: list[SensorPair]

    def markdown(self, level: str = "###") -> str:
        """The tables, each track's under a heading of ``level``; "" without tables."""
        if not self.tracks:
            return ""
        parts = [f"{level} {t} track\n\n{text}" if t else text for t, text in self.tracks]
        return "\n\n".join([ROBUSTNESS_NOTE, *parts])


def robustness(suite: str, parts: dict[str | None, dict[str | None, list[Section]]]) -> Robustness:
    """The robustness table of a suite with runs under more than one sensor, and its
    pairings (empty otherwise). Per track, from each sensor's first section: per
    backend, the headline metrics (:data:`ROBUSTNESS_KEYS`) under each sensor, ``ideal ->
    kinect-v1 -> d435``; then each sensor's run paired with the backend's run under the
    first of them (B - A over the items both scored, a bootstrap interval that resamples
    items, a verdict: :func:`beo_bench.bench.compare.paired_runs`)."""
    from beo_bench.bench.rundir import default_sensor_of

    own = default_sensor_of(suite)
    names = {tag: own if tag is None else tag for tag in parts}
    if len(set(names.values())) < 2:
        return Robustness([], [])
    order = sorted(parts, key=lambda t: _order_of(names[t]))  # ideal -> kinect-v1 -> d435
    tracks = sorted({t for p in parts.values() for t in p}, key=_track_key)
    blocks: list[tuple[str | None, str]] = []
    pairs: list[SensorPair] = []
    loaded: dict[Path, compare.Run | None] = {}
    for track in tracks:
        # each sensor's first section of the track: its own runs (not borrowed ones)
        firsts = {names[t]: parts[t][track][0] for t in order if parts[t].get(track)}
        if len(firsts) < 2:
            continue
        sensors = list(firsts)
        runs: dict[str, dict[str, Row]] = {}
        for sensor, sec in firsts.items():
            for r in sec.rows:
                if not r.borrowed and r.summary["backend"] not in DIAGNOSTIC:
                    runs.setdefault(label(r.summary), {})[sensor] = r
        ordered = sorted(runs, key=lambda b: _order_key(runs[b]))
        backends = [b for b in ordered if len(runs[b]) > 1]  # under two sensors at least
        if not backends:
            continue
        keys = [
            k
            for k in ROBUSTNESS_KEYS
            if any(k in r.summary["metrics"] for b in backends for r in runs[b].values())
        ]
        head = " -> ".join(f"`{x}`" for x in sensors)
        body: list[list[str]] = []
        track_pairs: list[SensorPair] = []
        shorter = False
        for b in backends:
            got = runs[b]
            ref = next(x for x in sensors if x in got)
            mine: list[SensorPair] = []
            for x in sensors:
                if x == ref or x not in got:
                    continue
                mine += _sensor_pairs(track, b, ref, got[ref], x, got[x], keys, loaded)
            # a sensor run over fewer items (pick's 200 of 500): every cell on the items all
            # of this backend's runs scored, as the paired rows below compare them
            common = _common_values(got[ref], mine)
            shorter |= bool(common)
            cells = [
                " -> ".join(
                    (
                        spec(k).format(common[(x, k)])
                        if (x, k) in common
                        else _value(got[x].summary, spec(k))
                    )
                    if x in got
                    else "-"
                    for x in sensors
                )
                for k in keys
            ]
            first = next(r for r in got.values())
            body.append([_name(first), *cells])
            track_pairs += mine
        lines = [markdown_table(["backend", *(f"{spec(k).label}: {head}" for k in keys)], body)]
        if shorter:
            lines += ["", SHORTER_NOTE]
        pairs += track_pairs
        table = sensor_verdict_table(track_pairs)
        blocks.append((track, "\n".join(lines) + ("\n\n" + table if table else "")))
    return Robustness(blocks, pairs)


SHORTER_NOTE = (
    "Where a sensor's runs cover fewer items than the first sensor's, a backend's figures "
    "under every sensor are over the items all of its runs scored, the paired rows' items."
)


def _common_values(ref: Row, pairs: list[SensorPair]) -> dict[tuple[str, str], float]:
    """(sensor, metric) -> the value over the items common to the pairs, when some sensor's
    run covers fewer items than the reference run and every pair has the same items; empty
    when each covers the reference's items (the summaries' figures are these)."""
    if not pairs:
        return {}
    n_items = {p.result.n_items for p in pairs}
    if len(n_items) != 1 or n_items == {items(ref.summary)}:
        return {}
    out = {(p.sensor, p.result.key): p.result.b for p in pairs}
    out.update({(p.baseline_sensor, p.result.key): p.result.a for p in pairs})
    return out


def _order_key(runs: dict[str, Row]) -> tuple[bool, str]:
    r = next(iter(runs.values()))
    return (is_bound(r.summary), label(r.summary))


def _sensor_pairs(
    track: str | None,
    backend: str,
    ref: str,
    a: Row,
    sensor: str,
    b: Row,
    keys: list[str],
    loaded: dict[Path, compare.Run | None],
) -> list[SensorPair]:
    """``b`` (under ``sensor``) against ``a`` (under ``ref``) on ``keys``, over the items
    both scored; none when either run's results are not at hand or they are not the same
    items (another seed)."""
    if a.path is None or b.path is None:
        return []
    a_run, b_run = _run(a, loaded), _run(b, loaded)
    if a_run is None or b_run is None or not a_run.items & b_run.items:
        return []
    both = {m.key for m in compare.pairable(a_run.summary, b_run.summary)}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", compare.ComparisonWarning)  # a shorter run: its items
            wanted = [k for k in keys if k in both]
            results = compare.paired_runs(a_run, b_run, wanted, across_sensors=True)
    except UsageError:  # another seed or version: not the same items
        return []
    return [SensorPair(track, backend, sensor, ref, r) for r in results]


def sensor_verdict_table(pairs: list[SensorPair]) -> str:
    """The paired verdicts of the robustness table: a row per (backend, sensor), per metric
    sensor - baseline sensor with its 95% interval and the verdict; "" without pairs."""
    if not pairs:
        return ""
    keys = [k for k in ROBUSTNESS_KEYS if any(p.result.key == k for p in pairs)]
    rows: dict[tuple[str, str, str], dict[str, compare.PairedResult]] = {}
    for p in pairs:
        rows.setdefault((p.backend, p.sensor, p.baseline_sensor), {})[p.result.key] = p.result
    body = [
        [backend, f"`{sensor}`", f"`{base}`", *_verdict_cells(res, keys)]
        for (backend, sensor, base), res in rows.items()
    ]
    head = ["backend", "sensor", "baseline", *_verdict_head("sensor - baseline", keys)]
    return (
        "Paired (exploratory: each sensor's run against the same backend's under the first "
        "sensor, on the items both scored; 95% bootstrap intervals that resample items; "
        f"*better* / *worse* when the interval excludes 0, {UNCORRECTED_NOTE}):\n\n"
        + markdown_table(head, body, "lllr" + "rl" * len(keys))
    )
