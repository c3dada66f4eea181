"""Volumes authored in Blender without a Volume object, through bpy, exported by the add-on.

* The usual procedural cloud (Texture Coordinate Object -> Noise -> Map Range -> Principled
  Volume Density, inside a rotated, scaled cube, under a sun) exports as a procedural
  medium (renderer.media.procedural).
* A mesh object whose geometry nodes output a volume (Volume Cube with a Noise density, Set
  Material to a Principled Volume) exports its grid (it used to be skipped).

Both export as they should (quick, no kernel compiles), and both render as Cycles renders
them (slow): RUNS renders with independent seeds per renderer in one Blender process,
compared by image means and block z-scores from the renders' own variance
(bench.comparison.compare_images). tools/procedural_volume_cycles.py prints the same comparison.
The renders became affordable when the trackers started calling the shader interpreter
through its address (renderer.kernels.native_call): before, a procedural medium's first
render spent over 15 CPU minutes compiling the interpreter again inside each tracker."""

from __future__ import annotations

import numpy as np
import pytest

from bench.blender import run_blender, shared_numba_cache
from bench.comparison import assert_agree, compare_images
from renderer.imageio import read_exr

pytestmark = [pytest.mark.bpy]

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


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """Both scenes exported, not rendered (no kernel compiles: quick)."""
    run = run_blender(scene_body(), tmp_path_factory.mktemp("exported"), timeout=600)
    assert run.returncode == 0 and run.result, run.describe()
    return run.result


def test_cloud_exports_as_a_procedural_medium(exported):
    assert [(t, p) for _, t, p in exported["media"]] == [("grid", True)], exported["media"]
    assert not exported["warnings"], exported["warnings"]


def test_volume_cube_modifier_exports_its_grid(exported):
    case = exported["volume_cube"]
    assert [(t, p) for _, t, p in case["media"]] == [("grid", False)], case["media"]
    assert not case["warnings"], case["warnings"]


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """Both scenes rendered RUNS times by Cycles and by Haze (one Blender process)."""
    run = run_blender(scene_body(), tmp_path_factory.mktemp("rendered"), timeout=2400,
                      numba_cache=shared_numba_cache(), env={"HAZE_TEST_RENDER": "1"})
    assert run.returncode == 0 and run.result, run.describe()
    return run.result


def _assert_renders_agree(case: dict) -> None:
    haze = np.stack([read_exr(p) for p in case["renders"]["haze"]])
    cycles = np.stack([read_exr(p) for p in case["renders"]["cycles"]])
    assert haze.shape == cycles.shape == (RUNS, SIZE, SIZE, 3)
    assert np.isfinite(haze).all()
    assert_agree(compare_images(haze, cycles))


@pytest.mark.slow
def test_procedural_cloud_agrees_with_cycles(rendered):
    _assert_renders_agree(rendered)


@pytest.mark.slow
def test_volume_cube_agrees_with_cycles(rendered):
    _assert_renders_agree(rendered["volume_cube"])
