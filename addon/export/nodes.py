"""Evaluate a Blender shader node tree into constant closures, with Cycles' semantics.

Haze materials are constant over a surface, so the tree is folded: every input is evaluated
to a constant by following links through Value/RGB/Math/Mix/... nodes, and shader nodes
become weighted closure terms (BSDF lobes, emission, volume coefficients).

Values can differ between the two faces of a surface: Geometry > Backfacing is 0 on front
faces and 1 on back faces, so every value is carried as a "sided" array of shape (2, k),
row 0 for front faces and row 1 for back faces (k = 1 for scalars, 3 for colours/vectors).
A Mix Shader whose factor is Backfacing thus yields front-only and back-only closures,
which is how Cycles users make one-sided emitters.

Nodes Haze cannot fold (textures, attributes, light-path tricks...) produce one warning per
material and node; the inputs they feed keep their own (unlinked) values. Closures Haze has
no model for are rendered as a Diffuse BSDF of their Color input (documented fallback).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from renderer.scene import LUMINANCE  # Rec. 709 (Blender's linear space): implicit colour-to-float

from .messages import Messages, node_subject

FRONT, BACK = 0, 1
SIDE_NAMES = ("front", "back")
SCALAR_TYPES = {"VALUE", "INT", "BOOLEAN"}
TRIPLE_TYPES = {"RGBA", "VECTOR"}


@dataclass
class Term:
    """One weighted closure. Lobe kinds are those of renderer.scene.Lobe; the others are
    "emission" (surface or world radiance), "scatter", "absorb" and "volume_emission"
    (volume coefficients per unit length)."""

    kind: str
    weight: np.ndarray  # (3,) RGB
    sides: str = "both"
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    roughness: float = 0.0
    ior: float = 1.5
    anisotropy: float = 0.0
    fresnel: str = "constant"  # conductors: "constant" (colour) or "f82" (F0 = colour, edge tint)
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def same_closure(self, other: Term) -> bool:
        return (
            self.kind == other.kind
            and self.fresnel == other.fresnel
            and np.allclose(self.weight, other.weight, rtol=1e-6, atol=1e-9)
            and np.allclose(self.color, other.color, rtol=1e-6, atol=1e-9)
            and np.allclose(self.tint, other.tint, rtol=1e-6, atol=1e-9)
            and math.isclose(self.roughness, other.roughness, abs_tol=1e-9)
            and math.isclose(self.ior, other.ior, abs_tol=1e-9)
            and math.isclose(self.anisotropy, other.anisotropy, abs_tol=1e-9)
        )


VOLUME_KINDS = {"scatter", "absorb", "volume_emission"}


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


def side_terms(terms: list[Term], side: int) -> list[Term]:
    return [replace(term, sides=SIDE_NAMES[side]) for term in terms]


def merge_sides(front: list[Term], back: list[Term]) -> list[Term]:
    """Terms evaluated for each face: one two-sided list when both faces agree."""
    if len(front) == len(back) and all(f.same_closure(b) for f, b in zip(front, back)):
        return [replace(term, sides="both") for term in front]
    return side_terms(front, FRONT) + side_terms(back, BACK)


def restrict_to_side(term: Term, side: str) -> Term | None:
    """The part of `term` on faces `side`, or None if it has none there."""
    if term.sides == "both":
        return replace(term, sides=side)
    return replace(term) if term.sides == side else None


def scale_terms(terms: list[Term], factor: np.ndarray) -> list[Term]:
    """Multiply closure weights by a sided scalar (2, 1), splitting terms whose faces differ."""
    front, back = float(factor[FRONT, 0]), float(factor[BACK, 0])
    scaled = []
    for term in terms:
        if front == back:
            scaled.append(replace(term, weight=term.weight * front))
            continue
        for side, value in (("front", front), ("back", back)):
            part = restrict_to_side(term, side)
            if part is not None:
                scaled.append(replace(part, weight=part.weight * value))
    return [term for term in scaled if np.any(term.weight != 0.0)]


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


def saturate(value: float) -> float:
    return min(max(value, 0.0), 1.0)


class Inputs:
    """Plain values of a node's inputs on one face (floats, or (3,) arrays for colours)."""

    def __init__(self, graph: ShaderGraph, node, scope: tuple, side: int) -> None:
        self._graph, self.node, self._scope, self._side = graph, node, scope, side

    def __call__(self, name: str):
        socket = self.node.inputs[name]
        row = self._graph.input_value(socket, self._scope)[self._side]
        return float(row[0]) if row.shape[0] == 1 else row.copy()

    def is_linked(self, name: str) -> bool:
        return self._graph.link_source(self.node.inputs[name]) is not None

    @property
    def subject(self) -> str:
        return node_subject(self._graph.owner, self.node.name)

    def warn(self, problem: str) -> None:
        self._graph.messages.warn(self.subject, problem)


