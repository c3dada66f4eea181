"""Prepare the Python environment before anything imports numba or the renderer's kernels.

Two things must happen first, at add-on import time, in this order:

* The `renderer` package must be importable. An installed extension ships it as a bundled
  wheel (Blender puts the wheel's folder on sys.path); a development checkout enabled from a
  clone has it next to this add-on folder, so the repository root is added to sys.path.
* The kernel cache is the command line's (renderer.cache_folder: HAZE_CACHE_DIR, else
  NUMBA_CACHE_DIR, else ~/.cache/haze): one compile per machine and user, whether the
  kernels are first needed by `python -m renderer`, F12 in an installed extension or the
  add-on enabled from a clone. Numba would otherwise write compiled functions next to their
  sources, i.e. into the installed extension, which may be read-only and is wiped on every
  update.

This module imports no numba and of the renderer only renderer.cache_folder (standard
library only): registering the add-on stays fast and Blender starts even when the renderer
is broken; the render reports the problem instead.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

NUMBA_CACHE_ENV = "NUMBA_CACHE_DIR"


def haze_cache_root() -> Path | None:
    """The folder the command line caches kernels under (renderer.cache_folder's rule, which
    imports no numba), or None when the renderer cannot be imported."""
    try:
        from renderer.cache_folder import cache_root
    except ImportError:
        return None  # renderer_problem() says why at render time
    return cache_root()


def configure_numba_cache() -> Path | None:
    """Share the command line's kernel cache, unless the user chose a cache folder.

    The renderer's kernels go to `<root>/kernels-<build key>` whatever NUMBA_CACHE_DIR says
    (renderer.kernels.cache); numba's other cached functions (none of Haze's today) go to
    NUMBA_CACHE_DIR, so it is pointed at the same root: otherwise numba would write them
    into the installed extension's folder. Returns the root. If numba was imported before
    us (by another add-on), its configuration is re-read so the setting still applies.
    """
    root = haze_cache_root()
    if root is None or os.environ.get(NUMBA_CACHE_ENV):
        return root  # the user's own choice wins (the root follows it unless HAZE_CACHE_DIR is set)
    root.mkdir(parents=True, exist_ok=True)
    os.environ[NUMBA_CACHE_ENV] = str(root)
    if "numba" in sys.modules:
        try:
            sys.modules["numba"].core.config.reload_config()
        except AttributeError:
            pass  # an unexpected numba layout: the cache then stays where numba put it
    return root


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
