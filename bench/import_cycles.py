"""Find import circles inside Python packages of this repository.

Every import statement counts, also those inside functions and under `if TYPE_CHECKING:`:
a function-level import only moves a circle to run time, it does not remove it. An import
`from package import name` is an edge to `package.name` when that is a module, else to
`package`. Importing a module also runs its parents' __init__ files; those implied edges are
left out (every module would otherwise form a circle with its package's __init__).

Usage: .venv/bin/python -m bench import_cycles [addon renderer ...]
Exit status 1 when a circle is found.
"""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def module_names(package: str) -> dict[str, Path]:
    """Dotted module name -> file, for every .py file under the package folder."""
    modules = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        modules[".".join(parts)] = path
    return modules


def absolute(module: str, is_package: bool, level: int, target: str | None) -> str:
    """The absolute name of a (possibly relative) import target seen from `module`."""
    if level == 0:
        return target or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join(base + ([target] if target else []))


def imports_of(module: str, path: Path, known: dict[str, Path]) -> set[str]:
    """Modules of `known` that `module` imports anywhere in its file."""
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            source = absolute(module, is_package, node.level, node.module)
            for alias in node.names:
                submodule = f"{source}.{alias.name}"
                found.add(submodule if submodule in known else source)
    return {name for name in found if name in known and name != module}


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for successor in sorted(graph[node]):
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench import_cycles", description=__doc__.splitlines()[0])
    parser.add_argument("packages", nargs="*", default=["addon"], help="packages to check (default addon)")
    packages = parser.parse_args(argv).packages
    known: dict[str, Path] = {}
    for package in packages:
        known.update(module_names(package))
    graph = {name: imports_of(name, path, known) for name, path in known.items()}
    found = circles(graph)
    edges = sum(len(targets) for targets in graph.values())
    print(f"{len(known)} modules, {edges} internal imports in {', '.join(packages)}: "
          f"{len(found)} import circle(s)")
    for component in found:
        print("  circle: " + ", ".join(component))
    return 1 if found else 0
