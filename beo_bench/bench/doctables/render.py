"""The results tables of the README and docs/results.md, made from ``leaderboards/*.json``.

A page marks each generated table with ``<!-- table: NAME -->`` ... ``<!-- /table -->``;
``python -m beo_bench.bench.doctables README.md docs/results.md`` rewrites what lies between
the marks (and nothing else), and ``tests/test_doc_figures.py`` checks that every marked
table equals what the committed leaderboards give, so no figure in them can go stale. The
dissertation's own figures are citations (chapter and table), written here once.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable
from pathlib import Path

from beo_bench.bench.doctables.boards import MARK, Boards, MissingFigureError, PendingSuiteError
from beo_bench.bench.doctables.dissertation import (
    beo_figures,
    dissertation,
    hbeo_detail,
    modelnet10,
    modelnet10_chapter4,
    modelnet10_headroom,
    modelnet10_viewpoints,
    ood,
    pick_models,
    ref_accuracy,
)
from beo_bench.bench.doctables.orderings import interval_widths, orderings, primary_declared
from beo_bench.bench.doctables.pick import (
    pick_audit,
    pick_pairs,
    pick_robust,
    pick_sensitivity,
    pick_tolerance,
    pick_vs_error,
)
from beo_bench.bench.doctables.pose import (
    beo_prior,
    class_given,
    headline,
    mdn_prior_table,
    prior_ablation,
    rest_prior,
    shape_selection,
    swap,
)
from beo_bench.bench.doctables.sensors import (
    ROBUSTNESS_CELLS,
    ROBUSTNESS_MORE_CELLS,
    bop_figures,
    robustness_table,
)

TABLES: dict[str, Callable[[Boards], str]] = {
    "robustness": robustness_table(ROBUSTNESS_CELLS),
    "robustness-more": robustness_table(ROBUSTNESS_MORE_CELLS),
    "bop-figures": bop_figures,
    "ref-accuracy": ref_accuracy,
    "pick-models": pick_models,
    "beo-figures": beo_figures,
    "headline": headline,
    "class-given": class_given,
    "beo-prior": beo_prior,
    "mdn-prior": mdn_prior_table("pose-3dof"),
    "mdn-prior-modelnet10": mdn_prior_table("modelnet10-3dof"),
    "swap": swap,
    "prior-ablation": prior_ablation(per_category=False),
    "prior-ablation-percat": prior_ablation(per_category=True),
    "shape-selection": shape_selection,
    "pick-pairs": pick_pairs,
    "pick-sensitivity": pick_sensitivity,
    "pick-vs-error": pick_vs_error,
    "pick-tolerance": pick_tolerance,
    "pick-audit": pick_audit,
    "pick-robust": pick_robust,
    "rest-prior": rest_prior,
    "ood": ood,
    "hbeo-detail": hbeo_detail,
    "dissertation": dissertation,
    "modelnet10": modelnet10,
    "modelnet10-viewpoints": modelnet10_viewpoints,
    "modelnet10-headroom": modelnet10_headroom,
    "modelnet10-chapter4": modelnet10_chapter4,
    "interval-widths": interval_widths,
    "orderings": orderings,
    "primary-comparisons": primary_declared,
}


def render(text: str, boards: Boards) -> str:
    """``text`` with every marked table regenerated (an unknown name is an error)."""

    def one(m: re.Match[str]) -> str:
        name = m.group(2)
        if name not in TABLES:
            raise MissingFigureError(
                f"no generated table named {name!r}: use one of {sorted(TABLES)}"
            )
        try:
            table = TABLES[name](boards)
        except PendingSuiteError as e:
            # a campaign run suite by suite (`all --update`) fills the leaderboards over
            # several sessions: until the rows are there the table says so, it never shows
            # another version's figures
            table = PENDING.format(reason=e)
        return m.group(1) + table + m.group(4)

    return MARK.sub(one, text)


PENDING = (
    "*Not in this suite version's leaderboards yet ({reason}); `beo-bench all --update "
    "--suites SUITE` makes its runs and this table.*\n"
)
"""What a generated table says while the leaderboards lack a row it needs."""


def main(argv: list[str] | None = None) -> int:
    """Rewrite the marked tables of the files given, from ``leaderboards/``."""
    args = sys.argv[1:] if argv is None else argv
    boards = Boards(Path("leaderboards"))
    for name in args:
        path = Path(name)
        new = render(path.read_text(), boards)
        if new != path.read_text():
            from beo_bench.atomic import atomic_write_bytes

            atomic_write_bytes(path, new.encode())
            print(f"rewrote the tables of {path}")
    return 0
