"""The project's imports as a graph, read from the source (no module is imported): cycles between modules, the
direction between packages, and a Mermaid picture of the layers for the architecture page.

Every ``import`` counts, also those inside functions (a lazy import is still a dependency).
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The packages from the bottom layer up: a package may import only packages on its left.
LAYERS = ("core", "ppm", "hrtf_dsp", "mesh2hrtf_io", "amt_bridge", "stitching", "listener", "demo", "reporting", "pipeline")


def module_files(root: Path = ROOT, packages: tuple[str, ...] = LAYERS) -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` of ``packages`` (a package's ``__init__`` by its name)."""
    modules = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            name = ".".join(path.relative_to(root).with_suffix("").parts)
            modules[name.removesuffix(".__init__")] = path
    return modules


def _targets(module: str, path: Path, node: ast.AST, known: dict[str, Path]) -> set[str]:
    names = []
    if isinstance(node, ast.Import):
        names = [alias.name for alias in node.names]
    elif isinstance(node, ast.ImportFrom):
        base = node.module or ""
        if node.level:
            parts = module.split(".")
            package = parts if path.name == "__init__.py" else parts[:-1]
            base = ".".join(package[:len(package) - (node.level - 1)] + ([node.module] if node.module else []))
        names = [base] + [f"{base}.{alias.name}" for alias in node.names]
    return {name for name in names if name in known and name != module}


def module_graph(root: Path = ROOT, packages: tuple[str, ...] = LAYERS) -> dict[str, set[str]]:
    """Module -> the project modules it imports (anywhere in the file)."""
    known = module_files(root, packages)
    graph = {}
    for module, path in known.items():
        graph[module] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            graph[module] |= _targets(module, path, node, known)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one member (Tarjan), each sorted: the import cycles."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for successor in sorted(graph.get(node, ())):
            if successor not in index:
                visit(successor)
                low[node] = min(low[node], low[successor])
            elif successor in on_stack:
                low[node] = min(low[node], index[successor])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def package_edges(graph: dict[str, set[str]]) -> dict[tuple[str, str], list[str]]:
    """(importing package, imported package) -> the module imports behind it ("a.b -> c.d")."""
    edges: dict[tuple[str, str], list[str]] = {}
    for module, targets in graph.items():
        for target in sorted(targets):
            pair = (module.split(".")[0], target.split(".")[0])
            if pair[0] != pair[1]:
                edges.setdefault(pair, []).append(f"{module} -> {target}")
    return edges


def upward_imports(graph: dict[str, set[str]], layers: tuple[str, ...] = LAYERS) -> list[str]:
    """Imports of a package from a package at or above its own layer (the list of LAYERS): each breaks the order."""
    rank = {package: i for i, package in enumerate(layers)}
    return [line for (importer, imported), lines in sorted(package_edges(graph).items())
            if rank[imported] > rank[importer] for line in lines]


def mermaid(graph: dict[str, set[str]]) -> str:
    """The package layers as a Mermaid flowchart (an arrow: imports), bottom layer at the bottom."""
    lines = ["flowchart BT"]
    for importer, imported in sorted(package_edges(graph)):
        lines.append(f"    {importer} --> {imported}")
    return "\n".join(lines)


if __name__ == "__main__":
    project = module_graph()
    print("cycles:", cycles(project) or "none")
    print("upward imports:", upward_imports(project) or "none")
    print(mermaid(project))
