"""Two Blender processes rendering at once from one user folder share one compile (issue 19).

Both start F12 on the same cold kernel cache (the user's cache folder, no HAZE_CACHE_DIR)
at the same time, one render worker each. Every process Haze starts appends the functions
it compiles to one HAZE_COMPILE_LOG file (renderer.kernels.cache.CompileLog): no function
may be compiled twice, with the same argument types, by the two renders' workers together,
and both images must be finished and finite.
"""

from __future__ import annotations

import threading
from collections import Counter
from pathlib import Path

import pytest

from bench.blender import run_blender

pytestmark = [pytest.mark.bpy, pytest.mark.slow]

BODY = r'''
import bpy
import numpy as np
import bpy_helpers as H


def main():
    H.enable_addon()
    scene = bpy.context.scene
    for obj in list(scene.collection.all_objects):
        if obj.type == "MESH":
            obj.data.materials.clear()  # the default cube, grey diffuse: the surface kernels
    H.configure_haze(scene, 2, 2, seed=1, workers=1)
    scene.render.resolution_x = scene.render.resolution_y = 16
    scene.render.resolution_percentage = 100
    path = H.render_exr(scene, os.path.join(os.getcwd(), "f12.exr"))
    image = bpy.data.images.load(path)
    pixels = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(pixels)
    return {"finite": bool(np.isfinite(pixels).all()), "mean": float(pixels.reshape(-1, 4)[:, :3].mean())}
'''


def test_two_blenders_on_one_cold_cache_never_compile_the_same_function(tmp_path):
    home, user = tmp_path / "home", tmp_path / "blender_user"
    log = tmp_path / "compiles.log"
    shared = {"HOME": str(home), "BLENDER_USER_RESOURCES": str(user), "XDG_CACHE_HOME": str(home / ".cache"),
              "XDG_CONFIG_HOME": str(home / ".config"), "HAZE_COMPILE_LOG": str(log)}
    runs: dict[str, object] = {}

    def blender(name: str) -> None:
        runs[name] = run_blender(BODY, tmp_path / name, timeout=900, env=shared)

    threads = [threading.Thread(target=blender, args=(name,)) for name in ("a", "b")]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for run in runs.values():
        assert run.returncode == 0 and run.result["finite"] and run.result["mean"] > 0, run.describe()
    lines = [line.split("\t") for line in log.read_text().splitlines()]
    compiled = Counter((function, args) for _, function, args, _ in lines)
    twice = [key for key, count in compiled.items() if count > 1]
    assert not twice, twice
    # The cache was cold: the surface stage was compiled, once, by one of the workers.
    stages = [function for function, _ in compiled if function.endswith(".shade_surface")]
    assert stages == ["renderer.integrator.surface_stage.shade_surface"], sorted(compiled)
    assert (home / ".cache" / "haze").is_dir()  # the user's own cache folder, shared
    assert not list(Path(tmp_path).glob("*/home/.cache/haze"))  # not the per-run homes run_blender makes
