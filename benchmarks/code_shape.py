"""The shape of the package's code: its lines and the tests', its largest modules (object
categories apart) and functions, its imports inside functions, and its import cycles (as
``tests/test_import_graph.py`` counts them, and again counting ``if TYPE_CHECKING:`` imports),
for this checkout or another one.

    python benchmarks/code_shape.py [ROOT] [--top N]
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

import networkx as nx

FOLDERS = ("beo_bench", "envs", "scenes", "perception")


def functions(root: Path) -> tuple[int, list[tuple[int, str]]]:
    """(lines of the package, [(lines, "path:function")] largest first)."""
    total, out = 0, []
    for folder in FOLDERS:
        for f in sorted((root / folder).rglob("*.py")):
            src = f.read_text()
            total += len(src.splitlines())
            for node in ast.walk(ast.parse(src)):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    assert node.end_lineno is not None
                    size = node.end_lineno - node.lineno + 1
                    out.append((size, f"{f.relative_to(root)}:{node.name}"))
    return total, sorted(out, reverse=True)


def modules(root: Path) -> list[tuple[int, str]]:
    """[(lines, path)] of the package's modules that are not an object category (a category
    is one file per class by design), largest first."""
    sys.path.insert(0, str(root))
    from beo_bench.objects.registry import categories

    out = []
    for folder in FOLDERS:
        for f in sorted((root / folder).rglob("*.py")):
            if f.parent == root / "beo_bench" / "objects" and f.stem in categories():
                continue
            out.append((len(f.read_text().splitlines()), str(f.relative_to(root))))
    return sorted(out, reverse=True)


def test_lines(root: Path) -> int:
    return sum(len(f.read_text().splitlines()) for f in (root / "tests").rglob("*.py"))


def inner_imports(root: Path) -> int:
    """Import statements inside a function (``def``) body."""
    n = 0
    for folder in FOLDERS:
        for f in sorted((root / folder).rglob("*.py")):
            for node in ast.walk(ast.parse(f.read_text())):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    n += sum(
                        isinstance(c, (ast.Import, ast.ImportFrom))
                        for c in ast.walk(node)
                        if c is not node
                    )
    return n


def cycles(root: Path, type_checking: bool = False) -> list[list[str]]:
    """The import graph's strongly connected components of more than one module (with the
    ``if TYPE_CHECKING:`` imports as edges too when ``type_checking``)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests import test_import_graph as graph

    graph.PACKAGES = {
        "beo_bench": root / "beo_bench",
        "beo_bench.envs": root / "envs",
        "beo_bench.scenes": root / "scenes",
        "beo_bench.perception": root / "perception",
    }
    G = graph.import_graph(type_checking)
    return sorted(sorted(c) for c in nx.strongly_connected_components(G) if len(c) > 1)


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("root", nargs="?", type=Path, default=Path(__file__).resolve().parents[1])
    p.add_argument("--top", type=int, default=10)
    args = p.parse_args(argv)
    total, funcs = functions(args.root)
    print(f"package lines: {total}")
    print(f"test lines: {test_lines(args.root)}")
    print(f"imports inside functions: {inner_imports(args.root)}")
    mods = modules(args.root)
    print(f"largest modules, object categories apart (of {len(mods)}):")
    for n, name in mods[: args.top]:
        print(f"  {n:5d}  {name}")
    print(f"largest functions (of {len(funcs)}):")
    for n, name in funcs[: args.top]:
        print(f"  {n:5d}  {name}")
    for label, tc in (("import cycles", False), ("import cycles with TYPE_CHECKING", True)):
        found = cycles(args.root, tc)
        print(f"{label}: {len(found)}")
        for c in found:
            print("  " + " <-> ".join(c))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
