"""A volume material evaluated at every voxel of a volume's grids (Cycles' semantics).

Cycles shades a volume object by looking grid attributes up at the shading point and running
the material's nodes on the values. Its lookups are stochastic (svm_node_attr with
`stochastic_sample`: one voxel picked with the trilinear weights), so the expected value of
anything the nodes compute from one lookup is the trilinear interpolation of that quantity
computed per voxel. Evaluating the nodes per voxel, as here, and letting Haze interpolate the
result is therefore what Cycles renders on average, Math nodes on the density included.

Values are arrays of shape (n, k): n = 1 for values that are the same in every voxel, else
one row per voxel; k = 1 for scalars and 3 for colours and vectors. The value-node handlers
of `node_values` work unchanged on such arrays; this module adds the Attribute node (the grids)
and evaluates volume closures per voxel (svm/closure.h: svm_node_closure_volume,
svm_node_principled_volume, svm_node_volume_coefficients, svm_node_closure_emission).
The object's volume density factor (Cycles' object_volume_density) is left out: the caller
applies it per instance.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .materials import uses_nodes
from .messages import Messages
from .node_values import VALUE_HANDLERS, socket_width
from .nodes import ShaderGraph

STEFAN_BOLTZMANN_OVER_PI = 5.670373e-8 * 1e-6 / np.pi  # Cycles' blackbody scale (svm/closure.h)
SURFACE_SHADERS = {
    "ShaderNodeBsdfPrincipled", "ShaderNodeBsdfDiffuse", "ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic",
    "ShaderNodeBsdfMetallic", "ShaderNodeBsdfGlass", "ShaderNodeBsdfTransparent", "ShaderNodeBsdfTranslucent",
    "ShaderNodeBsdfRefraction", "ShaderNodeSubsurfaceScattering", "ShaderNodeBsdfSheen", "ShaderNodeHoldout",
    "ShaderNodeBsdfToon", "ShaderNodeBsdfHair", "ShaderNodeBsdfHairPrincipled", "ShaderNodeBsdfRayPortal",
}


def row(value) -> np.ndarray:
    """A constant as a (1, k) value."""
    return np.atleast_1d(np.asarray(value, np.float64))[None, :]


@dataclass
class Blackbody:
    """Principled Volume's blackbody emission: tint * weight * S(T, intensity) * rgb(T)."""

    temperature: np.ndarray  # (n, 1) kelvin, >= 0
    intensity: np.ndarray  # (n, 1)
    tint: np.ndarray  # (n, 3)
    weight: np.ndarray  # (n, 1) mix weight


@dataclass
class VoxelCoefficients:
    """Coefficients of a volume material per voxel (n = voxel count, or 1 where constant)."""

    sigma_s: np.ndarray  # (n, 3) per unit length
    sigma_a: np.ndarray  # (n, 3)
    emission: np.ndarray  # (n, 3) per unit length, not counting blackbody
    anisotropy: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)  # (g, scatter weight)
    blackbody: list[Blackbody] = field(default_factory=list)
    grids_read: set[str] = field(default_factory=set)  # grid names the material looked up


