"""Shader programs (renderer.shading) against Cycles, through bpy.

Exact node values: Cycles bakes a node's output (Bake, type Emit, through an Emission
shader) on a plane with a UV map into a float image; the exporter compiles the same node
into a program, which runs at the texel centres. They must agree to float32 round-off
(the tolerance below is a few float32 ulps of values of order 1, and a looser one where
Cycles' float32 trigonometry and pow differ from double precision).

A textured scene: Haze and Cycles agree within noise (bench.comparison.assert_agree), with an
Image Texture (Blender-generated colour grid, sRGB bytes), a Checker driving Principled
Base Color and another Metallic (single-scatter GGX), a Gradient through Map Range driving
Roughness, and a Mix
Shader whose factor is a Color Ramp of a Gradient, the other side coloured by a (byte, per
vertex) colour attribute. The same scene exported with the
export operator renders through the CLI to the same image as F12.
"""

from __future__ import annotations

import subprocess
import sys

import bake_cases_nodes
import bake_cases_textures
import numpy as np
import pytest

from bench.blender import REPO, shared_numba_cache
from bench.comparison import assert_agree, compare_images
from helpers.blender_runs import blender_fixture
from renderer.imageio import read_exr

pytestmark = [pytest.mark.bpy, pytest.mark.slow]

BAKE_SIZE = 32
# |Haze - Cycles bake| / max(1, |value|). The program runs at the UVs Cycles baked (they
# are up to 6e-5 off the texel centres), but Cycles' own float32 coordinates still differ
# from ours by round-off, which steep operations (divide, power, logarithm near 0; wrap)
# amplify to 4e-5. Color Ramps (Blender's own ColorRamp.evaluate in Cycles' 257-entry
# tables) agree to 1e-6: TIGHT_CASES.
TOLERANCE = 1e-4

