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


NAME = re.compile(r"`(beo_bench(?:\.\w+)+)`")


def _public_names() -> list[str]:
    """The dotted names in backticks of the page's "Public names" section."""
    text = DESIGN.read_text()
    section = text[text.index("## Public names\n") :]
    section = section[: section.index("\n## ", 1)]
    return sorted(set(NAME.findall(section)))


def _resolve(dotted: str) -> object:
    """The object ``dotted`` names: its longest importable module prefix, then attributes."""
    import importlib

    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj: object = importlib.import_module(".".join(parts[:cut]))
        except ModuleNotFoundError:
            continue
        for attr in parts[cut:]:
            obj = getattr(obj, attr)  # AttributeError: the page names what is not there
        return obj
    raise ModuleNotFoundError(dotted)


def test_every_stable_name_in_design_md_imports() -> None:
    names = _public_names()
    # the plugin contract is among them
    for must in ("beo_bench.types.View", "beo_bench.types.Estimate", "beo_bench.backend.Backend"):
        assert must in names
    assert "beo_bench.perception.means.class_means" in names
    unresolved = []
    for dotted in names:
        try:
            _resolve(dotted)
        except (ImportError, AttributeError) as e:
            unresolved.append(f"{dotted} ({type(e).__name__}: {e})")
    assert not unresolved, f"docs/design.md lists stable names that do not import: {unresolved}"
    # and only objects: a dotted name that resolves to a module is a path, not a name
    import types

    assert not [n for n in names if isinstance(_resolve(n), types.ModuleType)]


def test_the_stable_names_checker_sees_a_wrong_name() -> None:
    import pytest

    with pytest.raises(AttributeError):
        _resolve("beo_bench.types.NoSuchView")
    assert NAME.findall("`beo_bench.types.View` and `View`") == ["beo_bench.types.View"]


def _statuses(text: str, start: str) -> list[int]:
    """The exit statuses listed in ``text``'s parenthesis that follows ``start``."""
    span = text[text.index(start) + len(start) :]
    return [int(n) for n in re.findall(r"(?<![\w-])(\d+)\b", span[: span.index(")")])]


def test_the_stable_exit_statuses_are_the_clis() -> None:
    """docs/design.md's stable exit statuses are the ones ``beo-bench --help`` lists (the CLI
    module's docstring), 3 (a regression, ``--max-failure-rate``) among them."""
    from beo_bench import cli

    page = _statuses(" ".join(DESIGN.read_text().split()), "and the exit statuses (")
    assert cli.__doc__
    listed = [int(n) for n in re.findall(r"\b(\d+) (?:on|when)\b", cli.EXIT_STATUS)]
    assert page == listed == [0, 1, 2, 3, 130], (page, listed)
