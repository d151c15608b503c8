"""Item kinds: one module per :class:`~beo_bench.bench.suites.Kind`, found by :func:`get_kind`.

Each module owns what differs between kinds: the class list its views carry
(``categories``), its items without a backend (``open``: views, truths, the rows known
before the backend is called), scoring one item with a backend (``run_item``), the rows of
an item whose backend never answered (``failed_rows``), and its summary metrics
(``view_values``, ``collect``, ``timing``, ``worst_cases``). The runner, the worker pool,
the evaluator and the summary dispatch through :func:`get_kind` alone; none of them compares
a kind or a protocol.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from beo_bench.bench.kinds import isolated, pick, tabletop
from beo_bench.bench.suites import Kind, Suite

if TYPE_CHECKING:
    from beo_bench.bench.evaluate import Evaluator
    from beo_bench.bench.kinds.common import Items
    from beo_bench.bench.tally import Tally

Rows = list[dict[str, Any]]


class ItemKind(Protocol):
    """What a kind module provides (each of :mod:`.isolated`, :mod:`.tabletop`,
    :mod:`.pick`)."""

    KIND: Kind

    def categories(self, suite: Suite) -> tuple[str, ...]: ...

    def open(self, suite: Suite, class_given: bool = False) -> Items: ...

    def run_item(self, ev: Evaluator, index: int, announce: Callable[[Rows], None]) -> Rows: ...

    def failed_rows(self, templates: Rows, reason: str) -> Rows: ...

    def view_values(self, suite: Suite, rows: Rows) -> dict[str, np.ndarray]: ...

    def collect(self, M: Tally, rows: Rows, values: dict[str, np.ndarray]) -> None: ...

    def timing(self, M: Tally, rows: Rows) -> None: ...

    def worst_cases(self, suite: Suite) -> dict[str, float]: ...


KINDS: dict[Kind, ItemKind] = {
    Kind.ISOLATED: isolated,
    Kind.TABLETOP: tabletop,
    Kind.PICK: pick,
}


def get_kind(kind: Kind | str) -> ItemKind:
    """The module of item kind ``kind``."""
    return KINDS[Kind(kind)]
