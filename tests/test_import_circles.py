"""No import circle among the project's modules: a module never imports, directly
or through others, a module that imports it back. The import graph is grimp's (installed
with import-linter); imports under ``if TYPE_CHECKING:`` count too, since a circle hidden
behind them is still a circle in the design. Package-level contracts (layers, no upward
imports) are import-linter's, in .importlinter.
"""
from __future__ import annotations

import grimp

PACKAGES = ("envs", "algorithms", "bench", "reports", "studies")


def strongly_connected(graph: grimp.ImportGraph) -> list[list[str]]:
    """Tarjan's strongly connected components of more than one module (iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    for root in sorted(graph.modules):
        if root in index:
            continue
        work = [(root, iter(sorted(graph.find_modules_directly_imported_by(root))))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.find_modules_directly_imported_by(child)))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    m = stack.pop()
                    on_stack.discard(m)
                    comp.append(m)
                    if m == node:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def test_strongly_connected__finds_a_planted_circle() -> None:
    graph = grimp.ImportGraph()
    for a, b in (("p.a", "p.b"), ("p.b", "p.c"), ("p.c", "p.a"), ("p.c", "p.d")):
        graph.add_import(importer=a, imported=b)
    assert strongly_connected(graph) == [["p.a", "p.b", "p.c"]]


def test_no_import_circle_among_the_packages_modules() -> None:
    graph = grimp.build_graph(*PACKAGES)
    circles = strongly_connected(graph)
    assert not circles, "import circles (each a set of modules importing each other): " + "; ".join(
        " <-> ".join(c) for c in circles)
