"""Build one of the examples' Blender scenes, save it and export it as a Haze scene folder.

    .venv/bin/python tools/blend_scene.py NAME OUT_DIR [--size 128] [--bounces 3]

NAME is a scene of examples/blender_gallery.py (textured_box, hdri, smoke_ball, ...). Writes
OUT_DIR/scene.blend (what Cycles renders: tools/cycles_reference.py takes a .blend too) and
OUT_DIR/scene/ (the same scene through the add-on's exporter, what Haze renders), so the
convergence benchmark (bench/blend_scenes.py) compares both renderers on one Blender scene
whose materials Haze evaluates per shading point. Runs with private Blender user folders, the
export done by the installed extension zip.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for _path in (REPO, REPO / "tests", REPO / "examples"):
    if str(_path) not in sys.path:  # appended: the installed extension's renderer comes first
        sys.path.append(str(_path))

ISOLATED = "HAZE_BLEND_SCENE_ISOLATED"


def isolate_blender() -> None:
    """Re-run this script with private HOME / Blender user folders, the extension zip of this
    checkout installed in the latter (bench/installed.py): Haze as users get it."""
    if os.environ.get(ISOLATED):
        return
    from bpy_helpers import blender_environment as private_folders

    from bench.installed import blender_environment

    env = private_folders(Path(tempfile.mkdtemp(prefix="haze-blend-scene-")), None)
    env = blender_environment(Path(env["BLENDER_USER_RESOURCES"]), env)
    env[ISOLATED] = "1"
    os.execve(sys.executable, [sys.executable, __file__, *sys.argv[1:]], env)


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("name")
    parser.add_argument("out", type=Path)
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--bounces", type=int, default=3)
    return parser.parse_args(argv)


def main(argv: list[str]) -> int:
    isolate_blender()
    arguments = parse_arguments(argv)
    import blender_gallery as G
    import bpy

    from bench.installed import enable_installed

    enable_installed()
    out = arguments.out.resolve()
    (out / "assets").mkdir(parents=True, exist_ok=True)
    scene = G.build(arguments.name, arguments.size, out / "assets")
    scene.render.engine = "HAZE"
    scene.haze.max_bounces = arguments.bounces
    bpy.ops.wm.save_as_mainfile(filepath=str(out / "scene.blend"))
    result = bpy.ops.export_scene.haze(filepath=str(out / "scene"))
    if result != {"FINISHED"}:
        print(f"export of {arguments.name} failed: {result}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