class ShaderGraph:
    """Folds one node tree (a material's or world's) into constant values and closure terms."""

    def __init__(self, owner: str, messages: Messages) -> None:
        self.owner = owner  # e.g. "Material 'Glass'", used in every message
        self.messages = messages
        self._values: dict[tuple, np.ndarray] = {}

    # ---------------------------------------------------------------- links
    @staticmethod
    def link_source(socket):
        """(node, output socket) feeding `socket`, skipping muted and invalid links."""
        if not socket.is_linked:
            return None
        for link in socket.links:
            if link.is_valid and not link.is_muted:
                return link.from_node, link.from_socket
        return None

    def warn_node(self, node, problem: str) -> None:
        self.messages.warn(node_subject(self.owner, node.name), problem)

    def warn_unsupported(self, node) -> None:
        self.warn_node(
            node,
            f"{node.bl_label} nodes are not supported by Haze; the inputs it feeds use their own values",
        )

    # ---------------------------------------------------------------- values
    def input_value(self, socket, scope: tuple = ()) -> np.ndarray:
        """Sided value (2, k) of an input socket, following its link if any."""
        width = socket_width(socket.type)
        source = self.link_source(socket)
        if source is not None:
            value = self.output_value(source[0], source[1], scope)
            if value is not None:
                return convert(value, source[1].type, socket.type)
        return self.unlinked_value(socket, width)

    @staticmethod
    def unlinked_value(socket, width: int) -> np.ndarray:
        default = getattr(socket, "default_value", None)
        if default is None or isinstance(default, str):
            return sided(0.0, width)
        if isinstance(default, (int, float, bool)):
            return sided(float(default), width)
        components = [float(x) for x in default][:3]
        return sided(components, width) if len(components) == width else sided(components[0], width)

    def output_value(self, node, socket, scope: tuple) -> np.ndarray | None:
        """Sided value of an output socket, or None when it cannot be folded (warned)."""
        key = (node.as_pointer(), socket.identifier, tuple(n.as_pointer() for n in scope))
        if key not in self._values:
            self._values[key] = self._evaluate_output(node, socket, scope)
        return self._values[key]

    def _evaluate_output(self, node, socket, scope: tuple) -> np.ndarray | None:
        if node.mute:
            return self._muted_output(node, socket, scope)
        handler = self.handler(node)
        if handler is None:
            self.warn_unsupported(node)
            return None
        return handler(self, node, socket, scope)

    def _muted_output(self, node, socket, scope: tuple) -> np.ndarray | None:
        # A muted node passes one input straight through (Blender's internal links).
        for link in node.internal_links:
            if link.to_socket.identifier == socket.identifier:
                return convert(self.input_value(link.from_socket, scope), link.from_socket.type, socket.type)
        return self.zero(socket_width(socket.type))

    @staticmethod
    def handler(node):
        """The function that evaluates `node`'s outputs (None: unsupported)."""
        return VALUE_HANDLERS.get(node.bl_idname)

    @staticmethod
    def zero(width: int) -> np.ndarray:
        """A zero value of `width` components in this graph's array form (sided)."""
        return sided(0.0, width)

    def group_output_input(self, group_node, identifier: str):
        tree = group_node.node_tree
        if tree is None:
            return None
        outputs = [n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"]
        active = [n for n in outputs if n.is_active_output] or outputs
        if not active:
            return None
        for candidate in active[0].inputs:
            if candidate.identifier == identifier:
                return candidate
        return None

    # ---------------------------------------------------------------- closures
    def closure(self, socket, scope: tuple = ()) -> list[Term]:
        """Closure terms reaching a shader input socket (empty when unlinked)."""
        source = self.link_source(socket)
        if source is None:
            return []
        node, output = source
        return self.closure_output(node, output, scope)

    def closure_output(self, node, output, scope: tuple) -> list[Term]:
        if node.mute:
            for link in node.internal_links:
                if link.to_socket.identifier == output.identifier:
                    return self.closure(link.from_socket, scope)
            return []
        if node.bl_idname == "NodeReroute":
            return self.closure(node.inputs[0], scope)
        if node.bl_idname == "ShaderNodeGroup":
            inner = self.group_output_input(node, output.identifier)
            return [] if inner is None else self.closure(inner, scope + (node,))
        if node.bl_idname == "NodeGroupInput":
            return self._group_input_closure(node, output, scope)
        if node.bl_idname in COMBINE_HANDLERS:
            return COMBINE_HANDLERS[node.bl_idname](self, node, scope)
        handler = CLOSURE_HANDLERS.get(node.bl_idname)
        if handler is None:
            return self._fallback_closure(node, scope)
        front = handler(Inputs(self, node, scope, FRONT))
        back = handler(Inputs(self, node, scope, BACK))
        return merge_sides(front, back)

    def _group_input_closure(self, node, output, scope: tuple) -> list[Term]:
        if not scope:
            return []
        group_node = scope[-1]
        for candidate in group_node.inputs:
            if candidate.identifier == output.identifier:
                return self.closure(candidate, scope[:-1])
        return []

    def _fallback_closure(self, node, scope: tuple) -> list[Term]:
        self.warn_node(
            node,
            f"{node.bl_label} shaders are not supported by Haze; rendered as a Diffuse BSDF of its Color",
        )
        if "Color" not in node.inputs:
            return [Term("diffuse", np.ones(3), color=(0.8, 0.8, 0.8))]
        front = Inputs(self, node, scope, FRONT)("Color")
        back = Inputs(self, node, scope, BACK)("Color")
        return merge_sides(
            [Term("diffuse", np.ones(3), color=tuple(np.atleast_1d(front) * np.ones(3)))],
            [Term("diffuse", np.ones(3), color=tuple(np.atleast_1d(back) * np.ones(3)))],
        )


# ---------------------------------------------------------------------------- value nodes


def value_passthrough_input(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray:
    # Reroute: the value of its input, in the output's type.
    return convert(graph.input_value(node.inputs[0], scope), node.inputs[0].type, socket.type)


def value_constant(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray:
    # Value and RGB nodes keep their constant in the output socket's default_value.
    return graph.unlinked_value(socket, socket_width(socket.type))


def value_group(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray | None:
    inner = graph.group_output_input(node, socket.identifier)
    if inner is None:
        return sided(0.0, socket_width(socket.type))
    return convert(graph.input_value(inner, scope + (node,)), inner.type, socket.type)


def value_group_input(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray:
    if not scope:
        return sided(0.0, socket_width(socket.type))
    group_node = scope[-1]
    for candidate in group_node.inputs:
        if candidate.identifier == socket.identifier:
            return convert(graph.input_value(candidate, scope[:-1]), candidate.type, socket.type)
    return sided(0.0, socket_width(socket.type))


def value_geometry(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray | None:
    if socket.identifier == "Backfacing":
        return np.array([[0.0], [1.0]])
    graph.warn_node(node, f"Geometry output '{socket.name}' varies over the surface; Haze supports "
                          "only Backfacing, the inputs it feeds use their own values")
    return None


def value_math(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray:
    a, b, c = (graph.input_value(s, scope) for s in node.inputs[:3])
    operation = MATH_OPERATIONS.get(node.operation)
    if operation is None:
        graph.warn_node(node, f"Math operation {node.operation} is not supported; its first input is used")
        result = a
    else:
        with np.errstate(all="ignore"):
            result = np.nan_to_num(operation(a, b, c), nan=0.0, posinf=0.0, neginf=0.0)
    return np.clip(result, 0.0, 1.0) if node.use_clamp else result


def blend(graph: ShaderGraph, node, blend_type: str, t, a, b) -> np.ndarray:
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


def value_mix(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray:
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


def value_mix_rgb(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray:
    factor = np.clip(graph.input_value(node.inputs["Fac"], scope), 0.0, 1.0)
    a = graph.input_value(node.inputs["Color1"], scope)
    b = graph.input_value(node.inputs["Color2"], scope)
    result = blend(graph, node, node.blend_type, factor, a, b)
    return np.clip(result, 0.0, 1.0) if node.use_clamp else result


def value_invert(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray:
    factor = graph.input_value(node.inputs["Fac"], scope)
    color = graph.input_value(node.inputs["Color"], scope)
    return color + factor * ((1.0 - color) - color)


def value_clamp(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray:
    value, low, high = (graph.input_value(node.inputs[n], scope) for n in ("Value", "Min", "Max"))
    if node.clamp_type == "RANGE":
        low, high = np.minimum(low, high), np.maximum(low, high)
    return np.minimum(np.maximum(value, low), high)


def value_map_range(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray | None:
    if node.data_type != "FLOAT" or node.interpolation_type != "LINEAR":
        graph.warn_node(node, "only linear float Map Range is supported; the inputs it feeds use "
                              "their own values")
        return None
    v, a, b, c, d = (graph.input_value(node.inputs[n], scope)
                     for n in ("Value", "From Min", "From Max", "To Min", "To Max"))
    t = safe_divide(v - a, b - a)
    result = c + t * (d - c)
    return np.clip(result, np.minimum(c, d), np.maximum(c, d)) if node.clamp else result


def value_combine(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray | None:
    if getattr(node, "mode", "RGB") != "RGB":
        graph.warn_node(node, f"{node.mode} colour mode is not supported; the inputs it feeds use "
                              "their own values")
        return None
    parts = [graph.input_value(s, scope) for s in node.inputs[:3]]
    return np.concatenate(parts, axis=1)


def value_separate(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray | None:
    if getattr(node, "mode", "RGB") != "RGB":
        graph.warn_node(node, f"{node.mode} colour mode is not supported; the inputs it feeds use "
                              "their own values")
        return None
    whole = graph.input_value(node.inputs[0], scope)
    index = [s.identifier for s in node.outputs].index(socket.identifier)
    return whole[:, index:index + 1].copy()


def value_rgb_to_bw(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray:
    return (graph.input_value(node.inputs["Color"], scope) @ LUMINANCE)[:, None]


def value_gamma(graph: ShaderGraph, node, socket, scope: tuple) -> np.ndarray:
    color = graph.input_value(node.inputs["Color"], scope)
    gamma = graph.input_value(node.inputs["Gamma"], scope)
    return np.where(color > 0.0, safe_power(color, gamma), color)


VALUE_HANDLERS: dict[str, Callable] = {
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


# ---------------------------------------------------------------------------- shader nodes


def combine_mix(graph: ShaderGraph, node, scope: tuple) -> list[Term]:
    # Cycles clamps the mix factor to [0, 1].
    factor = np.clip(graph.input_value(node.inputs[0], scope), 0.0, 1.0)
    first = graph.closure(node.inputs[1], scope)
    second = graph.closure(node.inputs[2], scope)
    return scale_terms(first, 1.0 - factor) + scale_terms(second, factor)


def combine_add(graph: ShaderGraph, node, scope: tuple) -> list[Term]:
    return graph.closure(node.inputs[0], scope) + graph.closure(node.inputs[1], scope)


COMBINE_HANDLERS: dict[str, Callable] = {
    "ShaderNodeMixShader": combine_mix,
    "ShaderNodeAddShader": combine_add,
}


def rgb(value) -> tuple[float, float, float]:
    array = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,))
    return (float(array[0]), float(array[1]), float(array[2]))


def reflection_kind(roughness: float) -> str:
    # Cycles treats roughness 0 as a perfect mirror.
    return "conductor" if roughness <= 0.0 else "rough_conductor"


def warn_ignored_distribution(read: Inputs, node) -> None:
    distribution = getattr(node, "distribution", "GGX")
    if distribution not in {"GGX", "MULTI_GGX"}:
        read.warn(f"{distribution} microfacets are rendered as GGX")


def shader_diffuse(read: Inputs) -> list[Term]:
    if read("Roughness") > 0.0:
        read.warn("Roughness (Oren-Nayar) is ignored; Haze's diffuse lobe is Lambertian")
    return [Term("diffuse", np.ones(3), color=rgb(np.maximum(read("Color"), 0.0)))]


def shader_glossy(read: Inputs) -> list[Term]:
    node = read.node
    warn_ignored_distribution(read, node)
    if read("Anisotropy") != 0.0:
        read.warn("Anisotropy is ignored")
    roughness = saturate(read("Roughness"))
    return [Term(reflection_kind(roughness), np.ones(3), color=rgb(np.maximum(read("Color"), 0.0)),
                 roughness=roughness)]


def conductor_reflectance(cos: float, ior: np.ndarray, extinction: np.ndarray) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a conductor of complex index n + ik seen from air."""
    n2, k2 = ior**2, extinction**2
    cos2 = cos * cos
    sin2 = 1.0 - cos2
    t = n2 - k2 - sin2
    a2b2 = np.sqrt(t * t + 4.0 * n2 * k2)
    a = np.sqrt(np.maximum(0.5 * (a2b2 + t), 0.0))
    r_s = (a2b2 + cos2 - 2.0 * a * cos) / np.maximum(a2b2 + cos2 + 2.0 * a * cos, 1e-300)
    r_p = r_s * (cos2 * a2b2 + sin2 * sin2 - 2.0 * a * cos * sin2) / np.maximum(
        cos2 * a2b2 + sin2 * sin2 + 2.0 * a * cos * sin2, 1e-300)
    return 0.5 * (r_s + r_p)


F82_COS = 1.0 / 7.0  # about 82 degrees, where the F82-tint curve takes its tint


def conductor_as_f82(ior: np.ndarray, extinction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F0, edge tint) of the F82-tint curve through the conductor's exact reflectance at
    normal incidence and at cos = 1/7: an approximation of Cycles' Physical Conductor."""
    f0 = np.clip(conductor_reflectance(1.0, ior, extinction), 0.0, 1.0)
    schlick82 = f0 + (1.0 - f0) * (1.0 - F82_COS) ** 5
    tint = conductor_reflectance(F82_COS, ior, extinction) / schlick82
    return f0, np.clip(tint, 0.0, 1.0)


def shader_metallic(read: Inputs) -> list[Term]:
    """Cycles' Metallic BSDF: the F82-tint Fresnel of Base Color and Edge Tint, or (Physical
    Conductor) the exact Fresnel of a complex index, here fitted by an F82-tint curve."""
    node = read.node
    warn_ignored_distribution(read, node)
    if read("Anisotropy") != 0.0:
        read.warn("Anisotropy is ignored")
    if node.fresnel_type == "PHYSICAL_CONDUCTOR":
        f0, tint = conductor_as_f82(np.maximum(read("IOR"), 0.0), np.maximum(read("Extinction"), 0.0))
    else:
        f0 = np.clip(read("Base Color"), 0.0, 1.0)
        tint = np.clip(read("Edge Tint"), 0.0, 1.0)
    roughness = saturate(read("Roughness"))
    return [Term(reflection_kind(roughness), np.ones(3), color=rgb(f0), roughness=roughness, fresnel="f82",
                 tint=rgb(tint))]


def shader_glass(read: Inputs) -> list[Term]:
    roughness = saturate(read("Roughness"))
    if roughness > 0.0:
        read.warn(f"rough glass (Roughness {roughness:g}) is rendered as smooth glass")
    ior = max(read("IOR"), 1e-5)
    return [Term("dielectric", np.ones(3), color=rgb(np.maximum(read("Color"), 0.0)), ior=ior)]


def shader_transparent(read: Inputs) -> list[Term]:
    return [Term("transparent", np.ones(3), color=rgb(np.maximum(read("Color"), 0.0)))]


def shader_emission(read: Inputs) -> list[Term]:
    radiance = np.asarray(read("Color")) * read("Strength")
    return [Term("emission", np.broadcast_to(radiance, (3,)).astype(np.float64))]


def principled_ignored_inputs(read: Inputs) -> list[str]:
    """Inputs of the Principled BSDF set to something Haze cannot render."""
    checks = [
        ("Coat Weight", read("Coat Weight") > 0.0),
        ("Sheen Weight", read("Sheen Weight") > 0.0),
        ("Subsurface Weight (rendered as diffuse)", read("Subsurface Weight") > 0.0),
        ("Anisotropic", read("Anisotropic") > 0.0),
        ("Thin Film Thickness", read("Thin Film Thickness") > 0.0),
        ("Diffuse Roughness", read("Diffuse Roughness") > 0.0),
        ("Specular Tint (of the dielectric layer; metals use it)",
         not np.allclose(read("Specular Tint"), 1.0) and read("Metallic") < 1.0),
    ]
    return [name for name, ignored in checks if ignored]


def adjusted_specular_ior(ior: float, level: float) -> float:
    """Cycles' Specular IOR Level: scales F0 by 2 x level and converts back to an IOR."""
    if level == 0.5:
        return ior
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 * 2.0 * level
    root = math.sqrt(min(max(f0, 0.0), 0.9999))
    eta = (1.0 + root) / (1.0 - root)
    return 1.0 / eta if ior < 1.0 else eta


def shader_principled(read: Inputs) -> list[Term]:
    """Cycles' Principled BSDF (svm/closure.h) as Haze lobes: alpha, metal (F82-tint Fresnel of
    Base Color and Specular Tint), glass, then the dielectric specular layer over diffuse
    (Haze's "plastic")."""
    ignored = principled_ignored_inputs(read)
    if ignored:
        read.warn("ignored inputs: " + ", ".join(ignored))
    base = np.maximum(read("Base Color"), 0.0)
    metallic, alpha = saturate(read("Metallic")), saturate(read("Alpha"))
    roughness, transmission = saturate(read("Roughness")), saturate(read("Transmission Weight"))
    ior = max(read("IOR"), 1e-5)
    terms: list[Term] = []
    weight = 1.0
    if alpha < 1.0:
        terms.append(Term("transparent", np.full(3, 1.0 - alpha)))
        weight = alpha
    emission = np.asarray(read("Emission Color")) * read("Emission Strength")
    if np.any(emission != 0.0):
        terms.append(Term("emission", np.broadcast_to(emission * weight, (3,)).astype(np.float64)))
    if metallic > 0.0:
        terms.append(Term(reflection_kind(roughness), np.full(3, weight * metallic),
                          color=rgb(np.minimum(base, 1.0)), roughness=roughness, fresnel="f82",
                          tint=rgb(np.clip(read("Specular Tint"), 0.0, 1.0))))
        weight *= 1.0 - metallic
    if transmission > 0.0 and weight > 0.0:
        if roughness > 0.0:
            read.warn(f"rough transmission (Roughness {roughness:g}) is rendered as smooth glass")
        terms.append(Term("dielectric", np.full(3, weight * transmission),
                          color=rgb(np.sqrt(np.minimum(base, 1.0))), ior=ior))
        weight *= 1.0 - transmission
    if weight > 0.0:
        eta = adjusted_specular_ior(ior, max(read("Specular IOR Level"), 0.0))
        kind = "diffuse" if eta == 1.0 else "plastic"
        terms.append(Term(kind, np.full(3, weight), color=rgb(base), roughness=roughness, ior=eta))
    return terms


def shader_background(read: Inputs) -> list[Term]:
    radiance = np.asarray(read("Color")) * read("Strength")
    return [Term("emission", np.broadcast_to(radiance, (3,)).astype(np.float64))]


def warn_phase(read: Inputs) -> None:
    phase = getattr(read.node, "phase", "HENYEY_GREENSTEIN")
    if phase != "HENYEY_GREENSTEIN":
        read.warn(f"{phase} phase function is rendered as Henyey-Greenstein with the node's Anisotropy")


def shader_volume_scatter(read: Inputs) -> list[Term]:
    warn_phase(read)
    density = max(read("Density"), 0.0)
    sigma_s = np.broadcast_to(np.asarray(read("Color")) * density, (3,)).astype(np.float64)
    return [Term("scatter", sigma_s, anisotropy=read("Anisotropy"))]


def shader_volume_absorption(read: Inputs) -> list[Term]:
    density = max(read("Density"), 0.0)
    sigma_a = np.maximum((1.0 - np.asarray(read("Color"))) * density, 0.0)
    return [Term("absorb", np.broadcast_to(sigma_a, (3,)).astype(np.float64))]


def shader_volume_coefficients(read: Inputs) -> list[Term]:
    warn_phase(read)
    return [
        Term("scatter", np.maximum(read("Scatter Coefficients"), 0.0), anisotropy=read("Anisotropy")),
        Term("absorb", np.maximum(read("Absorption Coefficients"), 0.0)),
        Term("volume_emission", np.asarray(read("Emission Coefficients"), dtype=np.float64)),
    ]


def shader_principled_volume(read: Inputs) -> list[Term]:
    """Cycles' Principled Volume for a homogeneous medium (svm_node_principled_volume)."""
    density = max(read("Density"), 0.0)
    color = np.asarray(read("Color"), dtype=np.float64)
    absorption_color = np.sqrt(np.maximum(read("Absorption Color"), 0.0))
    absorption = np.maximum(1.0 - color, 0.0) * np.maximum(1.0 - absorption_color, 0.0)
    emission = read("Emission Strength") * np.asarray(read("Emission Color"), dtype=np.float64)
    if read("Blackbody Intensity") > 0.0:
        read.warn("blackbody emission is not supported on mesh volumes and is ignored")
    terms = [
        Term("scatter", color * density, anisotropy=read("Anisotropy")),
        Term("absorb", absorption * density),
    ]
    if read("Emission Strength") > 0.0:
        terms.append(Term("volume_emission", np.broadcast_to(emission, (3,)).astype(np.float64)))
    return terms


def shader_volume_emission(read: Inputs) -> list[Term]:
    radiance = np.asarray(read("Color")) * read("Strength")
    return [Term("volume_emission", np.broadcast_to(radiance, (3,)).astype(np.float64))]


CLOSURE_HANDLERS: dict[str, Callable[[Inputs], list[Term]]] = {
    "ShaderNodeBsdfPrincipled": shader_principled,
    "ShaderNodeBsdfDiffuse": shader_diffuse,
    "ShaderNodeBsdfGlossy": shader_glossy,
    "ShaderNodeBsdfAnisotropic": shader_glossy,
    "ShaderNodeBsdfMetallic": shader_metallic,
    "ShaderNodeBsdfGlass": shader_glass,
    "ShaderNodeBsdfTransparent": shader_transparent,
    "ShaderNodeEmission": shader_emission,
    "ShaderNodeBackground": shader_background,
    "ShaderNodeVolumeScatter": shader_volume_scatter,
    "ShaderNodeVolumeAbsorption": shader_volume_absorption,
    "ShaderNodeVolumeCoefficients": shader_volume_coefficients,
    "ShaderNodeVolumePrincipled": shader_principled_volume,
}


def as_volume_terms(terms: list[Term]) -> list[Term]:
    """Terms reaching a Volume socket. Emission there is a volume source (per unit length)."""
    return [replace(t, kind="volume_emission") if t.kind == "emission" else t for t in terms]
