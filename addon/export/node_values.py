"""Value nodes (Value, RGB, Math, Mix, Map Range...) folded to constants, with Cycles' semantics.

A value is an array of shape (rows, k): k = 1 for scalars and 3 for colours and vectors. A
material's graph (nodes.ShaderGraph) has two rows, row 0 for front faces and row 1 for back
faces ("sided" values: Geometry > Backfacing differs between them); a volume's graph
(volume_shader.VoxelGraph) has one row per voxel, or one for values the same in every voxel.
The handlers here work on both: they compute row-wise and ask the graph for their inputs.

VALUE_HANDLERS maps node type names to handlers; a node type missing from it cannot be folded.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from renderer.scene import LUMINANCE  # Rec. 709 (Blender's linear space): implicit colour-to-float
from renderer.shading.math_arrays import map_range_array, math_array, mix_array
from renderer.shading.names import BLEND_TYPES, MAP_RANGE_TYPES, MATH_OPS

FRONT, BACK = 0, 1  # rows of a sided value
SIDE_NAMES = ("front", "back")
SCALAR_TYPES = {"VALUE", "INT", "BOOLEAN"}
TRIPLE_TYPES = {"RGBA", "VECTOR"}


class ValueGraph(Protocol):
    """What a value-node handler asks of the graph that evaluates it."""

    def input_value(self, socket, scope: tuple = ()) -> np.ndarray: ...

    def unlinked_value(self, socket, width: int) -> np.ndarray: ...

    def zero(self, width: int) -> np.ndarray: ...

    def group_output_input(self, group_node, identifier: str): ...

    def warn_node(self, node, problem: str) -> None: ...

    def warn_unsupported(self, node) -> None: ...


# (graph, node, output socket, group scope) -> the output's value, or None if it cannot be folded
ValueHandler = Callable[[ValueGraph, object, object, tuple], np.ndarray | None]


# ---------------------------------------------------------------------------- sided values


def sided(value, width: int) -> np.ndarray:
    """A constant (same on both faces) as a sided array of `width` components."""
    row = np.broadcast_to(np.asarray(value, dtype=np.float64), (width,))
    return np.array([row, row], dtype=np.float64)


def socket_width(socket_type: str) -> int:
    return 3 if socket_type in TRIPLE_TYPES else 1


def convert(value: np.ndarray, from_type: str, to_type: str) -> np.ndarray:
    """Blender's implicit socket conversions (colour to float = luminance, vector = average)."""
    if to_type in TRIPLE_TYPES:
        return np.repeat(value, 3, axis=1) if value.shape[1] == 1 else value
    if value.shape[1] == 1:
        return value
    if from_type == "RGBA":
        return (value @ LUMINANCE)[:, None]
    return value.mean(axis=1, keepdims=True)


# ---------------------------------------------------------------------------- value nodes
# Math, the colour blends and Map Range fold with the kernels' own functions
# (renderer.shading.math_arrays): one implementation of each of Cycles' semantics.


