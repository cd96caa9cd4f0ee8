"""The packages' imports run one way: no package imports one that imports it back, function-level imports included
(read with ast, not by importing), so that a stage added later cannot tie two orchestrators together again."""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def room(module: str) -> str | None:
    """The room a dotted module name belongs to: ``cosco``, a sub-package of twinreg (``twinreg.city.build`` ->
    ``city``), or a top-level module of twinreg (``twinreg.pipeline`` -> ``pipeline``); None for anything else.

    >>> room("twinreg.city.build"), room("twinreg.pipeline"), room("cosco.symmetry"), room("numpy")
    ('city', 'pipeline', 'cosco', None)
    """
    parts = module.split(".")
    if parts[0] == "cosco":
        return "cosco"
    if parts[0] != "twinreg" or len(parts) < 2:
        return None
    name = parts[1]
    if (REPO / "twinreg" / name).is_dir() or (REPO / "twinreg" / f"{name}.py").is_file():
        return name
    return None  # a name imported from twinreg's __init__


def imports(path: Path) -> set[str]:
    """Every module ``path`` imports, at any depth of its body, resolved to dotted names."""
    rel = path.relative_to(REPO).with_suffix("")
    parts = list(rel.parts)
    package = parts[:-1] if parts[-1] != "__init__" else parts[:-1]
    if parts[-1] == "__init__":
        parts = parts[:-1]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.add(mod)
            out |= {f"{mod}.{a.name}" for a in node.names}
    return out


def graph() -> dict:
    """{room: {room it imports: [modules that do]}}."""
    edges: dict = {}
    for path in sorted([*(REPO / "twinreg").rglob("*.py"), *(REPO / "cosco").rglob("*.py")]):
        rel = path.relative_to(REPO).with_suffix("")
        src = room(".".join(p for p in rel.parts if p != "__init__"))
        for mod in imports(path):
            dst = room(mod)
            if dst and src and dst != src and dst != "twinreg":
                edges.setdefault(src, {}).setdefault(dst, []).append(".".join(rel.parts))
    return edges


def cycles(edges: dict) -> list[list[str]]:
    """The strongly connected groups of more than one room (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, {}):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(sorted(group))

    for v in list(edges):
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b": []}, "b": {"c": []}, "c": {"a": []}, "d": {"a": []}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b": []}, "b": {}}) == []


def test_no_package_imports_one_that_imports_it_back():
    edges = graph()
    assert "city" in edges and "pipeline" in edges  # the graph was read
    found = cycles(edges)
    detail = [f"{a} -> {b} ({', '.join(sorted(set(edges[a][b]))[:3])})" for group in found for a in group
              for b in group if b in edges.get(a, {})]
    assert not found, detail


def test_cosco_imports_nothing_of_twinreg():
    assert "cosco" not in graph() or not graph()["cosco"]


def cosco_graph() -> dict:
    """{cosco module: {cosco module it imports: [files that do]}}, function-level imports included; a sub-package
    (``cosco.ground``, ``cosco.segment``) is one node, its files' imports its own."""
    edges: dict = {}
    names = {p.stem for p in (REPO / "cosco").glob("*.py")}
    names |= {p.parent.name for p in (REPO / "cosco").glob("*/__init__.py")}
    for path in sorted((REPO / "cosco").rglob("*.py")):
        rel = path.relative_to(REPO / "cosco").with_suffix("").parts
        node = rel[0]
        if node == "__init__":
            continue
        for mod in imports(path):
            parts = mod.split(".")
            if parts[0] == "cosco" and len(parts) > 1 and parts[1] in names and parts[1] != node:
                edges.setdefault(node, {}).setdefault(parts[1], []).append("/".join(rel))
    return edges


def test_no_cosco_module_imports_one_that_imports_it_back():
    edges = cosco_graph()
    assert "symmetry" in edges and "segment" in edges and "ground" in edges  # the graph was read, packages too
    found = cycles(edges)
    assert not found, [f"{a} -> {b}" for group in found for a in group for b in group if b in edges.get(a, {})]


def test_migrations_are_self_contained():
    """A migration must not change when the code does: it imports alembic, SQLAlchemy and numpy, never cosco or
    twinreg."""
    for path in sorted((REPO / "migrations" / "versions").glob("*.py")):
        used = {m.split(".")[0] for m in imports(path)}
        assert not used & {"cosco", "twinreg"}, path.name
