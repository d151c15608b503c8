"""The leaderboard's ablation pairs: one backend against a variant of itself, paired on the
items both runs scored (the variant may cover a prefix of the suite, as ``beo
(pose_prior=false)`` covers 300 of ``pose-3dof``'s 1000 views).

These are the comparisons the docs quote (the silhouette prior of HBEO-MDN, BEO's viewpoint
prior); the leaderboard writes them into ``<suite>_paired.json`` beside the baseline
verdicts (``"pairing": "ablation"``), so every paired interval in the docs comes from a
committed file that ``beo-bench leaderboard`` regenerates.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from beo_bench.bench import compare
from beo_bench.bench.columns import VERDICT_KEYS, markdown_table, verdict_cell
from beo_bench.bench.columns import spec as spec_of
from beo_bench.bench.runs import backend_label
from beo_bench.errors import UsageError


@dataclass(frozen=True)
class Ablation:
    """``method`` (a leaderboard label) against ``baseline``, with what the pair isolates."""

    method: str
    baseline: str
    what: str
    keys: tuple[str, ...] | None = None
    """The metrics it is paired on (those both runs have); ``None``: :data:`KEYS`, on
    suites with a pose metric only (a variant of the pose step changes nothing else)."""


PRIOR_STEPS: tuple[tuple[dict[str, Any], str], ...] = (
    ({"select": "prior"}, "Random Sample + SDF Error: the samples ranked by the prior alone"),
    ({"select": "oracle"}, "Random Sample + Oracle: the sample nearest the truth"),
    ({"prior_shape": "truth"}, "the prior of the true shape, at the estimated translation"),
    (
        {"prior_shape": "truth", "prior_translation": "truth"},
        "the prior of the true shape at the true translation",
    ),
    (
        {"prior_shape": "truth", "prior_translation": "aligned"},
        "the prior of the true shape, each silhouette shifted onto the observed centroid",
    ),
    ({"prior_grid": 64}, "the prior's shape re-projected at 64^3"),
    ({"prior_pixels": "view"}, "the silhouettes compared in the view's pixels, not the crop's"),
    ({"prior_occlusion": True}, "only the pixels no other object covers"),
    (
        {"prior_shape": "truth", "prior_occlusion": True},
        "the prior of the true shape, only the pixels no other object covers",
    ),
    ({"prior_shape": "hbeo"}, "the prior of the hbeo network's shape"),
    ({"prior_translation": "hbeo"}, "the prior placed at the hbeo network's translation"),
    ({"prior_translation": "aligned"}, "each silhouette shifted onto the observed centroid"),
    (
        {"prior_shape": "hbeo", "prior_translation": "hbeo"},
        "the prior of the hbeo network's shape, at its translation",
    ),
)
"""Chapter 5's ablation (issue 48; ``hbeo-mdn-posterior``'s options, docs/backends.md):
each step changes one input of the silhouette prior, or the rule that picks the sample, and
pairs with the likelihood on the same samples."""


SENSITIVITY_STEPS: tuple[tuple[dict[str, Any], str], ...] = (
    *(
        ({"rot_deg": d}, f"the true rotation turned {d} deg about a random axis")
        for d in (5, 15, 30, 60, 90)
    ),
    *(
        (
            {"rot_axis": "up", "rot_deg": d},
            f"the true rotation turned {d} deg about the up axis",
        )
        for d in (5, 15, 30, 60, 90)
    ),
    *(({"trans_cm": t}, f"the true translation moved {t:g} cm") for t in (0.5, 1, 2, 4)),
    ({"shape": "class-mean"}, "the class's mean shape and size in place of the instance's"),
)
"""Issue 49's sensitivity of pick: ``oracle``'s controlled damage (perception/bounds.py),
each step one error of a known size, paired with the oracle on the same episodes. The
options are spelt as ``--opt`` records them (``rot_deg=30``, ``trans_cm=0.5``): a row's label
is its recorded options."""

PER_CATEGORY: dict[str, Any] = {"per_category": True}
"""The option that answers each view with its class's own network (``pose-3dof-percat``'s
class-given track)."""

ABLATIONS: tuple[Ablation, ...] = (
    Ablation(
        "hbeo-mdn-posterior",
        "hbeo-mdn-likelihood",
        "the silhouette prior of eq. 5.6 (N = 25 samples)",
    ),
    Ablation(
        "hbeo-mdn-posterior (samples=100)",
        "hbeo-mdn-likelihood (samples=100)",
        "the silhouette prior of eq. 5.6 (N = 100 samples)",
    ),
    Ablation(
        "hbeo-mdn-posterior (samples=5)",
        "hbeo-mdn-likelihood (samples=5)",
        "the silhouette prior of eq. 5.6 (N = 5 samples)",
    ),
    *(
        Ablation(backend_label("hbeo-mdn-posterior", opts), "hbeo-mdn-likelihood", what)
        for opts, what in PRIOR_STEPS
    ),
    # Tables 5.1/5.2 with chapter 5's own networks, one per category (class-given track)
    *(
        Ablation(
            backend_label("hbeo-mdn-posterior", {**PER_CATEGORY, **n}),
            backend_label("hbeo-mdn-likelihood", {**PER_CATEGORY, **n}),
            f"the silhouette prior of eq. 5.6 (N = {n.get('samples', 25)} samples), each "
            "category's own network",
        )
        for n in ({}, {"samples": 100}, {"samples": 5})
    ),
    *(
        Ablation(
            backend_label("hbeo-mdn-posterior", {**PER_CATEGORY, **opts}),
            backend_label("hbeo-mdn-likelihood", PER_CATEGORY),
            f"{what}, each category's own network",
        )
        for opts, what in PRIOR_STEPS
    ),
    Ablation(
        "beo (pose_prior=false)",
        "beo",
        "BEO's pose prior P(r) of eq. 3.22 (the rig's viewpoints, or on a table the rest "
        "prior), made uniform",
    ),
    # the rest prior's control for the baseline without a learned prior (issue 47): the
    # same starts spread over SO(3) instead of upright about the world's up
    Ablation("icp (pose_prior=false)", "icp", "ICP's starts drawn from the rest prior, over SO(3)"),
    Ablation(
        "icp-plain (pose_prior=false)",
        "icp-plain",
        "plain ICP's one start upright about the world's up, the identity instead",
    ),
    # chapter 5's ordering (Tables 5.1, 5.2): the mixture head at or below HBEO's single
    # rotation; issue 28's headroom check reads these pairs on modelnet10-3dof
    Ablation("hbeo-mdn-likelihood", "hbeo", "the MDN's mixture head (chapter 5), likelihood mode"),
    Ablation("hbeo-mdn-posterior", "hbeo", "the MDN's mixture head with eq. 5.6's prior"),
    # pick's diagnostics (issue 47): what the truth of one component is worth to a backend's
    # grasps, on the same episodes; and what planning on voxels costs the oracle
    *(
        Ablation(f'swap (base="{b}", truth="{t}")', b, f"{b}'s {t} replaced by the truth")
        for b in ("hbeo", "hbeo-mdn-posterior", "icp")
        for t in ("class", "pose", "shape")
    ),
    Ablation(
        "oracle (mesh=false)", "oracle", "the oracle planning on its 32^3 voxels, not its mesh"
    ),
    # pick's sensitivity (issue 49): the truth with one controlled error, against the truth
    *(Ablation(backend_label("oracle", opts), "oracle", what) for opts, what in SENSITIVITY_STEPS),
    # chapter 4's comparison at a known pose (Table 3.1 against HBEO's figures): the learned
    # encoder against BEO's projection onto the class subspaces, on class and completion
    Ablation(
        "hbeo",
        "beo",
        "HBEO's learned encoder against BEO's projection (chapter 4)",
        keys=("class_acc", "iou_mean"),
    ),
)

KEYS: tuple[str, ...] = (*VERDICT_KEYS, "class_acc", "sample_best_rank_mean")
"""What an ablation is paired on: the verdict metrics and, where both have them, the class
and the rank of the best rotation sample (the posterior and the likelihood rank the same
samples: whether the silhouette prior moves the best one up)."""


PICK_KEYS: tuple[str, ...] = ("pick_success", "target_found_rate")
"""What an ablation is paired on in ``pick`` (no pose metric there): whether the variant
changes the grasps' outcome, and whether it finds the target it must grasp."""


