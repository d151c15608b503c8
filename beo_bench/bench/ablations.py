"""The leaderboard's ablation pairs: one backend against a variant of itself, paired on the
items both runs scored (the variant may cover a prefix of the suite, as ``beo
(pose_prior=false)`` covers 300 of ``pose-3dof``'s 1000 views).

These are the comparisons the docs quote (the silhouette prior of HBEO-MDN, BEO's viewpoint
prior); the leaderboard writes them into ``<suite>_paired.json`` beside the baseline
verdicts (``"pairing": "ablation"``), so every paired interval in the docs comes from a
committed file that ``beo-bench leaderboard`` regenerates.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from beo_bench.bench import compare
from beo_bench.bench.columns import VERDICT_KEYS
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


def ablation_results(
    track: str | None,
    rows: Sequence[Any],
    label: Callable[[dict[str, Any]], str],
    ablations: Sequence[Ablation] = ABLATIONS,
) -> list[AblationResult]:
    """Each ablation whose two runs are among ``rows`` (leaderboard rows of one track and
    seed, with ``summary`` and ``path``), paired on their common items."""
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
        except UsageError:  # not pairable (other items or scoring): no result
            continue
        out += [AblationResult(ab, track, r) for r in results]
    return out


def ablation_table(results: Sequence[AblationResult]) -> str:
    """Markdown: a row per ablation and metric, method - baseline [95%] and the verdict."""
    if not results:
        return ""
    lines = [
        "Ablations (exploratory: a backend against a variant of itself, paired on the items "
        "both scored; 95% bootstrap intervals that resample items; *better* / *worse* when "
        "the interval excludes 0, uncorrected for the page's many comparisons: its primary "
        "comparisons are the corrected ones):",
        "",
        "| method | baseline | what it isolates | items | metric | method - baseline [95%] "
        "| verdict, uncorrected |",
        "|---|---|---|---:|---|---:|---|",
    ]
    for x in results:
        r, spec = x.result, x.result.spec
        diff = f"{spec.format_diff(r.diff)} [{spec.format_diff(r.lo)}, {spec.format_diff(r.hi)}]"
        verdict = f"**{r.verdict}**" if r.verdict != "no difference" else r.verdict
        lines.append(
            f"| {x.ablation.method} | {x.ablation.baseline} | {x.ablation.what} | {r.n_items} "
            f"| {spec.label} | {diff} | {verdict} |"
        )
    return "\n".join(lines)


def ablation_json(x: AblationResult) -> dict[str, Any]:
    out = compare.paired_json(x.result, "ablation", x.track, x.ablation.method, x.ablation.baseline)
    return {**out, "what": x.ablation.what}