BAKE_BODY = rf'''
import bpy
import numpy as np
import bpy_helpers as H
import blender_cornell as C
import bake_cases_textures as T
import bake_cases_nodes as N

SIZE = {BAKE_SIZE}


def plane():
    scene = C.clear_scene()
    obj = H.new_object("Plane", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [(0, 1, 2, 3)])
    corners = [(0, 0), (1, 0), (1, 1), (0, 1)]
    uv = obj.data.uv_layers.new(name="UVMap")
    for loop, (u, v) in zip(obj.data.loops, corners):
        uv.data[loop.index].uv = (u, v)
    # Created after the UVs are written: a new attribute invalidates references to the others.
    col = obj.data.color_attributes.new("Col", "FLOAT_COLOR", "CORNER")
    for loop, (u, v) in zip(obj.data.loops, corners):
        col.data[loop.index].color = (u, v, 0.5, 1.0)  # affine over the plane, as UVs
    return scene, obj


def by_id(sockets, identifier):
    return next(s for s in sockets if s.identifier == identifier)


def texture_vector(tree, source):
    coords = tree.nodes.new("ShaderNodeTexCoord")
    return coords.outputs[source]


def case_nodes(tree, name):
    """(node output to bake, nodes) for case `name`."""
    n = tree.nodes.new
    link = tree.links.new
    if name.startswith("tex_"):
        return T.case_nodes(tree, name)
    if name.startswith("node_"):
        return N.case_nodes(tree, name)
    if name.startswith("checker"):
        node = n("ShaderNodeTexChecker")
        node.inputs["Scale"].default_value = 7.3
        node.inputs["Color1"].default_value = (0.9, 0.2, 0.1, 1)
        node.inputs["Color2"].default_value = (0.1, 0.4, 0.8, 1)
        link(texture_vector(tree, "UV" if name == "checker_uv" else "Object"), node.inputs["Vector"])
        return node.outputs["Color"]
    if name.startswith("mapping_"):
        node = n("ShaderNodeMapping")
        node.vector_type = name[len("mapping_"):].upper()
        by_id(node.inputs, "Location").default_value = (0.3, -0.2, 0.1)
        node.inputs["Rotation"].default_value = (0.4, 0.7, 1.1)
        node.inputs["Scale"].default_value = (1.5, 0.5, 2.0)
        link(texture_vector(tree, "Object"), node.inputs["Vector"])
        return node.outputs["Vector"]
    if name.startswith("math_"):
        node = n("ShaderNodeMath")
        node.operation = name[len("math_"):].upper()
        sep = n("ShaderNodeSeparateXYZ")
        link(texture_vector(tree, "Object"), sep.inputs["Vector"])
        link(sep.outputs["X"], node.inputs[0])
        link(sep.outputs["Y"], node.inputs[1])
        node.inputs[2].default_value = 0.35
        return node.outputs["Value"]
    if name.startswith("mix_"):
        node = n("ShaderNodeMix")
        node.data_type = "RGBA"
        node.blend_type = name[len("mix_"):].upper()
        sep = n("ShaderNodeSeparateXYZ")
        link(texture_vector(tree, "UV"), sep.inputs["Vector"])
        link(sep.outputs["X"], by_id(node.inputs, "Factor_Float"))
        link(texture_vector(tree, "UV"), by_id(node.inputs, "A_Color"))
        by_id(node.inputs, "B_Color").default_value = (0.2, 0.7, 0.4, 1)
        return by_id(node.outputs, "Result_Color")
    if name.startswith("gradient_"):
        node = n("ShaderNodeTexGradient")
        node.gradient_type = name[len("gradient_"):].upper()
        link(texture_vector(tree, "Object"), node.inputs["Vector"])
        return node.outputs["Fac"]
    if name.startswith("ramp_"):
        grad = n("ShaderNodeTexGradient")
        link(texture_vector(tree, "UV"), grad.inputs["Vector"])
        node = n("ShaderNodeValToRGB")
        ramp = node.color_ramp
        ramp.interpolation = name[len("ramp_"):].upper()
        ramp.elements[0].color = (0.9, 0.1, 0.2, 1)
        ramp.elements[1].position = 0.7
        ramp.elements.new(0.35).color = (0.1, 0.8, 0.3, 1)
        link(grad.outputs["Fac"], node.inputs["Fac"])
        return node.outputs["Color"]
    if name == "map_range":
        sep = n("ShaderNodeSeparateXYZ")
        link(texture_vector(tree, "UV"), sep.inputs["Vector"])
        node = n("ShaderNodeMapRange")
        node.interpolation_type = "SMOOTHSTEP"
        node.inputs["From Min"].default_value = 0.2
        node.inputs["From Max"].default_value = 0.8
        link(sep.outputs["X"], node.inputs["Value"])
        return node.outputs["Result"]
    if name == "image":
        image = bpy.data.images.new("Grid", 37, 23, alpha=False, float_buffer=False)
        image.generated_type = "COLOR_GRID"
        node = n("ShaderNodeTexImage")
        node.image = image
        node.interpolation = "Linear"
        mapping = n("ShaderNodeMapping")
        mapping.inputs["Scale"].default_value = (1.7, 1.3, 1.0)
        link(texture_vector(tree, "UV"), mapping.inputs["Vector"])
        link(mapping.outputs["Vector"], node.inputs["Vector"])
        return node.outputs["Color"]
    if name == "image_closest":
        image = bpy.data.images.new("Grid2", 16, 16, alpha=False, float_buffer=False)
        image.generated_type = "UV_GRID"
        node = n("ShaderNodeTexImage")
        node.image = image
        node.interpolation = "Closest"
        node.extension = "MIRROR"
        mapping = n("ShaderNodeMapping")
        mapping.inputs["Scale"].default_value = (2.5, 1.5, 1.0)
        link(texture_vector(tree, "UV"), mapping.inputs["Vector"])
        link(mapping.outputs["Vector"], node.inputs["Vector"])
        return node.outputs["Color"]
    if name.startswith("noise_"):
        node = n("ShaderNodeTexNoise")
        node.inputs["Scale"].default_value = 3.7
        node.inputs["Detail"].default_value = 4.5 if name == "noise_detail" else 2.0
        node.inputs["Roughness"].default_value = 0.6
        node.inputs["Distortion"].default_value = 0.8 if name == "noise_distortion" else 0.0
        node.normalize = name != "noise_raw"
        link(texture_vector(tree, "Object"), node.inputs["Vector"])
        return node.outputs["Color" if name == "noise_color" else "Fac"]
    if name in ("hsv", "separate_hsv", "combine_hsv"):
        mix = n("ShaderNodeMix")
        mix.data_type = "RGBA"
        link(texture_vector(tree, "UV"), by_id(mix.inputs, "A_Color"))
        by_id(mix.inputs, "B_Color").default_value = (0.9, 0.3, 0.6, 1)
        by_id(mix.inputs, "Factor_Float").default_value = 0.4
        color = by_id(mix.outputs, "Result_Color")
        if name == "hsv":
            node = n("ShaderNodeHueSaturation")
            node.inputs["Hue"].default_value = 0.3
            node.inputs["Saturation"].default_value = 1.4
            node.inputs["Value"].default_value = 0.8
            link(color, node.inputs["Color"])
            return node.outputs["Color"]
        sep = n("ShaderNodeSeparateColor")
        sep.mode = "HSV"
        link(color, sep.inputs["Color"])
        if name == "separate_hsv":
            return sep.outputs["Red"]  # the hue
        comb = n("ShaderNodeCombineColor")
        comb.mode = "HSV"
        for k in range(3):
            link(sep.outputs[k], comb.inputs[k])
        return comb.outputs["Color"]
    if name in ("fresnel", "layer_fresnel", "layer_facing"):
        # A varying normal (the view direction of a bake is the surface normal, +Z).
        tilt = n("ShaderNodeVectorMath")
        tilt.inputs[1].default_value = (0.0, 0.0, 1.2)
        link(texture_vector(tree, "Object"), tilt.inputs[0])
        unit = n("ShaderNodeVectorMath")
        unit.operation = "NORMALIZE"
        link(tilt.outputs["Vector"], unit.inputs[0])
        if name == "fresnel":
            node = n("ShaderNodeFresnel")
            node.inputs["IOR"].default_value = 1.7
        else:
            node = n("ShaderNodeLayerWeight")
            node.inputs["Blend"].default_value = 0.3
        link(unit.outputs["Vector"], node.inputs["Normal"])
        return node.outputs["Facing" if name == "layer_facing" else 0]
    if name == "attribute":
        node = n("ShaderNodeAttribute")
        node.attribute_name = "Col"
        return node.outputs["Fac"]
    if name == "color_attribute":
        return n("ShaderNodeVertexColor").outputs["Color"]  # the render colour attribute
    if name == "uv":
        return texture_vector(tree, "UV")
    if name.startswith("normal_map_"):
        node = n("ShaderNodeNormalMap")
        node.space, strength = {{"tangent": ("TANGENT", 0.7), "tangent_strong": ("TANGENT", 1.6),
                                 "world": ("WORLD", 0.6), "blender_world": ("BLENDER_WORLD", 1.0)}}[name[11:]]
        node.inputs["Strength"].default_value = strength
        color = n("ShaderNodeCombineXYZ")  # a colour that tilts the normal across the plane
        sep = n("ShaderNodeSeparateXYZ")
        link(texture_vector(tree, "UV"), sep.inputs["Vector"])
        link(sep.outputs["X"], color.inputs["X"])
        link(sep.outputs["Y"], color.inputs["Y"])
        color.inputs["Z"].default_value = 0.8
        link(color.outputs["Vector"], node.inputs["Color"])
        return node.outputs["Normal"]
    if name.startswith("bump_"):
        # A height linear over the plane: Cycles' finite differences over its bake
        # differentials and Haze's fixed offsets (renderer.shading.bump) give the same slope.
        node = n("ShaderNodeBump")
        node.invert = name == "bump_invert"
        node.inputs["Strength"].default_value = 0.6 if name == "bump_invert" else 1.0
        node.inputs["Distance"].default_value = 0.7
        height = n("ShaderNodeMath")
        height.operation = "MULTIPLY_ADD"
        sep = n("ShaderNodeSeparateXYZ")
        link(texture_vector(tree, "UV"), sep.inputs["Vector"])
        link(sep.outputs["X"], height.inputs[0])
        height.inputs[1].default_value = 1.5
        link(sep.outputs["Y"], height.inputs[2])
        link(height.outputs["Value"], node.inputs["Height"])
        if name == "bump_after_normal_map":
            normal_map = n("ShaderNodeNormalMap")
            normal_map.inputs["Color"].default_value = (0.6, 0.4, 0.9, 1.0)
            link(normal_map.outputs["Normal"], node.inputs["Normal"])
        return node.outputs["Normal"]
    raise ValueError(name)


def texel_centres():
    k = (np.arange(SIZE) + 0.5) / SIZE
    u, v = np.meshgrid(k, k)  # row 0 of Blender's pixels is v = 0
    return np.stack([u.ravel(), v.ravel()], axis=1)


def bake(obj, name):
    """(baked RGB (SIZE*SIZE, 3), material) of case `name` (Cycles, Emit, 1 sample per texel)."""
    material = bpy.data.materials.new(name)
    H.ensure_nodes(material)
    tree = material.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    emission = tree.nodes.new("ShaderNodeEmission")
    # + 4: Cycles' Emission drops negative colours; every case's values become positive.
    shift = tree.nodes.new("ShaderNodeVectorMath")
    shift.inputs[1].default_value = (4.0, 4.0, 4.0)
    tree.links.new(case_nodes(tree, name), shift.inputs[0])
    tree.links.new(shift.outputs["Vector"], emission.inputs["Color"])
    tree.links.new(emission.outputs["Emission"], out.inputs["Surface"])
    target = bpy.data.images.new("bake_" + name, SIZE, SIZE, float_buffer=True)
    target.colorspace_settings.name = "Non-Color"
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = target
    tree.nodes.active = node
    obj.data.materials.clear()
    obj.data.materials.append(material)
    bpy.ops.object.bake(type="EMIT", margin=0, use_clear=True)
    pixels = np.empty(SIZE * SIZE * 4, np.float32)
    target.pixels.foreach_get(pixels)
    return pixels.reshape(-1, 4)[:, :3], material, emission


def haze_values(obj, material, emission, uv):
    """The exporter's program for the Emission's Color input, run where Cycles baked each
    texel: at the UV coordinates `uv` (K, 2) Cycles itself baked (its texel positions are
    not exactly the texel centres)."""
    ImageLibrary = H.addon_module("export.images").ImageLibrary
    Messages = H.addon_module("export.messages").Messages
    ShaderGraph = H.addon_module("export.nodes").ShaderGraph
    object_info_values = H.addon_module("export.object_info").object_info_values
    WORLD_HANDLERS = H.addon_module("export.world_program").WORLD_HANDLERS
    from renderer.scene import CornerAttribute, Lobe, Material, Mesh
    from renderer.shading.evaluate import evaluate_program
    from renderer.shading.table import build_shading_tables

    messages = Messages()
    images = ImageLibrary(messages)
    graph = ShaderGraph("test", messages, images)
    graph.pass_index = material.pass_index
    if material.name.startswith("node_env_"):  # the world's Environment Texture handler
        env = "ShaderNodeTexEnvironment"
        graph.compiled = dict(graph.compiled, **{{env: WORLD_HANDLERS[env]}})
    reg = graph.input_varying(emission.inputs["Color"])
    assert reg is not None, messages
    program = graph.program.build([(0, 1, 3, reg.index, 0)])
    # One triangle whose corners carry the plane's attributes at (u, v) = (0,0), (1,0), (0,1);
    # attributes are affine over the plane, so barycentrics (1-u-v, u, v) give any texel.
    corners = np.array([[0, 0], [1, 0], [0, 1]], np.float32)
    obj_pos = np.concatenate([corners * 2 - 1, np.zeros((3, 1), np.float32)], axis=1)
    col = np.concatenate([corners, np.full((3, 1), 0.5, np.float32)], axis=1)
    # The plane's MikkTSpace frame: UVs run along x and y, so tangent +x, bitangent sign +1.
    tangent, sign = np.tile([1.0, 0.0, 0.0], (1, 3, 1)), np.ones((1, 3, 1))
    attributes = [CornerAttribute("uv:", corners[None]), CornerAttribute("object", obj_pos[None]),
                  CornerAttribute("attr:Col", col[None]), CornerAttribute("attr:", col[None]),
                  CornerAttribute("tangent:", tangent), CornerAttribute("tangent_sign:", sign)]
    info = object_info_values(obj, np.array(obj.matrix_world, np.float64))
    attributes += [CornerAttribute(k, np.broadcast_to(v, (1, 3, 3)).copy()) for k, v in info.items()]
    mesh = Mesh("t", obj_pos, np.array([[0, 1, 2]], np.int32), ["m"], attributes=attributes)
    m = Material("m", lobes=[Lobe("diffuse")], program=program)
    tables = build_shading_tables([m], [mesh], images.list(), 1)
    u, v = uv[:, 0].astype(np.float64), uv[:, 1].astype(np.float64)
    bary = np.stack([1 - u - v, u, v], axis=1)
    x = np.stack([2 * u - 1, 2 * v - 1, 0 * u], axis=1)
    n = np.tile([0.0, 0.0, 1.0], (len(u), 1))
    return evaluate_program(tables, 0, reg.index, 3, np.zeros(len(u), np.int32), bary, x, n)


def main():
    H.enable_addon()
    scene, obj = plane()
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.cycles.device = "CPU"
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    report = {{}}
    uv, _, _ = bake(obj, "uv")
    uv = uv - 4.0
    report["uv_offset"] = float(np.abs(uv[:, :2] - texel_centres()).max())
    for name in CASES:
        try:
            baked, material, emission = bake(obj, name)
            ours = haze_values(obj, material, emission, uv)
        except Exception as error:  # reported per case, so one broken node fails one test
            report[name] = repr(error)
            continue
        diff = np.abs(ours - baked) / np.maximum(1.0, np.abs(baked - 4.0))
        report[name] = [float(diff.max()), float(np.abs(baked - 4.0).max()), int(np.argmax(diff.max(axis=1)))]
    return report
'''

