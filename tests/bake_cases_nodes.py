"""Bake cases of Blackbody, Wavelength, the curve nodes, cubic images, the Environment
Texture's projections and Object Info, for tests/test_shader_programs.py (as
bake_cases_textures): each case name maps to a builder that adds the nodes to a material
tree inside Blender and returns the output socket to bake.

Inputs come from Object coordinates (x, y in [-1, 1] on the bake plane, z = 0), scaled to
sweep each node's whole domain: temperatures 500..12500 K (both clamps of Blackbody),
wavelengths 325..825 nm (both ends of Wavelength's table), curve inputs beyond the curves'
x range (Extend Horizontal and Extrapolated).

Environment Texture cases compile the world program's handler (world_program) inside the
material: Cycles bakes the node in a material, with the same projection code.

Object Info cases set the plane's location, colour and pass index and the material's pass
index first: they run last (the location moves the plane for the cases after them).
"""

from __future__ import annotations

CURVES = {
    "node_float_curve": ("ShaderNodeFloatCurve", "HORIZONTAL"),
    "node_float_curve_extrapolated": ("ShaderNodeFloatCurve", "EXTRAPOLATED"),
    "node_vector_curve": ("ShaderNodeVectorCurve", "HORIZONTAL"),
    "node_vector_curve_extrapolated": ("ShaderNodeVectorCurve", "EXTRAPOLATED"),
    "node_rgb_curve": ("ShaderNodeRGBCurve", "HORIZONTAL"),
    "node_rgb_curve_extrapolated": ("ShaderNodeRGBCurve", "EXTRAPOLATED"),
}
# name: (interpolation, extension)
IMAGES = {"node_image_cubic": ("Cubic", "REPEAT"), "node_image_smart_clip": ("Smart", "CLIP"),
          "node_image_cubic_extend": ("Cubic", "EXTEND"), "node_image_cubic_mirror": ("Cubic", "MIRROR")}
# name: (projection, interpolation)
ENVIRONMENTS = {"node_env_mirror_ball": ("MIRROR_BALL", "Linear"),
                "node_env_mirror_ball_cubic": ("MIRROR_BALL", "Cubic"),
                "node_env_equirectangular_cubic": ("EQUIRECTANGULAR", "Cubic")}
INFO = {f"node_info_{k.lower().replace(' ', '_')}": k
        for k in ("Location", "Color", "Alpha", "Object Index", "Material Index", "Random")}
CASES = (["node_blackbody", "node_wavelength", "node_spectrum_constant"] + list(CURVES) + list(IMAGES)
         + list(ENVIRONMENTS) + list(INFO))
# Measured: 4.3e-6 at most (spectra, curves, cubic images, Object Info); the Environment
# Texture cases go through atan2/acos/sqrt of Cycles' float32 directions (1.1e-5): the
# test's own tolerance.
TIGHT = 1e-5
TOLERANCES = {name: TIGHT for name in CASES if not name.startswith("node_env_")}


def _object(tree):
    return tree.nodes.new("ShaderNodeTexCoord").outputs["Object"]


def _sweep(tree, scale, offset):
    """Object x * scale + offset as a float socket."""
    sep = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(_object(tree), sep.inputs["Vector"])
    node = tree.nodes.new("ShaderNodeMath")
    node.operation = "MULTIPLY_ADD"
    node.inputs[1].default_value = scale
    node.inputs[2].default_value = offset
    tree.links.new(sep.outputs["X"], node.inputs[0])
    return node.outputs["Value"]


def _spectrum(tree, name):
    n = tree.nodes.new
    if name == "node_blackbody":
        node = n("ShaderNodeBlackbody")
        tree.links.new(_sweep(tree, 6000.0, 6500.0), node.inputs["Temperature"])
        return node.outputs["Color"]
    if name == "node_wavelength":
        node = n("ShaderNodeWavelength")
        tree.links.new(_sweep(tree, 250.0, 575.0), node.inputs["Wavelength"])
        return node.outputs["Color"]
    # Constant inputs (folded at export) mixed by a varying factor.
    hot, wave = n("ShaderNodeBlackbody"), n("ShaderNodeWavelength")
    hot.inputs["Temperature"].default_value = 2700.0
    wave.inputs["Wavelength"].default_value = 532.0
    mix = n("ShaderNodeMix")
    mix.data_type = "RGBA"
    tree.links.new(_sweep(tree, 0.5, 0.5), next(s for s in mix.inputs if s.identifier == "Factor_Float"))
    tree.links.new(hot.outputs["Color"], next(s for s in mix.inputs if s.identifier == "A_Color"))
    tree.links.new(wave.outputs["Color"], next(s for s in mix.inputs if s.identifier == "B_Color"))
    return next(s for s in mix.outputs if s.identifier == "Result_Color")


def _shape(mapping, curve, points, handles):
    """Give `curve` the points [(x, y)] with handle types, replacing its two defaults."""
    for k, ((x, y), handle) in enumerate(zip(points, handles)):
        point = curve.points[k] if k < 2 else curve.points.new(x, y)
        point.location = (x, y)
        point.handle_type = handle
    mapping.update()


