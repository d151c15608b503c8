"""Item kinds: one module per :class:`~beo_bench.bench.suites.Kind`, found by :func:`get_kind`.

Each module owns what differs between kinds and says so in one
:class:`~beo_bench.bench.kinds.common.ItemKind`: the class list its views carry
(``categories``), its items without a backend (``open``: views, truths, the rows known
before the backend is called), scoring one item with a backend (``run_item``), the rows of
an item whose backend never answered (``failed_rows``), and its summary metrics
(``view_values``, ``collect``, ``timing``, ``worst_cases``); isolated and tabletop items,
each view scored on its estimate, keep the defaults. The runner, the worker pool,
the evaluator and the summary dispatch through :func:`get_kind` alone; none of them compares
a kind or a protocol.
"""

from __future__ import annotations

from beo_bench.bench.kinds.common import ItemKind
from beo_bench.bench.kinds.isolated import ISOLATED
from beo_bench.bench.kinds.pick import PICK
from beo_bench.bench.kinds.tabletop import TABLETOP
from beo_bench.bench.suites import Kind

__all__ = ["KINDS", "ItemKind", "get_kind"]

KINDS: dict[Kind, ItemKind] = {k.kind: k for k in (ISOLATED, TABLETOP, PICK)}


def get_kind(kind: Kind | str) -> ItemKind:
    """What item kind ``kind`` does (its module's :class:`ItemKind`)."""
    return KINDS[Kind(kind)]
