"""Shading-normal nodes compiled into program instructions (renderer.shading.normals), with
Cycles' semantics: the Normal Map node. Its result drives a BSDF's Normal input
(closure_bindings.normal_bind). Handlers as in node_program."""

from __future__ import annotations

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


NORMAL_HANDLERS = {"ShaderNodeNormalMap": normal_map}
NORMAL_SOURCES = {"ShaderNodeNormalMap"}  # varies over a surface by itself (with the normal)
