"""The packages depend on each other one way: a graph of the imports, read
from the source, has no cycle, and the science imports nothing of the service."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path) -> set[str]:
    """Every module ``path`` imports (absolute names), at any depth of its code."""
    name, package = module_name(path), path.name == "__init__.py"
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if package else name.split(".")[:-1]
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            out.add(target)
            out.update(f"{target}.{a.name}" for a in node.names)
    return out


def package_of(module: str, top: str) -> str | None:
    """The package directly under ``top`` that holds ``module`` (or the top-level module itself)."""
    parts = module.split(".")
    if parts[0] != top or len(parts) < 2:
        return None
    candidate = ROOT / top / parts[1]
    return f"{top}.{parts[1]}" if candidate.is_dir() or candidate.with_suffix(".py").exists() else None


def package_graph(top: str) -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    for path in (ROOT / top).rglob("*.py"):
        source = package_of(module_name(path), top)
        if source is None:
            continue
        for target in imports(path):
            dest = package_of(target, top)
            if dest is not None and dest != source:
                graph.setdefault(source, set()).add(dest)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one package (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while (w := stack.pop()) != v:
                on_stack.discard(w)
                component.append(w)
            on_stack.discard(v)
            if component:
                found.append(sorted([v, *component]))

    for v in list(graph):
        if v not in index:
            visit(v)
    return found


@pytest.mark.parametrize("top", ["calib_core", "backend"])
def test_packages_import_each_other_one_way(top):
    assert cycles(package_graph(top)) == []


def test_the_graph_sees_a_cycle_when_there_is_one():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_calib_core_imports_nothing_of_the_service():
    offenders = sorted(module_name(p) for p in (ROOT / "calib_core").rglob("*.py")
                       if any(m.split(".")[0] == "backend" for m in imports(p)))
    assert offenders == []
