"""Where Haze keeps its caches: the one rule, for the renderer and the add-on alike.

HAZE_CACHE_DIR if set, else NUMBA_CACHE_DIR if set (the user's or a test's choice), else
the per-user cache folder: ~/.cache/haze on Linux (XDG_CACHE_HOME respected),
%LOCALAPPDATA%\\haze on Windows, ~/Library/Caches/haze on macOS.

Standard library only: the add-on asks it at registration, before anything may import
numba (renderer.kernels.cache, which keeps the kernels below this root, imports numba).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

CACHE_ENV = "HAZE_CACHE_DIR"
NUMBA_CACHE_ENV = "NUMBA_CACHE_DIR"


def cache_root() -> Path:
    """Where Haze keeps its caches (every build key's kernel folder lies below it)."""
    for name in (CACHE_ENV, NUMBA_CACHE_ENV):
        chosen = os.environ.get(name)
        if chosen:
            return Path(chosen)
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or str(Path.home() / "AppData" / "Local")
        return Path(base) / "haze"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "haze"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "haze"