@dataclass(frozen=True)
class AblationResult:
    ablation: Ablation
    track: str | None
    result: compare.PairedResult
    category: str | None = None
    """The category whose items alone were paired (chapter 5's per-category tables); None:
    every item."""


def ablation_results(
    track: str | None,
    rows: Sequence[Any],
    label: Callable[[dict[str, Any]], str],
    ablations: Sequence[Ablation] = ABLATIONS,
    by_category: bool = False,
) -> list[AblationResult]:
    """Each ablation whose two runs are among ``rows`` (leaderboard rows of one track and
    seed, with ``summary`` and ``path``), paired on their common items; ``by_category``:
    then on each category's items too (Tables 5.1/5.2 are per category)."""
    by_label = {label(r.summary): r for r in rows if getattr(r, "path", None) is not None}
    out: list[AblationResult] = []
    for ab in ablations:
        m, b = by_label.get(ab.method), by_label.get(ab.baseline)
        if m is None or b is None:
            continue
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # a prefix of the suite: paired on it
                a_run = compare.run_from(Path(b.path), b.summary)
                b_run = compare.run_from(Path(m.path), m.summary)
                both = {p.key for p in compare.pairable(a_run.summary, b_run.summary)}
                if ab.keys is not None:
                    keys = [k for k in ab.keys if k in both]
                elif both & set(VERDICT_KEYS):
                    keys = [k for k in KEYS if k in both]
                elif both & set(PICK_KEYS):  # pick: what the variant does to the grasps
                    keys = [k for k in PICK_KEYS if k in both]
                else:
                    continue  # no pose metric (known-pose): nothing these variants change
                if not keys:
                    continue
                results = compare.paired_runs(a_run, b_run, keys)
                out += [AblationResult(ab, track, r) for r in results]
                cats = sorted({str(r["category"]) for r in a_run.rows}) if by_category else []
                for c in cats:
                    a_c, b_c = (
                        replace(x, rows=tuple(r for r in x.rows if r["category"] == c))
                        for x in (a_run, b_run)
                    )
                    out += [
                        AblationResult(ab, track, r, c) for r in compare.paired_runs(a_c, b_c, keys)
                    ]
        except UsageError:  # not pairable (other items or scoring): no result
            continue
    return out