CASES = (
    ["checker_uv", "checker_object", "map_range", "image", "image_closest"]
    + [f"noise_{k}" for k in ("fbm", "detail", "distortion", "color", "raw")]
    + ["hsv", "separate_hsv", "combine_hsv", "fresnel", "layer_fresnel", "layer_facing", "attribute",
       "color_attribute"]
    + [f"normal_map_{k}" for k in ("tangent", "tangent_strong", "world", "blender_world")]
    + ["bump_linear", "bump_invert", "bump_after_normal_map"]
    + [f"mapping_{k}" for k in ("point", "texture", "vector", "normal")]
    + [f"gradient_{k}" for k in ("linear", "quadratic", "easing", "diagonal", "radial", "quadratic_sphere",
                                 "spherical")]
    + [f"ramp_{k}" for k in ("linear", "constant", "ease", "b_spline", "cardinal")]
    + [f"mix_{k}" for k in ("mix", "darken", "multiply", "burn", "lighten", "screen", "dodge", "add",
                            "overlay", "soft_light", "linear_light", "difference", "exclusion", "subtract",
                            "divide")]
    + [f"math_{k}" for k in ("add", "subtract", "multiply", "divide", "multiply_add", "power", "logarithm",
                             "sqrt", "inverse_sqrt", "absolute", "exponent", "minimum", "maximum",
                             "less_than", "greater_than", "sign", "compare", "smooth_min", "smooth_max",
                             "round", "floor", "ceil", "trunc", "fract", "modulo", "floored_modulo",
                             "wrap", "snap", "pingpong", "sine", "cosine", "tangent", "arcsine",
                             "arccosine", "arctangent", "arctan2", "sinh", "cosh", "tanh", "radians",
                             "degrees")]
    + bake_cases_textures.CASES
    + bake_cases_nodes.CASES
)


