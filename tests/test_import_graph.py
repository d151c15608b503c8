"""The package's import graph: no import cycles (counting imports inside functions, which
run as surely as the module's own; imports under ``if TYPE_CHECKING:`` are for the type
checker only), and the layer rules of docs/design.md ("Layers")."""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {
    "beo_bench": ROOT / "beo_bench",
    "beo_bench.envs": ROOT / "envs",
    "beo_bench.scenes": ROOT / "scenes",
    "beo_bench.perception": ROOT / "perception",
}


def modules() -> dict[str, Path]:
    out = {}
    for pkg, folder in PACKAGES.items():
        for f in folder.rglob("*.py"):
            parts = list(f.relative_to(folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([pkg, *parts])] = f
    return out


def _type_checking_only(node: ast.AST) -> bool:
    if not isinstance(node, ast.If):
        return False
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST, type_checking: bool = False) -> list[ast.Import | ast.ImportFrom]:
    """Every import statement that runs, and those under ``if TYPE_CHECKING:`` too when
    ``type_checking``."""
    out: list[ast.Import | ast.ImportFrom] = []
    stack = [tree]
    while stack:
        node = stack.pop()
        if _type_checking_only(node) and not type_checking:
            stack.extend(node.orelse)  # type: ignore[attr-defined]
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            out.append(node)
        stack.extend(ast.iter_child_nodes(node))
    return out


def import_graph(type_checking: bool = False) -> nx.DiGraph:
    mods = modules()

    def owner(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    G = nx.DiGraph()
    for m, f in mods.items():
        G.add_node(m)
        package = m if f.name == "__init__.py" else m.rpartition(".")[0]
        for node in _imports(ast.parse(f.read_text()), type_checking):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                base = node.module or ""
                if node.level:
                    parts = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                    base = ".".join(parts + ([base] if base else []))
                targets = [
                    f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names
                ]
            for t in targets:
                o = owner(t) if t.startswith("beo_bench") else None
                if o and o != m:
                    G.add_edge(m, o)
    return G


def test_the_package_has_no_import_cycles() -> None:
    # the imports under ``if TYPE_CHECKING:`` count too: a cycle there is a contract that
    # knows its caller (docs/design.md "Layers")
    G = import_graph(type_checking=True)
    cycles = sorted(sorted(c) for c in nx.strongly_connected_components(G) if len(c) > 1)
    assert not cycles, f"import cycles: {cycles}"


def test_the_graph_sees_function_level_imports() -> None:
    # the checker itself: a lazy import inside a function is an edge
    G = import_graph()
    assert G.has_edge("beo_bench.bench.kinds.tabletop", "beo_bench.envs.pick")


LAYERS = [
    # (modules under this prefix, prefixes they must never import)
    ("beo_bench.perception", ("beo_bench.envs", "beo_bench.bench", "beo_bench.cli")),
    ("beo_bench.scenes", ("beo_bench.envs", "beo_bench.bench", "beo_bench.perception")),
    ("beo_bench.objects", ("beo_bench.scenes", "beo_bench.envs", "beo_bench.bench")),
    (
        "beo_bench.bop",
        ("beo_bench.bench", "beo_bench.perception", "beo_bench.envs", "beo_bench.cli"),
    ),
    ("beo_bench.metrics", ("beo_bench.bench", "beo_bench.perception", "beo_bench.envs")),
    ("beo_bench.stats", ("beo_bench.bench", "beo_bench.perception", "beo_bench.envs")),
    ("beo_bench.types", ("beo_bench.bench", "beo_bench.perception", "beo_bench.envs")),
    ("beo_bench.envs", ("beo_bench.bench", "beo_bench.perception", "beo_bench.cli")),
    ("beo_bench.bench", ("beo_bench.cli",)),
]


@pytest.mark.parametrize(("layer", "never"), LAYERS, ids=[layer for layer, _ in LAYERS])
def test_layer_rules(layer: str, never: tuple[str, ...]) -> None:
    G = import_graph()
    bad = [
        (m, t)
        for m, t in G.edges
        if (m == layer or m.startswith(layer + "."))
        and any(t == n or t.startswith(n + ".") for n in never)
    ]
    assert not bad, f"{layer} imports what it must not: {bad}"
