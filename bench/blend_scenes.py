"""Benchmark scenes built in Blender: the scene is built by examples/ (bench/blend_scene.py,
in a bpy subprocess), saved as a .blend for Cycles and exported through the add-on for Haze,
so both renderers see one artist's scene, textures and world included. The export runs in
the extension zip built from this checkout and installed (bench/installed.py).

The export is cached under bench/cache/blend/, keyed by the scene's name, size and bounce
limit and by the sources that shape it (the examples' builders and the add-on's exporter),
so an edit to either rebuilds it.
"""

from __future__ import annotations

import hashlib
import subprocess
import sys
from pathlib import Path

from renderer.scene import Scene

REPO = Path(__file__).resolve().parents[1]
CACHE = REPO / "bench" / "cache" / "blend"
SOURCES = ("examples/*.py", "addon/**/*.py", "renderer/**/*.py", "bench/blend_scene.py",
           "bench/blender.py", "bench/installed.py")  # the zip that exports is built from these


def _sources_digest() -> str:
    digest = hashlib.sha256()
    for pattern in SOURCES:
        for path in sorted(REPO.glob(pattern)):
            digest.update(path.relative_to(REPO).as_posix().encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def export_folder(name: str, size: int, bounces: int) -> Path:
    """The folder holding scene.blend and scene/ (the Haze export), built if missing."""
    folder = CACHE / f"{name}-{size}-b{bounces}-{_sources_digest()}"
    if not (folder / "scene" / "scene.json").is_file():
        command = [sys.executable, "-m", "bench", "blend_scene", name, str(folder), "--size", str(size),
                   "--bounces", str(bounces)]
        process = subprocess.run(command, capture_output=True, text=True, cwd=REPO)
        if process.returncode != 0:
            raise RuntimeError(f"building {name} in Blender failed ({process.returncode}):\n"
                               f"{process.stdout[-3000:]}\n{process.stderr[-3000:]}")
    return folder


def blend_scene(name: str, size: int, bounces: int) -> Scene:
    from renderer.scenefile import load_scene

    return load_scene(export_folder(name, size, bounces) / "scene")


def blend_file(name: str, size: int, bounces: int) -> Path:
    return export_folder(name, size, bounces) / "scene.blend"