TIGHT_CASES = {name: bake_cases_nodes.TIGHT for name in CASES if name.startswith("ramp_")}


baked = blender_fixture(BAKE_BODY.replace("for name in CASES:", f"for name in {CASES!r}:"), "bake",
                        timeout=1800)


@pytest.mark.parametrize("case", CASES)
def test_node_values_match_cycles_bake(baked, case):
    assert not isinstance(baked[case], str), baked[case]
    worst, scale, texel = baked[case]
    tolerances = {**bake_cases_textures.TOLERANCES, **bake_cases_nodes.TOLERANCES, **TIGHT_CASES}
    tolerance = tolerances.get(case, TOLERANCE)
    assert worst <= tolerance, f"max relative |Haze - Cycles| {worst:g} at texel {texel} (|v| <= {scale:g})"


RUNS = 4
SIZE = 48
CYCLES_SAMPLES, HAZE_SAMPLES = 32, 128

SCENE_BODY = rf'''
import math
import os
import bpy
import bpy_helpers as H
import blender_cornell as C

SIZE = {SIZE}


def floor_material():
    """Principled: Base Color from a Checker on UVs, Roughness from a Gradient via Map Range,
    Metallic from a coarser Checker."""
    material, tree, out = C.node_material("Floor")
    n, link = tree.nodes.new, tree.links.new
    bsdf = n("ShaderNodeBsdfPrincipled")
    # Single-scatter GGX: Haze lacks Cycles' multiscatter compensation (issue 14 item 6).
    bsdf.distribution = "GGX"
    checker = n("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 6.0
    checker.inputs["Color1"].default_value = (0.8, 0.75, 0.7, 1)
    checker.inputs["Color2"].default_value = (0.1, 0.15, 0.3, 1)
    coords = n("ShaderNodeTexCoord")
    link(coords.outputs["UV"], checker.inputs["Vector"])
    link(checker.outputs["Color"], bsdf.inputs["Base Color"])
    gradient = n("ShaderNodeTexGradient")
    link(coords.outputs["UV"], gradient.inputs["Vector"])
    ranged = n("ShaderNodeMapRange")
    ranged.inputs["To Min"].default_value = 0.2
    ranged.inputs["To Max"].default_value = 0.8
    link(gradient.outputs["Fac"], ranged.inputs["Value"])
    link(ranged.outputs["Result"], bsdf.inputs["Roughness"])
    metal = n("ShaderNodeTexChecker")  # metal squares on a coarser grid
    metal.inputs["Scale"].default_value = 2.0
    link(coords.outputs["UV"], metal.inputs["Vector"])
    link(metal.outputs["Fac"], bsdf.inputs["Metallic"])
    link(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return material


def wall_material():
    """Diffuse of a colour-grid image, mixed with a diffuse of the colour attribute by a ramp
    of a gradient."""
    material, tree, out = C.node_material("Wall")
    n, link = tree.nodes.new, tree.links.new
    image = bpy.data.images.new("Grid", 64, 64, alpha=False, float_buffer=False)
    image.generated_type = "COLOR_GRID"
    tex = n("ShaderNodeTexImage")
    tex.image = image
    textured = n("ShaderNodeBsdfDiffuse")
    link(tex.outputs["Color"], textured.inputs["Color"])
    red = n("ShaderNodeBsdfDiffuse")  # coloured by the mesh's colour attribute
    link(n("ShaderNodeVertexColor").outputs["Color"], red.inputs["Color"])
    gradient = n("ShaderNodeTexGradient")
    coords = n("ShaderNodeTexCoord")
    link(coords.outputs["UV"], gradient.inputs["Vector"])
    ramp = n("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].position = 0.3
    ramp.color_ramp.elements[1].position = 0.7
    link(gradient.outputs["Fac"], ramp.inputs["Fac"])
    mix = n("ShaderNodeMixShader")
    link(ramp.outputs["Color"], mix.inputs["Fac"])
    link(red.outputs["BSDF"], mix.inputs[1])
    link(textured.outputs["BSDF"], mix.inputs[2])
    link(mix.outputs["Shader"], out.inputs["Surface"])
    return material


def main():
    H.enable_addon()
    scene = C.clear_scene()
    H.world_color(scene, (0.35, 0.4, 0.45), 1.0)
    H.uv_quad("Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor_material())
    wall = H.uv_quad("Wall", [(-3, 1.5, 0), (3, 1.5, 0), (3, 1.5, 3), (-3, 1.5, 3)], wall_material())
    colors = wall.data.color_attributes.new("Col", "BYTE_COLOR", "POINT")
    for k, c in enumerate([(0.7, 0.1, 0.1), (0.1, 0.7, 0.1), (0.1, 0.1, 0.7), (0.6, 0.6, 0.2)]):
        colors.data[k].color = (*c, 1.0)
    H.add_light("SUN", "Sun", (0.0, 0.0, 5.0), (40.0, 0.0, 30.0), energy=2.5, angle=math.radians(4.0))
    C.add_camera(scene, (0.0, -4.5, 2.0), (72.0, 0.0, 0.0), lens=30.0)
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    folder = os.path.join(os.getcwd(), "textured")
    os.makedirs(folder, exist_ok=True)
    result = {{"textured": H.render_both(scene, folder, {RUNS}, {CYCLES_SAMPLES}, {HAZE_SAMPLES}, 3)}}
    # The same scene through the export operator (the CLI renders it in the test process).
    H.configure_haze(scene, 8, 3, seed=7)
    result["f12"] = H.render_exr(scene, os.path.join(folder, "f12.exr"))
    result["export"] = sorted(bpy.ops.export_scene.haze(filepath=os.path.join(folder, "export")))
    result["export_folder"] = os.path.join(folder, "export")
    return result
'''


