"""Closure inputs driven by shader programs, against Cycles through bpy (issue 14 item 1):
textured emission, Alpha and IOR.

* A textured emitter: an Emission shader whose Color is a Checker (two colours that differ
  per channel) lights a wall and a floor. Camera rays see the checker directly; the wall is
  lit through light sampling, which must use the radiance the program gives at the light
  point (renderer.integrator.program_stage), not the emitter's table value (1 per channel).
* An alpha-textured leaf: a Principled BSDF whose Alpha is a Checker mapped to 0.15..0.85,
  over a floor whose Principled IOR is a Checker mapped to 1.1..2.2 (single-scatter GGX,
  roughness 0.3), under a sun: camera rays see through the leaf, and shadow rays from the
  floor walk through it with the program's transparency at each point.

* Normal Map (tangent space, MikkTSpace tangents exported from Blender) on a Principled
  BSDF's Normal, on a plane turned about z and on a mirrored one.

* Bump (issue 14 item 2): a Noise Texture height on a Principled BSDF's Normal, on a plane
  under a sun; a second plane bumps after a Normal Map (Bump's Normal input). Cycles'
  Filter Width is small (0.02) so its height offsets (a fraction of a pixel's footprint)
  approach the exact gradient Haze takes (renderer.shading.bump).

* Displacement (a Material Output's Displacement, rendered as bump as Cycles' default
  method, Bump Only, does): a Displacement node of a Noise height in world space on one
  plane, in object space on a plane scaled by 2 (its offsets are in object units).

* A world program (issue 14 item 5): a gradient sky (Generated = the direction, through
  Math and a Color Ramp) mixed half and half with an HDRI (an Environment Texture of a
  small linear EXR whose colour varies with azimuth and height) times a warm colour,
  lighting a diffuse ball on a floor, through the environment map Haze evaluates from the
  program.

The scenes render in one Blender process (one kernel compile); Haze and Cycles agree within
noise (bench.comparison.assert_agree).
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.comparison import assert_agree, compare_images
from helpers.blender_runs import blender_fixture
from renderer.imageio import read_exr

pytestmark = [pytest.mark.bpy, pytest.mark.slow]

RUNS = 4
SIZE = 32
CYCLES_SAMPLES, HAZE_SAMPLES = 32, 64

SCENE_BODY = rf'''
import math
import os
import bpy
import numpy as np
import bpy_helpers as H
import blender_cornell as C
from renderer.imageio import write_exr

SIZE = {SIZE}


def checker(tree, scale, color1=(1, 1, 1), color2=(0, 0, 0)):
    node = tree.nodes.new("ShaderNodeTexChecker")
    node.inputs["Scale"].default_value = scale
    node.inputs["Color1"].default_value = (*color1, 1)
    node.inputs["Color2"].default_value = (*color2, 1)
    tree.links.new(tree.nodes.new("ShaderNodeTexCoord").outputs["UV"], node.inputs["Vector"])
    return node


def mapped(tree, socket, low, high):
    node = tree.nodes.new("ShaderNodeMapRange")
    node.inputs["To Min"].default_value = low
    node.inputs["To Max"].default_value = high
    tree.links.new(socket, node.inputs["Value"])
    return node.outputs["Result"]


def checker_emitter():
    material, tree, out = C.node_material("Checker Emitter")
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 3.0
    tex = checker(tree, 3.0, (1.0, 0.8, 0.3), (0.1, 0.3, 1.0))
    tree.links.new(tex.outputs["Color"], emission.inputs["Color"])
    tree.links.new(emission.outputs["Emission"], out.inputs["Surface"])
    return material


def alpha_leaf():
    material, tree, out = C.node_material("Leaf")
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.2, 0.6, 0.1, 1)
    tree.links.new(mapped(tree, checker(tree, 3.0).outputs["Fac"], 0.15, 0.85), bsdf.inputs["Alpha"])
    tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return material


def ior_floor():
    material, tree, out = C.node_material("IOR Floor")
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.distribution = "GGX"
    bsdf.inputs["Base Color"].default_value = (0.3, 0.3, 0.35, 1)
    bsdf.inputs["Roughness"].default_value = 0.3
    tree.links.new(mapped(tree, checker(tree, 4.0).outputs["Fac"], 1.1, 2.2), bsdf.inputs["IOR"])
    tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return material


def normal_mapped():
    """Principled (single-scatter GGX) with a tangent-space Normal Map of a checker colour."""
    material, tree, out = C.node_material("Normal Mapped")
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.distribution = "GGX"
    bsdf.inputs["Base Color"].default_value = (0.6, 0.5, 0.4, 1)
    bsdf.inputs["Roughness"].default_value = 0.35
    normal_map = tree.nodes.new("ShaderNodeNormalMap")
    normal_map.inputs["Strength"].default_value = 0.8
    tex = checker(tree, 4.0, (0.8, 0.5, 0.8), (0.3, 0.65, 0.9))
    tree.links.new(tex.outputs["Color"], normal_map.inputs["Color"])
    tree.links.new(normal_map.outputs["Normal"], bsdf.inputs["Normal"])
    tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return material


def bumped(name, after_normal_map=False):
    """Principled (single-scatter GGX) whose Normal is a Bump of a Noise height."""
    material, tree, out = C.node_material(name)
    n, link = tree.nodes.new, tree.links.new
    bsdf = n("ShaderNodeBsdfPrincipled")
    bsdf.distribution = "GGX"
    bsdf.inputs["Base Color"].default_value = (0.55, 0.5, 0.45, 1)
    bsdf.inputs["Roughness"].default_value = 0.4
    noise = n("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 3.0
    noise.inputs["Detail"].default_value = 1.0
    bump = n("ShaderNodeBump")
    bump.inputs["Distance"].default_value = 0.25
    bump.inputs["Filter Width"].default_value = 0.02
    link(noise.outputs["Fac"], bump.inputs["Height"])
    if after_normal_map:
        normal_map = n("ShaderNodeNormalMap")
        normal_map.inputs["Strength"].default_value = 0.6
        tex = checker(tree, 2.0, (0.8, 0.5, 0.8), (0.3, 0.65, 0.9))
        link(tex.outputs["Color"], normal_map.inputs["Color"])
        link(normal_map.outputs["Normal"], bump.inputs["Normal"])
    link(bump.outputs["Normal"], bsdf.inputs["Normal"])
    link(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return material


def displaced(name, space="OBJECT"):
    """Principled (single-scatter GGX) over a Material Output Displacement: a Displacement
    node of a Noise height, which Cycles renders as bump (the default method, Bump Only)."""
    material, tree, out = C.node_material(name)
    n, link = tree.nodes.new, tree.links.new
    bsdf = n("ShaderNodeBsdfPrincipled")
    bsdf.distribution = "GGX"
    bsdf.inputs["Base Color"].default_value = (0.5, 0.55, 0.45, 1)
    bsdf.inputs["Roughness"].default_value = 0.35
    noise = n("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 3.0
    noise.inputs["Detail"].default_value = 1.0
    displacement = n("ShaderNodeDisplacement")
    displacement.space = space
    displacement.inputs["Scale"].default_value = 0.2
    link(noise.outputs["Fac"], displacement.inputs["Height"])
    link(displacement.outputs["Displacement"], out.inputs["Displacement"])
    link(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return material


def render(scene, name):
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    folder = os.path.join(os.getcwd(), name)
    os.makedirs(folder, exist_ok=True)
    return H.render_both(scene, folder, {RUNS}, {CYCLES_SAMPLES}, {HAZE_SAMPLES}, 3)


def emitter_scene():
    scene = C.clear_scene()
    C.black_world(scene)
    grey = C.diffuse_material("Grey", (0.7, 0.7, 0.7))
    H.new_object("Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [(0, 1, 2, 3)], grey)
    H.new_object("Wall", [(-3, 1.5, 0), (3, 1.5, 0), (3, 1.5, 3), (-3, 1.5, 3)], [(0, 1, 2, 3)], grey)
    # A vertical panel facing +x, near the wall: its checker lights the wall and the floor.
    H.uv_quad("Emitter", [(-1, -0.5, 0.2), (-1, 1.4, 0.2), (-1, 1.4, 1.8), (-1, -0.5, 1.8)],
              checker_emitter())
    C.add_camera(scene, (2.5, -3.5, 1.5), (83.5, 0.0, 35.0), lens=30.0)
    return render(scene, "emitter")


def leaf_scene():
    scene = C.clear_scene()
    H.world_color(scene, (0.3, 0.35, 0.4), 1.0)
    H.uv_quad("Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], ior_floor())
    H.uv_quad("Leaf", [(-1, -1, 0.8), (1, -1, 0.8), (1, 1, 0.8), (-1, 1, 0.8)], alpha_leaf())
    H.add_light("SUN", "Sun", (0.0, 0.0, 5.0), (40.0, 0.0, -60.0), energy=3.0, angle=math.radians(4.0))
    C.add_camera(scene, (0.0, -2.6, 2.6), (55.0, 0.0, 0.0), lens=30.0)
    return render(scene, "leaf")


def normal_map_scene():
    """Two normal-mapped planes: one turned about z (its tangents turn with it), one mirrored
    (scale x -1: the bitangent sign flips in world space). They must not overlap: at x = -1.1
    the turned plane's corner reached x = 0.27, over the mirrored one's edge at 0.1 in the same
    plane z = 0, and which of the two a ray met there was the renderers' tie-break (Haze and
    Cycles chose differently: 2 x 2 pixels 30-45 % apart, block z 6.7)."""
    scene = C.clear_scene()
    H.world_color(scene, (0.4, 0.45, 0.5), 1.0)
    material = normal_mapped()
    turned = H.uv_quad("Turned", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], material)
    turned.location, turned.rotation_euler = (-1.3, 0.0, 0.0), (0.0, 0.0, math.radians(30.0))
    mirrored = H.uv_quad("Mirrored", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], material)
    mirrored.location, mirrored.scale = (1.1, 0.0, 0.0), (-1.0, 1.0, 1.0)
    H.add_light("SUN", "Sun", (0.0, 0.0, 5.0), (35.0, 0.0, 60.0), energy=3.0, angle=math.radians(4.0))
    C.add_camera(scene, (0.0, -3.0, 2.4), (51.0, 0.0, 0.0), lens=26.0)
    return render(scene, "normal_map")


def bump_scene():
    scene = C.clear_scene()
    H.world_color(scene, (0.4, 0.45, 0.5), 1.0)
    H.uv_quad("Bumped", [(-2.1, -1, 0), (-0.1, -1, 0), (-0.1, 1, 0), (-2.1, 1, 0)], bumped("Bumped"))
    H.uv_quad("Mapped", [(0.1, -1, 0), (2.1, -1, 0), (2.1, 1, 0), (0.1, 1, 0)], bumped("Mapped", True))
    H.add_light("SUN", "Sun", (0.0, 0.0, 5.0), (50.0, 0.0, 60.0), energy=3.0, angle=math.radians(4.0))
    C.add_camera(scene, (0.0, -3.0, 2.4), (51.0, 0.0, 0.0), lens=26.0)
    return render(scene, "bump")


def displacement_scene():
    """Displacement as bump: in world space on a plane, and in object space (the node's
    default) on a plane of half the size scaled by 2, whose bump is then twice as deep."""
    scene = C.clear_scene()
    H.world_color(scene, (0.4, 0.45, 0.5), 1.0)
    H.uv_quad("World", [(-2.1, -1, 0), (-0.1, -1, 0), (-0.1, 1, 0), (-2.1, 1, 0)],
              displaced("World", "WORLD"))
    scaled = H.uv_quad("Scaled", [(-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0)],
                       displaced("Object"))
    scaled.location, scaled.scale = (1.1, 0.0, 0.0), (2.0, 2.0, 2.0)
    H.add_light("SUN", "Sun", (0.0, 0.0, 5.0), (50.0, 0.0, 60.0), energy=3.0, angle=math.radians(4.0))
    C.add_camera(scene, (0.0, -3.0, 2.4), (51.0, 0.0, 0.0), lens=26.0)
    return render(scene, "displacement")


def gradient_world(scene):
    """A sky: Generated (the direction) -> Z -> 0.5 z + 0.5 -> Color Ramp, warm at the horizon,
    blue at the zenith, dark below."""
    world = bpy.data.worlds.new("Gradient")
    H.ensure_nodes(world)
    tree = world.node_tree
    n, link = tree.nodes.new, tree.links.new
    separate = n("ShaderNodeSeparateXYZ")
    link(n("ShaderNodeTexCoord").outputs["Generated"], separate.inputs["Vector"])
    height = n("ShaderNodeMath")
    height.operation = "MULTIPLY_ADD"
    height.inputs[1].default_value = 0.5
    height.inputs[2].default_value = 0.5
    link(separate.outputs["Z"], height.inputs[0])
    ramp = n("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].position = 0.45
    ramp.color_ramp.elements[0].color = (0.05, 0.04, 0.03, 1)
    ramp.color_ramp.elements[1].position = 0.95
    ramp.color_ramp.elements[1].color = (0.2, 0.45, 1.0, 1)
    middle = ramp.color_ramp.elements.new(0.55)
    middle.color = (1.0, 0.7, 0.4, 1)
    link(height.outputs["Value"], ramp.inputs["Fac"])
    background = tree.nodes["Background"]
    background.inputs["Strength"].default_value = 1.5
    link(ramp.outputs["Color"], background.inputs["Color"])
    scene.world = world


def hdri_pixels(width=64, height=32):
    """RGBA rows from the bottom: warm toward +x (u = 1/2), bluer and brighter upward."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    facing = 0.5 - 0.5 * np.cos(2 * math.pi * u)[None, :]
    up = v[:, None]
    rgba = np.ones((height, width, 4), np.float32)
    rgba[..., 0] = 0.1 + 1.2 * facing * up
    rgba[..., 1] = 0.1 + 0.5 * facing + 0.3 * up
    rgba[..., 2] = 0.1 + 0.8 * up * up
    return rgba


