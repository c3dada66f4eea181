"""A Blender scene of several UV-mapped, image-textured meshes survives the scene folder:
exported with File > Export > Haze Scene (bpy.ops.export_scene.haze) and rendered by the
command line, it gives F12's image (issue 42: meshes sharing the "UVMap" name got another
mesh's UVs from the folder, or a traceback when their triangle counts differed).

Every mesh has a UV map called "UVMap" (as Blender names them) with its own layout, a
different number of triangles and its own image of a different size; with the same seed
and one worker the two renders are the same computation, so they must agree bit for bit.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from bench.blender import REPO, shared_numba_cache
from helpers.blender_runs import blender_fixture
from renderer.imageio import read_exr
from renderer.scenefile import load_scene

pytestmark = [pytest.mark.bpy, pytest.mark.slow]

SIZE_X, SIZE_Y = 48, 32

BODY = rf'''
import math
import os
import bpy
import numpy as np
import bpy_helpers as H
import blender_cornell as C


def textured_grid(name, x0, columns, rows, image_size, uv_of):
    """A 1 x 1.6 grid of columns x rows quads at x = x0, UV map "UVMap" from uv_of(s, t),
    textured by its own float image of image_size (width, height): a colour ramp per axis
    with a bright corner texel, so a texture read with the wrong UVs or image shows."""
    vertices = [(x0 + s / columns, 1.6 * t / rows, 0.0) for t in range(rows + 1) for s in range(columns + 1)]
    faces = [(r * (columns + 1) + c, r * (columns + 1) + c + 1, (r + 1) * (columns + 1) + c + 1,
              (r + 1) * (columns + 1) + c) for r in range(rows) for c in range(columns)]
    material = bpy.data.materials.new(name)
    H.ensure_nodes(material)
    tree = material.node_tree
    width, height = image_size
    image = bpy.data.images.new(name, width, height, alpha=False, float_buffer=True)
    u, v = np.meshgrid(np.linspace(0.0, 1.0, width), np.linspace(0.0, 1.0, height))
    rgba = np.stack([u, v, 1.0 - u * v, np.ones_like(u)], axis=-1).astype(np.float32)
    rgba[-1, -1, :3] = (4.0, 0.2, 0.2)
    image.pixels.foreach_set(rgba.ravel())
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    texture.interpolation = "Closest"
    coords = tree.nodes.new("ShaderNodeTexCoord")
    tree.links.new(coords.outputs["UV"], texture.inputs["Vector"])
    tree.links.new(texture.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    obj = H.new_object(name, vertices, faces, material)
    uv = obj.data.uv_layers.new(name="UVMap")
    for loop in obj.data.loops:
        x, y, _ = obj.data.vertices[loop.vertex_index].co
        uv.data[loop.index].uv = uv_of((x - x0), y / 1.6)
    return obj


def main():
    H.enable_addon()
    scene = C.clear_scene()
    H.world_color(scene, (0.3, 0.3, 0.3), 1.0)
    textured_grid("Left", -1.7, 1, 1, (4, 3), lambda s, t: (s, t))
    textured_grid("Middle", -0.5, 2, 3, (16, 8), lambda s, t: (1.0 - t, s))  # turned a quarter
    textured_grid("Right", 0.7, 3, 1, (7, 11), lambda s, t: (0.25 + 0.5 * s, 0.9 - 0.8 * t))
    H.add_light("SUN", "Sun", (0.0, 0.0, 5.0), (20.0, 10.0, 0.0), energy=3.0)
    C.add_camera(scene, (0.0, 0.8, 4.0), (0.0, 0.0, 0.0), lens=35.0)
    scene.render.resolution_x, scene.render.resolution_y = {SIZE_X}, {SIZE_Y}
    scene.render.resolution_percentage = 100
    H.configure_haze(scene, 8, 3, seed=7, workers=1)
    out = os.getcwd()
    result = {{"f12": H.render_exr(scene, os.path.join(out, "f12.exr"))}}
    folder = os.path.join(out, "export")
    result["export"] = sorted(bpy.ops.export_scene.haze(filepath=folder))
    result["export_folder"] = folder
    return result
'''


exported = blender_fixture(BODY, "uv_meshes", timeout=1800)


def test_the_export_keeps_each_meshes_uvs_and_image(exported):
    assert exported["export"] == ["FINISHED"]
    scene = load_scene(exported["export_folder"])
    meshes = {mesh.name: mesh for mesh in scene.meshes}
    triangles = {name: len(mesh.indices) for name, mesh in meshes.items()}
    assert triangles == {"Left": 2, "Middle": 12, "Right": 6}
    uvs = {}
    for material in scene.materials:
        # Each material reads the active UV map ("uv:", the Texture Coordinate node's UV) and
        # its own image; the mesh of the same name carries that attribute.
        assert material.program.images == [material.name]
        (name,) = material.program.attributes
        (uv,) = [a.values for a in meshes[material.name].attributes if a.name == name]
        assert uv.shape == (triangles[material.name], 3, 2)
        uvs[material.name] = (float(uv[..., 0].min()), float(uv[..., 0].max()),
                              float(uv[..., 1].min()), float(uv[..., 1].max()))
    np.testing.assert_allclose(uvs["Left"], (0.0, 1.0, 0.0, 1.0), atol=1e-6)
    np.testing.assert_allclose(uvs["Middle"], (0.0, 1.0, 0.0, 1.0), atol=1e-6)
    np.testing.assert_allclose(uvs["Right"], (0.25, 0.75, 0.1, 0.9), atol=1e-6)
    images = {image.name: image.pixels.shape for image in scene.images}
    assert images == {"Left": (3, 4, 4), "Middle": (8, 16, 4), "Right": (11, 7, 4)}


def test_the_cli_render_of_the_export_equals_f12(exported, tmp_path):
    output = tmp_path / "cli.exr"
    command = [sys.executable, "-m", "renderer", "render", exported["export_folder"], "-o", str(output),
               "--workers", "1", "--no-png"]
    env = {"NUMBA_CACHE_DIR": str(shared_numba_cache()), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    process = subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True, timeout=1200)
    assert process.returncode == 0, process.stderr
    f12, cli = read_exr(exported["f12"]), read_exr(output)
    assert f12.shape == cli.shape == (SIZE_Y, SIZE_X, 3)
    assert f12.mean() > 0.05 and f12.std() > 0.05  # lit, and textured: not a flat image
    np.testing.assert_array_equal(cli, f12)