class VoxelGraph(ShaderGraph):
    """A material's node tree over voxel values: `grids` maps grid names to (n,) or (n, 3) arrays.

    The grids present decide, as in Cycles, what an Attribute node or a Principled Volume
    attribute reads; a name without a grid reads 0 (Attribute node) or is skipped
    (Principled Volume's density, colour and temperature attributes)."""

    def __init__(self, owner: str, messages: Messages, grids: dict[str, np.ndarray]) -> None:
        super().__init__(owner, messages)
        self.grids = grids
        self.grids_read: set[str] = set()

    @staticmethod
    def unlinked_value(socket, width: int) -> np.ndarray:
        default = getattr(socket, "default_value", None)
        if default is None or isinstance(default, str):
            return np.zeros((1, width))
        if isinstance(default, (int, float, bool)):
            return np.full((1, width), float(default))
        components = [float(x) for x in default][:3]
        values = components if len(components) == width else [components[0]] * width
        return np.array([values], np.float64)

    @staticmethod
    def handler(node):
        return VOXEL_HANDLERS.get(node.bl_idname) or VALUE_HANDLERS.get(node.bl_idname)

    @staticmethod
    def zero(width: int) -> np.ndarray:
        """One row (the same for every voxel) of `width` zeros."""
        return np.zeros((1, width))

    # ------------------------------------------------------------------ grids
    def grid(self, name: str) -> np.ndarray | None:
        """The grid `name` as (n, 1) or (n, 3) values, or None if the volume has none."""
        values = self.grids.get(name)
        if values is None:
            return None
        self.grids_read.add(name)
        return values[:, None] if values.ndim == 1 else values

    def scalar(self, read: Reader, name: str) -> np.ndarray:
        return self.input_value(read.node.inputs[name], read.scope)

    def text(self, read: Reader, name: str) -> str:
        socket = read.node.inputs.get(name)
        if socket is None:
            return getattr(read.node, name.lower().replace(" ", "_"), "") or ""
        return str(socket.default_value or "")

    # ------------------------------------------------------------------ closures
    def coefficients(self, socket) -> VoxelCoefficients:
        """All volume closures reaching the material output's Volume socket, added up."""
        total = VoxelCoefficients(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)))
        self.closures(socket, (), np.ones((1, 1)), total)
        total.grids_read = set(self.grids_read)
        return total

    def closures(self, socket, scope: tuple, weight: np.ndarray, total: VoxelCoefficients) -> None:
        source = self.link_source(socket)
        if source is not None:
            self.closure_node(source[0], source[1], scope, weight, total)

    def closure_node(self, node, output, scope: tuple, weight: np.ndarray, total: VoxelCoefficients) -> None:
        if node.mute:
            for link in node.internal_links:
                if link.to_socket.identifier == output.identifier:
                    self.closures(link.from_socket, scope, weight, total)
            return
        kind = node.bl_idname
        if kind == "NodeReroute":
            self.closures(node.inputs[0], scope, weight, total)
        elif kind == "ShaderNodeGroup":
            inner = self.group_output_input(node, output.identifier)
            if inner is not None:
                self.closures(inner, scope + (node,), weight, total)
        elif kind == "NodeGroupInput":
            self._group_input(node, output, scope, weight, total)
        elif kind == "ShaderNodeMixShader":
            factor = np.clip(self.input_value(node.inputs[0], scope), 0.0, 1.0)  # Cycles clamps it
            self.closures(node.inputs[1], scope, weight * (1.0 - factor), total)
            self.closures(node.inputs[2], scope, weight * factor, total)
        elif kind == "ShaderNodeAddShader":
            self.closures(node.inputs[0], scope, weight, total)
            self.closures(node.inputs[1], scope, weight, total)
        elif kind in CLOSURE_HANDLERS:
            CLOSURE_HANDLERS[kind](self, Reader(node, scope), weight, total)
        elif kind in SURFACE_SHADERS:
            self.warn_node(node, "a surface shader connected to the Volume output is ignored (as in Cycles)")
        else:
            self.warn_node(node, f"{node.bl_label} shaders are not supported in volumes and are ignored")

    def _group_input(self, node, output, scope: tuple, weight, total) -> None:
        if not scope:
            return
        for candidate in scope[-1].inputs:
            if candidate.identifier == output.identifier:
                self.closures(candidate, scope[:-1], weight, total)


@dataclass
class Reader:
    """A closure node and the group scope it is evaluated in."""

    node: object
    scope: tuple


# ---------------------------------------------------------------------------- value nodes


def value_attribute(graph: VoxelGraph, node, socket, scope: tuple) -> np.ndarray | None:
    """The Attribute node on a volume: float grid v -> Factor v, Color (v, v, v), Alpha 1;
    vector grid -> Color the vector, Factor its average; no such grid -> all 0 (Cycles)."""
    if node.attribute_type != "GEOMETRY":
        graph.warn_node(node, f"{node.attribute_type.title()} attributes are not supported on volumes; "
                              "the inputs it feeds use their own values")
        return None
    values = graph.grid(node.attribute_name)
    if values is None:
        graph.warn_node(node, f"the volume has no grid '{node.attribute_name}'; it reads 0 (as in Cycles)")
        return np.zeros((1, socket_width(socket.type)))
    if socket.identifier == "Alpha":
        return np.ones((1, 1))
    if socket.identifier == "Fac":
        return values if values.shape[1] == 1 else values.mean(axis=1, keepdims=True)
    return values if values.shape[1] == 3 else np.repeat(values, 3, axis=1)


