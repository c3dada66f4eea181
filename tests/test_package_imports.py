"""What ships imports only what ships.

Installed, the add-on's package is `bl_ext.<repo>.haze`, never `addon`, and the renderer is
a wheel without the repository around it. So no module of addon/ may import itself by the
clone's package name (`import addon...`, `from addon...`), and nothing in renderer/ (the
wheel) or addon/ (the zip) may import the repository's other folders.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
REPOSITORY_ONLY = ("bench", "tools", "examples", "tests", "helpers")  # helpers: tests/helpers/


def imported_names(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import in the file, at any depth (functions too)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module))
    return found


def offending_imports(folder: str, banned: tuple[str, ...]) -> list[str]:
    lines = []
    for path in sorted((REPO / folder).rglob("*.py")):
        for line, name in imported_names(path):
            if name.split(".")[0] in banned:
                lines.append(f"{path.relative_to(REPO)}:{line} imports {name}")
    return lines


def test_addon_imports_itself_relatively():
    assert offending_imports("addon", ("addon",) + REPOSITORY_ONLY) == []


def test_renderer_imports_nothing_of_the_repository():
    assert offending_imports("renderer", ("addon",) + REPOSITORY_ONLY) == []


TEST_IMPORT = re.compile(r"^\s*(from|import)\s+(tests|helpers)\b", re.M)


def test_bench_and_examples_import_nothing_of_the_tests():
    """Benchmarks and examples stand on their own; this also reads the Blender scripts they
    hold in strings, which the import walk above cannot see."""
    found = [f"{path.relative_to(REPO)}: {match.group(0).strip()}"
             for folder in ("bench", "examples") for path in sorted((REPO / folder).rglob("*.py"))
             for match in TEST_IMPORT.finditer(path.read_text())]
    assert found == []


@pytest.mark.parametrize("source, caught", [
    ("import addon.volume_grids\n", True),
    ("def f():\n    from addon.volume_grids import import_openvdb\n", True),
    ("from tools import x\n", True),
    ("from ..volume_grids import import_openvdb\n", False),
    ("import addon_utils\n", False),
])
def test_the_rule_catches_clone_names(tmp_path, source, caught):
    """The check itself: an import by the clone's name is found, even inside a function."""
    (tmp_path / "m.py").write_text(source)
    names = [name for _, name in imported_names(tmp_path / "m.py")]
    assert any(n.split(".")[0] in ("addon",) + REPOSITORY_ONLY for n in names) == caught
