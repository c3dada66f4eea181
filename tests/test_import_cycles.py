"""The add-on's and the renderer's modules import each other without circles (bench/import_cycles.py)."""

from __future__ import annotations

from bench import import_cycles


def load_tool():
    return import_cycles


def test_circles_are_found():
    tool = load_tool()
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert tool.circles(graph) == [["a", "b", "c"]]


def test_addon_has_no_import_circles():
    tool = load_tool()
    known = tool.module_names("addon")
    graph = {name: tool.imports_of(name, path, known) for name, path in known.items()}
    assert "addon.export.scene" in graph["addon.export.validate"]  # imported inside a function
    assert tool.circles(graph) == []


def test_renderer_has_no_import_circles():
    tool = load_tool()
    known = tool.module_names("renderer")
    graph = {name: tool.imports_of(name, path, known) for name, path in known.items()}
    assert "renderer.media.layout" in graph["renderer.media.compile"]
    assert tool.circles(graph) == []
