"""Every reason a pick can end with is documented in docs/env.md ("Why a pick fails"): the
literals the grasp execution, the env and the pick suite assign are read from their source,
so a new reason without a line in the docs fails here."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SOURCES = ("scenes/execute.py", "envs/pick.py", "beo_bench/bench/kinds/pick.py")
INTERNAL = {"lifted"}  # GraspOutcome's; the env reports it as success or wrong_class


def _assigned_reasons() -> set[str]:
    found: set[str] = set()
    for src in SOURCES:
        text = (ROOT / src).read_text()
        found |= set(re.findall(r'reason ?= ?"([a-z_]+)"', text))
        found |= (
            set(re.findall(r'why = "([a-z_]+)" if .* else "([a-z_]+)"', text)[0])
            if ("why = " in text)
            else set()
        )
    return found - INTERNAL


def _documented_reasons() -> set[str]:
    text = (ROOT / "docs/env.md").read_text()
    section = text[text.index("### Why a pick fails") :]
    section = section[: section.index("\n## ")]
    return set(re.findall(r"^\| `([a-z_]+)` \|", section, flags=re.M))


def test_every_pick_reason_is_documented() -> None:
    assigned = _assigned_reasons()
    assert {"success", "no_grasp", "empty_shape", "pregrasp_in_collision", "timeout"} <= assigned
    missing = assigned - _documented_reasons()
    assert not missing, f"document these pick reasons in docs/env.md: {sorted(missing)}"
