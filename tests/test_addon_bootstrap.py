"""Where the add-on puts the kernel cache and how it finds the renderer (no Blender needed)."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from addon import bootstrap
from renderer.kernels import cache

REPO = Path(__file__).resolve().parents[1]


def hide_numba(monkeypatch) -> None:
    """Restored after the test: this process's numba configuration stays untouched."""
    monkeypatch.delitem(sys.modules, "numba", raising=False)


def test_addon_shares_the_command_lines_cache(monkeypatch, tmp_path):
    hide_numba(monkeypatch)
    for name in ("NUMBA_CACHE_DIR", "HAZE_CACHE_DIR"):
        monkeypatch.setenv(name, "")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    expected = cache.cache_root()  # the CLI's folder, asked before the add-on sets anything
    folder = bootstrap.configure_numba_cache()
    assert folder == expected == tmp_path / "haze" and folder.is_dir()
    assert os.environ["NUMBA_CACHE_DIR"] == str(folder)  # numba's other functions go there too
    assert cache.cache_root() == folder  # so the renderer still picks the same root
    assert not folder.resolve().is_relative_to((REPO / "addon").resolve())


@pytest.mark.parametrize("haze, numba", [("a", ""), ("", "b"), ("a", "b")])
def test_users_cache_choice_is_respected(monkeypatch, tmp_path, haze, numba):
    hide_numba(monkeypatch)
    monkeypatch.setenv("HAZE_CACHE_DIR", str(tmp_path / haze) if haze else "")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / numba) if numba else "")
    expected = cache.cache_root()
    assert bootstrap.configure_numba_cache() == expected == tmp_path / (haze or numba)
    assert bootstrap.haze_cache_root() == cache.cache_root()
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / (numba or haze))


def test_cache_root_rule_matches_the_renderers_on_every_platform(monkeypatch, tmp_path):
    for name in ("NUMBA_CACHE_DIR", "HAZE_CACHE_DIR"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("LOCALAPPDATA", str(tmp_path / "local"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    for platform in ("linux", "win32", "darwin"):
        monkeypatch.setattr(sys, "platform", platform)
        assert bootstrap.haze_cache_root() == cache.cache_root(), platform


def test_clone_layout_is_recognised():
    assert bootstrap.repository_root(str(REPO / "addon" / "__init__.py")) == REPO
    assert bootstrap.renderer_problem() is None


def test_folder_without_renderer_is_not_a_clone(tmp_path):
    lonely = tmp_path / "haze" / "__init__.py"
    lonely.parent.mkdir()
    lonely.write_text("")
    assert bootstrap.repository_root(str(lonely)) is None


def test_disabling_stops_persistent_render_workers_when_the_renderer_has_them(monkeypatch):
    import addon

    calls = []
    render = SimpleNamespace(shutdown_workers=lambda: calls.append(1))
    monkeypatch.setitem(sys.modules, "renderer.render", render)
    addon.stop_render_workers()
    assert calls == [1]
    monkeypatch.setitem(sys.modules, "renderer.render", SimpleNamespace())  # a renderer without them
    addon.stop_render_workers()
    monkeypatch.delitem(sys.modules, "renderer.render")  # not loaded: nothing to stop, nothing imported
    addon.stop_render_workers()
    assert calls == [1] and "renderer.render" not in sys.modules


@pytest.mark.parametrize("switch, headless, expected", [
    ("", False, True), ("", True, False), ("1", True, True), ("0", False, False), ("off", True, False)])
def test_background_compile_is_on_with_a_ui_unless_switched(monkeypatch, switch, headless, expected):
    from addon import background

    monkeypatch.setenv("HAZE_BACKGROUND_COMPILE", switch)
    assert background.enabled(headless) is expected
