"""Blender scenes whose look comes from shader nodes: a textured Cornell box and an HDRI-lit
floor with two balls. Built with Blender data only (no operators), so the gallery
(examples/blender_gallery.py), the convergence benchmark (bench/blend_scenes.py) and the
tests (tests/test_addon_hdri.py) render the very same scenes.

Both use only what Haze evaluates per shading point (issue 14): Texture Coordinate,
Mapping, Checker, Noise, Color Ramp, Map Range, Image and Environment textures.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import bpy
import numpy as np

REPO = Path(__file__).resolve().parents[1]
for _path in (REPO, REPO / "examples"):  # examples/bpy_helpers: shared builders
    if str(_path) not in sys.path:  # appended: an installed Haze's renderer comes first
        sys.path.append(str(_path))

import blender_cornell as C  # noqa: E402
import bpy_helpers as H  # noqa: E402

from renderer.imageio import write_exr  # noqa: E402

# ------------------------------------------------------------------ textured Cornell box


def uv_quad(name: str, corners, material, scale: float = 1.0) -> bpy.types.Object:
    """blender_cornell.quad with a UV map spanning [0, scale]^2 over the quad."""
    obj = C.quad(name, corners, material)
    uv = obj.data.uv_layers.new(name="UVMap")
    for loop, (u, v) in zip(obj.data.loops, [(0, 0), (1, 0), (1, 1), (0, 1)]):
        uv.data[loop.index].uv = (u * scale, v * scale)
    return obj


def checker_floor() -> bpy.types.Material:
    """Principled: Base Color from a Checker on Generated coordinates; Roughness from a Noise
    Texture through Map Range, so the highlight of the lamp breaks up."""
    material, tree, out = C.node_material("Checker Floor")
    n, link = tree.nodes.new, tree.links.new
    bsdf = n("ShaderNodeBsdfPrincipled")
    coords = n("ShaderNodeTexCoord")
    checker = n("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 8.0
    checker.inputs["Color1"].default_value = (0.75, 0.72, 0.66, 1)
    checker.inputs["Color2"].default_value = (0.12, 0.14, 0.2, 1)
    link(coords.outputs["Generated"], checker.inputs["Vector"])
    link(checker.outputs["Color"], bsdf.inputs["Base Color"])
    noise = n("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 6.0
    link(coords.outputs["Object"], noise.inputs["Vector"])
    ranged = n("ShaderNodeMapRange")
    ranged.inputs["To Min"].default_value = 0.15
    ranged.inputs["To Max"].default_value = 0.7
    link(noise.outputs["Fac"], ranged.inputs["Value"])
    link(ranged.outputs["Result"], bsdf.inputs["Roughness"])
    link(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return material


def image_wall() -> bpy.types.Material:
    """Diffuse of Blender's generated colour grid (8-bit sRGB) on the quad's UVs."""
    material, tree, out = C.node_material("Grid Wall")
    n, link = tree.nodes.new, tree.links.new
    image = bpy.data.images.new("Color Grid", 128, 128, alpha=False, float_buffer=False)
    image.generated_type = "COLOR_GRID"
    texture = n("ShaderNodeTexImage")
    texture.image = image
    bsdf = n("ShaderNodeBsdfDiffuse")
    link(n("ShaderNodeTexCoord").outputs["UV"], texture.inputs["Vector"])
    link(texture.outputs["Color"], bsdf.inputs["Color"])
    link(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return material


def marble_box() -> bpy.types.Material:
    """Diffuse coloured by a Color Ramp of a distorted Noise Texture in object space."""
    material, tree, out = C.node_material("Marble")
    n, link = tree.nodes.new, tree.links.new
    noise = n("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 3.0
    noise.inputs["Detail"].default_value = 6.0
    noise.inputs["Distortion"].default_value = 1.5
    link(n("ShaderNodeTexCoord").outputs["Object"], noise.inputs["Vector"])
    ramp = n("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].position = 0.35
    ramp.color_ramp.elements[0].color = (0.08, 0.2, 0.35, 1)
    ramp.color_ramp.elements[1].position = 0.65
    ramp.color_ramp.elements[1].color = (0.9, 0.85, 0.75, 1)
    link(noise.outputs["Fac"], ramp.inputs["Fac"])
    bsdf = n("ShaderNodeBsdfDiffuse")
    link(ramp.outputs["Color"], bsdf.inputs["Color"])
    link(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return material


def textured_cornell(size: int) -> bpy.types.Scene:
    """blender_cornell's box with a checker/noise Principled floor, an image on the back wall
    and a noise-marbled cube; camera, lamp and black world as the fog box's."""
    scene = C.clear_scene()
    C.build_cornell_walls(scene)
    h, top = C.BOX_HALF, 2.0 * C.BOX_HALF
    for name in ("Floor", "Back"):
        bpy.data.objects.remove(bpy.data.objects[name], do_unlink=True)
    C.quad("Floor", [(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], checker_floor())
    uv_quad("Back", [(-h, h, 0), (h, h, 0), (h, h, top), (-h, h, top)], image_wall(), scale=2.0)
    cube = C.box("Marble Cube", (0.35, 0.25, 0.35), 0.35, marble_box())
    cube.rotation_euler = (0.0, 0.0, math.radians(25.0))
    C.add_camera(scene, (0.0, -3.4, 1.0), (90.0, 0.0, 0.0), lens=35.0)
    C.black_world(scene)
    return _sized(scene, size)


# ------------------------------------------------------------------ HDRI world

HDRI_W, HDRI_H = 256, 128
SUN_ROW, SUN_COL = 96, 40  # from the bottom: about 45 degrees up


def sky_pixels() -> np.ndarray:
    """(HDRI_H, HDRI_W, 4) float32, row 0 at the bottom: a coloured sky brightening towards
    the zenith, a dim ground, and a 2x2-pixel sun of radiance 900 over a sky of 0.04 to 1.1."""
    v = (np.arange(HDRI_H) + 0.5) / HDRI_H
    u = (np.arange(HDRI_W) + 0.5) / HDRI_W
    z = -np.cos(math.pi * v)
    sky = np.clip(z, 0.0, None)[:, None] * (1.0 + 0.4 * np.sin(2 * math.pi * u))[None, :]
    rgba = np.ones((HDRI_H, HDRI_W, 4), np.float32)
    rgba[..., 0] = 0.06 + 0.25 * sky
    rgba[..., 1] = 0.05 + 0.4 * sky
    rgba[..., 2] = 0.04 + 0.8 * sky
    rgba[SUN_ROW:SUN_ROW + 2, SUN_COL:SUN_COL + 2, :3] = (900.0, 800.0, 650.0)
    return rgba


def hdri_world(scene: bpy.types.Scene, path: Path, projection: str) -> None:
    """Texture Coordinate > Mapping (30 degrees about z) > Environment Texture > Background
    (Strength 1.5), the image written to `path`."""
    # Written as an artist's HDRI arrives: a linear EXR (scanlines top-down), loaded as
    # Linear Rec.709. (Saving a generated float image from Blender instead writes it
    # display-encoded and tags it sRGB, which Cycles and Blender then decode differently.)
    write_exr(str(path), sky_pixels()[::-1, :, :3])
    world = bpy.data.worlds.new("HDRI")
    C.ensure_nodes(world)
    nodes, links = world.node_tree.nodes, world.node_tree.links
    background = nodes["Background"]
    background.inputs["Strength"].default_value = 1.5
    texture = nodes.new("ShaderNodeTexEnvironment")
    texture.image = bpy.data.images.load(str(path))
    texture.image.colorspace_settings.name = "Linear Rec.709"
    texture.projection = projection
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(30.0))
    coords = nodes.new("ShaderNodeTexCoord")
    links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
    links.new(texture.outputs["Color"], background.inputs["Color"])
    scene.world = world


def hdri_scene(size: int, folder: Path, projection: str = "EQUIRECTANGULAR") -> bpy.types.Scene:
    """A grey floor, a diffuse ball and a rough metal ball (Principled, GGX) under the HDRI
    world, its image written into `folder`."""
    scene = C.clear_scene()
    hdri_world(scene, Path(folder) / "sky.exr", projection)
    H.floor_plane("Floor", 3.0, C.diffuse_material("Floor", (0.6, 0.6, 0.6)))
    H.uv_sphere("Ball", (-0.6, 0.3, 0.5), 0.5, C.diffuse_material("Ball", (0.7, 0.4, 0.3)))
    H.uv_sphere("Metal", (0.7, 0.0, 0.45), 0.45, H.principled_material(
        "Metal", Base_Color=(0.9, 0.9, 0.9), Metallic=1.0, Roughness=0.3, distribution="GGX"))
    C.add_camera(scene, (0.0, -4.5, 1.3), (80.0, 0.0, 0.0), lens=30.0)
    return _sized(scene, size)


def _sized(scene: bpy.types.Scene, size: int) -> bpy.types.Scene:
    render = scene.render
    render.resolution_x = render.resolution_y = size
    render.resolution_percentage = 100
    return scene