def _curve(tree, name):
    kind, extend = CURVES[name]
    node = tree.nodes.new(kind)
    mapping = node.mapping
    mapping.extend = extend
    curves = list(mapping.curves)
    if kind == "ShaderNodeFloatCurve":
        _shape(mapping, curves[0], [(0.0, 0.1), (1.0, 0.7), (0.4, 0.8)], ["VECTOR", "AUTO", "AUTO_CLAMPED"])
        node.inputs[0].default_value = 0.8
        tree.links.new(_sweep(tree, 0.9, 0.45), node.inputs[1])  # -0.45..1.35: beyond [0, 1]
        return node.outputs[0]
    if kind == "ShaderNodeVectorCurve":
        _shape(mapping, curves[0], [(-0.8, -0.6), (0.9, 0.8), (0.1, 0.4)], ["AUTO", "VECTOR", "AUTO_CLAMPED"])
        _shape(mapping, curves[1], [(-0.6, 0.5), (0.7, -0.5)], ["AUTO", "AUTO"])
        node.inputs[0].default_value = 0.9
        tree.links.new(_object(tree), node.inputs[1])
        return node.outputs[0]
    _shape(mapping, curves[3], [(0.0, 0.05), (1.0, 0.9), (0.5, 0.7)], ["AUTO", "AUTO", "AUTO_CLAMPED"])
    _shape(mapping, curves[0], [(0.1, 0.0), (0.9, 1.0), (0.5, 0.3)], ["VECTOR", "AUTO", "AUTO"])
    node.inputs[0].default_value = 0.85
    scaled = tree.nodes.new("ShaderNodeVectorMath")  # a colour sweeping -0.3..1.3
    scaled.operation = "MULTIPLY_ADD"
    scaled.inputs[1].default_value = (0.8, 0.6, 0.7)
    scaled.inputs[2].default_value = (0.5, 0.45, 0.55)
    tree.links.new(_object(tree), scaled.inputs[0])
    tree.links.new(scaled.outputs["Vector"], node.inputs[1])
    return node.outputs[0]


def _image(tree, name):
    import bpy

    interpolation, extension = IMAGES[name]
    image = bpy.data.images.new("Cubic_" + name, 19, 13, alpha=False, float_buffer=True)
    image.generated_type = "COLOR_GRID"
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    node.interpolation = interpolation
    node.extension = extension
    mapping = tree.nodes.new("ShaderNodeMapping")  # UV -0.35..1.35: every extension shows
    mapping.inputs["Scale"].default_value = (1.7, 1.7, 1.0)
    mapping.inputs["Location"].default_value = (-0.35, -0.35, 0.0)
    tree.links.new(tree.nodes.new("ShaderNodeTexCoord").outputs["UV"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], node.inputs["Vector"])
    return node.outputs["Color"]


def _environment(tree, name):
    import bpy

    projection, interpolation = ENVIRONMENTS[name]
    image = bpy.data.images.new("Env_" + name, 40, 24, alpha=False, float_buffer=True)
    image.generated_type = "COLOR_GRID"
    node = tree.nodes.new("ShaderNodeTexEnvironment")
    node.image = image
    node.projection = projection
    node.interpolation = interpolation
    direction = tree.nodes.new("ShaderNodeVectorMath")  # (x, y, 0.4): every direction's side
    direction.inputs[1].default_value = (0.0, 0.0, 0.4)
    tree.links.new(_object(tree), direction.inputs[0])
    tree.links.new(direction.outputs["Vector"], node.inputs["Vector"])
    return node.outputs["Color"]


def _info(tree, name):
    import bpy

    obj = bpy.data.objects["Plane"]
    obj.location = (0.3, -0.7, 1.1)
    obj.color = (0.8, 0.35, 0.1, 0.6)
    obj.pass_index = 7
    material = next(m for m in bpy.data.materials if m.node_tree == tree)
    material.pass_index = 3
    bpy.context.view_layer.update()
    info = tree.nodes.new("ShaderNodeObjectInfo")
    # Times (x + 2): varying, so the program path compiles it (Cycles' value times the same).
    sweep = _sweep(tree, 1.0, 2.0)
    if INFO[name] in ("Location", "Color"):
        node = tree.nodes.new("ShaderNodeVectorMath")
        node.operation = "SCALE"
        tree.links.new(info.outputs[INFO[name]], node.inputs[0])
        tree.links.new(sweep, next(s for s in node.inputs if s.identifier == "Scale"))
        return node.outputs["Vector"]
    node = tree.nodes.new("ShaderNodeMath")
    node.operation = "MULTIPLY"
    tree.links.new(info.outputs[INFO[name]], node.inputs[0])
    tree.links.new(sweep, node.inputs[1])
    return node.outputs["Value"]


def case_nodes(tree, name):
    """(output socket to bake) of case `name`."""
    if name in CURVES:
        return _curve(tree, name)
    if name in IMAGES:
        return _image(tree, name)
    if name in ENVIRONMENTS:
        return _environment(tree, name)
    if name in INFO:
        return _info(tree, name)
    return _spectrum(tree, name)
