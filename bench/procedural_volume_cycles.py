"""Haze against Cycles on the two node-authored volumes of tests/test_addon_procedural_volume.py.

    .venv/bin/python -m bench procedural_volume_cycles [--runs 4] [--samples 64] [--size 32]

The procedural cloud (Noise -> Map Range -> Principled Volume Density in a rotated, scaled
cube, a procedural medium in Haze) and the mesh whose geometry nodes output a Volume Cube of
noise density, each rendered `runs` times with independent seeds by Cycles and by Haze (the
add-on of this checkout) in one Blender process, then compared as the suite compares
renders (bench.comparison.compare_images / assert_agree): image means per channel with
their noise sigma, block z-scores, chi-square. Prints the figures and the verdict per scene.

The suite runs the same comparison at these settings (test_addon_procedural_volume's slow
tests, which import the Blender script below); this command prints the figures and takes other
run counts, sample counts and sizes. The script runs with tests/ on its sys.path (run_blender)
and imports the Blender-side helpers of examples/bpy_helpers.py there.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.blender import run_blender, shared_numba_cache
from bench.comparison import assert_agree, compare_images
from renderer.imageio import read_exr

RUNS = 4
SIZE = 32
CYCLES_SAMPLES, HAZE_SAMPLES = 64, 64

_BODY = r'''
import math
import os
import bpy
import bpy_helpers as H
import blender_cornell as C
export_scene = H.addon_module("export.scene").export_scene

SIZE, RUNS, CYCLES_SAMPLES, HAZE_SAMPLES = SIZE_RUNS_SAMPLES
RENDER = "HAZE_TEST_RENDER" in os.environ


def cloud_material():
    material, tree, out = C.node_material("Cloud")
    n, link = tree.nodes.new, tree.links.new
    coords = n("ShaderNodeTexCoord")
    noise = n("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 1.5
    noise.inputs["Detail"].default_value = 2.0
    noise.inputs["Roughness"].default_value = 0.5
    ranged = n("ShaderNodeMapRange")
    ranged.inputs["From Min"].default_value = 0.45
    ranged.inputs["From Max"].default_value = 0.7
    ranged.inputs["To Min"].default_value = 0.0
    ranged.inputs["To Max"].default_value = 6.0
    volume = n("ShaderNodeVolumePrincipled")
    volume.inputs["Color"].default_value = (0.8, 0.7, 0.6, 1.0)
    link(coords.outputs["Object"], noise.inputs["Vector"])
    link(noise.outputs["Fac"], ranged.inputs["Value"])
    link(ranged.outputs["Result"], volume.inputs["Density"])
    link(volume.outputs["Volume"], out.inputs["Volume"])
    return material


def volume_cube_object():
    """A mesh object whose geometry nodes make a 24^3 Volume Cube of noise density."""
    material, tree, out = C.node_material("Smoke")
    volume = tree.nodes.new("ShaderNodeVolumePrincipled")
    volume.inputs["Color"].default_value = (0.6, 0.7, 0.8, 1.0)
    volume.inputs["Density"].default_value = 3.0
    tree.links.new(volume.outputs["Volume"], out.inputs["Volume"])
    obj = bpy.data.objects.new("Cube", bpy.data.meshes.new("Cube"))
    bpy.context.scene.collection.objects.link(obj)
    obj.data.materials.append(material)
    nodes = bpy.data.node_groups.new("Volume Cube", "GeometryNodeTree")
    nodes.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    cube = nodes.nodes.new("GeometryNodeVolumeCube")
    for axis in "XYZ":
        cube.inputs["Resolution " + axis].default_value = 24
    noise = nodes.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 1.5
    nodes.links.new(noise.outputs["Fac"], cube.inputs["Density"])
    assign = nodes.nodes.new("GeometryNodeSetMaterial")
    assign.inputs["Material"].default_value = material
    nodes.links.new(cube.outputs["Volume"], assign.inputs["Geometry"])
    nodes.links.new(assign.outputs["Geometry"], nodes.nodes.new("NodeGroupOutput").inputs[0])
    obj.modifiers.new("Volume", "NODES").node_group = nodes
    obj.rotation_euler = (0.0, 0.0, math.radians(25.0))
    return obj


def volume_cube_case():
    scene = C.clear_scene()
    H.world_color(scene, (0.25, 0.3, 0.4), 1.0)
    volume_cube_object()
    H.add_light("SUN", "Sun", (0.0, 0.0, 5.0), (40.0, 0.0, 30.0), energy=3.0, angle=math.radians(4.0))
    C.add_camera(scene, (0.0, -5.0, 1.0), (80.0, 0.0, 0.0), lens=40.0)
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    exported = export_scene(bpy.context.evaluated_depsgraph_get())
    media = [(m.name, m.type, m.program is not None) for m in exported.scene.media]
    folder = os.path.join(os.getcwd(), "volume_cube")
    os.makedirs(folder, exist_ok=True)
    renders = H.render_both(scene, folder, RUNS, CYCLES_SAMPLES, HAZE_SAMPLES, 3) if RENDER else None
    return {"renders": renders, "media": media, "warnings": exported.warnings}


def main():
    H.enable_addon()
    result = cloud_case()
    result["volume_cube"] = volume_cube_case()
    return result


def cloud_case():
    scene = C.clear_scene()
    H.world_color(scene, (0.25, 0.3, 0.4), 1.0)
    cube = C.box("Cloud", (0.0, 0.0, 0.0), 1.0, cloud_material())
    cube.rotation_euler = (math.radians(10.0), math.radians(20.0), math.radians(30.0))
    cube.scale = (1.2, 0.9, 1.0)
    H.add_light("SUN", "Sun", (0.0, 0.0, 5.0), (40.0, 0.0, 30.0), energy=3.0, angle=math.radians(4.0))
    C.add_camera(scene, (0.0, -5.0, 1.0), (80.0, 0.0, 0.0), lens=40.0)
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    exported = export_scene(bpy.context.evaluated_depsgraph_get())
    media = [(m.name, m.type, m.program is not None) for m in exported.scene.media]
    folder = os.path.join(os.getcwd(), "cloud")
    os.makedirs(folder, exist_ok=True)
    renders = H.render_both(scene, folder, RUNS, CYCLES_SAMPLES, HAZE_SAMPLES, 3) if RENDER else None
    return {"renders": renders, "media": media, "warnings": exported.warnings}
'''


def scene_body(size: int = SIZE, runs: int = RUNS, cycles_samples: int = CYCLES_SAMPLES,
               haze_samples: int = HAZE_SAMPLES) -> str:
    """The Blender body exporting both scenes (and rendering them, when run with
    HAZE_TEST_RENDER set: runs x samples per renderer, size x size pixels)."""
    return f"SIZE_RUNS_SAMPLES = ({size}, {runs}, {cycles_samples}, {haze_samples})\n" + _BODY


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench procedural_volume_cycles",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=RUNS)
    parser.add_argument("--samples", type=int, default=HAZE_SAMPLES, help="per render, both renderers")
    parser.add_argument("--size", type=int, default=SIZE)
    args = parser.parse_args(argv)
    body = scene_body(args.size, args.runs, args.samples, args.samples)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        run = run_blender(body, Path(folder), timeout=7200, numba_cache=shared_numba_cache(),
                            env={"HAZE_TEST_RENDER": "1"})
        if run.returncode != 0 or not run.result:
            print(run.describe())
            return 1
        print(f"{args.runs} x {args.samples} spp per renderer, {args.size}x{args.size}: "
              f"{time.perf_counter() - start:.0f} s in all")
        failed = False
        for name, case in (("procedural cloud", run.result), ("volume cube (geometry nodes)",
                                                               run.result["volume_cube"])):
            paths = case["renders"]
            haze = np.stack([read_exr(p) for p in paths["haze"]])
            cycles = np.stack([read_exr(p) for p in paths["cycles"]])
            comparison = compare_images(haze, cycles)
            print(f"{name}: media {case['media']}, warnings {case['warnings']}")
            print("  " + comparison.summary())
            try:
                assert_agree(comparison)
                print("  agrees with Cycles within noise")
            except AssertionError as error:
                failed = True
                print(f"  DISAGREES: {error}")
    return 1 if failed else 0
