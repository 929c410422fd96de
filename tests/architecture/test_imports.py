"""Hearth's packages are floors: a module imports from its own floor or the ones below, and no
two modules import each other, directly or round a loop (docs/architecture.md).

Every import counts, the ones inside functions too (a deferred import is still a dependency;
it only moves the failure to run time). Imports under ``if TYPE_CHECKING:`` do not: they never
run.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2] / "hearth"

#: Bottom first. A package may import from its own floor and every floor below.
FLOORS = [
    ("hearth", "hearth.util"),
    ("hearth.worldmodel",),
    ("hearth.perception",),
    ("hearth.robot",),
    ("hearth.skills",),
    ("hearth.mapping",),
    ("hearth.executive",),
    ("hearth.benchmarks",),
    ("hearth.cli",),
]
FLOOR = {pkg: i for i, pkgs in enumerate(FLOORS) for pkg in pkgs}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def package_of(module: str) -> str:
    if module == "hearth.__main__":          # ``python -m hearth``: the command line
        return "hearth.cli"
    parts = module.split(".")
    return ".".join(parts[:2]) if len(parts) > 1 and ".".join(parts[:2]) in FLOOR else "hearth"


def _type_checking_only(node: ast.AST, parents: dict) -> bool:
    while node in parents:
        node = parents[node]
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            return True
    return False


def imports_of(path: Path, modules: set[str]) -> set[str]:
    """The Hearth modules ``path`` imports (a ``from package import name`` that names a module
    counts as that module)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    parents = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
    me = module_name(path)
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                pkg = me.split(".") if path.name == "__init__.py" else me.split(".")[:-1]
                pkg = pkg[:len(pkg) - node.level + 1]
                base = ".".join(pkg + ([base] if base else []))
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                     for a in node.names]
        else:
            continue
        if _type_checking_only(node, parents):
            continue
        for name in names:
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name and name.startswith("hearth") and name != me:
                found.add(name)
    return found


def graph() -> dict[str, set[str]]:
    files = [p for p in ROOT.rglob("*.py") if "__pycache__" not in p.parts
             and not {"missions", "data"} & set(p.relative_to(ROOT).parts)]
    modules = {module_name(p) for p in files}
    return {module_name(p): imports_of(p, modules) for p in files}


def import_cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan's algorithm; a graph
    this small needs no library)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def test_every_package_has_a_floor():
    packages = {p.parent for p in ROOT.rglob("__init__.py") if "__pycache__" not in p.parts}
    tops = {".".join(p.relative_to(ROOT.parent).parts[:2]) for p in packages if p != ROOT}
    assert tops <= set(FLOOR), f"packages with no floor in this test: {sorted(tops - set(FLOOR))}"


def test_no_import_goes_up_a_floor():
    upward = sorted(f"{a} imports {b}" for a, bs in graph().items() for b in bs
                    if FLOOR[package_of(b)] > FLOOR[package_of(a)])
    assert upward == [], "\n".join(upward)


def test_no_import_circles():
    cycles = import_cycles(graph())
    assert cycles == [], "\n".join(" <-> ".join(c) for c in cycles)


def test_the_reader_finds_a_circle_and_an_upward_import():
    assert import_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert import_cycles({"a": {"b"}, "b": set()}) == []
    assert FLOOR[package_of("hearth.cli.main")] > FLOOR[package_of("hearth.worldmodel.io")]


@pytest.mark.parametrize("name", ["executive", "skills", "perception", "worldmodel", "robot"])
def test_only_hearth_is_a_top_level_package(name):
    assert not (ROOT.parent / name / "__init__.py").exists()
