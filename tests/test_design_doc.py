"""docs/design.md matches the code: every module path it names exists, and every section of
it that the code cites ("docs/design.md "Section"") is one of its headings."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "docs" / "design.md"
SOURCES = ("beo_bench", "envs", "scenes", "perception", "benchmarks", "tests")


PATH = re.compile(r"`((?:beo_bench|envs|scenes|perception|tests|benchmarks)/[\w./]*)`")


def _paths(text: str) -> list[str]:
    """Module and folder paths ``text`` names in backticks (``beo_bench/x.py``, ``scenes/``)."""
    return sorted(set(PATH.findall(text)))


def test_every_module_path_named_in_design_md_exists() -> None:
    paths = _paths(DESIGN.read_text())
    assert len(paths) > 30  # the page's table of where each concept lives is there
    missing = [p for p in paths if not (ROOT / p).exists()]
    assert not missing, f"docs/design.md names paths that do not exist: {missing}"


def test_the_checker_sees_a_wrong_path() -> None:
    # what the test above reads paths with finds a path that does not exist
    found = _paths("a `beo_bench/bench/nothing_here.py` and `scenes/`, not `beo_bench.bench`")
    assert found == ["beo_bench/bench/nothing_here.py", "scenes/"]
    assert not (ROOT / found[0]).exists()


def _headings() -> list[str]:
    return [
        line.lstrip("#").strip() for line in DESIGN.read_text().splitlines() if line.startswith("#")
    ]


def test_every_section_the_code_cites_is_a_heading() -> None:
    headings = _headings()
    cited: set[tuple[str, str]] = set()
    for folder in SOURCES:
        for f in (ROOT / folder).rglob("*.py"):
            if f == Path(__file__).resolve():
                continue  # this file's docstring shows the form
            text = f.read_text()
            for m in re.finditer(r'docs/design\.md[^"\n]{0,12}"([^"]+)"', text):
                cited.add((" ".join(m.group(1).split()), str(f.relative_to(ROOT))))
    assert cited
    bad = [
        (section, where)
        for section, where in sorted(cited)
        if not any(h == section or h.startswith(section + " ") for h in headings)
    ]
    assert not bad, f"the code cites sections of docs/design.md that it lacks: {bad}"
