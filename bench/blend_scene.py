"""Build one of the examples' Blender scenes, save it and export it as a Haze scene folder.

    .venv/bin/python -m bench blend_scene NAME OUT_DIR [--size 128] [--bounces 3]

NAME is a scene of examples/blender_gallery.py (textured_box, hdri, smoke_ball, ...). Writes
OUT_DIR/scene.blend (what Cycles renders: `python -m bench cycles_reference` takes a .blend
too) and OUT_DIR/scene/ (the same scene through the add-on's exporter, what Haze renders), so
the convergence benchmark (bench/blend_scenes.py) compares both renderers on one Blender
scene whose materials Haze evaluates per shading point. Runs with private Blender user
folders, the export done by the installed extension zip.

The build runs in a Python subprocess with bpy, started in OUT_DIR (not the checkout: a
working folder first on sys.path would put the checkout's renderer before the installed
extension's); it appends the repository and examples/ to its own sys.path.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

BLENDER_SIDE = """\
import sys
for _path in {paths!r}:
    if _path not in sys.path:  # appended: the installed extension's renderer comes first
        sys.path.append(_path)
from bench.blend_scene import build
raise SystemExit(build({argv!r}))
"""


def parse_arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m bench blend_scene", description=__doc__.splitlines()[0])
    parser.add_argument("name")
    parser.add_argument("out", type=Path)
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--bounces", type=int, default=3)
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Host side: private HOME / Blender user folders with the extension zip of this checkout
    installed (bench/installed.py: Haze as users get it), then the build in a subprocess."""
    from bench import installed
    from bench.blender import blender_environment as private_folders

    arguments = parse_arguments(argv)
    out = arguments.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    env = private_folders(Path(tempfile.mkdtemp(prefix="haze-blend-scene-")), None)
    env = installed.blender_environment(Path(env["BLENDER_USER_RESOURCES"]), env)
    rest = [arguments.name, str(out), "--size", str(arguments.size), "--bounces", str(arguments.bounces)]
    code = BLENDER_SIDE.format(paths=[str(REPO), str(REPO / "examples")], argv=rest)
    return subprocess.run([sys.executable, "-c", code], env=env, cwd=out).returncode


def build(argv: list[str]) -> int:
    """Blender side: build, save and export the scene."""
    arguments = parse_arguments(argv)
    import blender_gallery as G
    import bpy

    from bench.installed import enable_installed

    enable_installed()
    out = arguments.out
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