def hdri_gradient_world(scene):
    """gradient_world's ramp mixed half and half with HDRI x (1, 0.85, 0.6)."""
    gradient_world(scene)
    tree = scene.world.node_tree
    n, link = tree.nodes.new, tree.links.new
    path = os.path.join(os.getcwd(), "sky.exr")
    write_exr(path, hdri_pixels()[::-1, :, :3])  # EXR scanlines run top-down
    texture = n("ShaderNodeTexEnvironment")
    texture.image = bpy.data.images.load(path)
    texture.image.colorspace_settings.name = "Linear Rec.709"
    def socket(sockets, identifier):  # Mix repeats its names per data type
        return next(s for s in sockets if s.identifier == identifier)

    tint = n("ShaderNodeMix")
    tint.data_type, tint.blend_type = "RGBA", "MULTIPLY"
    socket(tint.inputs, "Factor_Float").default_value = 1.0
    link(texture.outputs["Color"], socket(tint.inputs, "A_Color"))
    socket(tint.inputs, "B_Color").default_value = (1.0, 0.85, 0.6, 1.0)
    mix = n("ShaderNodeMix")
    mix.data_type = "RGBA"
    socket(mix.inputs, "Factor_Float").default_value = 0.5
    background = tree.nodes["Background"]
    link(background.inputs["Color"].links[0].from_socket, socket(mix.inputs, "A_Color"))
    link(socket(tint.outputs, "Result_Color"), socket(mix.inputs, "B_Color"))
    link(socket(mix.outputs, "Result_Color"), background.inputs["Color"])


