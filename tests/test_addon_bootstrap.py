"""Where the add-on puts numba's cache and how it finds the renderer (no Blender needed)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from addon import bootstrap

REPO = Path(__file__).resolve().parents[1]


def test_numba_cache_goes_to_a_user_folder(monkeypatch, tmp_path):
    # Restored after the test; numba hidden so this process's numba configuration is untouched.
    monkeypatch.setenv("NUMBA_CACHE_DIR", "")
    monkeypatch.delitem(sys.modules, "numba", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    folder = bootstrap.configure_numba_cache("haze")  # not an extension: the per-user fallback
    assert folder == tmp_path / "haze" / "numba" and folder.is_dir()
    assert os.environ["NUMBA_CACHE_DIR"] == str(folder)
    assert not folder.resolve().is_relative_to((REPO / "addon").resolve())


def test_numba_cache_respects_the_users_choice(monkeypatch, tmp_path):
    monkeypatch.delitem(sys.modules, "numba", raising=False)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    assert bootstrap.configure_numba_cache("bl_ext.user_default.haze") == tmp_path / "mine"
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "mine")


def test_clone_layout_is_recognised():
    assert bootstrap.repository_root(str(REPO / "addon" / "__init__.py")) == REPO
    assert bootstrap.renderer_problem() is None


def test_folder_without_renderer_is_not_a_clone(tmp_path):
    lonely = tmp_path / "haze" / "__init__.py"
    lonely.parent.mkdir()
    lonely.write_text("")
    assert bootstrap.repository_root(str(lonely)) is None
