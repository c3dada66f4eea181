"""The kernel cache as the preferences panel shows it: folders, size, state, clearing.

No bpy or numba here. Only Haze's own build folders (`kernels-<build key>` directly under
the cache root) are counted and deleted: the root may be a folder the user chose and
shares with other programs (NUMBA_CACHE_DIR), so nothing else in it is ever touched.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from .background import State

BUILD_PREFIX = "kernels-"


def build_folders(root: Path) -> list[Path]:
    """Haze's kernel folders under `root`, one per build key (never a symlink)."""
    try:
        entries = list(root.iterdir())
    except OSError:
        return []
    return sorted(p for p in entries if p.name.startswith(BUILD_PREFIX) and p.is_dir() and not p.is_symlink())


def size_of(folders: list[Path]) -> int:
    """Bytes of the files below `folders`."""
    total = 0
    for folder in folders:
        for path in folder.rglob("*"):
            try:
                if path.is_file() and not path.is_symlink():
                    total += path.stat().st_size
            except OSError:
                pass  # a file removed while we count: it no longer takes space
    return total


def clear(root: Path) -> tuple[int, int]:
    """Delete Haze's kernel folders under `root`; returns (folders deleted, bytes freed)."""
    folders = build_folders(root)
    freed = size_of(folders)
    for folder in folders:
        shutil.rmtree(folder)
    return len(folders), freed


def megabytes(size: int) -> str:
    return f"{size / 1e6:.1f} MB"


def state_text(state: State) -> str:
    """One line for the panel: ready, compiling for N s, failed..."""
    seconds = f"{state.seconds:.0f} s"
    texts = {
        "idle": "Kernels not compiled in the background: the first render compiles what it needs",
        "checking": f"Checking the compiled kernels… {seconds}",
        "compiling": f"Compiling kernels in the background (first run only)… {seconds}",
        "ready": f"Kernels ready (checked in {seconds})",
        "stopped": "Background compile stopped; the first render compiles what is missing",
        "failed": "Background compile failed" + (f": {state.detail}" if state.detail else ""),
    }
    return texts.get(state.kind, state.kind)


def cache_text(root: Path) -> str:
    folders = build_folders(root)
    builds = "build" if len(folders) == 1 else "builds"
    return f"{megabytes(size_of(folders))} in {len(folders)} {builds}"
