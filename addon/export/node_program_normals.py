"""Shading-normal nodes compiled into program instructions (renderer.shading.normals and
bump), with Cycles' semantics: the Normal Map, Bump and Displacement nodes, and a Material
Output's Displacement rendered as bump. Its result drives a BSDF's Normal input
(closure_bindings.normal_bind). Handlers as in node_program."""

from __future__ import annotations

from collections.abc import Callable

from renderer.shading.bump import CORNER_POSITION
from renderer.shading.names import MATH_OPS, NORMAL_MAP_SPACES, VECTOR_OPS

from .object_info import OBJECT_SCALE
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


def tilted_normal(graph, height: Callable[[bool], Reg], strength: Reg, distance: Reg, normal_in: Reg,
                  invert: bool) -> Reg:
    """The bumped normal of a height field: height(fresh) compiled three times, at the point
    and at two points moved in the surface's tangent plane (bump_eval before each;
    renderer.shading.bump), then the normal tilted as Cycles' svm_node_set_bump does."""
    p = graph.program
    if CORNER_POSITION not in p.attributes:
        p.attributes.append(CORNER_POSITION)
    column = p.attributes.index(CORNER_POSITION)
    block = p.alloc(5)  # height at the point, at offsets 1 and 2, strength, distance
    for k, reg in ((3, strength), (4, distance)):
        p.emit("copy", 1, reg, i0=1, dst=Reg(block.index + k, 1))
    for axis in (1, 2, 0):  # the point itself last: later code reads it
        p.emit("bump_eval", 0, i0=axis, i1=column, dst=Reg(0, 0))
        p.emit("copy", 1, height(axis != 0), i0=1, dst=Reg(block.index + axis, 1))
    return p.emit("bump", 3, normal_in, block, i0=int(invert), i1=column)


def bump(graph, node, output, scope) -> Reg | None:
    """Bump: the Height's tilted normal (tilted_normal). Cycles' Filter Width only scales its
    pixel-footprint offsets; without ray differentials Haze's offset is fixed, so it has no
    effect here."""
    p = graph.program
    socket = node.inputs["Normal"]
    normal_in = graph.operand(socket, scope) if graph.link_source(socket) is not None else p.emit("normal", 3)
    height = node.inputs["Height"]
    if graph.input_varying(height, scope) is None:
        return normal_in  # a constant height tilts nothing

    def compiled(fresh: bool) -> Reg:
        return _fresh_operand(graph, height, scope) if fresh else graph.operand(height, scope)

    return tilted_normal(graph, compiled, graph.operand(node.inputs["Strength"], scope),
                         graph.operand(node.inputs["Distance"], scope), normal_in, bool(node.invert))


def displacement_bump(graph, socket) -> Reg | None:
    """A Material Output's Displacement as Cycles renders it with the material's default
    method, Bump Only (ShaderGraph::bump_from_displacement): the height is the displacement
    vector's component along the normal, and a Bump of Strength and Distance 1 sets the
    normal every closure without a Normal input of its own uses. None when nothing varies."""
    if graph.input_varying(socket) is None:
        return None  # a constant displacement tilts nothing
    p = graph.program
    normal = p.emit("normal", 3)
    dot, one = VECTOR_OPS.index("DOT_PRODUCT"), p.const(1.0)

    def height(fresh: bool) -> Reg:
        vector = _fresh_operand(graph, socket, ()) if fresh else graph.operand(socket)
        return p.emit("vector_math", 1, vector, normal, vector, one, i0=dot, i1=1)

    return tilted_normal(graph, height, one, one, normal, invert=False)


def displacement(graph, node, output, scope) -> Reg:
    """The Displacement node: (Height - Midlevel) x Scale along the Normal (svm/displace.h).
    In Object space the offset is in object units: Cycles turns the normal into object space
    and the offset back, which for a uniformly scaled object is the world normal times its
    scale ("info:scale", object_info.py)."""
    p = graph.program
    height, midlevel, scale = (graph.operand(node.inputs[k], scope) for k in ("Height", "Midlevel", "Scale"))
    socket = node.inputs["Normal"]
    normal = graph.operand(socket, scope) if graph.link_source(socket) is not None else p.emit("normal", 3)
    amount = p.emit("math", 1, height, midlevel, midlevel, i0=MATH_OPS.index("SUBTRACT"))
    amount = p.emit("math", 1, amount, scale, scale, i0=MATH_OPS.index("MULTIPLY"))
    if node.space == "OBJECT":
        object_scale = Reg(p.attribute(OBJECT_SCALE, 1).index, 1)
        amount = p.emit("math", 1, amount, object_scale, object_scale, i0=MATH_OPS.index("MULTIPLY"))
    return p.emit("vector_math", 3, normal, normal, normal, amount, i0=VECTOR_OPS.index("SCALE"))


NORMAL_HANDLERS = {"ShaderNodeNormalMap": normal_map, "ShaderNodeBump": bump,
                   "ShaderNodeDisplacement": displacement}
NORMAL_SOURCES = {"ShaderNodeNormalMap"}  # varies over a surface by itself (with the normal)