def ablation_table(results: Sequence[AblationResult]) -> str:
    """Markdown: a row per ablation and metric, method - baseline [95%] and the verdict."""
    if not results:
        return ""
    body = [
        [
            x.ablation.method,
            x.ablation.baseline,
            x.ablation.what + (f" ({x.category} only)" if x.category else ""),
            x.result.n_items,
            x.result.spec.label,
            x.result.spec.format_interval(x.result.diff, x.result.lo, x.result.hi),
            verdict_cell(x.result.verdict),
        ]
        for x in results
    ]
    head = [
        "method",
        "baseline",
        "what it isolates",
        "items",
        "metric",
        "method - baseline [95%]",
        "verdict, uncorrected",
    ]
    return (
        "Ablations (exploratory: a backend against a variant of itself, paired on the items "
        "both scored; 95% bootstrap intervals that resample items; *better* / *worse* when "
        "the interval excludes 0, uncorrected for the page's many comparisons: its primary "
        "comparisons are the corrected ones):\n\n" + markdown_table(head, body, "lllrlrl")
    )


def ablation_json(x: AblationResult) -> dict[str, Any]:
    out = compare.paired_json(x.result, "ablation", x.track, x.ablation.method, x.ablation.baseline)
    return {**out, "what": x.ablation.what, **({"category": x.category} if x.category else {})}


# -- training-seed spread ------------------------------------------------------------------------
SEED_MODEL = re.compile(r"seed(\d+)-[a-z0-9-]+")
"""A replicate's model name, ``seed<k>-<network>`` (``beo-bench train hbeo --recipe reference
--seed 1 --name seed1-hbeo``): the published recipe with another training seed (the
published models are seed 0). Its runs (``hbeo:model=seed1-hbeo``) are seed replicates of
the row with the same backend and the other options."""

