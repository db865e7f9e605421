"""The packages form layers that import one way (DESIGN.md, "Layers").

Every import of every module is read from its source, deferred ones inside functions
included, and mapped to the package it reaches. A package may import its own layer and the
layers below it; an import that reaches up, or a cycle between packages, fails here."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "maniskill_tidy"

# lowest first; the entry points (the package root's facade, the CLI, the bench) are on top
LAYERS = [
    "common",
    "knowledge",
    "houses",
    "tasks",
    "assets",
    "sim",
    "envs",
    "perception",
    "models",
    "policies",
    "recording",
    "eval",
    "training",
    "cli",
    "bench",
    "",  # maniskill_tidy/__init__.py
]


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def is_module(name: str) -> bool:
    path = PACKAGE.parent.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def imported_modules(source: str, me: str, package: bool = False) -> list[tuple[str, int]]:
    """(module, line) for every maniskill_tidy module that module ``me`` imports, at any
    depth; ``package``: ``me`` is a package's ``__init__``."""
    base = me.split(".") if package else me.split(".")[:-1]
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            start = base[: len(base) - node.level + 1] if node.level else []
            module = ".".join(start + ([node.module] if node.module else []))
            # `from pkg import sub` reaches pkg.sub when sub is a module, else pkg itself
            subs = [f"{module}.{a.name}" for a in node.names]
            names = [s if is_module(s) else module for s in subs]
        else:
            continue
        for name in names:
            if name.split(".")[0] != "maniskill_tidy":
                continue
            while not is_module(name):  # `import a.b.c` of a name inside a module
                name = name.rsplit(".", 1)[0]
            found.append((name, node.lineno))
    return found


def package_edges() -> dict[tuple[str, str], list[str]]:
    edges: dict[tuple[str, str], list[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        me = module_name(path)
        for target, line in imported_modules(path.read_text(), me, path.name == "__init__.py"):
            a, b = layer(me), layer(target)
            if a != b:
                rel = path.relative_to(PACKAGE.parent)
                edges.setdefault((a, b), []).append(f"{rel}:{line} imports {target}")
    return edges


def test_every_package_has_a_layer():
    packages = {layer(module_name(p)) for p in PACKAGE.rglob("*.py")}
    assert packages <= set(LAYERS), f"add {sorted(packages - set(LAYERS))} to LAYERS"


def test_no_import_reaches_up():
    rank = {name: i for i, name in enumerate(LAYERS)}
    upward = [
        where for (a, b), wheres in package_edges().items() if rank[b] > rank[a] for where in wheres
    ]
    assert not upward, "imports that reach up a layer:\n" + "\n".join(upward)


def test_no_cycle_between_packages():
    import networkx as nx

    graph = nx.DiGraph(list(package_edges()))
    cycles = list(nx.simple_cycles(graph))
    assert not cycles, f"package cycles: {cycles}"


@pytest.mark.parametrize(
    "source, expected",
    [
        ("from maniskill_tidy.eval.runner import run_dir\n", "maniskill_tidy.eval.runner"),
        ("from maniskill_tidy import assets\n", "maniskill_tidy.assets"),
        ("def f():\n    from ..eval import runner\n", "maniskill_tidy.eval.runner"),
    ],
)
def test_the_reader_sees_deferred_relative_and_submodule_imports(source, expected):
    """The reader itself: a reader that missed imports would let any code pass."""
    found = imported_modules(source, "maniskill_tidy.policies.probe")
    assert [m for m, _ in found] == [expected]
