"""Varying shader nodes (textures, coordinates, and value nodes fed by them) compiled into
program instructions (program_builder), with Cycles' semantics.

A handler gets the graph, the node, the output socket asked for and the group scope, and
returns the output's register (Reg) or None when it cannot compile it (the caller then
warns and folds the input to a constant, as before programs existed). Inputs come through
graph.operand(socket, scope): a register, holding a folded constant when nothing varying
feeds the socket.

PROGRAM_HANDLERS maps node type names to handlers; VARYING_SOURCES are the node types
whose outputs vary over a surface by themselves.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from renderer.shading.names import (
    BLEND_TYPES,
    GRADIENT_TYPES,
    MAP_RANGE_TYPES,
    MAPPING_TYPES,
    MATH_OPS,
    RAMP_SIZE,
    VECTOR_OPS,
    VECTOR_SCALAR_OPS,
)

from .program_builder import MATH, Reg

UV_ACTIVE = "uv:"  # the mesh's active render UV map (resolved per mesh at export)

VARYING_SOURCES = {
    "ShaderNodeTexCoord", "ShaderNodeUVMap", "ShaderNodeNewGeometry", "ShaderNodeTexImage",
    "ShaderNodeTexChecker", "ShaderNodeTexGradient", "ShaderNodeTexNoise", "ShaderNodeFresnel",
    "ShaderNodeLayerWeight", "ShaderNodeAttribute", "ShaderNodeVertexColor", "ShaderNodeObjectInfo",
}


def by_id(node, identifier: str):
    """An input socket by identifier (names repeat across a node's data types, and an
    unavailable socket is not found by name)."""
    return next(s for s in node.inputs if s.identifier == identifier)


def _texture_vector(graph, node, scope, default: str) -> Reg:
    """A texture's Vector input; unlinked, Cycles' default coordinates (UV or Generated)."""
    socket = node.inputs["Vector"]
    if graph.link_source(socket) is not None:
        return graph.operand(socket, scope)
    if default == "uv":
        return graph.program.attribute(UV_ACTIVE, 2)
    return graph.program.attribute("generated", 3)


def tex_coord(graph, node, output, scope) -> Reg | None:
    name = output.identifier
    if name == "UV":
        return graph.program.attribute(UV_ACTIVE, 2)
    if name == "Generated":
        return graph.program.attribute("generated", 3)
    if name == "Object" and node.object is None:
        return graph.program.attribute("object", 3)
    if name == "Normal":
        return graph.program.emit("normal", 3)
    return None


def uv_map(graph, node, output, scope) -> Reg | None:
    return graph.program.attribute("uv:" + node.uv_map if node.uv_map else UV_ACTIVE, 2)


def geometry(graph, node, output, scope) -> Reg | None:
    if output.identifier == "Position":
        return graph.program.emit("position", 3)
    if output.identifier == "Normal":
        return graph.program.emit("normal", 3)
    return None


def attribute(graph, node, output, scope) -> Reg | None:
    """Attribute node (Geometry type) and Color Attribute: a mesh attribute by name, read per
    corner ("attr:<name>"; an empty name is the mesh's render colour attribute)."""
    if node.bl_idname == "ShaderNodeAttribute":
        if node.attribute_type != "GEOMETRY":
            return None
        name = node.attribute_name
    else:
        name = node.layer_name
    if output.identifier == "Alpha":
        return None
    value = graph.program.attribute("attr:" + name, 3)
    if output.identifier != "Fac":
        return value
    total = graph.program.component_sum(value)  # Cycles' Fac of a colour: its average
    return graph.program.emit("math", 1, total, graph.program.const(1.0 / 3.0), graph.program.const(0.0),
                              i0=MATH["MULTIPLY"])


def math_node(graph, node, output, scope) -> Reg:
    a, b, c = (graph.operand(node.inputs[k], scope) for k in range(3))
    return graph.program.emit("math", 1, a, b, c, i0=MATH_OPS.index(node.operation), i1=int(node.use_clamp))


def vector_math(graph, node, output, scope) -> Reg:
    a, b, c = (graph.operand(node.inputs[k], scope) for k in range(3))
    s = graph.operand(node.inputs[3], scope)
    scalar = node.operation in VECTOR_SCALAR_OPS
    out = graph.program.emit("vector_math", 1 if scalar else 3, a, b, c, s,
                             i0=VECTOR_OPS.index(node.operation), i1=int(scalar))
    if output.identifier == "Value":
        return out if scalar else graph.program.const(0.0)
    return graph.program.widen(graph.program.const(0.0)) if scalar else out


def mix(graph, node, output, scope) -> Reg | None:
    p = graph.program
    kind = node.data_type
    if kind == "RGBA":
        t = graph.operand(by_id(node, "Factor_Float"), scope)
        a, b = graph.operand(by_id(node, "A_Color"), scope), graph.operand(by_id(node, "B_Color"), scope)
        return p.emit("mix", 3, t, a, b, i0=BLEND_TYPES.index(node.blend_type), i1=int(node.clamp_factor),
                      i2=int(node.clamp_result))
    if kind == "FLOAT":
        t = graph.operand(by_id(node, "Factor_Float"), scope)
        a, b = graph.operand(by_id(node, "A_Float"), scope), graph.operand(by_id(node, "B_Float"), scope)
        return p.emit("mix_float", 1, t, a, b, i1=int(node.clamp_factor))
    if kind == "VECTOR":
        uniform = node.factor_mode == "UNIFORM"
        t = graph.operand(by_id(node, "Factor_Float" if uniform else "Factor_Vector"), scope)
        a, b = graph.operand(by_id(node, "A_Vector"), scope), graph.operand(by_id(node, "B_Vector"), scope)
        t = p.widen(t)
        out = p.alloc(3)
        for k in range(3):
            p.emit("mix_float", 1, p.component(t, k), p.component(a, k), p.component(b, k),
                   i1=int(node.clamp_factor), dst=Reg(out.index + k, 1))
        return out
    return None


def mix_rgb(graph, node, output, scope) -> Reg:
    t, a, b = (graph.operand(node.inputs[k], scope) for k in ("Fac", "Color1", "Color2"))
    return graph.program.emit("mix", 3, t, a, b, i0=BLEND_TYPES.index(node.blend_type), i1=1,
                              i2=int(node.use_clamp))


def mapping(graph, node, output, scope) -> Reg:
    names = ("Vector", "Location", "Rotation", "Scale")
    v, loc, rot, scale = (graph.operand(by_id(node, k), scope) for k in names)
    return graph.program.emit("mapping", 3, v, loc, rot, scale, i0=MAPPING_TYPES.index(node.vector_type))


def checker(graph, node, output, scope) -> Reg:
    p = graph.program
    v = _texture_vector(graph, node, scope, "generated")
    c1, c2 = graph.operand(node.inputs["Color1"], scope), graph.operand(node.inputs["Color2"], scope)
    out = p.emit("checker", 4, v, c1, c2, graph.operand(node.inputs["Scale"], scope))
    return Reg(out.index + 3, 1) if output.identifier == "Fac" else Reg(out.index, 3)


def gradient(graph, node, output, scope) -> Reg:
    v = _texture_vector(graph, node, scope, "generated")
    f = graph.program.emit("gradient", 1, v, i0=GRADIENT_TYPES.index(node.gradient_type))
    return f if output.identifier == "Fac" else graph.program.widen(f)


def image(graph, node, output, scope) -> Reg | None:
    if node.image is None:
        # Cycles' missing-image colour
        return graph.program.const((1.0, 0.0, 1.0) if output.identifier == "Color" else 1.0)
    if node.projection != "FLAT":
        graph.warn_node(node, f"{node.projection} projection is not supported; rendered as Flat")
    name = graph.add_image(node.image)
    if name is None:
        return None
    p = graph.program
    v = _texture_vector(graph, node, scope, "uv")
    extension = ("REPEAT", "EXTEND", "CLIP", "MIRROR").index(node.extension)
    out = p.emit("image", 4, v, i0=p.image(name), i1=interpolation_index(node.interpolation), i2=extension)
    return Reg(out.index + 3, 1) if output.identifier == "Alpha" else Reg(out.index, 3)


def interpolation_index(interpolation: str) -> int:
    """program.INTERPOLATIONS index of an image node's interpolation (Smart: Cubic, as Cycles'
    CPU sampler renders it)."""
    return {"Closest": 0, "Linear": 1}.get(interpolation, 2)


INFO_ATTRIBUTES = {"Location": ("info:location", 0, 3), "Color": ("info:color", 0, 3),
                   "Alpha": ("info:values", 0, 1), "Object Index": ("info:values", 1, 1),
                   "Random": ("info:values", 2, 1)}


def object_info(graph, node, output, scope) -> Reg | None:
    """Object Info: per-object values the exporter writes as constant corner attributes
    (mesh.object_info_attributes); Material Index is the material's own constant."""
    if output.identifier == "Material Index":
        return graph.program.const(float(graph.pass_index))
    if output.identifier not in INFO_ATTRIBUTES:
        return None
    name, first, width = INFO_ATTRIBUTES[output.identifier]
    reg = graph.program.attribute(name, 3)
    return Reg(reg.index + first, width)


def color_ramp(graph, node, output, scope) -> Reg:
    """Cycles bakes the ramp into RAMP_SIZE entries (Blender's own evaluate) and
    interpolates linearly between them unless the ramp is Constant."""
    ramp = node.color_ramp
    table = np.array([ramp.evaluate(k / (RAMP_SIZE - 1)) for k in range(RAMP_SIZE)], np.float32)
    p = graph.program
    out = p.emit("ramp", 4, graph.operand(node.inputs["Fac"], scope), i0=p.table(table),
                 i1=int(ramp.interpolation != "CONSTANT"))
    return Reg(out.index + 3, 1) if output.identifier == "Alpha" else Reg(out.index, 3)


def separate(graph, node, output, scope) -> Reg | None:
    mode = getattr(node, "mode", "RGB")
    if mode not in ("RGB", "HSV", "HSL"):
        return None
    v = graph.operand(node.inputs[0], scope)
    if mode != "RGB":
        v = graph.program.emit("hsv_convert", 3, v, i0=0 if mode == "HSV" else 2)
    k = [o.identifier for o in node.outputs].index(output.identifier)
    return graph.program.component(v, k)


def combine(graph, node, output, scope) -> Reg | None:
    mode = getattr(node, "mode", "RGB")
    if mode not in ("RGB", "HSV", "HSL"):
        return None
    a, b, c = (graph.operand(node.inputs[k], scope) for k in range(3))
    out = graph.program.emit("combine", 3, a, b, c)
    return out if mode == "RGB" else graph.program.emit("hsv_convert", 3, out, i0=1 if mode == "HSV" else 3)


def hue_saturation(graph, node, output, scope) -> Reg:
    p = graph.program
    block = p.alloc(4)  # hue, saturation, value, factor: consecutive registers
    for k, name in enumerate(("Hue", "Saturation", "Value", "Fac")):
        p.emit("copy", 1, graph.operand(node.inputs[name], scope), i0=1, dst=Reg(block.index + k, 1))
    return p.emit("hsv", 3, graph.operand(node.inputs["Color"], scope), block)


def _normal_input(graph, node, scope) -> Reg:
    socket = node.inputs["Normal"]
    if graph.link_source(socket) is not None:
        return graph.operand(socket, scope)
    return graph.program.emit("normal", 3)


def fresnel(graph, node, output, scope) -> Reg:
    return graph.program.emit("fresnel", 1, graph.operand(node.inputs["IOR"], scope),
                              _normal_input(graph, node, scope))


def layer_weight(graph, node, output, scope) -> Reg:
    return graph.program.emit("layer_weight", 1, graph.operand(node.inputs["Blend"], scope),
                              _normal_input(graph, node, scope), i0=int(output.identifier == "Facing"))


def invert(graph, node, output, scope) -> Reg:
    return graph.program.emit("invert", 3, graph.operand(node.inputs["Fac"], scope),
                              graph.operand(node.inputs["Color"], scope))


def rgb_to_bw(graph, node, output, scope) -> Reg:
    return graph.program.emit("rgb_to_bw", 1, graph.operand(node.inputs["Color"], scope))


def clamp(graph, node, output, scope) -> Reg:
    a, lo, hi = (graph.operand(node.inputs[k], scope) for k in ("Value", "Min", "Max"))
    return graph.program.emit("clamp", 1, a, lo, hi, i0=int(node.clamp_type == "RANGE"))


def map_range(graph, node, output, scope) -> Reg | None:
    if node.data_type != "FLOAT":
        return None
    p = graph.program
    block = p.alloc(5)  # from min, from max, to min, to max, steps: consecutive registers
    for k in range(5):  # inputs 1..5 (by index: the vector variants share the names)
        p.emit("copy", 1, graph.operand(node.inputs[1 + k], scope), i0=1, dst=Reg(block.index + k, 1))
    return p.emit("map_range", 1, graph.operand(node.inputs[0], scope), block,
                  i0=MAP_RANGE_TYPES.index(node.interpolation_type), i1=int(node.clamp))


def gamma(graph, node, output, scope) -> Reg:
    return graph.program.emit("gamma", 3, graph.operand(node.inputs["Color"], scope),
                              graph.operand(node.inputs["Gamma"], scope))


def bright_contrast(graph, node, output, scope) -> Reg:
    return graph.program.emit("bright_contrast", 3, graph.operand(node.inputs["Color"], scope),
                              graph.operand(node.inputs["Bright"], scope),
                              graph.operand(node.inputs["Contrast"], scope))


PROGRAM_HANDLERS: dict[str, Callable] = {
    "ShaderNodeTexCoord": tex_coord,
    "ShaderNodeUVMap": uv_map,
    "ShaderNodeNewGeometry": geometry,
    "ShaderNodeMath": math_node,
    "ShaderNodeAttribute": attribute,
    "ShaderNodeVertexColor": attribute,
    "ShaderNodeVectorMath": vector_math,
    "ShaderNodeMix": mix,
    "ShaderNodeMixRGB": mix_rgb,
    "ShaderNodeMapping": mapping,
    "ShaderNodeTexChecker": checker,
    "ShaderNodeTexGradient": gradient,
    "ShaderNodeTexImage": image,
    "ShaderNodeValToRGB": color_ramp,
    "ShaderNodeSeparateXYZ": separate,
    "ShaderNodeSeparateColor": separate,
    "ShaderNodeCombineXYZ": combine,
    "ShaderNodeCombineColor": combine,
    "ShaderNodeInvert": invert,
    "ShaderNodeRGBToBW": rgb_to_bw,
    "ShaderNodeClamp": clamp,
    "ShaderNodeMapRange": map_range,
    "ShaderNodeGamma": gamma,
    "ShaderNodeHueSaturation": hue_saturation,
    "ShaderNodeFresnel": fresnel,
    "ShaderNodeLayerWeight": layer_weight,
    "ShaderNodeBrightContrast": bright_contrast,
    "ShaderNodeObjectInfo": object_info,
}
MATH_ADD = MATH["ADD"]

# Procedural textures (noise, ...) are compiled in their own module.
from .node_program_curves import TABLE_HANDLERS  # noqa: E402
from .node_program_textures import TEXTURE_HANDLERS, TEXTURE_SOURCES  # noqa: E402

PROGRAM_HANDLERS.update(TEXTURE_HANDLERS)
PROGRAM_HANDLERS.update(TABLE_HANDLERS)
VARYING_SOURCES |= TEXTURE_SOURCES
