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


# ---------------------------------------------------------------------------- Cycles' safe maths


def safe_divide(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(b != 0.0, a / np.where(b != 0.0, b, 1.0), 0.0)


def safe_power(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    # Cycles' safe_powf: negative bases only with integer exponents, else 0.
    integer = b == np.round(b)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        result = np.where((a >= 0.0) | integer, np.power(np.abs(a), b) * np.where(
            (a < 0.0) & (np.mod(b, 2.0) == 1.0), -1.0, 1.0), 0.0)
    return np.nan_to_num(result, nan=0.0, posinf=0.0, neginf=0.0)


def safe_log(a: np.ndarray, base: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        result = np.where((a > 0.0) & (base > 0.0) & (base != 1.0), np.log(np.abs(a)) / np.log(
            np.where((base > 0.0) & (base != 1.0), base, 2.0)), 0.0)
    return result


MATH_OPERATIONS: dict[str, Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]] = {
    "ADD": lambda a, b, c: a + b,
    "SUBTRACT": lambda a, b, c: a - b,
    "MULTIPLY": lambda a, b, c: a * b,
    "DIVIDE": lambda a, b, c: safe_divide(a, b),
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "POWER": lambda a, b, c: safe_power(a, b),
    "LOGARITHM": lambda a, b, c: safe_log(a, b),
    "SQRT": lambda a, b, c: np.sqrt(np.maximum(a, 0.0)),
    "INVERSE_SQRT": lambda a, b, c: safe_divide(np.ones_like(a), np.sqrt(np.maximum(a, 0.0))),
    "ABSOLUTE": lambda a, b, c: np.abs(a),
    "EXPONENT": lambda a, b, c: np.exp(a),
    "MINIMUM": lambda a, b, c: np.minimum(a, b),
    "MAXIMUM": lambda a, b, c: np.maximum(a, b),
    "LESS_THAN": lambda a, b, c: (a < b).astype(np.float64),
    "GREATER_THAN": lambda a, b, c: (a > b).astype(np.float64),
    "SIGN": lambda a, b, c: np.sign(a),
    "COMPARE": lambda a, b, c: (np.abs(a - b) <= np.maximum(c, 1e-5)).astype(np.float64),
    "ROUND": lambda a, b, c: np.floor(a + 0.5),
    "FLOOR": lambda a, b, c: np.floor(a),
    "CEIL": lambda a, b, c: np.ceil(a),
    "TRUNC": lambda a, b, c: np.trunc(a),
    "FRACT": lambda a, b, c: a - np.floor(a),
    "MODULO": lambda a, b, c: np.where(b != 0.0, np.fmod(a, np.where(b != 0.0, b, 1.0)), 0.0),
    "FLOORED_MODULO": lambda a, b, c: np.where(b != 0.0, a - np.floor(safe_divide(a, b)) * b, 0.0),
    "SINE": lambda a, b, c: np.sin(a),
    "COSINE": lambda a, b, c: np.cos(a),
    "TANGENT": lambda a, b, c: np.tan(a),
    "ARCSINE": lambda a, b, c: np.arcsin(np.clip(a, -1.0, 1.0)),
    "ARCCOSINE": lambda a, b, c: np.arccos(np.clip(a, -1.0, 1.0)),
    "ARCTANGENT": lambda a, b, c: np.arctan(a),
    "ARCTAN2": lambda a, b, c: np.arctan2(a, b),
    "SINH": lambda a, b, c: np.sinh(a),
    "COSH": lambda a, b, c: np.cosh(a),
    "TANH": lambda a, b, c: np.tanh(a),
    "RADIANS": lambda a, b, c: np.radians(a),
    "DEGREES": lambda a, b, c: np.degrees(a),
}

COLOR_BLENDS: dict[str, Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]] = {
    "MIX": lambda t, a, b: a + t * (b - a),
    "ADD": lambda t, a, b: a + t * b,
    "MULTIPLY": lambda t, a, b: a * (1.0 - t + t * b),
    "SUBTRACT": lambda t, a, b: a - t * b,
    "SCREEN": lambda t, a, b: 1.0 - (1.0 - t + t * (1.0 - b)) * (1.0 - a),
    "DIVIDE": lambda t, a, b: np.where(b != 0.0, (1.0 - t) * a + t * safe_divide(a, b), a),
    "DIFFERENCE": lambda t, a, b: a + t * (np.abs(a - b) - a),
    "DARKEN": lambda t, a, b: a + t * (np.minimum(a, b) - a),
    "LIGHTEN": lambda t, a, b: a + t * (np.maximum(a, b) - a),
}



# ---------------------------------------------------------------------------- value nodes


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
    operation = MATH_OPERATIONS.get(node.operation)
    if operation is None:
        graph.warn_node(node, f"Math operation {node.operation} is not supported; its first input is used")
        result = a
    else:
        with np.errstate(all="ignore"):
            result = np.nan_to_num(operation(a, b, c), nan=0.0, posinf=0.0, neginf=0.0)
    return np.clip(result, 0.0, 1.0) if node.use_clamp else result


def blend(graph: ValueGraph, node, blend_type: str, t, a, b) -> np.ndarray:
    operation = COLOR_BLENDS.get(blend_type)
    if operation is None:
        graph.warn_node(node, f"blend mode {blend_type} is not supported; MIX is used")
        operation = COLOR_BLENDS["MIX"]
    return operation(t, a, b)


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
    if node.data_type != "FLOAT" or node.interpolation_type != "LINEAR":
        graph.warn_node(node, "only linear float Map Range is supported; the inputs it feeds use "
                              "their own values")
        return None
    v, a, b, c, d = (graph.input_value(node.inputs[n], scope)
                     for n in ("Value", "From Min", "From Max", "To Min", "To Max"))
    t = safe_divide(v - a, b - a)
    result = c + t * (d - c)
    return np.clip(result, np.minimum(c, d), np.maximum(c, d)) if node.clamp else result


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
    return np.where(color > 0.0, safe_power(color, gamma), color)


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
