"""No import cycles among the modules of ``pipeline``, ``simulate``, ``synth_scenes``, ``eval``.

Every ``import`` statement counts, the lazy ones inside functions too (a lazy import
hides a cycle from the interpreter, not from the reader).  The graph is built from the
source with :mod:`ast` and its strongly connected components are found with scipy; a
component of more than one module is a cycle, and every one is reported.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

REPO = Path(__file__).resolve().parents[2]
PACKAGES = ("pipeline", "simulate", "synth_scenes", "eval")



def module_name(path: Path) -> str:
    rel = path.relative_to(REPO).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def imports_of(path: Path, name: str, known: set[str]) -> set[str]:
    """Modules of ``known`` that the file imports (absolute or relative, at any depth)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                root = ".".join(base + ([node.module] if node.module else []))
            else:
                root = node.module or ""
            targets = [f"{root}.{a.name}" for a in node.names] + [root]
        for t in targets:
            # the longest known module that t names (``from pkg import mod`` names pkg.mod)
            while t and t not in known:
                t = t.rpartition(".")[0]
            if t and t != name:
                found.add(t)
    return found


def import_graph() -> dict[str, set[str]]:
    files = {module_name(p): p for pkg in PACKAGES for p in (REPO / pkg).rglob("*.py")}
    known = set(files)
    return {name: imports_of(path, name, known) for name, path in files.items()}


def import_cycles(graph: dict[str, set[str]]) -> list[set[str]]:
    """Every strongly connected component of more than one module."""
    names = sorted(graph)
    idx = {n: i for i, n in enumerate(names)}
    edges = np.array([(idx[a], idx[b]) for a, bs in graph.items() for b in bs],
                     dtype=np.int64).reshape(-1, 2)
    g = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])),
                   shape=(len(names), len(names)))
    _, label = connected_components(g, directed=True, connection="strong")
    comps = [{names[i] for i in np.flatnonzero(label == lab)} for lab in np.unique(label)]
    return [c for c in comps if len(c) > 1]


def test_the_detector_finds_a_cycle_and_a_lazy_one():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert import_cycles(graph) == [{"a", "b", "c"}]
    assert import_cycles({"a": {"b"}, "b": set()}) == []


def test_relative_and_lazy_imports_are_edges(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    src = pkg / "m.py"
    src.write_text("from . import n\ndef f():\n    from .o import x\n    import pkg.p\n")
    known = {"pkg", "pkg.m", "pkg.n", "pkg.o", "pkg.p"}
    assert imports_of(src, "pkg.m", known) == {"pkg", "pkg.n", "pkg.o", "pkg.p"}


def test_no_import_cycles():
    cycles = import_cycles(import_graph())
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(sorted(c)) for c in cycles)

