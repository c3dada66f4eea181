"""Compile the kernels common scenes need, in a process of its own (run as a script).

The add-on starts this when it is enabled (addon/background.py), so that the first F12
finds the kernels compiled instead of waiting minutes for numba. It renders one tiny pass
of a surface-only Cornell box, of the box with a fog cube and with fog filling it, and of
a grid smoke ball: between them they call every kernel signature those kinds of scenes
use. If the cache already holds them this takes a few seconds and compiles nothing;
otherwise it compiles under the renderer's compile lock, so an F12 started meanwhile (or
another Blender) waits for it and then loads its result instead of compiling again.

It imports only numpy and the renderer (never bpy or the add-on): an installed extension
ships the renderer as a wheel, not the examples. The parent puts its sys.path in
PYTHONPATH so `renderer` and the bundled numba are found; stdout goes to a log file.
The process ends itself when its parent (Blender) is gone.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path

import numpy as np

READY_LINE = "kernels ready"  # the last line of a successful run (addon/background.py reads it)
COMPILING_LINE = "compiling kernels (first run only)"


def quad(center, u, v) -> tuple[np.ndarray, np.ndarray]:
    """A square center +- u +- v, facing u x v."""
    c, u, v = (np.asarray(x, np.float32) for x in (center, u, v))
    vertices = np.array([c - u - v, c + u - v, c + u + v, c - u + v], np.float32)
    return vertices, np.array([[0, 1, 2], [0, 2, 3]], np.int32)


def cube(center, half: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed cube with outward faces."""
    c = np.asarray(center, np.float32)
    corners = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], np.float32)
    faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    triangles = [[a, b, c_] for a, b, c_, d in faces] + [[a, c_, d] for a, b, c_, d in faces]
    return c + half * corners, np.array(triangles, np.int32)


def surface_box():
    """A tiny Cornell box: diffuse walls, an emitting quad, a point light, no media."""
    from renderer.scene import Camera, Film, IntegratorSettings, Lobe, Material, Mesh, PointLight, Scene

    walls = [quad((0, -1, 0), (0, 0, 1), (1, 0, 0)), quad((0, 0, -1), (1, 0, 0), (0, 1, 0)),
             quad((-1, 0, 0), (0, 1, 0), (0, 0, 1)), quad((1, 0, 0), (0, 0, 1), (0, 1, 0)),
             quad((0, 1, 0), (1, 0, 0), (0, 0, 1))]
    meshes = [Mesh(f"wall{i}", v, t, ["white"]) for i, (v, t) in enumerate(walls)]
    meshes.append(Mesh("lamp", *quad((0, 0.99, 0), (0.25, 0, 0), (0, 0, 0.25)), ["lamp"]))
    materials = [Material("white", [Lobe("diffuse", color=(0.7, 0.7, 0.7))]),
                 Material("lamp", [Lobe("diffuse")], emission=(10.0, 10.0, 10.0))]
    to_world = np.eye(4)
    to_world[:3, 3] = (0.0, 0.0, 3.9)
    return Scene(camera=Camera(to_world=to_world, fov=37.0), film=Film(4, 4),
                 integrator=IntegratorSettings(spp=1, max_bounces=3), materials=materials, meshes=meshes,
                 lights=[PointLight((0.0, 0.5, 0.0), (1.0, 1.0, 1.0))])


def fog_cube_box():
    """The box with a cube of homogeneous fog (a medium inside an invisible boundary, as F12's fog box)."""
    from renderer.scene import Material, Medium, Mesh

    scene = surface_box()
    scene.materials.append(Material("boundary"))
    scene.media.append(Medium("fog", sigma_a=(0.5, 0.5, 0.5), sigma_s=(1.5, 1.5, 1.5), g=0.3))
    scene.meshes.append(Mesh("fog", *cube((0.0, -0.4, 0.0), 0.5), ["boundary"], medium="fog"))
    return scene


def fog_filled_box():
    """The box filled with fog, camera included (the command line's fog Cornell box)."""
    from renderer.scene import Medium

    scene = surface_box()
    scene.media.append(Medium("fog", sigma_a=(0.002, 0.003, 0.002), sigma_s=(0.3, 0.3, 0.3)))
    scene.medium = "fog"
    return scene


def smoke_ball_box():
    """The box with an 11^3 grid smoke ball in an invisible boundary cube."""
    from renderer.media.generators import smoke_ball_density
    from renderer.scene import Material, Medium, Mesh

    scene = surface_box()
    scene.materials.append(Material("boundary"))
    scene.media.append(Medium("smoke", "grid", sigma_a=(9.0, 9.0, 9.0), sigma_s=(1.0, 1.0, 1.0),
                              density=smoke_ball_density(11), p0=(-0.5, -0.9, -0.5), p1=(0.5, 0.1, 0.5)))
    scene.meshes.append(Mesh("smoke", *cube((0.0, -0.4, 0.0), 0.51), ["boundary"], medium="smoke"))
    scene.integrator.max_bounces = 16
    return scene


SCENES = {"surface box": surface_box, "fog cube": fog_cube_box, "fog-filled box": fog_filled_box,
          "smoke ball": smoke_ball_box}


def announce(names: list[str]) -> None:
    print(f"{COMPILING_LINE}: {', '.join(names)}", flush=True)


def render_one_pass(scene) -> None:
    from renderer.render import render_progressive

    frames = render_progressive(scene, workers=1, on_compile=announce)
    try:
        next(frames)
    finally:
        frames.close()


def exit_with_parent(parent: int, poll: float = 1.0) -> None:
    """End this process once Blender is gone: nobody waits for its kernels any more."""
    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(poll)
        os._exit(3)

    threading.Thread(target=watch, daemon=True).start()


def main() -> int:
    exit_with_parent(os.getppid())
    import renderer
    from renderer.kernels.cache import kernel_cache_dir

    print(f"renderer: {Path(renderer.__file__).parent}", flush=True)
    print(f"kernel cache: {kernel_cache_dir()}", flush=True)
    t0 = time.perf_counter()
    for name, build in SCENES.items():
        t = time.perf_counter()
        render_one_pass(build())
        print(f"{name}: {time.perf_counter() - t:.1f} s", flush=True)
    print(f"{READY_LINE} ({time.perf_counter() - t0:.1f} s)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