textured = blender_fixture(SCENE_BODY, "textured", timeout=1800)


def test_textured_scene_agrees_with_cycles(textured):
    haze = np.stack([read_exr(p) for p in textured["textured"]["haze"]])
    cycles = np.stack([read_exr(p) for p in textured["textured"]["cycles"]])
    assert haze.shape == cycles.shape == (RUNS, SIZE, SIZE, 3)
    assert cycles.mean() > 0.01, "the reference image is black: the scene is broken"
    assert_agree(compare_images(haze, cycles))


def test_textured_scene_through_export_and_cli_equals_f12(textured, tmp_path):
    """Programs, corner attributes and images survive the scene folder: the CLI renders the
    exported scene to the same image as F12 (same seed, one worker)."""
    assert textured["export"] == ["FINISHED"]
    output = tmp_path / "cli.exr"
    command = [sys.executable, "-m", "renderer", "render", textured["export_folder"], "-o", str(output),
               "--workers", "1", "--no-png"]
    env = {"NUMBA_CACHE_DIR": str(shared_numba_cache()), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    process = subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True, timeout=900)
    assert process.returncode == 0, process.stderr
    f12 = read_exr(textured["f12"])
    assert f12.mean() > 0.01
    np.testing.assert_array_equal(read_exr(output), f12)
