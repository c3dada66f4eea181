"""Measure the add-on's own costs: scene export and image display.

    .venv/bin/python tools/bench_addon.py [--skip-render]

1. Export of a 1M-triangle mesh from the evaluated depsgraph (goal <= 0.5 s), flat, smooth
   (one normal per vertex) and mixed smooth/sharp (one normal per face corner).
2. Display overhead: the cost of one push of a 1920x1080 image into Blender's render result
   (flip, RGBA copy, foreach_set, update_result), and the share of render time it takes in a
   real time-limited Haze render (goal <= 2 %).

Runs Blender as a Python module in this process (a tool, not a test).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import bpy
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import addon  # noqa: E402  (needs the repository on sys.path first)
from addon.display import ResultBuffer, write_result  # noqa: E402
from addon.session import MAX_DISPLAY_SHARE, PUSH_INTERVAL, RenderSession  # noqa: E402

GRID_CUTS = 708  # 708 x 708 grid: 1,002,528 triangles
PUSH_SIZE = (1920, 1080)


def empty_scene() -> bpy.types.Scene:
    scene = bpy.context.scene
    for obj in list(scene.collection.all_objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0.0, 0.0, 3.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    return scene


def million_triangle_grid() -> bpy.types.Object:
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=GRID_CUTS, y_subdivisions=GRID_CUTS, size=2.0)
    return bpy.context.active_object


def median_seconds(function, repeats: int = 5) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def bench_export() -> None:
    from addon.export.scene import export_scene

    empty_scene()
    grid = million_triangle_grid()
    depsgraph = bpy.context.evaluated_depsgraph_get()

    def export() -> None:
        result = export_scene(depsgraph, render_depsgraph=False)
        assert sum(len(m.indices) for m in result.scene.meshes) == len(grid.data.loop_triangles)

    print(f"export of {len(grid.data.loop_triangles):,} triangles (median of 5, goal <= 0.5 s):")
    print(f"  flat shading        {median_seconds(export):.3f} s")
    grid.data.shade_smooth()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    print(f"  smooth (per vertex) {median_seconds(export):.3f} s")
    half = len(grid.data.polygons) // 2
    flags = np.zeros(len(grid.data.polygons), dtype=bool)
    flags[:half] = True
    grid.data.polygons.foreach_set("use_smooth", flags)
    grid.data.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert grid.data.normals_domain == "CORNER"
    print(f"  mixed (per corner)  {median_seconds(export):.3f} s")
    bpy.data.objects.remove(grid, do_unlink=True)


class PushBenchEngine(bpy.types.RenderEngine):
    """Pushes one full-HD image many times, as the Haze engine does once a second."""

    bl_idname = "HAZE_PUSH_BENCH"
    bl_label = "Haze push benchmark"
    timings: list[float] = []

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)

    def render(self, depsgraph) -> None:
        width, height = self.resolution_x, self.resolution_y
        image = np.random.default_rng(1).random((height, width, 3), dtype=np.float32)
        buffer = ResultBuffer(width, height)
        result = self.begin_result(0, 0, width, height)
        for _ in range(20):
            start = time.perf_counter()
            buffer.fill(image)
            write_result(result, buffer)
            self.update_result(result)
            PushBenchEngine.timings.append(time.perf_counter() - start)
        self.end_result(result)


def bench_push_cost() -> float:
    bpy.utils.register_class(PushBenchEngine)
    scene = empty_scene()
    scene.render.engine = PushBenchEngine.bl_idname
    scene.render.resolution_x, scene.render.resolution_y = PUSH_SIZE
    scene.render.resolution_percentage = 100
    bpy.ops.render.render()
    bpy.utils.unregister_class(PushBenchEngine)
    per_push = statistics.median(PushBenchEngine.timings)
    # The session pushes once a second, or less often when a push is slow (MAX_DISPLAY_SHARE).
    interval = max(PUSH_INTERVAL, per_push / MAX_DISPLAY_SHARE)
    print(f"push of a {PUSH_SIZE[0]}x{PUSH_SIZE[1]} image: {1000 * per_push:.1f} ms median; pushed every "
          f"{interval:.2f} s that is {100 * per_push / interval:.2f} % of render time (goal <= 2 %)")
    return per_push


def bench_real_render(seconds: float) -> None:
    """A real time-limited Haze render at full HD: measured share of time spent pushing."""
    sys.path.insert(0, str(REPO / "examples"))
    import blender_cornell

    spent: list[float] = []
    original = RenderSession._push

    def timed_push(self, result) -> None:
        start = time.perf_counter()
        original(self, result)
        spent.append(time.perf_counter() - start)

    RenderSession._push = timed_push
    try:
        scene = blender_cornell.build_fog_cornell(*PUSH_SIZE, max_bounces=3)
        scene.haze.samples, scene.haze.time_limit, scene.haze.workers = 100000, seconds, 0
        start = time.perf_counter()
        bpy.ops.render.render()
        total = time.perf_counter() - start
    finally:
        RenderSession._push = original
    print(f"Haze render {PUSH_SIZE[0]}x{PUSH_SIZE[1]}, {seconds:g} s limit: {len(spent)} pushes, "
          f"{1000 * sum(spent):.0f} ms pushing of {total:.1f} s = {100 * sum(spent) / total:.2f} % "
          f"(goal <= 2 %)")


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-render", action="store_true", help="skip the real render measurement")
    parser.add_argument("--render-seconds", type=float, default=20.0)
    arguments = parser.parse_args(argv)
    addon.register()
    bench_export()
    bench_push_cost()
    if not arguments.skip_render:
        bench_real_render(arguments.render_seconds)
    addon.unregister()


if __name__ == "__main__":
    main(sys.argv[1:])
