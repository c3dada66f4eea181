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

This module is the graph evaluation: links, reroutes, groups, muted nodes and the cache of
folded outputs. What each node computes is looked up by node type name in the registries of
node_values (VALUE_HANDLERS) and node_closures (CLOSURE_HANDLERS, COMBINE_HANDLERS);
volume_shader.VoxelGraph reuses the evaluation with per-voxel values.
"""

from __future__ import annotations

import numpy as np

from .messages import Messages, node_subject
from .node_closures import CLOSURE_HANDLERS, COMBINE_HANDLERS, Inputs, Term, fallback_closure, merge_sides
from .node_principled import shader_principled
from .node_program import PROGRAM_HANDLERS, VARYING_SOURCES
from .node_program_normals import NORMAL_HANDLERS, NORMAL_SOURCES
from .node_values import BACK, FRONT, VALUE_HANDLERS, ValueHandler, convert, sided, socket_width
from .program_builder import ProgramBuilder, Reg

SURFACE_HANDLERS = {**CLOSURE_HANDLERS, "ShaderNodeBsdfPrincipled": shader_principled}
COMPILED = {**PROGRAM_HANDLERS, **NORMAL_HANDLERS}  # varying nodes compiled into programs
VARYING = VARYING_SOURCES | NORMAL_SOURCES


class ShaderGraph:
    """Folds one node tree (a material's or world's) into constant values and closure terms."""

    def __init__(self, owner: str, messages: Messages, images=None) -> None:
        self.owner = owner  # e.g. "Material 'Glass'", used in every message
        self.messages = messages
        self._values: dict[tuple, np.ndarray] = {}
        # Shader programs: what varies over the surface (textures...), compiled per node.
        self.program = ProgramBuilder()
        self.images = images  # images.ImageLibrary, or None: no Image Texture is compiled
        # Whether inputs may compile to programs (material surfaces; worlds and volumes not yet).
        self.programs = images is not None
        self.compiled = COMPILED  # node handlers by type (a world's see directions: world_program)
        self.sources = VARYING  # node types that vary by themselves (a world's add its own)
        self._varying: dict[tuple, bool] = {}
        self._registers: dict[tuple, Reg | None] = {}
        self.pass_index = 0  # the material's Pass Index (Object Info's Material Index)

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
    def handler(node) -> ValueHandler | None:
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

    # ---------------------------------------------------------------- programs
    def is_varying(self, node, scope: tuple = ()) -> bool:
        """Whether `node`'s outputs vary over a surface (a texture or coordinate reaches it)."""
        key = (node.as_pointer(), tuple(n.as_pointer() for n in scope))
        if key not in self._varying:
            self._varying[key] = False  # a cycle (invalid tree) is not varying
            self._varying[key] = self._find_varying(node, scope)
        return self._varying[key]

    def _find_varying(self, node, scope: tuple) -> bool:
        if node.mute or node.bl_idname not in self.compiled and node.bl_idname != "NodeReroute":
            return False
        if node.bl_idname in self.sources:
            return True
        for socket in node.inputs:
            source = self.link_source(socket)
            if source is not None and self.is_varying(source[0], scope):
                return True
        return False

    def input_varying(self, socket, scope: tuple = ()) -> Reg | None:
        """The register of a varying input (converted to the socket's type), or None when
        the input is constant or cannot be compiled (then input_value folds it, warning)."""
        source = self.link_source(socket)
        if not self.programs or source is None or not self.is_varying(source[0], scope):
            return None
        node, output = source
        if node.bl_idname == "NodeReroute":
            return self.input_varying(node.inputs[0], scope)
        key = (node.as_pointer(), output.identifier, tuple(n.as_pointer() for n in scope))
        if key not in self._registers:
            self._registers[key] = self.compiled[node.bl_idname](self, node, output, scope)
        reg = self._registers[key]
        return None if reg is None else self.program.convert(reg, output.type, socket.type)

    def operand(self, socket, scope: tuple = ()) -> Reg:
        """A node input as a register: varying, or its folded value (front faces) as a constant."""
        reg = self.input_varying(socket, scope)
        if reg is not None:
            return reg
        return self.program.const(self.input_value(socket, scope)[FRONT])

    def add_image(self, image) -> str | None:
        return None if self.images is None else self.images.add(image, self.owner)

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
        handler = SURFACE_HANDLERS.get(node.bl_idname)
        if handler is None:
            return fallback_closure(self, node, scope)
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