def value_geometry(graph: VoxelGraph, node, socket, scope: tuple) -> np.ndarray | None:
    if socket.identifier == "Backfacing":
        return np.zeros((1, 1))  # volume shading points face nothing
    graph.warn_node(node, f"Geometry output '{socket.name}' is not supported on volumes; the inputs it "
                          "feeds use their own values")
    return None


def value_color_ramp(graph: VoxelGraph, node, socket, scope: tuple) -> np.ndarray:
    """Color Ramp with linear or constant interpolation (the others are taken as linear)."""
    ramp = node.color_ramp
    if ramp.interpolation not in ("LINEAR", "CONSTANT"):
        graph.warn_node(node, f"{ramp.interpolation.title()} colour ramps are interpolated linearly")
    if ramp.color_mode != "RGB":
        graph.warn_node(node, f"{ramp.color_mode} colour ramps are interpolated in RGB")
    stops = sorted(ramp.elements, key=lambda e: e.position)
    positions = np.array([e.position for e in stops])
    colors = np.array([tuple(e.color) for e in stops])
    t = graph.input_value(node.inputs["Fac"], scope)[:, 0]
    if ramp.interpolation == "CONSTANT":
        index = np.clip(np.searchsorted(positions, t, side="right") - 1, 0, len(stops) - 1)
        values = colors[index]
    else:
        values = np.stack([np.interp(t, positions, colors[:, c]) for c in range(4)], axis=1)
    if socket.identifier == "Alpha":
        return values[:, 3:4]
    return values[:, :3]


VOXEL_HANDLERS: dict[str, Callable] = {
    "ShaderNodeAttribute": value_attribute,
    "ShaderNodeNewGeometry": value_geometry,
    "ShaderNodeValToRGB": value_color_ramp,
}


# ---------------------------------------------------------------------------- closures


def add_scatter(total: VoxelCoefficients, sigma_s: np.ndarray, anisotropy: np.ndarray) -> None:
    total.sigma_s = total.sigma_s + sigma_s
    total.anisotropy.append((anisotropy, sigma_s))


def warn_phase(graph: VoxelGraph, read: Reader) -> None:
    phase = getattr(read.node, "phase", "HENYEY_GREENSTEIN")
    if phase != "HENYEY_GREENSTEIN":
        graph.warn_node(read.node, f"{phase} phase function is rendered as Henyey-Greenstein with the "
                                   "node's Anisotropy")


def closure_scatter(graph: VoxelGraph, read: Reader, weight: np.ndarray, total: VoxelCoefficients) -> None:
    warn_phase(graph, read)
    density = weight * np.maximum(graph.scalar(read, "Density"), 0.0)
    add_scatter(total, graph.scalar(read, "Color") * density, graph.scalar(read, "Anisotropy"))


def closure_absorption(graph: VoxelGraph, read: Reader, weight: np.ndarray, total: VoxelCoefficients) -> None:
    density = weight * np.maximum(graph.scalar(read, "Density"), 0.0)
    total.sigma_a = total.sigma_a + (1.0 - graph.scalar(read, "Color")) * density


def closure_coefficients(graph: VoxelGraph, read: Reader, weight: np.ndarray,
                         total: VoxelCoefficients) -> None:
    warn_phase(graph, read)
    add_scatter(total, weight * graph.scalar(read, "Scatter Coefficients"), graph.scalar(read, "Anisotropy"))
    total.sigma_a = total.sigma_a + weight * graph.scalar(read, "Absorption Coefficients")
    total.emission = total.emission + weight * graph.scalar(read, "Emission Coefficients")


def closure_emission(graph: VoxelGraph, read: Reader, weight: np.ndarray, total: VoxelCoefficients) -> None:
    total.emission = total.emission + weight * graph.scalar(read, "Color") * graph.scalar(read, "Strength")


