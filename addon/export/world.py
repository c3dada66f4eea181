"""The world: constant background radiance and the scene-wide (world) volume.

A Background fed by an Environment Texture (an HDRI, optionally through a Mapping node)
becomes an environment map, importance-sampled (world_map.py); one whose Color or Strength
nodes compile to a program (a gradient sky...) becomes a map evaluated from the program
(world_program.py). Otherwise the world's
Surface is folded like a material to one constant radiance (Background colour x strength,
Mix/Add of Backgrounds with constant factors); anything else that varies with direction
(sky textures, a mix of an HDRI with another background...) is warned about once and
replaced by the unlinked value of the input it feeds (documented fallback).
"""

from __future__ import annotations

import numpy as np

from renderer.scene import Environment, Medium

from .images import ImageLibrary
from .materials import active_output, uses_nodes, volume_medium
from .messages import Messages
from .node_closures import as_volume_terms, rgb
from .nodes import ShaderGraph
from .world_map import environment_map
from .world_program import WORLD_HANDLERS, WORLD_SOURCES, world_program_map


def world_subject(name: str) -> str:
    return f"World '{name}'"


def world_environment(world, messages: Messages) -> tuple[Environment, Medium | None]:
    """(background radiance, world volume) of a Blender world; black and none without one."""
    if world is None:
        return Environment(), None
    tree = world.node_tree
    if tree is None or not uses_nodes(world):
        return Environment(radiance=rgb(np.asarray(world.color[:3], dtype=np.float64))), None
    output = active_output(tree)
    if output is None:
        messages.warn(world_subject(world.name), "has no active World Output node; the background is black")
        return Environment(), None
    graph = ShaderGraph(world_subject(world.name), messages)
    volume_terms = as_volume_terms(graph.closure(output.inputs["Volume"]))
    medium = volume_medium(f"{world.name} (world volume)", volume_terms, messages, world_subject(world.name))
    mapped = environment_map(graph, output.inputs["Surface"])
    if mapped is not None:
        return mapped, medium
    # A program graph of its own: the one above has folded (and cached) values without one.
    program_graph = ShaderGraph(world_subject(world.name), messages, ImageLibrary(messages))
    program_graph.compiled = {**program_graph.compiled, **WORLD_HANDLERS}
    program_graph.sources = program_graph.sources | WORLD_SOURCES
    mapped = world_program_map(program_graph, output.inputs["Surface"])
    if mapped is not None:
        return mapped, medium
    terms = graph.closure(output.inputs["Surface"])
    radiance = sum((t.weight for t in terms if t.kind == "emission" and t.sides != "back"), np.zeros(3))
    if any(t.kind != "emission" for t in terms):
        messages.warn(world_subject(world.name),
                      "only Background shaders light the world surface; others are ignored")
    return Environment(radiance=rgb(radiance)), medium
