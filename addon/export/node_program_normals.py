"""Shading-normal nodes compiled into program instructions (renderer.shading.normals and
bump), with Cycles' semantics: the Normal Map and Bump nodes. Its result drives a BSDF's Normal input
(closure_bindings.normal_bind). Handlers as in node_program."""

from __future__ import annotations

from renderer.shading.bump import CORNER_POSITION
from renderer.shading.names import NORMAL_MAP_SPACES

from .program_builder import Reg

COMPILED_SPACES = ("TANGENT", "WORLD", "BLENDER_WORLD")  # object space needs the object's transform


def normal_map(graph, node, output, scope) -> Reg | None:
    """Normal Map: tangent space with the mesh's MikkTSpace tangents of the node's UV map
    (exported per corner as "tangent:<map>" and "tangent_sign:<map>"), or world space."""
    if node.space not in COMPILED_SPACES:
        graph.warn_node(node, f"{node.space.replace('_', ' ').lower()} space is not supported; "
                              "the mesh's own normal is used")
        return graph.program.emit("normal", 3)
    p = graph.program
    color = graph.operand(node.inputs["Color"], scope)
    strength = graph.operand(node.inputs["Strength"], scope)
    tangent = sign = p.const((0.0, 0.0, 0.0))
    if node.space == "TANGENT":
        tangent = p.attribute("tangent:" + node.uv_map, 3)
        sign = p.attribute("tangent_sign:" + node.uv_map, 1)
    return p.emit("normal_map", 3, color, strength, tangent, sign, i0=NORMAL_MAP_SPACES.index(node.space))


def _fresh_operand(graph, socket, scope) -> Reg:
    """The socket compiled anew (nothing reused from code emitted before), so that its
    attribute and position reads follow the last bump_eval."""
    saved = graph._registers, graph.program._emitted
    graph._registers, graph.program._emitted = {}, {}
    try:
        return graph.operand(socket, scope)
    finally:
        graph._registers, graph.program._emitted = saved


def bump(graph, node, output, scope) -> Reg | None:
    """Bump: the Height compiled three times, at the point and at two points moved in the
    surface's tangent plane (bump_eval before each; renderer.shading.bump), then the tilted
    normal. Cycles' Filter Width only scales its pixel-footprint offsets; without ray
    differentials Haze's offset is fixed, so it has no effect here."""
    p = graph.program
    socket = node.inputs["Normal"]
    normal_in = graph.operand(socket, scope) if graph.link_source(socket) is not None else p.emit("normal", 3)
    height = node.inputs["Height"]
    if graph.input_varying(height, scope) is None:
        return normal_in  # a constant height tilts nothing
    if CORNER_POSITION not in p.attributes:
        p.attributes.append(CORNER_POSITION)
    column = p.attributes.index(CORNER_POSITION)
    block = p.alloc(5)  # height at the point, at offsets 1 and 2, strength, distance
    for k, name in ((3, "Strength"), (4, "Distance")):
        p.emit("copy", 1, graph.operand(node.inputs[name], scope), i0=1, dst=Reg(block.index + k, 1))
    for axis in (1, 2, 0):  # the point itself last: later code reads it
        p.emit("bump_eval", 0, i0=axis, i1=column, dst=Reg(0, 0))
        h = _fresh_operand(graph, height, scope) if axis else graph.operand(height, scope)
        p.emit("copy", 1, h, i0=1, dst=Reg(block.index + axis, 1))
    return p.emit("bump", 3, normal_in, block, i0=int(node.invert), i1=column)


NORMAL_HANDLERS = {"ShaderNodeNormalMap": normal_map, "ShaderNodeBump": bump}
NORMAL_SOURCES = {"ShaderNodeNormalMap"}  # varies over a surface by itself (with the normal)