SEED_KEYS: tuple[str, ...] = (*VERDICT_KEYS, "class_acc", "pick_success")
"""The figures a seed spread is reported for, where the runs have them."""


@dataclass(frozen=True)
class SeedSpread:
    """One learned row's figure over its training seeds: the published model's (seed 0) and
    each replicate's, on the items all of them scored (the means as each run reports them
    when the runs cover the same items)."""

    label: str
    key: str
    published: float
    seeds: tuple[tuple[int, float], ...]

    @property
    def values(self) -> list[float]:
        return [self.published, *(v for _, v in self.seeds)]

    @property
    def spread(self) -> float:
        """Max - min over the seeds, the published one included."""
        return max(self.values) - min(self.values)


def seed_spreads(rows: Sequence[Any], label: Callable[[dict[str, Any]], str]) -> list[SeedSpread]:
    """Every published row of ``rows`` (leaderboard rows of one section) with seed
    replicates among them, per figure of :data:`SEED_KEYS` that all of its runs have."""
    published: dict[str, dict[str, Any]] = {}
    replicas: dict[str, list[tuple[int, dict[str, Any]]]] = {}
    for r in rows:
        s = r.summary
        kwargs = dict(s.get("provenance", {}).get("backend_kwargs") or {})
        match = SEED_MODEL.fullmatch(str(kwargs.get("model", "")))
        if match is None:
            published[label(s)] = s
            continue
        del kwargs["model"]
        base = label({**s, "provenance": {**s.get("provenance", {}), "backend_kwargs": kwargs}})
        replicas.setdefault(base, []).append((int(match.group(1)), s))
    out: list[SeedSpread] = []
    for base, reps in replicas.items():
        pub = published.get(base)
        if pub is None or any(s.get("n") != pub.get("n") for _, s in reps):
            continue  # no published row, or other items: not a spread of the same figure
        for key in SEED_KEYS:
            runs = [pub, *(s for _, s in reps)]
            if all(key in s.get("metrics", {}) for s in runs):
                seeds = tuple(sorted((k, float(s["metrics"][key])) for k, s in reps))
                out.append(SeedSpread(base, key, float(pub["metrics"][key]), seeds))
    return out


def seed_table(spreads: Sequence[SeedSpread]) -> str:
    """Markdown: each learned row's figures at the published seed, at every other seed and
    their spread; then each pair of learned rows whose gap the seeds could make: the
    published rows' gap against the larger of their two spreads."""
    if not spreads:
        return ""
    body = []
    for x in spreads:
        spec = spec_of(x.key)
        others = ", ".join(f"{k}: {spec.format(v)}" for k, v in x.seeds)
        body.append(
            [
                x.label,
                spec.label,
                spec.format(x.published),
                others,
                spec.format_diff(x.spread).lstrip("+"),
            ]
        )
    head = ["backend", "metric", "published (seed 0)", "other seeds", "spread (max - min)"]
    lines = [
        "Training-seed spread: each learned row's figure with the published model (seed 0) "
        "and with the same recipe trained from other seeds (`seed<k>-<network>` models), on "
        "the same items. A gap between two learned rows no larger than their seed spread is "
        "not a difference between the methods, whatever its paired interval says:",
        "",
        markdown_table(head, body, "llr"),
    ]
    gaps = []
    for i, a in enumerate(spreads):
        for b in spreads[i + 1 :]:
            if a.key != b.key:
                continue
            spec, gap = spec_of(a.key), b.published - a.published
            widest = max(a.spread, b.spread)
            says = (
                "the seeds spread as far as the gap"
                if abs(gap) <= widest
                else "the gap exceeds the seed spread"
            )
            gaps.append(
                f"| {b.label} | {a.label} | {spec.label} | {spec.format_diff(gap)} "
                f"| {spec.format_diff(widest).lstrip('+')} | {says} |"
            )
    if gaps:
        lines += [
            "",
            "| method | baseline | metric | published gap | larger seed spread | |",
            "|---|---|---|---:|---:|---|",
            *gaps,
        ]
    return "\n".join(lines)