def closure_principled(graph: VoxelGraph, read: Reader, weight: np.ndarray, total: VoxelCoefficients) -> None:
    """svm_node_principled_volume: density = Density x density attribute (if the volume has
    that grid), scattering = Color (x colour attribute) x density, absorption =
    max(1 - Color, 0) x max(1 - sqrt(Absorption Color), 0) x density; emission = Emission
    Strength x Emission Color where the strength is positive; blackbody where the intensity is."""
    density = weight * np.maximum(graph.scalar(read, "Density"), 0.0)
    attribute = graph.grid(graph.text(read, "Density Attribute"))
    if attribute is not None:
        density = np.maximum(density * attribute.mean(axis=1, keepdims=True), 0.0)
    color = graph.scalar(read, "Color")
    color_attribute = graph.grid(graph.text(read, "Color Attribute"))
    if color_attribute is not None:
        color = color * np.broadcast_to(color_attribute, (color_attribute.shape[0], 3))
    absorption_color = np.sqrt(np.maximum(graph.scalar(read, "Absorption Color"), 0.0))
    absorption = np.maximum(1.0 - color, 0.0) * np.maximum(1.0 - absorption_color, 0.0)
    add_scatter(total, color * density, graph.scalar(read, "Anisotropy"))
    total.sigma_a = total.sigma_a + absorption * density
    strength = graph.scalar(read, "Emission Strength")
    total.emission = total.emission + np.where(strength > 0.0, strength, 0.0) * graph.scalar(
        read, "Emission Color") * weight
    intensity = graph.scalar(read, "Blackbody Intensity")
    if np.any(intensity > 0.0):
        temperature = graph.scalar(read, "Temperature")
        grid = graph.grid(graph.text(read, "Temperature Attribute"))
        if grid is not None:
            temperature = temperature * np.maximum(grid.mean(axis=1, keepdims=True), 0.0)
        total.blackbody.append(Blackbody(np.maximum(temperature, 0.0), np.maximum(intensity, 0.0),
                                         graph.scalar(read, "Blackbody Tint"), weight))


CLOSURE_HANDLERS: dict[str, Callable] = {
    "ShaderNodeVolumeScatter": closure_scatter,
    "ShaderNodeVolumeAbsorption": closure_absorption,
    "ShaderNodeVolumeCoefficients": closure_coefficients,
    "ShaderNodeVolumePrincipled": closure_principled,
    "ShaderNodeEmission": closure_emission,
}


def evaluate_volume_material(material, owner: str, messages: Messages,
                             grids: dict[str, np.ndarray]) -> VoxelCoefficients | None:
    """Per-voxel coefficients of `material`'s volume (None if it has no Volume output link)."""
    tree = material.node_tree if material is not None and uses_nodes(material) else None
    output = tree.get_output_node("CYCLES") if tree is not None else None
    if output is None:
        return None
    graph = VoxelGraph(owner, messages, grids)
    if graph.link_source(output.inputs["Volume"]) is None:
        return None
    return graph.coefficients(output.inputs["Volume"])


def grids_a_material_reads(material) -> set[str]:
    """Grid names `material`'s volume may look up (Attribute nodes, Principled Volume's
    attribute names), found without evaluating it: the grids worth reading at all."""
    names: set[str] = set()
    trees = [material.node_tree] if material is not None and material.node_tree is not None else []
    seen: set[str] = set()
    while trees:
        tree = trees.pop()
        if tree.name_full in seen:
            continue
        seen.add(tree.name_full)
        for node in tree.nodes:
            if node.bl_idname == "ShaderNodeAttribute" and node.attribute_type == "GEOMETRY":
                names.add(node.attribute_name)
            elif node.bl_idname == "ShaderNodeVolumePrincipled":
                for name in ("Density Attribute", "Color Attribute", "Temperature Attribute"):
                    socket = node.inputs.get(name)
                    if socket is not None and socket.default_value:
                        names.add(str(socket.default_value))
            elif node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None:
                trees.append(node.node_tree)
    return names