def value_passthrough_input(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray:
    # Reroute: the value of its input, in the output's type.
    return convert(graph.input_value(node.inputs[0], scope), node.inputs[0].type, socket.type)


def value_constant(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray:
    # Value and RGB nodes keep their constant in the output socket's default_value.
    return graph.unlinked_value(socket, socket_width(socket.type))


def value_group(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray | None:
    inner = graph.group_output_input(node, socket.identifier)
    if inner is None:
        return graph.zero(socket_width(socket.type))
    return convert(graph.input_value(inner, scope + (node,)), inner.type, socket.type)


def value_group_input(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray:
    if not scope:
        return graph.zero(socket_width(socket.type))
    group_node = scope[-1]
    for candidate in group_node.inputs:
        if candidate.identifier == socket.identifier:
            return convert(graph.input_value(candidate, scope[:-1]), candidate.type, socket.type)
    return graph.zero(socket_width(socket.type))


def value_geometry(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray | None:
    if socket.identifier == "Backfacing":
        return np.array([[0.0], [1.0]])
    graph.warn_node(node, f"Geometry output '{socket.name}' varies over the surface; Haze supports "
                          "only Backfacing, the inputs it feeds use their own values")
    return None


def value_math(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray:
    a, b, c = (graph.input_value(s, scope) for s in node.inputs[:3])
    if node.operation not in MATH_OPS:
        graph.warn_node(node, f"Math operation {node.operation} is not supported; its first input is used")
        result = a
    else:
        with np.errstate(all="ignore"):
            result = math_array(MATH_OPS.index(node.operation), a, b, c)
        result = np.nan_to_num(result, nan=0.0, posinf=0.0, neginf=0.0)
    return np.clip(result, 0.0, 1.0) if node.use_clamp else result


def blend(graph: ValueGraph, node, blend_type: str, t, a, b) -> np.ndarray:
    if blend_type not in BLEND_TYPES:
        graph.warn_node(node, f"blend mode {blend_type} is not supported; MIX is used")
        blend_type = "MIX"
    with np.errstate(all="ignore"):
        return mix_array(BLEND_TYPES.index(blend_type), t, a, b)


def by_identifier(sockets, identifier: str):
    """A socket by its identifier (the Mix node has several inputs named "A", "B"...)."""
    for socket in sockets:
        if socket.identifier == identifier:
            return socket
    raise KeyError(identifier)


def value_mix(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray:
    kind = {"FLOAT": "Float", "VECTOR": "Vector", "RGBA": "Color"}.get(node.data_type)
    if kind is None:
        graph.warn_unsupported(node)
        return None
    uniform = node.data_type != "VECTOR" or node.factor_mode == "UNIFORM"
    factor_socket = by_identifier(node.inputs, "Factor_Float" if uniform else "Factor_Vector")
    factor = graph.input_value(factor_socket, scope)
    if node.clamp_factor:
        factor = np.clip(factor, 0.0, 1.0)
    a = graph.input_value(by_identifier(node.inputs, f"A_{kind}"), scope)
    b = graph.input_value(by_identifier(node.inputs, f"B_{kind}"), scope)
    result = blend(graph, node, node.blend_type, factor, a, b) if kind == "Color" else a + factor * (b - a)
    if kind == "Color" and node.clamp_result:
        result = np.clip(result, 0.0, 1.0)
    if kind == "Float":
        return result
    return convert(result, "RGBA" if kind == "Color" else "VECTOR", socket.type)


def value_mix_rgb(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray:
    factor = np.clip(graph.input_value(node.inputs["Fac"], scope), 0.0, 1.0)
    a = graph.input_value(node.inputs["Color1"], scope)
    b = graph.input_value(node.inputs["Color2"], scope)
    result = blend(graph, node, node.blend_type, factor, a, b)
    return np.clip(result, 0.0, 1.0) if node.use_clamp else result


def value_invert(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray:
    factor = graph.input_value(node.inputs["Fac"], scope)
    color = graph.input_value(node.inputs["Color"], scope)
    return color + factor * ((1.0 - color) - color)


def value_clamp(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray:
    value, low, high = (graph.input_value(node.inputs[n], scope) for n in ("Value", "Min", "Max"))
    if node.clamp_type == "RANGE":
        low, high = np.minimum(low, high), np.maximum(low, high)
    return np.minimum(np.maximum(value, low), high)


def value_map_range(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray | None:
    if node.data_type != "FLOAT":
        graph.warn_node(node, "only float Map Range is supported; the inputs it feeds use their own values")
        return None
    # Value, From Min, From Max, To Min, To Max, Steps (by index: the vector variants share the names)
    v, a, b, c, d, steps = (graph.input_value(node.inputs[k], scope) for k in range(6))
    with np.errstate(all="ignore"):
        kind = MAP_RANGE_TYPES.index(node.interpolation_type)
        result = map_range_array(kind, node.clamp, v, a, b, c, d, steps)
    return np.nan_to_num(result, nan=0.0, posinf=0.0, neginf=0.0)


def value_combine(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray | None:
    if getattr(node, "mode", "RGB") != "RGB":
        graph.warn_node(node, f"{node.mode} colour mode is not supported; the inputs it feeds use "
                              "their own values")
        return None
    # Broadcast: in a voxel graph one input may be per voxel and another the same everywhere.
    parts = np.broadcast_arrays(*[graph.input_value(s, scope) for s in node.inputs[:3]])
    return np.concatenate(parts, axis=1)


def value_separate(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray | None:
    if getattr(node, "mode", "RGB") != "RGB":
        graph.warn_node(node, f"{node.mode} colour mode is not supported; the inputs it feeds use "
                              "their own values")
        return None
    whole = graph.input_value(node.inputs[0], scope)
    index = [s.identifier for s in node.outputs].index(socket.identifier)
    return whole[:, index:index + 1].copy()


def value_rgb_to_bw(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray:
    return (graph.input_value(node.inputs["Color"], scope) @ LUMINANCE)[:, None]


def value_gamma(graph: ValueGraph, node, socket, scope: tuple) -> np.ndarray:
    color = graph.input_value(node.inputs["Color"], scope)
    gamma = graph.input_value(node.inputs["Gamma"], scope)
    with np.errstate(all="ignore"):
        power = np.nan_to_num(math_array(MATH_OPS.index("POWER"), color, gamma, 0.0), nan=0.0, posinf=0.0,
                              neginf=0.0)
    return np.where(color > 0.0, power, color)


VALUE_HANDLERS: dict[str, ValueHandler] = {
    "NodeReroute": value_passthrough_input,
    "ShaderNodeValue": value_constant,
    "ShaderNodeRGB": value_constant,
    "ShaderNodeGroup": value_group,
    "NodeGroupInput": value_group_input,
    "ShaderNodeNewGeometry": value_geometry,
    "ShaderNodeMath": value_math,
    "ShaderNodeMix": value_mix,
    "ShaderNodeMixRGB": value_mix_rgb,
    "ShaderNodeInvert": value_invert,
    "ShaderNodeClamp": value_clamp,
    "ShaderNodeMapRange": value_map_range,
    "ShaderNodeCombineColor": value_combine,
    "ShaderNodeCombineXYZ": value_combine,
    "ShaderNodeSeparateColor": value_separate,
    "ShaderNodeSeparateXYZ": value_separate,
    "ShaderNodeRGBToBW": value_rgb_to_bw,
    "ShaderNodeGamma": value_gamma,
}