def gradient_world_scene():
    scene = C.clear_scene()
    hdri_gradient_world(scene)
    grey = C.diffuse_material("Grey", (0.7, 0.7, 0.7))
    H.uv_sphere("Ball", (0.0, 0.0, 0.8), 0.8, grey)
    H.new_object("Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [(0, 1, 2, 3)], grey)
    C.add_camera(scene, (0.0, -3.5, 1.6), (80.0, 0.0, 0.0), lens=30.0)
    return render(scene, "gradient_world")


def main():
    H.enable_addon()
    return {{"emitter": emitter_scene(), "leaf": leaf_scene(), "normal_map": normal_map_scene(),
             "bump": bump_scene(), "displacement": displacement_scene(),
             "gradient_world": gradient_world_scene()}}
'''


renders = blender_fixture(SCENE_BODY, "program_closures", timeout=1800)


def _images(paths: list[str]) -> np.ndarray:
    return np.stack([read_exr(p) for p in paths])


@pytest.mark.parametrize("scene", ["emitter", "leaf", "normal_map", "bump", "displacement", "gradient_world"])
def test_program_driven_closures_agree_with_cycles(renders, scene):
    haze, cycles = _images(renders[scene]["haze"]), _images(renders[scene]["cycles"])
    assert haze.shape == cycles.shape == (RUNS, SIZE, SIZE, 3)
    assert cycles.mean() > 0.01, "the reference image is black: the scene is broken"
    assert_agree(compare_images(haze, cycles))
