"""Prepare the Python environment before anything imports numba or the renderer.

Two things must happen first, at add-on import time:

* NUMBA_CACHE_DIR points to a per-user cache folder. Numba otherwise writes compiled
  kernels next to the renderer's sources, i.e. into the installed extension, which may be
  read-only and is wiped on every update.
* The `renderer` package must be importable. An installed extension ships it as a bundled
  wheel (Blender puts the wheel's folder on sys.path); a development checkout enabled from a
  clone has it next to this add-on folder, so the repository root is added to sys.path.

This module imports neither numba nor the renderer itself: registering the add-on stays fast
and Blender starts even when the renderer is broken; the render reports the problem instead.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

NUMBA_CACHE_ENV = "NUMBA_CACHE_DIR"


def extension_cache_dir(package: str) -> Path | None:
    """The extension's user folder for numba's cache, or None outside Blender's extension system."""
    if not package.startswith("bl_ext."):
        return None  # enabled as a legacy add-on or imported directly: no extension user folder
    try:
        import bpy

        return Path(bpy.utils.extension_path_user(package, path="numba_cache", create=True))
    except (ImportError, AttributeError, ValueError, OSError):
        return None


def fallback_cache_dir() -> Path:
    """A per-user cache folder when Blender does not provide one (XDG / LOCALAPPDATA / ~/.cache)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.environ.get("LOCALAPPDATA")
    root = Path(base) if base else Path.home() / ".cache"
    return root / "haze" / "numba"


def configure_numba_cache(package: str) -> Path:
    """Point numba's on-disk cache at a user folder, unless the user chose one already.

    Returns the folder in use. If numba was imported before us (by another add-on), its
    configuration is re-read so the setting still applies to our kernels.
    """
    chosen = os.environ.get(NUMBA_CACHE_ENV)
    if chosen:
        return Path(chosen)  # the user's own choice wins
    folder = extension_cache_dir(package) or fallback_cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    os.environ[NUMBA_CACHE_ENV] = str(folder)
    if "numba" in sys.modules:
        try:
            sys.modules["numba"].core.config.reload_config()
        except AttributeError:
            pass  # an unexpected numba layout: the cache then stays where numba put it
    return folder


def repository_root(addon_file: str) -> Path | None:
    """The checkout holding this add-on, if it is run from a clone (renderer/ beside addon/)."""
    addon_dir = Path(os.path.realpath(addon_file)).parent
    root = addon_dir.parent
    if (root / "renderer" / "scene.py").is_file():
        return root
    return None


def make_renderer_importable(addon_file: str) -> None:
    """Add the repository root to sys.path when the renderer is not installed as a wheel."""
    if importlib.util.find_spec("renderer") is not None:
        return
    root = repository_root(addon_file)
    if root is not None and str(root) not in sys.path:
        sys.path.append(str(root))


def renderer_problem() -> str | None:
    """None if `renderer` can be imported, else a sentence saying why not."""
    try:
        import renderer.scene  # noqa: F401  (only checks that the package is there)
    except ImportError as error:
        return (
            f"the Haze renderer package cannot be imported ({error}); reinstall the extension "
            "or, from a clone, keep addon/ next to renderer/"
        )
    return None
